"""The two-step k-NN (paper §6.4) for every joint and input: experimental, without bias, numerical."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from identify.dataset import Dataset
from identify.knn import TwoStepKNN, query_matrix
from identify.validation import GridError, grid_error
from rom.contact import ContactPattern

from .bias import MATCH_WINDOW, Features

__all__ = ["INPUTS", "Predictions", "predict"]

#: The identification's inputs: the measurement with the bias removed, without it, and the ROM with the
#: reference patterns (a check of the method, only where every joint has a reference pattern).
INPUTS = ("experimental", "experimental_no_bias", "numerical")


@dataclass(frozen=True, eq=False)
class Predictions:
    """The k-NN's answer per input.

    Attributes
    ----------
    joints : ndarray of int, shape (n_joints,)
        The joints with a disk–one-blade test (the rows of ``targets``).
    patterns : dict input → dict joint → ContactPattern
    labels : dict input → dict joint → tuple
        ``(i_L, i_R, distance, beyond, outside)``: the pair (0-based), its distance, how far each feature lies
        beyond what the synthetic pairs reach at the joint's δ (relative, shape (n_features,)) and whether that
        exceeds twice the ROM's scatter on the filmed joints (experimental input only; else ``None``).
    targets : dict input → ndarray, shape (n_joints, n_features)
        The feature frequencies (Hz) each input queried with (the refinement's targets).
    tolerance_pct : dict input → float
        Where a refinement of that input stops: the model error the measured input carries (the numerical
        input, its control, stops where the experimental one does).
    step1 : identify.validation.GridError
        Step 1's δ grid error on the experimental input (Eq. 40).
    missing : list of int
        Joints whose EMA found none of the feature modes (they get the baseline pattern).
    partial : dict joint → list of int
        Joints whose EMA missed some feature modes (1-based tracked modes): they are matched on the others.
    """

    joints: np.ndarray
    patterns: dict
    labels: dict
    targets: dict
    tolerance_pct: dict
    step1: GridError
    missing: list
    partial: dict


def _query(knn: TwoStepKNN, ds: Dataset, joints, deltas, features: np.ndarray) -> tuple[dict, dict, np.ndarray]:
    """Each joint's nearest pair, on the feature modes its EMA found.

    A joint whose EMA missed some feature modes (NaN) is matched on the others: a k-NN with those features'
    weights set to 0 (Eq. 33 then ignores them). A joint that found none gets no pair (the baseline).
    """
    found = np.isfinite(features)
    pats, labels = {}, {}
    delta = np.zeros(deltas.shape)
    beyond = np.zeros(features.shape)
    rows_of: dict[tuple, list[int]] = {}
    for k, mask in enumerate(found):
        if mask.any():
            rows_of.setdefault(tuple(mask), []).append(k)
    for mask, rows in rows_of.items():
        est = knn if all(mask) else TwoStepKNN.from_dataset(ds, weights=knn.weights_ * np.array(mask, float))
        match = est.match(query_matrix(deltas[rows], np.where(found[rows], features[rows], 0.0)))
        delta[rows] = match.delta
        beyond[rows] = np.where(found[rows], match.beyond / np.where(found[rows], features[rows], 1.0), 0.0)
        for r, k in enumerate(rows):
            iL, iR = (int(x) for x in match.label[r, 0])
            j = int(joints[k])
            pats[j] = ContactPattern(ds.patterns_L[iL], ds.patterns_R[iR])
            labels[j] = (iL, iR, float(match.distance[r, 0]), beyond[k], None)
    return pats, labels, delta


def _targets(f: Features, feat: list[int], bias: bool) -> tuple[dict, dict]:
    f_exp = f.measured_hz[:, feat]
    targets = {"experimental": f_exp / (1 + f.bias[feat])}
    # Measured targets are fitted down to the model error (the ROM's scatter on the filmed joints; without the
    # bias correction, bias and scatter together), not below it. The numerical input is the control of that same
    # procedure (the paper's Case A: "the intrinsic accuracy of the identification procedure itself"), so its
    # search stops by the same rule. Fitted on down to its 40 solves, three exact frequencies moved the bundled
    # campaign's area error from 12.2 to 13.0 pp for 95 s of solves (design §8.71).
    tol = {"experimental": float(100 * np.mean(f.spread[feat]))}
    if bias:
        targets["experimental_no_bias"] = f_exp
        tol["experimental_no_bias"] = float(100 * np.mean(np.hypot(f.bias[feat], f.spread[feat])))
    if f.numerical_hz is not None:
        targets["numerical"], tol["numerical"] = f.numerical_hz, tol["experimental"]
    return targets, tol


def predict(dataset: Dataset, features: Features, delta_all: np.ndarray, known: dict, *, n_delta_modes: int,
            bias: bool, step_pct: float) -> Predictions:
    """The node: query the k-NN with each input's features, flag the joints beyond the synthetic family."""
    from identify.errors import IdentifyError

    feat = list(dataset.feature_modes)
    knn = TwoStepKNN.from_dataset(dataset)
    joints = features.joints
    deltas = delta_all[joints - 1, :n_delta_modes]
    targets, tol = _targets(features, feat, bias)
    found = np.isfinite(targets["experimental"])
    missing = joints[~found.any(axis=1)].tolist()
    partial = {int(j): [feat[m] + 1 for m in np.flatnonzero(~row)] for j, row in zip(joints, found, strict=True)
               if row.any() and not row.all()}
    if len(missing) == len(joints):
        raise IdentifyError(f"no disk-one-blade test has any of the feature modes {[m + 1 for m in feat]} within "
                            f"{100 * MATCH_WINDOW:.0f} % of the dataset's")
    pats, labels, step1_delta = {}, {}, None
    for name, t in targets.items():
        pats[name], labels[name], d = _query(knn, dataset, joints, deltas, t)
        step1_delta = d if name == "experimental" else step1_delta
    # A joint whose measured features lie beyond what the synthetic pairs reach, by more than twice the ROM's
    # scatter on the filmed joints (the model error the bias correction leaves), is one the family does not
    # cover: the k-NN can only return the family's nearest edge for it.
    limit = 2 * features.spread[feat]
    for j, lab in labels["experimental"].items():
        if j not in known:
            labels["experimental"][j] = (*lab[:4], bool(np.any(np.abs(lab[3]) > limit)))
    if not bias:
        pats["experimental_no_bias"], labels["experimental_no_bias"] = pats["experimental"], labels["experimental"]
    step1 = grid_error(step1_delta, deltas, step_pct / 100)
    return Predictions(joints, pats, labels, targets, tol, step1, missing, partial)
