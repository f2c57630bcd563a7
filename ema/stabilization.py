"""Stabilization diagrams: poles per model order with a stability class each."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .poles import DOF, PoleSet

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
            raise ValueError(f"freq_tol {self.freq_tol}: expected > 0")
        if not self.damping_tol > 0:
            raise ValueError(f"damping_tol {self.damping_tol}: expected > 0")
        if not 0 <= self.mac_min <= 1:
            raise ValueError(f"mac_min {self.mac_min}: expected in [0, 1]")
        lo, hi = self.damping_range
        if not hi > lo:
            raise ValueError(f"damping_range {self.damping_range}: expected (low, high) with high > low")


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
    frequency_hz, damping_ratio : ndarray, shape (n_poles,)
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
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    vector: np.ndarray
    stability: np.ndarray
    mac_prev: np.ndarray
    criteria: StabilityCriteria
    outputs: tuple[DOF, ...] = ()
    inputs: tuple[DOF, ...] = ()

    def __post_init__(self) -> None:
        for name in ("order", "pole", "frequency_hz", "damping_ratio", "vector", "stability", "mac_prev"):
            arr = np.array(getattr(self, name))
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n_poles(self) -> int:
        return int(self.pole.size)

    def count(self, cls: int) -> int:
        """Number of poles of stability class ``cls`` or better."""
        return int(np.sum(self.stability >= cls))


def _mac_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """MAC between row vectors ``a[k]`` and ``b[k]``, shape (n,)."""
    num = np.abs(np.sum(a.conj() * b, axis=1)) ** 2
    den = np.sum(np.abs(a) ** 2, axis=1) * np.sum(np.abs(b) ** 2, axis=1)
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)


def stabilize(poles: PoleSet, criteria: StabilityCriteria | None = None) -> StabilizationDiagram:
    """Classify the poles of each order against the poles of the previous computed order.

    Poles outside the physical damping range are dropped. For each remaining pole the nearest pole in
    frequency of the previous order is its match; the pole is stable in frequency when their relative
    frequency difference is within ``freq_tol``, additionally in damping when the relative damping
    difference is within ``damping_tol``, and additionally in vector when their MAC is at least ``mac_min``.

    Parameters
    ----------
    poles : PoleSet
    criteria : StabilityCriteria, optional

    Returns
    -------
    StabilizationDiagram
    """
    crit = criteria or StabilityCriteria()
    f, z = poles.frequency_hz, poles.damping_ratio
    lo, hi = crit.damping_range
    keep = (z >= lo) & (z <= hi) & (f > 0)
    order, pole, vec = poles.order[keep], poles.pole[keep], poles.vector[keep]
    f, z = f[keep], z[keep]
    idx = np.lexsort((f, order))
    order, pole, vec, f, z = order[idx], pole[idx], vec[idx], f[idx], z[idx]
    stab = np.zeros(order.size, dtype=np.int64)
    mac_prev = np.full(order.size, np.nan)
    prev = None
    for p in poles.orders:
        sel = np.flatnonzero(order == p)
        if prev is not None and prev.size and sel.size:
            fp = f[prev]
            j = np.searchsorted(fp, f[sel])
            j0 = np.clip(j - 1, 0, fp.size - 1)
            j1 = np.clip(j, 0, fp.size - 1)
            pick = np.where(np.abs(fp[j0] - f[sel]) <= np.abs(fp[j1] - f[sel]), j0, j1)
            m = prev[pick]
            df = np.abs(f[sel] - f[m]) / f[sel]
            dz = np.abs(z[sel] - z[m]) / np.maximum(z[sel], 1e-12)
            mac = _mac_rows(vec[sel], vec[m])
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
        frequency_hz=f,
        damping_ratio=z,
        vector=vec,
        stability=stab,
        mac_prev=mac_prev,
        criteria=crit,
        outputs=poles.outputs,
        inputs=poles.inputs,
    )
