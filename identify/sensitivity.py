"""Sensitivity of the disk–one-blade frequencies to contact mistuning (paper §6.2, Figs. 15–16).

The tuned blade (δ = 0) is assembled with every left × right pair of synthetic patterns, and the first
``n_modes`` modes of each pair are **tracked by MAC** against the modes of one reference pair, never taken by
index: a contact change moves modes past each other (the tests show a swap on the coarse model), and the
i-th frequency of a pair would then describe another mode than the i-th of its neighbour.

Tracking
    The reference pair is the *medoid* of each side (the pattern with the least total Hamming distance to the
    others of its side, :func:`reference_pair`): a real pattern of the set, central, so that every pair's
    modes stay close to its modes. Its first ``n_modes`` elastic modes are the tracked set. For each pair
    the lowest ``n_modes + n_extra`` elastic modes are candidates; an assignment (Hungarian, maximum total
    MAC) gives each reference mode one candidate. The MAC is mass-weighted with the reference pair's mass
    matrix, ``(aᵀ M b)² / ((aᵀ M a)(bᵀ M b))``: all patterns share the ROM's coordinates (CB disk coordinates,
    blade modal coordinates, accessory DOFs; the exact formulation drops only force-free DOFs, design
    §8.7), and mixing modal amplitudes with displacements needs a physical inner product.

Output
    The frequency maps (n_L, n_R, n_modes), the standard deviation of each mode over all pairs (Hz and % of
    its mean, population std), the feature modes (the ``n_features`` largest relative std, returned in
    ascending mode order: the paper found modes 5, 6, 8) and default weights for Eq. 33: the features' std in
    Hz scaled to sum 1 (the more contact-sensitive mode weighs more, paper §6.4; the same rule as the
    k-NN's ``weights="sensitivity"``).

The pencils, the shared coordinates and the mode assignment are the disk–one-blade tracker's
(:mod:`identify.tracking`), the same as the dataset's and the tracker's.
"""

from __future__ import annotations

import dataclasses
import sys
import warnings
from dataclasses import dataclass, field

import numpy as np
from tqdm.auto import tqdm

from ema.mac import mac as ema_mac
from rom.craig_bampton import CraigBamptonModel
from rom.modal import dense_modes, single_thread_blas
from rom.rubin import RubinModel

from .errors import IdentifyError
from .tracking import assign_modes, check_formulation, common_coords, model_key, pencil_checked

__all__ = [
    "Sensitivity",
    "sensitivity",
    "summarize",
    "reference_pair",
    "check_patterns",
    "MAC_WARN",
]

#: Tracked modes whose MAC with their reference mode falls below this are reported (warnings.warn).
MAC_WARN = 0.5


@dataclass(frozen=True, eq=False)
class Sensitivity:
    """Tuned-blade frequency maps over all pattern pairs, tracked by MAC (paper §6.2).

    Attributes
    ----------
    frequencies_hz : ndarray of float64, shape (n_L, n_R, n_modes)
        Frequency of reference mode ``m`` in pair (i_L, i_R) (Hz): the maps of paper Fig. 16.
    mean_hz, std_hz : ndarray of float64, shape (n_modes,)
        Mean and population standard deviation over all n_L · n_R pairs (Hz), paper Fig. 15.
    std_rel_pct : ndarray of float64, shape (n_modes,)
        ``100 · std_hz / mean_hz`` (%).
    feature_modes : tuple of int
        0-based tracked modes chosen as k-NN features (ascending).
    weights : ndarray of float64, shape (n_features,)
        Default weights w_i of Eq. 33 for ``feature_modes`` (sum 1).
    reference : (int, int)
        The reference pair (i_L, i_R), 0-based.
    mode_index : ndarray of int, shape (n_L, n_R, n_modes)
        Rank (0-based, among the pair's elastic modes by ascending frequency) of the mode tracking each
        reference mode. Rows other than ``arange(n_modes)`` are pairs where contact reorders the modes.
    mac : ndarray of float64, shape (n_L, n_R, n_modes)
        Mass-weighted MAC of each tracked mode with its reference mode.
    patterns_L, patterns_R : ndarray of bool, shape (n_L, rows, cols), (n_R, rows, cols)
    model_key : str
        :func:`model_key` of the ROM used.
    """

    frequencies_hz: np.ndarray
    mean_hz: np.ndarray
    std_hz: np.ndarray
    std_rel_pct: np.ndarray
    feature_modes: tuple[int, ...]
    weights: np.ndarray
    reference: tuple[int, int]
    mode_index: np.ndarray
    mac: np.ndarray
    patterns_L: np.ndarray
    patterns_R: np.ndarray
    model_key: str
    meta: dict = field(default_factory=dict)

    @property
    def n_modes(self) -> int:
        return int(self.frequencies_hz.shape[2])

    def with_features(self, feature_modes, weights=None) -> Sensitivity:
        """The same analysis with other feature modes (0-based) and weights (default: the std rule)."""
        modes = check_features(feature_modes, self.n_modes)
        w = default_weights(self.std_hz, modes) if weights is None else check_weights(weights, len(modes))
        return dataclasses.replace(self, feature_modes=modes, weights=w)


# ----------------------------------------------------------------------------------------- validation
def check_patterns(patterns, name: str, grid: tuple[int, int] | None = None) -> np.ndarray:
    """A read-only boolean copy of a pattern stack of shape (n, rows, cols); IdentifyError otherwise.

    Parameters
    ----------
    patterns : array_like of bool (or 0/1), shape (n, rows, cols)
    name : str
        Used in messages (e.g. ``"patterns_L"``).
    grid : (int, int), optional
        The model's contact grid (rows, cols).
    """
    a = np.asarray(patterns)
    if a.ndim != 3 or a.shape[0] == 0:
        raise IdentifyError(f"{name} has shape {a.shape}, expected (n_patterns ≥ 1, rows, cols)")
    if a.dtype != bool:
        if a.dtype.kind not in "iuf" or not np.isin(a, (0, 1)).all():
            raise IdentifyError(f"{name} must be boolean (or 0/1), got dtype {a.dtype}")
        a = a.astype(bool)
    if grid is not None and a.shape[1:] != tuple(grid):
        raise IdentifyError(f"{name} has grid {a.shape[1:]}, the model's contact grid is {tuple(grid)}")
    a = a.copy()
    a.flags.writeable = False
    return a


def check_features(feature_modes, n_modes: int) -> tuple[int, ...]:
    modes = tuple(int(m) for m in np.atleast_1d(np.asarray(feature_modes)).ravel())
    if not modes or len(set(modes)) != len(modes) or min(modes) < 0 or max(modes) >= n_modes:
        raise IdentifyError(f"feature_modes {modes}: expected distinct 0-based modes in 0..{n_modes - 1}")
    return modes


def check_weights(weights, n: int) -> np.ndarray:
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n,) or not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
        raise IdentifyError(f"weights {np.array2string(w, precision=4)}: expected {n} finite values ≥ 0, not all 0")
    return w.copy()


def blade_grid(blade: RubinModel) -> tuple[int, int]:
    g = blade.meta.get("grid")
    if g is None:
        raise IdentifyError("the blade model carries no contact-grid shape (meta['grid']); use rom.reduce_blade()")
    return int(g[0]), int(g[1])


# ----------------------------------------------------------------------------------------- helpers
def reference_pair(patterns_L, patterns_R) -> tuple[int, int]:
    """Medoid of each side: the pattern with the least summed Hamming distance to the others (ties: lowest).

    Parameters
    ----------
    patterns_L, patterns_R : array_like of bool, shape (n, rows, cols)
    """
    out = []
    for name, P in (("patterns_L", patterns_L), ("patterns_R", patterns_R)):
        X = check_patterns(P, name).reshape(len(P), -1).astype(np.int64)
        ham = (X[:, None, :] != X[None, :, :]).sum(axis=2)
        out.append(int(np.argmin(ham.sum(axis=1))))
    return out[0], out[1]


def default_weights(std_hz: np.ndarray, feature_modes: tuple[int, ...]) -> np.ndarray:
    """Eq. 33 weights: the features' std (Hz) scaled to sum 1 (uniform if all are 0)."""
    s = np.asarray(std_hz, dtype=np.float64)[list(feature_modes)]
    return s / s.sum() if s.sum() > 0 else np.full(len(feature_modes), 1.0 / len(feature_modes))


def summarize(frequencies_hz: np.ndarray, n_features: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                          tuple[int, ...], np.ndarray]:
    """Mean, std (Hz), relative std (%), the most sensitive modes and their weights (paper §6.2).

    Parameters
    ----------
    frequencies_hz : ndarray, shape (..., n_modes)
        Tracked frequencies, any leading shape (e.g. (n_L, n_R)).
    n_features : int
        How many modes to pick by largest relative std.

    Returns
    -------
    mean_hz, std_hz, std_rel_pct : ndarray, shape (n_modes,)
    feature_modes : tuple of int (ascending)
    weights : ndarray, shape (n_features,)
    """
    f = np.asarray(frequencies_hz, dtype=np.float64)
    f = f.reshape(-1, f.shape[-1])
    n_modes = f.shape[1]
    if not isinstance(n_features, (int, np.integer)) or not 1 <= n_features <= n_modes:
        raise IdentifyError(f"n_features={n_features!r}: expected an integer in 1..{n_modes}")
    mean = f.mean(axis=0)
    std = f.std(axis=0)
    rel = 100.0 * std / mean
    # Stable sort on −rel: equal sensitivities keep the lower mode first.
    modes = tuple(sorted(int(m) for m in np.argsort(-rel, kind="stable")[:n_features]))
    return mean, std, rel, modes, default_weights(std, modes)


def warn_low_mac(mac: np.ndarray, what: str) -> None:
    bad = mac < MAC_WARN
    if bad.any():
        i = np.unravel_index(np.argmin(mac), mac.shape)
        warnings.warn(f"{int(bad.sum())} tracked mode(s) of {what} have MAC < {MAC_WARN} with their reference mode; "
                      f"worst {mac[i]:.3f} at index {tuple(int(x) for x in i)} (pattern pair, mode): tracking "
                      "there is uncertain; consider more candidate modes (n_extra) or a closer reference pair",
                      stacklevel=3)


# ----------------------------------------------------------------------------------------- public
def sensitivity(
    disk: CraigBamptonModel,
    blade: RubinModel,
    patterns_L,
    patterns_R,
    *,
    n_modes: int = 10,
    n_features: int = 3,
    reference: tuple[int, int] | None = None,
    n_extra: int = 4,
    formulation: str = "exact",
    progress: bool = True,
) -> Sensitivity:
    """Tracked tuned-blade d1b frequencies over all pattern pairs and their spread (paper §6.2).

    One direct dense solve (:func:`rom.modal.dense_modes`) per pair.

    Parameters
    ----------
    disk : rom.CraigBamptonModel
        Disk reduced on one slot.
    blade : rom.RubinModel
        Its δ is ignored: the blade is tuned here.
    patterns_L, patterns_R : array_like of bool, shape (n_L, rows, cols), (n_R, rows, cols)
        Synthetic contact grids per flank; every pair must make a valid :class:`rom.ContactPattern`.
    n_modes : int
        Tracked modes (the paper: the first 10).
    n_features : int
        Feature modes picked by relative std.
    reference : (int, int), optional
        Reference pair (0-based); default :func:`reference_pair`.
    n_extra : int
        Extra candidate modes per pair above ``n_modes`` (a tracked mode may have moved up).
    formulation : {"exact", "paper"}
    progress : bool
        tqdm bar on stderr.

    Returns
    -------
    Sensitivity

    Raises
    ------
    IdentifyError
        Bad patterns, counts or reference.

    Warns
    -----
    UserWarning
        If a tracked mode has MAC < :data:`MAC_WARN` with its reference mode.
    """
    check_formulation(formulation)
    grid = blade_grid(blade)
    PL, PR = check_patterns(patterns_L, "patterns_L", grid), check_patterns(patterns_R, "patterns_R", grid)
    n_cand = _check_counts(n_modes, n_extra)
    ref = check_reference(reference, PL, PR)
    freq, mac = np.empty((len(PL), len(PR), n_modes)), np.empty((len(PL), len(PR), n_modes))
    index = np.empty((len(PL), len(PR), n_modes), np.int64)
    W = ref_shapes = common = None
    order = [ref] + [(i, j) for i in range(len(PL)) for j in range(len(PR)) if (i, j) != ref]  # reference first
    for i, j in tqdm(order, desc="sensitivity", unit="pair", file=sys.stderr, disable=not progress):
        K, M = pencil_checked(disk, blade, PL[i], PR[j], i, j, formulation)
        with single_thread_blas():  # small dense products: one thread (see tracking.d1b_pencil)
            dm = dense_modes(K, M, n_cand, max_rigid=6)
            if dm.frequencies_hz.size < n_cand:
                raise IdentifyError(f"pair ({i}, {j}): the ROM has only {dm.frequencies_hz.size} elastic modes, "
                                    f"n_modes + n_extra = {n_cand} requested")
            if W is None:  # the reference pair comes first
                common = common_coords(K.shape[0], disk, blade)
                W = M[np.ix_(common, common)]
                ref_shapes = dm.shapes[common, :n_modes]
            cmac = ema_mac(ref_shapes, dm.shapes[common], weight=W)
        cols, vals = assign_modes(cmac)
        freq[i, j], index[i, j], mac[i, j] = dm.frequencies_hz[cols], cols, vals
    warn_low_mac(mac, "the sensitivity maps")
    mean, std, rel, modes, w = summarize(freq, n_features)
    return Sensitivity(frequencies_hz=freq, mean_hz=mean, std_hz=std, std_rel_pct=rel, feature_modes=modes, weights=w,
                       reference=ref, mode_index=index, mac=mac, patterns_L=PL, patterns_R=PR,
                       model_key=model_key(disk, blade, formulation),
                       meta={"formulation": formulation, "n_extra": int(n_extra)})


def _check_counts(n_modes, n_extra) -> int:
    """Checks the tracked and extra mode counts; returns the candidates per pair, their sum."""
    if not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise IdentifyError(f"n_modes={n_modes!r}: expected an integer ≥ 1")
    if not isinstance(n_extra, (int, np.integer)) or n_extra < 0:
        raise IdentifyError(f"n_extra={n_extra!r}: expected an integer ≥ 0")
    return int(n_modes + n_extra)


def check_reference(reference, PL: np.ndarray, PR: np.ndarray) -> tuple[int, int]:
    if reference is None:
        return reference_pair(PL, PR)
    try:
        i, j = (int(x) for x in reference)
    except (TypeError, ValueError):
        raise IdentifyError(f"reference={reference!r}: expected a pair (i_L, i_R) of 0-based indices") from None
    if not (0 <= i < len(PL) and 0 <= j < len(PR)):
        raise IdentifyError(f"reference={reference!r}: expected i_L in 0..{len(PL) - 1}, i_R in 0..{len(PR) - 1}")
    return i, j
