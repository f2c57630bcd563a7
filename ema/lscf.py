"""Poly-reference least-squares complex frequency-domain estimator (pLSCF).

Model (right matrix-fraction, real coefficients, z-domain basis ``z_k = exp(j*omega_k*Ts)``)::

    H_o(omega_k) = B_o(z_k) A(z_k)^-1,   B_o(z) = sum_j z^j beta_oj (1 x n_i),   A(z) = sum_j z^j alpha_j (n_i x n_i)

The linearised equation error ``B_o(z_k) - H_o(omega_k) A(z_k)`` is minimised in least squares; the
numerator coefficients are eliminated (normal-equation reduction ``M = sum_o T_o - S_o^T R^-1 S_o``) and
``alpha_p = I`` is imposed. ``R``, ``S_o`` and ``T`` are Toeplitz in the coefficient index and are
built from FFTs when the lines are evenly spaced. Because the Cholesky factor of a leading block of ``R``
is the leading block of the full factor, the reduced matrices of all orders come from one pass over
rows (a cumulative sum), so a whole stabilization series costs little more than its highest order.

References: Guillaume, Verboven, Vanlanduit, Van der Auweraer, Peeters, "A poly-reference implementation
of the least-squares complex frequency-domain estimator", IMAC XXI (2003); Peeters et al., "The
PolyMAX frequency-domain method", Shock and Vibration 11 (2004).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

import numpy as np
import scipy.linalg as sla
from tqdm import tqdm

from .frf import FRFSet
from .poles import BandData, PoleSet, band_data, check_workspace, resolve_orders, single_thread_blas

__all__ = ["lscf", "max_supported_order"]

log = logging.getLogger(__name__)


def _power_sums(freq: np.ndarray, X: np.ndarray, p: int) -> tuple[np.ndarray, float]:
    """``sum_k z_k**m * X[..., k]`` for m = -p..p, and the sampling time Ts.

    Parameters
    ----------
    freq : ndarray, shape (n_freq,)
        Lines in Hz.
    X : ndarray, shape (n_series, n_freq)
    p : int
        Highest power.

    Returns
    -------
    sums : ndarray of complex128, shape (n_series, 2p + 1)
        Column ``m + p`` holds the sum for power m.
    Ts : float
        Sampling time in s (the highest line maps close to ``z = -1``).
    """
    df = np.diff(freq)
    uniform = bool(np.all(np.abs(df - df[0]) <= 1e-6 * df[0]))
    m = np.arange(-p, p + 1)
    if uniform:
        L = max(int(np.ceil(freq[-1] / df[0] - 1e-6)), freq.size, p + 1)
        n_fft = 2 * L
        if n_fft <= 1 << 22:
            Ts = 1.0 / (2.0 * L * df[0])
            theta0 = 2.0 * np.pi * freq[0] * Ts
            spec = np.fft.ifft(X, n=n_fft, axis=-1) * n_fft  # sum_k X_k exp(+2 pi j m k / n_fft)
            sums = spec[:, m % n_fft] * np.exp(1j * m * theta0)[None, :]
            return sums, Ts
    Ts = 1.0 / (2.0 * freq[-1])
    phase = 2.0 * np.pi * freq * Ts
    sums = np.empty((X.shape[0], m.size), dtype=np.complex128)
    chunk = max(1, int(2e7 // max(freq.size, 1)))
    for start in range(0, m.size, chunk):
        mm = m[start : start + chunk]
        E = np.exp(1j * np.outer(phase, mm))  # (n_freq, chunk)
        sums[:, start : start + chunk] = X @ E
    return sums, Ts


def max_supported_order(n_freq: int, n_outputs: int, n_inputs: int) -> int:
    """Highest LSCF order p whose least-squares problem has at least as many equations as unknowns.

    Each line gives ``n_o * n_i`` complex equations (``2 n_f n_o n_i`` real ones); the unknowns are the real
    numerator coefficients ``(p + 1) n_i`` per output and the denominator ``p n_i**2`` (``alpha_p = I``). So
    ``(p + 1) n_o n_i + p n_i**2 <= 2 n_f n_o n_i``, i.e. ``p <= n_o (2 n_f - 1) / (n_o + n_i)``; this also
    keeps the Gram matrix R (rank ``<= 2 n_f``) invertible.
    """
    return n_outputs * (2 * n_freq - 1) // (n_outputs + n_inputs)


def _cholesky(R: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        eps = 1e-12 * np.trace(R) / R.shape[0]
        log.info("LSCF: R not positive definite, regularising with %.3g", eps)
        return np.linalg.cholesky(R + eps * np.eye(R.shape[0]))


def lscf(
    frf: FRFSet,
    band: tuple[float, float] | None = None,
    max_order: int = 40,
    orders: Iterable[int] | None = None,
    normalize: bool = True,
    progress: bool = False,
) -> PoleSet:
    """Estimate poles with the poly-reference LSCF method for a series of model orders.

    Parameters
    ----------
    frf : FRFSet
        Measured FRFs, shape (n_outputs, n_inputs, n_freq); any form (the poles do not depend on it).
    band : (f_lo, f_hi) in Hz, optional
        Band to fit; default all finite lines.
    max_order : int
        Highest polynomial order p (orders 1..p when ``orders`` is None). Order p holds up to
        ``p * n_inputs / 2`` modes. At most :func:`max_supported_order` of the band's size.
    orders : iterable of int, optional
        Explicit orders, e.g. ``range(2, 201, 2)``.
    normalize : bool
        Scale each output to unit RMS over the band before fitting (equal weight per output). Without it
        all FRFs are still scaled by one power of two, so that the normal equations neither under- nor
        overflow: the poles do not depend on the unit of the data.
    progress : bool
        Show a tqdm progress bar on stderr.

    Returns
    -------
    PoleSet
        Poles (rad/s, positive imaginary part, natural frequency within the band) per order, with
        vectors ``vec(psi_r l_r^T)`` (psi: numerator at the pole times l, l: participation factor).

    Raises
    ------
    EMAError
        An order above :func:`max_supported_order` or one whose matrices would not fit in memory (checked
        before anything large is allocated); the data refusals of :func:`ema.poles.band_data`.
    """
    data = band_data(frf, band, per="output" if normalize else "scalar")
    H = data.H
    n_o, n_i, n_f = H.shape
    top = max_supported_order(n_f, n_o, n_i)
    where = f"{', '.join(frf.sources) or 'FRF set'}: LSCF"
    size = f"{n_f} lines x {n_o} outputs x {n_i} inputs in [{data.band_hz[0]:g}, {data.band_hz[1]:g}] Hz"
    order_list = resolve_orders(max_order, orders, maximum=top, why=f"{where} on {size}")
    p_max = order_list[-1]
    P = p_max + 1
    # power sums (rows x FFT length, complex), S/W and their complex temporaries, T and G
    n_series = 1 + n_o * n_i + n_i * n_i
    check_workspace(16.0 * n_series * 2 * max(n_f, P) + 8.0 * P * P * n_i * (4 * n_o + 2 * n_i),
                    f"{where} at order {p_max} on {size}")

    L, W, T, Ts = _reduced_matrices(data, p_max)

    G = np.zeros((P * n_i, P * n_i))
    wanted = set(order_list)
    found: list[tuple[int, np.ndarray, np.ndarray]] = []
    with single_thread_blas():
        bar = tqdm(total=len(order_list), desc="LSCF", unit="order", disable=not progress, leave=False)
        for row in range(P):
            Wr = W[row]
            G += Wr.T @ Wr
            p = row
            if p not in wanted:
                continue
            c = (p + 1) * n_i
            poles = _order_poles(p, T[:c, :c] - G[:c, :c], W, L, Ts, data)
            if poles is not None:
                found.append(poles)
            bar.update(1)
        bar.close()
    return PoleSet.from_orders("lscf", data.band_hz, order_list, found, n_o * n_i, frf.outputs, frf.inputs)


def _reduced_matrices(data: BandData, p_max: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The Cholesky factor L of R, ``W = L⁻¹ S_o`` (shape (P, n_o, P n_i)), T and the sampling time, P = p_max + 1.

    R, S_o and T are Toeplitz in the coefficient index, built from the power sums of the lines (module notes).
    """
    H = data.H
    n_o, n_i, n_f = H.shape
    P = p_max + 1
    # Power sums: r (R), s_oi (S) and t_ii' (T), all for powers -p..p.
    flat = H.reshape(n_o * n_i, n_f)
    gram = np.einsum("oaf,obf->abf", H.conj(), H).reshape(n_i * n_i, n_f)
    series = np.vstack([np.ones((1, n_f)), flat, gram])
    sums, Ts = _power_sums(data.freq_hz, series, p_max)
    r = sums[0].real
    s = sums[1 : 1 + n_o * n_i].reshape(n_o, n_i, 2 * p_max + 1)
    t = sums[1 + n_o * n_i :].reshape(n_i, n_i, 2 * p_max + 1)

    a = np.arange(P)
    D = a[None, :] - a[:, None] + p_max  # index of power (b - a)
    R = r[D]
    # S_o[a, (b, i)] = -Re s_oi[b - a]
    S = -np.transpose(s[:, :, D].real, (0, 2, 3, 1)).reshape(n_o, P, P * n_i)
    # T[(a, i), (b, i')] = Re t_ii'[b - a]
    T = np.transpose(t[:, :, D].real, (2, 0, 3, 1)).reshape(P * n_i, P * n_i)

    L = _cholesky(R)
    W = sla.solve_triangular(L, np.transpose(S, (1, 0, 2)).reshape(P, n_o * P * n_i), lower=True)
    return L, W.reshape(P, n_o, P * n_i), T, Ts


def _order_poles(p: int, M: np.ndarray, W: np.ndarray, L: np.ndarray, Ts: float, data: BandData
                 ) -> tuple[int, np.ndarray, np.ndarray] | None:
    """Order p's poles in the band and their vectors, from its reduced matrix M (shape ((p+1) n_i, (p+1) n_i));
    None when none lies in the band."""
    n_o, n_i = data.H.shape[:2]
    c = (p + 1) * n_i
    k = p * n_i
    try:
        top = -np.linalg.solve(M[:k, :k], M[:k, k:])
    except np.linalg.LinAlgError:
        top = -np.linalg.lstsq(M[:k, :k], M[:k, k:], rcond=None)[0]
    alpha = np.vstack([top, np.eye(n_i)])  # (c, n_i)
    z, lvec = _companion_roots(top, p, n_i)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.log(z.astype(np.complex128)) / Ts
    fn = np.abs(lam) / (2 * np.pi)
    f_lo, f_hi = data.band_hz
    keep = (lam.imag > 0) & (fn >= f_lo) & (fn <= f_hi) & np.isfinite(lam)
    lam, zk, lvec = lam[keep], z[keep], lvec[:, keep]
    if not lam.size:
        return None
    # numerator coefficients theta_o = -R_p^-1 S_o alpha, then psi = B(z_r) l_r
    Wa = W[: p + 1, :, :c] @ alpha  # (p+1, n_o, n_i)
    theta = -sla.solve_triangular(L[: p + 1, : p + 1].T, Wa.reshape(p + 1, n_o * n_i), lower=False)
    theta = theta.reshape(p + 1, n_o, n_i)
    Zp = zk[None, :] ** np.arange(p + 1)[:, None]  # (p+1, n_r)
    Bl = np.einsum("joi,ir,jr->or", theta, lvec, Zp)  # (n_o, n_r)
    # undo the per-output weights relative to each other (vectors are defined up to a scale)
    Bl = Bl / (data.scale / np.max(data.scale))[:, None]
    vec = (Bl[:, None, :] * lvec[None, :, :]).reshape(n_o * n_i, lam.size).T if n_i > 1 else Bl.T
    return p, lam, vec


def _companion_roots(top: np.ndarray, p: int, n_i: int) -> tuple[np.ndarray, np.ndarray]:
    """Roots z of the matrix denominator of order p (``alpha_p = I``, the others ``top``, shape (p n_i, n_i)) and
    their participation vectors l, shape (n_i, n_roots): eigenvalues of the block companion matrix."""
    k = p * n_i
    if n_i == 1:
        comp = np.zeros((p, p))
        if p > 1:
            comp[:-1, 1:] = np.eye(p - 1)
        comp[-1, :] = -top[:, 0]
        z = np.linalg.eigvals(comp)
        return z, np.ones((1, z.size), dtype=np.complex128)
    comp = np.zeros((k, k))
    if p > 1:
        comp[:-n_i, n_i:] = np.eye(k - n_i)
    comp[-n_i:, :] = -top.T
    z, V = np.linalg.eig(comp)
    return z, V[:n_i, :]
