"""One-call EMA: poles over orders -> stabilization diagram -> selection -> LSFD modal model.

:func:`fit` composes the steps, each in a module of its own: the global fit (:mod:`ema.global_fit`), the
selection and the dominance filter (:mod:`ema.select_modes`), the refinement inside the band (:mod:`ema.refine`),
the standard deviations (:mod:`ema.uncertainty`), the dense families (:mod:`ema.families`) and the modes the
model misses (:mod:`ema.unexplained`). Its tuning is one :class:`ema.settings.FitSettings`.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .dominance import mode_dominance
from .errors import EMAError
from .families import merge_families, resolve_families
from .frf import FRFSet
from .global_fit import global_fit
from .lsfd import fit_quality
from .modal import ModalModel
from .poles import band_data, in_band, single_thread_blas
from .refine import refine_in_band
from .select_modes import choose_modes, dominant_model, with_split_modes
from .selection import PoleSelection
from .settings import FitSettings, refuse_settings_keywords
from .stabilization import StabilizationDiagram
from .uncertainty import with_std
from .unexplained import fill_unexplained

__all__ = ["EMAResult", "fit"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class EMAResult:
    """Everything one EMA fit produced.

    Attributes
    ----------
    diagram : StabilizationDiagram
    selection : PoleSelection
    model : ModalModel
        Poles after (optional) refinement, residues and shapes from LSFD.
    quality : ndarray, shape (n_outputs, n_inputs)
        Fit quality of each FRF (1 - relative squared error of the synthesis over the band).
    dominance : ndarray, shape (n_modes,)
        :func:`ema.dominance.mode_dominance` of each kept mode.
    dropped_hz : tuple of float
        Frequencies of selected poles dropped as non-dominant.
    """

    diagram: StabilizationDiagram
    selection: PoleSelection
    model: ModalModel
    quality: np.ndarray
    dominance: np.ndarray
    dropped_hz: tuple[float, ...] = ()

    def as_dict(self) -> dict:
        """JSON-ready summary: ``modes``, ``method``, ``band_hz``, ``fit_quality``."""
        return {
            "method": self.diagram.method,
            "band_hz": [float(self.diagram.band_hz[0]), float(self.diagram.band_hz[1])],
            "modes": self.model.as_records(),
            "fit_quality": {
                "min": float(np.min(self.quality)) if self.quality.size else None,
                "mean": float(np.mean(self.quality)) if self.quality.size else None,
            },
        }


@refuse_settings_keywords
def fit(
    frf: FRFSet,
    band: tuple[float, float] | None = None,
    settings: FitSettings | None = None,
    *,
    max_order: int = 60,
    frequencies_hz: Sequence[float] | None = None,
    picks: Sequence[tuple[int, float]] | None = None,
    families: bool = False,
    progress: bool = False,
) -> EMAResult:
    """Identify modes from FRFs in one call.

    A single-band fit (``settings.n_bands == 1``) estimates the poles, selects and refines the modes over the band
    widened by ``settings.pad`` of its width on each side, where the FRFs have lines, and then keeps the modes
    inside the band: a mode near a band edge is then as accurate as one in the middle, because the estimators'
    edge effects fall in the padding, and the modes just outside the band enter the LSFD model and the refinement
    as poles instead of through the residual terms.

    Parameters
    ----------
    frf : FRFSet
    band : (f_lo, f_hi) in Hz, optional
        Band of the modes returned; default all lines (no padding possible then).
    settings : FitSettings, optional
        Estimator, orders, criteria, thresholds, bands, refinement, padding, the local LSRF check and the order
        growth; default ``FitSettings()``. One of its fields passed as a keyword is refused (TypeError).
    max_order : int
        Highest model order (see :func:`ema.lscf.lscf`, :func:`ema.lsrf.lsrf`; the order may grow from it,
        ``settings.grow``).
    frequencies_hz : sequence of float, optional
        Select modes near these frequencies (:func:`ema.selection.select_near`).
    picks : sequence of (order, frequency_hz), optional
        Explicit picks (:func:`ema.selection.select_picks`). Default: automatic selection.
    families : bool
        Resolve dense mode families (:mod:`ema.families`: every window of two or more modes refitted with rank-one
        residues, each mode from the fit that gives it the smaller standard deviation), then fit a grown window
        wherever the residual still stands above the noise (:func:`ema.unexplained.fill_unexplained`), so the modes
        the estimator missed at ``max_order`` are found too. For tests of a whole mistuned bladed disk.
    progress : bool
        Progress bars (tqdm) over the orders, bands and families.

    Returns
    -------
    EMAResult
        Diagram, selection and model of the band (the diagram's poles come from the padded fit).

    Raises
    ------
    EMAError
        Both ``frequencies_hz`` and ``picks``, or a bad method, band or order.
    """
    s = settings if settings is not None else FitSettings()
    if frequencies_hz is not None and picks is not None:
        raise EMAError("give approximate frequencies or explicit picks, not both")
    user_band = band_data(frf, band, per="none").band_hz
    g = global_fit(frf, user_band, s, max_order, s.grow and picks is None, progress)
    diagram = g.diagram
    selection, protect = choose_modes(diagram, g.selection, user_band, s.min_quality, frequencies_hz, picks)
    with single_thread_blas():
        kept = dominant_model(frf, diagram, selection.pole, selection.quality, protect, s.min_dominance, s.refine)
        if g.band_hz != user_band:
            kept = refine_in_band(frf, kept, user_band, s.refine, diagram.criteria.mac_min)
            diagram = diagram.within(user_band)
            selection = selection.take(in_band(selection.frequencies_hz, user_band))
        if s.split and not families and picks is None and frequencies_hz is None:
            kept = with_split_modes(frf, kept, diagram, user_band, s.min_dominance, s.refine)
        model, dom = kept.model, kept.dominance
        if model.n_modes:  # each mode's standard deviations: the fit's covariance and the scatter over orders
            model = with_std(frf, model, user_band, diagram)
        if families and model.n_modes:
            fits = resolve_families(frf, model.poles, user_band, progress=progress)
            model = fill_unexplained(frf, merge_families(frf, model, fits), user_band, [f.window_hz for f in fits])
            dom = mode_dominance(frf, model, diagram.criteria.mac_min) if model.n_modes else np.zeros(0)
    quality = fit_quality(frf, model) if model.n_modes else np.zeros((frf.n_outputs, frf.n_inputs))
    log.info("%s: %d modes in %.6g-%.6g Hz", diagram.method, model.n_modes, *diagram.band_hz)
    return EMAResult(diagram=diagram, selection=selection, model=model, quality=quality, dominance=dom,
                     dropped_hz=tuple(sorted(kept.dropped)))
