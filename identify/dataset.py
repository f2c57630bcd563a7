"""The identification dataset: δ grid × pattern pairs → tracked disk–one-blade frequencies (paper §6.3, Fig. 17).

Every δ row of the grid (one value per blade mode for the first ``n_delta_modes`` blade modes, Eq. 19) is
combined with every left × right pattern pair, and the disk–one-blade ROM (Eq. 22) gives the first
``n_modes`` frequencies, each **tracked by MAC**: a sample's mode is matched to its pair's δ = 0 mode, and that
one to the reference pair's mode (:mod:`identify.sensitivity`). Column ``m`` of ``frequencies_hz`` therefore
always describes the same physical mode, and all ``n_modes`` are stored, so another feature choice needs no
rebuild.

Tracking is chained on purpose: sample → its pair's δ = 0 modes (MAC with the pair's mass matrix, which δ does
not change) → the reference pair's modes (MAC with the reference mass, decided once per pair). Where two modes
of a pair veer (each about half like either reference mode; on the coarse test model modes 9–10 of one pair),
tracking each sample straight to the reference would flip between them as δ changes; the chain keeps a
pair's features continuous in δ. Elsewhere the two rules agree (tests).

Speed: reanalysis, not one dense solve per sample (:mod:`identify.reanalysis`). Per pattern pair one
factorisation and a small Krylov basis give a δ-parametric model of ~35 coordinates; each δ row is then a
tiny eigenproblem, solved in batches. Every sample carries a rigorous bound on its frequencies' relative
error against the exact ROM eigenvalues (residuals in the full ROM space). Where the bound exceeds ``tol``
the sample is solved directly (:func:`rom.modal.dense_modes`) and counted as a fallback.

Storage: Parquet (pyarrow), one row per sample (columns ``delta_1..k``, ``i_L``, ``i_R``, ``f_1..n``,
``error_bound``, ``fallback``, ``mac_min``), and the rest in the schema metadata under
``b"bladetwin.identify.dataset"`` as JSON (format version, model key, grid, pattern grids as 0/1 strings,
feature modes, weights, δ grid). :func:`save_dataset` writes atomically; :func:`load_dataset` validates
everything and refuses a dataset made with another ROM (:func:`identify.sensitivity.model_key`).
"""

from __future__ import annotations

import itertools
import json
import math
import os
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from ema.mac import mac
from rom.craig_bampton import CraigBamptonModel
from rom.fileio import atomic_path
from rom.modal import dense_modes, single_thread_blas
from rom.rubin import RubinModel

from .errors import IdentifyError
from .reanalysis import RitzModel, ritz_model, solve_ritz
from .sensitivity import (
    MAC_WARN,
    Sensitivity,
    assign_modes,
    blade_grid,
    check_features,
    check_formulation,
    check_patterns,
    check_reference,
    check_weights,
    common_coords,
    model_key,
    pencil_checked,
    summarize,
    update_index,
    warn_low_mac,
)

__all__ = [
    "Dataset",
    "DatasetPlan",
    "PairResult",
    "build_dataset",
    "plan_dataset",
    "solve_pair",
    "assemble_dataset",
    "grid_from_deltas",
    "save_dataset",
    "load_dataset",
    "DEFAULT_STEP",
    "DEFAULT_TOL",
    "FORMAT_VERSION",
]

#: Default δ grid step (paper §6.3: 0.5 %).
DEFAULT_STEP = 0.005
#: Default bound on a stored frequency's relative error before a sample falls back to a direct solve.
#: Ten times below the 0.01 % accuracy target; the bound is rigorous (reanalysis module docstring).
DEFAULT_TOL = 1e-5
#: Parquet layout version (bump on incompatible changes).
FORMAT_VERSION = 1
_META_KEY = b"bladetwin.identify.dataset"
_FORMAT = "bladetwin.identify.dataset"
#: δ rows solved per batch (bounds the s × s × batch work arrays).
_BATCH = 4096
#: Rows per Parquet batch read by :func:`load_dataset`.
_READ_BATCH = 262_144


@dataclass(frozen=True, eq=False)
class Dataset:
    """Tracked disk–one-blade frequencies over a δ grid and all pattern pairs (paper §6.3).

    Attributes
    ----------
    deltas : ndarray of float64, shape (n_samples, n_delta_modes)
        Blade mistuning of each sample, relative (0.01 = 1 %), values of ``delta_grid``.
    pair : ndarray of int64, shape (n_samples, 2)
        Pattern pair ``(i_L, i_R)``, 0-based rows of ``patterns_L`` and ``patterns_R``.
    frequencies_hz : ndarray of float64, shape (n_samples, n_modes)
        Frequency of tracked mode ``m`` (the reference pair's m-th mode, paper Eq. 34), Hz.
    patterns_L, patterns_R : ndarray of bool, shape (n_L, rows, cols), (n_R, rows, cols)
    feature_modes : tuple of int
        0-based columns of ``frequencies_hz`` used as k-NN features.
    weights : ndarray of float64, shape (n_features,)
        Weights of Eq. 33 for the features.
    delta_grid : ndarray of float64, shape (n_values,)
        Grid values (relative), shared by every δ mode.
    model_key : str
        :func:`identify.sensitivity.model_key` of the ROM that made the dataset.
    error_bound : ndarray of float64, shape (n_samples,)
        Largest bound on the relative frequency error of the sample's tracked modes; NaN for fallbacks
        (solved directly).
    fallback : ndarray of bool, shape (n_samples,)
        Samples solved by a direct dense solve.
    mac_min : ndarray of float64, shape (n_samples,)
        Smallest MAC of the sample's tracked modes with its pair's δ = 0 modes.
    meta : dict
        Provenance: reference pair, n_fallbacks, tolerances, formulation, build time.
    """

    deltas: np.ndarray
    pair: np.ndarray
    frequencies_hz: np.ndarray
    patterns_L: np.ndarray
    patterns_R: np.ndarray
    feature_modes: tuple[int, ...]
    weights: np.ndarray
    delta_grid: np.ndarray
    model_key: str
    error_bound: np.ndarray | None = None
    fallback: np.ndarray | None = None
    mac_min: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        D = _readonly(self.deltas, np.float64, "deltas", 2)
        P = _readonly(self.pair, np.int64, "pair", 2)
        F = _readonly(self.frequencies_hz, np.float64, "frequencies_hz", 2)
        n = D.shape[0]
        if P.shape != (n, 2) or F.shape[0] != n:
            raise IdentifyError(f"dataset fields disagree: deltas {D.shape}, pair {P.shape}, frequencies_hz {F.shape}; "
                                "expected (n_samples, k), (n_samples, 2), (n_samples, n_modes)")
        PL = check_patterns(self.patterns_L, "patterns_L")
        PR = check_patterns(self.patterns_R, "patterns_R", PL.shape[1:])
        if n and ((P.min(axis=0) < 0).any() or (P.max(axis=0) >= (len(PL), len(PR))).any()):
            raise IdentifyError(f"dataset.pair holds indices outside 0..{len(PL) - 1} (L) / 0..{len(PR) - 1} (R)")
        modes = check_features(self.feature_modes, F.shape[1])
        w = check_weights(self.weights, len(modes))
        w.flags.writeable = False
        g = _readonly(self.delta_grid, np.float64, "delta_grid", 1)
        if not isinstance(self.model_key, str) or not self.model_key:
            raise IdentifyError(f"dataset.model_key must be a non-empty string, got {self.model_key!r}")
        for name, dtype in (("error_bound", np.float64), ("fallback", bool), ("mac_min", np.float64)):
            v = getattr(self, name)
            if v is not None:
                v = _readonly(v, dtype, name, 1)
                if v.shape != (n,):
                    raise IdentifyError(f"dataset.{name} has shape {v.shape}, expected ({n},)")
                object.__setattr__(self, name, v)
        for name, v in (("deltas", D), ("pair", P), ("frequencies_hz", F), ("patterns_L", PL), ("patterns_R", PR),
                        ("feature_modes", modes), ("weights", w), ("delta_grid", g)):
            object.__setattr__(self, name, v)
        object.__setattr__(self, "meta", dict(self.meta))

    @property
    def n_samples(self) -> int:
        return int(self.deltas.shape[0])

    @property
    def features_hz(self) -> np.ndarray:
        """``frequencies_hz[:, feature_modes]``, shape (n_samples, n_features)."""
        return self.frequencies_hz[:, list(self.feature_modes)]

    def check_model(self, key: str) -> None:
        """Raise IdentifyError unless the dataset was built with the ROM whose model key is ``key``."""
        if key != self.model_key:
            raise IdentifyError(f"dataset model key {self.model_key[:16]}… does not match the ROM in use "
                                f"({key[:16]}…): the dataset was built with another model; rebuild it")


def _readonly(a, dtype, name: str, ndim: int) -> np.ndarray:
    # A read-only array of the right dtype that owns its memory is taken as it is (load_dataset hands over
    # its own arrays, and a million-row table would otherwise be copied again); anything else, a view
    # included, is copied, so the caller cannot change the dataset afterwards through an array it holds.
    owned = isinstance(a, np.ndarray) and a.dtype == dtype and not a.flags.writeable and a.base is None
    try:
        out = a if owned else np.array(a, dtype=dtype)
    except (TypeError, ValueError):
        raise IdentifyError(f"dataset.{name} cannot be read as {np.dtype(dtype).name}") from None
    if out.ndim != ndim:
        raise IdentifyError(f"dataset.{name} has shape {out.shape}, expected a {ndim}-D array")
    # error_bound is NaN for direct solves, mac_min for datasets saved without it.
    if out.dtype.kind == "f" and not np.all(np.isfinite(out)) and name not in ("error_bound", "mac_min"):
        raise IdentifyError(f"dataset.{name} holds NaN or infinite values")
    out.flags.writeable = False
    return out


# ----------------------------------------------------------------------------------------- δ grid
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


def _off_grid(D: np.ndarray, g: np.ndarray, tol: float = 1e-12) -> np.ndarray:
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


def _check_grid(delta_grid) -> np.ndarray:
    g = np.asarray(delta_grid, dtype=np.float64)
    if g.ndim != 1 or g.size == 0 or not np.all(np.isfinite(g)):
        raise IdentifyError(f"delta_grid must be a non-empty 1-D array of finite values, got shape {g.shape}")
    if np.any(g <= -1.0):
        raise IdentifyError(f"delta_grid value {g.min():g} ≤ −1: blade eigenvalues (1 + δ) ω² must stay > 0")
    if np.unique(g).size != g.size:
        raise IdentifyError("delta_grid holds repeated values")
    return np.sort(g)


# ----------------------------------------------------------------------------------------- build
def _assign_batch(mac: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each sample, the candidate of each tracked δ = 0 mode (``rows``), maximum total MAC.

    ``mac`` (t, n_cand δ=0, n_cand sample). Where every tracked row's best candidate has MAC > 0.5 that
    argmax is the assignment: a unit-norm sample mode has MAC > 0.5 with at most one δ = 0 mode (they are
    orthonormal in the same inner product), so the argmaxes are distinct, and each row takes its maximum.
    Otherwise the Hungarian assignment decides.
    """
    sub = mac[:, rows, :]
    cols = np.argmax(sub, axis=2)
    vals = np.take_along_axis(sub, cols[:, :, None], axis=2)[:, :, 0]
    for t in np.flatnonzero(~(vals > 0.5).all(axis=1)):
        cols[t], vals[t] = assign_modes(sub[t])
    return cols, vals


def _solve_rows(base: RitzModel, D: np.ndarray, rows: np.ndarray, tol: float, K0, M, idx, w2):
    """Tracked frequencies, error bounds, min MAC and fallback flags of one pair's δ rows ``D``.

    Reanalysis first; rows whose bound (over the tracked modes) exceeds ``tol`` are solved directly.
    """
    sol = solve_ritz(base, D)
    cols, vals = _assign_batch(sol.mac0, rows)
    freq = np.take_along_axis(sol.frequencies_hz, cols, axis=1)
    bound = np.take_along_axis(sol.bound, cols, axis=1).max(axis=1)
    mac_min = vals.min(axis=1)
    fallback = ~(bound <= tol)
    for t in np.flatnonzero(fallback):
        freq[t], v = _direct_sample(K0, M, idx, D[t] * w2, base, rows)
        mac_min[t], bound[t] = v.min(), np.nan
    return freq, bound, mac_min, fallback


def _direct_sample(K0, M, idx, d, base: RitzModel, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Direct dense solve of one sample, tracked against the pair's δ = 0 modes (mass-weighted MAC)."""
    K = K0.copy()
    K[idx, idx] += d
    with single_thread_blas():
        dm = dense_modes(K, M, base.n_cand)
    num = (base.mass_shapes0.T @ dm.shapes) ** 2  # both M-normalised
    cols, vals = assign_modes(num[rows])
    return dm.frequencies_hz[cols], vals


def build_dataset(
    disk: CraigBamptonModel,
    blade: RubinModel,
    patterns_L,
    patterns_R,
    delta_grid,
    *,
    n_delta_modes: int = 3,
    n_modes: int = 10,
    sensitivity: Sensitivity | None = None,
    n_features: int = 3,
    reference: tuple[int, int] | None = None,
    n_extra: int = 4,
    formulation: str = "exact",
    tol: float = DEFAULT_TOL,
    method: str = "auto",
    progress: bool = True,
) -> Dataset:
    """Build the dataset: every δ row of the grid × every pattern pair (paper §6.3), by reanalysis.

    Parameters
    ----------
    disk : rom.CraigBamptonModel
        Disk reduced on one slot.
    blade : rom.RubinModel
        Its own δ is ignored; the grid's δ perturbs its first ``n_delta_modes`` modes (Eq. 19).
    patterns_L, patterns_R : array_like of bool, shape (n_L, rows, cols), (n_R, rows, cols)
    delta_grid : array_like, shape (n_values,)
        Relative δ values (e.g. :func:`grid_from_deltas`); every δ row is a tuple of them.
    n_delta_modes : int
        Blade modes perturbed (paper: 3). Samples: ``n_values ** n_delta_modes · n_L · n_R``.
    n_modes : int
        Tracked d1b modes stored per sample (paper: 10).
    sensitivity : Sensitivity, optional
        A sensitivity analysis of the same model and patterns: its reference pair, feature modes and
        weights are used (and its tracking is checked). Without it they are computed from the δ = 0 modes
        found here (the same analysis, paper §6.2), with ``n_features`` and ``reference``.
    n_features : int
    reference : (int, int), optional
        Reference pair for tracking (default :func:`identify.sensitivity.reference_pair`).
    n_extra : int
        Candidate modes above ``n_modes`` per sample for tracking.
    formulation : {"exact", "paper"}
    tol : float
        A sample whose error bound exceeds ``tol`` (relative) is solved directly.
    method : {"auto", "krylov", "eigh"}
        Ritz basis per pair (:func:`identify.reanalysis.ritz_model`).
    progress : bool
        tqdm bar on stderr.

    Returns
    -------
    Dataset
        Samples ordered pair by pair (i_L, then i_R), δ rows in ``itertools.product`` order inside a pair.

    Raises
    ------
    IdentifyError
        Bad patterns, grid, counts, or a sensitivity made for another model or pattern set.

    Warns
    -----
    UserWarning
        Tracked modes with MAC < 0.5 against their reference (pair or δ = 0).
    """
    t_start = time.perf_counter()
    plan = plan_dataset(disk, blade, patterns_L, patterns_R, delta_grid, n_delta_modes=n_delta_modes,
                        n_modes=n_modes, sensitivity=sensitivity, reference=reference, n_extra=n_extra,
                        formulation=formulation, tol=tol, method=method)
    results = {}
    bar = tqdm(total=plan.n_samples, desc="dataset", unit="sample", file=sys.stderr, disable=not progress,
               smoothing=0.05)
    try:
        for pair in plan.pairs:
            results[pair] = solve_pair(plan, *pair)
            bar.update(plan.n_rows)
    finally:
        bar.close()
    return assemble_dataset(plan, results, sensitivity=sensitivity, n_features=n_features, t_start=t_start)


@dataclass(frozen=True, eq=False)
class DatasetPlan:
    """A checked dataset build, split into independent pattern pairs (issue 12: chunked, resumable builds).

    Made by :func:`plan_dataset`; :func:`solve_pair` computes one pair from it alone, and
    :func:`assemble_dataset` puts the pairs together. The reference pair's δ = 0 modes (``ref_shapes`` on the
    ``common`` coordinates, with the mass ``W``) are in it, so every pair tracks against the same modes
    whichever process solves it.
    """

    disk: CraigBamptonModel
    blade: RubinModel
    PL: np.ndarray
    PR: np.ndarray
    grid: np.ndarray
    rows_d: np.ndarray
    n_delta_modes: int
    n_modes: int
    n_extra: int
    formulation: str
    tol: float
    method: str
    reference: tuple[int, int]
    key: str
    idx: np.ndarray
    w2: np.ndarray
    common: np.ndarray
    W: np.ndarray
    ref_shapes: np.ndarray

    @property
    def n_rows(self) -> int:
        return len(self.rows_d)

    @property
    def pairs(self) -> list[tuple[int, int]]:
        """Every (i_L, i_R), the reference pair first (the serial build's order)."""
        every = [(i, j) for i in range(len(self.PL)) for j in range(len(self.PR))]
        return [self.reference] + [p for p in every if p != self.reference]

    @property
    def n_samples(self) -> int:
        return len(self.PL) * len(self.PR) * self.n_rows


@dataclass(frozen=True, eq=False)
class PairResult:
    """One pattern pair's samples: tracked frequencies (Hz, shape (n_rows, n_modes)), error bounds, min MAC and
    fallback flags (shape (n_rows,)), and its δ = 0 modes against the reference (``freq0``, ``mac_ref``,
    ``rank_ref``, shape (n_modes,))."""

    i: int
    j: int
    frequencies_hz: np.ndarray
    bound: np.ndarray
    mac_min: np.ndarray
    fallback: np.ndarray
    freq0: np.ndarray
    mac_ref: np.ndarray
    rank_ref: np.ndarray


def plan_dataset(disk, blade, patterns_L, patterns_R, delta_grid, *, n_delta_modes: int = 3, n_modes: int = 10,
                 sensitivity: Sensitivity | None = None, reference: tuple[int, int] | None = None,
                 n_extra: int = 4, formulation: str = "exact", tol: float = DEFAULT_TOL, method: str = "auto"
                 ) -> DatasetPlan:
    """Check a build's inputs and solve its reference pair's δ = 0 modes (arguments as :func:`build_dataset`)."""
    check_formulation(formulation)
    grid = blade_grid(blade)
    PL = check_patterns(patterns_L, "patterns_L", grid)
    PR = check_patterns(patterns_R, "patterns_R", grid)
    g = _check_grid(delta_grid)
    if not isinstance(n_delta_modes, (int, np.integer)) or not 1 <= n_delta_modes <= blade.m:
        raise IdentifyError(f"n_delta_modes={n_delta_modes!r}: expected an integer in 1..{blade.m} (blade modes)")
    if not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise IdentifyError(f"n_modes={n_modes!r}: expected an integer ≥ 1")
    if not isinstance(n_extra, (int, np.integer)) or n_extra < 0:
        raise IdentifyError(f"n_extra={n_extra!r}: expected an integer ≥ 0")
    if not (isinstance(tol, (int, float)) and 0 < tol < 1):
        raise IdentifyError(f"tol={tol!r}: expected a relative frequency error bound in (0, 1)")
    key = model_key(disk, blade, formulation)
    if sensitivity is not None:
        _check_sensitivity(sensitivity, key, PL, PR, n_modes)
        ref = sensitivity.reference
    else:
        ref = check_reference(reference, PL, PR)
    ref = (int(ref[0]), int(ref[1]))
    idx = update_index(disk, blade, n_delta_modes)
    w2 = blade.omega2_tuned[:n_delta_modes]
    rows_d = np.array(list(itertools.product(g, repeat=int(n_delta_modes))))
    with single_thread_blas():
        K0, M = pencil_checked(disk, blade, PL[ref[0]], PR[ref[1]], ref[0], ref[1], formulation)
        _check_update_index(disk, blade, PL[ref[0]], PR[ref[1]], formulation, K0, idx)
        common = common_coords(K0.shape[0], disk, blade)
        W = M[np.ix_(common, common)]
        base = _ritz(K0, M, idx, w2, n_modes + n_extra, method, tol, n_modes, ref)
    return DatasetPlan(disk, blade, PL, PR, g, rows_d, int(n_delta_modes), int(n_modes), int(n_extra), formulation,
                       float(tol), method, ref, key, idx, w2, common, W, base.shapes0[common, :n_modes])


def _ritz(K0, M, idx, w2, n_cand: int, method: str, tol: float, n_modes: int, pair: tuple[int, int]) -> RitzModel:
    try:
        return ritz_model(K0, M, idx, w2, n_cand, method=method, basis_tol=0.1 * tol, n_check=n_modes)
    except ValueError as exc:
        raise IdentifyError(f"pattern pair (L {pair[0]}, R {pair[1]}) (0-based): reanalysis failed: {exc}") from None


def solve_pair(plan: DatasetPlan, i: int, j: int) -> PairResult:
    """Every δ row of one pattern pair (reanalysis, direct fallback), tracked against the reference modes."""
    # One BLAS thread: thin products with ~1,500² matrices are memory-bound, and threaded BLAS on a loaded
    # 2-core machine was up to 40× slower (rom.modal.single_thread_blas). It also makes a pair's numbers the
    # same in any process, so every executor gives the same table.
    with single_thread_blas():
        K0, M = pencil_checked(plan.disk, plan.blade, plan.PL[i], plan.PR[j], i, j, plan.formulation)
        base = _ritz(K0, M, plan.idx, plan.w2, plan.n_modes + plan.n_extra, plan.method, plan.tol, plan.n_modes,
                     (i, j))
        rows, vals = assign_modes(mac(plan.ref_shapes, base.shapes0[plan.common], weight=plan.W))
        n = plan.n_rows
        freq, bound = np.empty((n, plan.n_modes)), np.empty(n)
        mac_min, fallback = np.empty(n), np.zeros(n, bool)
        for b0 in range(0, n, _BATCH):
            Db = plan.rows_d[b0 : b0 + _BATCH]
            sl = slice(b0, b0 + len(Db))
            freq[sl], bound[sl], mac_min[sl], fallback[sl] = _solve_rows(base, Db, rows, plan.tol, K0, M, plan.idx,
                                                                         plan.w2)
    return PairResult(int(i), int(j), freq, bound, mac_min, fallback, base.frequencies0_hz[rows], vals,
                      np.asarray(rows, np.int64))


def assemble_dataset(plan: DatasetPlan, results: dict, *, sensitivity: Sensitivity | None = None,
                     n_features: int = 3, t_start: float | None = None) -> Dataset:
    """The :class:`Dataset` of a plan from every pair's :class:`PairResult` (keyed by (i_L, i_R))."""
    nL, nR, n_rows, n_modes = len(plan.PL), len(plan.PR), plan.n_rows, plan.n_modes
    missing = [p for p in ((i, j) for i in range(nL) for j in range(nR)) if p not in results]
    if missing:
        raise IdentifyError(f"{len(missing)} pattern pair(s) not computed, first (L, R) = {missing[0]}")
    pairs = [(i, j) for i in range(nL) for j in range(nR)]
    n_s = len(pairs) * n_rows
    freq = np.empty((n_s, n_modes))
    bound, mac_min, fallback = np.empty(n_s), np.empty(n_s), np.zeros(n_s, bool)
    freq0 = np.empty((nL, nR, n_modes))
    mac_ref = np.empty((nL, nR, n_modes))
    rank_ref = np.empty((nL, nR, n_modes), np.int64)
    for k, (i, j) in enumerate(pairs):
        r = results[i, j]
        sl = slice(k * n_rows, (k + 1) * n_rows)
        freq[sl], bound[sl], mac_min[sl], fallback[sl] = r.frequencies_hz, r.bound, r.mac_min, r.fallback
        freq0[i, j], mac_ref[i, j], rank_ref[i, j] = r.freq0, r.mac_ref, r.rank_ref
    rows_d = plan.rows_d
    warn_low_mac(mac_ref, "the pattern pairs (δ = 0, against the reference pair)")
    if (mac_min < MAC_WARN).any():
        k = int(np.argmin(mac_min))
        warnings.warn(f"{int((mac_min < MAC_WARN).sum())} sample(s) track a mode with MAC < {MAC_WARN} against their "
                      f"pair's δ = 0 mode; worst {mac_min[k]:.3f} at sample {k} (δ {rows_d[k % n_rows].tolist()})",
                      stacklevel=2)
    if sensitivity is not None:
        modes, weights = sensitivity.feature_modes, sensitivity.weights
        moved = np.argwhere((rank_ref != sensitivity.mode_index).any(axis=2))
        if moved.size:
            warnings.warn(f"{len(moved)} pattern pair(s) track their δ = 0 modes differently from the sensitivity "
                          f"analysis, first (L, R) = {tuple(int(x) for x in moved[0])}", stacklevel=2)
    else:
        _, _, _, modes, weights = summarize(freq0, n_features)
    n_fb = int(fallback.sum())
    meta = {
        "reference": [int(plan.reference[0]), int(plan.reference[1])],
        "n_modes": int(n_modes),
        "n_extra": int(plan.n_extra),
        "formulation": plan.formulation,
        "tol": float(plan.tol),
        "n_fallbacks": n_fb,
        "max_error_bound": float(np.nanmax(bound)) if n_fb < n_s else 0.0,
        "build_s": time.perf_counter() - t_start if t_start is not None else None,
    }
    return Dataset(
        deltas=np.tile(rows_d, (len(pairs), 1)),
        pair=np.repeat(np.array(pairs, np.int64), n_rows, axis=0),
        frequencies_hz=freq,
        patterns_L=plan.PL,
        patterns_R=plan.PR,
        feature_modes=modes,
        weights=weights,
        delta_grid=plan.grid,
        model_key=plan.key,
        error_bound=bound,
        fallback=fallback,
        mac_min=mac_min,
        meta=meta,
    )


def _check_sensitivity(sens: Sensitivity, key: str, PL: np.ndarray, PR: np.ndarray, n_modes: int) -> None:
    if not isinstance(sens, Sensitivity):
        raise IdentifyError(f"sensitivity must be an identify.sensitivity.Sensitivity, got {type(sens).__name__}")
    if sens.model_key != key:
        raise IdentifyError("sensitivity was computed with another ROM (model key differs); recompute it")
    if not (np.array_equal(sens.patterns_L, PL) and np.array_equal(sens.patterns_R, PR)):
        raise IdentifyError("sensitivity was computed for other patterns_L / patterns_R than the dataset's")
    if sens.n_modes != n_modes:
        raise IdentifyError(f"sensitivity tracks {sens.n_modes} modes, the dataset n_modes={n_modes}")


def _check_update_index(disk, blade, L, R, formulation, K0, idx) -> None:
    """The δ update must be exactly K[idx, idx] += δ ω² (guards against a change of the ROM's ordering)."""
    probe = np.full(idx.size, 0.01)
    K1, _ = pencil_checked(disk, blade, L, R, -1, -1, formulation, delta=probe)
    dK = K1 - K0
    expect = np.zeros_like(dK)
    expect[idx, idx] = probe * blade.omega2_tuned[: idx.size]
    if not np.allclose(dK, expect, rtol=1e-9, atol=1e-12 * np.abs(K0).max()):
        raise AssertionError("blade δ does not enter the d1b stiffness at the expected coordinates")  # pragma: no cover


# ----------------------------------------------------------------------------------------- Parquet
def _bits(P: np.ndarray) -> list[str]:
    return ["".join("1" if v else "0" for v in p.ravel()) for p in P]


def _unbits(strings, grid, name: str, path) -> np.ndarray:
    rows, cols = grid
    if not isinstance(strings, list) or not strings:
        raise IdentifyError(f"{path}: metadata field {name!r} must be a non-empty list of 0/1 strings")
    out = np.zeros((len(strings), rows, cols), bool)
    for k, s in enumerate(strings):
        if not isinstance(s, str) or len(s) != rows * cols or set(s) - {"0", "1"}:
            raise IdentifyError(f"{path}: metadata {name}[{k}] must be a string of {rows * cols} '0'/'1' characters "
                                f"(grid {rows}×{cols})")
        out[k] = np.frombuffer(s.encode(), np.uint8).reshape(rows, cols) == ord("1")
    return out


def save_dataset(dataset: Dataset, path: str | os.PathLike) -> Path:
    """Write ``dataset`` to a Parquet file (atomic: temporary file + rename).

    Parameters
    ----------
    dataset : Dataset
    path : str or PathLike

    Returns
    -------
    pathlib.Path
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    if not isinstance(dataset, Dataset):
        raise IdentifyError(f"save_dataset needs a Dataset, got {type(dataset).__name__}")
    n = dataset.n_samples
    cols: dict[str, object] = {}
    for k in range(dataset.deltas.shape[1]):
        cols[f"delta_{k + 1}"] = pa.array(dataset.deltas[:, k], pa.float64())
    cols["i_L"] = pa.array(dataset.pair[:, 0], pa.int32())
    cols["i_R"] = pa.array(dataset.pair[:, 1], pa.int32())
    for m in range(dataset.frequencies_hz.shape[1]):
        cols[f"f_{m + 1}"] = pa.array(dataset.frequencies_hz[:, m], pa.float64())
    cols["error_bound"] = pa.array(np.full(n, np.nan) if dataset.error_bound is None else dataset.error_bound,
                                   pa.float64())
    cols["fallback"] = pa.array(np.zeros(n, bool) if dataset.fallback is None else dataset.fallback, pa.bool_())
    cols["mac_min"] = pa.array(np.full(n, np.nan) if dataset.mac_min is None else dataset.mac_min, pa.float64())
    meta = {
        "format": _FORMAT,
        "version": FORMAT_VERSION,
        "model_key": dataset.model_key,
        "grid": list(dataset.patterns_L.shape[1:]),
        "patterns_L": _bits(dataset.patterns_L),
        "patterns_R": _bits(dataset.patterns_R),
        "feature_modes": list(dataset.feature_modes),
        "weights": dataset.weights.tolist(),
        "delta_grid": dataset.delta_grid.tolist(),
        "n_delta_modes": int(dataset.deltas.shape[1]),
        "n_modes": int(dataset.frequencies_hz.shape[1]),
        "meta": dataset.meta,
    }
    table = pa.table(cols).replace_schema_metadata({_META_KEY: json.dumps(meta, default=_json_default).encode()})
    path = Path(path)
    # Dictionary encoding only where values repeat (δ grid values, pattern indices, flags). Arrow tries it
    # on every column by default, and the frequency columns' dictionary pages cost read time for nothing:
    # without them the 1.76 M-sample file is 122 MB instead of 129 and loads in 0.47 s instead of 0.70
    # (medians of 8 fresh processes).
    repeated = [c for c in cols if c.startswith("delta_") or c in ("i_L", "i_R", "fallback")]
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, use_dictionary=repeated)
    return path


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"dataset meta value of type {type(o).__name__} is not JSON-serialisable")


def _first_line(exc: BaseException) -> str:
    """The first line of an exception's message, or its type name when the message is empty."""
    return (str(exc).splitlines() or [type(exc).__name__])[0]


_REQUIRED = ("format", "version", "model_key", "grid", "patterns_L", "patterns_R", "feature_modes", "weights",
             "delta_grid", "n_delta_modes", "n_modes")


def load_dataset(path: str | os.PathLike, *, model_key: str | None = None) -> Dataset:
    """Read and validate a dataset written by :func:`save_dataset`.

    Parameters
    ----------
    path : str or PathLike
    model_key : str, optional
        Key of the ROM in use (:func:`identify.sensitivity.model_key`); a dataset made with another model
        is refused.

    Returns
    -------
    Dataset

    Raises
    ------
    IdentifyError
        Not a Parquet file, missing or malformed metadata or columns, values off the δ grid, pair indices
        out of range, or a model key other than ``model_key``.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        pf = pq.ParquetFile(path)
    except (pa.ArrowException, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise IdentifyError(f"{path}: not a readable Parquet dataset ({_first_line(exc)})") from None
    meta = _read_meta(pf, path)
    grid = meta["grid"]
    PL = _unbits(meta["patterns_L"], grid, "patterns_L", path)
    PR = _unbits(meta["patterns_R"], grid, "patterns_R", path)
    D, pair, F, extra = _read_rows(pf, meta["n_delta_modes"], meta["n_modes"], path)
    g = _checked_grid(meta, D, path)
    if model_key is not None and meta["model_key"] != model_key:
        raise IdentifyError(f"{path}: dataset model key {str(meta['model_key'])[:16]}… does not match the ROM in use "
                            f"({model_key[:16]}…): the dataset was built with another model; rebuild it")
    try:
        return Dataset(deltas=D, pair=pair, frequencies_hz=F, patterns_L=PL, patterns_R=PR,
                       feature_modes=tuple(meta["feature_modes"]), weights=meta["weights"], delta_grid=g,
                       model_key=meta["model_key"], error_bound=extra.get("error_bound"),
                       fallback=extra.get("fallback"), mac_min=extra.get("mac_min"),
                       meta=meta.get("meta") or {})
    except IdentifyError as exc:
        raise IdentifyError(f"{path}: {exc}") from None


def _read_meta(pf, path: Path) -> dict:
    """The dataset's metadata from the Parquet schema, checked (format, version, fields, grid, mode counts)."""
    raw = (pf.schema_arrow.metadata or {}).get(_META_KEY)
    if raw is None:
        raise IdentifyError(f"{path}: no bladetwin dataset metadata (schema key {_META_KEY.decode()!r}); "
                            "expected a file written by identify.dataset.save_dataset")
    try:
        meta = json.loads(raw)
    except ValueError:
        raise IdentifyError(f"{path}: dataset metadata is not valid JSON") from None
    if not isinstance(meta, dict):
        raise IdentifyError(f"{path}: dataset metadata must be a JSON object")
    missing = [k for k in _REQUIRED if k not in meta]
    if missing:
        raise IdentifyError(f"{path}: dataset metadata lacks field(s) {missing}")
    if meta["format"] != _FORMAT or meta["version"] != FORMAT_VERSION:
        raise IdentifyError(f"{path}: dataset format {meta['format']!r} version {meta['version']!r}; expected "
                            f"{_FORMAT!r} version {FORMAT_VERSION}")
    grid = meta["grid"]
    if not (isinstance(grid, list) and len(grid) == 2 and all(isinstance(x, int) and x > 0 for x in grid)):
        raise IdentifyError(f"{path}: metadata field 'grid' = {grid!r}, expected [rows, cols]")
    nd, nm = meta["n_delta_modes"], meta["n_modes"]
    if not (isinstance(nd, int) and nd >= 1 and isinstance(nm, int) and nm >= 1):
        raise IdentifyError(f"{path}: n_delta_modes={nd!r}, n_modes={nm!r}: expected integers ≥ 1")
    return meta


def _read_rows(pf, nd: int, nm: int, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """δ (n, nd), pairs (n, 2), frequencies (n, nm) and the optional columns, read-only."""
    import pyarrow as pa

    schema = pf.schema_arrow
    names = [f"delta_{k + 1}" for k in range(nd)] + ["i_L", "i_R"] + [f"f_{m + 1}" for m in range(nm)]
    absent = [c for c in names if c not in schema.names]
    if absent:
        raise IdentifyError(f"{path}: dataset lacks column(s) {absent}")
    # Batch by batch straight into the final arrays: Arrow then reuses one batch's buffers instead of holding
    # the whole table beside its NumPy copy, and a million-row table makes every extra copy count (a fresh
    # page costs more than the copy on these machines: 1.76 M samples load in 0.5 s instead of 0.7–1.1 s).
    n = pf.metadata.num_rows
    D, pair, F = np.empty((n, nd)), np.empty((n, 2), np.int64), np.empty((n, nm))
    extra = {name: np.empty(n, dtype) for name, dtype in
             (("error_bound", np.float64), ("fallback", bool), ("mac_min", np.float64)) if name in schema.names}
    targets = [(D, k) for k in range(nd)] + [(pair, 0), (pair, 1)] + [(F, m) for m in range(nm)]
    targets += [(a, None) for a in extra.values()]
    wanted = names + list(extra)
    pos = 0
    try:
        for batch in pf.iter_batches(batch_size=_READ_BATCH, columns=wanted):
            rows = slice(pos, pos + batch.num_rows)
            for (out, k), name in zip(targets, wanted, strict=True):
                values = batch.column(name).to_numpy(zero_copy_only=False)  # by name: any column order
                if k is None:
                    out[rows] = values
                else:
                    out[rows, k] = values
            pos += batch.num_rows
    except (pa.ArrowException, OSError, ValueError, TypeError) as exc:  # any Arrow fault: refused
        raise IdentifyError(f"{path}: dataset rows cannot be read ({_first_line(exc)})") from None
    if pos != n:
        raise IdentifyError(f"{path}: the file declares {n} rows but holds {pos}")
    for a in (D, pair, F, *extra.values()):
        a.flags.writeable = False  # Dataset takes read-only arrays as they are
    return D, pair, F, extra


def _checked_grid(meta: dict, D: np.ndarray, path: Path) -> np.ndarray:
    """The metadata's δ grid, with every row's δ checked to lie on it."""
    try:
        g = np.asarray(meta["delta_grid"], dtype=np.float64)
    except (TypeError, ValueError):
        raise IdentifyError(f"{path}: metadata field 'delta_grid' must be a list of numbers") from None
    if g.ndim != 1 or g.size == 0:
        raise IdentifyError(f"{path}: metadata field 'delta_grid' must be a non-empty list of numbers")
    off = _off_grid(D, g)
    if off.any():
        r, k = np.argwhere(off)[0]
        raise IdentifyError(f"{path}: row {r}, delta_{k + 1} = {D[r, k]:.6g} is not a value of the δ grid {g.tolist()}")
    return g
