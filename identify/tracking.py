"""The disk–one-blade tracker: one pattern's d1b pencil, its shared coordinates, and MAC mode assignment (Eq. 34).

Everything that compares d1b frequencies across contact patterns and blade δ needs the same tracking: the
sensitivity maps (:mod:`identify.sensitivity`), the dataset (:mod:`identify.dataset_build`), the "numerical
input" of paper §6.4, a known joint's ROM frequencies for the bias estimate, a predicted pattern in the dynamic
validation and the ROM update. This module holds its parts:

* :func:`d1b_pencil` — the dense (K, M) of the disk–one-blade ROM for one pattern pair and blade δ (Eqs. 19, 22);
* :func:`common_coords` — the coordinates every pattern shares, where mode shapes of two patterns compare;
* :func:`assign_modes` — each reference mode's candidate, maximum total MAC (Hungarian);
* :func:`model_key` — the hash of the d1b ROM, so a dataset made with another ROM is refused;
* :class:`ModeTracker` — a direct solve, then MAC assignment against a reference pair's modes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from ema.mac import mac
from rom.cache import hash_inputs
from rom.contact import ContactPattern
from rom.craig_bampton import CraigBamptonModel
from rom.modal import dense_modes, single_thread_blas
from rom.rom_assembly import FORMULATIONS, assemble_d1b
from rom.rubin import RubinModel

from .errors import IdentifyError

__all__ = [
    "ModeTracker",
    "TrackedModes",
    "d1b_pencil",
    "pencil_checked",
    "common_coords",
    "update_index",
    "assign_modes",
    "model_key",
    "check_formulation",
]

#: Full bases kept by some reduced models; they do not change the ROM, so they stay out of the model key.
_KEY_SKIP = {"Phi", "Psi", "excess_dofs", "Phi_r", "Phi_f", "Psi_r", "delta"}


# ----------------------------------------------------------------------------------------- the d1b ROM
def check_formulation(formulation: str) -> None:
    """IdentifyError unless ``formulation`` is one of :data:`rom.rom_assembly.FORMULATIONS`."""
    if formulation not in FORMULATIONS:
        raise IdentifyError(f"formulation={formulation!r}: expected one of {FORMULATIONS}")


def model_key(disk: CraigBamptonModel, blade: RubinModel, formulation: str = "exact") -> str:
    """SHA-256 (:func:`rom.cache.hash_inputs`) of every array and setting that defines the d1b ROM.

    Optional full bases and the blade's own δ (the dataset sets δ itself) are left out. A dataset or
    sensitivity built with another model gets another key.
    """
    check_formulation(formulation)
    parts: list = ["identify-d1b", formulation]
    for model in (disk, blade):
        parts.append(type(model).__name__)
        for f in dataclasses.fields(model):
            v = getattr(model, f.name)
            if f.name in _KEY_SKIP or v is None:
                continue
            parts += [f.name, v if isinstance(v, (np.ndarray, dict, list, tuple)) else np.asarray(v)]
    return hash_inputs(*parts)


def d1b_pencil(disk, blade, L, R, *, formulation: str = "exact", delta=None) -> tuple[np.ndarray, np.ndarray]:
    """Dense (K, M) of the disk–one-blade ROM for one pattern pair (Eq. 22), blade tuned unless ``delta``.

    Assembled with one BLAS thread: on a loaded 2-core machine threaded BLAS was up to 40× slower here.
    """
    with single_thread_blas():
        asm = assemble_d1b(disk, blade, ContactPattern(L, R), delta=0.0 if delta is None else delta,
                           formulation=formulation)
    return asm.K, asm.M


def pencil_checked(disk, blade, L, R, i: int, j: int, formulation: str, delta=None):
    """:func:`d1b_pencil` of pattern pair (``i``, ``j``), with an invalid pattern named in an IdentifyError."""
    try:
        return d1b_pencil(disk, blade, L, R, formulation=formulation, delta=delta)
    except IdentifyError:
        raise
    except ValueError as exc:  # an invalid ContactPattern (no contact, collinear) or a model mismatch
        raise IdentifyError(f"pattern pair (L {i}, R {j}) (0-based): {exc}") from None


def update_index(disk: CraigBamptonModel, blade: RubinModel, n_delta_modes: int) -> np.ndarray:
    """d1b coordinates of the blade modal coordinates η_f,1..k, whose stiffness is (1 + δ_i) ω_i² (Eq. 19).

    :func:`rom.rom_assembly.assemble_d1b` puts the disk's coordinates first, then the blade's rigid-body and
    free-interface modal coordinates.
    """
    return disk.n + blade.n_r + np.arange(int(n_delta_modes))


def common_coords(n: int, disk: CraigBamptonModel, blade: RubinModel) -> np.ndarray:
    """Coordinates every pattern shares: disk + blade modal coordinates, then the accessory DOFs (last).

    Equal to all coordinates in the exact formulation; the paper formulation also keeps detached root
    DOFs, whose number depends on the pattern.
    """
    front = disk.n + blade.n_r + blade.m
    n_acc = blade.n_b - blade.n_interface
    return np.concatenate([np.arange(front), np.arange(n - n_acc, n)])


# ----------------------------------------------------------------------------------------- tracking
def assign_modes(mac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Assign each row (reference mode) one distinct column (candidate) with maximum total MAC (Hungarian).

    Parameters
    ----------
    mac : ndarray, shape (n_ref, n_cand), n_cand ≥ n_ref

    Returns
    -------
    cols : ndarray of int, shape (n_ref,)
    values : ndarray of float64, shape (n_ref,)
        The MAC of each assignment.
    """
    rows, cols = linear_sum_assignment(mac, maximize=True)
    out = np.empty(mac.shape[0], np.int64)
    out[rows] = cols
    return out, mac[np.arange(mac.shape[0]), out]


@dataclass(frozen=True, eq=False)
class TrackedModes:
    """Frequencies (Hz) and MAC with the reference modes, shape (n_modes,) each, for one pattern and δ."""

    frequencies_hz: np.ndarray
    mac: np.ndarray


@dataclass(frozen=True, eq=False)
class ModeTracker:
    """The reference modes a dataset tracks, and a solver that tracks any pattern against them.

    A dataset stores, for each sample, the frequency of the reference pair's m-th mode as it moves with the
    pattern and δ; comparing anything with it needs the same tracking. Build it with :meth:`from_dataset`
    (or :meth:`from_reference`) and call :meth:`track`.

    Attributes
    ----------
    disk, blade : the ROM (reduced disk on one slot, Rubin blade)
    shapes : ndarray, shape (n_common, n_modes)
        The reference pair's tuned modes on the coordinates every pattern shares.
    weight : ndarray, shape (n_common, n_common)
        Mass matrix on those coordinates (the MAC's inner product).
    n_extra : int
        Candidate modes above ``n_modes`` per solve.
    formulation : str
    """

    disk: CraigBamptonModel
    blade: RubinModel
    shapes: np.ndarray
    weight: np.ndarray
    n_extra: int = 4
    formulation: str = "exact"

    @property
    def n_modes(self) -> int:
        return int(self.shapes.shape[1])

    @classmethod
    def from_reference(cls, disk, blade, L, R, n_modes: int = 10, *, n_extra: int = 4,
                       formulation: str = "exact") -> ModeTracker:
        """Reference modes of the tuned blade with the pattern (L, R) (bool grids, shape (rows, cols))."""
        K, M = d1b_pencil(disk, blade, np.asarray(L, bool), np.asarray(R, bool), formulation=formulation)
        with single_thread_blas():
            dm = dense_modes(K, M, n_modes, max_rigid=6)
        common = common_coords(K.shape[0], disk, blade)
        return cls(disk, blade, dm.shapes[common, :n_modes], M[np.ix_(common, common)], n_extra, formulation)

    @classmethod
    def from_dataset(cls, disk, blade, dataset, *, n_extra: int = 4) -> ModeTracker:
        """The tracker of a dataset (its reference pair, mode count and formulation); checks the model key.

        Raises
        ------
        IdentifyError
            The dataset was built with another ROM.
        """
        formulation = str(dataset.meta.get("formulation", "exact"))
        dataset.check_model(model_key(disk, blade, formulation))
        ref = dataset.meta.get("reference")
        if ref is None:
            raise IdentifyError("dataset metadata lacks its reference pair ('reference'); rebuild it")
        i, j = (int(x) for x in ref)
        return cls.from_reference(disk, blade, dataset.patterns_L[i], dataset.patterns_R[j],
                                  dataset.frequencies_hz.shape[1], n_extra=n_extra, formulation=formulation)

    def track(self, pattern: ContactPattern, delta=None) -> TrackedModes:
        """Direct dense solve of the d1b ROM with ``pattern`` and blade ``delta`` (Eq. 19), tracked by MAC.

        Parameters
        ----------
        pattern : rom.ContactPattern
        delta : float or array_like, optional
            Blade mistuning, relative; a vector perturbs the first ``len(delta)`` blade modes.
        """
        f, cols, vals = self._solve(pattern, delta)
        return TrackedModes(f[cols], vals)

    def untracked_hz(self, pattern: ContactPattern, delta=None) -> np.ndarray:
        """The solve's candidate modes that no tracked mode took (Hz, ascending, shape (n_extra,)).

        A measured mode near one of them is that mode, not a tracked one: the pairing with a test
        (``bladetwin.stages.bias.match_to_reference``) keeps them as neighbours. Same arguments as :meth:`track`.
        """
        f, cols, _ = self._solve(pattern, delta)
        return np.sort(np.delete(f, cols))

    def _solve(self, pattern: ContactPattern, delta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        K, M = d1b_pencil(self.disk, self.blade, pattern.L, pattern.R, formulation=self.formulation,
                          delta=delta)
        n_cand = self.n_modes + self.n_extra
        with single_thread_blas():
            dm = dense_modes(K, M, n_cand, max_rigid=6)
            common = common_coords(K.shape[0], self.disk, self.blade)
            cols, vals = assign_modes(mac(self.shapes, dm.shapes[common], weight=self.weight))
        return np.asarray(dm.frequencies_hz, np.float64), cols, vals
