"""A family-wise comparison of a ROM's modes with measured ones (frequency, MAC, subspace correlation).

In a mistuned bladed disk a blade-dominated family holds about one mode per blade within about 1 %, some
0.06 % apart. A blade-level error of a few hundredths of a percent then reshuffles which blades each mode
mixes, and single-mode MAC drops although the family's *subspace* is right. The principal angles between the
measured family's n shapes and the n ROM shapes nearest to them in frequency (one-to-one) say whether it is
(Björck & Golub 1973; :func:`scipy.linalg.subspace_angles`). Equal dimensions matter: the ROM's whole family
(one mode per blade) spans nearly any combination of blade motions, so a wider ROM subspace would always
correlate.

A family here is a run of measured modes whose consecutive gaps are below :data:`FAMILY_GAP` (relative): well
above a family's spacing, below the gap between a blade family and the next.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import subspace_angles
from scipy.optimize import linear_sum_assignment

from .validation import ModeComparison

__all__ = ["FAMILY_GAP", "FamilyRow", "mode_families", "family_view"]

#: Largest relative gap between consecutive modes of one family (2 %: twice a blade family's width).
FAMILY_GAP = 0.02


@dataclass(frozen=True)
class FamilyRow:
    """One family's figures: its band (Hz), its measured modes, and how the ROM matches them.

    ``subspace_cos_min`` is the cosine of the largest principal angle between the measured family's shapes and
    as many ROM shapes, nearest in frequency (1: they span the same space); ``subspace_mean_cos2`` the mean
    squared cosine over the angles (a MAC of subspaces).
    """

    f_low_hz: float
    f_high_hz: float
    n_measured: int
    n_paired: int
    mean_abs_df_pct: float
    mean_mac: float
    subspace_cos_min: float
    subspace_mean_cos2: float


def mode_families(frequencies_hz: np.ndarray, gap: float = FAMILY_GAP) -> list[np.ndarray]:
    """Indices of each family: runs of ascending frequencies with relative gaps ≤ ``gap``."""
    f = np.asarray(frequencies_hz, np.float64)
    order = np.argsort(f)
    if not order.size:
        return []
    cuts = np.flatnonzero(np.diff(f[order]) / f[order][:-1] > gap) + 1
    return [np.asarray(g) for g in np.split(order, cuts)]


def family_view(comparison: ModeComparison, measured_hz: np.ndarray, measured_shapes: np.ndarray,
                rom_hz: np.ndarray, rom_shapes: np.ndarray, gap: float = FAMILY_GAP) -> list[FamilyRow]:
    """Each measured family's frequency error, MAC and subspace correlation with a ROM.

    Parameters
    ----------
    comparison : ModeComparison
        The mode pairing (measured = reference), e.g. from :func:`identify.validation.compare_modes`.
    measured_hz, rom_hz : ndarray, shape (n_meas,), (n_rom,)
    measured_shapes, rom_shapes : ndarray, shape (n_dof, n_meas), (n_dof, n_rom)
        On the same DOFs.
    """
    rows = []
    ref_idx = comparison.pairs[:, 0] if comparison.pairs.size else np.zeros(0, int)
    for fam in mode_families(measured_hz, gap):
        lo, hi = float(np.min(measured_hz[fam])), float(np.max(measured_hz[fam]))
        hit = np.isin(ref_idx, fam)
        cos_min = cos2 = float("nan")
        if rom_hz.size:
            # as many ROM modes as the family has, nearest in frequency, one-to-one
            _, near = linear_sum_assignment(np.abs(np.log(rom_hz[None, :] / measured_hz[fam][:, None])))
            ang = subspace_angles(measured_shapes[:, fam], rom_shapes[:, near])
            cos_min, cos2 = float(np.cos(ang.max())), float(np.mean(np.cos(ang) ** 2))
        rows.append(FamilyRow(lo, hi, int(fam.size), int(hit.sum()),
                              float(np.mean(np.abs(comparison.freq_error_pct[hit]))) if hit.any() else float("nan"),
                              float(np.mean(comparison.mac[hit])) if hit.any() else float("nan"), cos_min, cos2))
    return rows
