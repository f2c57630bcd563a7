"""Tracked disk–one-blade frequencies of any pattern and blade δ, consistent with a dataset (paper Eq. 34).

The dataset stores, for each sample, the frequency of the reference pair's m-th mode as it moves with the
pattern and δ (:mod:`identify.sensitivity`, :mod:`identify.dataset`). Comparing anything with it (the
"numerical input" of paper §6.4, a known joint's ROM frequencies for the bias estimate, a predicted pattern
in the dynamic validation) needs the same tracking: a direct solve, then MAC assignment against the
reference pair's modes. :class:`ModeTracker` keeps those reference modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ema.mac import mac
from rom.contact import ContactPattern
from rom.craig_bampton import CraigBamptonModel
from rom.modal import dense_modes, single_thread_blas
from rom.rubin import RubinModel

from .errors import IdentifyError
from .sensitivity import assign_modes, common_coords, d1b_pencil, model_key

__all__ = ["ModeTracker", "TrackedModes"]


@dataclass(frozen=True, eq=False)
class TrackedModes:
    """Frequencies (Hz) and MAC with the reference modes, shape (n_modes,) each, for one pattern and δ."""

    frequencies_hz: np.ndarray
    mac: np.ndarray


@dataclass(frozen=True, eq=False)
class ModeTracker:
    """The reference modes a dataset tracks, and a solver that tracks any pattern against them.

    Build it with :meth:`from_dataset` (or :meth:`from_reference`) and call :meth:`track`.

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
        K, M = d1b_pencil(self.disk, self.blade, pattern.L, pattern.R, formulation=self.formulation,
                          delta=delta)
        n_cand = self.n_modes + self.n_extra
        with single_thread_blas():
            dm = dense_modes(K, M, n_cand, max_rigid=6)
            common = common_coords(K.shape[0], self.disk, self.blade)
            cols, vals = assign_modes(mac(self.shapes, dm.shapes[common], weight=self.weight))
        return TrackedModes(np.asarray(dm.frequencies_hz[cols], np.float64), vals)
