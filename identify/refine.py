"""Local refinement of an identified pattern pair: a compass search in the PCA family and the contact level.

Beyond the paper. The two-step k-NN (:mod:`identify.knn`) picks the best of the dataset's pre-drawn pattern
pairs (100 by default, §6.1), so its answer can be no closer to a joint than the nearest of them. Here the
k-NN's pair is the start of a local search over the same synthetic family, continuously:

* the PCA coefficients κ of each flank side (Eq. 32: map = μ + V κ), in units of the known coefficients'
  standard deviations σ_z (Eq. 30), bounded by ``max_sigma``;
* the contact level of each side: the threshold that turns the map into a contact grid. The k-NN's family
  uses one level for all joints (the known films' mean). A joint seated deeper or clamped harder has a
  larger contact area for the same pressure shape, and lowering the level is how the film's map shows it.
  Its unit is the standard deviation of the known maps' values.

Each candidate is scored by a direct, MAC-tracked d1b solve (:meth:`identify.tracking.ModeTracker.track`) at
the joint's blade δ: the mean absolute relative error on the feature modes against the target frequencies.
The search polls ± one step along every coordinate, moves to the best candidate if it improves the score
(and doubles that coordinate's step, up to 4× its first, since a joint far from the start needs long moves),
and halves the steps otherwise (a compass search; Kolda, Lewis & Torczon, SIAM Review 45, 2003). Thresholded
grids are piecewise constant in (κ, level), so candidates that give grids already scored are free; only new
grids count against ``max_solves``. Every step is deterministic: the same inputs give the same pattern.

The search only ever accepts a better score, so the refined pattern reproduces the target features at least
as well as its start. Three frequencies cannot pin down a pattern: a better feature match is not always a
closer contact area (docs/identify.md gives the figures on the virtual campaigns).
"""

from __future__ import annotations

import hashlib
import numbers
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from rom.contact import ContactPattern

from .errors import IdentifyError
from .sampler import PatternSampler, non_collinear
from .tracking import ModeTracker

__all__ = ["RefinedPattern", "SolveMemo", "refine_pattern"]

#: First step along a PCA coordinate, in σ_z.
KAPPA_STEP = 0.5
#: First step of the contact level, in standard deviations of the known maps' values.
LEVEL_STEP = 0.15


class SolveMemo(Protocol):
    """What :func:`refine_pattern` needs of a memo: ``get(key)`` (``None`` if absent) and ``memo[key] = value``.

    A ``dict`` will do; ``bladetwin run`` keeps one on disk for its forked workers.
    """

    def get(self, key: str, /) -> np.ndarray | None: ...

    def __setitem__(self, key: str, value: np.ndarray, /) -> None: ...


@dataclass(frozen=True, eq=False)
class RefinedPattern:
    """The result of :func:`refine_pattern` for one joint.

    Attributes
    ----------
    pattern : rom.ContactPattern
        The refined contact grids.
    kappa_L, kappa_R : ndarray of float64, shape (k_L,) and (k_R,)
        Their PCA coefficients (Eq. 32).
    level_L, level_R : float
        Their contact levels (thresholds on the maps' scale).
    error_pct : float
        Mean absolute relative error of the tracked feature frequencies against the target, %.
    start_error_pct : float
        The same for the start pattern.
    n_solves : int
        Direct d1b solves spent, the start's included.
    """

    pattern: ContactPattern
    kappa_L: np.ndarray
    kappa_R: np.ndarray
    level_L: float
    level_R: float
    error_pct: float
    start_error_pct: float
    n_solves: int


def _known_std(sampler: PatternSampler) -> float:
    """Standard deviation of the known maps' values, rebuilt from the PCA (exact: k = n_known − 1 keeps all)."""
    maps = sampler.mean_ + sampler.scores_ @ sampler.components_
    s = float(np.std(maps))
    return s if s > 0 else 1.0


def _next_crossing(excess: np.ndarray, rate: np.ndarray) -> float:
    """Smallest h > 0 at which some node of ``excess + h · rate`` changes sign (contact ⇔ excess > 0), a hair
    beyond it; inf if none does.

    Parameters
    ----------
    excess : ndarray, shape (n_nodes,)
        Map value minus level per node.
    rate : ndarray, shape (n_nodes,)
        Its change per unit of the search coordinate, in the direction polled.
    """
    on = excess > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(on & (rate < 0), -excess / rate, np.where(~on & (rate > 0), -excess / rate, np.inf))
    h = h[h >= 0]
    return float(h.min() * (1 + 1e-9) + 1e-12) if h.size else np.inf


def _check(tracker, samplers, target_hz, feature_modes, max_solves, max_sigma, tol_pct) -> tuple[np.ndarray, list[int]]:
    if not isinstance(tracker, ModeTracker):
        raise IdentifyError(f"tracker must be an identify.ModeTracker, got {type(tracker).__name__}")
    for side, s in zip("LR", samplers, strict=True):
        if not isinstance(s, PatternSampler) or not hasattr(s, "components_"):
            raise IdentifyError(f"sampler_{side} must be a fitted identify.PatternSampler")
    if samplers[0].grid_shape_ != samplers[1].grid_shape_:
        raise IdentifyError(f"the L and R samplers have different grids: {samplers[0].grid_shape_} and "
                            f"{samplers[1].grid_shape_}")
    feats = [int(m) for m in np.atleast_1d(feature_modes)]
    if not feats or any(not 0 <= m < tracker.n_modes for m in feats):
        raise IdentifyError(f"feature_modes must be 0-based mode indices in 0..{tracker.n_modes - 1}, got "
                            f"{list(np.atleast_1d(feature_modes))}")
    target = np.asarray(target_hz, dtype=np.float64).ravel()
    if target.shape != (len(feats),) or not np.all(np.isfinite(target)) or np.any(target <= 0):
        raise IdentifyError(f"target_hz must hold {len(feats)} positive, finite frequencies (one per feature "
                            f"mode), got {np.asarray(target_hz).tolist()}")
    if isinstance(max_solves, bool) or not isinstance(max_solves, numbers.Integral) or max_solves < 1:
        raise IdentifyError(f"max_solves must be a positive integer, got {max_solves!r}")
    if not (isinstance(max_sigma, numbers.Real) and max_sigma > 0):
        raise IdentifyError(f"max_sigma must be a positive number, got {max_sigma!r}")
    if not (isinstance(tol_pct, numbers.Real) and tol_pct >= 0):
        raise IdentifyError(f"tol_pct must be a number ≥ 0, got {tol_pct!r}")
    return target, feats


def refine_pattern(
    tracker: ModeTracker,
    sampler_L: PatternSampler,
    sampler_R: PatternSampler,
    target_hz,
    feature_modes,
    start_L,
    start_R,
    *,
    delta=None,
    max_solves: int = 100,
    max_sigma: float = 4.0,
    tol_pct: float = 0.0,
    memo: SolveMemo | None = None,
) -> RefinedPattern:
    """Refine one joint's pattern pair by a compass search (module docstring).

    Parameters
    ----------
    tracker : ModeTracker
        The dataset's tracker (:meth:`ModeTracker.from_dataset`), so frequencies are tracked as the k-NN's.
    sampler_L, sampler_R : PatternSampler
        The fitted samplers of the synthetic family, per flank side; their ``threshold_`` is the start level.
    target_hz : array_like, shape (n_features,)
        The joint's frequencies of the feature modes, Hz (measured and bias-corrected, or the numerical input).
    feature_modes : sequence of int, length n_features
        0-based indices into the tracked modes (``Dataset.feature_modes``).
    start_L, start_R : array_like, shape (rows, cols)
        Grayscale maps of the start pair, e.g. the k-NN's synthetic pair (``SyntheticPatterns.gray_L[i_L]``).
        They are projected on the PCA (Eq. 29).
    delta : float or array_like, optional
        The joint's blade δ (relative; a vector perturbs the first modes), as in :meth:`ModeTracker.track`.
    max_solves : int
        Most direct d1b solves, the start's included. Default 100 (about 13 s at the default level).
    max_sigma : float
        Bound on every PCA coordinate, |κ_z| ≤ max_sigma · σ_z. Default 4.
    tol_pct : float
        Stop once the error is at most this, %. For measured targets, the model error's size (e.g. the ROM's
        scatter against the filmed joints): fitting a measurement closer than its model error fits that
        error, not the contact (the discrepancy principle). Default 0: the numerical input has none.
    memo : SolveMemo, optional
        A mapping, e.g. a ``dict``, of tracked frequencies (Hz, shape (n_modes,)) of the grids already
        solved with this ``tracker``, keyed by a hash of the two grids and ``delta``. It is read before each
        solve and written after it. Share one memo between searches of the same joint, e.g. for several
        targets, since their first polls coincide. A memo hit counts against ``max_solves`` like a solve,
        so the search and its result do not depend on the memo.

    Returns
    -------
    RefinedPattern

    Raises
    ------
    IdentifyError
        Unfitted samplers, grids that differ, a target or feature list of the wrong size, bad limits, or a
        start pair that is not a valid contact pattern.
    """
    samplers = (sampler_L, sampler_R)
    target, feats = _check(tracker, samplers, target_hz, feature_modes, max_solves, max_sigma, tol_pct)
    search = _Search.start(tracker, samplers, target, feats, start_L, start_R, delta, memo, max_solves, max_sigma)
    x = search.x0
    step0 = np.concatenate([np.full(sum(search.k), KAPPA_STEP), [LEVEL_STEP, LEVEL_STEP]])
    step = step0.copy()
    best = search.score(x)
    if not np.isfinite(best):
        raise IdentifyError("the start pair is not a valid contact pattern (empty, full or collinear grid)")
    start = best
    while search.n_solved < max_solves and step.max() >= KAPPA_STEP / 64 and 100 * best > tol_pct:
        cands = search.polls(x, step)
        vals = [search.score(c) for c in cands]
        i = int(np.argmin(vals))
        if vals[i] < best:
            # a successful direction is worth a longer stride next time: far-off joints need long moves
            best, x = vals[i], cands[i]
            step[i // 2] = min(2 * step[i // 2], 4 * step0[i // 2])
        else:
            step = step / 2
    kL, kR, tL, tR, gL, gR = search.decode(x)
    return RefinedPattern(ContactPattern(gL, gR), kL, kR, tL, tR, 100 * best, 100 * start, search.n_solved)


@dataclass(eq=False)
class _Search:
    """One compass search's state: the family's search coordinates, the grids scored so far, the solve budget.

    Search coordinates: κ_L/σ_L, κ_R/σ_R, then the two level offsets in their units (of the known maps' spread).
    """

    tracker: ModeTracker
    samplers: tuple
    target: np.ndarray
    feats: list
    delta: object
    memo: object
    max_solves: int
    k: tuple[int, int]
    sig: tuple[np.ndarray, np.ndarray]
    lev_unit: tuple[float, float]
    x0: np.ndarray
    bound: np.ndarray
    n_nodes: int
    scores: dict = field(default_factory=dict)
    n_solved: int = 0  # direct solves so far (invalid grids cost none)

    @classmethod
    def start(cls, tracker, samplers, target, feats, start_L, start_R, delta, memo, max_solves, max_sigma):
        kappa0 = [s.transform(np.asarray(g, np.float64)[None])[0] for s, g in zip(samplers, (start_L, start_R),
                                                                                    strict=True)]
        k = (len(kappa0[0]), len(kappa0[1]))
        sig = tuple(np.where(s.score_std_ > 0, s.score_std_, 1.0) for s in samplers)
        lev_unit = tuple(_known_std(s) for s in samplers)
        x = np.concatenate([kappa0[0] / sig[0], kappa0[1] / sig[1], [0.0, 0.0]])
        bound = np.maximum(max_sigma, np.abs(x[:-2]))  # a start beyond the bound stays allowed
        return cls(tracker, samplers, target, feats, delta, memo, max_solves, k, sig, lev_unit, x, bound,
                   int(np.prod(samplers[0].grid_shape_)))

    def decode(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float, np.ndarray, np.ndarray]:
        (sL, sR), k = self.samplers, self.k
        kL, kR = x[: k[0]] * self.sig[0], x[k[0]: k[0] + k[1]] * self.sig[1]
        tL = sL.threshold_ + x[-2] * self.lev_unit[0]
        tR = sR.threshold_ + x[-1] * self.lev_unit[1]
        gL = sL.inverse_transform(kL[None])[0] > tL
        gR = sR.inverse_transform(kR[None])[0] > tR
        return kL, kR, float(tL), float(tR), gL, gR

    def score(self, x: np.ndarray) -> float:
        """Mean relative feature error of the grids at ``x``; inf for an invalid grid or past the budget."""
        if np.any(np.abs(x[:-2]) > self.bound):
            return np.inf
        *_, gL, gR = self.decode(x)
        key = gL.tobytes() + gR.tobytes()
        if key not in self.scores:
            valid = all(0 < g.sum() < self.n_nodes and non_collinear(g) for g in (gL, gR))
            if not valid:
                self.scores[key] = np.inf
            elif self.n_solved >= self.max_solves:
                return np.inf  # out of budget: not scored, not cached
            else:
                f = _tracked(self.tracker, gL, gR, self.delta, self.memo)[self.feats]
                self.n_solved += 1
                self.scores[key] = float(np.mean(np.abs(f / self.target - 1)))
        return self.scores[key]

    def polls(self, x: np.ndarray, step: np.ndarray) -> list[np.ndarray]:
        """Both directions along every coordinate, each at least to the next grid change."""
        # Rates of (map − level) per unit of each search coordinate, per side: grids change only where a node's
        # value crosses its level, so every poll goes at least to the next crossing (no poll repeats the grid).
        (sL, sR), k, sig = self.samplers, self.k, self.sig
        rates = [(0, sig[0][z] * sL.components_[z]) for z in range(k[0])]
        rates += [(1, sig[1][z] * sR.components_[z]) for z in range(k[1])]
        rates += [(0, np.full(self.n_nodes, -self.lev_unit[0])), (1, np.full(self.n_nodes, -self.lev_unit[1]))]
        kL, kR, tL, tR, _, _ = self.decode(x)
        excess = (sL.inverse_transform(kL[None]).ravel() - tL, sR.inverse_transform(kR[None]).ravel() - tR)
        cands = []
        for z, (side, g) in enumerate(rates):
            for sign in (1.0, -1.0):
                c = x.copy()
                c[z] += sign * max(step[z], _next_crossing(excess[side], sign * g))
                cands.append(c)
        return cands


def _tracked(tracker: ModeTracker, gL: np.ndarray, gR: np.ndarray, delta,
             memo: SolveMemo | None) -> np.ndarray:
    """Tracked frequencies (Hz, shape (n_modes,)) of the grids (gL, gR) at ``delta``, from ``memo`` if there."""
    if memo is None:
        return tracker.track(ContactPattern(gL, gR), delta).frequencies_hz
    # δ's shape is part of the key: a scalar δ perturbs every blade mode, a vector only its first entries.
    d = np.zeros(0) if delta is None else np.asarray(delta, np.float64)
    h = hashlib.sha256()
    for a in (np.asarray(gL.shape, np.int64), gL, gR, np.asarray((delta is None, d.ndim, d.size), np.int64), d):
        h.update(np.ascontiguousarray(a).tobytes())
    key = h.hexdigest()[:32]
    f = memo.get(key)
    if f is None or np.shape(f) != (tracker.n_modes,):
        f = tracker.track(ContactPattern(gL, gR), delta).frequencies_hz
        memo[key] = f
    return np.asarray(f, np.float64)
