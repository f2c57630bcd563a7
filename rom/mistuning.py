"""Blade mistuning parameters (paper §2.3.1, Eq. 19): validation of δ vectors.

A blade's mistuning is a vector δ of relative perturbations of its free-interface eigenvalues,
``ω_f,i² → (1 + δ_i) ω_f,i²`` (relative units: 0.01 = 1 %). A δ shorter than the number m of retained
modes perturbs only the first ``len(δ)`` modes (experiments identify only a few blade modes); the other
modes stay tuned.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["as_delta", "as_deltas", "rom_deltas"]


def as_delta(delta, m: int) -> np.ndarray:
    """Validate one blade's δ and pad it with zeros to length ``m``.

    Parameters
    ----------
    delta : float, array_like of shape (k,), 1 ≤ k ≤ m, or None
        A scalar applies to every mode; ``None`` means tuned.
    m : int
        Number of retained free-interface modes.

    Returns
    -------
    ndarray, shape (m,)

    Raises
    ------
    ValueError
        On NaN/inf entries, δ ≤ −1 (non-positive eigenvalue), or more than ``m`` entries.
    """
    if delta is None:
        return np.zeros(m)
    d = np.asarray(delta, dtype=np.float64)
    if d.ndim == 0:
        d = np.full(m, float(d))
    if d.ndim != 1:
        raise ValueError(f"delta must be a scalar or a 1-D vector of length 1..{m}, got shape {d.shape}")
    if d.size == 0 or d.size > m:
        raise ValueError(f"delta must have 1..{m} entries (one per retained blade mode), got {d.size}")
    if not np.all(np.isfinite(d)):
        raise ValueError(f"delta must be finite, got NaN/inf at mode(s) {np.flatnonzero(~np.isfinite(d)) + 1}")
    if np.any(d <= -1.0):
        raise ValueError(f"delta entries must be > -1 (eigenvalue (1 + δ) ω² > 0), got min {d.min():g}")
    out = np.zeros(m)
    out[: d.size] = d
    return out


def as_deltas(deltas, n_blades: int, m: int) -> np.ndarray:
    """Validate the δ vectors of ``n_blades`` blades; returns shape (n_blades, m).

    ``deltas`` may be None (all tuned), an array of shape (n_blades, k), or a mapping/sequence with one
    entry per blade (each as accepted by :func:`as_delta`).
    """
    if deltas is None:
        return np.zeros((n_blades, m))
    if isinstance(deltas, dict):
        raise ValueError("deltas must be a sequence with one entry per blade, not a mapping")
    rows = list(deltas) if not isinstance(deltas, np.ndarray) else list(np.atleast_2d(deltas))
    if len(rows) != n_blades:
        raise ValueError(f"deltas must have one row per blade ({n_blades}), got {len(rows)}")
    return np.vstack([as_delta(r, m) for r in rows])


def rom_deltas(blade_freqs: np.ndarray, deltas_pct: np.ndarray, rom_freqs_hz: np.ndarray) -> np.ndarray:
    """ROM mistuning δ (fractions, Eq. 19) from measured blade deltas (%, Eq. 37).

    Each tracked measured mode is matched to the ROM blade's free-interface mode nearest in frequency
    (one-to-one); unmatched ROM modes stay tuned.

    Parameters
    ----------
    blade_freqs : ndarray, shape (n_blades, k)
        Measured frequencies of the tracked modes (Hz; NaN where a blade lacks a mode).
    deltas_pct : ndarray, shape (n_blades, k)
    rom_freqs_hz : ndarray, shape (m,)

    Returns
    -------
    ndarray, shape (n_blades, m)
    """
    mean_f = np.nanmean(blade_freqs, axis=0)
    cost = np.abs(rom_freqs_hz[None, :] / mean_f[:, None] - 1)
    rows, cols = linear_sum_assignment(cost)
    out = np.zeros((blade_freqs.shape[0], rom_freqs_hz.size))
    out[:, cols] = np.nan_to_num(deltas_pct[:, rows]) / 100
    return out
