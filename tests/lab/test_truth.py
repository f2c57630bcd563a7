"""The truth twin: contact springs against exact ties, FE-level blade variation, conformity, determinism."""

import dataclasses

import numpy as np
import pytest

from lab.truth import TruthParams, assemble_truth, make_truth_twin, solve_truth
from rom.contact import ContactPattern
from rom.fe_assembly import assemble_fe, solve_fe
from rom.solver import solve_modes

#: The ideal twin (the model's own parts) without blade variation: these tests isolate the contact springs.
NOMINAL = dataclasses.replace(TruthParams.ideal(), thickness_spread=0, chord_spread=0, span_spread=0,
                              modulus_spread=0, fillet_fraction=0)


@pytest.fixture(scope="module")
def patterns(coarse_bd):
    rng = np.random.default_rng(3)
    return [ContactPattern.random(coarse_bd.params.grid, 0.6, rng) for _ in range(coarse_bd.n_slots)]


def test_stiff_springs_converge_to_the_tied_fe_assembly_from_below(coarse_bd, patterns):
    """Springs → ∞ approach the exact ties of ``rom`` (an independent assembly); finite springs only lower ω."""
    tied = solve_fe(assemble_fe(coarse_bd, {2: patterns[1]}), 8).frequencies_hz
    errors = []
    for k in (5e13, 5e15, 5e17):
        twin = make_truth_twin(coarse_bd, patterns, np.random.default_rng(0),
                               dataclasses.replace(NOMINAL, contact_stiffness_n_per_m3=k))
        f = solve_truth(assemble_truth(twin, [2]), 8).frequencies_hz
        assert np.all(f <= tied * (1 + 1e-9))  # a spring is softer than a tie (Rayleigh's monotonicity)
        errors.append(np.max(np.abs(f / tied - 1)))
    assert errors[0] > errors[1] > errors[2] and errors[2] < 1e-5, errors


def test_nominal_blades_are_the_rom_blade_and_varied_roots_conform(coarse_bd, patterns):
    twin = make_truth_twin(coarse_bd, patterns, np.random.default_rng(0), NOMINAL)
    assert (twin.blades[0].K != coarse_bd.blade.K).nnz == 0
    varied = make_truth_twin(coarse_bd, patterns, np.random.default_rng(0), TruthParams.ideal())
    for s, blade in enumerate(varied.blades, start=1):
        for f in ("L", "R"):
            grid = blade.node_set(f)
            np.testing.assert_array_equal(blade.coords[grid], coarse_bd.blade.coords[grid])
        assert blade.name == f"blade{s}"


def test_blade_variation_looks_like_paper_table2(coarse_bd, patterns):
    """Deltas of tenths of a percent to ~2 %, and one mode family where the fillet blades stand apart."""
    twin = make_truth_twin(coarse_bd, patterns, np.random.default_rng(11), TruthParams.ideal())
    f = np.array([solve_modes(b.K, b.M, 6).frequencies_hz for b in twin.blades])
    lam = f**2
    delta = 100 * (lam - lam.mean(0)) / lam.mean(0)
    fillet = np.array([v.fillet for v in twin.variations])
    assert 0 < fillet.sum() < fillet.size
    plain = delta[~fillet]
    spread = plain.std(axis=0)
    assert np.all((spread > 0.1) & (spread < 2.0)), spread
    gap = delta[fillet].mean(axis=0) - plain.mean(axis=0)
    assert np.max(np.abs(gap) / spread) > 4, (gap, spread)


def test_same_seed_same_twin(coarse_bd, patterns):
    a = make_truth_twin(coarse_bd, patterns, np.random.default_rng(5), TruthParams.ideal())
    b = make_truth_twin(coarse_bd, patterns, np.random.default_rng(5), TruthParams.ideal())
    assert a.variations == b.variations
    c = make_truth_twin(coarse_bd, patterns, np.random.default_rng(6), TruthParams.ideal())
    assert a.variations != c.variations


def test_bad_truth_inputs(coarse_bd, patterns):
    with pytest.raises(ValueError, match="one true pattern per slot"):
        make_truth_twin(coarse_bd, patterns[:3], np.random.default_rng(0))
    with pytest.raises(ValueError, match="contact_stiffness"):
        make_truth_twin(coarse_bd, patterns, np.random.default_rng(0), TruthParams(contact_stiffness_n_per_m3=-1))


def test_canonical_degenerate_removes_the_solver_basis_of_a_double_mode():
    """A double mode in two different bases (as two solver runs may return it) becomes the same modes."""
    from lab.rig import canonical_degenerate
    from rom.fe_assembly import AssemblyModes

    rng = np.random.default_rng(4)
    shapes = rng.standard_normal((8, 4))
    f = np.array([100.0, 250.0, 250.0 * (1 + 1e-10), 400.0])
    out = []
    for angle in (0.3, 2.1):
        c, s = np.cos(angle), np.sin(angle)
        rot = shapes.copy()
        rot[:, 1:3] = shapes[:, 1:3] @ np.array([[c, -s], [s, c]])
        order = [0, 2, 1, 3] if angle > 1 else [0, 1, 2, 3]  # the solver may also swap the pair
        m = AssemblyModes(f[order], rot[:, order], [("x", 0, k, 1) for k in range(8)],
                          rigid_shapes=np.zeros((8, 0)), blade_energy=np.array([0.1, 0.5, 0.5, 0.9]))
        out.append(canonical_degenerate(m, [0]))
    np.testing.assert_allclose(out[0].meas_shapes, out[1].meas_shapes, atol=1e-12)
    np.testing.assert_allclose(out[0].frequencies_hz, out[1].frequencies_hz, rtol=1e-15)
    # the hammer (row 0) excites one combination only; the modes outside the group are untouched up to sign
    assert abs(out[0].meas_shapes[0, 2]) < 1e-12 < abs(out[0].meas_shapes[0, 1])
    np.testing.assert_allclose(np.abs(out[0].meas_shapes[:, [0, 3]]), np.abs(shapes[:, [0, 3]]))


def test_parallel_truth_solves_equal_one_by_one(coarse_bd, patterns):
    """The campaign's forked d1b solves give exactly what the same solves give one after the other."""
    from lab.campaign import solve_parallel

    twin = make_truth_twin(coarse_bd, patterns, np.random.default_rng(5), TruthParams.ideal())
    jobs = [([s], True, 8) for s in (1, 2, 3)]
    seq = solve_parallel(twin, jobs, workers=1)
    par = solve_parallel(twin, jobs, workers=2)
    for (la, a), (lb, b) in zip(seq, par, strict=True):
        assert la == lb
        np.testing.assert_array_equal(a.frequencies_hz, b.frequencies_hz)
        np.testing.assert_array_equal(a.meas_shapes, b.meas_shapes)
