"""Pattern matching at the measured δ itself: the dataset interpolated over its δ grid (beyond paper §6.4).

The paper's two-step k-NN (:class:`identify.knn.TwoStepKNN`) compares a joint's frequencies, measured at its
blade's δ, with samples computed at the *nearest grid* δ. Half a grid step of δ (0.25 % with the paper's
0.5 % step) moves a blade-dominated d1b frequency by about as much as the contact pattern does, so step 1's
rounding leaks into step 2's choice. Here each pattern pair's tracked frequencies are interpolated
(multilinear, :class:`scipy.interpolate.RegularGridInterpolator`) to the joint's exact δ, and the pairs are
ranked by the same normalised, weighted distance (Eqs. 33, 39) over all pairs.

Measured on the default virtual campaign's numerical input (benchmarks/identify_numerical.py, 13 unknown
joints): both methods chose the same pattern pair for every joint (mean d1b feature error 0.11 % with 10
patterns per flank), because the choice there is limited by how close the dataset's patterns come to the
truth, not by the δ rounding. The pipeline therefore keeps the paper's two-step k-NN; this is the option for
coarse δ grids.

δ outside the grid is extrapolated linearly from the edge cells, with a warning naming the joint and mode.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from .errors import IdentifyError

__all__ = ["InterpolatedMatch", "match_interpolated", "pair_grid"]


@dataclass(frozen=True, eq=False)
class InterpolatedMatch:
    """Ranked pattern pairs per joint.

    Attributes
    ----------
    label : ndarray of int, shape (n_joints, k, 2)
        (i_L, i_R), 0-based, best first.
    distance : ndarray, shape (n_joints, k)
        Weighted normalised distance (Eqs. 33, 39).
    features_hz : ndarray, shape (n_joints, k, n_features)
        The candidates' interpolated feature frequencies at the joint's δ.
    """

    label: np.ndarray
    distance: np.ndarray
    features_hz: np.ndarray


def pair_grid(dataset) -> tuple[np.ndarray, np.ndarray]:
    """The dataset as a regular grid per pattern pair.

    Returns
    -------
    pairs : ndarray of int, shape (n_pairs, 2)
    F : ndarray, shape (n_pairs, n_values, ..., n_values, n_modes)
        Tracked frequencies (Hz), one δ axis per δ mode.

    Raises
    ------
    IdentifyError
        If the dataset is not the full grid (every δ row × every pair).
    """
    grid = np.asarray(dataset.delta_grid, float)
    D = np.asarray(dataset.deltas, float)
    k = D.shape[1]
    idx = np.rint((D - grid[0]) / np.diff(grid).mean()).astype(int) if grid.size > 1 else np.zeros_like(D, int)
    if grid.size > 1 and not np.allclose(grid[np.clip(idx, 0, grid.size - 1)], D, atol=1e-12):
        raise IdentifyError("dataset δ values are not on an evenly spaced delta_grid; rebuild the dataset")
    pairs, inv = np.unique(np.asarray(dataset.pair), axis=0, return_inverse=True)
    inv = inv.ravel()
    F = np.full((len(pairs), *([grid.size] * k), dataset.frequencies_hz.shape[1]), np.nan)
    F[(inv, *idx.T)] = dataset.frequencies_hz
    if np.isnan(F).any():
        raise IdentifyError(f"dataset is not a full grid: {int(np.isnan(F[..., 0]).sum())} (pair, δ row) samples "
                            "missing; rebuild it")
    return pairs, F


def match_interpolated(dataset, deltas, features_hz, *, weights=None, n_neighbors: int = 1,
                       joints=None) -> InterpolatedMatch:
    """Rank the dataset's pattern pairs for each joint, with features interpolated to the joint's δ.

    Parameters
    ----------
    dataset : identify.dataset.Dataset
    deltas : array_like, shape (n_joints, n_delta_modes)
        Each joint's blade δ (relative) on the dataset's δ modes.
    features_hz : array_like, shape (n_joints, n_features)
        Measured (or numerical) frequencies of the feature modes, in ``dataset.feature_modes`` order.
    weights : array_like, shape (n_features,), optional
        Eq. 33 weights; default ``dataset.weights``.
    n_neighbors : int
    joints : sequence of int, optional
        Joint numbers for the warnings (default 1..n_joints).
    """
    D = np.atleast_2d(np.asarray(deltas, float))
    Y = np.atleast_2d(np.asarray(features_hz, float))
    feat = list(dataset.feature_modes)
    if D.shape[1] != dataset.deltas.shape[1] or Y.shape != (len(D), len(feat)):
        raise IdentifyError(f"deltas {D.shape} and features {Y.shape}: expected (n, {dataset.deltas.shape[1]}) and "
                            f"(n, {len(feat)})")
    if not (np.isfinite(D).all() and np.isfinite(Y).all()):
        raise IdentifyError("deltas and features must be finite")
    w = np.asarray(dataset.weights if weights is None else weights, float)
    if w.shape != (len(feat),) or (w < 0).any() or w.sum() <= 0:
        raise IdentifyError(f"weights {w!r}: expected {len(feat)} non-negative values, not all 0")
    pairs, F = pair_grid(dataset)
    grid = np.asarray(dataset.delta_grid, float)
    joints = list(range(1, len(D) + 1)) if joints is None else list(joints)
    half = 0.5 * (grid[1] - grid[0]) if grid.size > 1 else 0.0
    for r, c in zip(*np.nonzero((D < grid[0] - half) | (D > grid[-1] + half)), strict=True):
        warnings.warn(f"joint {joints[r]}, δ mode {c + 1}: {100 * D[r, c]:.3g} % lies outside the dataset's δ grid "
                      f"[{100 * grid[0]:.3g}, {100 * grid[-1]:.3g}] %: extrapolated", stacklevel=2)
    axes = tuple([grid] * D.shape[1])
    Fm = np.moveaxis(F[..., feat], 0, -2)  # (n_v, ..., n_v, n_pairs, n_features)
    interp = RegularGridInterpolator(axes, Fm, method="linear", bounds_error=False, fill_value=None)
    C = interp(D)  # (n_joints, n_pairs, n_features)
    # Eq. 39 normalisation over the candidates at the joint's δ (the shift by the mean cancels in the
    # difference), then Eq. 33's weighted Euclidean distance.
    sd = C.std(axis=1, keepdims=True)
    sd = np.where(sd > 0, sd, 1.0)
    dist = np.sqrt(np.sum(w * ((C - Y[:, None, :]) / sd) ** 2, axis=2))
    k = int(min(max(n_neighbors, 1), len(pairs)))
    order = np.argsort(dist, axis=1, kind="stable")[:, :k]
    rows = np.arange(len(D))[:, None]
    return InterpolatedMatch(pairs[order], dist[rows, order], C[rows, order])
