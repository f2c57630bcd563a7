"""A family window's shapes re-estimated output by output, each FRF weighted by its own noise.

The structured fit (:func:`ema.family.fit_family`) finds the poles and participations on FRFs divided by a
rank-one weighting ``a_o b_i`` (:func:`ema.fit_noise.rank_one_scale`): one design for every output, so the shapes
are one solve. But the noise of a full-assembly test is not rank one. Near a hammer, the in-plane outputs of the
struck blade see a mass line about 1000 times the resonances, and its noise with it, while the same outputs
hammered from other blades are quiet; ``a_o b_i`` weights those FRFs alike. On a 48-blade campaign the shape
entries there came out 10 times their truth with arbitrary phase (411.9 Hz: 0.20 against 0.023, with true poles
too), and the mean shape MAC was 0.65; without the in-plane outputs it was 0.88 (design §8.63).

Given the poles and participations, each output's shape is a weighted least-squares problem of its own, with
weight ``1/σ_oi²`` per reference (σ: :func:`ema.fit_noise.band_floor`, over the whole band, not the window). The
residual terms belong to one FRF each, so they are projected out reference by reference, where the weight is a
constant; with the projected design ``C̃ = Q R`` (one QR for the window) output o solves
``(Σ_i w_oi Q_iᵀ Q_i) z = Σ_i w_oi Q_iᵀ ỹ_oi`` and ``R x = z`` (``Q_i``: Q's rows of reference i). The first
matrix lies between ``min_i w_oi I`` and ``max_i w_oi I`` since ``Σ_i Q_iᵀ Q_i = I``: the solve is no worse
conditioned than the weights' spread, and the back substitution no worse than the unweighted fit's.
"""

from __future__ import annotations

import numpy as np

from .family_window import FamilyWindow
from .frf import FRFSet
from .lsfd import triangular_solve

__all__ = ["reweighted_residues"]


def reweighted_residues(frf: FRFSet, window: tuple[float, float], poles: np.ndarray, residues: np.ndarray,
                        floor: np.ndarray, complex_residuals: bool = False) -> np.ndarray:
    """Rank-one residues ``ψ_r l_rᵀ`` with each ψ_r re-estimated output by output on noise-weighted FRFs.

    Parameters
    ----------
    frf : FRFSet
        The unweighted FRFs the window was fitted to.
    window : (f_lo, f_hi)
        The window's lines (Hz).
    poles : ndarray of complex, shape (n,)
        The window's poles (rad/s).
    residues : ndarray of complex, shape (n, n_outputs, n_inputs)
        The structured fit's rank-one residues; only their participations ``l_r`` (row space) are used.
    floor : ndarray of float, shape (n_outputs, n_inputs)
        Each FRF's noise σ (:func:`ema.fit_noise.band_floor`).
    complex_residuals : bool
        As the fit had (:class:`ema.family_window.FamilyWindow`).

    Returns
    -------
    ndarray of complex, shape (n, n_outputs, n_inputs)
    """
    n = poles.size
    if n == 0:
        return residues
    win = FamilyWindow(frf, window, complex_residuals)
    ni, L = win.n_in, win.n_lines
    # each mode's participations up to a factor (ψ takes it): its residues' row at the output that sees it most
    strongest = np.argmax(np.sum(np.abs(residues), axis=2), axis=1)
    part = residues[np.arange(n), strongest, :].T                      # (n_in, n)
    C = win.design(poles, part)
    rows = [np.r_[i * L:(i + 1) * L, (ni + i) * L:(ni + i + 1) * L] for i in range(ni)]
    # the residual terms of reference i live on its rows only, with the same kernels for every reference: one
    # basis of them over a reference's rows projects them out everywhere
    n_res = win.residual_bases.shape[0]
    Qr = np.linalg.qr(C[rows[0]][:, 2 * n:2 * n + n_res])[0]
    Ct, Yt = np.empty((2 * ni * L, 2 * n)), np.empty_like(win.Y)
    for rw in rows:
        Cm, Y = C[rw, :2 * n], win.Y[rw]
        Ct[rw], Yt[rw] = Cm - Qr @ (Qr.T @ Cm), Y - Qr @ (Qr.T @ Y)
    Q, R = np.linalg.qr(Ct)
    QQ = np.stack([Q[rw].T @ Q[rw] for rw in rows])                    # (n_in, 2n, 2n)
    QY = np.stack([Q[rw].T @ Yt[rw] for rw in rows])                   # (n_in, 2n, n_out)
    w = 1.0 / floor**2                                                 # (n_out, n_in)
    w = w / np.max(w, axis=1, keepdims=True)                           # per output: only the ratios matter
    S = np.einsum("oi,iab->oab", w, QQ)
    t = np.einsum("oi,iao->oa", w, QY)
    z = np.linalg.solve(S, t[:, :, None])[:, :, 0]                     # (n_out, 2n)
    coef = triangular_solve(R, z.T)
    psi = coef[:n] + 1j * coef[n:]                                     # (n, n_out)
    return psi[:, :, None] * part.T[:, None, :]
