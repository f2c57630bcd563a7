"""The global fit: the poles of the whole band, in one fit or band by band, and their stabilization diagram.

A single-band fit widens the band by ``pad`` of its width on each side where the FRFs have lines
(:func:`padded_band`), so that the estimators' edge effects fall in the padding; a band-by-band fit
(:func:`local_poles`) fits the band itself in pieces. :func:`global_fit` runs the estimator, grows the order
from the data where asked (:func:`ema.growth.grow_order`) and stabilizes the poles.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .errors import EMAError
from .frf import FRFSet
from .growth import grow_order
from .lscf import lscf
from .lsrf import lsrf
from .mac import mac_paired
from .poles import PoleSet, band_data, merge_polesets
from .selection import PoleSelection
from .settings import FitSettings
from .stabilization import StabilizationDiagram, stabilize

__all__ = ["METHODS", "estimate_poles", "local_poles", "padded_band", "GlobalFit", "global_fit"]

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


def padded_band(frf: FRFSet, band: tuple[float, float], pad: float) -> tuple[float, float]:
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


@dataclass(frozen=True)
class GlobalFit:
    """The poles of the fitted band as a diagram.

    Attributes
    ----------
    band_hz : (f_lo, f_hi)
        The band fitted (Hz): the user's band, padded for a single-band fit.
    diagram : StabilizationDiagram
    selection : PoleSelection or None
        The automatic selection of the diagram where the order grew (:func:`ema.growth.grow_order` made it).
    """

    band_hz: tuple[float, float]
    diagram: StabilizationDiagram
    selection: PoleSelection | None


def global_fit(frf: FRFSet, band: tuple[float, float], settings: FitSettings, max_order: int, grow: bool,
               progress: bool) -> GlobalFit:
    """Estimate the poles over ``band`` (padded, or band by band) at ``max_order`` and stabilize them.

    Parameters
    ----------
    frf : FRFSet
    band : (f_lo, f_hi)
        Hz, the resolved band of the modes asked for.
    settings : FitSettings
        ``method``, ``orders``, ``n_bands``, ``pad``, ``criteria`` and ``min_quality`` apply here.
    max_order : int
    grow : bool
        Grow the order from the data (:func:`ema.growth.grow_order`), as far as ``settings`` allow it (a single
        band, no explicit orders); :func:`ema.fit` asks for it with ``settings.grow`` unless poles were picked.
    progress : bool

    Returns
    -------
    GlobalFit
    """
    s = settings
    if s.n_bands > 1:
        fit_band = band
        poles = local_poles(frf, s.n_bands, s.method, band, max_order, progress=progress, orders=s.orders)
    else:
        fit_band = padded_band(frf, band, s.pad)
        poles = estimate_poles(frf, s.method, fit_band, max_order, s.orders, progress)
    if s.n_bands <= 1 and grow and s.orders is None:
        grown = grow_order(lambda top, series: estimate_poles(frf, s.method, fit_band, top, series), frf, poles,
                           s.method, band, max_order, s.criteria, s.min_quality)
        return GlobalFit(fit_band, grown.diagram, grown.selection)
    return GlobalFit(fit_band, stabilize(poles, s.criteria), None)
