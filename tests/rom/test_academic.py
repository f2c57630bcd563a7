"""The academic bladed disk: geometry, conformity, physics facts, and the paper's Table 1."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from rom.academic import SLOT_SHARE, AcademicParams, Material, build_bladed_disk, disk_scale_for
from rom.calibration import calibrate_modulus
from rom.solver import nodal_diameters, solve_modes

TABLE1_HZ = np.array([1090.6, 1971.1, 2638.1, 3647.6, 4421.5])
TABLE1_ND = [2, 0, 3, 1, 4]


def _distinct(freqs, tol=1e-4):
    keep = [0] + [i for i in range(1, freqs.size) if freqs[i] / freqs[i - 1] - 1 > tol]
    return np.array(keep)


def test_paper_dimensions():
    p = AcademicParams()
    assert p.n_blades == 18
    assert 2 * p.disk_outer_radius == pytest.approx(0.200)
    assert p.blade_length == pytest.approx(0.1175)
    assert 2 * p.blade_tip_radius == pytest.approx(0.412)
    assert p.grid == (7, 31)


def test_mass_equals_density_times_analytic_volume(coarse_bd):
    p = coarse_bd.params
    assert coarse_bd.disk.mass() == pytest.approx(p.disk_material.rho * p.disk_volume(), rel=1e-3)
    assert coarse_bd.blade.mass() == pytest.approx(p.blade_material.rho * p.blade_volume(), rel=1e-3)


def test_interface_grids_conform_in_every_slot(coarse_bd):
    gaps = [coarse_bd.interface_gap(s) for s in range(1, coarse_bd.n_slots + 1)]
    assert max(gaps) <= 1e-9
    # The grids are distinct nodes with the model's grid shape.
    for s in (1, 18):
        for f in ("L", "R"):
            g = coarse_bd.disk.node_set(f"slot{s}_{f}")
            assert g.shape == (3, 7) and np.unique(g).size == g.size


def test_grid_orientation_rows_axial_columns_radial_outward(coarse_bd):
    X = coarse_bd.blade.coords
    L, R = coarse_bd.blade.node_set("L"), coarse_bd.blade.node_set("R")
    assert np.all(np.diff(X[L][:, :, 2], axis=0) > 0)  # rows: z increases
    assert np.all(np.diff(X[L][:, :, 1], axis=1) > 0)  # columns: radially outward
    assert np.all(X[L][..., 0] < 0) and np.all(X[R][..., 0] > 0)  # L at −x, R at +x


@pytest.mark.parametrize("which", ["disk", "blade"])
def test_free_component_has_exactly_six_rigid_body_modes(coarse_bd, which):
    comp = getattr(coarse_bd, which)
    sol = solve_modes(comp.K, comp.M, 4, max_rigid=8)
    assert sol.n_rigid == 6
    assert sol.frequencies_hz[0] > 100.0


def test_free_disk_nd_pairs_are_degenerate_and_match_table1(coarse_bd):
    d = coarse_bd.disk
    sol = solve_modes(d.K, d.M, 14)
    nd = nodal_diameters(sol.shapes[3 * d.node_set("meas") + 2])
    f = sol.frequencies_hz
    keep = _distinct(f)
    assert list(nd[keep][:5]) == TABLE1_ND
    for k in keep[:5]:
        if nd[k] >= 1:
            assert f[k + 1] / f[k] - 1 < 1e-6, f"ND {nd[k]} pair split by {f[k + 1] / f[k] - 1:.2e}"
    # Table 1 after calibration: one factor rescales every eigenvalue (test below), so f · 1090.6 / f₁; each of the
    # first five within 15 %, the calibrated modulus physical. The default level's: benchmarks/fe_modes.py.
    scale = TABLE1_HZ[0] / f[keep[0]]
    err = f[keep[:5]] * scale / TABLE1_HZ - 1
    assert np.all(np.abs(err) < 0.15), err
    assert 150e9 < d.meta["E"] * scale**2 < 250e9


def test_calibration_hits_target_and_scales_all_modes(coarse_bd):
    cal = calibrate_modulus(coarse_bd.blade, 900.0)
    sol = solve_modes(cal.component.K, cal.component.M, 3)
    assert sol.frequencies_hz[0] == pytest.approx(900.0, rel=1e-8)
    before = solve_modes(coarse_bd.blade.K, coarse_bd.blade.M, 3).frequencies_hz
    np.testing.assert_allclose(sol.frequencies_hz, before * np.sqrt(cal.scale), rtol=1e-8)


BAD = [
    (dict(n_blades=1), "n_blades"),
    (dict(disk_thickness=0.0), "disk_thickness"),
    (dict(slot_width=-0.01), "slot_width"),
    (dict(bore_radius=0.095), "bore_radius"),
    (dict(slot_width=0.05), "slot_width"),  # wider than the slot pitch: roots overlap
    (dict(n_blades=60), "slot_width"),  # 60 slots of 16 mm do not fit on the rim
    (dict(grid=(7, 30)), "grid"),  # even column count cannot take every node of quadratic elements
    (dict(grid=(1, 31)), "grid"),
    (dict(level="ultra"), "level"),
    (dict(blade_thickness=0.02), "blade_thickness"),
    (dict(blade_tip_radius=0.101), "blade_tip_radius"),
    (dict(disk_material=Material(E=-1.0, rho=7800.0)), "disk_material.E"),
]


@pytest.mark.parametrize(("change", "name"), BAD)
def test_bad_parameters_raise_value_error_naming_parameter(change, name):
    with pytest.raises(ValueError, match=name.replace(".", r"\.")):
        dataclasses.replace(AcademicParams(level="coarse"), **change)


def test_calibration_with_known_frequency_skips_the_solve_and_agrees(coarse_bd):
    solved = calibrate_modulus(coarse_bd.blade, 900.0)
    known = calibrate_modulus(coarse_bd.blade, 900.0, current_hz=solved.frequency_before_hz)
    assert known.E_after == pytest.approx(solved.E_after, rel=1e-12)
    with pytest.raises(ValueError, match="current_hz"):
        calibrate_modulus(coarse_bd.blade, 900.0, current_hz=-1.0)


# ------------------------------------------------------------------ disks of many blades (issue 49)
def test_up_to_24_blades_keep_the_papers_disk():
    for n in (2, 18, 24):
        assert disk_scale_for(n) == 1.0
        assert AcademicParams.for_blades(n) == AcademicParams(n_blades=n)


@pytest.mark.parametrize("n", [25, 36, 48, 80])
def test_a_disk_of_many_blades_grows_until_its_slots_take_the_set_share_of_the_pitch(n):
    p = AcademicParams.for_blades(n, level="coarse", grid=(3, 7))
    paper = AcademicParams()
    pitch = 2 * p.slot_bottom_radius * np.sin(np.pi / n)          # chord between slot centres at the slot bottom
    assert p.slot_width / pitch == pytest.approx(SLOT_SHARE, rel=1e-12)
    s = p.slot_bottom_radius / paper.slot_bottom_radius
    assert s == pytest.approx(disk_scale_for(n), rel=1e-12) and s > 1.0
    assert p.bore_radius == pytest.approx(s * paper.bore_radius, rel=1e-12)
    # the same slots and blade: slot depth, blade length, root width, thickness, chord
    depth = p.disk_outer_radius - p.slot_bottom_radius
    assert depth == pytest.approx(paper.disk_outer_radius - paper.slot_bottom_radius, rel=1e-12)
    assert p.blade_length == pytest.approx(paper.blade_length, rel=1e-12)
    assert (p.slot_width, p.blade_thickness, p.disk_thickness) == (paper.slot_width, paper.blade_thickness,
                                                                   paper.disk_thickness)


def test_the_48_blade_disk_is_built_conforming_with_the_papers_blade():
    bd = build_bladed_disk(AcademicParams.for_blades(48, level="coarse", grid=(3, 7)))
    paper_blade = build_bladed_disk(AcademicParams(level="coarse", grid=(3, 7))).blade
    assert bd.n_slots == 48
    assert max(bd.interface_gap(s) for s in (1, 17, 48)) <= 1e-9
    p = bd.params
    assert bd.disk.mass() == pytest.approx(p.disk_material.rho * p.disk_volume(), rel=1e-3)
    # the same blade but for its root's bottom arc, flatter on the larger slot-bottom radius
    assert bd.blade.mass() == pytest.approx(paper_blade.mass(), rel=5e-3)    # measured 2.3e-3
    assert bd.blade.mass() == pytest.approx(p.blade_material.rho * p.blade_volume(), rel=1e-3)


def test_a_manifest_reads_back_the_disk_it_was_simulated_on(tmp_path):
    from bladetwin.campaign import CampaignError
    from bladetwin.model import model_params
    from lab.campaign import CampaignSpec

    def campaign(**model):
        return SimpleNamespace(model={"family": "academic", "level": "coarse", "n_blades": 36, "grid": [3, 7],
                                      **model}, root=tmp_path, n_blades=36, grid=(3, 7))

    got = model_params(campaign(disk_scale=disk_scale_for(36)))
    assert got == AcademicParams.for_blades(36, level="coarse", grid=(3, 7))
    assert got == CampaignSpec(n_blades=36, grid=(3, 7), level="coarse").model_params()   # what the rig simulates
    # without the key, the paper's disk, which cannot hold 36 slots: one line naming the manifest
    with pytest.raises(CampaignError, match=r"campaign\.toml \[model\]: slot_width"):
        model_params(campaign())
    with pytest.raises(CampaignError, match="disk_scale"):
        model_params(campaign(disk_scale=-1.0))
