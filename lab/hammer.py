"""Virtual hammer test in the time domain: impacts, modal responses, an analyser's windows, H1 and coherence.

:func:`lab.rig.measure` writes noise straight onto exact FRFs. :func:`hammer_test` measures them as a lab
does (docs/twin.md, "The hammer test"), for each reference DOF (roving hammer) and each average:

1. **Impact.** A half-sine force pulse of contact time T_c, its peak scattered around the nominal one, and
   now and then a double hit (a smaller second pulse a little later): :func:`draw_impacts`,
   :func:`impact_force`.
2. **Structure.** Modal superposition: each elastic mode's velocity under the force, computed *exactly*
   for the piecewise-linear force through the samples of a simulation grid finer than the analyser's (an
   exact first-order-hold discretisation of the mode's ODE, run with :func:`scipy.signal.lfilter`); each
   rigid-body mode integrates the force (the velocity step of a free–free structure on soft foam).
3. **Analyser.** Record length T = 1/df and fs = N/T ≥ 2.56 f_max, so the FFT bins fall on the setup's
   lines. An ideal anti-aliasing filter precedes each converter: the analyser sees the continuous Fourier
   transform of each windowed channel at the lines. The response is smooth, so the DFT of its fine-grid
   samples gives that transform (its aliases weigh about (f/fs_sim)²: ~1e-4 relative at the default grid,
   falling as 1/factor²); the force is piecewise linear, so its transform is exactly the DFT of its
   samples times sinc²(f/fs_sim), the transform of the linear-interpolation kernel. Converter noise is
   Gaussian, white, at the analyser's rate: drawn there, windowed and transformed there; by linearity its
   spectrum adds to the signal's, and the modes' spectra are mixed into the laser's outputs after the FFT.
4. **Windows.** A rectangular force window over the pulse, and an exponential window w(t) = exp(-t/τ) on
   both channels (on the force it is ≈ 1 over the pulse; on both, the measured FRF is exactly that of the
   structure with its poles moved by -1/τ). That adds the damping Δζ_r = 1/(τ ω_r) to mode r
   (:attr:`HammerResult.window_damping`), as in a lab; subtract it before comparing damping with a truth.
5. **Estimate.** Auto and cross spectra summed over the averages: H1 = Gxy/Gxx and γ² = |Gxy|²/(Gxx Gyy).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import fft, signal

from ema.frf import FRFSet
from ema.numbering import dof_label
from rom.fe_assembly import AssemblyModes

from .hammer_settings import HammerSettings
from .impacts import Impacts, draw_impacts, impact_force
from .rig import RigSetup

__all__ = ["HammerSettings", "HammerResult", "AnalyserGrid", "Impacts", "analyser_grid", "draw_impacts",
           "impact_force", "hammer_test", "windowed_mobility"]

#: The force pulse gets at least this many samples of the simulation grid (the grid is refined for it).
MIN_SAMPLES_PER_CONTACT = 8
#: Outputs whose noise is drawn and transformed together (bounds the memory of the noise records).
OUTPUT_CHUNK = 64


@dataclass(frozen=True)
class AnalyserGrid:
    """Sampling of one record: the analyser's grid and the finer grid the structure is simulated on.

    Attributes
    ----------
    n_samples : int
        Analyser samples per record, N (fs = N df ≥ oversampling × f_max).
    factor : int
        Simulation samples per analyser sample.
    first_line : int
        FFT bin of the band's first line (its frequency over df).
    n_lines : int
        Lines in the band.
    df_hz : float
    """

    n_samples: int
    factor: int
    first_line: int
    n_lines: int
    df_hz: float

    @property
    def dt(self) -> float:
        """Analyser sampling interval (s)."""
        return 1.0 / (self.n_samples * self.df_hz)

    @property
    def dt_sim(self) -> float:
        """Simulation sampling interval (s)."""
        return self.dt / self.factor

    @property
    def lines(self) -> slice:
        """The band's bins in an rfft of the record."""
        return slice(self.first_line, self.first_line + self.n_lines)


def analyser_grid(setup: RigSetup, settings: HammerSettings) -> AnalyserGrid:
    """The sampling that puts the FFT bins on ``setup.frequencies()``.

    Raises
    ------
    ValueError
        The band's first line is not a multiple of df (no FFT bin falls on it).
    """
    freq = setup.frequencies()
    df = float(setup.df_hz)
    k0 = int(round(freq[0] / df))
    if abs(k0 * df - freq[0]) > 1e-9 * max(df, freq[0]):
        raise ValueError(f"RigSetup.band_hz starts at {freq[0]} Hz: expected a multiple of df_hz = {df} Hz "
                         "(the FFT's lines are k df)")
    k_last = k0 + freq.size - 1
    n = fft.next_fast_len(math.ceil(settings.oversampling * k_last - 1e-9), real=True)
    # The pulse needs MIN_SAMPLES_PER_CONTACT samples; next_fast_len keeps the long FFT fast.
    need = math.ceil(MIN_SAMPLES_PER_CONTACT / (settings.contact_time_s * n * df) - 1e-9)
    factor = fft.next_fast_len(max(int(settings.simulation_factor), need), real=True)
    return AnalyserGrid(n_samples=int(n), factor=int(factor), first_line=k0, n_lines=int(freq.size), df_hz=df)


@dataclass(frozen=True, eq=False)
class HammerResult:
    """A virtual hammer test's estimates.

    Attributes
    ----------
    frf : FRFSet
        H1 mobility (m/s/N) on ``setup.frequencies()``, labels as :func:`lab.rig.measure`'s.
    coherence : ndarray, shape (n_outputs, n_inputs, n_freq)
        Ordinary coherence γ² in [0, 1] (1 for a single average; 0 where a channel carries nothing).
    window_damping : ndarray, shape (n_modes,)
        Damping ratio Δζ_r = 1/(τ ω_r) the exponential window adds to each elastic mode (0 without it).
        To first order, away from the rigid-body mass line, the measured FRF is
        ``synthesize_mobility(modes, zeta + window_damping, ...)``; exactly, :func:`windowed_mobility`.
    window_time_constant_s : float
        τ of the exponential window (inf without it).
    force_autospectrum : ndarray, shape (n_inputs, n_freq)
        Gxx: mean |F|² over the averages of the windowed force's Fourier transform ((N s)²).
    double_hits : ndarray of bool, shape (n_inputs, n_averages)
        Which hits were double.
    """

    frf: FRFSet
    coherence: np.ndarray
    window_damping: np.ndarray
    window_time_constant_s: float
    force_autospectrum: np.ndarray
    double_hits: np.ndarray


def windowed_mobility(
    modes: AssemblyModes, zeta: np.ndarray, freq_hz: np.ndarray, outputs: Sequence[int], inputs: Sequence[int],
    tau_s: float,
) -> np.ndarray:
    """The mobility (m/s/N) a test with the exponential window exp(-t/τ) on both channels measures, exactly.

    The window multiplies every impulse response by exp(-t/τ), so the measured FRF is the structure's
    mobility at s = iω + 1/τ: each pole moves by -1/τ (the damping Δζ_r = 1/(τ ω_r) of
    :attr:`HammerResult.window_damping`, to first order) and the rigid-body mass line 1/(iω) becomes
    1/(iω + 1/τ). Same arguments and shape as :func:`lab.rig.synthesize_mobility`; ``tau_s = inf`` gives it.
    """
    s = 2j * np.pi * np.asarray(freq_hz, np.float64) + 1.0 / tau_s
    wn = 2.0 * np.pi * np.asarray(modes.frequencies_hz, np.float64)
    den = wn[:, None] ** 2 + 2.0 * np.asarray(zeta)[:, None] * wn[:, None] * s[None] + s[None] ** 2
    out, inp = np.asarray(outputs), np.asarray(inputs)
    H = np.einsum("or,ir,rf->oif", modes.meas_shapes[out], modes.meas_shapes[inp], s[None] / den)
    if modes.rigid_shapes is not None:
        rigid = modes.rigid_shapes[out] @ modes.rigid_shapes[inp].T
        H += rigid[:, :, None] / s[None, None]
    return H


def _modal_filters(freq_hz: np.ndarray, zeta: np.ndarray, dt: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """lfilter coefficients (b, a) of each elastic mode, from unit modal force to modal velocity.

    Exact for a force that is linear between samples: the first-order-hold (triangle-hold) equivalent.
    """
    out = []
    for f, z in zip(freq_hz, zeta, strict=True):
        w = 2.0 * np.pi * float(f)
        A = np.array([[0.0, 1.0], [-w * w, -2.0 * float(z) * w]])
        B, Cv, D = np.array([[0.0], [1.0]]), np.array([[0.0, 1.0]]), np.zeros((1, 1))
        sysd = signal.cont2discrete((A, B, Cv, D), dt, method="foh")
        b, a = signal.ss2tf(*sysd[:4])
        out.append((np.asarray(b[0], np.float64), np.asarray(a, np.float64)))
    return out


def _modal_spectra(
    filters: list, rigid: bool, force: np.ndarray, window: np.ndarray, grid: AnalyserGrid
) -> tuple[np.ndarray, np.ndarray]:
    """Windowed spectra of each modal velocity under the force, and their Gram matrix on the first hit.

    Column c < len(filters) is elastic mode c; with ``rigid`` the last column is the rigid-body velocity
    (the integral of the force: exact, as the force is linear between samples).

    Returns
    -------
    spectra : ndarray, shape (n_cols, n_hits, n_lines)
        Fourier transforms (m/s·s per unit modal participation) of the windowed modal velocities.
    gram : ndarray, shape (n_cols, n_cols)
        Mean over the record of products of the modal velocities of the first hit, at the analyser's
        instants: the channels' mean squares are quadratic forms of it.
    """
    n_cols = len(filters) + int(rigid)
    spectra = np.empty((n_cols, force.shape[0], grid.n_lines), np.complex128)
    first = np.empty((n_cols, grid.n_samples))
    for c in range(n_cols):
        if c < len(filters):
            g = signal.lfilter(*filters[c], force, axis=-1)
        else:
            g = grid.dt_sim * (np.cumsum(force, axis=-1) - 0.5 * (force[:, :1] + force))
        first[c] = g[0, :: grid.factor]
        spectra[c] = fft.rfft(g * window, axis=-1)[:, grid.lines] * grid.dt_sim
    return spectra, first @ first.T / grid.n_samples


def _noise_spectra(rng: np.random.Generator, sigma: np.ndarray, n_hits: int, window: np.ndarray,
                   grid: AnalyserGrid) -> np.ndarray:
    """Transforms of windowed white Gaussian converter noise, shape (n_channels, n_hits, n_lines)."""
    out = np.zeros((sigma.size, n_hits, grid.n_lines), np.complex128)
    if not np.any(sigma > 0):
        return out
    for h in range(n_hits):
        e = rng.standard_normal((sigma.size, grid.n_samples)) * sigma[:, None]
        out[:, h] = fft.rfft(e * window, axis=-1)[:, grid.lines] * grid.dt
    return out


def _windows(grid: AnalyserGrid, settings: HammerSettings) -> tuple[float, dict[str, np.ndarray]]:
    """τ of the exponential window and the windows on both grids: response ("resp_*") and force ("force_*")."""
    record = 1.0 / grid.df_hz
    tau = math.inf if settings.exp_window_end is None else record / math.log(1.0 / settings.exp_window_end)
    out = {"t_sim": np.arange(grid.n_samples * grid.factor) * grid.dt_sim}
    for name, n, dt in (("sim", grid.n_samples * grid.factor, grid.dt_sim), ("an", grid.n_samples, grid.dt)):
        t = np.arange(n) * dt
        w = np.exp(-t / tau)
        out[f"resp_{name}"] = w
        if settings.force_window is not None:
            # a half-sample margin: a pulse ending on a sample stays inside
            w = w * (t <= settings.force_window * settings.contact_time_s + 0.5 * dt)
        out[f"force_{name}"] = w
    return tau, out


def _check_inputs(modes: AssemblyModes, zeta: np.ndarray, inputs: list, outputs: list) -> None:
    n_meas, n_modes = modes.meas_shapes.shape
    if zeta.shape != (n_modes,) or not np.all(np.isfinite(zeta)) or np.any(zeta < 0):
        raise ValueError(f"zeta has shape {zeta.shape}: expected ({n_modes},) finite damping ratios >= 0")
    if not inputs:
        raise ValueError("inputs is empty: expected at least one hammer DOF")
    for name, rows in (("inputs", inputs), ("outputs", outputs)):
        bad = [k for k in rows if not 0 <= k < n_meas]
        if bad:
            raise ValueError(f"{name} {bad[:3]}: expected rows of modes.meas_shapes (0..{n_meas - 1})")


def hammer_test(
    modes: AssemblyModes,
    zeta: np.ndarray,
    setup: RigSetup,
    rng: np.random.Generator,
    inputs: Sequence[int],
    outputs: Sequence[int] | None = None,
    settings: HammerSettings = HammerSettings(),  # noqa: B008  (frozen: a shared default is safe)
) -> HammerResult:
    """A virtual roving-hammer test in the time domain: H1 mobility and coherence (see the module's notes).

    Parameters
    ----------
    modes : AssemblyModes
        Modes of the tested structure (elastic, and rigid-body in ``rigid_shapes`` for a free–free one),
        computed to well above ``setup.band_hz``.
    zeta : ndarray, shape (n_modes,)
        Modal damping ratio of each elastic mode.
    setup : RigSetup
        Band and df (record length 1/df); its noise fields are not used (``settings`` has the channels').
    rng : numpy.random.Generator
        Every draw comes from it, in a fixed order: the same generator state gives the same test.
    inputs : sequence of int
        Hammer DOFs (rows of ``modes.meas_shapes``), hit one after the other.
    outputs : sequence of int, optional
        Laser DOFs (default: every measurement DOF).
    settings : HammerSettings

    Returns
    -------
    HammerResult

    Raises
    ------
    ValueError
        A bad setting (see :meth:`HammerSettings.validate`), a band not on multiples of df, damping of the
        wrong shape, or DOF rows out of range.
    """
    settings.validate()
    zeta = np.asarray(zeta, np.float64).reshape(-1)
    inputs = [int(k) for k in inputs]
    outputs = list(range(modes.meas_shapes.shape[0])) if outputs is None else [int(k) for k in outputs]
    _check_inputs(modes, zeta, inputs, outputs)
    grid = analyser_grid(setup, settings)
    tau, win = _windows(grid, settings)
    filters = _modal_filters(modes.frequencies_hz, zeta, grid.dt_sim)
    rigid = modes.rigid_shapes is not None and modes.rigid_shapes.shape[1] > 0
    phi = np.asarray(modes.meas_shapes, np.float64)
    n_out, n_in, n_avg = len(outputs), len(inputs), int(settings.n_averages)
    k = np.arange(grid.first_line, grid.first_line + grid.n_lines)
    hold = np.sinc(k / (grid.n_samples * grid.factor)) ** 2  # transform of the linear-interpolation kernel
    Gxy = np.zeros((n_out, n_in, grid.n_lines), np.complex128)
    Gyy = np.zeros((n_out, n_in, grid.n_lines))
    Gxx = np.zeros((n_in, grid.n_lines))
    doubles = np.zeros((n_in, n_avg), bool)
    for j, i in enumerate(inputs):
        hits, force, F = _force_spectra(settings, rng, n_avg, win, grid, hold)
        doubles[j] = hits.double
        Gxx[j] = np.sum(np.abs(F) ** 2, axis=0)
        spectra, gram = _modal_spectra(filters, rigid, force, win["resp_sim"], grid)
        if rigid:
            # The range is set on the elastic response: a free specimen's rigid-body drift lies below any band
            # and the analyser's AC coupling takes it out first (else its constant velocity, the bulk of the
            # record's RMS, would bury the weaker modes under a noise floor no 24-bit analyser has).
            gram[-1, :] = gram[:, -1] = 0.0
        # modal participation of each column at each output for this hammer DOF
        C = phi[outputs] * phi[i][None, :]
        if rigid:
            C = np.hstack([C, modes.rigid_shapes[outputs] @ modes.rigid_shapes[i][:, None]])
        Gxy[:, j], Gyy[:, j] = _output_spectra(C, spectra, gram, F, rng, settings.response_noise, win["resp_an"], grid)
    return _result(modes, setup, outputs, inputs, (Gxx, Gyy, Gxy), tau, doubles, n_avg)


def _force_spectra(settings: HammerSettings, rng: np.random.Generator, n_avg: int, win: dict[str, np.ndarray],
                   grid: AnalyserGrid, hold: np.ndarray):
    """One reference's hits (module notes, steps 1 and 3): the impacts drawn, the force on the simulation grid,
    shape (n_avg, n_sim), and the Fourier transforms of the windowed force channel with its noise, shape
    (n_avg, n_lines); ``hold`` is the linear-interpolation kernel's transform at the lines."""
    hits = draw_impacts(settings, rng, n_avg)
    force = impact_force(win["t_sim"], settings.contact_time_s, hits)
    F = fft.rfft(force * win["force_sim"], axis=-1)[:, grid.lines] * (grid.dt_sim * hold)
    F += _noise_spectra(rng, np.full(1, settings.force_noise * settings.peak_force_n), n_avg,
                        win["force_an"], grid)[0]
    return hits, force, F


def _output_spectra(C: np.ndarray, spectra: np.ndarray, gram: np.ndarray, F: np.ndarray, rng: np.random.Generator,
                    noise: float, window: np.ndarray, grid: AnalyserGrid) -> tuple[np.ndarray, np.ndarray]:
    """One reference's Gxy and Gyy at every output, shape (n_out, n_lines), summed over its hits.

    Each output's spectrum is its modal participations ``C`` (n_out, n_cols) times the modal ``spectra`` of
    :func:`_modal_spectra`, plus the laser's noise (``noise`` times the channel's RMS from ``gram``); outputs
    are taken :data:`OUTPUT_CHUNK` at a time.
    """
    n_out, n_avg = C.shape[0], F.shape[0]
    Gxy = np.zeros((n_out, grid.n_lines), np.complex128)
    Gyy = np.zeros((n_out, grid.n_lines))
    for lo in range(0, n_out, OUTPUT_CHUNK):
        c = C[lo : lo + OUTPUT_CHUNK]
        Y = np.tensordot(c.astype(np.complex128), spectra, axes=(1, 0))  # (chunk, n_avg, n_lines)
        rms = np.sqrt(np.maximum(np.einsum("oc,cd,od->o", c, gram, c), 0.0))
        Y += _noise_spectra(rng, noise * rms, n_avg, window, grid)
        Gxy[lo : lo + OUTPUT_CHUNK] = np.einsum("af,oaf->of", np.conj(F), Y)
        Gyy[lo : lo + OUTPUT_CHUNK] = np.sum(np.abs(Y) ** 2, axis=1)
    return Gxy, Gyy


def _result(modes: AssemblyModes, setup: RigSetup, outputs: list, inputs: list, spectra: tuple, tau: float,
            doubles: np.ndarray, n_avg: int) -> HammerResult:
    """H1 and coherence from the summed spectra, packed with the labels and the window's damping."""
    Gxx, Gyy, Gxy = spectra
    H = Gxy / Gxx[None]
    den = Gxx[None] * Gyy
    coh = np.divide(np.abs(Gxy) ** 2, den, out=np.zeros_like(Gyy), where=den > 0)
    labels = [dof_label(modes.meas_labels[k]) for k in outputs]
    refs = [dof_label(modes.meas_labels[k]) for k in inputs]
    frf = FRFSet(setup.frequencies(), H, labels, refs, form="mobility", units="m/s/N")
    w = 2.0 * np.pi * np.asarray(modes.frequencies_hz, np.float64)
    return HammerResult(frf=frf, coherence=np.clip(coh, 0.0, 1.0), window_damping=1.0 / (tau * w),
                        window_time_constant_s=tau, force_autospectrum=Gxx / n_avg, double_hits=doubles)
