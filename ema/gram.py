"""The Gauss–Newton normal equations of a family window, from Gram matrices of its kernels over the lines.

Every column of the window's design and of Kaufman's Jacobian (:class:`ema.family_window.FamilyWindow`) is, over the
rows (reference i, line l), a sum of separable terms ``c_i k(ω_l)``: a coefficient per reference times one of
a few kernels of the frequency. Mode r's columns use only ``a_r = g/(jω − λ_r)``, ``b_r = g/(jω − conj λ_r)``
and their derivatives in λ; the residual terms use ``g/(jω)²`` and ``g``. So every inner product of two
columns is a sum of products of a kernel Gram entry (a sum over the lines) and a coefficient product (a sum
over the references), and the Jacobian's Gram matrix costs one (4n + 2)² Gram of the kernels over the lines
instead of a product of the (2 n_in n_lines) × 4 n n_in Jacobian with itself: on a window of the bundled
18-blade assembly test (6 references, 1399 lines, 22 modes) the normal equations with their least-squares solve
take about 100 ms instead of 306 ms on 2 cores. Most columns are mostly zero: a participation's sit on one
reference, and the pole's and the design's are a coefficient times the participations. So the mode blocks are
summed over the references first (:func:`_mode_grams`), a few n × n products instead of products over every
reference (3× faster on a 50-mode window of 6 references).

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


#: A participation column's coefficients on the kernels a and b, for Re l_i (d1, d2) then Im l_i (d1, d2)
_PART = np.array([[1, 1], [1j, -1j], [1j, -1j], [-1, -1]])


def _free_references(pivot: np.ndarray, n_in: int) -> np.ndarray:
    """Each mode's references other than its pivot, ascending (its participations that are parameters); shape
    (n, n_in − 1)."""
    ref = np.broadcast_to(np.arange(n_in), (pivot.size, n_in))
    return np.sort(np.where(ref == pivot[:, None], n_in, ref), axis=1)[:, :n_in - 1]


def _pole_columns(lam: np.ndarray) -> tuple[tuple, tuple]:
    """The pole-type columns of every mode, as (k, k', x, y): column c of mode r holds ``x[r, c] P[r, i]`` on
    kernel k and ``y[r, c] conj(P[r, i])`` on kernel k' at every reference i.

    Returns
    -------
    design : tuple
        The design's Re ψ_r and Im ψ_r, on kernels a and b; x and y of shape (n, 2).
    derivatives : tuple
        Their derivatives in f and log ζ (d1, d2 interleaved), on kernels da and db; x and y of shape (n, 4).
    """
    n = lam.size
    d_f, d_z = _pole_derivatives(lam)
    design = (_A, _B, np.broadcast_to(np.array([1, 1j]), (n, 2)), np.broadcast_to(np.array([1, -1j]), (n, 2)))
    derivatives = (_DA, _DB, np.stack([d_f, 1j * d_f, d_z, 1j * d_z], axis=1),
                   np.stack([d_f.conj(), -1j * d_f.conj(), d_z.conj(), -1j * d_z.conj()], axis=1))
    return design, derivatives


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
    WD = np.zeros((n, 4 * ni, 4, ni), complex)
    for W, (k1, k2, x, y) in zip((WC, WD[:, :4]), _pole_columns(lam), strict=True):
        for c in range(0, x.shape[1], 2):
            # each d2 column is i times its d1 column on the first kernel, −i times it on the second (as x and y
            # say); multiplied this way round, the columns keep the bits they had before _pole_columns
            W[:, c, k1], W[:, c, k2] = P * x[:, c, None], P.conj() * y[:, c, None]
            W[:, c + 1, k1], W[:, c + 1, k2] = 1j * W[:, c, k1], -1j * W[:, c, k2]
    r, i = np.repeat(np.arange(n), ni - 1), _free_references(pivot, ni).ravel()
    c = 4 + 4 * np.tile(np.arange(ni - 1), n)                       # Re l_i: d1, d2; Im l_i: d1, d2
    for k, (ca, cb) in enumerate(_PART):
        WD[r, c + k, _A, i], WD[r, c + k, _B, i] = ca, cb
    return WC, WD


def _pole_pole(Gm: np.ndarray, SV: tuple, left: tuple, right: tuple) -> np.ndarray:
    """Re of the inner products of two sets of pole-type columns; shape (n, ca, n, cb).

    A pole-type column c of mode r holds ``x[r, c] P[r, i]`` on kernel k and ``y[r, c] conj(P[r, i])`` on kernel
    k' for every reference i (``left`` = (k, k', x, y), x and y of shape (n, ca); ``right`` likewise). Summed over
    the references first, each pair of kernels takes one of S = conj(P) Pᵀ and V = P Pᵀ (``SV``) or their
    conjugates.
    """
    k1, k2, x, y = left
    q1, q2, u, v = right
    S, V = SV
    terms = ((Gm[k1, :, q1] * S, x.conj(), u), (Gm[k1, :, q2] * V.conj(), x.conj(), v),
             (Gm[k2, :, q1] * V, y.conj(), u), (Gm[k2, :, q2] * S.conj(), y.conj(), v))
    return sum(np.einsum("rs,rc,sd->rcsd", g, l, m) for g, l, m in terms).real


def _pole_part(Gm: np.ndarray, Pf: np.ndarray, left: tuple) -> np.ndarray:
    """Re of the inner products of pole-type columns (``left``, as :func:`_pole_pole`) with every mode's
    participation columns (``_PART`` on kernels a and b, at one reference each); ``Pf[r, s, m]`` is mode r's
    participation at mode s's m-th free reference. Shape (n, ca, n, n_free, 4)."""
    k1, k2, x, y = left
    out = 0
    for k, coef, p in ((k1, x.conj(), Pf.conj()), (k2, y.conj(), Pf)):
        H = Gm[k, :, _A][:, :, None] * _PART[:, 0] + Gm[k, :, _B][:, :, None] * _PART[:, 1]   # (n, n, 4)
        out = out + coef[:, :, None, None, None] * (p[:, None, :, :, None] * H[:, None, :, None, :])
    return out.real


def _mode_grams(Gm: np.ndarray, part: np.ndarray, pivot: np.ndarray, lam: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """The mode blocks of DᵀD and CᵀD, from the structure of the columns (:func:`_coefficients`' WD and WC).

    A mode's derivative columns in f and log ζ, and its design columns Re ψ and Im ψ, are pole-type
    (:func:`_pole_columns`, :func:`_pole_pole`); a participation's columns sit on one reference, so two of them
    meet only on a common reference, where their product does not depend on it. Each block is then a few products
    of size n², not a product over the references of columns that are mostly zero: on a 50-mode window of a
    48-blade test (6 references) those products took 16 of the fit's 61 s.

    Returns
    -------
    DD : ndarray, shape (n, 4 n_in, n, 4 n_in)
    CD : ndarray, shape (n, 2, n, 4 n_in)
        In the column order of WD and WC.
    """
    ni, n = part.shape
    P = part.T
    SV = (P.conj() @ P.T, P @ P.T)
    design, poles = _pole_columns(lam)
    free = _free_references(pivot, ni)                                                       # (n, n_in - 1)
    Pf = P[:, free]                                                       # (n, n, n_in - 1): P[r, free[s, m]]
    m = 4 * (ni - 1)
    pq = _pole_part(Gm, Pf, poles).reshape(n, 4, n, m)
    qq = np.einsum("jk,jrls,lm->rksm", _PART.T.conj(), Gm[:2, :, :2], _PART.T).real          # (n, 4, n, 4)
    DD = np.empty((n, 4 + m, n, 4 + m))
    DD[:, :4, :, :4] = _pole_pole(Gm, SV, poles, poles)
    DD[:, :4, :, 4:] = pq
    DD[:, 4:, :, :4] = pq.transpose(2, 3, 0, 1)
    # two participations meet on a common reference only, where their product does not depend on it
    DD[:, 4:, :, 4:] = 0.0
    block = DD[:, 4:, :, 4:].reshape(n, ni - 1, 4, n, ni - 1, 4)          # a view: filled in place
    for i in range(ni):
        R, at = np.nonzero(free == i)                     # the modes whose reference i is free, and its place
        block[R[:, None], at[:, None], :, R[None, :], at[None, :], :] = qq[R][:, :, R].transpose(0, 2, 1, 3)
    cd = _pole_part(Gm, Pf, design).reshape(n, 2, n, m)
    return DD, np.concatenate([_pole_pole(Gm, SV, design, poles), cd], axis=3)


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
    WD = _coefficients(lam, part, pivot)[1]
    m2 = WD.shape[0] * WD.shape[1]
    DDm, CDm = _mode_grams(Gm, part, pivot, lam)
    DD = DDm.reshape(m2, m2)
    # the design's rows of CᵀD: Re ψ of every mode, Im ψ of every mode, then the residual terms
    CD = np.vstack([CDm.transpose(1, 0, 2, 3).reshape(2 * n, m2),
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
    # summed in place, in the order of Python's sum over (a, b): the same bits, without its temporaries
    JJ = Gs[:, :, 0, :, :, 0] * N[:, None, :, None, 0, 0]
    for a, b in ((0, 1), (1, 0), (1, 1)):
        JJ += Gs[:, :, a, :, :, b] * N[:, None, :, None, a, b]
    return JJ.reshape(n * p, n * p)
