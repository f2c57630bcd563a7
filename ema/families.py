"""Dense mode families: every window of several modes refitted by the structured fit, and the better of each mode.

:func:`resolve_families` fits every window of :func:`ema.family.family_windows` that holds two or more of a
model's modes with rank-one residues (:func:`ema.family.fit_family`), grown while a new mode explains more than the
noise of its band, on the FRFs weighted by the rank-one part of their noise, each window's shapes then by each
FRF's own (:func:`ema.family.fit_weighted`). :func:`merge_families` then takes each mode from the fit that gives it
the smaller standard deviation.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .family import FamilyFit, fit_weighted
from .family_windows import family_windows
from .fit_noise import band_floor
from .frf import FRFSet
from .lsfd import modal_model, shapes_from_residues
from .modal import ModalModel, modal_from_pole
from .poles import single_thread_blas

__all__ = ["resolve_families", "merge_families"]

log = logging.getLogger(__name__)


def resolve_families(frf: FRFSet, poles: np.ndarray, band: tuple[float, float], min_modes: int = 2,
                     progress: bool = False) -> list[FamilyFit]:
    """Structured fits of every window holding at least ``min_modes`` of ``poles`` (see the module docstring).

    Parameters
    ----------
    frf : FRFSet
    poles : ndarray of complex, shape (n,)
        The modes an ordinary fit found (rad/s).
    band : (f_lo, f_hi)
        Hz; windows are clipped to it.
    min_modes : int
        Windows with fewer modes are left to the ordinary fit (a lone mode is no family).
    progress : bool
        A progress bar over the windows (tqdm).
    """
    poles = np.asarray(poles, np.complex128).reshape(-1)
    f = modal_from_pole(poles)[0]
    jobs = [(w, c) for w, c in family_windows(poles, frf, band)
            if np.count_nonzero((f >= w[0]) & (f <= w[1])) >= min_modes]
    if progress:
        from tqdm import tqdm
        jobs = tqdm(jobs, desc="mode families", unit="window")
    fits = []
    # each FRF weighted by its noise (ema.fit_noise.band_floor): the noise differs by 10^4 between the FRFs of a
    # full-assembly test, and unweighted, the strong FRFs' noise buried modes that the quiet ones show (the bundled
    # campaign's 1081.7 and 1087.4 Hz; design §8.61)
    floor = band_floor(frf, band)
    for window, core in jobs:
        inside = (f >= window[0]) & (f <= window[1])
        fit = fit_weighted(frf, floor, poles[inside], window, core)
        log.info("family %.6g-%.6g Hz: %d modes -> %d", *window, fit.n_start, fit.n_modes)
        fits.append(fit)
    return fits


def merge_families(frf: FRFSet, model: ModalModel, fits: Sequence[FamilyFit],
                   found: Sequence[np.ndarray] | None = None) -> ModalModel:
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
        :func:`resolve_families` on ``model.poles``.
    found : sequence of ndarray of bool, optional
        Per fit, shape (n_modes,) in its order: structured modes kept as new even where growth added no mode (the
        mode :func:`ema.unexplained.fill_unexplained` found on the line that opened its window).
    """
    if not fits:
        return model
    f, z = model.frequencies_hz, model.damping_ratio
    sig = np.where(np.isfinite(model.frequency_std_hz), model.frequency_std_hz, np.inf)
    spacing = float(np.median(np.diff(frf.freq_hz))) if frf.freq_hz.size > 1 else 0.0
    keep_ord = np.ones(f.size, bool)
    lam, res, fs, zs = [], [], [], []
    for i, fit in enumerate(fits):
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
            keep_s &= taken | (found[i] if found is not None else False)
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
        shapes[:, structured] = shapes_from_residues(np.concatenate(res)[idx], new[idx], frf)[0]
    # modes of an earlier structured fit keep their rank-one shapes: this LSFD's residues are free ones
    earlier = np.r_[_structured(model)[keep_ord], np.zeros(new.size, bool)][order]
    source = np.r_[np.arange(keep_ord.sum()), np.full(new.size, -1)][order]
    shapes[:, earlier] = model.shapes[:, keep_ord][:, source[earlier]]
    merged = replace(merged, shapes=shapes)
    return replace(merged, frequency_std_hz=f_std[order], damping_std=z_std[order])


def _with_tag(method: str, tag: str) -> str:
    """``method`` with ``tag`` appended once (merges repeat: the residual scan merges window by window)."""
    return method if method.endswith(tag) else method + tag


def _structured(model: ModalModel) -> np.ndarray:
    """Which modes came from a structured fit (:func:`merge_families` gives them no selection quality)."""
    if model.quality is None:
        return np.zeros(model.n_modes, bool)
    return np.isnan(np.asarray(model.quality, dtype=np.float64))
