"""Refinement of a model's poles over its band, mode by mode in local windows where the band's refinement is refused.

:func:`refine_band` refines the poles by variable projection (:func:`ema.varpro.refine_poles`), over the whole band
or mode by mode in local windows. :func:`refine_in_band` takes the modes of a padded fit that lie inside the band
asked for and refines them there, with the padding's modes taken off the data.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .dominance import Kept, mode_dominance
from .frf import FRFSet
from .lsfd import half_widths, local_windows, modal_model, synthesize
from .modal import ModalModel
from .poles import in_band
from .varpro import refine_poles

__all__ = ["refine_band", "refine_in_band", "without_modes"]


def refine_band(frf: FRFSet, model: ModalModel, band: tuple[float, float],
                settled: tuple[np.ndarray, list[float]] = (np.zeros(0, complex), [])) -> np.ndarray:
    """Refine a model's poles over the whole band; where that is refused, refine each mode in a window around it.

    :func:`ema.varpro.refine_poles` keeps all starting poles when any of them would move by more than 1 %
    (typically a weak pole of the band's edges that the data hardly determine) or when the band's problem is
    beyond its size, which would leave every mode at the estimator's accuracy. The fallback refines each mode r
    over its local window (:func:`ema.lsfd.local_windows`: ``f_r +- W_r``, ``W_r = max(10 zeta_r f_r, 20 lines)``,
    its resonance down to about -20 dB, where the residual terms absorb what lies outside) with the modes inside
    the window as poles, on the data less the model's terms of the other modes (:func:`without_modes`, the model's
    residues), and keeps the refined pole of r where that refinement is accepted; the 1 % rule judges r alone.
    Why not the modes within ``2 W_r`` as free poles: a broad mode's window then held up to 21 poles
    (``benchmarks/ema.py``), each refinement cost 50-70 model evaluations, and a weak neighbour that moved by
    more than 1 % had the refinement of r rejected (15 of 30 windows with LSCF).

    ``settled``: the poles of an earlier refinement and the frequencies (Hz) of the modes dropped since. A mode
    whose pole is one of those keeps it unless a dropped mode lay within ``2 W_r``: its window's data and poles
    are the same but for the far modes' residues (:func:`ema.select_modes.dominant_model` refines again after each
    drop).

    Returns
    -------
    ndarray of complex128, shape (n_modes,)
    """
    poles = model.poles
    lam = refine_poles(frf, poles, band)
    if poles.size < 2 or not np.array_equal(lam, poles):
        return lam
    out = poles.copy()
    f, halves, _ = half_widths(poles, frf, band)
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
            local = refine_poles(without_modes(data, model, ~np.isin(np.arange(f.size), inside)), poles[inside], window,
                                 check=np.searchsorted(inside, [r]))
        except ValueError:  # a window the LSFD refuses (e.g. non-finite lines): keep the pole
            continue
        out[r] = local[np.searchsorted(inside, r)]
    return out


def without_modes(frf: FRFSet, model: ModalModel, modes: np.ndarray) -> FRFSet:
    """The FRFs less the synthesised terms of some modes of a model (with residues), on every line."""
    idx = np.flatnonzero(modes)
    if idx.size == 0:
        return frf
    # The modal terms alone (no residual terms): those belong to the band being refined.
    terms = replace(model.take(idx), lower_residual=None, upper_residual=None)
    return replace(frf, H=frf.H - synthesize(terms, frf.freq_hz, form=frf.form).H)


def refine_in_band(frf: FRFSet, kept: Kept, band: tuple[float, float], refine: bool, mac_min: float) -> Kept:
    """The modes of a fit over a padded band that lie inside ``band``, refitted (and refined) over ``band``.

    The band's own refinement runs on the data less the fitted modes of the padding: those modes stay in as
    fixed poles, and no misfit at the padded edges pulls on the band's modes.

    Parameters
    ----------
    frf : FRFSet
    kept : Kept
        The padded fit's model (with residues), its dominance and the frequencies (Hz) it dropped.
    band : (f_lo, f_hi)
        Hz.
    refine : bool
        Refine the band's poles (:func:`refine_band`).
    mac_min : float
        MAC threshold of the stability criteria (:func:`ema.dominance.mode_dominance`).

    Returns
    -------
    Kept
        The model over ``band``, its dominance, and the dropped frequencies inside ``band``.
    """
    model = kept.model
    keep = in_band(model.frequencies_hz, band)
    lam = model.poles[keep]
    if refine and keep.any():
        lam = refine_band(without_modes(frf, model, ~keep), model.take(np.flatnonzero(keep)), band)
    model = modal_model(frf, lam, band, quality=model.quality[keep], method=model.method)
    dom = mode_dominance(frf, model, mac_min) if model.n_modes else np.zeros(0)
    return Kept(model, dom, [f for f in kept.dropped if in_band(np.array([f]), band)[0]])
