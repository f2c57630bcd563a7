"""The modal model at one DOF per blade, the engine-order force and the receptance (package notes)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ROMError

__all__ = ["BladeModes", "FORMS", "blade_modes", "engine_order_force", "modal_forces", "receptance",
           "whitehead_limit"]

#: FRF forms: the response's factor on the receptance X (m/N).
FORMS = ("receptance", "mobility", "accelerance")


@dataclass(frozen=True, eq=False)
class BladeModes:
    """A bladed disk's modes at one DOF per blade: what the forced response needs.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_modes,)
        Undamped natural frequencies (Hz), positive.
    damping_ratio : ndarray, shape (n_modes,)
        Viscous modal damping ratios, in (0, 1). A scalar is broadcast to every mode.
    shapes : ndarray, shape (n_blades, n_modes), float64 or complex128
        Mass-normalised shapes (φᵀ M φ = 1 over the whole model, m/√kg) at the chosen DOF of blades 1..N in
        angular order.
    """

    frequencies_hz: np.ndarray
    damping_ratio: np.ndarray
    shapes: np.ndarray

    def __post_init__(self) -> None:
        f = np.asarray(self.frequencies_hz, np.float64).reshape(-1)
        phi = np.asarray(self.shapes)
        phi = phi.astype(np.complex128 if np.iscomplexobj(phi) else np.float64)
        if phi.ndim != 2 or phi.shape[1] != f.size or phi.shape[0] < 2:
            raise ROMError(f"shapes have shape {phi.shape}, expected (n_blades ≥ 2, {f.size}): one row per blade, "
                           "one column per mode")
        if f.size == 0 or not np.all(np.isfinite(f) & (f > 0)):
            raise ROMError(f"frequencies must be positive and finite (Hz), got {f.size} values, min {f.min(initial=0)}")
        z = np.broadcast_to(np.asarray(self.damping_ratio, np.float64), f.shape) if np.ndim(self.damping_ratio) == 0 \
            else np.asarray(self.damping_ratio, np.float64).reshape(-1)
        if z.shape != f.shape:
            raise ROMError(f"{z.size} damping ratios for {f.size} modes: give one per mode or one for all")
        if not np.all(np.isfinite(z) & (z > 0) & (z < 1)):
            bad = z[~(np.isfinite(z) & (z > 0) & (z < 1))][0]
            raise ROMError(f"damping ratio {bad} outside (0, 1): every mode needs positive viscous damping")
        if not np.all(np.isfinite(phi)):
            raise ROMError("shapes hold non-finite values")
        for name, arr in (("frequencies_hz", f), ("damping_ratio", np.array(z)), ("shapes", phi)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n_blades(self) -> int:
        return int(self.shapes.shape[0])

    @property
    def n_modes(self) -> int:
        return int(self.frequencies_hz.size)

    @property
    def omega(self) -> np.ndarray:
        """Natural frequencies (rad/s), shape (n_modes,)."""
        return 2.0 * math.pi * self.frequencies_hz


def blade_modes(modes, damping_ratio, point: int = 1) -> BladeModes:
    """The rows of an :class:`rom.fe_assembly.AssemblyModes` at blade point ``point`` of every slot.

    Parameters
    ----------
    modes : AssemblyModes
        ``meas_labels`` ``("blade", slot, point, direction)``; shapes mass-normalised (every ROM and FE solve).
    damping_ratio : float or array_like, shape (n_modes,)
    point : int
        Blade measurement point (1-based), the same on every blade.

    Raises
    ------
    ROMError
        If some slot 1..N has no such point, or one has two.
    """
    rows = {int(lab[1]): k for k, lab in enumerate(modes.meas_labels) if lab[0] == "blade" and int(lab[2]) == point}
    n = max(rows, default=0)
    if n < 2 or sorted(rows) != list(range(1, n + 1)) or \
            sum(lab[0] == "blade" and int(lab[2]) == point for lab in modes.meas_labels) != n:
        raise ROMError(f"blade point {point} is not measured exactly once on each slot 1..N "
                       f"(found on slots {sorted(rows)})")
    shapes = np.asarray(modes.meas_shapes)[[rows[s] for s in range(1, n + 1)]]
    return BladeModes(modes.frequencies_hz, damping_ratio, shapes)


def whitehead_limit(n_blades: int) -> float:
    """Whitehead's (1966) largest amplification factor (1 + √N)/2 of one isolated, lightly damped family."""
    if n_blades < 1:
        raise ROMError(f"number of blades must be ≥ 1, got {n_blades}")
    return 0.5 * (1.0 + math.sqrt(n_blades))


def _check_eo(eo, n_blades: int) -> int:
    if not (isinstance(eo, (int, np.integer)) and 0 <= eo <= n_blades // 2):
        raise ROMError(f"engine order {eo!r} outside 0..{n_blades // 2} (N = {n_blades} blades)")
    return int(eo)


def engine_order_force(n_blades: int, eo: int, amplitude_n: float = 1.0) -> np.ndarray:
    """Travelling-wave force F_j = F0 exp(i 2π EO (j − 1)/N) on blades j = 1..N, shape (N,), complex (N)."""
    eo = _check_eo(eo, n_blades)
    if not (math.isfinite(amplitude_n) and amplitude_n > 0):
        raise ROMError(f"force amplitude {amplitude_n} N must be positive and finite")
    return amplitude_n * np.exp(2j * math.pi * eo * np.arange(n_blades) / n_blades)


def modal_forces(model: BladeModes, force: np.ndarray) -> np.ndarray:
    """Modal forces φ_rᵀ F (N/√kg), shape (n_modes,), complex: a plain transpose, no conjugate (package notes)."""
    force = np.asarray(force)
    if force.shape != (model.n_blades,):
        raise ROMError(f"force has shape {force.shape}, expected ({model.n_blades},): one value per blade")
    return model.shapes.T @ force


def _form_factor(form: str, omega: np.ndarray) -> np.ndarray | float:
    if form == "receptance":
        return 1.0
    if form == "mobility":
        return 1j * omega
    if form == "accelerance":
        return -(omega**2)
    raise ROMError(f"form {form!r} not one of {FORMS}")


def receptance(model: BladeModes, force: np.ndarray, frequencies_hz, form: str = "receptance") -> np.ndarray:
    """Steady response of every blade's DOF to the harmonic force, by modal superposition (:mod:`rom.forced` notes).

    Parameters
    ----------
    model : BladeModes
    force : ndarray, shape (n_blades,), complex
        Force amplitudes (N) at the blades' DOFs, e.g. :func:`engine_order_force`.
    frequencies_hz : array_like, shape (n_freq,)
        Excitation frequencies (Hz).
    form : {"receptance", "mobility", "accelerance"}
        X (m), i ω X (m/s) or −ω² X (m/s²).

    Returns
    -------
    ndarray, shape (n_freq, n_blades), complex
    """
    q = modal_forces(model, force)
    w = 2.0 * math.pi * np.asarray(frequencies_hz, np.float64).reshape(-1)
    wr, z = model.omega, model.damping_ratio
    den = wr**2 - w[:, None] ** 2 + 2j * (z * wr) * w[:, None]
    return _times_shapes_t(q / den, model.shapes) * np.reshape(_form_factor(form, w), (-1, 1))


def _times_shapes_t(A: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """A Φᵀ for complex A: with real Φ as two real products (numpy's complex-by-real
    product skips BLAS: ~25× slower at 190 × 60 × 20)."""
    if np.iscomplexobj(shapes):
        return A @ shapes.T
    return (A.real @ shapes.T) + 1j * (A.imag @ shapes.T)


def blade_power_slopes(model: BladeModes, q: np.ndarray, form: str):
    """f ↦ (P, dP/dω, d²P/dω²) of each blade j at its own frequency f[j] (Hz), P = |response|², for the Newton
    refinement of the peaks: shapes (n_blades,) → three (n_blades,).

    With X = Σ_r S_jr / D_r, D_r = ω_r² − ω² + i c_r ω, E_r = (2ω − i c_r) / D_r: X' = Σ S E / D and
    X'' = Σ S (2 / D + 2 E²) / D; the response Y = h X with h = 1, iω or −ω² (the form); P' = 2 Re(Ȳ Y'),
    P'' = 2 (|Y'|² + Re(Ȳ Y''))."""
    wr2 = model.omega**2
    c = 2.0 * model.damping_ratio * model.omega
    Sq = model.shapes * q

    def slopes(f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = (2.0 * math.pi * f)[:, None]
        inv = 1.0 / (wr2 - w**2 + 1j * c * w)
        E = (2.0 * w - 1j * c) * inv
        SI = Sq * inv
        X, X1, X2 = SI.sum(axis=1), (SI * E).sum(axis=1), (SI * (2.0 * inv + 2.0 * E**2)).sum(axis=1)
        w = w[:, 0]
        if form == "receptance":
            Y, Y1, Y2 = X, X1, X2
        elif form == "mobility":
            Y, Y1, Y2 = 1j * w * X, 1j * (X + w * X1), 1j * (2.0 * X1 + w * X2)
        else:
            Y, Y1, Y2 = -(w**2) * X, -(2.0 * w * X + w**2 * X1), -(2.0 * X + 4.0 * w * X1 + w**2 * X2)
        return (np.abs(Y) ** 2, 2.0 * np.real(np.conj(Y) * Y1),
                2.0 * (np.abs(Y1) ** 2 + np.real(np.conj(Y) * Y2)))

    return slopes


def blade_amplitudes(model: BladeModes, q: np.ndarray, form: str):
    """f ↦ |response| of each blade j at its own frequency f[j] (Hz): shapes (n_blades,) → (n_blades,)."""
    wr2 = model.omega**2
    c = 2.0 * model.damping_ratio * model.omega
    Sq = model.shapes * q  # blade j's share of each mode: φ_jr (φ_rᵀ F), precomputed for the many calls

    def amp(f: np.ndarray) -> np.ndarray:
        w = (2.0 * math.pi * f)[:, None]
        X = (Sq / (wr2 - w**2 + 1j * c * w)).sum(axis=1)
        return np.abs(X) if form == "receptance" else np.abs(X * _form_factor(form, w[:, 0]))

    return amp
