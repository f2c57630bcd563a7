"""The tuned disk's mode families: the band a sweep covers (package notes)."""

from __future__ import annotations

import numpy as np

from ..errors import ROMError
from ..solver import nodal_diameters
from .model import BladeModes

__all__ = ["family_band", "family_damping", "PAIR_RTOL"]

#: Relative frequency spread under which tuned modes count as one degenerate pair (a pair splits ≤ 1e-7).
PAIR_RTOL = 1e-5


def family_band(tuned: BladeModes, family: int, *, margin: float = 0.02, candidates=None,
                pair_rtol: float = PAIR_RTOL) -> tuple[float, float]:
    """The sweep band of the tuned disk's ``family`` (1-based): its extent over all nodal diameters, widened.

    At each nodal diameter h (:func:`rom.solver.nodal_diameters` of the shapes at the blades), the tuned
    modes of that h are grouped into resonances (degenerate pairs within ``pair_rtol`` count once); the
    family's member at h is the ``family``-th lowest. The band is [f_min (1 − margin), f_max (1 + margin)].

    Parameters
    ----------
    tuned : BladeModes
        The tuned disk's modes.
    family : int
        1 for the lowest family.
    margin : float
        Relative widening for the mistuned modes that leave the tuned family's extent (≥ 0).
    candidates : array_like of bool, shape (n_modes,), optional
        Modes that may form a family, e.g. ``blade_energy > 0.5``: where disk-dominated modes interleave
        with the blades' families, they would otherwise take a rank.
    pair_rtol : float

    Raises
    ------
    ROMError
        If no nodal diameter has that many resonances.
    """
    if not (isinstance(family, (int, np.integer)) and family >= 1):
        raise ROMError(f"family {family!r} must be an integer ≥ 1")
    if not margin >= 0:
        raise ROMError(f"margin {margin} must be ≥ 0")
    mask = np.ones(tuned.n_modes, bool) if candidates is None else np.asarray(candidates, bool).reshape(-1)
    if mask.shape != (tuned.n_modes,):
        raise ROMError(f"candidates has {mask.size} values for {tuned.n_modes} modes")
    nd = nodal_diameters(tuned.shapes)
    members = [m for h in range(tuned.n_blades // 2 + 1)
               if (m := _resonance(tuned.frequencies_hz[mask & (nd == h)], family, pair_rtol)) is not None]
    if not members:
        raise ROMError(f"family {family} has no modes: the tuned model holds fewer resonances at every nodal "
                       f"diameter ({tuned.n_modes} modes in {tuned.frequencies_hz.min():.6g}–"
                       f"{tuned.frequencies_hz.max():.6g} Hz)")
    f = np.concatenate(members)
    return float(f.min() * (1.0 - margin)), float(f.max() * (1.0 + margin))


def _resonance(f: np.ndarray, k: int, rtol: float) -> np.ndarray | None:
    """The frequencies of the k-th lowest group (within ``rtol``) of ``f``, or None."""
    f = np.sort(f)
    if not f.size:
        return None
    groups = np.split(f, np.flatnonzero(np.diff(f) > rtol * f[:-1]) + 1)
    return groups[k - 1] if k <= len(groups) else None


def family_damping(frequencies_hz, bands_hz, ratios) -> np.ndarray:
    """One damping ratio per mode from one per family: a mode takes its band's ratio, or its nearest band's.

    The AF compares the mistuned and the tuned disk "with the same damping": give both models the damping
    of the family each mode belongs to (e.g. the mean of the family's EMA damping), not mode by mode.

    Parameters
    ----------
    frequencies_hz : array_like, shape (n_modes,)
    bands_hz : sequence of (float, float)
        Each family's band (Hz), e.g. :func:`family_band`.
    ratios : array_like, shape (n_families,)
        Each family's damping ratio.

    Returns
    -------
    ndarray, shape (n_modes,)
        Modes outside every band take the ratio of the band nearest in relative frequency.
    """
    f = np.asarray(frequencies_hz, np.float64).reshape(-1)
    bands = np.asarray(bands_hz, np.float64).reshape(-1, 2)
    z = np.asarray(ratios, np.float64).reshape(-1)
    if z.size != bands.shape[0] or not bands.size:
        raise ROMError(f"{z.size} damping ratios for {bands.shape[0]} family bands: give one per family")
    if np.any(bands[:, 0] <= 0) or np.any(bands[:, 1] <= bands[:, 0]):
        raise ROMError(f"family bands {bands.tolist()} Hz must satisfy 0 < low < high")
    # Relative distance of each mode to each band: 0 inside it.
    dist = np.maximum(np.log(bands[None, :, 0] / f[:, None]), np.log(f[:, None] / bands[None, :, 1])).clip(0)
    return z[np.argmin(dist, axis=1)]
