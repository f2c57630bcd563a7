"""Pole sets: what the estimators (LSCF, LSRF, local fitting) return, and the data they share."""

from __future__ import annotations

import contextlib
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from .frf import DOF, FRFSet

__all__ = ["PoleSet", "BandData", "band_data", "resolve_orders", "merge_polesets", "single_thread_blas"]


@dataclass(frozen=True)
class PoleSet:
    """Poles estimated for a series of model orders, flattened.

    Attributes
    ----------
    method : str
        Estimator name, e.g. ``"lscf"``, ``"lsrf"``, ``"lsrf/local"``.
    band_hz : tuple of float
        Fitted band ``(f_lo, f_hi)`` in Hz.
    orders : tuple of int
        Model orders computed, ascending (an order may contribute no pole).
    order : ndarray of int, shape (n_poles,)
        Model order of each pole.
    pole : ndarray of complex128, shape (n_poles,)
        Continuous-time poles in rad/s with positive imaginary part.
    vector : ndarray of complex128, shape (n_poles, n_vec)
        Mode-shape estimate of each pole, used for the MAC stability test: the vectorised residue matrix
        (outputs x inputs, output-major), up to a complex scale.
    outputs, inputs : tuple of (int, int)
        DOF labels the vectors refer to.
    """

    method: str
    band_hz: tuple[float, float]
    orders: tuple[int, ...]
    order: np.ndarray
    pole: np.ndarray
    vector: np.ndarray
    outputs: tuple[DOF, ...] = field(default=())
    inputs: tuple[DOF, ...] = field(default=())

    @classmethod
    def from_orders(
        cls,
        method: str,
        band_hz: tuple[float, float],
        orders: tuple[int, ...],
        found: list[tuple[int, np.ndarray, np.ndarray]],
        n_vec: int,
        outputs: tuple[DOF, ...],
        inputs: tuple[DOF, ...],
    ) -> PoleSet:
        """Flatten ``[(order, poles (n_r,), vectors (n_r, n_vec)), ...]`` of an estimator's order loop."""
        return cls(
            method=method,
            band_hz=band_hz,
            orders=orders,
            order=np.concatenate([np.full(lam.size, n) for n, lam, _ in found]) if found else np.zeros(0, int),
            pole=np.concatenate([lam for _, lam, _ in found]) if found else np.zeros(0, complex),
            vector=np.vstack([v for _, _, v in found]) if found else np.zeros((0, n_vec), complex),
            outputs=outputs,
            inputs=inputs,
        )

    def __post_init__(self) -> None:
        order = np.asarray(self.order, dtype=np.int64).reshape(-1)
        pole = np.asarray(self.pole, dtype=np.complex128).reshape(-1)
        vec = np.asarray(self.vector, dtype=np.complex128)
        if vec.ndim != 2 or vec.shape[0] != pole.size or order.size != pole.size:
            raise ValueError(
                f"PoleSet: {order.size} orders, {pole.size} poles and vectors of shape {vec.shape} disagree"
            )
        for arr in (order, pole, vec):
            arr.setflags(write=False)
        object.__setattr__(self, "order", order)
        object.__setattr__(self, "pole", pole)
        object.__setattr__(self, "vector", vec)
        object.__setattr__(self, "orders", tuple(int(o) for o in self.orders))
        object.__setattr__(self, "band_hz", (float(self.band_hz[0]), float(self.band_hz[1])))

    @property
    def frequency_hz(self) -> np.ndarray:
        """Undamped natural frequency of each pole in Hz, shape (n_poles,)."""
        return np.abs(self.pole) / (2.0 * np.pi)

    @property
    def damping_ratio(self) -> np.ndarray:
        """Damping ratio of each pole, shape (n_poles,)."""
        wn = np.abs(self.pole)
        return -self.pole.real / np.where(wn > 0, wn, 1.0)


@dataclass(frozen=True)
class BandData:
    """FRF data of one band prepared for an estimator.

    Attributes
    ----------
    freq_hz : ndarray, shape (n_freq,)
        Lines in the band where every FRF is finite.
    H : ndarray of complex128, shape (n_outputs, n_inputs, n_freq)
        FRFs, scaled by ``scale`` when normalised.
    scale : ndarray, shape (n_outputs,) or (n_outputs, n_inputs)
        Factor each output (or FRF) was multiplied by.
    band_hz : tuple of float
    """

    freq_hz: np.ndarray
    H: np.ndarray
    scale: np.ndarray
    band_hz: tuple[float, float]


def band_data(frf: FRFSet, band: tuple[float, float] | None, per: str = "output") -> BandData:
    """Cut an FRF set to a band, drop non-finite lines and normalise the FRFs to unit RMS.

    Parameters
    ----------
    frf : FRFSet
    band : (f_lo, f_hi) in Hz or None
        None means every finite line of the set.
    per : {"output", "frf", "none"}
        Normalise each output row (needed to keep a poly-reference model exact), each FRF, or nothing.
    """
    valid = frf.valid_lines()
    if band is None:
        f = frf.freq_hz[valid]
        if f.size < 2:
            raise ValueError(f"FRF set has {f.size} finite lines; expected at least 2")
        band = (float(f[0]), float(f[-1]))
    f_lo, f_hi = float(band[0]), float(band[1])
    if not (np.isfinite(f_lo) and np.isfinite(f_hi) and f_hi > f_lo >= 0):
        raise ValueError(f"band [{f_lo}, {f_hi}] Hz: expected 0 <= f_lo < f_hi")
    mask = valid & (frf.freq_hz >= f_lo) & (frf.freq_hz <= f_hi)
    n = int(mask.sum())
    if n < 4:
        raise ValueError(
            f"band [{f_lo}, {f_hi}] Hz holds {n} finite lines of the axis [{frf.freq_hz[0]}, "
            f"{frf.freq_hz[-1]}] Hz; expected at least 4"
        )
    H = frf.H[:, :, mask]
    if per == "output":
        rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=(1, 2)))
        scale = 1.0 / np.where(rms > 0, rms, 1.0)
        Hs = H * scale[:, None, None]
    elif per == "frf":
        rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=2))
        scale = 1.0 / np.where(rms > 0, rms, 1.0)
        Hs = H * scale[:, :, None]
    elif per == "none":
        scale = np.ones(H.shape[0])
        Hs = H.copy()
    else:
        raise ValueError(f"normalisation {per!r} not one of 'output', 'frf', 'none'")
    return BandData(freq_hz=frf.freq_hz[mask], H=Hs, scale=scale, band_hz=(f_lo, f_hi))


def resolve_orders(max_order: int | None, orders: Iterable[int] | None, minimum: int = 1) -> tuple[int, ...]:
    """Validate model orders: ``orders`` if given, else ``minimum .. max_order``; ascending, unique."""
    if orders is None:
        if max_order is None or int(max_order) < minimum:
            raise ValueError(f"max_order {max_order!r}: expected an integer >= {minimum}")
        return tuple(range(minimum, int(max_order) + 1))
    out = sorted({int(o) for o in orders})
    if not out or out[0] < minimum:
        raise ValueError(f"orders {list(orders)!r}: expected a non-empty set of integers >= {minimum}")
    return tuple(out)


def merge_polesets(sets: list[PoleSet], method: str, band_hz: tuple[float, float]) -> PoleSet:
    """Concatenate pole sets of one FRF set (e.g. from several bands) order by order."""
    if not sets:
        raise ValueError("merge_polesets: nothing to merge")
    n_vec = {s.vector.shape[1] for s in sets}
    if len(n_vec) != 1:
        raise ValueError(f"merge_polesets: vectors of different lengths {sorted(n_vec)}")
    orders = sorted({o for s in sets for o in s.orders})
    order = np.concatenate([s.order for s in sets])
    pole = np.concatenate([s.pole for s in sets])
    vector = np.vstack([s.vector for s in sets])
    idx = np.lexsort((np.abs(pole), order))
    return PoleSet(
        method=method, band_hz=band_hz, orders=tuple(orders), order=order[idx], pole=pole[idx],
        vector=vector[idx], outputs=sets[0].outputs, inputs=sets[0].inputs,
    )


def single_thread_blas() -> contextlib.AbstractContextManager:
    """Context limiting BLAS/LAPACK to one thread (via threadpoolctl when installed).

    The order loops of the estimators call LAPACK on many small matrices (a few hundred rows), where
    multi-threaded OpenBLAS is slower than one thread, and dramatically so on a loaded machine
    (measured here: eig of 60 companion matrices of order <= 180 took 14.7 s threaded, 0.47 s single).
    ``rom.modal.single_thread_blas`` is its floor-1 twin (docs/design.md §8.10).
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl ships with scikit-learn
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")
