"""Calibration of a component's Young's modulus to a measured frequency (paper §5, Table 4).

For a homogeneous linear-elastic component, ``K`` is proportional to ``E`` while ``M`` does not depend on
it, so every eigenvalue scales with ``E``: ``f_i(E') = f_i(E) √(E'/E)``. Matching mode ``i`` to a target
frequency therefore needs one modal solve and a rescaling, with no iteration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import gmean

from .component import Component
from .solver import solve_modes

__all__ = ["Calibration", "calibrate_modulus", "calibrate_bladed_disk", "MaterialCalibration", "component_mass",
           "calibrate_material", "pool_calibrations", "scaled_component", "apply_calibration"]


@dataclass(frozen=True)
class Calibration:
    """Result of :func:`calibrate_modulus`.

    Attributes
    ----------
    component : Component
        The recalibrated component (``K`` scaled, ``meta["E"]`` updated).
    E_before, E_after : float
        Young's modulus in Pa before and after.
    mode : int
        0-based index of the elastic mode that was matched.
    frequency_before_hz, target_hz : float
    """

    component: Component
    E_before: float
    E_after: float
    mode: int
    frequency_before_hz: float
    target_hz: float

    @property
    def scale(self) -> float:
        """E_after / E_before: every eigenvalue scales by this factor."""
        return self.E_after / self.E_before


def calibrate_modulus(
    component: Component, target_hz: float, mode: int = 0, backend: str = "auto", current_hz: float | None = None
) -> Calibration:
    """Set the Young's modulus so that elastic mode ``mode`` (0-based) sits at ``target_hz``.

    The paper matches the disk's first mode to 1090.6 Hz, and the blade's first free–free eigenvalue to the
    mean over its measured blades.

    Parameters
    ----------
    component : Component
        Homogeneous component whose ``meta["E"]`` holds its current modulus in Pa.
    target_hz : float
        Target frequency in Hz (> 0).
    mode : int
        Elastic mode index, 0-based, rigid-body modes excluded.
    current_hz : float, optional
        The component's present frequency of that mode, when the caller has already solved for it
        (skips the modal solve).
    """
    if not (isinstance(target_hz, (int, float)) and math.isfinite(target_hz) and target_hz > 0):
        raise ValueError(f"target_hz must be a positive frequency in Hz, got {target_hz!r}")
    if not (isinstance(mode, int) and 0 <= mode < 100):
        raise ValueError(f"mode must be an elastic mode index in 0..99, got {mode!r}")
    if "E" not in component.meta:
        raise ValueError(f"component {component.name!r} has no meta['E']: cannot calibrate a non-homogeneous model")
    if current_hz is None:
        f = float(solve_modes(component.K, component.M, mode + 1, backend=backend).frequencies_hz[mode])
    elif math.isfinite(current_hz) and current_hz > 0:
        f = float(current_hz)
    else:
        raise ValueError(f"current_hz must be a positive frequency in Hz, got {current_hz!r}")
    scale = (target_hz / f) ** 2
    E0 = float(component.meta["E"])
    meta = dict(component.meta, E=E0 * scale)
    new = Component(component.name, component.K * scale, component.M, component.node_ids, component.coords,
                    dict(component.node_sets), meta, component.elements)
    return Calibration(new, E0, E0 * scale, mode, f, float(target_hz))


def calibrate_bladed_disk(bd, disk_target_hz: float | None = 1090.6, blade_target_hz: float | None = None,
                          backend: str = "auto", disk_current_hz: float | None = None):
    """Calibrate the disk (first elastic mode) and/or the blade (first free–free mode) of a ``BladedDisk``.

    Returns a new ``BladedDisk`` whose components and ``params`` materials carry the calibrated moduli.
    ``None`` leaves that component as it is. ``disk_current_hz`` is the disk's present first elastic
    frequency when the caller already knows it (no modal solve).
    """
    from dataclasses import replace

    disk, blade, params = bd.disk, bd.blade, bd.params
    if disk_target_hz is not None:
        cal = calibrate_modulus(disk, disk_target_hz, 0, backend, current_hz=disk_current_hz)
        disk = cal.component
        params = replace(params, disk_material=replace(params.disk_material, E=cal.E_after))
    if blade_target_hz is not None:
        cal = calibrate_modulus(blade, blade_target_hz, 0, backend)
        blade = cal.component
        params = replace(params, blade_material=replace(params.blade_material, E=cal.E_after))
    return replace(bd, params=params, disk=disk, blade=blade)


@dataclass(frozen=True)
class MaterialCalibration:
    """E and ρ of one homogeneous component calibrated on the tests (paper §5, Table 4).

    ρ comes from the weighed mass where given (ρ' = ρ m_measured / m_model), then E from the matched
    frequency: every eigenvalue scales with E/ρ, so ``E' = E (ρ'/ρ) (f_target / f_model)²``.

    Attributes
    ----------
    component : str
        ``"disk"`` or ``"blade"``.
    target_hz : float
        The test's frequency matched (disk: its first mode; blade: √ of the blades' mean f₁²).
    model_hz : float
        The uncalibrated model's frequency of that mode.
    E_before, E_after : float
        Young's modulus (Pa).
    rho_before, rho_after : float
        Density (kg/m³).
    rho_source : str
        ``"masses"`` (the manifest's ``[masses]``) or ``"nominal"`` (not weighed: ρ kept).
    mass_kg, model_mass_kg : float or None, float
        The weighed mass (None where not given) and the uncalibrated model's.
    """

    component: str
    target_hz: float
    model_hz: float
    E_before: float
    E_after: float
    rho_before: float
    rho_after: float
    rho_source: str
    mass_kg: float | None
    model_mass_kg: float

    @property
    def E_scale(self) -> float:
        """E_after / E_before: the factor on the component's stiffness matrix."""
        return self.E_after / self.E_before

    @property
    def rho_scale(self) -> float:
        """ρ_after / ρ_before: the factor on the component's mass matrix."""
        return self.rho_after / self.rho_before

    def to_dict(self) -> dict:
        return {"target_hz": self.target_hz, "model_hz": self.model_hz, "E_before_pa": self.E_before,
                "E_after_pa": self.E_after, "E_change_pct": 100 * (self.E_scale - 1), "rho_before_kg_m3":
                self.rho_before, "rho_after_kg_m3": self.rho_after, "rho_change_pct": 100 * (self.rho_scale - 1),
                "rho_source": self.rho_source, "mass_kg": self.mass_kg, "model_mass_kg": self.model_mass_kg}


def component_mass(component: Component) -> float:
    """A component's mass (kg): the kinetic energy of a unit x-translation, 1ᵀ M_xx 1 (node-major DOFs)."""
    return float(component.M[0::3, 0::3].sum())


def calibrate_material(component: str, E: float, rho: float, model_hz: float, target_hz: float,
                       model_mass_kg: float, mass_kg: float | None = None) -> MaterialCalibration:
    """E (and ρ, where the component was weighed) that put the model's frequency on ``target_hz``.

    Pure arithmetic on the model's present frequency, with no solve: see :class:`MaterialCalibration`.
    """
    for name, v in (("model_hz", model_hz), ("target_hz", target_hz), ("model_mass_kg", model_mass_kg)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{component}: {name} must be a positive number, got {v!r}")
    if mass_kg is not None and not (math.isfinite(mass_kg) and mass_kg > 0):
        raise ValueError(f"{component}: mass_kg must be a positive mass in kg, got {mass_kg!r}")
    rho_scale = 1.0 if mass_kg is None else mass_kg / model_mass_kg
    E_after = E * rho_scale * (target_hz / model_hz) ** 2
    return MaterialCalibration(component, float(target_hz), float(model_hz), float(E), float(E_after), float(rho),
                               float(rho * rho_scale), "nominal" if mass_kg is None else "masses",
                               None if mass_kg is None else float(mass_kg), float(model_mass_kg))


def scaled_component(component: Component, cal: MaterialCalibration) -> Component:
    """The component with K × E_scale and M × ρ_scale (a homogeneous material: exact), ``meta`` updated."""
    meta = dict(component.meta, E=cal.E_after, rho=cal.rho_after)
    M = component.M if cal.rho_scale == 1 else component.M * cal.rho_scale
    return Component(component.name, component.K * cal.E_scale, M, component.node_ids, component.coords,
                     dict(component.node_sets), meta, component.elements)


def pool_calibrations(cals: list[MaterialCalibration]) -> MaterialCalibration:
    """One calibration of a component from several campaigns' calibrations of it (re-assemblies of one disk).

    E and ρ are the geometric means of the campaigns' (so the pooled eigenvalue scale E/ρ is theirs); the
    target is √ of the mean squared target, the weighed mass the mean where every campaign weighed it.
    """
    if not cals:
        raise ValueError("pool_calibrations: expected at least one calibration")
    first = cals[0]
    if len(cals) == 1:
        return first
    if any(c.component != first.component or c.E_before != first.E_before or c.rho_before != first.rho_before
           for c in cals):
        raise ValueError(f"pool_calibrations: the calibrations are of different components or models "
                         f"({sorted({c.component for c in cals})})")
    masses = [c.mass_kg for c in cals]
    weighed = all(m is not None for m in masses)
    return MaterialCalibration(
        first.component, float(np.sqrt(np.mean([c.target_hz**2 for c in cals]))), first.model_hz, first.E_before,
        float(gmean([c.E_after for c in cals])), first.rho_before, float(gmean([c.rho_after for c in cals])),
        "masses" if weighed else "nominal", float(np.mean(masses)) if weighed else None, first.model_mass_kg)


def apply_calibration(bd, disk: MaterialCalibration | None, blade: MaterialCalibration | None):
    """A ``BladedDisk`` whose disk and blade carry the calibrated E and ρ (``None`` leaves that component)."""
    from dataclasses import replace

    params, new_disk, new_blade = bd.params, bd.disk, bd.blade
    if disk is not None:
        new_disk = scaled_component(bd.disk, disk)
        params = replace(params, disk_material=replace(params.disk_material, E=disk.E_after, rho=disk.rho_after))
    if blade is not None:
        new_blade = scaled_component(bd.blade, blade)
        params = replace(params, blade_material=replace(params.blade_material, E=blade.E_after, rho=blade.rho_after))
    return replace(bd, params=params, disk=new_disk, blade=new_blade)
