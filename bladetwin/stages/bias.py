"""The model bias on the filmed joints (design §2, step 4): measured against ROM frequencies, per tracked mode."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

import ema
from identify.dataset import Dataset
from identify.in_situ import population_centre
from identify.tracking import ModeTracker
from rom.contact import ContactPattern

__all__ = ["MATCH_WINDOW", "Features", "tracker_for", "match_to_reference", "subset_reference", "measured_tracked",
           "recentred_reference", "filmed_frequencies", "bias_spread", "known_bias", "features"]

#: Window of the frequency matching between measured and tracked modes (relative).
MATCH_WINDOW = 0.05

#: The last tracker built in this process, with the models and dataset it was built on (held, so that their ids
#: cannot be reused by other objects while the entry stands).
_TRACKERS: dict = {}


@dataclass(frozen=True, eq=False)
class Features:
    """Each joint's measured d1b frequencies on the dataset's tracked modes, and the ROM's bias.

    Attributes
    ----------
    joints : ndarray of int, shape (n_joints,)
        Joints with a disk–one-blade test, ascending.
    measured_hz : ndarray, shape (n_joints, n_tracked)
        EMA frequencies matched to the tracked modes (NaN: not found within :data:`MATCH_WINDOW`).
    bias, spread : ndarray, shape (n_tracked,)
        Median and std over the filmed joints of f_measured / f_ROM − 1 (zeros when not estimated).
    rom_known_hz : dict joint → ndarray, shape (n_tracked,)
        The ROM's tracked frequencies of each filmed joint with its film and δ.
    numerical_hz : ndarray, shape (n_joints, n_features), or None
        The ROM's feature frequencies with each joint's reference pattern (the numerical input).
    bias_estimated : bool
    """

    joints: np.ndarray
    measured_hz: np.ndarray
    bias: np.ndarray
    spread: np.ndarray
    rom_known_hz: dict
    numerical_hz: np.ndarray | None
    bias_estimated: bool

    @property
    def filmed_seen(self) -> np.ndarray:
        """How many filmed joints' tests found each tracked mode, shape (n_tracked,) (int)."""
        rows = [k for k, j in enumerate(self.joints) if int(j) in self.rom_known_hz]
        return np.isfinite(self.measured_hz[rows]).sum(axis=0)


def tracker_for(disk, blade, dataset: Dataset) -> ModeTracker:
    """The dataset's mode tracker, built once per process for the same (loaded) models and dataset."""
    k = (id(disk), id(blade), id(dataset))
    if k not in _TRACKERS:
        _TRACKERS.clear()
        _TRACKERS[k] = (disk, blade, dataset, ModeTracker.from_dataset(disk, blade, dataset))
    return _TRACKERS[k][3]


def match_to_reference(frequencies_hz: np.ndarray, reference_hz: np.ndarray, window: float = MATCH_WINDOW,
                       neighbours_hz: np.ndarray | None = None) -> np.ndarray:
    """Measured frequencies (Hz, shape (n_measured,)) matched one-to-one to tracked modes (Hungarian).

    ``neighbours_hz`` (Hz, shape (n_other,)): the model's modes in the band that are not tracked
    (:meth:`identify.tracking.ModeTracker.untracked_hz`). They take part in the pairing, so that a measured mode
    nearer to one of them is not given to a tracked mode whose own mode the test did not resolve.

    Returns, shape (n_modes,): the measured frequency matched to each of ``reference_hz``; NaN where none lies
    within ``window`` (relative).
    """
    f = np.asarray(frequencies_hz, float).ravel()
    ref = np.asarray(reference_hz, float).ravel()
    out = np.full(ref.size, np.nan)
    every = ref if neighbours_hz is None else np.r_[ref, np.asarray(neighbours_hz, float).ravel()]
    # an unpaired mode costs the window: pairing as many modes as possible first would let a neighbour take a
    # tracked mode's own measured mode and push the tracked one onto a pole further off
    rows, cols = ema.pair_by_frequency(every, f, window, unpaired_cost=True)
    mine = rows < ref.size
    out[rows[mine]] = f[cols[mine]]
    return out


def subset_reference(dataset: Dataset, deltas: np.ndarray) -> np.ndarray:
    """Mean tracked frequencies (Hz) of the dataset's δ row nearest to each joint's δ, shape (n_joints, n_modes)."""
    rows = np.unique(dataset.deltas, axis=0)
    out = np.empty((len(deltas), dataset.frequencies_hz.shape[1]))
    for k, d in enumerate(np.asarray(deltas, float)):
        near = rows[np.argmin(np.linalg.norm(rows - d, axis=1))]
        out[k] = dataset.frequencies_hz[np.all(dataset.deltas == near, axis=1)].mean(axis=0)
    return out


def measured_tracked(dataset: Dataset, d1b: dict[int, ema.ModalModel], joints, deltas,
                     neighbours_hz: np.ndarray | None = None) -> np.ndarray:
    """Each joint's EMA frequencies matched to the dataset's tracked modes (Hz; NaN: not found).

    ``deltas`` (shape (n_joints, n_delta_modes), relative): the dataset's δ row nearest to each joint's gives
    its expected frequencies. ``neighbours_hz`` (shape (n_joints, n_other)): each joint's untracked model modes
    (:func:`match_to_reference`). The pairing runs twice: the second time each tracked mode's reference is moved
    by the joints' median offset from the first (:func:`recentred_reference`). Returns shape (n_joints, n_tracked).
    """
    ref = subset_reference(dataset, deltas)
    others = [None] * len(ref) if neighbours_hz is None else list(neighbours_hz)

    def pair(reference):
        return np.array([match_to_reference(d1b[int(j)].frequencies_hz, reference[k], neighbours_hz=others[k])
                         for k, j in enumerate(joints)])

    return pair(recentred_reference(pair(ref), ref))


def recentred_reference(measured_hz: np.ndarray, reference_hz: np.ndarray) -> np.ndarray:
    """The joints' reference frequencies moved, per tracked mode, by the joints' median offset from them.

    Why: the model's error is shared by every joint (a realistic specimen's tracked mode 10 lies about 3 % below
    the model's, halfway to the next mode), and a window centred on the model can then give a joint's mode 10 the
    next mode up (3650 Hz) instead of its own (3398 Hz; the other joints agree on 3390–3450 Hz: design §8.54).
    The median over the joints (at least 3, :func:`identify.in_situ.population_centre`; else no move) is what the
    joints share, which a minority of mispaired joints cannot move.

    Parameters
    ----------
    measured_hz, reference_hz : ndarray, shape (n_joints, n_modes)
        The first pairing (Hz; NaN: none) and the references it was made against (Hz).

    Returns
    -------
    ndarray, shape (n_joints, n_modes)
    """
    offset = np.asarray(measured_hz, float) / np.asarray(reference_hz, float) - 1.0
    centre = population_centre(np.nan_to_num(offset), np.isfinite(offset))
    return np.asarray(reference_hz, float) * (1.0 + np.nan_to_num(centre))


def filmed_frequencies(tracker: ModeTracker, known: dict[int, ContactPattern], delta_all: np.ndarray, joints,
                       measured: np.ndarray) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """(measured, ROM) tracked frequencies (Hz) of each filmed joint with a d1b test: :func:`known_bias`'s inputs."""
    row = {int(j): k for k, j in enumerate(joints)}
    rom_hz = {j: tracker.track(p, delta_all[j - 1]).frequencies_hz for j, p in known.items() if j in row}
    return {j: measured[row[j]] for j in rom_hz}, rom_hz


def bias_spread(measured_hz: dict[int, np.ndarray], rom_hz: dict[int, np.ndarray]) -> np.ndarray:
    """Spread (std over the filmed joints) of f_measured / f_ROM − 1 per mode; 0 with fewer than 2 joints."""
    ratios = np.array([measured_hz[j] / rom_hz[j] - 1 for j in measured_hz])
    if len(ratios) < 2:
        return np.zeros(ratios.shape[1] if ratios.ndim == 2 else 0)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a mode no joint found: NaN, then 0 (nan_to_num)
        return np.nan_to_num(np.nanstd(ratios, axis=0))


def known_bias(measured_hz: dict[int, np.ndarray], rom_hz: dict[int, np.ndarray]) -> np.ndarray:
    """Per-mode relative bias of the ROM on the filmed joints: median of f_measured / f_ROM − 1 (0: no joint)."""
    ratios = np.array([measured_hz[j] / rom_hz[j] - 1 for j in measured_hz])
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a mode no joint found: NaN, then 0 (nan_to_num)
        b = np.nanmedian(np.where(np.isfinite(ratios), ratios, np.nan), axis=0) if ratios.size else np.zeros(0)
    return np.nan_to_num(b)


def features(disk, blade, dataset: Dataset, delta_all: np.ndarray, known: dict[int, ContactPattern],
             reference, *, n_delta_modes: int, bias: bool, **d1b) -> Features:
    """The node: match every d1b test's modes to the tracked ones, estimate the bias, track the references.

    ``d1b`` holds each joint's :class:`~bladetwin.stages.measured.TestFit` by test name (``d1b_07``).
    """
    tracker = tracker_for(disk, blade, dataset)
    fits = {int(name.rsplit("_", 1)[1]): fit.model for name, fit in d1b.items()}
    joints = np.array(sorted(fits))
    i, j = (int(x) for x in dataset.meta["reference"])  # the tracker's own pair (ModeTracker.from_dataset)
    # one solve for every joint: a blade's δ moves a neighbour by about a percent, well inside the 5 % window, and
    # a solve per joint took 8.7 s on the bundled campaign
    neighbours = tracker.untracked_hz(ContactPattern(dataset.patterns_L[i], dataset.patterns_R[j]))
    others = np.tile(neighbours, (len(joints), 1))
    measured = measured_tracked(dataset, fits, joints, delta_all[joints - 1, :n_delta_modes], others)
    meas_known, rom_known = filmed_frequencies(tracker, known, delta_all, joints, measured)
    n_tracked = dataset.frequencies_hz.shape[1]
    estimated = bias and len(rom_known) >= 2
    b = known_bias(meas_known, rom_known) if estimated else np.zeros(n_tracked)
    spread = bias_spread(meas_known, rom_known) if rom_known else np.zeros(n_tracked)
    num = None
    if reference is not None:
        feat = list(dataset.feature_modes)
        num = np.array([tracker.track(reference[j - 1], delta_all[j - 1]).frequencies_hz[feat] for j in joints])
    return Features(joints, measured, b, spread, rom_known, num, estimated)
