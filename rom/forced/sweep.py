"""The sweep of one band: each blade's peak on a grid fine for the damping, refined (package notes)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ROMError
from .model import FORMS, BladeModes, blade_amplitudes, blade_power_slopes, engine_order_force, modal_forces, receptance

__all__ = ["ForcedResponse", "forced_response", "GOLDEN_ITERATIONS"]

#: Golden-section steps of a peak's refinement where Newton's method fails: 0.618^31 · 2 Δf ≈ 2e-7 Δf.
GOLDEN_ITERATIONS = 31
#: Newton steps of a peak's refinement at most, and the relative step that ends them.
NEWTON_ITERATIONS, NEWTON_TOL = 20, 1e-12
_GOLD = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True, eq=False)
class ForcedResponse:
    """Each blade's peak response over one sweep under one engine order.

    Attributes
    ----------
    eo : int
    amplitude_n : float
        Force amplitude F0 (N) on each blade.
    form : str
        ``"receptance"`` (peaks in m), ``"mobility"`` (m/s) or ``"accelerance"`` (m/s²).
    band_hz : tuple of float
        The sweep's band (Hz).
    peaks : ndarray, shape (n_blades,)
        Each blade's largest response amplitude over the band.
    peak_hz : ndarray, shape (n_blades,)
        Where it occurs (Hz).
    step_hz : float
        The sweep's grid step (Hz), before the refinement.
    sweep_hz : ndarray, shape (n_freq,) or None
        The grid (kept only when asked: ``keep_sweep=True``).
    sweep_amplitude : ndarray, shape (n_freq, n_blades) or None
        |response| of each blade on the grid.
    """

    eo: int
    amplitude_n: float
    form: str
    band_hz: tuple[float, float]
    peaks: np.ndarray
    peak_hz: np.ndarray
    step_hz: float
    sweep_hz: np.ndarray | None = None
    sweep_amplitude: np.ndarray | None = None

    @property
    def worst_blade(self) -> int:
        """The blade (1-based) with the largest peak."""
        return int(np.argmax(self.peaks)) + 1

    @property
    def max_peak(self) -> float:
        return float(self.peaks.max())


def _check_band(band_hz) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in band_hz)
    except (TypeError, ValueError):
        raise ROMError(f"band {band_hz!r} must be two frequencies (low, high) in Hz") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        raise ROMError(f"band ({lo}, {hi}) Hz must satisfy 0 < low < high")
    return lo, hi


def _sweep_grid(model: BladeModes, band: tuple[float, float], points_per_bandwidth: float,
                max_points: int) -> np.ndarray:
    """Uniform grid over ``band`` with ``points_per_bandwidth`` points in the narrowest in-band half-power width."""
    lo, hi = band
    inside = (model.frequencies_hz >= lo) & (model.frequencies_hz <= hi)
    if not inside.any():
        raise ROMError(f"no mode in the band {lo:.6g}–{hi:.6g} Hz (modes span {model.frequencies_hz.min():.6g}–"
                       f"{model.frequencies_hz.max():.6g} Hz)")
    if not points_per_bandwidth >= 2:
        raise ROMError(f"points_per_bandwidth {points_per_bandwidth} must be ≥ 2 to resolve a peak")
    bw = 2.0 * model.damping_ratio[inside] * model.frequencies_hz[inside]
    n = int(math.ceil((hi - lo) / (bw.min() / points_per_bandwidth))) + 1
    if n > max_points:
        raise ROMError(f"the sweep of {lo:.6g}–{hi:.6g} Hz needs {n} points (> max_points {max_points}) for damping "
                       f"{model.damping_ratio[inside].min():.3g}: narrow the band or raise max_points")
    return np.linspace(lo, hi, max(n, 3))


def _refine_peaks(model: BladeModes, q: np.ndarray, grid: np.ndarray, amp: np.ndarray, form: str):
    """Each blade's |X_j| maximised between the grid neighbours of its grid maximum: Newton's method on d|X_j|²/dω
    from the grid maximum; where it leaves that bracket, meets a convex stretch or ends below the grid's maximum
    (two modes closer than two grid steps), a golden-section search of the bracket.

    Why Newton first: the golden-section search took :data:`GOLDEN_ITERATIONS` evaluations per peak, 9.5 s of the
    13.4 s of the bundled campaign's amplification factors with their intervals (8060 sweeps); Newton converges
    in a few, each about three evaluations' work, from the grid maximum, which lies within a sixteenth of a
    bandwidth of the peak (design §8.75)."""
    i = np.argmax(amp, axis=0)
    best_f = grid[i].copy()
    best_a = amp[i, np.arange(amp.shape[1])].copy()
    a = grid[np.maximum(i - 1, 0)]
    b = grid[np.minimum(i + 1, grid.size - 1)]
    x, ok = _newton_peaks(blade_power_slopes(model, q, form), best_f.copy(), a, b)
    ev = blade_amplitudes(model, q, form)
    fx = ev(x)
    ok &= fx >= best_a
    best_f, best_a = np.where(ok, x, best_f), np.where(ok, fx, best_a)
    if not ok.all():  # the golden-section search for every blade (the evaluations take them all), kept where needed
        ga, gf = _golden(ev, a, b, best_f, best_a)
        best_f, best_a = np.where(ok, best_f, gf), np.where(ok, best_a, ga)
    return best_a, best_f


def _newton_peaks(slopes, x: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method on P' = d|Y|²/dω for every blade at once, from ``x`` (Hz); returns the points and which
    converged (steps below :data:`NEWTON_TOL` relative, inside [a, b], P'' < 0 all the way)."""
    ok = np.ones(x.size, bool)
    for _ in range(NEWTON_ITERATIONS):
        _, g, h = slopes(x)
        ok &= h < 0
        step = np.where(ok, -g / np.where(ok, h, -1.0), 0.0) / (2.0 * math.pi)
        x = x + step
        ok &= (x >= a) & (x <= b)
        if np.all(~ok | (np.abs(step) <= NEWTON_TOL * np.abs(x))):
            return x, ok
    return x, ok & (np.abs(step) <= NEWTON_TOL * np.abs(x))


def _golden(ev, a: np.ndarray, b: np.ndarray, best_f: np.ndarray, best_a: np.ndarray):
    """Golden-section maximisation of ``ev`` over [a, b] per blade; the better of its result and (best_f, best_a)."""
    c, d = b - _GOLD * (b - a), a + _GOLD * (b - a)
    fc, fd = ev(c), ev(d)
    for _ in range(GOLDEN_ITERATIONS):
        left = fc >= fd  # the maximum lies in [a, d]: d ← c
        a, b = np.where(left, a, c), np.where(left, d, b)
        new = np.where(left, b - _GOLD * (b - a), a + _GOLD * (b - a))
        fnew = ev(new)
        c, d, fc, fd = (np.where(left, new, d), np.where(left, c, new),
                        np.where(left, fnew, fd), np.where(left, fc, fnew))
    for x, fx in ((c, fc), (d, fd)):
        better = fx > best_a
        best_f, best_a = np.where(better, x, best_f), np.where(better, fx, best_a)
    return best_a, best_f


def forced_response(model: BladeModes, eo: int, band_hz, *, amplitude_n: float = 1.0, form: str = "receptance",
                    points_per_bandwidth: float = 8.0, max_points: int = 200_000,
                    keep_sweep: bool = False) -> ForcedResponse:
    """Each blade's peak response to engine order ``eo`` over a sweep of ``band_hz`` (:mod:`rom.forced` notes).

    Parameters
    ----------
    model : BladeModes
        All the modes of the model (modes outside the band still contribute).
    eo : int
        Engine order, 0..⌊N/2⌋.
    band_hz : (float, float)
        The sweep's band (Hz), e.g. :func:`family_band`; it must hold at least one of the model's modes.
    amplitude_n : float
        Force amplitude F0 (N) on each blade.
    form : {"receptance", "mobility", "accelerance"}
    points_per_bandwidth : float
        Grid points in the narrowest half-power bandwidth 2 ζ_r f_r of the in-band modes (≥ 2).
    max_points : int
        Largest grid allowed (a guard against near-zero damping over a wide band).
    keep_sweep : bool
        Keep the grid and the amplitudes on it (for plots).

    Raises
    ------
    ROMError
        For an EO outside 0..⌊N/2⌋, a band with no mode, a bad form or grid.
    """
    force = engine_order_force(model.n_blades, eo, amplitude_n)
    if form not in FORMS:
        raise ROMError(f"form {form!r} not one of {FORMS}")
    band = _check_band(band_hz)
    grid = _sweep_grid(model, band, points_per_bandwidth, max_points)
    amp = np.abs(receptance(model, force, grid, form))
    peaks, peak_hz = _refine_peaks(model, modal_forces(model, force), grid, amp, form)
    return ForcedResponse(int(eo), float(amplitude_n), form, band, peaks, peak_hz, float(grid[1] - grid[0]),
                          grid if keep_sweep else None, amp if keep_sweep else None)
