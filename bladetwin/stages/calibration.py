"""The paper's material calibration (§5, Table 4) as a stage: E and ρ of the disk and the blades on the tests.

* The disk's E on its first measured frequency; its ρ from its weighed mass (``[masses] disk_kg``).
* The blades' E on the mean of their squared first frequencies (the eigenvalue the blade ROM's mistuning
  perturbs with zero mean, Eq. 19); their ρ from the mean weighed blade (``[masses] blade_kg``).

The stage computes the calibration; ``bladetwin run`` applies it to the FE model before any reduction
(:func:`rom.calibration.apply_calibration`), so every ROM downstream is the calibrated one.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from rom.calibration import MaterialCalibration, calibrate_material, component_mass
from rom.solver import solve_modes

__all__ = ["CalibrationResult", "calibrate", "PLAUSIBLE_CHANGE"]

#: A calibration that moves a frequency by more than this (relative) is not a material's uncertainty but a
#: wrong pairing or a wrong model: it is refused with a warning and the model kept (E would move by 44 %).
PLAUSIBLE_CHANGE = 0.2


@dataclass(frozen=True)
class CalibrationResult:
    """The calibration of a run: each component's, or why it was not calibrated.

    Attributes
    ----------
    disk, blade : MaterialCalibration or None
    notes : tuple of str
        Why a component kept the model's material (no test, an imported model, an implausible change).
    disk_test_hz, disk_model_hz : ndarray, shapes (m,), (m + 2,)
        The free disk's measured modes and the uncalibrated model's first elastic modes (Hz).
    blade_test_hz, blade_model_hz : ndarray, shapes (k,), (k + 2,)
        √ of the blades' mean f² per tracked mode, and the uncalibrated model blade's first elastic modes (Hz).
    """

    disk: MaterialCalibration | None
    blade: MaterialCalibration | None
    notes: tuple[str, ...] = ()
    disk_test_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    disk_model_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    blade_test_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    blade_model_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict:
        return {"disk": None if self.disk is None else self.disk.to_dict(),
                "blade": None if self.blade is None else self.blade.to_dict(), "notes": list(self.notes)}

    def mode_rows(self) -> list[dict]:
        """Each measured mode against the model before and after calibration, paired by nearest frequency after.

        Rows ``{"component", "mode", "test_hz", "before_hz", "after_hz", "before_pct", "after_pct"}`` (errors in
        % of the test; the calibrated frequencies are the uncalibrated ones × √(E'/E · ρ/ρ'), exact for a
        homogeneous component).
        """
        rows = []
        for name, test, model, cal in (("blade", self.blade_test_hz, self.blade_model_hz, self.blade),
                                       ("disk", self.disk_test_hz, self.disk_model_hz, self.disk)):
            factor = 1.0 if cal is None else float(np.sqrt(cal.E_scale / cal.rho_scale))
            for k, f in enumerate(np.asarray(test, dtype=np.float64)):
                if not np.isfinite(f) or not len(model):
                    continue
                after = np.asarray(model) * factor
                i = int(np.argmin(np.abs(after - f)))
                rows.append({"component": name, "mode": k + 1, "test_hz": float(f), "before_hz": float(model[i]),
                             "after_hz": float(after[i]), "before_pct": float(100 * (model[i] / f - 1)),
                             "after_pct": float(100 * (after[i] / f - 1))})
        return rows


def _first_modes_hz(component, n: int) -> np.ndarray:
    return np.asarray(solve_modes(component.K, component.M, n).frequencies_hz, dtype=np.float64)


def _one(name: str, component, params, target_hz: float | None, mass_kg: float | None,
         notes: list[str], model_hz: float) -> MaterialCalibration | None:
    if target_hz is None or not np.isfinite(target_hz):
        notes.append(f"{name}: no measured first frequency; the model's E and ρ are kept")
        return None
    material = getattr(params, f"{name}_material", None)
    if material is None or "E" not in component.meta:
        notes.append(f"{name}: the FE model is not one homogeneous material (imported); E and ρ are kept")
        return None
    cal = calibrate_material(name, material.E, material.rho, model_hz, float(target_hz), component_mass(component),
                             mass_kg)
    if abs(target_hz / model_hz - 1) > PLAUSIBLE_CHANGE:
        warnings.warn(f"calibration: the {name}'s first measured frequency {target_hz:.1f} Hz is "
                      f"{100 * (target_hz / model_hz - 1):+.1f} % from the model's {model_hz:.1f} Hz; more than a "
                      "material's uncertainty, so the model's E and ρ are kept (check the test and the model)",
                      UserWarning, stacklevel=2)
        notes.append(f"{name}: implausible change refused")
        return None
    return cal


def calibrate(bd, campaign, blades, disk=None) -> CalibrationResult:
    """Calibrate the disk and the blade of ``bd`` on the campaign's tests (paper §5).

    Parameters
    ----------
    bd : rom.academic.BladedDisk
        The uncalibrated model.
    campaign : bladetwin.campaign.Campaign
        Its ``masses`` give ρ where the components were weighed.
    blades : bladetwin.stages.measured.BladeTests
        The free blades' EMA (tracked frequencies, Hz, shape (n_blades, k)).
    disk : bladetwin.stages.measured.TestFit, optional
        The free disk's EMA; without it the disk keeps the model's material.
    """
    notes: list[str] = []
    masses = campaign.masses
    F = np.asarray(blades.frequencies_hz, dtype=np.float64)
    blade_test = np.sqrt(np.nanmean(F**2, axis=0)) if F.size else np.zeros(0)
    blade_target = float(blade_test[0]) if blade_test.size and np.isfinite(blade_test[0]) else None
    blade_mass = masses.get("blade_kg")
    blade_mass = None if blade_mass is None else float(np.mean(blade_mass))
    disk_test = np.sort(np.asarray(disk.model.frequencies_hz, dtype=np.float64)) if disk is not None else np.zeros(0)
    disk_target = float(disk_test[0]) if disk_test.size else None
    blade_model = _first_modes_hz(bd.blade, blade_test.size + 2)
    disk_model = _first_modes_hz(bd.disk, disk_test.size + 2) if disk_test.size else np.zeros(0)
    # The disk's first measured mode is matched with the model's nearest mode, not its first: a hammer and one
    # axial point per sector miss some modes (a 4-blade disk's first doublet has its nodal lines through every
    # measured point), and a material's error moves a frequency by far less than the modes' spacing.
    disk_model_hz = float(disk_model[np.argmin(np.abs(disk_model - disk_target))]) if disk_model.size else np.nan
    disk_cal = _one("disk", bd.disk, bd.params, disk_target, masses.get("disk_kg"), notes, disk_model_hz)
    blade_cal = _one("blade", bd.blade, bd.params, blade_target, blade_mass, notes, float(blade_model[0]))
    return CalibrationResult(disk_cal, blade_cal, tuple(notes), disk_test, disk_model, blade_test, blade_model)
