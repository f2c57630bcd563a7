"""One-call EMA: poles over orders -> stabilization diagram -> selection -> LSFD modal model.

Also local (band-by-band) pole estimation for dense spectra.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

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
    orders: Sequence[int] | None = None,
    freq_tol: float = 0.01,
    mac_min: float = 0.8,
) -> PoleSet:
    """Band-by-band pole estimation for dense spectra, merged into one pole set.

    The band is cut into ``n_bands`` equal cores; each is fitted over the core widened by ``overlap``
    of its width on both sides (clipped to the band). LSRF fits use complex coefficients
    (:func:`ema.lsrf.lsrf` with ``coefficients="complex"``): each pole appears once, the numerators absorb
    the modes outside the fit band, and noise poles come out unstable.

    Merging, order by order: each fit offers its poles up to half the overlap beyond its core. Where two
    neighbouring fits both offer a pole of the same mode near their common core boundary (same order,
    frequencies within ``freq_tol``, vector MAC >= ``mac_min``), only the one from the fit in which it sits
    farther from the fit-band edges is kept; an unmatched pole is kept only inside its own core. So a
    mode that sits on a boundary gives one pole per order, not two, whichever side of the boundary each
    fit puts it.

    Parameters
    ----------
    frf : FRFSet
    n_bands : int
        Number of sub-bands (>= 1).
    method : {"lsrf", "lscf"}
    band : (f_lo, f_hi) in Hz, optional
    max_order : int
        Highest order of every local fit (complex LSRF: order n holds up to n poles in its fit band).
    overlap : float
        Widening of each fit band, as a fraction of the core width.
    progress : bool
    orders : sequence of int, optional
        Explicit orders of every local fit (default ``1 .. max_order``).
    freq_tol, mac_min : float
        Matching tolerances of the duplicate test at the core boundaries.

    Returns
    -------
    PoleSet
        Method ``"<method>/local"``; orders are the local orders.
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r} not one of {sorted(METHODS)}")
    if int(n_bands) < 1:
        raise ValueError(f"n_bands {n_bands}: expected >= 1")
    n_bands = int(n_bands)
    if not 0 <= overlap <= 1:
        raise ValueError(f"overlap {overlap}: expected in [0, 1]")
    full = band_data(frf, band, per="none").band_hz
    edges = np.linspace(full[0], full[1], n_bands + 1)
    fits: list[_LocalFit] = []
    iterator = range(n_bands)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"{method} bands", unit="band", leave=False)
    for k in iterator:
        lo, hi = edges[k], edges[k + 1]
        pad = overlap * (hi - lo)
        fit_band = (max(full[0], lo - pad), min(full[1], hi + pad))
        if method == "lsrf":
            ps = lsrf(frf, band=fit_band, max_order=max_order, orders=orders, coefficients="complex")
        else:
            ps = estimate_poles(frf, method, fit_band, max_order, orders)
        fits.append(_LocalFit(ps, lo, hi, 0.5 * pad))
    sets = [_offered(fits, k) for k in range(n_bands)]
    for k in range(n_bands - 1):
        sets[k], sets[k + 1] = _dedupe_boundary(sets[k], sets[k + 1], fits[k], fits[k + 1], freq_tol, mac_min)
    return merge_polesets(
        [PoleSet(method=fk.poles.method, band_hz=fk.poles.band_hz, orders=fk.poles.orders, order=order,
                 pole=pole, vector=vector, outputs=frf.outputs, inputs=frf.inputs)
         for fk, (order, pole, vector) in zip(fits, sets, strict=True)],
        f"{method}/local", full,
    )


class _LocalFit(NamedTuple):
    poles: PoleSet  # all poles of the fit over the widened band
    lo: float  # core
    hi: float
    guard: float  # how far beyond its core the fit offers poles (half the widening)

    def edge_distance(self, f: float) -> float:
        """Distance of a frequency from the nearer edge of the fit band, relative to its width."""
        f_lo, f_hi = self.poles.band_hz
        return min(f - f_lo, f_hi - f) / (f_hi - f_lo)


_Poles = tuple[np.ndarray, np.ndarray, np.ndarray]  # order, pole, vector


def _offered(fits: list[_LocalFit], k: int) -> _Poles:
    """Poles of fit k up to its guard beyond its core (not beyond the outer edges of the first/last core)."""
    fk = fits[k]
    f = fk.poles.frequency_hz
    lo_g = fk.lo - fk.guard if k > 0 else fk.lo
    hi_g = fk.hi + fk.guard if k < len(fits) - 1 else np.inf
    keep = (f >= lo_g) & (f <= hi_g)
    return fk.poles.order[keep], fk.poles.pole[keep], fk.poles.vector[keep]


def _dedupe_boundary(
    a: _Poles, b: _Poles, fit_a: _LocalFit, fit_b: _LocalFit, freq_tol: float, mac_min: float
) -> tuple[_Poles, _Poles]:
    """Resolve the poles two neighbouring fits offer around their common core boundary (see local_poles)."""
    (oa, pa, va), (ob, pb, vb) = a, b
    boundary = fit_a.hi
    fa, fb = np.abs(pa) / (2 * np.pi), np.abs(pb) / (2 * np.pi)
    drop_a = np.zeros(fa.size, bool)
    drop_b = np.zeros(fb.size, bool)
    za = np.flatnonzero(fa >= boundary)  # fit a's poles beyond its core
    zb = np.flatnonzero(fb < boundary)  # fit b's poles below its core
    near_a = np.flatnonzero(np.abs(fa - boundary) <= fit_a.guard)
    near_b = np.flatnonzero(np.abs(fb - boundary) <= fit_b.guard)
    matched_a, matched_b = set(), set()
    if near_a.size and near_b.size:
        # candidate pairs of the same order, closest first
        ia, ib = np.meshgrid(near_a, near_b, indexing="ij")
        ia, ib = ia.ravel(), ib.ravel()
        same = oa[ia] == ob[ib]
        ia, ib = ia[same], ib[same]
        df = np.abs(fa[ia] - fb[ib]) / fb[ib]
        num = np.abs(np.sum(va[ia].conj() * vb[ib], axis=1)) ** 2
        den = np.sum(np.abs(va[ia]) ** 2, axis=1) * np.sum(np.abs(vb[ib]) ** 2, axis=1)
        mac = num / np.maximum(den, 1e-300)
        ok = (df <= freq_tol) & (mac >= mac_min)
        ia, ib, df, mac = ia[ok], ib[ok], df[ok], mac[ok]
        for e in np.argsort(df + (1.0 - mac), kind="stable"):
            i, j = int(ia[e]), int(ib[e])
            if i in matched_a or j in matched_b:
                continue
            matched_a.add(i)
            matched_b.add(j)
            if fit_a.edge_distance(fa[i]) >= fit_b.edge_distance(fb[j]):
                drop_b[j] = True
            else:
                drop_a[i] = True
    # unmatched poles beyond their own core go
    drop_a[[i for i in za.tolist() if i not in matched_a]] = True
    drop_b[[j for j in zb.tolist() if j not in matched_b]] = True
    keep_a, keep_b = ~drop_a, ~drop_b
    return (oa[keep_a], pa[keep_a], va[keep_a]), (ob[keep_b], pb[keep_b], vb[keep_b])


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
        > 1 fits band by band (:func:`local_poles`): ``max_order`` / ``orders`` then apply to every
        sub-band, and LSRF runs with complex coefficients there (order n holds n poles of its sub-band).
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
        poles = local_poles(frf, n_bands, method, band, max_order, progress=progress, orders=orders)
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

