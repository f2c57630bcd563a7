"""Which modes a fit keeps: the selection from the diagram, then the LSFD model less the non-dominant modes.

:func:`choose_modes` selects the modes (automatically, near given frequencies or by explicit picks, with the
padding's modes), :func:`dominant_model` fits their LSFD model and drops the modes that only patch the fit, with
the refinement in between, and :func:`with_split_modes` adds the modes the estimator merged
(:func:`ema.resolve.split_merged`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .dominance import Kept, mode_dominance
from .frf import FRFSet
from .lsfd import modal_model
from .modal import ModalModel
from .poles import in_band
from .refine import refine_band
from .resolve import split_merged
from .selection import PoleSelection, merge_selections, select_auto, select_near, select_picks
from .stabilization import StabilizationDiagram

__all__ = ["choose_modes", "dominant_model", "with_split_modes"]

log = logging.getLogger(__name__)


def choose_modes(diagram: StabilizationDiagram, auto: PoleSelection | None, band: tuple[float, float],
                 min_quality: float, frequencies_hz: Sequence[float] | None = None,
                 picks: Sequence[tuple[int, float]] | None = None) -> tuple[PoleSelection, np.ndarray]:
    """The modes to fit: the automatic selection, or the user's choice with the automatic modes of the padding.

    Parameters
    ----------
    diagram : StabilizationDiagram
        Over the fitted (possibly padded) band.
    auto : PoleSelection, optional
        The diagram's automatic selection, where it is known already (:class:`ema.global_fit.GlobalFit`).
    band : (f_lo, f_hi)
        Hz, the band of the modes asked for.
    min_quality : float
        Automatic selection threshold.
    frequencies_hz : sequence of float, optional
        Modes near these frequencies inside ``band`` (:func:`ema.selection.select_near`).
    picks : sequence of (order, frequency_hz), optional
        Explicit picks (:func:`ema.selection.select_picks`).

    Returns
    -------
    selection : PoleSelection
    protect : ndarray of bool, shape (n_modes,)
        The modes the user chose, which the dominance filter never drops.
    """
    if picks is not None or frequencies_hz is not None:
        chosen = (select_picks(diagram, picks) if picks is not None
                  else select_near(diagram.within(band), frequencies_hz))
        # modes of the padding, to model what lies just outside the band; the user's own choice is kept
        extra = select_auto(diagram, min_quality=min_quality)
        extra = extra.take(~in_band(extra.frequencies_hz, band))
        selection = merge_selections(chosen, extra)
        return selection, np.isin(selection.pole, chosen.pole)
    selection = auto if auto is not None else select_auto(diagram, min_quality=min_quality)
    return selection, np.zeros(selection.n_modes, bool)


def dominant_model(
    frf: FRFSet,
    diagram: StabilizationDiagram,
    poles: np.ndarray,
    quality: np.ndarray,
    protect: np.ndarray,
    min_dominance: float,
    refine: bool,
) -> Kept:
    """LSFD, dominance filter and optional refinement of selected poles over the diagram's band.

    ``poles``, ``quality`` and ``protect`` (bool, the modes the filter never drops) have shape (n_modes,), in the
    selection's order. With refinement the filter judges the refined model, and the survivors are refined and
    judged again until none is below ``min_dominance``: at the estimator's rough pole the weaker member of a close
    pair can look like a patch, and a pole that only fits noise or patches a peak can look like a resonance until
    the refinement has moved it.
    """
    mac_min = diagram.criteria.mac_min
    dropped: list[float] = []

    def lsfd_model(lam: np.ndarray, quality: np.ndarray, keep: np.ndarray) -> tuple[ModalModel, np.ndarray, np.ndarray]:
        # sorted here, so that quality and protection follow the poles (modal_model sorts by |lambda|)
        srt = np.argsort(np.abs(lam), kind="stable")
        model = modal_model(frf, lam[srt], diagram.band_hz, quality=quality[srt], method=diagram.method)
        dom = mode_dominance(frf, model, mac_min) if model.n_modes else np.zeros(0)
        return model, dom, keep[srt]

    def drop(model: ModalModel, dom: np.ndarray, kept: np.ndarray) -> tuple[ModalModel, np.ndarray, np.ndarray]:
        # one at a time, least dominant first: removing a mode changes the others' residues
        while True:
            weak = np.flatnonzero((dom < min_dominance) & ~kept)
            if weak.size == 0:
                return model, dom, kept
            k = int(weak[np.argmin(dom[weak])])
            dropped.append(float(model.frequencies_hz[k]))
            rest = np.delete(np.arange(model.n_modes), k)
            model, dom, kept = lsfd_model(model.poles[rest], model.quality[rest], kept[rest])

    last: list = [np.zeros(0, complex), 0]  # the poles of the last refinement, and how many were dropped then

    def refined(model: ModalModel, kept: np.ndarray) -> tuple[ModalModel, np.ndarray, np.ndarray]:
        lam = refine_band(frf, model, diagram.band_hz, settled=(last[0], dropped[last[1]:]))
        last[:] = [lam, len(dropped)]
        return lsfd_model(lam, model.quality, kept)

    model, dom, kept = lsfd_model(poles, quality, np.asarray(protect, bool))
    # each pass drops at least one mode, so this ends; refinement moves poles, so judge again after it
    while True:
        if refine and model.n_modes:
            model, dom, kept = refined(model, kept)
        if not (min_dominance > 0 and np.any((dom < min_dominance) & ~kept)):
            return Kept(model, dom, dropped)
        model, dom, kept = drop(model, dom, kept)
        if not refine:
            return Kept(model, dom, dropped)


def with_split_modes(frf: FRFSet, kept: Kept, diagram: StabilizationDiagram, band: tuple[float, float],
                     min_dominance: float, refine: bool) -> Kept:
    """The model with the modes :func:`ema.resolve.split_merged` finds in its windows, refitted over ``band`` (LSFD,
    refinement, dominance as :func:`dominant_model`); the model unchanged where no window gains a mode."""
    model = kept.model
    found = split_merged(frf, model.poles, band, diagram.criteria)
    if found is None:
        return kept
    lam, local = found
    quality = np.full(lam.size, 1.0)  # both in ascending |λ|: the kept modes keep their selection quality
    if model.quality is not None:
        quality[~local] = np.asarray(model.quality, float)[np.isin(model.poles, lam[~local])]
    log.info("local LSRF: %d modes -> %d before the dominance check", model.n_modes, lam.size)
    fitted = dominant_model(frf, replace(diagram, band_hz=band), lam, quality, np.zeros(lam.size, bool),
                            min_dominance, refine)
    return Kept(fitted.model, fitted.dominance, sorted([*kept.dropped, *fitted.dropped]))
