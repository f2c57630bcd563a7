"""Disk–one-blade ROM (Eqs. 20–22) against the FE reference assembly."""

import numpy as np
import pytest

from ema.mac import mac
from rom.contact import ContactPattern
from rom.fe_assembly import assemble_fe, solve_fe
from rom.rom_assembly import assemble_d1b, solve_d1b
from rom.validation import fe_assembly_mistuned, one_flank_pattern

from . import rom_models

GRID = (3, 7)


def _patterns():
    rng = np.random.default_rng(11)
    L30 = np.zeros(GRID, bool)
    L30.flat[rng.choice(L30.size, 6, replace=False)] = True
    R30 = np.zeros(GRID, bool)
    R30.flat[rng.choice(R30.size, 7, replace=False)] = True
    return {
        "all contact": ContactPattern.full(GRID),
        "~30 % contact": ContactPattern(L30, R30),
        "one flank": one_flank_pattern(GRID, "R"),
        "~70 % random": ContactPattern.random(GRID, 0.7, rng),
    }


PATTERNS = _patterns()


@pytest.fixture(scope="module")
def fe_refs():
    bd = rom_models.bladed_disk()
    out = {(name, 1): solve_fe(assemble_fe(bd, {1: p}), 10) for name, p in PATTERNS.items()}
    out[("~30 % contact", 7)] = solve_fe(assemble_fe(bd, {7: PATTERNS["~30 % contact"]}), 10)
    return out


@pytest.mark.parametrize("formulation", ["exact", "paper"])
@pytest.mark.parametrize("name,slot", [(n, 1) for n in PATTERNS] + [("~30 % contact", 7)])
def test_d1b_first_10_modes_within_0p3_percent_and_mac_0p99(fe_refs, name, slot, formulation):
    fe = fe_refs[(name, slot)]
    rom = solve_d1b(rom_models.disk_cb(), rom_models.blade(), PATTERNS[name], slot, formulation=formulation)
    assert rom.meas_labels == fe.meas_labels
    rel = rom.frequencies_hz / fe.frequencies_hz - 1
    assert np.abs(rel).max() <= 3e-3
    assert rel.min() >= -1e-7  # Rayleigh–Ritz (up to the eigensolver tolerance)
    assert np.diag(mac(fe.meas_shapes, rom.meas_shapes)).min() >= 0.99


def test_paper_and_exact_formulations_agree_and_exact_is_smaller():
    cb, b = rom_models.disk_cb(), rom_models.blade()
    p = PATTERNS["~30 % contact"]
    a_paper = assemble_d1b(cb, b, p, formulation="paper")
    a_exact = assemble_d1b(cb, b, p, formulation="exact")
    n_detached = 3 * int((~p.L).sum() + (~p.R).sum())
    assert a_paper.n - a_exact.n == n_detached
    f_p = solve_d1b(cb, b, p, formulation="paper").frequencies_hz
    f_e = solve_d1b(cb, b, p, formulation="exact").frequencies_hz
    np.testing.assert_allclose(f_e, f_p, rtol=1e-6)


def test_mistuned_d1b_matches_fe_blade_with_scaled_stiffness():
    """A blade with stiffness (1 + δ) K has eigenvalues (1 + δ) ω_i² and the same shapes: Eq. 19 with δ_i = δ."""
    bd = rom_models.bladed_disk()
    p = PATTERNS["~70 % random"]
    fe = solve_fe(fe_assembly_mistuned(bd, {4: p}, np.array([0.015])), 10)
    rom = solve_d1b(rom_models.disk_cb(), rom_models.blade(), p, 4, delta=0.015)
    assert np.abs(rom.frequencies_hz / fe.frequencies_hz - 1).max() <= 3e-3
    assert np.diag(mac(fe.meas_shapes, rom.meas_shapes)).min() >= 0.99


def test_zero_delta_reproduces_tuned_d1b_exactly():
    cb, b = rom_models.disk_cb(), rom_models.blade()
    p = PATTERNS["one flank"]
    a0, a1 = assemble_d1b(cb, b, p), assemble_d1b(cb, b, p, delta=np.zeros(b.m))
    np.testing.assert_array_equal(a0.K, a1.K)
    np.testing.assert_array_equal(a0.M, a1.M)


def test_bad_inputs_give_clear_errors():
    cb, b = rom_models.disk_cb(), rom_models.blade()
    p = PATTERNS["all contact"]
    with pytest.raises(ValueError, match="no contact on either flank"):
        ContactPattern(np.zeros(GRID, bool), np.zeros(GRID, bool))
    with pytest.raises(ValueError, match=r"grid shape \(4, 7\).*expects \(3, 7\)"):
        solve_d1b(cb, b, ContactPattern.full((4, 7)))
    for bad in (0, 19, 2.5):
        with pytest.raises(ValueError, match="slot must be an integer in 1..18"):
            solve_d1b(cb, b, p, bad)
    with pytest.raises(ValueError, match="finite"):
        solve_d1b(cb, b, p, delta=[0.01, np.nan])
    with pytest.raises(ValueError, match="entries"):
        solve_d1b(cb, b, p, delta=np.zeros(b.m + 3))
    with pytest.raises(ValueError, match="formulation"):
        solve_d1b(cb, b, p, formulation="penalty")
