"""Least-squares rational fraction (LSRF) estimator with a discrete-orthonormal polynomial basis.

Model (common denominator, complex coefficients, in the normalised frequency ``x = (omega - omega_c)/omega_h``
that maps the band onto [-1, 1])::

    H_f(x_k) = N_f(x_k) / D(x_k),   N_f(x) = sum_j b_fj q_j(x),   D(x) = sum_j a_j q_j(x)

The basis ``q_0 .. q_n`` is orthonormal on the measured lines (``Q^T Q = I``), built by the Stieltjes /
Arnoldi process with full re-orthogonalisation ("Vandermonde with Arnoldi", the discrete analogue of
Forsythe's orthogonal polynomials). The least-squares matrices are therefore perfectly conditioned in
the numerator part at any order, which is what makes the method usable at high orders (the monomial
rational fraction of Richardson & Formenti breaks down past order ~20).

With ``Q`` orthonormal the numerator coefficients are eliminated exactly (``b_f = Q^T diag(h_f) Q a``),
leaving ``M = Q^T diag(sum_f |h_f|^2) Q - sum_f S_f^H S_f`` with ``S_f = Q^T diag(h_f) Q``. As in the LSCF
implementation, the matrices of all orders come out of one cumulative pass over the rows of ``S_f``.
``a_n = 1`` is imposed and the roots of ``D`` are the eigenvalues of the comrade matrix (Arnoldi
Hessenberg matrix with a rank-one correction in its last column). Complex coefficients let each pole in
the band appear once (no conjugate), so order n holds up to n modes; modes outside the band are absorbed
by the numerators, which suits local (band-by-band) fitting.

Normalisation and reweighting of the complex model: with ``a_n = 1`` the noise part of the normal matrix drives the
denominator towards the polynomial orthogonal on the lines, whose roots are real: in the complex model every spare
order adds a pole with about zero damping somewhere in the band, and those poles crowd the stabilization diagram of
a dense band. Minimising ``a^H M a`` under ``D(x0) = 1`` instead gives ``a ~ M^-1 conj(q(x0))``, a kernel
(Christoffel-Darboux) polynomial whose spurious roots lie in the half-plane opposite ``x0``. A physical
pole ``lambda = -sigma + j omega_d`` sits at ``x = (omega_d - omega_c + j sigma) / omega_h`` (upper
half-plane), so ``x0 = j`` sends the noise poles to negative damping, where the diagram drops them.
Noise-free data are fitted exactly under either normalisation.

The linearised error ``D h - N`` weights each line by ``|D|``, which is small near the poles already
found: a close mode next to a found one is fitted last, after noise (Levy's bias), so dense clusters
need very high orders. Weighting the lines by ``1 / |D_s|`` (one Sanathanan-Koerner step) turns the
error near the found poles into the output error ``h - N / D_s`` and resolves such clusters at
moderate orders. Every order of the series is refitted with the same weights, so the stabilization
diagram stays a diagram of one estimator. Distances to roots closer to the axis than one line are
floored at one line, so a spurious near-axis root cannot dominate the weights.

References: Richardson & Formenti, IMAC 1 (1982) and IMAC 3 (1985); Forsythe, J. SIAM 5 (1957);
Brubeck, Nakatsukasa & Trefethen, "Vandermonde with Arnoldi", SIAM Review 63 (2021).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from tqdm import tqdm

from .frf import FRFSet
from .poles import BandData, PoleSet, band_data, check_workspace, resolve_orders, single_thread_blas

__all__ = ["lsrf", "max_supported_order", "orthonormal_basis", "evaluate_basis"]

log = logging.getLogger(__name__)


def orthonormal_basis(x: np.ndarray, n: int, weight: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Polynomials ``q_0..q_n`` orthonormal on the points ``x`` (Arnoldi with re-orthogonalisation).

    Parameters
    ----------
    x : ndarray, shape (n_points,)
        Real sample points (normalised frequencies in [-1, 1]).
    n : int
        Highest degree.
    weight : ndarray, shape (n_points,), optional
        Positive weights: the columns are then ``w(x) q_j(x)``, orthonormal in the weighted inner product
        (``q_0 = 1 / ||w||``); default all ones (``q_0 = 1 / sqrt(n_points)``).

    Returns
    -------
    Q : ndarray, shape (n_points, n + 1)
        ``Q[:, j] = w(x) q_j(x)``, ``Q^T Q = I``.
    Hs : ndarray, shape (n + 1, n)
        Recurrence (Hessenberg) matrix: ``x * Q[:, :n] = Q @ Hs``.
    """
    m = x.size
    if n + 1 > m:
        raise ValueError(f"order {n} needs at least {n + 1} lines, the band has {m}")
    Q = np.zeros((m, n + 1))
    Hs = np.zeros((n + 1, n))
    if weight is None:
        Q[:, 0] = 1.0 / np.sqrt(m)
    else:
        Q[:, 0] = weight / np.linalg.norm(weight)
    for k in range(n):
        v = x * Q[:, k]
        for _ in range(2):  # classical Gram-Schmidt, twice
            c = Q[:, : k + 1].T @ v
            v -= Q[:, : k + 1] @ c
            Hs[: k + 1, k] += c
        Hs[k + 1, k] = np.linalg.norm(v)
        Q[:, k + 1] = v / Hs[k + 1, k]
    return Q, Hs


def evaluate_basis(Hs: np.ndarray, x: np.ndarray, n: int, m_points: float) -> np.ndarray:
    """Values of ``q_0..q_n`` at arbitrary (complex) points from the recurrence matrix.

    Parameters
    ----------
    Hs : ndarray, shape (>= n + 1, >= n)
    x : ndarray, shape (n_x,)
    n : int
    m_points : float
        Number of lines the basis was built on (``q_0 = 1/sqrt(m_points)``); for a weighted basis the
        squared norm of the weights.

    Returns
    -------
    ndarray, shape (n_x, n + 1)
    """
    x = np.asarray(x, dtype=np.complex128)
    V = np.zeros((x.size, n + 1), dtype=np.complex128)
    V[:, 0] = 1.0 / np.sqrt(m_points)
    for k in range(n):
        V[:, k + 1] = (x * V[:, k] - V[:, : k + 1] @ Hs[: k + 1, k]) / Hs[k + 1, k]
    return V


def lsrf(
    frf: FRFSet,
    band: tuple[float, float] | None = None,
    max_order: int = 40,
    orders: Iterable[int] | None = None,
    normalize: bool = True,
    progress: bool = False,
    coefficients: str = "real",
    reweight: int | None = None,
) -> PoleSet:
    """Estimate poles with the LSRF method for a series of model orders.

    Parameters
    ----------
    frf : FRFSet
        Measured FRFs, shape (n_outputs, n_inputs, n_freq).
    band : (f_lo, f_hi) in Hz, optional
        Band to fit; default all finite lines.
    max_order : int
        Highest denominator order n (orders 1..n when ``orders`` is None); order n holds up to n modes. At
        most :func:`max_supported_order` of the band's size.
    orders : iterable of int, optional
        Explicit orders.
    normalize : bool
        Scale each FRF to unit RMS over the band (equal weight per FRF). Without it all FRFs are still
        scaled by one power of two, so that the normal equations neither under- nor overflow.
    progress : bool
        Show a tqdm progress bar on stderr.
    coefficients : {"real", "complex"}
        "real" (default): real polynomials in ``s = j omega``; the basis is orthonormal on the lines
        mirrored to negative frequencies, ``x = omega / omega_hi``, and poles come in conjugate pairs
        (order n holds n/2 modes). "complex": complex coefficients in ``x`` centred on the band, each
        pole once (order n holds n modes), suited to narrow local bands. The complex denominator is
        normalised by ``D(j) = 1`` (a point off the band, on the side of the stable poles) instead of a
        unit leading coefficient: the least-squares denominator is then a kernel polynomial of the noise,
        whose noise roots fall on the unstable side (negative damping) instead of on the frequency axis,
        as the noise poles of LSCF do (module notes).
    reweight : int, optional
        Sanathanan-Koerner passes (complex model only; default 2 there, 0 for "real"): each pass fits the
        highest order, then weights the lines by ``1 / |D_s(x)|``, ``D_s`` holding the stable roots it found
        in or near the band; the series of orders is fitted with the last weights (module notes).

    Returns
    -------
    PoleSet
        Poles (rad/s, positive imaginary part, natural frequency within the band) per order, with the
        numerators at the pole (``N_f(x_r)``, proportional to the residues) as vectors.

    Raises
    ------
    EMAError
        An order above :func:`max_supported_order` or one whose matrices would not fit in memory (checked
        before anything large is allocated); the data refusals of :func:`ema.poles.band_data`.
    """
    real, passes = _model(coefficients, reweight)
    data = band_data(frf, band, per="frf" if normalize else "scalar")
    n_o, n_i, n_f = data.H.shape
    h = data.H.reshape(n_o * n_i, n_f)
    n_frf = h.shape[0]
    where = f"{', '.join(frf.sources) or 'FRF set'}: LSRF ({coefficients} coefficients)"
    size = f"{n_f} lines x {n_frf} FRFs in [{data.band_hz[0]:g}, {data.band_hz[1]:g}] Hz"
    order_list = resolve_orders(max_order, orders, maximum=max_supported_order(n_f, n_frf, real),
                                why=f"{where} on {size}")
    P = order_list[-1] + 1
    # S_f for every FRF, the basis on the (mirrored) lines, T and G
    check_workspace(n_frf * P * P * (8.0 if real else 16.0) + 16.0 * n_f * P + 32.0 * P * P,
                    f"{where} at order {order_list[-1]} on {size}")
    w = 2 * np.pi * data.freq_hz
    w_lo, w_hi = 2 * np.pi * data.band_hz[0], 2 * np.pi * data.band_hz[1]
    wc, wh = (0.0, w_hi) if real else (0.5 * (w_lo + w_hi), 0.5 * (w_hi - w_lo))
    x = (w - wc) / wh
    weight = None
    for _ in range(passes):
        _, top_roots = _lsrf_pass(h, x, weight, order_list[-1:], real, data, (wc, wh), False)
        weight = _sk_weight(x, top_roots, weight)
    found, _ = _lsrf_pass(h, x, weight, order_list, real, data, (wc, wh), progress)
    return PoleSet.from_orders("lsrf", data.band_hz, order_list, found, n_frf, frf.outputs, frf.inputs)


def _model(coefficients: str, reweight: int | None) -> tuple[bool, int]:
    """Whether the model is real, and its number of Sanathanan-Koerner passes; ValueError for a bad choice."""
    if coefficients not in ("real", "complex"):
        raise ValueError(f"coefficients {coefficients!r}: expected 'real' or 'complex'")
    real = coefficients == "real"
    passes = (0 if real else 2) if reweight is None else int(reweight)
    if passes < 0 or (real and passes):
        raise ValueError(f"reweight {reweight!r}: expected >= 0, and 0 with real coefficients")
    return real, passes


def max_supported_order(n_freq: int, n_frf: int, real: bool = True) -> int:
    """Highest LSRF order n whose least-squares problem has at least as many equations as unknowns.

    Every FRF gives ``n_f`` complex equations. Real model: real numerators of ``n + 1`` coefficients per
    FRF and a real denominator of ``n`` free ones (``a_n = 1``) against ``2 n_f`` real equations per FRF:
    ``n <= n_frf (2 n_f - 1) / (n_frf + 1)``. Complex model: complex numerators of ``n + 1`` and a
    denominator of ``n`` free complex coefficients (``D(x0) = 1``) against ``n_f`` complex equations:
    ``n <= n_frf (n_f - 1) / (n_frf + 1)``. Both also keep the basis (at most as many polynomials as
    points) defined.
    """
    if real:
        return n_frf * (2 * n_freq - 1) // (n_frf + 1)
    return n_frf * (n_freq - 1) // (n_frf + 1)


def _sk_weight(x: np.ndarray, roots: np.ndarray, previous: np.ndarray | None) -> np.ndarray | None:
    """Sanathanan-Koerner line weights ``1 / |prod (x - x_r)|`` over the stable roots near the band."""
    stable = roots[np.isfinite(roots) & (roots.imag > 0) & (np.abs(roots.real) <= 1.25)]
    if stable.size == 0:
        return previous
    floor = float(np.median(np.diff(x))) if x.size > 1 else 1.0
    logd = np.sum(np.log(np.maximum(np.abs(x[:, None] - stable[None, :]), floor)), axis=1)
    return np.exp(-(logd - logd.min()))


def _comrade_roots(C: np.ndarray, real: bool) -> np.ndarray:
    """Eigenvalues (roots in x) of the comrade matrix C, shape (n, n).

    Real model: the basis is orthonormal on lines mirrored about 0, so its recurrence has a zero diagonal,
    and the denominator is a real polynomial in s = j x. Then ``C~ = j E^-1 C E`` with ``E = diag(j^k)`` is
    real and its eigenvalues are the roots in s: a real eigen-solve (about 4x cheaper than the complex one,
    which dominated LSRF) gives ``x = -j s``. Falls back to the complex solve if C~ is not real.
    """
    if real:
        n = C.shape[0]
        k = np.arange(n)
        Ct = C * (1j ** ((k[None, :] - k[:, None] + 1) % 4))
        if np.abs(Ct.imag).max() <= 1e-12 * max(np.abs(Ct.real).max(), 1e-300):
            return -1j * np.linalg.eigvals(Ct.real)
    return np.linalg.eigvals(C)


def _frf_grams(h: np.ndarray, Q: np.ndarray, real: bool) -> np.ndarray:
    """``S_f = Q^T diag(h_f) Q`` for every FRF f, shape (n_frf, P, P), in chunks of FRFs.

    Complex model: complex S_f. Real model: ``Re(j^(j-i) S_f)``, the real unknowns' matrix. There the
    phase ``j^(j-i)`` is real for even ``j - i`` and imaginary for odd ``j - i``, so the even-difference
    entries need only ``Re h`` and the odd ones only ``Im h``: splitting the basis into its even and odd
    columns needs three products of (P/2)-column blocks instead of two full ones (about 5x fewer flops;
    this is the dominant cost of LSRF).
    """
    n_frf, n_f = h.shape
    P = Q.shape[1]
    chunk = max(1, int(4e7 // (n_f * P)))

    def gram(hpart: np.ndarray, QA: np.ndarray, QB: np.ndarray) -> np.ndarray:
        # One GEMM for the whole chunk; the product is built as (n_f, c, nb) so that the reshape is free.
        c, nb = hpart.shape[0], QB.shape[1]
        X = (hpart.T[:, :, None] * QB[:, None, :]).reshape(n_f, c * nb)
        return (QA.T @ X).reshape(QA.shape[1], c, nb).transpose(1, 0, 2)

    if not real:
        S = np.empty((n_frf, P, P), dtype=np.complex128)
        for start in range(0, n_frf, chunk):
            hs = h[start : start + chunk]
            S[start : start + hs.shape[0]] = gram(hs.real, Q, Q) + 1j * gram(hs.imag, Q, Q)
        return S
    ev, od = np.arange(0, P, 2), np.arange(1, P, 2)
    d = np.arange(P)[None, :] - np.arange(P)[:, None]  # j - i
    sign_even = np.where(d % 4 == 0, 1.0, -1.0)  # Re j^d for even d
    sign_odd = -np.where(d % 4 == 1, 1.0, -1.0)  # -Im j^d for odd d: Re(j^d (a + j b)) = -Im(j^d) b
    Qe, Qo = Q[:, ev], Q[:, od]
    S = np.empty((n_frf, P, P))
    for start in range(0, n_frf, chunk):
        hs = h[start : start + chunk]
        sl = slice(start, start + hs.shape[0])
        S[sl, ev[:, None], ev[None, :]] = gram(hs.real, Qe, Qe) * sign_even[np.ix_(ev, ev)]
        S[sl, od[:, None], od[None, :]] = gram(hs.real, Qo, Qo) * sign_even[np.ix_(od, od)]
        B = gram(hs.imag, Qe, Qo)  # (c, n_even, n_odd); the (odd, even) block is its transpose
        S[sl, ev[:, None], od[None, :]] = B * sign_odd[np.ix_(ev, od)]
        S[sl, od[:, None], ev[None, :]] = B.transpose(0, 2, 1) * sign_odd[np.ix_(od, ev)]
    return S


class _Basis(NamedTuple):
    """The basis of one LSRF pass: values on the lines ``Q`` (n_f, P), recurrence ``Hs`` (P, P - 1), the norm
    ``q_0`` is built on (:func:`evaluate_basis`' ``m_points``) and the phases ``j^j`` (P,) that make the real
    model's polynomials real (ones for the complex model)."""

    Q: np.ndarray
    Hs: np.ndarray
    m_points: float
    jpow: np.ndarray


def _basis(x: np.ndarray, weight: np.ndarray | None, n_max: int, real: bool) -> _Basis:
    """The orthonormal basis of degree ``n_max`` on the normalised lines ``x`` (weighted, complex model)."""
    P = n_max + 1
    if real:
        # basis orthonormal on the symmetric lines {-w_k} U {w_k}: q_j has the parity of j and
        # psi_j = j^j q_j(w / w_hi) is a real polynomial in s = j w
        Qfull, Hs = orthonormal_basis(np.concatenate([-x[::-1], x]), n_max)
        return _Basis(Qfull[x.size:], Hs, 2.0 * x.size, 1j ** np.arange(P))
    Q, Hs = orthonormal_basis(x, n_max, weight)
    return _Basis(Q, Hs, float(x.size) if weight is None else float(np.sum(weight**2)), np.ones(P))


def _lsrf_pass(
    h: np.ndarray, x: np.ndarray, weight: np.ndarray | None, order_list: tuple[int, ...], real: bool,
    data: BandData, centre: tuple[float, float], progress: bool,
) -> tuple[list[tuple[int, np.ndarray, np.ndarray]], np.ndarray]:
    """One LSRF pass over all orders.

    Returns ``[(order, poles in the band (rad/s), numerators at them (n_r, n_frf))]`` and all the roots
    (in ``x``) of the highest order. ``centre`` is ``(omega_c, omega_h)`` with ``x = (omega - omega_c) / omega_h``.
    """
    n_max = order_list[-1]
    P = n_max + 1
    basis = _basis(x, weight, n_max, real)
    T = basis.Q.T @ (np.sum(np.abs(h) ** 2, axis=0)[:, None] * basis.Q)
    S = _frf_grams(h, basis.Q, real)
    if real:
        # real unknowns: S_f <- Re(j^(j-i) S_f) (built so by _frf_grams), numerator b_f = 2 S_f a,
        # M = T' - 2 sum S_f^T S_f; Re j^(j - i) is 0 for odd j - i, else +-1
        T = T * (basis.jpow.conj()[:, None] * basis.jpow[None, :]).real
        G = np.zeros((P, P))
    else:
        G = np.zeros((P, P), dtype=np.complex128)
    # values of the basis at the normalisation point x0 = j (complex model only); they grow like
    # (1 + sqrt 2)^j, which stays finite up to order ~800
    anchor = None if real else evaluate_basis(basis.Hs, np.array([1j]), n_max, basis.m_points)[0]
    wanted = set(order_list)
    found: list[tuple[int, np.ndarray, np.ndarray]] = []
    top_roots = np.zeros(0, complex)
    with single_thread_blas():
        bar = tqdm(total=len(order_list), desc="LSRF", unit="order", disable=not progress, leave=False)
        for row in range(P):
            Sr = S[:, row, :]
            G += Sr.conj().T @ Sr
            n = row
            if n not in wanted:
                continue
            bar.update(1)
            a = _denominator(T[: n + 1, : n + 1] - (2.0 if real else 1.0) * G[: n + 1, : n + 1], n, real, anchor)
            if a is None:
                continue
            c_coef = a * basis.jpow[: n + 1]
            C = basis.Hs[:n, :n].astype(np.complex128)
            C[:, n - 1] -= basis.Hs[n, n - 1] * c_coef[:n] / c_coef[n]
            xr = _comrade_roots(C, real)
            if n == n_max:
                top_roots = xr
            poles = _order_poles(n, xr, a, S, basis, real, data, centre)
            if poles is not None:
                found.append(poles)
        bar.close()
    return found, top_roots


def _denominator(M: np.ndarray, n: int, real: bool, anchor: np.ndarray | None) -> np.ndarray | None:
    """The denominator coefficients of order n, shape (n + 1,), from its reduced matrix M; None where the complex
    model's solution is not finite or has no leading coefficient."""
    if real:
        try:
            top = -np.linalg.solve(M[:n, :n], M[:n, n])
        except np.linalg.LinAlgError:
            top = -np.linalg.lstsq(M[:n, :n], M[:n, n], rcond=None)[0]
        return np.append(top, 1.0)
    # minimise a^H M a under D(x0) = q(x0)^T a = 1 (see the module notes)
    c0 = anchor[: n + 1] / np.linalg.norm(anchor[: n + 1])
    try:
        y = np.linalg.solve(M, c0.conj())
    except np.linalg.LinAlgError:
        y = np.linalg.lstsq(M, c0.conj(), rcond=None)[0]
    a = y / (c0 @ y)
    if not (np.all(np.isfinite(a)) and abs(a[n]) > 1e-14 * np.linalg.norm(a)):
        return None
    return a


def _order_poles(n: int, xr: np.ndarray, a: np.ndarray, S: np.ndarray, basis: _Basis, real: bool, data: BandData,
                 centre: tuple[float, float]) -> tuple[int, np.ndarray, np.ndarray] | None:
    """Order n's poles in the band (rad/s) and the numerators at them (n_r, n_frf), from the denominator's
    coefficients ``a`` and roots ``xr`` (in x); None when no root lies in the band."""
    wc, wh = centre
    f_lo, f_hi = data.band_hz
    wr = wc + wh * xr
    lam = 1j * wr
    fn = np.abs(lam) / (2 * np.pi)
    keep = (wr.real > 0) & (fn >= f_lo) & (fn <= f_hi) & np.isfinite(lam)
    lam, xr = lam[keep], xr[keep]
    if not lam.size:
        return None
    b = S[:, : n + 1, : n + 1] @ a * (2.0 if real else 1.0)  # (n_frf, n+1) numerator coefficients
    V = evaluate_basis(basis.Hs, xr, n, basis.m_points) * basis.jpow[None, : n + 1]  # (n_r, n+1)
    # undo the per-FRF weights relative to each other (vectors are defined up to a scale)
    num = (V @ b.T) / (data.scale.reshape(-1) / np.max(data.scale))[None, :]  # (n_r, n_frf)
    return n, lam, num
