"""Pole sets: what the estimators (LSCF, LSRF, local fitting) return, and the data they share."""

from __future__ import annotations

import contextlib
import functools
import numbers
import os
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from .errors import EMAError
from .frf import DOF, FRFSet, line_ranges

__all__ = [
    "PoleSet",
    "BandData",
    "band_data",
    "in_band",
    "resolve_orders",
    "check_workspace",
    "merge_polesets",
    "single_thread_blas",
]


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
        (outputs x inputs, output-major), up to a complex scale (estimators scale it to a largest
        magnitude of 1, whatever the unit of the data).
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
        """Flatten ``[(order, poles (n_r,), vectors (n_r, n_vec)), ...]`` of an estimator's order loop.

        Each vector is divided by its largest magnitude: vectors are defined up to a scale, and unit-size
        ones keep the MAC tests (sums of squares) clear of under- and overflow whatever the data's unit.
        """
        return cls(
            method=method,
            band_hz=band_hz,
            orders=orders,
            order=np.concatenate([np.full(lam.size, n) for n, lam, _ in found]) if found else np.zeros(0, int),
            pole=np.concatenate([lam for _, lam, _ in found]) if found else np.zeros(0, complex),
            vector=_unit_rows(np.vstack([v for _, _, v in found])) if found else np.zeros((0, n_vec), complex),
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
    def frequencies_hz(self) -> np.ndarray:
        """Undamped natural frequency of each pole in Hz, shape (n_poles,)."""
        return np.abs(self.pole) / (2.0 * np.pi)

    @property
    def damping_ratio(self) -> np.ndarray:
        """Damping ratio of each pole, shape (n_poles,)."""
        wn = np.abs(self.pole)
        return -self.pole.real / np.where(wn > 0, wn, 1.0)


def _unit_rows(V: np.ndarray) -> np.ndarray:
    """Rows of V divided by their largest magnitude (zero rows stay zero)."""
    peak = np.max(np.abs(V), axis=1, keepdims=True) if V.shape[1] else np.ones((V.shape[0], 1))
    return V / np.where(peak > 0, peak, 1.0)


@dataclass(frozen=True)
class BandData:
    """FRF data of one band prepared for an estimator.

    Attributes
    ----------
    freq_hz : ndarray, shape (n_freq,)
        Lines of the band (a non-finite 0 Hz line left out).
    H : ndarray of complex128, shape (n_outputs, n_inputs, n_freq)
        FRFs multiplied by ``scale``.
    scale : ndarray, shape (n_outputs,) or (n_outputs, n_inputs)
        Factor each output (or FRF) was multiplied by.
    band_hz : tuple of float
    """

    freq_hz: np.ndarray
    H: np.ndarray
    scale: np.ndarray
    band_hz: tuple[float, float]


def _where(frf: FRFSet) -> str:
    return ", ".join(frf.sources) or "FRF set"


def _rms(H: np.ndarray, axis: tuple[int, ...]) -> np.ndarray:
    """Root mean square of ``|H|`` over ``axis``, without squaring tiny or huge values (no under/overflow)."""
    peak = np.max(np.abs(H), axis=axis, keepdims=True)
    safe = np.where(peak > 0, peak, 1.0)
    rms = safe * np.sqrt(np.mean((np.abs(H) / safe) ** 2, axis=axis, keepdims=True))  # abs first: real division
    return np.squeeze(np.where(peak > 0, rms, 0.0), axis=axis)


def _inverse(rms: np.ndarray, frf: FRFSet, exact_unit: bool) -> np.ndarray:
    """Scale factors that bring ``rms`` to 1 (``exact_unit``) or, as a power of two, into [0.5, 1) (exact)."""
    tiny = np.finfo(np.float64).tiny
    if np.any(rms < tiny):
        raise EMAError(
            f"{_where(frf)}: FRF values of RMS {float(np.min(rms)):.3g} are below the normal float64 range "
            f"({tiny:.3g}): they have lost precision; rescale the data (change its unit)"
        )
    if exact_unit:
        return 1.0 / rms
    _, e = np.frexp(rms)
    return np.ldexp(1.0, -e)


def band_data(frf: FRFSet, band: tuple[float, float] | None, per: str = "output") -> BandData:
    """Cut an FRF set to a band, check its values and normalise the FRFs to unit RMS.

    Parameters
    ----------
    frf : FRFSet
    band : (f_lo, f_hi) in Hz or None
        None means the whole axis.
    per : {"output", "frf", "scalar", "none"}
        Normalise each output row to unit RMS (needed to keep a poly-reference model exact), each FRF to
        unit RMS, all FRFs by one power of two that brings their joint RMS into [0.5, 1) (the data's own
        weights kept, the scaling exact), or nothing. Any of the first three makes the estimators
        independent of the unit of the data: normal equations of FRFs of 1e-156 or 1e+144 would under- or
        overflow. The RMS itself is computed without squaring the raw values.

    Raises
    ------
    EMAError
        Fewer than 4 lines in the band; a NaN or infinite value in the band (except on a 0 Hz line, which is
        left out: there a free structure's receptance is infinite and a form conversion divides by zero); an
        FRF that is zero or constant on every line of the band. Messages name the files and the FRF.
    """
    freq = frf.freq_hz
    # a non-finite 0 Hz line carries no modal information and is legitimate (see FRFSet): leave it out
    usable = ~((freq == 0) & ~np.all(np.isfinite(frf.H), axis=(0, 1)))
    if band is None:
        f = freq[usable]
        band = (float(f[0]), float(f[-1])) if f.size else (0.0, 0.0)
    f_lo, f_hi = float(band[0]), float(band[1])
    if not (np.isfinite(f_lo) and np.isfinite(f_hi) and f_hi > f_lo >= 0):
        raise EMAError(f"band [{f_lo}, {f_hi}] Hz: expected 0 <= f_lo < f_hi")
    mask = usable & (freq >= f_lo) & (freq <= f_hi)
    n = int(mask.sum())
    if n < 4:
        raise EMAError(
            f"{_where(frf)}: band [{f_lo:g}, {f_hi:g}] Hz holds {n} usable lines of the axis [{freq[0]:g}, "
            f"{freq[-1]:g}] Hz; expected at least 4"
        )
    f = freq[mask]
    H = frf.H[:, :, mask]
    bad = ~np.isfinite(H)
    if bad.any():
        o, i = (int(k) for k in np.argwhere(bad.any(axis=2))[0])
        n_bad = int(bad.any(axis=2).sum())
        others = f" (and {n_bad - 1} more FRFs)" if n_bad > 1 else ""
        raise EMAError(
            f"{_where(frf)}: FRF {frf.outputs[o]} / {frf.inputs[i]} has non-finite values (NaN or inf) on "
            f"{line_ranges(f, bad[o, i])}{others}; refusing to fit without those lines"
        )
    peak = np.max(np.abs(H), axis=2)
    spread = np.max(np.abs(H - H[:, :, :1]), axis=2)
    # constant to a few rounding units of the values: a scale-free test, no tolerance tied to the data
    dead = spread <= 4 * np.finfo(np.float64).eps * peak
    if dead.any():
        o, i = (int(k) for k in np.argwhere(dead)[0])
        what = "zero" if peak[o, i] == 0 else f"constant ({complex(H[o, i, 0]):.6g})"
        raise EMAError(
            f"{_where(frf)}: FRF {frf.outputs[o]} / {frf.inputs[i]} is {what} on every line of "
            f"[{f[0]:g}, {f[-1]:g}] Hz: it carries no signal"
        )
    if per == "output":
        scale = _inverse(_rms(H, (1, 2)), frf, True)
        Hs = H * scale[:, None, None]
    elif per == "frf":
        scale = _inverse(_rms(H, (2,)), frf, True)
        Hs = H * scale[:, :, None]
    elif per == "scalar":
        scale = np.full(H.shape[0], _inverse(_rms(H, (0, 1, 2)), frf, False))
        Hs = H * scale[0]
    elif per == "none":
        scale = np.ones(H.shape[0])
        Hs = H.copy()
    else:
        raise ValueError(f"normalisation {per!r} not one of 'output', 'frf', 'scalar', 'none'")
    return BandData(freq_hz=f, H=Hs, scale=scale, band_hz=(f_lo, f_hi))


def in_band(freq_hz, band: tuple[float, float]) -> np.ndarray:
    """Which frequencies (Hz, array-like) lie in ``band`` (edges included): bool, their shape."""
    return (np.asarray(freq_hz) >= band[0]) & (np.asarray(freq_hz) <= band[1])


def resolve_orders(
    max_order: int | None,
    orders: Iterable[int] | None,
    minimum: int = 1,
    maximum: int | None = None,
    why: str = "",
) -> tuple[int, ...]:
    """Validate model orders: ``orders`` if given, else ``minimum .. max_order``; ascending, unique.

    Parameters
    ----------
    max_order : int or None
    orders : iterable of int or None
    minimum : int
    maximum : int, optional
        Highest order the data support (see the estimators); checked before the orders are listed, so an
        absurd order fails at once instead of exhausting memory.
    why : str
        What limits ``maximum``, put first in the message (e.g. ``"a.uff: LSCF on 400 lines x 3 outputs x 1
        inputs in [10, 500] Hz"``).

    Raises
    ------
    EMAError
        Orders that are not integers >= ``minimum``, or above ``maximum``.
    """
    if orders is None:
        if isinstance(max_order, bool) or not isinstance(max_order, numbers.Integral) or max_order < minimum:
            raise EMAError(f"max_order {max_order!r}: expected an integer >= {minimum}")
        top = int(max_order)
        if maximum is not None and top > maximum:
            raise EMAError(_too_high(top, maximum, why))
        return tuple(range(minimum, top + 1))
    if isinstance(orders, range):  # checked from its ends: range(1, 10**12) must not be listed
        if len(orders) == 0 or min(orders[0], orders[-1]) < minimum:
            raise EMAError(f"orders {orders!r}: expected a non-empty set of integers >= {minimum}")
        if maximum is not None and max(orders[0], orders[-1]) > maximum:
            raise EMAError(_too_high(max(orders[0], orders[-1]), maximum, why))
    given = list(orders)
    if any(isinstance(o, bool) or not isinstance(o, numbers.Integral) for o in given):
        raise EMAError(f"orders {given!r}: expected integers")
    out = sorted({int(o) for o in given})
    if not out or out[0] < minimum:
        raise EMAError(f"orders {given!r}: expected a non-empty set of integers >= {minimum}")
    if maximum is not None and out[-1] > maximum:
        raise EMAError(_too_high(out[-1], maximum, why))
    return tuple(out)


def _too_high(order: int, maximum: int, why: str) -> str:
    where = f"{why}: " if why else ""
    return (f"{where}model order {order} is above the maximum {maximum} the data support (more unknowns than"
            " equations beyond it)")


def check_workspace(n_bytes: float, what: str) -> None:
    """Refuse a computation whose arrays would not fit in this machine's physical memory, before allocating.

    Parameters
    ----------
    n_bytes : float
        Estimated size of the largest arrays held at once.
    what : str
        The computation, for the message (names the order).
    """
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # not POSIX: let the allocation decide
        return
    if total > 0 and n_bytes > total:
        raise EMAError(
            f"{what} needs about {n_bytes / 2**30:.3g} GiB of memory, more than this machine has "
            f"({total / 2**30:.3g} GiB); lower the model order or fit a narrower band"
        )


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


@functools.cache
def _blas_controller():
    """One threadpoolctl controller for the process.

    Building one scans every loaded library: 7 ms a time in a ``bladetwin run`` of a 4-blade campaign, whose
    EMA enters :func:`single_thread_blas` 240 times (1.6 s of its 12 s). scipy's LAPACK is loaded first, so
    that the scan finds it as well as numpy's.
    """
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - threadpoolctl ships with scikit-learn
        return None
    import scipy.linalg  # noqa: F401

    return ThreadpoolController()


def single_thread_blas() -> contextlib.AbstractContextManager:
    """Context limiting BLAS/LAPACK to one thread (via threadpoolctl when installed).

    The order loops of the estimators call LAPACK on many small matrices (a few hundred rows), where
    multi-threaded OpenBLAS is slower than one thread, and dramatically so on a loaded machine
    (measured here: eig of 60 companion matrices of order <= 180 took 14.7 s threaded, 0.47 s single).
    ``rom.modal.single_thread_blas`` is its floor-1 twin (docs/design.md §8.10).
    """
    ctl = _blas_controller()
    if ctl is None:  # pragma: no cover
        return contextlib.nullcontext()
    return ctl.limit(limits=1, user_api="blas")
