"""The ROM updated beyond Eq. 19 (:mod:`identify.rom_update`): contact stiffness, in-situ corrections, full solves.

Nodes: ``rom_update/stiffness`` (the filmed joints' disk–one-blade tests), ``rom_update/answer`` and
``rom_update/reference`` (every blade's in-situ correction with the run's answer, or the true patterns), and the
full solves ``full/updated*``. None of them takes the full-assembly test: it stays the validation.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from identify.dataset import Dataset
from identify.in_situ import (
    N_CANDIDATES,
    calibration_warnings,
    common_correction,
    consistent_pattern,
    disagrees,
    held_at_common,
)
from identify.posterior import evenly_spaced
from identify.rom_update import (
    StiffnessFit,
    UpdatedROM,
    fit_contact_stiffness,
    fit_corrections,
    noise_floor,
    tracked_sensitivity,
)
from rom.contact import ContactPattern
from rom.contact_stiffness import blade_compliance_parts, interface_compliance, with_contact_stiffness
from rom.rubin import RubinModel

from .bias import Features, tracker_for
from .full import FullSolve, solve_assembly
from .models import CyclicBuild
from .posterior import ema_std_rel

__all__ = ["ROM_KINDS", "updated_blade", "updated_parts", "stiffness_node", "update_node", "solve_updated",
           "candidates_node"]

#: ``--rom``: the paper's ROM only, or the updated one beside it (default).
ROM_KINDS = ("paper", "updated")


def updated_blade(blade: RubinModel, bd, stiffness) -> RubinModel:
    """The Rubin blade on the fitted contact springs (unchanged where ``stiffness`` is None: rigid ties)."""
    if stiffness is None:
        return blade
    return with_contact_stiffness(blade, interface_compliance(blade_compliance_parts(bd.blade), stiffness))


def updated_parts(blade: RubinModel, bd, delta_all: np.ndarray, update=None) -> tuple[RubinModel, np.ndarray]:
    """(blade, δ of every blade) of the updated ROM: the blade on ``update``'s contact springs and δ + ε, shape
    (n_blades, n_delta); the paper's ``blade`` and ``delta_all`` where ``update`` is None."""
    if update is None:
        return blade, delta_all
    return updated_blade(blade, bd, update.stiffness), delta_all + update.corrections


def _sigma(features: Features, fits: dict) -> dict[int, np.ndarray]:
    """Each tested joint's relative noise per tracked mode (:func:`identify.rom_update.noise_floor`)."""
    return {int(j): noise_floor(ema_std_rel(fits.get(f"d1b_{int(j):02d}"), features.measured_hz[k]))
            for k, j in enumerate(features.joints)}


def stiffness_node(disk, blade, dataset: Dataset, features: Features, known: dict, delta_all: np.ndarray, bd,
                   **d1b) -> StiffnessFit | None:
    """The node: the joints' contact stiffness from the filmed joints' disk–one-blade tests (their patterns known).

    ``None`` (rigid ties kept, with a warning) where no filmed joint has a disk–one-blade test.
    """
    sigma = _sigma(features, d1b)
    rows = {int(j): k for k, j in enumerate(features.joints)}
    joints = {j: (known[j], delta_all[j - 1], features.measured_hz[rows[j]], sigma[j]) for j in sorted(known)
              if j in rows and np.isfinite(features.measured_hz[rows[j]]).any()}
    if not joints:
        warnings.warn("no filmed joint has a usable disk–one-blade test: the updated ROM keeps the paper's rigid "
                      "contact ties (no contact stiffness fitted)", UserWarning, stacklevel=2)
        return None
    return fit_contact_stiffness(tracker_for(disk, blade, dataset), blade_compliance_parts(bd.blade), joints)


def update_node(disk, blade, dataset: Dataset, features: Features, delta_all: np.ndarray, bd,
                stiffness: StiffnessFit | None, patterns: list[ContactPattern], warn: bool = True,
                candidates: dict | None = None, **d1b) -> UpdatedROM:
    """The node: every tested blade's in-situ correction with its joint's pattern in ``patterns`` (one per slot).

    Blades without a disk–one-blade test keep Eq. 19 (ε = 0). Warnings name the blade and the mode whose data
    the calibration cannot use (:func:`identify.rom_update.calibration_warnings`); ``warn=False`` keeps them
    quiet, for the controls (the baseline's and the true patterns' updates), which repeat the exported ROM's
    warnings with other figures. ``candidates`` (:func:`candidates_node`): joint → plausible patterns; where
    the given pattern leaves a blade's correction beyond the bound, the one its test bears out best is taken
    (:func:`identify.in_situ.consistent_pattern`, :attr:`UpdatedROM.replaced`).
    """
    tracker = tracker_for(disk, blade, dataset)
    stiff = None if stiffness is None else stiffness.stiffness
    upd = replace(tracker, blade=updated_blade(blade, bd, stiff))
    sigma = _sigma(features, d1b)
    n_blades, m = delta_all.shape
    n_tracked = features.measured_hz.shape[1]
    eps = np.zeros((n_blades, m))
    done = np.zeros(n_blades, bool)
    res, res_paper = np.full((n_blades, n_tracked), np.nan), np.full((n_blades, n_tracked), np.nan)
    free_hz = np.sqrt(blade.omega2_tuned) / (2 * np.pi)
    fits = {}
    for k, j in enumerate(int(j) for j in features.joints):
        y = features.measured_hz[k]
        if not np.isfinite(y).any():
            if warn:
                warnings.warn(f"blade {j}: its disk–one-blade test found none of the tracked modes: the blade "
                              "keeps Eq. 19's free-test values, uncalibrated", UserWarning, stacklevel=2)
            continue
        fits[j] = fit_corrections(upd, patterns[j - 1], delta_all[j - 1], y, sigma[j])
        f_paper, _ = tracked_sensitivity(tracker, patterns[j - 1], delta_all[j - 1])
        res_paper[j - 1] = (y / f_paper - 1) * 100
    # what all blades share (the model's own error in the seated blade), from the blades that see each mode; a
    # blade whose test cannot see a mode takes it, and each is measured from it: design §8.53
    centre = common_correction(list(fits.values()), m)
    for k, j in enumerate(int(j) for j in features.joints):
        if j in fits:
            fits[j] = _at_centre(upd, patterns[j - 1], delta_all[j - 1], features.measured_hz[k], sigma[j], centre,
                                 fits[j])
    replaced = _replace_inconsistent(upd, fits, candidates or {}, centre, features, delta_all, sigma)
    for j, fit in fits.items():
        eps[j - 1], done[j - 1], res[j - 1] = fit.correction, True, fit.residual_pct
    for j, fit in fits.items() if warn else ():
        filmed = stiffness is not None and j in stiffness.joints  # its pattern is the film's
        for text in calibration_warnings(j, fit, free_hz, filmed=filmed, centre=centre):
            warnings.warn(text, UserWarning, stacklevel=2)
    return UpdatedROM(stiff, eps, done, res, res_paper, free_hz, tuple(replaced))


def _at_centre(upd, pattern: ContactPattern, delta, y, sigma, centre, fit=None):
    """A blade's in-situ fit (``fit``, or a fresh one) refitted with the blades' common correction ``centre`` held
    on the free modes its test cannot see (:func:`identify.in_situ.held_at_common`); as it was where there are none."""
    fit = fit_corrections(upd, pattern, delta, y, sigma) if fit is None else fit
    hold = held_at_common(fit, centre)
    return fit if hold is None else fit_corrections(upd, pattern, delta, y, sigma, held=hold)


def _replace_inconsistent(upd, fits: dict, candidates: dict, centre, features: Features, delta_all, sigma) -> list:
    """[(joint, pattern)] of the joints whose fit disagrees and a candidate that does not; ``fits`` updated."""
    rows = {int(j): k for k, j in enumerate(features.joints)}
    replaced = []
    for j, pats in candidates.items():
        if j not in fits or not disagrees(fits[j], centre):
            continue
        y = features.measured_hz[rows[j]]

        def fit_one(pat, j=j, y=y):
            return _at_centre(upd, pat, delta_all[j - 1], y, sigma[j], centre)

        if (got := consistent_pattern(fit_one, pats, sigma[j], centre)) is not None:
            replaced.append((int(j), got[0]))
            fits[j] = got[1]
    return replaced


def solve_updated(cyclic: CyclicBuild, bd, blade: RubinModel, patterns: list[ContactPattern], delta_all: np.ndarray,
                  n_modes: int, update: UpdatedROM) -> FullSolve:
    """The node: the full bladed disk's modes with the updated ROM (blades on springs, δ + ε) and ``patterns``."""
    blade, delta_all = updated_parts(blade, bd, delta_all, update)
    return solve_assembly(cyclic, bd, blade, update.patterns_for(patterns), delta_all, n_modes)


def candidates_node(**posts) -> dict[int, list[ContactPattern]]:
    """The node: each unfilmed joint's plausible patterns for the ROM update, from its contact posterior
    (``post_NN``: :class:`identify.posterior.JointPosterior` or None): :data:`identify.in_situ.N_CANDIDATES` of
    its kept draws, evenly spaced."""
    out = {}
    for name, post in posts.items():
        grids = None if post is None else post.samples_grids
        if grids is not None and len(grids):
            out[int(name.rsplit("_", 1)[1])] = [ContactPattern(grids[k, 0], grids[k, 1])
                                                for k in evenly_spaced(len(grids), N_CANDIDATES)]
    return out
