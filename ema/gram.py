"""The Gauss–Newton normal equations of a family window, from Gram matrices of its kernels over the lines.

Every column of the window's design and of Kaufman's Jacobian (:class:`ema.family_window.FamilyWindow`) is, over the
rows (reference i, line l), a sum of separable terms ``c_i k(ω_l)``: a coefficient per reference times one of
a few kernels of the frequency. Mode r's columns use only ``a_r = g/(jω − λ_r)``, ``b_r = g/(jω − conj λ_r)``
and their derivatives in λ; the residual terms use ``g/(jω)²`` and ``g``. So every inner product of two
columns is a sum of products of a kernel Gram entry (a sum over the lines) and a coefficient product (a sum
over the references), and the Jacobian's Gram matrix costs one (4n + 2)² Gram of the kernels over the lines
instead of a product of the (2 n_in n_lines) × 4 n n_in Jacobian with itself: on a window of the bundled
18-blade assembly test (6 references, 1399 lines, 22 modes) the normal equations with their least-squares solve
take about 100 ms instead of 306 ms on 2 cores.

The real inner product of two stacked vectors [Re z; Im z] is Re(zᴴw), which is what the sums below take.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

__all__ = ["gauss_newton", "weighted_blocks"]

# the kernels of mode r, in this order, and the coefficient slots of a column
_A, _B, _DA, _DB = range(4)


def _pole_derivatives(lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dλ/df (f in Hz) and dλ/d log ζ, each shape (n,)."""
    w = np.abs(lam)
    zeta = -lam.real / w
    root = np.sqrt(1.0 - zeta**2)
    return 2 * np.pi * (-zeta + 1j * root), w * (-1.0 - 1j * zeta / root) * zeta


def _coefficients(lam: np.ndarray, part: np.ndarray, pivot: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Each mode's design and Jacobian columns as coefficients on its four kernels, per reference.

    Returns
    -------
    WC : ndarray of complex, shape (n, 2, 4, n_in)
        The columns Re ψ_r and Im ψ_r of the design.
    WD : ndarray of complex, shape (n, 4 n_in, 4, n_in)
        The derivatives of those two columns (interleaved: d1, d2) in f, log ζ, then Re and Im of each
        non-pivot participation, in :meth:`ema.family_window.FamilyWindow.gauss_newton`' order.
    """
    ni, n = part.shape
    P = part.T                                                      # (n, n_in)
    WC = np.zeros((n, 2, 4, ni), complex)
    WC[:, 0, _A], WC[:, 0, _B] = P, P.conj()
    WC[:, 1, _A], WC[:, 1, _B] = 1j * P, -1j * P.conj()
    WD = np.zeros((n, 4 * ni, 4, ni), complex)
    for j, dl in enumerate(_pole_derivatives(lam)):
        A_, B_ = P * dl[:, None], P.conj() * np.conj(dl)[:, None]
        WD[:, 2 * j, _DA], WD[:, 2 * j, _DB] = A_, B_
        WD[:, 2 * j + 1, _DA], WD[:, 2 * j + 1, _DB] = 1j * A_, -1j * B_
    free = np.ones((n, ni), bool)
    free[np.arange(n), pivot] = False
    r, i = np.nonzero(free)                                         # each mode's free references, ascending
    c = 4 + 4 * (np.cumsum(free, axis=1)[r, i] - 1)                 # Re l_i: d1, d2; Im l_i: d1, d2
    for k, (ca, cb) in enumerate(((1, 1), (1j, -1j), (1j, -1j), (-1, -1))):
        WD[r, c + k, _A, i], WD[r, c + k, _B, i] = ca, cb
    return WC, WD


def _mode_gram(Gm: np.ndarray, WA: np.ndarray, WB: np.ndarray) -> np.ndarray:
    """Re of the inner products of mode columns ``WA`` (n, ca, 4, n_in) with ``WB`` (n, cb, 4, n_in), given the
    kernels' Gram ``Gm`` (4, n, 4, n); shape (n, ca, n, cb)."""
    n, ca, _, ni = WA.shape
    cb = WB.shape[1]
    # T[r, k, i, s, d] = Σ_q Gm[k, r, q, s] WB[s, d, q, i], as one product per s
    T = np.matmul(Gm.transpose(3, 1, 0, 2).reshape(n, 4 * n, 4), WB.transpose(0, 2, 1, 3).reshape(n, 4, cb * ni))
    T = T.reshape(n, n, 4, cb, ni).transpose(1, 2, 4, 0, 3).reshape(n, 4 * ni, n * cb)
    return np.matmul(WA.conj().reshape(n, ca, 4 * ni), T).real.reshape(n, ca, n, cb)


def _residual_gram(Gmr: np.ndarray, WA: np.ndarray) -> np.ndarray:
    """Re of the inner products of mode columns ``WA`` (n, ca, 4, n_in) with the residual-term columns (reference
    i, then each residual kernel), given the kernels' cross Gram ``Gmr`` (4, n, n_res); shape (n, ca, n_res n_in)."""
    n, ca, _, ni = WA.shape
    return np.einsum("rcki,krp->rcip", WA.conj(), Gmr).real.reshape(n, ca, Gmr.shape[2] * ni)


def gauss_newton(kernels: tuple[np.ndarray, ...], residual_kernels: np.ndarray, part: np.ndarray,
                 pivot: np.ndarray, lam: np.ndarray, res: np.ndarray, coef: np.ndarray, R: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Newton matrix JᵀJ and gradient Jᵀr of the variable-projection cost (as the explicit Jacobian gives).

    Parameters
    ----------
    kernels : (a, b, da, db), each ndarray of complex, shape (n, n_lines)
        ``g/(jω − λ_r)``, the same for conj λ_r, and their derivatives in λ_r (g = (jω)^k of the FRF form).
    residual_kernels : ndarray of complex, shape (n_res, n_lines)
        ``g/(jω)²`` and ``g`` (and the same times j, for complex residual terms).
    part : ndarray of complex, shape (n_in, n)
        Participations, 1 at each mode's ``pivot`` reference.
    pivot : ndarray of int, shape (n,)
    lam : ndarray of complex, shape (n,)
        Poles (rad/s).
    res : ndarray, shape (2 n_in n_lines, n_out)
        The least-squares residual at these poles, rows [Re; Im] of (reference, line).
    coef : ndarray, shape (2 n + n_res n_in, n_out)
        The least-squares coefficients: Re ψ, Im ψ, residual terms.
    R : ndarray, shape (2 n + n_res n_in, 2 n + n_res n_in)
        The triangular factor of the design's QR.

    Returns
    -------
    JJ : ndarray, shape (n p, n p)
        p = 2 n_in parameters per mode: f (Hz), log ζ, Re and Im of the non-pivot participations.
    grad : ndarray, shape (n p,)
    """
    a, b, da, db = kernels
    ni, n = part.shape
    K = np.vstack([a, b, da, db])                                   # (4n, n_lines)
    Gk = K.conj() @ np.vstack([K, residual_kernels]).T              # (4n, 4n + n_res)
    Gm, Gmr = Gk[:, :4 * n].reshape(4, n, 4, n), Gk[:, 4 * n:].reshape(4, n, -1)
    WC, WD = _coefficients(lam, part, pivot)
    m2 = WD.shape[0] * WD.shape[1]
    DD = _mode_gram(Gm, WD, WD).reshape(m2, m2)
    # the design's rows of CᵀD: Re ψ of every mode, Im ψ of every mode, then the residual terms
    CD = np.vstack([_mode_gram(Gm, WC, WD).transpose(1, 0, 2, 3).reshape(2 * n, m2),
                    _residual_gram(Gmr, WD).reshape(m2, -1).T])
    QD = solve_triangular(R, CD, trans="T", check_finite=False)     # Qᵀ D, since C = Q R
    G = (DD - QD.T @ QD).reshape(m2 // 2, 2, m2 // 2, 2)            # EᵀE, E = P⊥ D
    M = np.stack([coef[:n], coef[n:2 * n]], axis=1)                 # (n, 2, n_out)
    JJ = weighted_blocks(G, M)
    # Eᵀr = Dᵀr, as Qᵀr = 0 for the least-squares residual; and Σ_o (D_{k,a}ᵀ r_o) M[r, a, o] = D_{k,a}ᵀ ρ_{r,a} with
    # ρ_{r,a} = Σ_o r_o M[r, a, o]: one real product over the outputs first, then the kernels per mode. The kernels'
    # product with every output's residual took 128 ms of 242 on a 50-mode, 192-output window.
    lines = a.shape[1]
    rho = res @ M.reshape(2 * n, -1).T                              # (rows, 2n): columns (mode, a)
    rho = (rho[:ni * lines] + 1j * rho[ni * lines:]).reshape(ni, lines, n, 2).transpose(2, 1, 0, 3)
    Z = np.matmul(K.conj().reshape(4, n, lines).transpose(1, 0, 2), rho.reshape(n, lines, 2 * ni))
    grad = -np.einsum("rpaki,rkia->rp", WD.conj().reshape(n, 2 * ni, 2, 4, ni), Z.reshape(n, 4, ni, 2))
    return 0.5 * (JJ + JJ.T), grad.real.reshape(-1)


def weighted_blocks(G: np.ndarray, M: np.ndarray) -> np.ndarray:
    """JᵀJ from the projected derivative columns' Gram ``G`` (n p, 2, n p, 2) and the coefficients ``M`` (n, 2,
    n_out): entry (k, l) is Σ_ab G[k, a, l, b] (M_r[a] · M_s[b]) for k's mode r and l's mode s; shape (n p, n p).

    Four products of strided blocks, not an einsum over the owners' expanded (n p, n p, 2, 2) coefficient
    products: 1.7 ms instead of 8.7 ms for 30 modes of 12 parameters."""
    n = M.shape[0]
    p = G.shape[0] // n
    flat = M.transpose(1, 0, 2).reshape(2 * n, -1)                  # rows (a, mode)
    N = (flat @ flat.T).reshape(2, n, 2, n).transpose(1, 3, 0, 2)   # (n, n, 2, 2): a product, not an einsum
    Gs = G.reshape(n, p, 2, n, p, 2)
    JJ = sum(Gs[:, :, a, :, :, b] * N[:, None, :, None, a, b] for a in range(2) for b in range(2))
    return JJ.reshape(n * p, n * p)
