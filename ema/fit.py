"""One-call EMA: poles over orders -> stabilization diagram -> selection -> LSFD modal model.

Also local (band-by-band) pole estimation for dense spectra.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .frf import FRFSet
from .lscf import lscf
from .lsfd import dominance, fit_quality, modal_model, refine_poles
from .lsrf import lsrf
from .modal import ModalModel
from .poles import PoleSet, band_data, merge_polesets, single_thread_blas
from .selection import PoleSelection, select_auto, select_near, select_picks
from .stabilization import StabilityCriteria, StabilizationDiagram, stabilize

__all__ = ["METHODS", "estimate_poles", "local_poles", "EMAResult", "fit"]

log = logging.getLogger(__name__)

METHODS = {"lscf": lscf, "lsrf": lsrf}


def estimate_poles(
    frf: FRFSet,
    method: str = "lsrf",
    band: tuple[float, float] | None = None,
    max_order: int = 40,
    orders: Sequence[int] | None = None,
    progress: bool = False,
) -> PoleSet:
    """Run one pole estimator (``"lscf"`` or ``"lsrf"``) over a band; see :func:`ema.lscf.lscf`."""
    if method not in METHODS:
        raise ValueError(f"method {method!r} not one of {sorted(METHODS)}")
    return METHODS[method](frf, band=band, max_order=max_order, orders=orders, progress=progress)


def local_poles(
    frf: FRFSet,
    n_bands: int,
    method: str = "lsrf",
    band: tuple[float, float] | None = None,
    max_order: int = 30,
    overlap: float = 0.25,
    progress: bool = False,
) -> PoleSet:
    """Band-by-band pole estimation for dense spectra, merged into one pole set.

    The band is cut into ``n_bands`` equal cores; each is fitted over the core widened by ``overlap``
    of its width on both sides (clipped to the band), and keeps only the poles whose frequency falls in
    its core, so every pole comes from the fit where it sits farthest from the edges.

    Parameters
    ----------
    frf : FRFSet
    n_bands : int
        Number of sub-bands (>= 1).
    method : {"lsrf", "lscf"}
    band : (f_lo, f_hi) in Hz, optional
    max_order : int
        Highest order of every local fit.
    overlap : float
        Widening of each fit band, as a fraction of the core width.
    progress : bool

    Returns
    -------
    PoleSet
        Method ``"<method>/local"``; orders are the local orders.
    """
    if int(n_bands) < 1:
        raise ValueError(f"n_bands {n_bands}: expected >= 1")
    if not 0 <= overlap <= 1:
        raise ValueError(f"overlap {overlap}: expected in [0, 1]")
    full = band_data(frf, band, per="none").band_hz
    edges = np.linspace(full[0], full[1], int(n_bands) + 1)
    sets = []
    iterator = range(int(n_bands))
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"{method} bands", unit="band", leave=False)
    for k in iterator:
        lo, hi = edges[k], edges[k + 1]
        pad = overlap * (hi - lo)
        fit_band = (max(full[0], lo - pad), min(full[1], hi + pad))
        ps = estimate_poles(frf, method, fit_band, max_order)
        fk = ps.frequency_hz
        core = (fk >= lo) & ((fk < hi) if k < n_bands - 1 else (fk <= hi))
        sets.append(
            PoleSet(
                method=ps.method, band_hz=ps.band_hz, orders=ps.orders, order=ps.order[core], pole=ps.pole[core],
                vector=ps.vector[core], outputs=ps.outputs, inputs=ps.inputs,
            )
        )
    return merge_polesets(sets, f"{method}/local", full)


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
        :func:`ema.lsfd.dominance` of each kept mode.
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


def fit(
    frf: FRFSet,
    method: str = "lsrf",
    band: tuple[float, float] | None = None,
    max_order: int = 40,
    orders: Sequence[int] | None = None,
    frequencies_hz: Sequence[float] | None = None,
    picks: Sequence[tuple[int, float]] | None = None,
    criteria: StabilityCriteria | None = None,
    min_quality: float = 0.15,
    min_dominance: float = 0.7,
    n_bands: int = 1,
    refine: bool = True,
    progress: bool = False,
) -> EMAResult:
    """Identify modes from FRFs in one call.

    Parameters
    ----------
    frf : FRFSet
    method : {"lsrf", "lscf"}
    band : (f_lo, f_hi) in Hz, optional
    max_order, orders :
        Model orders (see :func:`ema.lscf.lscf`, :func:`ema.lsrf.lsrf`).
    frequencies_hz : sequence of float, optional
        Select modes near these frequencies (:func:`ema.selection.select_near`).
    picks : sequence of (order, frequency_hz), optional
        Explicit picks (:func:`ema.selection.select_picks`). Default: automatic selection.
    criteria : StabilityCriteria, optional
    min_quality : float
        Automatic selection threshold.
    min_dominance : float
        Automatic selection only: drop modes whose :func:`ema.lsfd.dominance` is below this (poles that
        only patch the fit of a neighbour), then refit. 0 keeps everything.
    n_bands : int
        > 1 fits band by band (:func:`local_poles`).
    refine : bool
        Refine the selected poles by nonlinear least squares on the LSFD model.
    progress : bool

    Returns
    -------
    EMAResult
    """
    if frequencies_hz is not None and picks is not None:
        raise ValueError("give approximate frequencies or explicit picks, not both")
    if n_bands > 1:
        poles = local_poles(frf, n_bands, method, band, max_order, progress=progress)
    else:
        poles = estimate_poles(frf, method, band, max_order, orders, progress)
    diagram = stabilize(poles, criteria)
    if picks is not None:
        selection = select_picks(diagram, picks)
    elif frequencies_hz is not None:
        selection = select_near(diagram, frequencies_hz)
    else:
        selection = select_auto(diagram, min_quality=min_quality)
    with single_thread_blas():
        model, dom, dropped = _finish(frf, diagram, selection, min_dominance if picks is None and frequencies_hz is None
                                      else 0.0, refine)
    quality = fit_quality(frf, model) if model.n_modes else np.zeros((frf.n_outputs, frf.n_inputs))
    log.info("%s: %d modes in %.6g-%.6g Hz", diagram.method, model.n_modes, *diagram.band_hz)
    return EMAResult(diagram=diagram, selection=selection, model=model, quality=quality, dominance=dom,
                     dropped_hz=tuple(sorted(dropped)))


def _finish(
    frf: FRFSet, diagram: StabilizationDiagram, selection: PoleSelection, min_dominance: float, refine: bool
) -> tuple[ModalModel, np.ndarray, list[float]]:
    """LSFD, dominance filter and optional refinement of a selection."""
    lam, qual = selection.pole, selection.quality
    dropped: list[float] = []
    model = modal_model(frf, lam, diagram.band_hz, quality=qual, method=diagram.method)
    dom = dominance(frf, model) if model.n_modes else np.zeros(0)
    if min_dominance > 0 and model.n_modes:
        while model.n_modes and dom.min() < min_dominance:
            k = int(np.argmin(dom))
            dropped.append(float(model.frequency_hz[k]))
            keep = np.delete(np.arange(model.n_modes), k)
            model = modal_model(frf, model.poles[keep], diagram.band_hz, quality=model.quality[keep],
                                method=diagram.method)
            dom = dominance(frf, model) if model.n_modes else np.zeros(0)
    if refine and model.n_modes:
        lam = refine_poles(frf, model.poles, diagram.band_hz)
        model = modal_model(frf, lam, diagram.band_hz, quality=model.quality, method=diagram.method)
        dom = dominance(frf, model)
    return model, dom, dropped

