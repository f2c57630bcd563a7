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

References: Richardson & Formenti, IMAC 1 (1982) and IMAC 3 (1985); Forsythe, J. SIAM 5 (1957);
Brubeck, Nakatsukasa & Trefethen, "Vandermonde with Arnoldi", SIAM Review 63 (2021).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

import numpy as np
from tqdm import tqdm

from .frf import FRFSet
from .poles import PoleSet, band_data, resolve_orders, single_thread_blas

__all__ = ["lsrf", "orthonormal_basis", "evaluate_basis"]

log = logging.getLogger(__name__)


def orthonormal_basis(x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Polynomials ``q_0..q_n`` orthonormal on the points ``x`` (Arnoldi with re-orthogonalisation).

    Parameters
    ----------
    x : ndarray, shape (n_points,)
        Real sample points (normalised frequencies in [-1, 1]).
    n : int
        Highest degree.

    Returns
    -------
    Q : ndarray, shape (n_points, n + 1)
        ``Q[:, j] = q_j(x)``, ``Q^T Q = I``.
    Hs : ndarray, shape (n + 1, n)
        Recurrence (Hessenberg) matrix: ``x * Q[:, :n] = Q @ Hs``.
    """
    m = x.size
    if n + 1 > m:
        raise ValueError(f"order {n} needs at least {n + 1} lines, the band has {m}")
    Q = np.zeros((m, n + 1))
    Hs = np.zeros((n + 1, n))
    Q[:, 0] = 1.0 / np.sqrt(m)
    for k in range(n):
        v = x * Q[:, k]
        for _ in range(2):  # classical Gram-Schmidt, twice
            c = Q[:, : k + 1].T @ v
            v -= Q[:, : k + 1] @ c
            Hs[: k + 1, k] += c
        Hs[k + 1, k] = np.linalg.norm(v)
        Q[:, k + 1] = v / Hs[k + 1, k]
    return Q, Hs


def evaluate_basis(Hs: np.ndarray, x: np.ndarray, n: int, m_points: int) -> np.ndarray:
    """Values of ``q_0..q_n`` at arbitrary (complex) points from the recurrence matrix.

    Parameters
    ----------
    Hs : ndarray, shape (>= n + 1, >= n)
    x : ndarray, shape (n_x,)
    n : int
    m_points : int
        Number of lines the basis was built on (``q_0 = 1/sqrt(m_points)``).

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
) -> PoleSet:
    """Estimate poles with the LSRF method for a series of model orders.

    Parameters
    ----------
    frf : FRFSet
        Measured FRFs, shape (n_outputs, n_inputs, n_freq).
    band : (f_lo, f_hi) in Hz, optional
        Band to fit; default all finite lines.
    max_order : int
        Highest denominator order n (orders 1..n when ``orders`` is None); order n holds up to n modes.
    orders : iterable of int, optional
        Explicit orders.
    normalize : bool
        Scale each FRF to unit RMS over the band (equal weight per FRF).
    progress : bool
        Show a tqdm progress bar on stderr.
    coefficients : {"real", "complex"}
        "real" (default): real polynomials in ``s = j omega``; the basis is orthonormal on the lines
        mirrored to negative frequencies, ``x = omega / omega_hi``, and poles come in conjugate pairs
        (order n holds n/2 modes). "complex": complex coefficients in ``x`` centred on the band, each
        pole once (order n holds n modes), suited to narrow local bands.

    Returns
    -------
    PoleSet
        Poles (rad/s, positive imaginary part, natural frequency within the band) per order, with the
        numerators at the pole (``N_f(x_r)``, proportional to the residues) as vectors.
    """
    if coefficients not in ("real", "complex"):
        raise ValueError(f"coefficients {coefficients!r}: expected 'real' or 'complex'")
    order_list = resolve_orders(max_order, orders)
    data = band_data(frf, band, per="frf" if normalize else "none")
    n_o, n_i, n_f = data.H.shape
    h = data.H.reshape(n_o * n_i, n_f)
    n_frf = h.shape[0]
    n_max = order_list[-1]
    P = n_max + 1
    w = 2 * np.pi * data.freq_hz
    w_lo, w_hi = 2 * np.pi * data.band_hz[0], 2 * np.pi * data.band_hz[1]
    real = coefficients == "real"
    if real:
        # basis orthonormal on the symmetric lines {-w_k} U {w_k}: q_j has the parity of j and
        # psi_j = j^j q_j(w / w_hi) is a real polynomial in s = j w
        wc, wh = 0.0, w_hi
        x = w / wh
        Qfull, Hs = orthonormal_basis(np.concatenate([-x[::-1], x]), n_max)
        Q = Qfull[n_f:]
        m_points = 2 * n_f
        jpow = 1j ** np.arange(P)
        phase = (jpow.conj()[:, None] * jpow[None, :]).real  # Re j^(j - i): 0 for odd j - i, else +-1
    else:
        wc, wh = 0.5 * (w_lo + w_hi), 0.5 * (w_hi - w_lo)
        x = (w - wc) / wh
        Q, Hs = orthonormal_basis(x, n_max)
        m_points = n_f
        jpow = np.ones(P)

    # S_f = Q^T diag(h_f) Q for all f, in chunks (real BLAS on real and imaginary parts)
    S = np.empty((n_frf, P, P), dtype=np.complex128)
    chunk = max(1, int(4e7 // (n_f * P)))
    for start in range(0, n_frf, chunk):
        hs = h[start : start + chunk]  # (c, n_f)
        c = hs.shape[0]
        re = (hs.real[:, :, None] * Q[None, :, :]).transpose(1, 0, 2).reshape(n_f, c * P)
        im = (hs.imag[:, :, None] * Q[None, :, :]).transpose(1, 0, 2).reshape(n_f, c * P)
        Sr = (Q.T @ re).reshape(P, c, P).transpose(1, 0, 2)
        Si = (Q.T @ im).reshape(P, c, P).transpose(1, 0, 2)
        S[start : start + c] = Sr + 1j * Si
    T = Q.T @ (np.sum(np.abs(h) ** 2, axis=0)[:, None] * Q)
    if real:
        # real unknowns: S_f <- Re(j^(j-i) S_f), numerator b_f = 2 S_f a, M = T' - 2 sum S_f^T S_f
        jj = jpow.conj()[:, None] * jpow[None, :]
        S = (S * jj[None]).real
        T = T * phase
        G = np.zeros((P, P))
    else:
        G = np.zeros((P, P), dtype=np.complex128)
    wanted = set(order_list)
    out_order, out_pole, out_vec = [], [], []
    f_lo, f_hi = data.band_hz
    with single_thread_blas():
        bar = tqdm(total=len(order_list), desc="LSRF", unit="order", disable=not progress, leave=False)
        for row in range(P):
            Sr = S[:, row, :]
            G += Sr.conj().T @ Sr
            n = row
            if n not in wanted:
                continue
            M = T[: n + 1, : n + 1] - (2.0 if real else 1.0) * G[: n + 1, : n + 1]
            try:
                top = -np.linalg.solve(M[:n, :n], M[:n, n])
            except np.linalg.LinAlgError:
                top = -np.linalg.lstsq(M[:n, :n], M[:n, n], rcond=None)[0]
            a = np.append(top, 1.0)
            c_coef = a * jpow[: n + 1]
            C = Hs[:n, :n].astype(np.complex128)
            C[:, n - 1] -= Hs[n, n - 1] * c_coef[:n] / c_coef[n]
            xr = np.linalg.eigvals(C)
            wr = wc + wh * xr
            lam = 1j * wr
            fn = np.abs(lam) / (2 * np.pi)
            keep = (wr.real > 0) & (fn >= f_lo) & (fn <= f_hi) & np.isfinite(lam)
            lam, xr = lam[keep], xr[keep]
            if lam.size:
                b = S[:, : n + 1, : n + 1] @ a * (2.0 if real else 1.0)  # (n_frf, n+1) numerator coefficients
                V = evaluate_basis(Hs, xr, n, m_points) * jpow[None, : n + 1]  # (n_r, n+1)
                num = (V @ b.T) / data.scale.reshape(-1)[None, :]  # (n_r, n_frf)
                out_order.append(np.full(lam.size, n))
                out_pole.append(lam)
                out_vec.append(num)
            bar.update(1)
        bar.close()
    return PoleSet(
        method="lsrf",
        band_hz=data.band_hz,
        orders=order_list,
        order=np.concatenate(out_order) if out_order else np.zeros(0, int),
        pole=np.concatenate(out_pole) if out_pole else np.zeros(0, complex),
        vector=np.vstack(out_vec) if out_vec else np.zeros((0, n_frf), complex),
        outputs=frf.outputs,
        inputs=frf.inputs,
    )
