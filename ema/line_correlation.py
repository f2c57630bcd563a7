"""Noise that is correlated over neighbouring spectral lines, and the sandwich covariances that account for it.

A hammer test's FRFs are computed from windowed records: the exponential window of the response, or a record
shorter than the response's decay, convolves the spectrum with the window's transform, so the noise at one
line is correlated with its neighbours' (0.64–0.72 at lag one on the rig's 48-blade test, design §8.64). A
sandwich covariance with each line a cluster of its own (White's) then understates the poles' scatter, by the
square root of the long-run variance ratio ``Σ_k ρ_k`` (about 2.4 at ρ₁ = 0.7). The remedy is the
heteroscedasticity-and-autocorrelation-consistent (HAC) estimator of Newey & West (Econometrica 1987): the
meat sums each line's score with its neighbours' up to a bandwidth, with Bartlett weights, which keep it
positive semi-definite; the bandwidth is Andrews' (Econometrica 1991) rule for the Bartlett kernel with the
AR(1) approximation, estimated from the residuals themselves. White noise gives a bandwidth under one line
and the estimators as before.
"""

from __future__ import annotations

import numpy as np

__all__ = ["correlate_lines", "line_correlation", "scores_variance"]

#: Lag-one correlations are clipped to this magnitude in the bandwidth rule (which diverges at 1).
MAX_RHO = 0.99


def line_correlation(z: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Bartlett-tapered autocorrelation over the lines of standardised residuals, pooled over every series.

    Parameters
    ----------
    z : ndarray of float64
        Residuals divided by their noise model's standard deviation; ``axis`` runs over evenly spaced lines.
    axis : int

    Returns
    -------
    rho : ndarray of float64, shape (K + 1,)
        ``w_k ρ̂_k`` for lags 0..K (ρ̂_0 = 1): ρ̂_k the biased sample autocorrelation (pooled sums over all series,
        divided by the pooled sum of squares). Positive semi-definite (a Schur product of two such sequences), so
        a valid correlation for :func:`correlate_lines`.
    weights : ndarray of float64, shape (K + 1,)
        The Bartlett weights w_k = 1 − k / S, S Andrews' bandwidth ``1.1447 (α T)^{1/3}``, α = 4ρ̂₁² / (1 − ρ̂₁²)²,
        T the number of lines; K is the largest lag under S. ``[1.]`` (White's estimator) for white noise.
    """
    z = np.moveaxis(np.asarray(z, dtype=np.float64), axis, -1)
    n = z.shape[-1]
    z = z.reshape(-1, n)
    total = float(np.sum(z * z))
    if n < 2 or not total > 0:
        return np.ones(1), np.ones(1)
    rho1 = float(np.clip(np.sum(z[:, :-1] * z[:, 1:]) / total, -MAX_RHO, MAX_RHO))
    bandwidth = 1.1447 * (4 * rho1**2 / (1 - rho1**2) ** 2 * n) ** (1 / 3)
    lags = np.arange(1, min(int(np.ceil(bandwidth)), n))
    rho = np.array([np.sum(z[:, :-k] * z[:, k:]) / total for k in lags])
    weights = np.r_[1.0, 1 - lags / bandwidth]
    return weights * np.r_[1.0, rho], weights


def correlate_lines(white: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Independent standard normal draws ``white`` (..., n_lines) made correlated over the last axis as ``rho``
    (:func:`line_correlation`), unit variance kept: times a square root of the Toeplitz correlation matrix."""
    n = white.shape[-1]
    if rho.size == 1 or n < 2:
        return white
    col = np.zeros(n)
    col[:min(rho.size, n)] = rho[:n]
    C = col[np.abs(np.arange(n)[:, None] - np.arange(n)[None, :])]
    e, V = np.linalg.eigh(C)
    root = V * np.sqrt(np.clip(e, 0.0, None))          # C = root rootᵀ; round-off can leave e at -1e-16
    return white @ root.T


def scores_variance(u: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``Σ_l Σ_|k|≤K w_|k| u_l u_{l+k}`` per parameter: the diagonal of a sandwich ``B (Σ_lm w s_l s_mᵀ) B``.

    Parameters
    ----------
    u : ndarray, shape (..., n_lines, n_parameters)
        Each line's score times the bread, ``s_l B``.
    weights : ndarray, shape (K + 1,)
        Lag weights, 1 at lag 0 (a single 1: White's estimator).

    Returns
    -------
    ndarray, shape (..., n_parameters)
    """
    out = np.sum(u * u, axis=-2)
    for k in range(1, min(weights.size, u.shape[-2])):
        out = out + 2.0 * weights[k] * np.sum(u[..., :-k, :] * u[..., k:, :], axis=-2)
    return out
