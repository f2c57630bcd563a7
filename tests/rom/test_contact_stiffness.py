"""Finite contact stiffness in the Rubin blade (rom.contact_stiffness) against the full FE with explicit springs."""

import dataclasses

import numpy as np
import pytest

from lab.truth import TruthParams, assemble_truth, make_truth_twin, solve_truth
from rom.contact import ContactPattern
from rom.contact_stiffness import (
    ContactStiffness,
    blade_compliance_parts,
    flank_normal,
    interface_compliance,
    tributary_areas,
    with_contact_stiffness,
)
from rom.rom_assembly import solve_d1b

from . import rom_models

#: The ideal twin (the model's own parts) without blade variation: these tests isolate the contact springs.
NOMINAL = dataclasses.replace(TruthParams.ideal(), thickness_spread=0, chord_spread=0, span_spread=0,
                              modulus_spread=0, fillet_fraction=0)


@pytest.fixture(scope="module")
def pattern():
    return ContactPattern.random(rom_models.COARSE.grid, 0.6, np.random.default_rng(5))


def test_areas_tile_the_flank_and_the_normal_is_the_blade_local_x():
    bd = rom_models.bladed_disk()
    for f, sign in (("L", -1.0), ("R", 1.0)):
        g = bd.blade.coords[bd.blade.node_set(f)]
        a = tributary_areas(g)
        span = np.linalg.norm(g[-1, 0] - g[0, 0]) * np.sum(np.linalg.norm(np.diff(g[0], axis=0), axis=1))
        assert a.shape == g.shape[:2] and np.all(a > 0)
        assert a.sum() == pytest.approx(span, rel=1e-12)  # the tributary areas add up to the grid's area
        n = flank_normal(g)
        assert abs(n[0]) == pytest.approx(1.0, abs=1e-12) and np.sign(n[0]) in (sign, -sign)


@pytest.mark.parametrize("k", [1e14, 3e13])
def test_the_rom_on_springs_matches_the_fe_assembly_with_springs(pattern, k):
    """The d1b ROM with G_bb + C (series springs) against the truth twin's FE with explicit springs (nominal blades).

    The rigid-tie ROM misses the same FE by several times more: the springs, not the reduction, close the gap.
    """
    bd = rom_models.bladed_disk()
    patterns = [pattern] * bd.n_slots
    twin = make_truth_twin(bd, patterns, np.random.default_rng(0),
                           dataclasses.replace(NOMINAL, contact_stiffness_n_per_m3=k))
    fe = solve_truth(assemble_truth(twin, [1]), 10).frequencies_hz
    disk, blade = rom_models.disk_cb(), rom_models.blade(keep_basis=False)
    stiff = ContactStiffness(k, NOMINAL.tangential_ratio * k)
    sprung = with_contact_stiffness(blade, interface_compliance(blade_compliance_parts(bd.blade), stiff))
    rom_k = solve_d1b(disk, sprung, pattern, n_modes=10).frequencies_hz
    rigid = solve_d1b(disk, blade, pattern, n_modes=10).frequencies_hz
    err_k, err_rigid = np.abs(rom_k / fe - 1), np.abs(rigid / fe - 1)
    assert err_k.max() < 5e-4, err_k
    assert err_rigid.max() > 4 * err_k.max(), (err_rigid, err_k)


def test_very_stiff_springs_give_back_the_rigid_ties(pattern):
    bd = rom_models.bladed_disk()
    disk, blade = rom_models.disk_cb(), rom_models.blade(keep_basis=False)
    stiff = ContactStiffness(1e22, 1e22)
    sprung = with_contact_stiffness(blade, interface_compliance(blade_compliance_parts(bd.blade), stiff))
    f = solve_d1b(disk, sprung, pattern, n_modes=8).frequencies_hz
    f0 = solve_d1b(disk, blade, pattern, n_modes=8).frequencies_hz
    assert np.max(np.abs(f / f0 - 1)) < 1e-7
    assert sprung.omega2 == pytest.approx(blade.omega2)  # the free modes (Eq. 19) are untouched


def test_bad_stiffness_and_compliance_are_refused():
    with pytest.raises(ValueError, match="normal_n_per_m3 must be a positive number"):
        ContactStiffness(-1.0, 1e14)
    with pytest.raises(ValueError, match="tangential_n_per_m3"):
        ContactStiffness(1e14, float("nan"))
    blade = rom_models.blade(keep_basis=False)
    with pytest.raises(ValueError, match="compliance must have shape"):
        with_contact_stiffness(blade, np.zeros((3, 3, 3)))
    with pytest.raises(ValueError, match="collinear"):
        flank_normal(np.c_[np.arange(4.0), np.zeros(4), np.zeros(4)].reshape(2, 2, 3))
