"""The tracked disk–one-blade solve of the ROM update: frequencies and their sensitivities to the blade's δ.

A fit over a blade's in-situ correction ε (:func:`identify.rom_update.fit_corrections`) solves one pattern's
disk–one-blade ROM for several δ + ε. δ enters only the blade's modal stiffness diagonal (Eq. 19), so:

* :func:`tuned_pencil` assembles the pattern's ROM once (the Rubin super-element is 40 % of a direct solve);
* :func:`tracked_sensitivity` solves it directly for one δ (dense Lanczos), tracked by MAC;
* :func:`eps_model` builds, at the fit's starting point, the δ-parametric Ritz model of
  :mod:`identify.reanalysis` over the corrected modes; :meth:`EpsModel.sensitivity` then solves a δ that differs
  from the start only on those modes in an s × s problem (s ≈ 40), with a rigorous bound on every tracked
  frequency's error. Above :data:`RITZ_TOL` it answers ``None`` and the caller solves directly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ema.mac import mac
from rom.contact import ContactPattern
from rom.mistuning import as_delta
from rom.modal import dense_modes, single_thread_blas

from .reanalysis import RitzModel, ritz_model, solve_ritz
from .tracking import ModeTracker, assign_modes, common_coords, d1b_pencil, update_index

__all__ = ["RITZ_TOL", "tuned_pencil", "tracked_sensitivity", "EpsModel", "eps_model"]

#: Bound on a tracked frequency's relative error under which :meth:`EpsModel.sensitivity` answers: a hundredth
#: of the ROM's own error (``identify.rom_update.ROM_ERROR``), so no fit can tell the two solves apart.
RITZ_TOL = 1e-6


def tuned_pencil(tracker: ModeTracker, pattern: ContactPattern) -> tuple[np.ndarray, np.ndarray]:
    """Dense (K, M) of the tracker's disk–one-blade ROM for ``pattern``, blade tuned (δ = 0); shape (n, n) each."""
    return d1b_pencil(tracker.disk, tracker.blade, pattern.L, pattern.R, formulation=tracker.formulation)


def _with_delta(K: np.ndarray, tracker: ModeTracker, delta) -> np.ndarray:
    """A copy of the tuned stiffness ``K`` with the blade's Ω_f² = (1 + δ) ω² (Eq. 19)."""
    blade = tracker.blade
    idx = update_index(tracker.disk, blade, blade.m)
    K = K.copy()
    K[idx, idx] += blade.omega2_tuned * as_delta(delta, blade.m)
    return K


def _tracked(tracker: ModeTracker, freqs: np.ndarray, common: np.ndarray, blade_rows: np.ndarray):
    """Frequencies and Jacobian of the candidates (``freqs`` (n_cand,), M-normalised shapes' ``common`` and
    ``blade_rows`` (m, n_cand) rows) tracked against the reference modes; also the tracked columns."""
    with single_thread_blas():
        cols, _ = assign_modes(mac(tracker.shapes, common, weight=tracker.weight))
    f = np.asarray(freqs[cols], np.float64)
    lam = (2 * np.pi * f) ** 2
    jac = 0.5 * blade_rows[:, cols].T ** 2 * tracker.blade.omega2_tuned[None, :] / lam[:, None]
    return f, jac, cols


def tracked_sensitivity(tracker: ModeTracker, pattern: ContactPattern, delta, *,
                        pencil: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Tracked d1b frequencies and their sensitivities to the blade's eigenvalue factors (Eq. 19), solved directly.

    Parameters
    ----------
    tracker : ModeTracker
        Its ``blade`` is the model solved (rigid ties or on springs).
    pattern : ContactPattern
    delta : ndarray, shape (m,)
        The blade's δ (+ ε), relative.
    pencil : (K, M), optional
        :func:`tuned_pencil` of this tracker and pattern, when the caller solves it for several δ.

    Returns
    -------
    frequencies_hz : ndarray, shape (n_tracked,)
    jacobian : ndarray, shape (n_tracked, m)
        ``∂ ln f_k / ∂ δ_i = ω_i² φ_k,i² / (2 λ_k)`` with φ_k mass-normalised and ``i`` the blade's i-th
        free-interface coordinate (the stiffness's only δ-dependent entry, Eq. 19).
    """
    K, M = tuned_pencil(tracker, pattern) if pencil is None else pencil
    K = _with_delta(K, tracker, delta)
    with single_thread_blas():
        dm = dense_modes(K, M, tracker.n_modes + tracker.n_extra, max_rigid=6)
        phi = dm.shapes / np.sqrt(np.einsum("ik,ik->k", dm.shapes, M @ dm.shapes))
    common = common_coords(K.shape[0], tracker.disk, tracker.blade)
    blade_rows = update_index(tracker.disk, tracker.blade, tracker.blade.m)
    f, jac, _ = _tracked(tracker, dm.frequencies_hz, phi[common], phi[blade_rows])
    return f, jac


@dataclass(frozen=True, eq=False)
class EpsModel:
    """A pattern's disk–one-blade ROM as a Ritz model over the blade's corrected modes (:func:`eps_model`).

    Attributes
    ----------
    ritz : RitzModel
        Built at ``delta0``; its ``basis_rows`` are the shared coordinates, then the blade's m modal ones.
    delta0 : ndarray, shape (m,)
    free : ndarray of int, shape (k,)
        The modes whose δ may move.
    n_common : int
    """

    ritz: RitzModel
    delta0: np.ndarray
    free: np.ndarray
    n_common: int

    def sensitivity(self, tracker: ModeTracker, delta) -> tuple[np.ndarray, np.ndarray] | None:
        """:func:`tracked_sensitivity` at ``delta`` (shape (m,)), or ``None`` where a tracked frequency's bound
        exceeds :data:`RITZ_TOL` (then solve directly).

        Raises
        ------
        ValueError
            ``delta`` differs from ``delta0`` outside ``free``.
        """
        d = as_delta(delta, self.delta0.size) - self.delta0
        fixed = np.ones(d.size, bool)
        fixed[self.free] = False
        if np.any(d[fixed] != 0):
            raise ValueError(f"δ moved on modes {np.flatnonzero(fixed & (d != 0)).tolist()}, outside the model's "
                             f"{self.free.tolist()}")
        # The model's update is relative to the tuned ω², as δ is (Eq. 19).
        sol = solve_ritz(self.ritz, d[self.free][None, :], coords=True)
        x = self.ritz.basis_rows @ sol.coords[0]
        f, jac, cols = _tracked(tracker, sol.frequencies_hz[0], x[: self.n_common], x[self.n_common:])
        return (f, jac) if np.all(sol.bound[0, cols] <= RITZ_TOL) else None


def eps_model(tracker: ModeTracker, pencil: tuple[np.ndarray, np.ndarray], delta0, free) -> EpsModel | None:
    """The Ritz model of ``pencil`` (:func:`tuned_pencil`) at δ = ``delta0`` (shape (m,)), δ free on ``free``.

    ``None`` when the model is too small for a Ritz basis beside its candidates: solve directly then.
    """
    K, M = pencil
    blade = tracker.blade
    delta0 = as_delta(delta0, blade.m)
    free = np.asarray(free, np.int64).ravel()
    idx = update_index(tracker.disk, blade, blade.m)
    common = common_coords(K.shape[0], tracker.disk, blade)
    try:
        rm = ritz_model(_with_delta(K, tracker, delta0), M, idx[free], blade.omega2_tuned[free],
                        tracker.n_modes + tracker.n_extra, basis_tol=0.1 * RITZ_TOL, n_check=tracker.n_modes,
                        block=max(24, free.size + 1), rows=np.concatenate([common, idx]))
    except ValueError:
        return None
    return EpsModel(rm, delta0, free, int(common.size))
