"""True contact patterns (lab.patterns): determinism, fraction ranges, validity, similarity between joints."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from lab.patterns import PressureParams, flank_coordinates, simulate_pressure
from rom.academic import AcademicParams
from rom.contact import ContactPattern

GRIDS = [(3, 7), (7, 31), (5, 11)]


def academic_grid(rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) node coordinates of an academic flank from the geometry alone: axial ±t/2, radial along the wall."""
    p = AcademicParams()
    y_bot, y_top = p.wall_y_range
    t = p.disk_thickness
    return np.meshgrid(np.linspace(-t / 2, t / 2, rows), np.linspace(y_bot, y_top, cols), indexing="ij")


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def mean_pairwise_iou(grids: np.ndarray) -> float:
    return float(np.mean([iou(a, b) for a, b in itertools.combinations(grids, 2)]))


def test_flank_coordinates_follow_the_academic_geometry(coarse_bd):
    u, v = flank_coordinates(coarse_bd)
    p = coarse_bd.params
    assert u.shape == v.shape == p.grid == (3, 7)
    assert u.dtype == v.dtype == np.float64
    # u: axial, varies along the rows only, from −t/2 to +t/2; v: radial, along the columns, slot bottom to rim.
    u_ref, v_ref = academic_grid(*p.grid)
    np.testing.assert_allclose(u, u_ref, atol=1e-12)
    np.testing.assert_allclose(v, v_ref, atol=1e-12)
    # Both flanks share the layout: the R nodes have the same (y, z), mirrored in x.
    XR = coarse_bd.blade.coords[coarse_bd.blade.node_set("R")]
    np.testing.assert_allclose(XR[..., 2], u, atol=1e-12)
    np.testing.assert_allclose(XR[..., 1], v, atol=1e-12)


def test_same_seed_same_truth_other_seed_differs():
    u, v = academic_grid(5, 11)
    a = simulate_pressure(u, v, 6, np.random.default_rng(7))
    b = simulate_pressure(u, v, 6, np.random.default_rng(7))
    c = simulate_pressure(u, v, 6, np.random.default_rng(8))
    assert np.array_equal(a.L, b.L) and np.array_equal(a.R, b.R)
    assert np.array_equal(a.threshold, b.threshold)
    pts = np.random.default_rng(0).uniform(-1, 1, (2, 50)) * 2e-3 + np.array([[0.0], [0.094]])
    assert np.array_equal(a.pressure(3, "R", *pts), b.pressure(3, "R", *pts))
    assert not (np.array_equal(a.L, c.L) and np.array_equal(a.R, c.R))
    assert not np.allclose(a.pressure(3, "R", *pts), c.pressure(3, "R", *pts))


def test_first_joints_do_not_change_when_more_are_drawn():
    u, v = academic_grid(3, 7)
    few = simulate_pressure(u, v, 2, np.random.default_rng(3))
    many = simulate_pressure(u, v, 18, np.random.default_rng(3))
    assert np.array_equal(few.L, many.L[:2]) and np.array_equal(few.R, many.R[:2])


@pytest.mark.parametrize("grid", GRIDS)
@pytest.mark.parametrize("n_joints", [2, 6, 18])
def test_fractions_in_range_and_every_joint_a_valid_pattern(grid, n_joints):
    u, v = academic_grid(*grid)
    lo, hi = PressureParams().fraction_range
    assert (lo, hi) == (0.30, 0.85)
    for seed in range(3):
        truth = simulate_pressure(u, v, n_joints, np.random.default_rng(seed))
        assert truth.L.shape == truth.R.shape == (n_joints, *grid)
        frac = np.stack([truth.L.mean(axis=(1, 2)), truth.R.mean(axis=(1, 2))], axis=1)
        assert ((frac >= lo) & (frac <= hi)).all(), frac
        pats = truth.patterns()
        assert len(pats) == n_joints
        for k, pat in enumerate(pats):
            assert isinstance(pat, ContactPattern)
            assert np.array_equal(pat.L, truth.L[k]) and np.array_equal(pat.R, truth.R[k])
        # The grids are the pressure field thresholded at the nodes.
        j = 1 + seed % n_joints
        for k, flank in enumerate("LR"):
            grids = truth.L if flank == "L" else truth.R
            assert np.array_equal(grids[j - 1], truth.pressure(j, flank, u, v) > truth.threshold[j - 1, k])


def test_fractions_spread_over_the_range():
    u, v = academic_grid(7, 31)
    truth = simulate_pressure(u, v, 18, np.random.default_rng(11))
    f = truth.fractions.ravel()
    assert f.min() < 0.45 and f.max() > 0.70  # not all squeezed in the middle of 30–85 %


def test_custom_fraction_range_is_honoured():
    u, v = academic_grid(7, 31)
    params = PressureParams(fraction_range=(0.5, 0.6))
    truth = simulate_pressure(u, v, 6, np.random.default_rng(1), params)
    assert ((truth.fractions >= 0.5) & (truth.fractions <= 0.6)).all()


@pytest.mark.parametrize("grid", [(7, 31), (5, 11)])
def test_joints_are_similar_but_not_identical(grid):
    u, v = academic_grid(*grid)
    rng_ref = np.random.default_rng(99)
    for seed in range(3):
        truth = simulate_pressure(u, v, 18, np.random.default_rng(seed))
        for grids in (truth.L, truth.R):
            same_side = mean_pairwise_iou(grids)
            # Reference: independent random grids with exactly the same node counts.
            shuffled = np.stack([rng_ref.permutation(g.ravel()).reshape(g.shape) for g in grids])
            independent = mean_pairwise_iou(shuffled)
            assert same_side > independent + 0.12, (same_side, independent)
            assert same_side < 0.95
            # Coarse grids may repeat a pattern by chance; a copied shape would repeat it everywhere.
            identical = [np.array_equal(a, b) for a, b in itertools.combinations(grids, 2)]
            assert np.mean(identical) < 0.05


def test_pressure_is_a_smooth_positive_field_beyond_the_nodes():
    u, v = academic_grid(7, 31)
    truth = simulate_pressure(u, v, 2, np.random.default_rng(5))
    # Between nodes the field interpolates: at cell centres it lies within the range of the 4 corners,
    # widened by a small curvature allowance.
    p = truth.pressure(2, "L", u, v)
    uc, vc = 0.5 * (u[1:, 1:] + u[:-1, :-1]), 0.5 * (v[1:, 1:] + v[:-1, :-1])
    pc = truth.pressure(2, "L", uc, vc)
    corners = np.stack([p[1:, 1:], p[:-1, :-1], p[1:, :-1], p[:-1, 1:]])
    span = corners.max(0) - corners.min(0) + 0.02 * p.max()
    assert (pc >= corners.min(0) - span).all() and (pc <= corners.max(0) + span).all()
    assert (truth.pressure(1, "R", u + 1e-3, v) > 0).all()


def test_lattice_evaluation_equals_pointwise():
    u, v = academic_grid(7, 31)
    truth = simulate_pressure(u, v, 3, np.random.default_rng(2))
    origin, row_step, col_step, shape = (u[0, 0] - 5e-4, v[0, 0] + 1e-4), (2.0e-5, 3e-7), (-4e-7, 2.2e-5), (40, 57)
    r, c = np.arange(shape[0])[:, None], np.arange(shape[1])[None, :]
    uu = origin[0] + r * row_step[0] + c * col_step[0]
    vv = origin[1] + r * row_step[1] + c * col_step[1]
    for joint, flank in [(1, "L"), (3, "R")]:
        fast = truth.pressure_on_lattice(joint, flank, origin, row_step, col_step, shape)
        np.testing.assert_allclose(fast, truth.pressure(joint, flank, uu, vv), rtol=1e-10)


def test_tiny_grid_still_gives_valid_patterns():
    u, v = academic_grid(2, 3)
    truth = simulate_pressure(u, v, 4, np.random.default_rng(0))
    assert len(truth.patterns()) == 4


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(fraction_range=(0.0, 0.5)), "fraction_range"),
        (dict(fraction_range=(0.6, 0.5)), "fraction_range"),
        (dict(length_scale=0.0), "length_scale"),
        (dict(island_radius=(0.2, 0.1)), "island_radius"),
    ],
)
def test_bad_params_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PressureParams(**kwargs)


def test_bad_inputs_are_named():
    u, v = academic_grid(3, 7)
    with pytest.raises(ValueError, match="n_joints"):
        simulate_pressure(u, v, 0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="same shape"):
        simulate_pressure(u, v[:, :-1], 2, np.random.default_rng(0))
    truth = simulate_pressure(u, v, 2, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"joint must be an integer in 1\.\.2"):
        truth.pressure(3, "L", u, v)
    with pytest.raises(ValueError, match="flank"):
        truth.contact_threshold(1, "X")


ROUGH = PressureParams.of("realistic")


def test_ideal_generator_is_the_plain_one_and_roughness_is_off_there():
    assert PressureParams.of("ideal") == PressureParams() and PressureParams().roughness == 0
    u, v = academic_grid(7, 31)
    a = simulate_pressure(u, v, 4, np.random.default_rng(5))
    b = simulate_pressure(u, v, 4, np.random.default_rng(5), PressureParams.of("ideal"))
    assert np.array_equal(a.L, b.L) and np.array_equal(a.R, b.R)
    with pytest.raises(ValueError, match="realism"):
        PressureParams.of("rough")


def test_roughness_adds_a_field_of_its_stated_spread_and_short_correlation():
    """z with roughness minus z without it is the roughness field: a unit-variance field times a_r, whose
    correlation between points one correlation length apart is exp(-1/2) (the squared-exponential kernel)."""
    from dataclasses import replace

    u, v = academic_grid(7, 31)
    truth = simulate_pressure(u, v, 6, np.random.default_rng(3), ROUGH)
    xi, eta = np.meshgrid(np.linspace(-0.5, 0.5, 120), np.linspace(-0.5, 0.5, 120), indexing="ij")
    diffs = []
    for pair in truth.fields:
        for f in pair:
            diffs.append(f(xi, eta) - replace(f, roughness=None)(xi, eta))
    d = np.stack(diffs)
    # 12 independent 64-feature draws: the pooled spread is a_r within sampling error (~ 6 %)
    assert abs(d.std() / ROUGH.roughness - 1) < 0.15
    ell = ROUGH.roughness_length_scale
    step = 1.0 / 119
    lag = round(ell / step)
    rho = np.mean(d[:, lag:, :] * d[:, :-lag, :]) / np.mean(d * d)
    assert abs(rho - np.exp(-0.5 * (lag * step / ell) ** 2)) < 0.1


@pytest.mark.parametrize("grid", GRIDS)
def test_rough_patterns_stay_valid_in_their_range_and_agree_with_the_film_lattice(grid):
    u, v = academic_grid(*grid)
    lo, hi = ROUGH.fraction_range
    n = grid[0] * grid[1]
    for seed in range(4):
        truth = simulate_pressure(u, v, 5, np.random.default_rng(seed), ROUGH)
        f = truth.fractions
        assert (f >= lo - 1.0 / n - 1e-12).all() and (f <= hi + 1.0 / n + 1e-12).all()
        for p in truth.patterns():
            assert isinstance(p, ContactPattern)
    origin, row_step, col_step, shape = (u[0, 0], v[0, 0]), (1.0e-5, 0.0), (0.0, 1.0e-5), (30, 40)
    r, c = np.arange(shape[0])[:, None], np.arange(shape[1])[None, :]
    uu, vv = origin[0] + r * row_step[0] + c * col_step[0], origin[1] + r * row_step[1] + c * col_step[1]
    fast = truth.pressure_on_lattice(2, "L", origin, row_step, col_step, shape)
    np.testing.assert_allclose(fast, truth.pressure(2, "L", uu, vv), rtol=1e-10)
