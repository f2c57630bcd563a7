"""The refinement after the k-NN (beyond the paper): a compass search per unfilmed joint, then every joint's answer."""

from __future__ import annotations

import numpy as np

from identify.dataset import Dataset
from identify.refine import RefinedPattern, refine_pattern
from identify.synthetic import SyntheticPatterns
from rom.cache import hash_inputs
from rom.contact import ContactPattern

from .bias import tracker_for
from .knn import Predictions
from .patterns import family_samplers

__all__ = ["refine_joint", "joint_patterns", "pattern_list"]


def refine_joint(disk, blade, dataset: Dataset, films, synthetic: SyntheticPatterns, predictions: Predictions,
                 delta_all: np.ndarray, store, *, input: str, joint: int, max_solves: int) -> RefinedPattern | None:
    """The node: refine one joint's k-NN pair for one input (:func:`identify.refine.refine_pattern`).

    Returns ``None`` where the k-NN gave the joint no pair (a feature mode missing from its EMA). The d1b solves
    go through a memo in the store shared by every joint's searches (they start from the same grids).
    """
    labels = predictions.labels[input]
    if joint not in labels:
        return None
    tracker = tracker_for(disk, blade, dataset)
    iL, iR = labels[joint][:2]
    row = _row(predictions, input, joint)
    from identify.tracking import model_key

    # The solves depend on the d1b ROM and the tracker's reference modes only (not on the family).
    memo = store.memo("refine-solves-" + hash_inputs(
        "refine-solves", model_key(tracker.disk, tracker.blade, tracker.formulation), tracker.shapes,
        tracker.weight, int(tracker.n_extra))[:32])
    # a feature mode the joint's EMA missed (NaN) is left out of its search
    found = np.isfinite(row)
    feats = [m for m, ok in zip(dataset.feature_modes, found, strict=True) if ok]
    return refine_pattern(tracker, *family_samplers(films), row[found], feats,
                          synthetic.gray_L[iL], synthetic.gray_R[iR], delta=delta_all[joint - 1],
                          max_solves=max_solves, tol_pct=predictions.tolerance_pct[input], memo=memo)


def _row(predictions: Predictions, input: str, joint: int) -> np.ndarray:
    """The joint's target features for ``input`` (rows of ``targets`` follow the joints with a d1b test)."""
    return np.asarray(predictions.targets[input][list(predictions.joints).index(joint)], float)


def joint_patterns(predictions: Predictions, known: dict, baseline: ContactPattern, *, input: str, n_blades: int,
                   **refined: RefinedPattern | None) -> list[ContactPattern]:
    """Every joint's answer for one input: its film, else its refined (or k-NN) pattern, else the baseline.

    ``refined`` holds the refinement of each unfilmed joint by name ``joint_07`` (absent without refinement).
    """
    pats = dict(predictions.patterns[input])
    for name, r in refined.items():
        if r is not None:
            pats[int(name.rsplit("_", 1)[1])] = r.pattern
    out = []
    for j in range(1, n_blades + 1):
        p = known.get(j, pats.get(j))
        out.append(baseline if p is None else p)
    return out


def pattern_list(known: dict, baseline: ContactPattern, *, n_blades: int) -> list[ContactPattern]:
    """The baseline's answer: the film at each filmed joint, the films' majority pattern elsewhere."""
    return [known.get(j, baseline) for j in range(1, n_blades + 1)]
