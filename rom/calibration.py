"""Calibration of a component's Young's modulus to a measured frequency (paper §5, Table 4).

For a homogeneous linear-elastic component, ``K`` is proportional to ``E`` while ``M`` does not depend on
it, so every eigenvalue scales with ``E``: ``f_i(E') = f_i(E) √(E'/E)``. Matching mode ``i`` to a target
frequency therefore needs one modal solve and a rescaling, with no iteration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .component import Component
from .solver import solve_modes

__all__ = ["Calibration", "calibrate_modulus", "calibrate_bladed_disk"]


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
