"""The realistic twin's specimen effects (issue 44) against independent references: perturbation theory for the
disk's doublet split, the pressure ranking for re-seating, mass sums for the bolts, the ideal twin unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from lab import specimen
from lab.documents import weighed
from lab.truth import TruthParams, assemble_truth, make_truth_twin, solve_truth
from rom.contact import FLANKS, ContactPattern
from rom.solver import solve_modes


@pytest.fixture(scope="module")
def patterns(coarse_bd):
    rng = np.random.default_rng(3)
    return [ContactPattern.random(coarse_bd.params.grid, 0.6, rng) for _ in range(coarse_bd.n_slots)]


def test_the_ideal_twin_is_the_model_s_own_parts(coarse_bd, patterns):
    twin = make_truth_twin(coarse_bd, patterns, np.random.default_rng(0), TruthParams.ideal())
    assert twin.truth_disk is coarse_bd.disk and twin.contact_scale is None
    assert twin.patterns_of("assembly") == twin.patterns
    assert set(twin.day_factors.values()) == {1.0} and set(twin.materials.values()) == {0.0}


def test_a_sector_scatter_splits_the_doublets_as_first_order_perturbation_predicts(coarse_bd):
    """Degenerate perturbation theory: the split pair's eigenvalues are λ₀ + eig(Φᵀ ΔK Φ) (Φ the tuned pair,
    mass-normalised), an estimate independent of the mistuned disk's direct solve it is checked against."""
    eps = 0.004 * np.random.default_rng(1).standard_normal(coarse_bd.n_slots)
    tuned = coarse_bd.disk
    mistuned = specimen.truth_disk(coarse_bd, 0.0, 0.0, eps)
    t = solve_modes(tuned.K, tuned.M, 6)
    m = solve_modes(mistuned.K, mistuned.M, 6)
    lam0 = (2 * np.pi * t.frequencies_hz) ** 2
    lam = (2 * np.pi * m.frequencies_hz) ** 2
    pair = next(k for k in range(5) if abs(lam0[k + 1] / lam0[k] - 1) < 1e-8)  # the first doublet
    phi = t.shapes[:, pair:pair + 2]
    dK = mistuned.K - tuned.K
    predicted = lam0[pair] + np.linalg.eigvalsh(phi.T @ (dK @ phi))
    split, split_pred = lam[pair + 1] - lam[pair], predicted[1] - predicted[0]
    assert split / lam[pair] > 1e-5  # a real split (tuned: 0)
    assert abs(split - split_pred) < 0.05 * split, (split, split_pred)
    np.testing.assert_allclose(lam[pair:pair + 2], predicted, rtol=2e-5)


def test_the_whole_disk_modulus_offset_scales_every_frequency_by_its_square_root(coarse_bd):
    disk = specimen.truth_disk(coarse_bd, 0.03, -0.01, None)
    f0 = solve_modes(coarse_bd.disk.K, coarse_bd.disk.M, 3).frequencies_hz
    f = solve_modes(disk.K, disk.M, 3).frequencies_hz
    np.testing.assert_allclose(f / f0, np.sqrt(1.03 / 0.99), rtol=1e-8)


def test_reseating_moves_the_stated_share_of_edge_nodes_by_pressure_rank():
    rng = np.random.default_rng(4)
    grid = (5, 9)
    pressure = rng.random((6, 2, *grid))
    pats = [ContactPattern(pressure[j, 0] > 0.5, pressure[j, 1] > 0.5) for j in range(6)]
    seated = specimen.reseated_patterns(pats, pressure, np.random.default_rng(0), 0.2)
    for j, (a, b) in enumerate(zip(pats, seated, strict=True)):
        for k, f in enumerate(FLANKS):
            before, after = a.flank(f), b.flank(f)
            changed = before != after
            assert changed.sum() == round(0.2 * specimen._edge(before).sum())
            p = pressure[j, k]
            if after.sum() > before.sum():  # grown: the new nodes are the detached nodes of highest pressure
                assert p[changed].min() >= p[~before & ~changed].max()
            elif after.sum() < before.sum():
                assert p[changed].max() <= p[before & ~changed].min()


def test_the_contact_stiffness_follows_the_pressure_with_its_exponent():
    rng = np.random.default_rng(2)
    pressure = rng.uniform(1e6, 4e7, (40, 2, 3, 7))
    pats = [ContactPattern(np.ones((3, 7), bool), np.ones((3, 7), bool)) for _ in range(40)]
    scale = specimen.contact_scale(pressure, pats, np.random.default_rng(0), 0.3, 2 / 3)
    ratio = scale / (pressure / pressure.mean(axis=(2, 3), keepdims=True)) ** (2 / 3)
    c = ratio[:, :, 0, 0]
    # one factor per joint and flank
    np.testing.assert_allclose(ratio, np.broadcast_to(c[:, :, None, None], ratio.shape), rtol=1e-12)
    # lognormal with mean 1 and σ_log 0.3: the sample of 80 factors within 4 standard errors
    assert abs(np.log(c).std() - 0.3) < 4 * 0.3 / np.sqrt(2 * 80)
    assert abs(c.mean() - 1) < 4 * np.sqrt(np.exp(0.09) - 1) / np.sqrt(80)


def test_the_bolts_add_their_mass_to_each_mounted_slot(coarse_bd, patterns):
    params = TruthParams(mesh_refinement=0)
    twin = make_truth_twin(coarse_bd, patterns, np.random.default_rng(0), params)
    alone = assemble_truth(twin, [2], with_disk=True)
    bare = specimen.bolt_masses(twin.truth_disk, [], params.bolt_mass_kg, params.bolts_per_slot)
    assert bare.sum() == 0
    blade_m = twin.blades[1].M[0::3, 0::3].sum()
    added = alone.M[0::3, 0::3].sum() - twin.truth_disk.M[0::3, 0::3].sum() - blade_m
    assert added == pytest.approx(params.bolts_per_slot * params.bolt_mass_kg, rel=1e-9)
    # the manifest's [masses] gives what the lab weighs of them, per slot; the ideal twin has none to weigh
    assert weighed(twin)["slot_hardware_kg"] == pytest.approx(added, rel=1e-6)
    ideal = make_truth_twin(coarse_bd, patterns, np.random.default_rng(0), TruthParams.of("ideal"))
    assert "slot_hardware_kg" not in weighed(ideal)


def test_the_realistic_twin_solves_and_its_reseated_assembly_differs(coarse_bd, patterns):
    params = TruthParams(mesh_refinement=0, reseat_edge_share=0.5)
    twin = make_truth_twin(coarse_bd, patterns, np.random.default_rng(0), params)
    f_d1b = solve_truth(assemble_truth(twin, [1], state="d1b"), 4).frequencies_hz
    f_asm = solve_truth(assemble_truth(twin, [1], state="assembly"), 4).frequencies_hz
    assert np.all(np.isfinite(f_d1b)) and not np.allclose(f_d1b, f_asm, rtol=1e-9)
    with pytest.raises(ValueError, match="state"):
        twin.patterns_of("other")
