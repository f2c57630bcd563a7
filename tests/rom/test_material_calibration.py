"""The paper's material calibration (§5, Table 4): a known modulus and density recovered from a specimen made
with them, by an independent solve of the specimen (not the calibration's own arithmetic)."""

from __future__ import annotations

import numpy as np
import pytest

from rom.calibration import apply_calibration, calibrate_material, component_mass
from rom.hex20 import assemble
from rom.solver import solve_modes


def test_calibration_recovers_a_known_modulus_and_density(coarse_bd):
    mat = coarse_bd.params.blade_material
    blade = coarse_bd.blade
    E_true, rho_true = mat.E * 1.031, mat.rho * 0.996
    K, M = assemble(blade.coords, blade.elements, E_true, mat.nu, rho_true)
    target = solve_modes(K, M, 1).frequencies_hz[0]
    specimen_mass = float(M[0::3, 0::3].sum())
    model_hz = solve_modes(blade.K, blade.M, 1).frequencies_hz[0]
    cal = calibrate_material("blade", mat.E, mat.rho, model_hz, target, component_mass(blade), specimen_mass)
    assert cal.E_after == pytest.approx(E_true, rel=1e-7)
    assert cal.rho_after == pytest.approx(rho_true, rel=1e-12)
    bd = apply_calibration(coarse_bd, None, cal)
    f = solve_modes(bd.blade.K, bd.blade.M, 3).frequencies_hz
    np.testing.assert_allclose(f, solve_modes(K, M, 3).frequencies_hz, rtol=1e-7)
    assert bd.params.blade_material.E == cal.E_after and bd.disk is coarse_bd.disk


def test_without_a_mass_only_the_modulus_moves():
    cal = calibrate_material("disk", 200e9, 7800.0, 1000.0, 1010.0, 1.7)
    assert cal.rho_source == "nominal" and cal.rho_after == 7800.0
    assert cal.E_after == pytest.approx(200e9 * 1.01**2)


@pytest.mark.parametrize("kw, needle", [({"target_hz": -1.0}, "target_hz"), ({"mass_kg": 0.0}, "mass_kg"),
                                        ({"model_hz": float("nan")}, "model_hz")])
def test_bad_values_are_refused_naming_them(kw, needle):
    args = {"model_hz": 1000.0, "target_hz": 1010.0, "mass_kg": None} | kw
    with pytest.raises(ValueError, match=needle):
        calibrate_material("disk", 200e9, 7800.0, args["model_hz"], args["target_hz"], 1.7, args["mass_kg"])


def test_pooled_calibrations_of_re_assemblies_put_the_mean_eigenvalue_on_the_mean_target():
    """Two campaigns of one blade set: the pooled E/ρ is the geometric mean of theirs, so the model's f² lands on
    the geometric mean of the two targets' f² (f² ∝ E/ρ); one campaign is its own pool."""
    from rom.calibration import pool_calibrations

    a = calibrate_material("blade", 210e9, 7850.0, 700.0, 690.0, 0.033, 0.0331)
    b = calibrate_material("blade", 210e9, 7850.0, 700.0, 694.0, 0.033, 0.0329)
    p = pool_calibrations([a, b])
    f2 = 700.0**2 * (p.E_scale / p.rho_scale)
    assert f2 == pytest.approx(np.sqrt(690.0**2 * 694.0**2), rel=1e-12)
    assert p.rho_after == pytest.approx(np.sqrt(a.rho_after * b.rho_after)) and p.rho_source == "masses"
    assert pool_calibrations([a]) is a
    c = calibrate_material("blade", 210e9, 7850.0, 700.0, 690.0, 0.033)
    assert pool_calibrations([a, c]).rho_source == "nominal"
    with pytest.raises(ValueError, match="different components"):
        pool_calibrations([a, calibrate_material("disk", 200e9, 7800.0, 1000.0, 1010.0, 1.7)])
