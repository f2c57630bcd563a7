"""Pole refinement by nonlinear least squares on the LSFD model (variable projection).

The residues and residual terms of :func:`ema.lsfd.lsfd` are linear in the data once the poles are fixed; they
are eliminated (Golub-Pereyra variable projection), and the natural frequencies and damping ratios are optimised
by Levenberg-Marquardt steps with Kaufman's Jacobian. This removes the noise bias of the linearised pole
estimators. :class:`VarPro` is the problem of one band, shared with :func:`ema.uncertainty.pole_std`.
"""

from __future__ import annotations

import logging

import numpy as np

from .frf import FRF_FORMS, FRFSet
from .lsfd import band_lines, modal_basis
from .modal import modal_from_pole, pole_from_modal

__all__ = ["VarPro", "refine_poles"]

log = logging.getLogger(__name__)


def _basis_derivatives(poles: np.ndarray, freq_hz: np.ndarray, form: str) -> tuple[np.ndarray, np.ndarray]:
    """d(basis columns of mode r)/d(f_r, zeta_r): two arrays (n_freq, n_modes, 2) for the two columns."""
    jw = 1j * 2 * np.pi * freq_hz[:, None]
    wn = np.abs(poles)
    z = -poles.real / wn
    sq = np.sqrt(np.clip(1 - z**2, 1e-12, None))
    dl_df = 2 * np.pi * (poles / wn)  # d lambda / d f (Hz)
    dl_dz = -wn - 1j * wn * z / sq  # d lambda / d zeta
    a = 1.0 / (jw - poles[None, :])
    b = 1.0 / (jw - poles.conj()[None, :])
    d1, d2 = [], []
    for dl in (dl_df, dl_dz):
        da = a**2 * dl[None, :]
        db = b**2 * dl.conj()[None, :]
        d1.append(da + db)
        d2.append(1j * (da - db))
    k = FRF_FORMS[form]
    c1, c2 = np.stack(d1, axis=2), np.stack(d2, axis=2)
    if k:
        c1, c2 = c1 * (jw**k)[:, :, None], c2 * (jw**k)[:, :, None]
    return c1, c2


class VarPro:
    """The variable-projection least-squares problem of :func:`refine_poles` on one band.

    ``Yr`` are the band's FRFs (each scaled to unit RMS, real and imaginary parts stacked), compressed onto
    their dominant right singular directions (as many as model columns): the signal subspace, less noise.
    """

    def __init__(self, f: np.ndarray, Yr: np.ndarray, form: str, residuals: bool) -> None:
        self.f, self.Yr, self.form, self.residuals = f, Yr, form, residuals

    @classmethod
    def of(cls, frf: FRFSet, band, residuals: bool, n_modes: int) -> VarPro:
        f, Y, _ = band_lines(frf, band, "frf", residuals)
        n_c = 2 * n_modes + (2 if residuals else 0)
        Yr = np.vstack([Y.real, Y.imag])
        if Yr.shape[1] > n_c:
            _, _, Vt = np.linalg.svd(Yr, full_matrices=False)
            Yr = Yr @ Vt[:n_c].T
        return cls(f, Yr, frf.form, residuals)

    def evaluate(self, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residual (2 n_f, k), linear coefficients (n_c, k) and the basis' orthonormal Q at poles ``lam``."""
        B = modal_basis(lam, self.f, self.form, self.residuals)
        A = np.vstack([B.real, B.imag])
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        Qa, Ra = np.linalg.qr(A / scale)
        proj = Qa.T @ self.Yr
        c = np.linalg.solve(Ra, proj) / scale[:, None] if np.all(np.abs(np.diag(Ra)) > 1e-14) else (
            np.linalg.lstsq(A, self.Yr, rcond=None)[0]
        )
        return self.Yr - Qa @ proj, c, Qa

    def _projected(self, lam: np.ndarray, c: np.ndarray, Qa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The basis derivatives off the basis' span and the coefficients they multiply.

        Mode r's parameter p moves only mode r's two basis columns, so its Kaufman column is
        ``-(I - Q Qᵀ) U_rp C_r``: ``U_rp`` (2 n_f, 2) the real-stacked derivatives of the two columns, ``C_r``
        (2, k) their coefficients. Returns ``Ũ`` (2 n_f, n_modes, 2, 2) and ``C`` (n_modes, 2, k).
        """
        n = lam.size
        d1, d2 = _basis_derivatives(lam, self.f, self.form)
        U = np.stack([d1, d2], axis=3)  # (n_f, n, 2 parameters, 2 columns)
        flat = np.concatenate([U.real, U.imag], axis=0).reshape(2 * self.f.size, -1)
        flat = flat - Qa @ (Qa.T @ flat)
        return flat.reshape(2 * self.f.size, n, 2, 2), np.stack([c[:n], c[n : 2 * n]], axis=1)

    def jacobian(self, lam: np.ndarray, c: np.ndarray, Qa: np.ndarray) -> np.ndarray:
        """d(residual)/d(f_r [Hz], ζ_r), Kaufman's approximation, shape (2 n_f · k, 2 n_modes)."""
        U, C = self._projected(lam, c, Qa)
        J = -np.einsum("xrpa,rak->xkpr", U, C, optimize=True)
        return J.reshape(U.shape[0] * C.shape[2], 2 * lam.size)

    def normal_equations(self, lam: np.ndarray, c: np.ndarray, Qa: np.ndarray, res: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """``JᵀJ`` and ``Jᵀ r`` of :meth:`jacobian` without forming J (its columns are rank two, see
        :meth:`_projected`): O(n_f · n_modes²) instead of O(n_f · k · n_modes²)."""
        n = lam.size
        U, C = self._projected(lam, c, Qa)
        flat = U.reshape(U.shape[0], -1)
        G = (flat.T @ flat).reshape(n, 2, 2, n, 2, 2)
        CC = np.einsum("rak,sbk->rasb", C, C)
        JtJ = np.einsum("rpasqb,rasb->prqs", G, CC, optimize=True).reshape(2 * n, 2 * n)
        Jtr = -np.einsum("rpak,rak->pr", (flat.T @ res).reshape(n, 2, 2, -1), C).reshape(2 * n)
        return JtJ, Jtr

    def minimise(self, fr: np.ndarray, zr: np.ndarray, max_iter: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Levenberg-Marquardt from natural frequencies ``fr`` (Hz) and damping ratios ``zr``, shape (n_modes,).

        Returns the frequencies and poles it ends at, and the cost ``||r||²`` at the start and at the end.
        """
        n = fr.size
        evaluate = self.evaluate
        lam = pole_from_modal(fr, zr)
        r, c, Qa = evaluate(lam)
        cost0 = cost = float(np.sum(r**2))
        mu = 1e-3
        for _ in range(max_iter):
            JtJ, g = self.normal_equations(lam, c, Qa, r)
            # scale parameters: frequencies relative to f, damping relative to zeta
            D = np.concatenate([fr, zr])
            JtJ, g = JtJ * np.outer(D, D), g * D
            improved = False
            for _ in range(10):
                step = -np.linalg.solve(JtJ + mu * np.diag(np.diag(JtJ) + 1e-12), g)
                fr_new = fr * (1 + step[:n])
                zr_new = zr * np.exp(np.clip(step[n:], -1.0, 1.0))
                lam_new = pole_from_modal(fr_new, zr_new)
                r_new, c_new, Qa_new = evaluate(lam_new)
                cost_new = float(np.sum(r_new**2))
                if cost_new < cost:
                    improved = True
                    break
                mu *= 10.0
            if not improved:
                break
            rel = (cost - cost_new) / max(cost, 1e-300)
            fr, zr, lam, r, c, Qa, cost = fr_new, zr_new, lam_new, r_new, c_new, Qa_new, cost_new
            mu = max(mu / 10.0, 1e-9)
            if rel < 1e-10:
                break
        return fr, lam, cost0, cost


def refine_poles(
    frf: FRFSet,
    poles: np.ndarray,
    band: tuple[float, float] | None = None,
    residuals: bool = True,
    max_iter: int = 30,
    max_size: float = 4e7,
    check: np.ndarray | None = None,
) -> np.ndarray:
    """Refine poles by nonlinear least squares on the LSFD model (variable projection).

    Minimises ``sum_f || w_f (H_f - H_f_model) ||^2`` over the natural frequencies and damping ratios,
    with the residues and residual terms solved linearly (Golub-Pereyra variable projection, Kaufman's
    Jacobian, Levenberg-Marquardt steps) and every FRF weighted to unit RMS. The FRFs are first compressed
    onto their dominant right singular directions (as many as model columns), which keeps the signal
    subspace and drops only noise.

    Parameters
    ----------
    frf : FRFSet
    poles : ndarray of complex, shape (n_modes,)
        Starting poles (rad/s).
    band : (f_lo, f_hi) in Hz, optional
    residuals : bool
    max_iter : int
        Levenberg-Marquardt iterations.
    max_size : float
        Skip the refinement (and log it) when the Jacobian would exceed this many entries.
    check : ndarray of int, optional
        The poles whose move the 1 % rule judges (default all): a local fit's own mode, whose neighbours in the
        window only model the data around it.

    Returns
    -------
    ndarray of complex128, shape (n_modes,)
        Refined poles; the starting poles when the refinement does not reduce the misfit or moves a
        frequency by more than 1 %.
    """
    poles = np.asarray(poles, dtype=np.complex128).reshape(-1)
    n = poles.size
    if n == 0:
        return poles
    vp = VarPro.of(frf, band, residuals, n)
    if vp.Yr.shape[0] * vp.Yr.shape[1] * 2 * n > max_size:
        log.info("pole refinement skipped: %d modes on %d lines is beyond max_size", n, vp.f.size)
        return poles
    fr, zr = modal_from_pole(poles)
    fr, lam, cost0, cost = vp.minimise(fr, np.clip(zr, 1e-6, None), max_iter)
    f0, _ = modal_from_pole(poles)
    if not cost < cost0:
        return poles
    judged = slice(None) if check is None else np.asarray(check, dtype=int)
    if np.any(np.abs(fr - f0)[judged] / f0[judged] > 0.01):
        log.warning("pole refinement moved a mode by more than 1 %; keeping the estimator's poles")
        return poles
    return lam
