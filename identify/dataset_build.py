"""The identification dataset's build: δ grid × pattern pairs → tracked disk–one-blade frequencies (paper §6.3).

Every δ row of the grid (one value per blade mode for the first ``n_delta_modes`` blade modes, Eq. 19) is
combined with every left × right pattern pair, and the disk–one-blade ROM (Eq. 22) gives the first
``n_modes`` frequencies, each **tracked by MAC**: a sample's mode is matched to its pair's δ = 0 mode, and that
one to the reference pair's mode (:mod:`identify.tracking`). Column ``m`` of ``frequencies_hz`` therefore
always describes the same physical mode, and all ``n_modes`` are stored, so another feature choice needs no
rebuild. The result is a :class:`identify.dataset.Dataset`.

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

A build is split into independent pattern pairs (:func:`plan_dataset`, :func:`solve_pair`,
:func:`assemble_dataset`), so :mod:`identify.dataset_parts` can run them in parts or on Dask.
"""

from __future__ import annotations

import itertools
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np
from tqdm.auto import tqdm

from ema.mac import mac
from rom.craig_bampton import CraigBamptonModel
from rom.modal import dense_modes, single_thread_blas
from rom.rubin import RubinModel

from .dataset import Dataset
from .delta_grid import check_grid
from .errors import IdentifyError
from .reanalysis import RitzModel, ritz_model, solve_ritz
from .sensitivity import (
    MAC_WARN,
    Sensitivity,
    blade_grid,
    check_patterns,
    check_reference,
    summarize,
    warn_low_mac,
)
from .tracking import assign_modes, check_formulation, common_coords, model_key, pencil_checked, update_index

__all__ = [
    "DatasetPlan",
    "PairResult",
    "build_dataset",
    "plan_dataset",
    "solve_pair",
    "assemble_dataset",
    "DEFAULT_TOL",
]

#: Default bound on a stored frequency's relative error before a sample falls back to a direct solve.
#: Ten times below the 0.01 % accuracy target; the bound is rigorous (reanalysis module docstring).
DEFAULT_TOL = 1e-5
#: δ rows solved per batch (bounds the s × s × batch work arrays).
_BATCH = 4096


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
        Relative δ values (e.g. :func:`identify.delta_grid.grid_from_deltas`); every δ row is a tuple of them.
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
    g = check_grid(delta_grid)
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
