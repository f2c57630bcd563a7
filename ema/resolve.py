"""Modes the fit merged, found again window by window (issue 44, item 7): the local complex LSRF check.

A single-reference LSCF fit with few outputs returns one pole for two modes 0.3 % apart at every order up to
about 200 (a blade-like hammer test, tests/ema/test_close_pairs.py): its common denominator, fitted to a short arc
of the unit circle, prefers the compromise. The complex, reweighted LSRF of :func:`ema.lsrf.lsrf` separates them
at low orders on a narrow band. :func:`split_merged` therefore refits the window of every mode the fit kept
(:func:`ema.family.family_windows`: each mode's local window, its damping at most the test's outlier bound,
overlapping ones merged) with that estimator at orders ``1 .. LOCAL_ORDER`` and selects its stable modes; where
that local selection holds more modes of quality at least :data:`SPLIT_QUALITY` in the window's core than the fit,
the window's modes are replaced by them. The
caller then refits and refines the whole model and judges every mode by its dominance as before, so a local pole
that only patches a neighbour is dropped there.

Why a local fit and not a higher global order: on the same test LSCF still merged the pair at order 120 and
resolved it only at 240, with 13 spurious stable modes; the order ladder of :func:`ema.fit_auto_order` climbed to
320 on LSRF (15 spurious modes at the band's top edge, 164 s). The local fit holds a window's few modes with a
few dozen lines, so its order, and its cost, do not grow with the band.
"""

from __future__ import annotations

import numpy as np

from .errors import EMAError
from .family_windows import family_windows
from .frf import FRFSet
from .lsrf import lsrf
from .modal import modal_from_pole
from .selection import select_auto
from .stabilization import StabilityCriteria, stabilize

__all__ = ["split_merged", "LOCAL_ORDER", "SPLIT_QUALITY"]

#: Highest order of each window's complex LSRF (order n holds n poles of its window; windows hold a few modes).
LOCAL_ORDER = 20
#: Least selection quality (order coverage × MAC) of a local mode that may replace the fit's: the true members
#: of the test's pair score 0.79–0.89, the local fits' noise clusters 0.15–0.25.
SPLIT_QUALITY = 0.5


def split_merged(frf: FRFSet, poles: np.ndarray, band: tuple[float, float],
                 criteria: StabilityCriteria | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """The fit's poles with every window whose local LSRF finds more modes replaced by those (module notes).

    Parameters
    ----------
    frf : FRFSet
    poles : ndarray of complex, shape (n,)
        The fit's modes (rad/s).
    band : (f_lo, f_hi)
        Hz; windows are clipped to it.
    criteria : StabilityCriteria, optional
        The fit's stability criteria.

    Returns
    -------
    (poles, replaced) or None
        All poles sorted by magnitude, and which of them came from a local fit; None where no window changed.
    """
    poles = np.asarray(poles, np.complex128).reshape(-1)
    if poles.size == 0:
        return None
    f = modal_from_pole(poles)[0]
    keep = np.ones(poles.size, bool)
    new: list[np.ndarray] = []
    for window, core in family_windows(poles, frf, band):
        in_core = (f >= core[0]) & (f <= core[1])
        local = _local_modes(frf, window, core, criteria)
        if local is not None and local.size > np.count_nonzero(in_core):
            keep &= ~in_core
            new.append(local)
    if not new:
        return None
    added = np.concatenate(new)
    out = np.r_[poles[keep], added]
    mark = np.r_[np.zeros(keep.sum(), bool), np.ones(added.size, bool)]
    order = np.argsort(np.abs(out), kind="stable")
    return out[order], mark[order]


def _local_modes(frf: FRFSet, window: tuple[float, float], core: tuple[float, float],
                 criteria: StabilityCriteria | None) -> np.ndarray | None:
    """Poles of the modes that a complex LSRF of ``window`` selects in ``core`` with quality ≥ SPLIT_QUALITY."""
    try:
        ps = lsrf(frf, band=window, max_order=LOCAL_ORDER, coefficients="complex")
    except EMAError:  # too few lines in the window for the order
        return None
    sel = select_auto(stabilize(ps, criteria))
    f = sel.frequencies_hz
    ok = (f >= core[0]) & (f <= core[1]) & (sel.quality >= SPLIT_QUALITY)
    return sel.pole[ok]
