"""The δ grid of the identification dataset (paper §6.3): one set of relative values shared by every δ mode.

Each blade's measured deltas (Eq. 37) set the range, rounded outward to multiples of the step (0.5 % in the
paper); every δ row of the dataset is a tuple of grid values, one per perturbed blade mode (Eq. 19).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .errors import IdentifyError

__all__ = ["DEFAULT_STEP", "grid_from_deltas", "check_grid", "off_grid"]

#: Default δ grid step (paper §6.3: 0.5 %).
DEFAULT_STEP = 0.005


def grid_from_deltas(measured, *, step: float = DEFAULT_STEP, n_delta_modes: int = 3) -> np.ndarray:
    """δ grid spanning the measured blade deltas, rounded outward to multiples of ``step`` (paper §6.3).

    Parameters
    ----------
    measured : array_like, shape (n_blades, n_modes)
        Measured blade deltas, relative (0.01 = 1 %; Eq. 37 gives them in %: divide by 100).
    step : float
        Grid step, relative (default 0.005 = 0.5 %).
    n_delta_modes : int
        Leading blade modes the dataset perturbs; only their columns set the range.

    Returns
    -------
    ndarray of float64, shape (n_values,)
        ``step · arange(floor(min / step), ceil(max / step) + 1)``; values within 1e-9 steps of a multiple
        count as that multiple (a measured −0.5 % gives −0.5 %, not −1 %).

    Raises
    ------
    IdentifyError
        Not 2-D, fewer columns than ``n_delta_modes``, NaN/inf, step ≤ 0, or a grid value ≤ −1.
    """
    m = np.asarray(measured, dtype=np.float64)
    if m.ndim != 2 or m.shape[0] == 0:
        raise IdentifyError(f"measured deltas have shape {m.shape}, expected (n_blades ≥ 1, n_modes)")
    if not isinstance(n_delta_modes, (int, np.integer)) or not 1 <= n_delta_modes <= m.shape[1]:
        raise IdentifyError(f"n_delta_modes={n_delta_modes!r}: expected an integer in 1..{m.shape[1]} "
                            f"(measured deltas have {m.shape[1]} mode columns)")
    if not (isinstance(step, (int, float, np.floating)) and math.isfinite(step) and step > 0):
        raise IdentifyError(f"step={step!r}: expected a finite relative step > 0 (e.g. 0.005 = 0.5 %)")
    cols = m[:, :n_delta_modes]
    bad = ~np.isfinite(cols)
    if bad.any():
        b, k = np.argwhere(bad)[0]
        raise IdentifyError(f"measured deltas: blade {b + 1}, mode {k + 1} is {cols[b, k]} (expected a finite value)")
    lo = math.floor(cols.min() / step + 1e-9)
    hi = math.ceil(cols.max() / step - 1e-9)
    if hi - lo > 1000:
        raise IdentifyError(f"δ grid of {hi - lo + 1} values from {cols.min():.4g} to {cols.max():.4g} with step "
                            f"{step:g}: expected ≤ 1001 values; check the units (relative, 0.01 = 1 %)")
    grid = np.round(np.arange(lo, hi + 1) * step, 12)
    if grid[0] <= -1.0:
        raise IdentifyError(f"δ grid starts at {grid[0]:.4g}: blade eigenvalues (1 + δ) ω² must stay > 0; "
                            "check the units (relative, 0.01 = 1 %)")
    if grid.size > 50:
        warnings.warn(f"δ grid has {grid.size} values per mode ({grid.size ** n_delta_modes} δ rows): a large "
                      "dataset; consider a coarser step", stacklevel=2)
    return grid


def off_grid(D: np.ndarray, g: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """Mask of the values of ``D`` farther than ``tol`` from every value of the grid ``g``.

    Exact membership first, then bisection on the sorted grid for the rest (O(n) memory): a million-sample
    table against a 26-value grid would otherwise build a 10⁸-element temporary.
    """
    gs = np.sort(g)
    off = ~np.isin(D, gs)  # save_dataset writes the grid's own values: exact membership settles nearly all
    if not off.any():
        return off
    d = D[off]
    if gs.size == 1:
        off[off] = np.abs(d - gs[0]) > tol
    else:
        pos = np.clip(np.searchsorted(gs, d), 1, gs.size - 1)
        off[off] = np.minimum(np.abs(d - gs[pos - 1]), np.abs(d - gs[pos])) > tol
    return off


def check_grid(delta_grid) -> np.ndarray:
    """The grid ``delta_grid`` sorted, as float64; IdentifyError unless 1-D, finite, distinct and > −1."""
    g = np.asarray(delta_grid, dtype=np.float64)
    if g.ndim != 1 or g.size == 0 or not np.all(np.isfinite(g)):
        raise IdentifyError(f"delta_grid must be a non-empty 1-D array of finite values, got shape {g.shape}")
    if np.any(g <= -1.0):
        raise IdentifyError(f"delta_grid value {g.min():g} ≤ −1: blade eigenvalues (1 + δ) ω² must stay > 0")
    if np.unique(g).size != g.size:
        raise IdentifyError("delta_grid holds repeated values")
    return np.sort(g)
