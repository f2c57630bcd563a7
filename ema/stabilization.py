"""Stabilization diagrams: poles per model order with a stability class each."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .errors import EMAError
from .mac import ScaledRows
from .poles import DOF, PoleSet, in_band

__all__ = [
    "StabilityCriteria",
    "StabilizationDiagram",
    "stabilize",
    "UNSTABLE",
    "STABLE_F",
    "STABLE_FD",
    "STABLE_FDV",
    "CLASS_NAMES",
]

#: Stability classes, ordered: each one implies the previous.
UNSTABLE, STABLE_F, STABLE_FD, STABLE_FDV = 0, 1, 2, 3
CLASS_NAMES = {UNSTABLE: "new", STABLE_F: "f", STABLE_FD: "f+d", STABLE_FDV: "f+d+v"}
#: The fields of :class:`StabilizationDiagram` with one entry per pole.
_POLE_FIELDS = ("order", "pole", "frequencies_hz", "damping_ratio", "vector", "stability", "mac_prev")


@dataclass(frozen=True)
class StabilityCriteria:
    """Tolerances that make a pole stable with respect to the previous model order.

    Attributes
    ----------
    freq_tol : float
        Relative frequency change, default 0.01 (1 %).
    damping_tol : float
        Relative damping change, default 0.05 (5 %).
    mac_min : float
        Minimum MAC between the pole vectors, default 0.95.
    damping_range : tuple of float
        Physical damping ratios; poles outside are dropped from the diagram. Default (0, 0.2).
    """

    freq_tol: float = 0.01
    damping_tol: float = 0.05
    mac_min: float = 0.95
    damping_range: tuple[float, float] = (0.0, 0.2)

    def __post_init__(self) -> None:
        if not self.freq_tol > 0:
            raise EMAError(f"freq_tol {self.freq_tol}: expected > 0")
        if not self.damping_tol > 0:
            raise EMAError(f"damping_tol {self.damping_tol}: expected > 0")
        if not 0 <= self.mac_min <= 1:
            raise EMAError(f"mac_min {self.mac_min}: expected in [0, 1]")
        lo, hi = self.damping_range
        if not hi > lo:
            raise EMAError(f"damping_range {self.damping_range}: expected (low, high) with high > low")


@dataclass(frozen=True)
class StabilizationDiagram:
    """Physical poles of a series of model orders with their stability class.

    Attributes
    ----------
    method : str
    band_hz : tuple of float
    orders : tuple of int
        All model orders computed.
    order : ndarray of int, shape (n_poles,)
    pole : ndarray of complex128, shape (n_poles,)
        Continuous-time poles in rad/s.
    frequencies_hz, damping_ratio : ndarray, shape (n_poles,)
    vector : ndarray of complex128, shape (n_poles, n_vec)
    stability : ndarray of int, shape (n_poles,)
        :data:`UNSTABLE` (new), :data:`STABLE_F`, :data:`STABLE_FD` or :data:`STABLE_FDV`.
    mac_prev : ndarray, shape (n_poles,)
        MAC with the matched pole of the previous order (NaN when none).
    criteria : StabilityCriteria
    outputs, inputs : tuple of (int, int)
    """

    method: str
    band_hz: tuple[float, float]
    orders: tuple[int, ...]
    order: np.ndarray
    pole: np.ndarray
    frequencies_hz: np.ndarray
    damping_ratio: np.ndarray
    vector: np.ndarray
    stability: np.ndarray
    mac_prev: np.ndarray
    criteria: StabilityCriteria
    outputs: tuple[DOF, ...] = ()
    inputs: tuple[DOF, ...] = ()

    def __post_init__(self) -> None:
        for name in _POLE_FIELDS:
            arr = np.array(getattr(self, name))
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n_poles(self) -> int:
        return int(self.pole.size)

    def count(self, cls: int) -> int:
        """Number of poles of stability class ``cls`` or better."""
        return int(np.sum(self.stability >= cls))

    def take(self, keep: np.ndarray, **changes) -> StabilizationDiagram:
        """The diagram of the poles ``keep`` (bool or indices) selects, with the other fields in ``changes``."""
        return replace(self, **changes, **{name: getattr(self, name)[keep] for name in _POLE_FIELDS})

    def within(self, band: tuple[float, float]) -> StabilizationDiagram:
        """The diagram's poles inside ``band`` (Hz), with that band."""
        return self.take(in_band(self.frequencies_hz, band), band_hz=band)


def _match_previous(
    f: np.ndarray, lam: np.ndarray, vec: ScaledRows, sel: np.ndarray, prev: np.ndarray, freq_tol: float
) -> tuple[np.ndarray, np.ndarray]:
    """The pole of the previous order that each pole of ``sel`` is compared with, and their MAC.

    Among the previous poles within ``freq_tol``, the match minimises ``|dlambda|/|lambda| + (1 - MAC)``,
    the distance the selection clusters with: the nearest pole in frequency alone is often the other
    member of a close pair, whose vector differs, and that comparison would call a well-estimated mode
    unstable. Without a previous pole within ``freq_tol``, the nearest in frequency is reported.

    Parameters
    ----------
    f : ndarray, shape (n_poles,)
        Frequencies of all poles; ``f[prev]`` ascending.
    lam : ndarray of complex, shape (n_poles,)
    vec : ScaledRows
        Pole vectors of all poles, scaled once (n_poles rows).
    sel, prev : ndarray of int
        Poles of the current and of the previous order.
    freq_tol : float

    Returns
    -------
    match : ndarray of int, shape (sel.size,)
        Index (into all poles) of the compared previous pole.
    mac : ndarray, shape (sel.size,)
    """
    fp = f[prev]
    j = np.searchsorted(fp, f[sel])
    j0 = np.clip(j - 1, 0, fp.size - 1)
    j1 = np.clip(j, 0, fp.size - 1)
    match = prev[np.where(np.abs(fp[j0] - f[sel]) <= np.abs(fp[j1] - f[sel]), j0, j1)]
    # all (current, previous) pairs within the tolerance; fp is sorted, so each current pole has a run
    lo = np.searchsorted(fp, f[sel] * (1.0 - freq_tol), side="left")
    hi = np.searchsorted(fp, f[sel] * (1.0 + freq_tol), side="right")
    counts = np.maximum(hi - lo, 0)
    if counts.sum():
        ii = np.repeat(np.arange(sel.size), counts)
        jj = prev[np.repeat(lo, counts) + np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)]
        mac = vec.mac(sel[ii], vec, jj)
        dist = np.abs(lam[sel[ii]] - lam[jj]) / np.abs(lam[sel[ii]]) + (1.0 - mac)
        # the smallest distance per current pole: sort by (pole, distance), keep the first of each run
        first = np.lexsort((dist, ii))
        keep = first[np.r_[True, ii[first][1:] != ii[first][:-1]]]
        match[ii[keep]] = jj[keep]
    return match, vec.mac(sel, vec, match)


def stabilize(poles: PoleSet, criteria: StabilityCriteria | None = None) -> StabilizationDiagram:
    """Classify the poles of each order against the poles of the previous computed order.

    Poles outside the physical damping range are dropped. Each remaining pole is compared with one pole
    of the previous order: among those within ``freq_tol`` in frequency, the one nearest in
    ``|dlambda|/|lambda| + (1 - MAC)`` (frequency and vector, so that the two members of a close pair are
    each compared with themselves), else the nearest in frequency. The pole is stable in frequency when
    their relative frequency difference is within ``freq_tol``, additionally in damping when the relative
    damping difference is within ``damping_tol``, and additionally in vector when their MAC is at least
    ``mac_min``.

    Parameters
    ----------
    poles : PoleSet
    criteria : StabilityCriteria, optional

    Returns
    -------
    StabilizationDiagram
    """
    crit = criteria or StabilityCriteria()
    f, z = poles.frequencies_hz, poles.damping_ratio
    lo, hi = crit.damping_range
    keep = (z >= lo) & (z <= hi) & (f > 0)
    order, pole, vec = poles.order[keep], poles.pole[keep], poles.vector[keep]
    f, z = f[keep], z[keep]
    idx = np.lexsort((f, order))
    order, pole, vec, f, z = order[idx], pole[idx], vec[idx], f[idx], z[idx]
    stab = np.zeros(order.size, dtype=np.int64)
    mac_prev = np.full(order.size, np.nan)
    prev = None
    scaled = ScaledRows.of(vec)
    for p in poles.orders:
        sel = np.flatnonzero(order == p)
        if prev is not None and prev.size and sel.size:
            m, mac = _match_previous(f, pole, scaled, sel, prev, crit.freq_tol)
            df = np.abs(f[sel] - f[m]) / f[sel]
            dz = np.abs(z[sel] - z[m]) / np.maximum(z[sel], 1e-12)
            mac_prev[sel] = mac
            ok_f = df <= crit.freq_tol
            ok_d = ok_f & (dz <= crit.damping_tol)
            ok_v = ok_d & (mac >= crit.mac_min)
            stab[sel] = np.where(ok_v, STABLE_FDV, np.where(ok_d, STABLE_FD, np.where(ok_f, STABLE_F, UNSTABLE)))
        if sel.size:
            prev = sel
        else:
            prev = None
    return StabilizationDiagram(
        method=poles.method,
        band_hz=poles.band_hz,
        orders=poles.orders,
        order=order,
        pole=pole,
        frequencies_hz=f,
        damping_ratio=z,
        vector=vec,
        stability=stab,
        mac_prev=mac_prev,
        criteria=crit,
        outputs=poles.outputs,
        inputs=poles.inputs,
    )
