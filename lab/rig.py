"""Virtual hammer tests on the truth twin (issue 9, item 4): FRFs as a laser vibrometer measures them.

A test is free–free: the truth modes (elastic and rigid-body) of the tested assembly, light modal damping,
an impact hammer at one or more reference DOFs and the laser's out-of-plane velocity at every measurement
point, so the FRFs are **mobilities** (m/s/N):

    H_oi(ω) = Σ_r iω φ_or φ_ir / (ω_r² − ω² + 2 i ζ_r ω_r ω)

The sum runs over the elastic modes computed up to well above the band (their residual effect stays) and the
rigid-body modes (ω_r = 0: the mass line of a structure on soft foam). Noise is added as a lab sees it:
multiplicative (the hammer's force and the laser's gain scatter, proportional to |H|) and additive (the
laser's noise floor, a fraction of each FRF's RMS over the band), both complex Gaussian from the rng.

DOF labels for the UFF files (node, direction): disk sector k is node ``k`` (direction 3, axial); point p
of the blade in slot s is node ``1000 s + p`` (direction 1, out of the blade's plane, in the blade's local
frame), and point p of a blade tested alone is node ``p`` (label slot 0: the same points on every blade).
:func:`dof_label` is the one place this is defined.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ema.frf import FRFSet
from ema.numbering import dof_label, rom_modal_model
from rom.fe_assembly import AssemblyModes

__all__ = ["RigSetup", "dof_label", "rom_modal_model", "synthesize_mobility", "measure", "peak_snr", "MIN_SNR",
           "canonical_degenerate", "damping_ratios"]

#: A mode belongs to a test when its resonance peak stands at least this far above the noise floor in some
#: FRF (about 30 dB): weaker modes are lost in the noise, as in a real test.
MIN_SNR = 30.0


@dataclass(frozen=True)
class RigSetup:
    """Band, resolution and noise of one virtual test.

    Attributes
    ----------
    band_hz : (float, float)
        First and last spectral line (Hz).
    df_hz : float
        Line spacing (Hz).
    multiplicative_noise : float
        Standard deviation of the relative complex error on every line (0.005 = 0.5 %).
    additive_noise : float
        Noise floor: standard deviation of the additive complex error, as a fraction of each FRF's RMS
        magnitude over the band.
    """

    band_hz: tuple[float, float]
    df_hz: float
    multiplicative_noise: float = 0.005
    additive_noise: float = 0.002

    def frequencies(self) -> np.ndarray:
        """Spectral lines (Hz), shape (n_freq,)."""
        lo, hi = self.band_hz
        if not (0 < lo < hi and self.df_hz > 0):
            raise ValueError(f"test band {self.band_hz} Hz with df {self.df_hz} Hz: expected 0 < low < high, df > 0")
        n = int(np.floor((hi - lo) / self.df_hz + 1e-9)) + 1
        return lo + self.df_hz * np.arange(n)


def synthesize_mobility(
    modes: AssemblyModes, zeta: np.ndarray, freq_hz: np.ndarray, outputs: Sequence[int], inputs: Sequence[int]
) -> np.ndarray:
    """Noise-free mobility FRFs (m/s/N) between measurement DOFs of ``modes``.

    Parameters
    ----------
    modes : AssemblyModes
    zeta : ndarray, shape (n_modes,)
        Modal damping ratio of each elastic mode.
    freq_hz : ndarray, shape (n_freq,)
    outputs, inputs : sequence of int
        Rows of ``modes.meas_shapes`` (response and excitation DOFs).

    Returns
    -------
    ndarray of complex128, shape (n_outputs, n_inputs, n_freq)
    """
    w = 2 * np.pi * np.asarray(freq_hz, dtype=np.float64)
    wn = 2 * np.pi * modes.frequencies_hz
    den = wn[:, None] ** 2 - w[None, :] ** 2 + 2j * np.asarray(zeta)[:, None] * wn[:, None] * w[None, :]
    out, inp = np.asarray(outputs), np.asarray(inputs)
    phi_o, phi_i = modes.meas_shapes[out], modes.meas_shapes[inp]
    H = np.einsum("or,ir,rf->oif", phi_o, phi_i, 1.0 / den)
    # Rigid-body modes: receptance −1/ω² each (free–free on soft foam: the mass line). A mode set without
    # them (a ROM solve) is a grounded model: no mass line.
    if modes.rigid_shapes is not None:
        rigid = np.einsum("or,ir->oi", modes.rigid_shapes[out], modes.rigid_shapes[inp])
        H += rigid[:, :, None] / (-(w**2))[None, None]
    return H * (1j * w)[None, None, :]


def measure(
    modes: AssemblyModes,
    zeta: np.ndarray,
    setup: RigSetup,
    rng: np.random.Generator,
    inputs: Sequence[int],
    outputs: Sequence[int] | None = None,
) -> FRFSet:
    """One virtual hammer test: noisy mobility FRFs at the measurement DOFs, as an :class:`ema.FRFSet`.

    Parameters
    ----------
    modes : AssemblyModes
        Modes of the tested assembly, computed to well above ``setup.band_hz``.
    zeta : ndarray, shape (n_modes,)
    setup : RigSetup
    rng : numpy.random.Generator
    inputs : sequence of int
        Hammer DOFs (rows of ``modes.meas_shapes``).
    outputs : sequence of int, optional
        Laser DOFs (default: every measurement DOF).
    """
    freq = setup.frequencies()
    outputs = list(range(modes.meas_shapes.shape[0])) if outputs is None else list(outputs)
    H = synthesize_mobility(modes, zeta, freq, outputs, inputs)
    shape = H.shape

    def cnoise() -> np.ndarray:
        return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)

    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=2, keepdims=True))
    H = H * (1 + setup.multiplicative_noise * cnoise()) + setup.additive_noise * rms * cnoise()
    labels = [dof_label(modes.meas_labels[k]) for k in outputs]
    refs = [dof_label(modes.meas_labels[k]) for k in inputs]
    return FRFSet(freq, H, labels, refs, form="mobility", units="m/s/N")


def peak_snr(
    modes: AssemblyModes, zeta: np.ndarray, setup: RigSetup, outputs: Sequence[int], inputs: Sequence[int]
) -> np.ndarray:
    """Each mode's best resonance peak over the noise floor, shape (n_modes,).

    The peak of mode r in mobility H_oi is |φ_or φ_ir| / (2 ζ_r ω_r); the floor is ``setup.additive_noise``
    times the FRF's RMS over the band. A flat airfoil's in-plane modes move nothing out of plane, so an
    out-of-plane laser cannot see them: their ratio is near 0 (see :data:`MIN_SNR`).
    """
    H = synthesize_mobility(modes, zeta, setup.frequencies(), outputs, inputs)
    floor = setup.additive_noise * np.sqrt(np.mean(np.abs(H) ** 2, axis=2))  # (n_out, n_in)
    phi_o, phi_i = modes.meas_shapes[list(outputs)], modes.meas_shapes[list(inputs)]
    w = 2 * np.pi * modes.frequencies_hz
    peak = np.abs(phi_o[:, None, :] * phi_i[None, :, :]) / (2 * np.asarray(zeta) * w)[None, None, :]
    return np.max(peak / floor[:, :, None], axis=(0, 1))


def canonical_degenerate(modes: AssemblyModes, inputs: Sequence[int], rtol: float = 1e-7) -> AssemblyModes:
    """The same modes with every group of repeated frequencies in a basis fixed by the hammer ``inputs``.

    A cyclic disk's double modes are one eigenspace: the solver returns an arbitrary basis of it, so the
    response of each member at the hammer (and whether a test "sees" it) would change from run to run. Here
    each group (frequencies within ``rtol``) is rotated by the SVD of its rows at the inputs: the first members
    carry the input participation in decreasing order, the rest have none (a hammer excites only that
    combination). The group's frequencies become their mean and each shape's largest value is positive, so
    the result does not depend on the solver's basis or order.

    Parameters
    ----------
    modes : AssemblyModes
    inputs : sequence of int
        Rows of ``modes.meas_shapes`` that are hammer points.
    """
    f = np.array(modes.frequencies_hz, dtype=np.float64)
    shapes = np.array(modes.meas_shapes, dtype=np.float64)
    energy = None if modes.blade_energy is None else np.array(modes.blade_energy, dtype=np.float64)
    start = 0
    while start < f.size:
        stop = start + 1
        while stop < f.size and f[stop] <= f[start] * (1 + rtol):
            stop += 1
        if stop - start > 1:
            g = slice(start, stop)
            _, _, vt = np.linalg.svd(shapes[list(inputs), g], full_matrices=True)
            shapes[:, g] = shapes[:, g] @ vt.T
            f[g] = f[g].mean()
            if energy is not None:
                energy[g] = energy[g].mean()
        start = stop
    k = np.argmax(np.abs(shapes), axis=0)
    shapes *= np.where(shapes[k, np.arange(shapes.shape[1])] < 0, -1.0, 1.0)
    return AssemblyModes(f, shapes, modes.meas_labels, rigid_shapes=modes.rigid_shapes, blade_energy=energy)


def damping_ratios(n_modes: int, rng: np.random.Generator, damping_range: tuple[float, float]) -> np.ndarray:
    """Modal damping ratios, log-uniform in ``damping_range`` and varying from mode to mode, shape (n_modes,)."""
    lo, hi = damping_range
    return np.exp(rng.uniform(np.log(lo), np.log(hi), n_modes))
