"""One family window's FRFs as a real least-squares problem for the structured fit of :mod:`ema.family`.

For given poles and participations the design holds each mode's two columns (Re ψ, Im ψ: its shape over the
outputs) and the residual terms; the shapes are one linear solve shared by every output (variable
projection). :meth:`FamilyWindow.gauss_newton` gives the refinement its Gauss–Newton matrix and gradient from
the kernels' Gram matrices (:mod:`ema.gram`); :meth:`FamilyWindow.scores` forms Kaufman's Jacobian explicitly,
for the sandwich covariance and as the reference the Gram route is tested against.
"""

from __future__ import annotations

import numpy as np

from .frf import FRF_FORMS, FRFSet
from .gram import gauss_newton, weighted_blocks
from .lsfd import nearly_dependent, triangular_solve

__all__ = ["FamilyWindow"]


class FamilyWindow:
    """The FRFs of one window as a real least-squares problem: rows (re/im, reference, line), columns outputs."""

    def __init__(self, frf: FRFSet, window: tuple[float, float], complex_residuals: bool = False):
        sel = frf.valid_lines() & (frf.freq_hz >= window[0]) & (frf.freq_hz <= window[1]) & (frf.freq_hz > 0)
        self.freq = frf.freq_hz[sel]
        self.jw = 2j * np.pi * self.freq
        self.power = FRF_FORMS[frf.form]
        H = frf.H[:, :, sel]
        self.n_out, self.n_in, self.n_lines = H.shape
        Y = H.transpose(1, 2, 0).reshape(self.n_in * self.n_lines, self.n_out)
        self.Y = np.vstack([Y.real, Y.imag])
        g = self.jw**self.power
        # the residual terms' kernels over g: the mass and stiffness lines (real coefficients), and with
        # complex_residuals the same times j, so that each FRF's two terms take any phase
        bases = [1.0 / self.jw**2, np.ones_like(self.jw)]
        self.residual_bases = np.array(bases + [1j * b for b in bases] if complex_residuals else bases)
        cols = []
        for i in range(self.n_in):
            for base in self.residual_bases:
                c = np.zeros((self.n_in, self.n_lines), complex)
                c[i] = base * g
                cols.append(c.ravel())
        self.residual_cols = np.array(cols).T

    def kernels(self, lam: np.ndarray) -> tuple[np.ndarray, ...]:
        """(jω)^k/(jω − λ), the same for conj λ, and their derivatives in λ; each shape (n_modes, n_lines)."""
        g = self.jw[None, :] ** self.power
        d, dc = self.jw[None, :] - lam[:, None], self.jw[None, :] - lam.conj()[:, None]
        return g / d, g / dc, g / d**2, g / dc**2

    def design(self, lam: np.ndarray, part: np.ndarray) -> np.ndarray:
        """Real design matrix, shape (2 n_in n_lines, 2 n_modes + n_res n_in): Re ψ, Im ψ, residual terms (n_res of
        ``residual_bases`` per reference)."""
        a, b, _, _ = self.kernels(lam)
        n = lam.size
        pa = part.T[:, :, None] * a[:, None, :]
        pb = part.conj().T[:, :, None] * b[:, None, :]
        C = np.concatenate([(pa + pb).reshape(n, -1).T, (1j * (pa - pb)).reshape(n, -1).T, self.residual_cols],
                           axis=1)
        return np.vstack([C.real, C.imag])

    def solve(self, lam: np.ndarray, part: np.ndarray
              ) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(cost ½‖r‖², residual (rows, n_out), coefficients (columns, n_out), Q and R of the design)."""
        Q, R = np.linalg.qr(self.design(lam, part))
        QtY = Q.T @ self.Y
        res = self.Y - Q @ QtY
        coef = triangular_solve(R, QtY)    # lstsq's SVD took 6.5 of a 24-blade fit's 113 s
        return 0.5 * float(np.sum(res**2)), res, coef, Q, R

    def gauss_newton(self, lam: np.ndarray, part: np.ndarray, pivot: np.ndarray, solved: tuple | None = None
                     ) -> tuple[float, np.ndarray, np.ndarray]:
        """Cost, Gauss–Newton matrix JᵀJ and gradient Jᵀr in (f Hz, log ζ, Re/Im l without the pivot) per mode,
        from the kernels' Gram matrices (:func:`ema.gram.gauss_newton`); :meth:`scores` forms the Jacobian.
        ``solved``: :meth:`solve`'s answer at the same poles and participations, if the caller has it."""
        cost, res, coef, _, R = solved if solved is not None else self.solve(lam, part)
        # where a design column nearly depends on the others (two equal poles) the Gram route's Qᵀ D = R⁻ᵀ Cᵀ D
        # loses the digits, and the Jacobian is formed row by row instead
        if nearly_dependent(R):
            JJ, per = self.scores(lam, part, pivot, np.zeros((0, *self.Y.shape)))
            return cost, JJ, per[0].sum(axis=0)
        g = self.jw**self.power
        JJ, grad = gauss_newton(self.kernels(lam), self.residual_bases * g, part, pivot, lam, res, coef, R)
        return cost, JJ, grad

    def scores(self, lam: np.ndarray, part: np.ndarray, pivot: np.ndarray, draws: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """Gauss–Newton matrix JᵀJ (as :meth:`gauss_newton`) and each spectral line's share of the gradient, for
        the sandwich covariance of :func:`ema.family.fit_family`: for the fit's residual and then each of
        ``draws`` (residuals drawn from a noise model, shape (n_draws, rows, n_out)); shape (1 + n_draws,
        n_lines, n_parameters).

        Kaufman's variable-projection Jacobian of parameter k of mode r is ``−P⊥ (d1_k x_rᵀ + d2_k y_rᵀ)``
        (d1, d2: the derivatives of mode r's two design columns; x_r, y_r: its rows Re ψ_r, Im ψ_r of the
        coefficients), rank two over the outputs, so JᵀJ is assembled from 2 × 2 blocks.
        """
        _, res, coef, Q, _ = self.solve(lam, part)
        n, ni = lam.size, self.n_in
        a, b, da, db = self.kernels(lam)
        w = np.abs(lam)
        zeta = -lam.real / w
        root = np.sqrt(1.0 - zeta**2)
        k = 2 * ni                      # parameters per mode: f, log ζ, Re and Im of the non-pivot participations
        d1 = np.empty((n, k, ni * self.n_lines), complex)
        d2 = np.empty_like(d1)
        P = part.T[:, :, None]
        # dλ/df (f in Hz) and dλ/d log ζ
        for j, dl in enumerate((2 * np.pi * (-zeta + 1j * root), w * (-1.0 - 1j * zeta / root) * zeta)):
            A_, B_ = P * (da * dl[:, None])[:, None, :], P.conj() * (db * np.conj(dl)[:, None])[:, None, :]
            d1[:, j] = (A_ + B_).reshape(n, -1)
            d2[:, j] = (1j * (A_ - B_)).reshape(n, -1)
        eye = np.eye(ni)[None, :, :, None]
        free = np.ones((n, ni), bool)
        free[np.arange(n), pivot] = False
        s = (eye * (a + b)[:, None, None, :])[free].reshape(n, ni - 1, ni * self.n_lines)
        d = (eye * (a - b)[:, None, None, :])[free].reshape(n, ni - 1, ni * self.n_lines)
        d1[:, 2::2], d2[:, 2::2] = s, 1j * d        # d/d Re l_i of the Re ψ and Im ψ columns
        d1[:, 3::2], d2[:, 3::2] = 1j * d, -s       # d/d Im l_i
        m = n * k
        D1, D2 = d1.reshape(m, -1).T, d2.reshape(m, -1).T
        D = np.empty((self.Y.shape[0], 2 * m))
        D[:, 0::2] = np.vstack([D1.real, D1.imag])
        D[:, 1::2] = np.vstack([D2.real, D2.imag])
        E = D - Q @ (Q.T @ D)
        G = (E.T @ E).reshape(m, 2, m, 2)
        M = np.stack([coef[:n], coef[n:2 * n]], axis=1)          # (n, 2, n_out)
        JJ = weighted_blocks(G, M)
        Er = E.reshape(-1, m, 2)

        def per_line(r: np.ndarray) -> np.ndarray:    # one residual at a time: bounded memory
            RM = np.einsum("xo,rao->xra", r, M)                              # (rows, n, 2)
            per_row = -np.einsum("xka,xka->xk", Er, RM[:, np.repeat(np.arange(n), k), :])
            return per_row.reshape(2, self.n_in, self.n_lines, m).sum(axis=(0, 1))

        return JJ, np.stack([per_line(r) for r in (res, *draws)])
