"""One-call EMA: poles over orders -> stabilization diagram -> selection -> LSFD modal model.

Also local (band-by-band) pole estimation for dense spectra.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from .errors import EMAError
from .family import FamilyFit, fit_family, resolve_families, unexplained_lines
from .frf import FRF_FORMS, FRFSet
from .growth import grow_order
from .lscf import lscf
from .lsfd import _half_widths, _shapes, dominance, fit_quality, local_windows, modal_model, refine_poles, synthesize
from .lsrf import lsrf
from .mac import distinct_mac, mac, mac_paired
from .modal import ModalModel, modal_from_pole, pole_from_modal
from .poles import PoleSet, band_data, merge_polesets, single_thread_blas
from .resolve import split_merged
from .selection import PoleSelection, select_auto, select_near, select_picks
from .stabilization import StabilityCriteria, StabilizationDiagram, stabilize
from .uncertainty import order_spread, pole_std

__all__ = ["METHODS", "estimate_poles", "local_poles", "EMAResult", "fit", "mode_dominance", "merge_families",
           "fill_unexplained"]

log = logging.getLogger(__name__)

METHODS = {"lscf": lscf, "lsrf": lsrf}


def estimate_poles(
    frf: FRFSet,
    method: str = "lsrf",
    band: tuple[float, float] | None = None,
    max_order: int = 60,
    orders: Sequence[int] | None = None,
    progress: bool = False,
) -> PoleSet:
    """Run one pole estimator (``"lscf"`` or ``"lsrf"``) over a band.

    ``"lscf"`` is :func:`ema.lscf.lscf`; ``"lsrf"`` is :func:`ema.lsrf.lsrf` with complex coefficients
    (order n holds up to n poles in the band). The real-coefficient model resolves a close pair only at
    some orders (at the others the two members merge into one pole, odd and even orders alternating),
    while the complex, reweighted one separates it at most orders above the number of modes in the band
    (tests/ema/test_close_modes.py). Call :func:`ema.lsrf.lsrf` directly for the real model.

    Returns
    -------
    PoleSet
    """
    if method not in METHODS:
        raise EMAError(f"method {method!r} not one of {sorted(METHODS)}")
    if method == "lsrf":
        return lsrf(frf, band=band, max_order=max_order, orders=orders, progress=progress, coefficients="complex")
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
        raise EMAError(f"method {method!r} not one of {sorted(METHODS)}")
    if int(n_bands) < 1:
        raise EMAError(f"n_bands {n_bands}: expected >= 1")
    n_bands = int(n_bands)
    if not 0 <= overlap <= 1:
        raise EMAError(f"overlap {overlap}: expected in [0, 1]")
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
    f = fk.poles.frequencies_hz
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
        mac = mac_paired(va[ia], vb[ib])
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
    max_order: int = 60,
    orders: Sequence[int] | None = None,
    frequencies_hz: Sequence[float] | None = None,
    picks: Sequence[tuple[int, float]] | None = None,
    criteria: StabilityCriteria | None = None,
    min_quality: float = 0.15,
    min_dominance: float = 0.7,
    n_bands: int = 1,
    refine: bool = True,
    progress: bool = False,
    pad: float = 0.25,
    families: bool = False,
    split: bool = True,
    grow: bool = True,
) -> EMAResult:
    """Identify modes from FRFs in one call.

    A single-band fit (``n_bands=1``) estimates the poles, selects and refines the modes over the band
    widened by ``pad`` of its width on each side, where the FRFs have lines, and then keeps the modes
    inside the band: a mode near a band edge is then as accurate as one in the middle, because the
    estimators' edge effects fall in the padding, and the modes just outside the band enter the LSFD
    model and the refinement as poles instead of through the residual terms.

    Parameters
    ----------
    frf : FRFSet
    method : {"lsrf", "lscf"}
        Pole estimator (:func:`estimate_poles`; LSRF with complex coefficients). LSRF is the default: on
        close pairs it separates the two modes at every order, where LSCF often returns a single pole
        for both (tests/ema/test_close_modes.py).
    band : (f_lo, f_hi) in Hz, optional
        Band of the modes returned; default all lines (no padding possible then).
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
        Drop modes whose :func:`mode_dominance` is below this (poles that only patch the fit of a
        neighbour), then refit; again after the refinement. Applies to automatically selected modes and
        to the modes of the padding, never to modes chosen by ``frequencies_hz`` or ``picks``. 0 keeps
        everything.
    n_bands : int
        > 1 fits band by band (:func:`local_poles`) over the band itself (no padding): ``max_order`` /
        ``orders`` then apply to every sub-band.
    refine : bool
        Refine the selected poles by nonlinear least squares on the LSFD model.
    progress : bool
    pad : float
        Widening of the band on each side, as a fraction of its width (single-band fits); 0 fits the band
        alone.
    families : bool
        Resolve dense mode families (:func:`ema.family.resolve_families`): every window of two or more of the
        selected modes is refitted with rank-one residues and grown while a new mode explains more than the
        noise of its band. Each mode is then taken from the fit that gives it the smaller standard deviation
        (:func:`merge_families`), and wherever the residual still stands above the noise a window is opened and
        grown the same way (:func:`fill_unexplained`), so the modes the pole estimator missed at ``max_order``
        are found too. For tests of a whole mistuned bladed disk.
    split : bool
        Refit the window of every automatically selected mode with the complex LSRF and take its modes where
        it finds more (:func:`ema.resolve.split_merged`: two modes that the estimator merged at its order), then
        refit, refine and judge the dominance of the whole model again. Not with ``frequencies_hz``, ``picks`` or
        ``families`` (whose growth resolves its windows itself; the check moved a family's starting modes and left
        one mode of tests/ema/test_family.py's family at shape MAC 0.02).
    grow : bool
        The order from the data (single-band fits, no ``orders``, no ``picks``): double ``max_order`` while the
        automatic selection fills more than 1/:data:`ema.growth.HEADROOM` of the modes the estimator's highest
        order holds and the diagram's upper orders still add modes (:func:`ema.growth.grow_order`).

    Returns
    -------
    EMAResult
        Diagram, selection and model of the band (the diagram's poles come from the padded fit).

    Raises
    ------
    EMAError
        Both ``frequencies_hz`` and ``picks``, a negative ``pad``, or a bad method, band or order.
    """
    if frequencies_hz is not None and picks is not None:
        raise EMAError("give approximate frequencies or explicit picks, not both")
    if not pad >= 0:
        raise EMAError(f"pad {pad}: expected >= 0")
    user_band = band_data(frf, band, per="none").band_hz
    if n_bands > 1:
        fit_band = user_band
        poles = local_poles(frf, n_bands, method, user_band, max_order, progress=progress, orders=orders)
    else:
        fit_band = _padded(frf, user_band, pad)
        poles = estimate_poles(frf, method, fit_band, max_order, orders, progress)
    grown = None
    if n_bands <= 1 and grow and orders is None and picks is None:
        grown = grow_order(lambda top, series: estimate_poles(frf, method, fit_band, top, series), frf, poles,
                           method, user_band, max_order, criteria, min_quality)
        poles = grown.poles
    diagram = grown.diagram if grown is not None else stabilize(poles, criteria)
    inside = _band_mask(user_band)
    if picks is not None or frequencies_hz is not None:
        chosen = (select_picks(diagram, picks) if picks is not None
                  else select_near(_restrict(diagram, user_band), frequencies_hz))
        # modes of the padding, to model what lies just outside the band; the user's own choice is kept
        extra = select_auto(diagram, min_quality=min_quality)
        extra = _subset(extra, ~inside(extra.frequencies_hz))
        selection = _merge(chosen, extra)
        protect = np.isin(selection.pole, chosen.pole)
    else:
        selection = grown.selection if grown is not None else select_auto(diagram, min_quality=min_quality)
        protect = np.zeros(selection.n_modes, bool)
    with single_thread_blas():
        model, dom, dropped = _finish(frf, diagram, selection, min_dominance, refine, protect)
        if fit_band != user_band:
            keep = inside(model.frequencies_hz)
            lam = model.poles[keep]
            if refine and keep.any():
                # the band's own refinement, on the data less the fitted modes of the padding: those modes
                # stay in as fixed poles, and no misfit at the padded edges pulls on the band's modes
                lam = _refine(_without(frf, model, ~keep), model.take(np.flatnonzero(keep)), user_band)
            model = modal_model(frf, lam, user_band, quality=model.quality[keep], method=diagram.method)
            dom = mode_dominance(frf, model, diagram.criteria.mac_min) if model.n_modes else np.zeros(0)
            dropped = [f for f in dropped if inside(np.array([f]))[0]]
            diagram = _restrict(diagram, user_band)
            selection = _subset(selection, inside(selection.frequencies_hz))
        if split and not families and picks is None and frequencies_hz is None:
            model, dom, dropped = _split(frf, model, diagram, user_band, (min_dominance, refine), dom, dropped)
        if model.n_modes:  # each mode's standard deviations: the fit's covariance and the scatter over orders
            f_std, z_std = pole_std(frf, model.poles, user_band)
            f_std = np.hypot(f_std, order_spread(model.frequencies_hz, model.damping_ratio, diagram))
            model = replace(model, frequency_std_hz=f_std, damping_std=z_std)
        if families and model.n_modes:
            fits = resolve_families(frf, model.poles, user_band, progress=progress)
            model = fill_unexplained(frf, merge_families(frf, model, fits), user_band, [f.window_hz for f in fits])
            dom = mode_dominance(frf, model, diagram.criteria.mac_min) if model.n_modes else np.zeros(0)
    quality = fit_quality(frf, model) if model.n_modes else np.zeros((frf.n_outputs, frf.n_inputs))
    log.info("%s: %d modes in %.6g-%.6g Hz", diagram.method, model.n_modes, *diagram.band_hz)
    return EMAResult(diagram=diagram, selection=selection, model=model, quality=quality, dominance=dom,
                     dropped_hz=tuple(sorted(dropped)))


def merge_families(frf: FRFSet, model: ModalModel, fits: Sequence[FamilyFit]) -> ModalModel:
    """The model with each window's modes taken from the more precise of the ordinary and the structured fit.

    An ordinary mode corresponds to the nearest structured mode of its window within ``max(2 ζ f, 2 lines)``.
    It is kept, and that structured mode dropped, when its own frequency standard deviation is the smaller
    (a mode seen by few FRFs under the large background of a strong family is fitted better with free
    residues); otherwise the structured mode replaces it. An ordinary mode with no structured counterpart is
    kept, and structured modes that correspond to no ordinary mode are new modes; ordinary modes are matched
    closest first, each structured mode to one at most. Shapes and standard deviations of the structured modes
    come from their rank-one residues and sandwich covariance (:class:`ema.family.FamilyFit`); modes of an
    earlier merge's structured fits (no selection quality) keep their shapes.

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        The ordinary fit, with ``frequency_std_hz``.
    fits : sequence of FamilyFit
        :func:`ema.family.resolve_families` on ``model.poles``.
    """
    if not fits:
        return model
    f, z = model.frequencies_hz, model.damping_ratio
    sig = np.where(np.isfinite(model.frequency_std_hz), model.frequency_std_hz, np.inf)
    spacing = float(np.median(np.diff(frf.freq_hz))) if frf.freq_hz.size > 1 else 0.0
    keep_ord = np.ones(f.size, bool)
    lam, res, fs, zs = [], [], [], []
    for fit in fits:
        ff = modal_from_pole(fit.poles)[0]
        keep_s = np.ones(ff.size, bool)
        taken = np.zeros(ff.size, bool)   # each structured mode answers for one ordinary mode at most
        inside = np.flatnonzero((f >= fit.window_hz[0]) & (f <= fit.window_hz[1]))
        for r in sorted(inside, key=lambda r: np.min(np.abs(ff - f[r])) if ff.size else 0.0):
            near = np.where(taken, np.inf, np.abs(ff - f[r]))
            s = int(np.argmin(near)) if ff.size else -1
            if s < 0 or near[s] > max(2 * z[r] * f[r], 2 * spacing):
                continue  # the structured fit lost it: the ordinary mode stays
            taken[s] = True
            s_sig = fit.frequency_std_hz[s] if np.isfinite(fit.frequency_std_hz[s]) else np.inf
            if sig[r] < s_sig:
                keep_s[s] = False
            else:
                keep_ord[r] = False
        if fit.n_modes <= fit.n_start:
            # growth added nothing, so a structured mode that answers for no ordinary mode is a starting mode
            # that left its own (seed 12: 556.8 and 592.2 Hz moved to 573.7 Hz, 2.7 % from every true mode, and
            # to the window's edge, fitting the tail of two modes outside it); the ordinary modes stay
            keep_s &= taken
        lam.append(fit.poles[keep_s])
        res.append(fit.residues[keep_s])
        fs.append(fit.frequency_std_hz[keep_s])
        zs.append(fit.damping_std[keep_s])
    new = np.concatenate(lam)
    poles = np.r_[model.poles[keep_ord], new]
    mark = np.r_[np.zeros(keep_ord.sum(), bool), np.ones(new.size, bool)]
    f_std = np.r_[model.frequency_std_hz[keep_ord], np.concatenate(fs)]
    z_std = np.r_[model.damping_std[keep_ord], np.concatenate(zs)]
    quality = np.r_[model.quality[keep_ord], np.full(new.size, np.nan)] if model.quality is not None else None
    order = np.argsort(np.abs(poles), kind="stable")
    with single_thread_blas():
        merged = modal_model(frf, poles[order], model.band_hz, quality=None if quality is None else quality[order],
                             method=_with_tag(model.method, "+families"))
    structured = mark[order]
    shapes = merged.shapes.copy()
    if structured.any():
        # the structured modes' shapes: their rank-one residues, scaled as the ordinary ones
        idx = np.argsort(np.abs(new), kind="stable")
        shapes[:, structured] = _shapes(np.concatenate(res)[idx], new[idx], frf)[0]
    # modes of an earlier structured fit keep their rank-one shapes: this LSFD's residues are free ones
    earlier = np.r_[_structured(model)[keep_ord], np.zeros(new.size, bool)][order]
    source = np.r_[np.arange(keep_ord.sum()), np.full(new.size, -1)][order]
    shapes[:, earlier] = model.shapes[:, keep_ord][:, source[earlier]]
    merged = replace(merged, shapes=shapes)
    return replace(merged, frequency_std_hz=f_std[order], damping_std=z_std[order])


def fill_unexplained(frf: FRFSet, model: ModalModel, band: tuple[float, float],
                     tried: Sequence[tuple[float, float]] = ()) -> ModalModel:
    """Open a structured fit wherever the data hold modes that ``model`` misses (the order from the data).

    A fit at a fixed model order finds nothing of a family whose stable poles need a higher order, and a window
    grown from the found modes never reaches it. Here the line that :func:`ema.family.unexplained_lines` ranks
    highest above its noise threshold gets a window (the local half-width rule of :func:`ema.lsfd.local_windows`
    at the model's median damping). :func:`ema.family.fit_family` grows it from the model's modes inside it, on
    the data less the model's other modes (so that a strong neighbour's tail does not draw the new pole away);
    a grown window is merged in (:func:`merge_families`) when one of its modes sits on the line that opened
    it, and the residual is scanned again. Each try uses up its window's core, so the loop ends; it
    ends early when no line stands above the threshold.

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        With residues and ``frequency_std_hz`` (at least one mode: its damping sets the windows' width).
    band : (f_lo, f_hi)
        Hz.
    tried : sequence of (f_lo, f_hi)
        Hz ranges already grown (the windows of :func:`ema.family.resolve_families`): not tried again.
    """
    tried = list(tried)
    scan = unexplained_lines(frf, model, band) if model.n_modes else None
    while scan is not None:
        freq, z, threshold, floor = scan
        z = z.copy()
        for lo, hi in tried:
            z[(freq >= lo) & (freq <= hi)] = 0.0
        k = int(np.argmax(z))
        if z[k] <= threshold:
            break
        zeta = float(np.median(model.damping_ratio))
        _, half, _ = _half_widths(pole_from_modal(np.array([freq[k]]), np.array([zeta])), frf, band)
        window = (max(band[0], freq[k] - half[0]), min(band[1], freq[k] + half[0]))
        core = (max(window[0], freq[k] - half[0] / 2), min(window[1], freq[k] + half[0] / 2))
        tried.append(core)
        f = model.frequencies_hz
        inside = (f >= window[0]) & (f <= window[1])
        # weighted by the noise floor: a mode that only a few quiet FRFs see (a disk mode at the blade tips)
        # counts by its own noise there, not under the strong FRFs' noise
        scale = _rank_one(floor)
        data = _without(frf, model, ~inside)
        fit = fit_family(replace(data, H=data.H / scale[:, :, None]), model.poles[inside], window, core, zeta0=zeta)
        fit = replace(fit, residues=fit.residues * scale[None])
        log.info("unexplained %.6g Hz (z %.3g > %.3g): %d modes -> %d", freq[k], z[k], threshold, fit.n_start,
                 fit.n_modes)
        f_new, z_new = modal_from_pole(fit.poles)
        # kept only if a mode of it sits on the line that opened the window: within max(2 ζ f, 2 lines), as
        # merge_families matches, with ζ its own but at most the model's median. A pole that wandered off to
        # fit something else in the window is noise; so is a narrow one beside the line (a 6-blade campaign:
        # ζ 0.025 %, 1.35 Hz away, 2.8 % from every true mode) and a broad one whose band merely covers it
        # (seed 12: ζ 2.5 %, 6 Hz away, 1.2 % from every true mode)
        spacing = float(np.median(np.diff(freq))) if freq.size > 1 else 0.0
        reach = np.maximum(2 * np.minimum(z_new, zeta) * f_new, 2 * spacing)
        if fit.n_modes > fit.n_start and np.any(np.abs(f_new - freq[k]) <= reach):
            model = merge_families(frf, model, [fit])
            scan = unexplained_lines(frf, model, band)
    return model


def _with_tag(method: str, tag: str) -> str:
    """``method`` with ``tag`` appended once (merges repeat: the residual scan merges window by window)."""
    return method if method.endswith(tag) else method + tag


def _rank_one(floor: np.ndarray) -> np.ndarray:
    """The nearest ``a_o b_i`` to a positive (n_outputs, n_inputs) array in log scale: a weighting of the FRFs that
    the rank-one residues ``ψ l^T`` absorb exactly (ψ_o scales by a_o, l_i by b_i)."""
    lg = np.log(floor)
    return np.exp(lg.mean(axis=1, keepdims=True) + lg.mean(axis=0, keepdims=True) - lg.mean())


def _structured(model: ModalModel) -> np.ndarray:
    """Which modes came from a structured fit (:func:`merge_families` gives them no selection quality)."""
    if model.quality is None:
        return np.zeros(model.n_modes, bool)
    return np.isnan(np.asarray(model.quality, dtype=np.float64))


def _padded(frf: FRFSet, band: tuple[float, float], pad: float) -> tuple[float, float]:
    """``band`` widened by ``pad`` of its width on each side, as far as the FRFs have finite lines.

    The widening stops short of a line with a non-finite value (which the estimators refuse), except a
    0 Hz line, which they leave out anyway.
    """
    freq = frf.freq_hz
    finite = frf.valid_lines()
    bad = freq[~finite & (freq > 0)]
    good = freq[finite & (freq > 0)]
    if pad == 0 or good.size == 0:
        return band
    width = band[1] - band[0]
    below, above = bad[bad < band[0]], bad[bad > band[1]]
    lo_lines = good[good > below.max()] if below.size else good
    hi_lines = good[good < above.min()] if above.size else good
    lo = max(band[0] - pad * width, float(lo_lines[0])) if lo_lines.size else band[0]
    hi = min(band[1] + pad * width, float(hi_lines[-1])) if hi_lines.size else band[1]
    return (min(lo, band[0]), max(hi, band[1]))


def _without(frf: FRFSet, model: ModalModel, modes: np.ndarray) -> FRFSet:
    """The FRFs less the synthesised terms of some modes of a model (with residues), on every line."""
    idx = np.flatnonzero(modes)
    if idx.size == 0:
        return frf
    # The modal terms alone (no residual terms): those belong to the band being refined.
    terms = replace(model.take(idx), lower_residual=None, upper_residual=None)
    return replace(frf, H=frf.H - synthesize(terms, frf.freq_hz, form=frf.form).H)


def _band_mask(band: tuple[float, float]):
    """A function telling which frequencies (Hz, ndarray) lie in ``band``."""
    return lambda f: (np.asarray(f) >= band[0]) & (np.asarray(f) <= band[1])


def _restrict(diagram: StabilizationDiagram, band: tuple[float, float]) -> StabilizationDiagram:
    """The diagram's poles inside ``band``, with that band."""
    keep = _band_mask(band)(diagram.frequencies_hz)
    fields = ("order", "pole", "frequencies_hz", "damping_ratio", "vector", "stability", "mac_prev")
    return replace(diagram, band_hz=band, **{name: getattr(diagram, name)[keep] for name in fields})


def _subset(selection: PoleSelection, keep: np.ndarray) -> PoleSelection:
    fields = ("pole", "frequencies_hz", "damping_ratio", "quality", "vector", "n_poles")
    return replace(selection, **{name: getattr(selection, name)[keep] for name in fields})


def _merge(a: PoleSelection, b: PoleSelection) -> PoleSelection:
    """Two selections as one (ascending frequency), named after the first."""
    fields = ("pole", "frequencies_hz", "damping_ratio", "quality", "vector", "n_poles")
    both = {name: np.concatenate([getattr(a, name), getattr(b, name)]) for name in fields}
    srt = np.argsort(np.abs(both["pole"]), kind="stable")
    return replace(a, **{name: value[srt] for name, value in both.items()})


def _finish(
    frf: FRFSet,
    diagram: StabilizationDiagram,
    selection: PoleSelection,
    min_dominance: float,
    refine: bool,
    protect: np.ndarray,
) -> tuple[ModalModel, np.ndarray, list[float]]:
    """LSFD, dominance filter and optional refinement of a selection over the diagram's band.

    ``protect`` (bool, shape (n_modes,), in the selection's order) marks modes the filter never drops.
    With refinement the filter judges the refined model, and the survivors are refined and judged again
    until none is below ``min_dominance``: at the estimator's rough pole the weaker member of a close
    pair can look like a patch, and a pole that only fits noise or patches a peak can look like a
    resonance until the refinement has moved it.
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
        lam = _refine(frf, model, diagram.band_hz, settled=(last[0], dropped[last[1]:]))
        last[:] = [lam, len(dropped)]
        return lsfd_model(lam, model.quality, kept)

    model, dom, kept = lsfd_model(selection.pole, selection.quality, np.asarray(protect, bool))
    # each pass drops at least one mode, so this ends; refinement moves poles, so judge again after it
    while True:
        if refine and model.n_modes:
            model, dom, kept = refined(model, kept)
        if not (min_dominance > 0 and np.any((dom < min_dominance) & ~kept)):
            return model, dom, dropped
        model, dom, kept = drop(model, dom, kept)
        if not refine:
            return model, dom, dropped


def _split(frf: FRFSet, model: ModalModel, diagram: StabilizationDiagram, band: tuple[float, float],
           settings: tuple[float, bool], dom: np.ndarray, dropped: list[float]
           ) -> tuple[ModalModel, np.ndarray, list[float]]:
    """The model with the modes :func:`ema.resolve.split_merged` finds in its windows, refitted over ``band`` (LSFD,
    refinement, dominance as :func:`_finish`); the model unchanged where no window gains a mode."""
    found = split_merged(frf, model.poles, band, diagram.criteria)
    if found is None:
        return model, dom, dropped
    lam, local = found
    quality = np.full(lam.size, 1.0)  # both in ascending |λ|: the kept modes keep their selection quality
    if model.quality is not None:
        quality[~local] = np.asarray(model.quality, float)[np.isin(model.poles, lam[~local])]
    log.info("local LSRF: %d modes -> %d before the dominance check", model.n_modes, lam.size)
    chosen = _Chosen(lam, quality)
    fitted, dom, more = _finish(frf, replace(diagram, band_hz=band), chosen, settings[0], settings[1],
                                np.zeros(lam.size, bool))
    return fitted, dom, sorted([*dropped, *more])


class _Chosen(NamedTuple):
    """The two fields of a selection that :func:`_finish` reads."""

    pole: np.ndarray
    quality: np.ndarray


def _refine(frf: FRFSet, model: ModalModel, band: tuple[float, float],
            settled: tuple[np.ndarray, list[float]] = (np.zeros(0, complex), [])) -> np.ndarray:
    """Refine a model's poles over the whole band; where that is refused, refine each mode in a window around it.

    :func:`ema.lsfd.refine_poles` keeps all starting poles when any of them would move by more than 1 %
    (typically a weak pole of the band's edges that the data hardly determine) or when the band's problem is
    beyond its size, which would leave every mode at the estimator's accuracy. The fallback refines each mode r
    over its local window (:func:`ema.lsfd.local_windows`: ``f_r +- W_r``, ``W_r = max(10 zeta_r f_r, 20 lines)``,
    its resonance down to about -20 dB, where the residual terms absorb what lies outside) with the modes inside
    the window as poles, on the data less the model's terms of the other modes (:func:`_without`, the model's
    residues), and keeps the refined pole of r where that refinement is accepted; the 1 % rule judges r alone.
    Why not the modes within ``2 W_r`` as free poles, as before: a broad mode's window then held up to 21 poles
    (``benchmarks/ema.py``), each refinement cost 50-70 model evaluations, and a weak neighbour that moved by
    more than 1 % had the refinement of r rejected (15 of 30 windows with LSCF).

    ``settled``: the poles of an earlier refinement and the frequencies (Hz) of the modes dropped since. A mode
    whose pole is one of those keeps it unless a dropped mode lay within ``2 W_r``: its window's data and poles
    are the same but for the far modes' residues (:func:`_finish` refines again after each drop).

    Returns
    -------
    ndarray of complex128, shape (n_modes,)
    """
    poles = model.poles
    lam = refine_poles(frf, poles, band)
    if poles.size < 2 or not np.array_equal(lam, poles):
        return lam
    out = poles.copy()
    f, halves, _ = _half_widths(poles, frf, band)
    for r, item in enumerate(local_windows(poles, frf, band)):
        if item is None:
            continue  # too few lines for the poles and residual terms of the window
        window, near = item
        if np.any(np.isclose(poles[r], settled[0], rtol=1e-12, atol=0)) and not np.any(
                np.abs(np.asarray(settled[1]) - f[r]) <= 2 * halves[r]):
            continue  # refined before, and no mode near it dropped since
        inside = near[np.abs(f[near] - f[r]) <= halves[r]]
        try:
            data = frf.band(*window)
            local = refine_poles(_without(data, model, ~np.isin(np.arange(f.size), inside)), poles[inside], window,
                                 check=np.searchsorted(inside, [r]))
        except ValueError:  # a window the LSFD refuses (e.g. non-finite lines): keep the pole
            continue
        out[r] = local[np.searchsorted(inside, r)]
    return out


#: How far (amplitude ratio) a mode's own term must stand above the local fit residual for its separated
#: dominance to count (see :func:`mode_dominance`).
SEPARATION_SNR = 10.0


def mode_dominance(frf: FRFSet, model: ModalModel, mac_min: float = 0.95) -> np.ndarray:
    """Dominance of each mode, telling close modes with distinct shapes apart (what ``fit`` filters on).

    The larger of :func:`ema.lsfd.dominance` (own term over the measured FRF at the mode's frequency) and
    a separated dominance: the own term over what the measured FRF leaves once the terms of the modes
    with other shapes are taken off, plus the RMS fit residual around the mode,

    ``d_r = max_f |H_f,r(f_r)| / (|H_f(f_r) - sum_s H_f,s(f_r)| + rms_f(H_f - H_f,model))``,

    the sum over the modes s whose shapes are distinct from mode r's (MAC below
    :func:`ema.mac.distinct_mac` of ``mac_min``), the maximum over the FRFs f where the own term stands
    :data:`SEPARATION_SNR` times (20 dB) above that residual. At a close pair the stronger member's term
    covers the weaker one at every response point, so its plain dominance is low although it is a
    resonance; with the partner's term taken off it is about 1 again. A pole that only fits noise
    absorbs that noise, so its term stands only a few times above the residual left (2-7 in the tests,
    against 50 and more for the weaker member of a close pair at 1 % noise): the 20 dB margin keeps it
    at its plain dominance. The separation is trusted only between
    resolved modes, whose half-power band ``2 zeta f`` spans at least one line: around a peak narrower
    than the line spacing the estimators place extra poles that patch its shape, with vectors that
    differ at few response points, and those must keep their low plain dominance. Modes with no
    resolved, distinct partner get the plain dominance.

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        With residues (:func:`ema.lsfd.modal_model`).
    mac_min : float
        MAC threshold of the stability criteria; shapes below ``distinct_mac(mac_min)`` are distinct.

    Returns
    -------
    ndarray, shape (n_modes,)
    """
    plain = dominance(frf, model)
    if model.n_modes < 2:
        return plain
    data = frf.with_form(model.form) if frf.form != model.form else frf
    valid = data.valid_lines()
    lines, H = data.freq_hz[valid], data.H[:, :, valid]
    if lines.size < 2:
        return plain
    spacing = np.interp(model.frequencies_hz, lines, np.gradient(lines))
    half_width = model.damping_ratio * model.frequencies_hz
    resolved = 2.0 * half_width >= spacing
    distinct = (mac(model.shapes, model.shapes) < distinct_mac(mac_min)) & resolved[None, :] & resolved[:, None]
    out = plain.copy()
    for r in np.flatnonzero(distinct.any(axis=1)):
        # residual level from the lines of the half-power band, at least the nearest five
        near = np.flatnonzero(np.abs(lines - model.frequencies_hz[r]) <= max(half_width[r], 2.0 * spacing[r]))
        if near.size == 0:
            continue
        resid = H[:, :, near] - synthesize(model, lines[near]).H
        rms = np.sqrt(np.mean(np.abs(resid) ** 2, axis=2))
        i = near[np.argmin(np.abs(lines[near] - model.frequencies_hz[r]))]
        terms = _mode_terms(model, lines[i])  # (n_modes, n_outputs, n_inputs)
        own = np.abs(terms[r])
        rest = np.abs(H[:, :, i] - terms[distinct[r]].sum(axis=0)) + rms
        sep = np.where(own >= SEPARATION_SNR * rms, own / np.where(rest > 0, rest, np.inf), 0.0)
        out[r] = max(out[r], float(np.max(sep)))
    return out


def _mode_terms(model: ModalModel, freq_hz: float) -> np.ndarray:
    """Each mode's term of the synthesis at one frequency, in the model's form, shape (n_modes, n_o, n_i)."""
    jw = 1j * 2 * np.pi * freq_hz
    lam = model.poles[:, None, None]
    A = model.residues
    return (A / (jw - lam) + A.conj() / (jw - lam.conj())) * jw ** FRF_FORMS[model.form]
