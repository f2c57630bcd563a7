"""The windows of the structured family fit (:func:`ema.family.fit_family`): each mode's local window, merged."""

from __future__ import annotations

import numpy as np

from .frf import FRFSet
from .lsfd import half_widths
from .modal import modal_from_pole, pole_from_modal

__all__ = ["damping_outlier_bound", "family_windows"]


def family_windows(poles: np.ndarray, frf: FRFSet, band: tuple[float, float]) -> list[tuple[tuple, tuple]]:
    """Windows of the structured fit: each mode's local window (:func:`ema.lsfd.local_windows`' rule, with its
    damping ratio at most :func:`damping_outlier_bound` of the poles'), overlapping ones merged, clipped to ``band``.

    Why the bound: a window's width follows its poles' damping, and one pole far more damped than the rest
    stretched its family's window over hundreds of hertz, where the residual terms cannot stand for the modes
    outside and the refinement sent every pole to the damping bound (bundled test: a pole at 1093 Hz, ζ 2.5 %,
    made the second blade family's window 824-1313 Hz; one at 478 Hz, ζ 2.6 %, a 353-676 Hz window that lost
    every mode). Such a pole still starts the fit of the window it falls in.

    Returns
    -------
    list of (window, core), each (f_lo, f_hi) in Hz
        ``core``: the span of the window's modes widened by half the margin, where growth may add modes.
    """
    fn, zeta = modal_from_pole(np.asarray(poles, np.complex128).reshape(-1))
    f, half, _ = half_widths(pole_from_modal(fn, np.minimum(zeta, damping_outlier_bound(zeta))), frf, band)
    if f.size == 0:
        return []
    spans = sorted(zip(f - half, f + half, f, half, strict=True))
    merged: list[list[float]] = []
    for lo, hi, fr, h in spans:
        if merged and lo <= merged[-1][1]:
            m = merged[-1]
            m[1], m[3], m[4] = max(m[1], hi), fr, max(m[4], h)
        else:
            merged.append([lo, hi, fr, fr, h])
    out = []
    for lo, hi, first, last, h in merged:
        window = (max(band[0], lo), min(band[1], hi))
        core = (max(window[0], first - h / 2), min(window[1], last + h / 2))
        out.append((window, core))
    return out


def damping_outlier_bound(zeta: np.ndarray) -> float:
    """The largest damping ratio that is not an outlier among ``zeta``: median + 3 × 1.4826 MAD (Hampel's rule;
    the MAD scaled to a normal σ); infinite for fewer than three poles, where no spread can be measured."""
    zeta = np.asarray(zeta, float)
    if zeta.size < 3:
        return float("inf")
    med = float(np.median(zeta))
    return med + 3 * 1.4826 * float(np.median(np.abs(zeta - med)))
