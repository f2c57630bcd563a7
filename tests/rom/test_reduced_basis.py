"""The affine spring model of the disk–one-blade ROM and its certified reduced basis (rom.spring_assembly,
rom.reduced_basis), on the coarse 3×7 model: against the compliance formulation, against accurate full-order
eigenvalues on held-out patterns, on a deliberately poor basis, and on bad input."""

import numpy as np
import pytest
import scipy.linalg as sla

from rom.contact import ContactPattern
from rom.contact_stiffness import (
    ContactStiffness,
    blade_compliance_parts,
    interface_compliance,
    with_contact_stiffness,
)
from rom.modal import single_thread_blas
from rom.reduced_basis import evaluate, frequency_bounds, plausible_patterns, reduce_spring_d1b
from rom.rom_assembly import assemble_d1b, solve_d1b
from rom.spring_assembly import solve_spring_d1b, spring_d1b

from . import rom_models

STIFF = ContactStiffness(1e14, 7e13)  # the ideal truth twin's joint (design §8.14)
SIGMA = -((2 * np.pi * 100.0) ** 2)


def _exact(K, M, k, n_rigid=6):
    """Lowest ``k`` elastic eigenvalues (rad²/s²) to ~1e-13, from the standard form of T = (K − σM)⁻¹M."""
    with single_thread_blas():  # small dense work: one thread is faster, and steady on a shared machine
        L = sla.cholesky(K - SIGMA * M, lower=True)
        T = sla.solve_triangular(L, sla.solve_triangular(L, M, lower=True).T, lower=True)
        mu = np.linalg.eigvalsh(0.5 * (T + T.T))[::-1]  # T's largest are the lowest λ; the rigid modes first
    return 1.0 / mu[n_rigid : n_rigid + k] + SIGMA


@pytest.fixture(scope="module")
def parts():
    return blade_compliance_parts(rom_models.bladed_disk().blade)


@pytest.fixture(scope="module")
def model(parts):
    return spring_d1b(rom_models.disk_cb(), rom_models.blade(keep_basis=False), parts, STIFF)


@pytest.fixture(scope="module")
def rb(model):
    return reduce_spring_d1b(model, n_train=30, seed=1)


def _patterns():
    grid = rom_models.COARSE.grid
    return [ContactPattern.full(grid), ContactPattern.random(grid, 0.5, np.random.default_rng(3)),
            plausible_patterns(grid, 1, seed=5)[0]]


def test_spring_model_matches_the_compliance_formulation(model, parts):
    """Two independent paths to the blade on springs: stiffness springs between kept node pairs (affine) and
    the springs' compliance in Eq. 13 (rom.contact_stiffness). The compliance path is the spring model with the
    residual coordinates condensed onto the springs, a Rayleigh–Ritz restriction: never below it (to round-off, 1e-10),
    and above by ≤ 6e-11 here with accurate eigen-solves. The public dense solvers add their own ~1e-8 scatter."""
    disk, blade = rom_models.disk_cb(), rom_models.blade(keep_basis=False)
    sprung = with_contact_stiffness(blade, interface_compliance(parts, STIFF))
    for pat in _patterns():
        primal = _exact(model.K(model.parameters(pat)), model.M, 10)
        asm = assemble_d1b(disk, sprung, pat)
        rel = _exact(asm.K, asm.M, 10) / primal - 1
        # round-off: springs 1e8 times stiffer than the blade leave ~1e-11 of scatter (-2.4e-11 on one machine)
        assert np.all(rel > -1e-10) and np.all(rel < 1e-9)
        got = solve_spring_d1b(model, pat, 10).frequencies_hz
        np.testing.assert_allclose(got, solve_d1b(disk, sprung, pat, n_modes=10).frequencies_hz, rtol=5e-8)


def test_stiffer_springs_approach_the_rigid_ties(parts):
    disk, blade = rom_models.disk_cb(), rom_models.blade(keep_basis=False)
    pat = _patterns()[1]
    rigid = solve_d1b(disk, blade, pat, n_modes=10).frequencies_hz
    err = []
    for k in (1e14, 1e15, 1e16):
        m = spring_d1b(disk, blade, parts, ContactStiffness(k, 0.7 * k))
        err.append(np.abs(solve_spring_d1b(m, pat, 10).frequencies_hz / rigid - 1).max())
    assert err[0] > 5 * err[1] > 25 * err[2] and err[2] < 1e-4  # about 1/k


def test_blade_mistuning_is_an_affine_term(model, parts):
    """Eq. 19 as the affine term Σ δ_j ω_j² e_j e_jᵀ against the compliance path's ``with_delta``."""
    disk, blade = rom_models.disk_cb(), rom_models.blade(keep_basis=False)
    sprung = with_contact_stiffness(blade, interface_compliance(parts, STIFF))
    pat, delta = _patterns()[2], np.random.default_rng(0).uniform(-0.03, 0.03, 8)
    asm = assemble_d1b(disk, sprung, pat, delta=delta)
    rel = _exact(asm.K, asm.M, 10) / _exact(model.K(model.parameters(pat, delta)), model.M, 10) - 1
    assert np.all(np.abs(rel) < 1e-9)
    assert np.abs(_exact(model.K(model.parameters(pat)), model.M, 10) / _exact(asm.K, asm.M, 10) - 1).max() > 1e-4


def test_reduced_basis_on_held_out_patterns_is_within_its_certified_bounds(model, rb):
    """≥ 50 held-out patterns (another seed than the training's): every Ritz frequency lies within its bound of
    the full model's (accurate reference), each row is certified to ``tol`` or answered by a direct solve."""
    tol = 5e-5
    test = plausible_patterns(model.grid, 60, seed=99)
    res = evaluate(rb, test, 10, tol=tol, shapes=True)
    assert res.frequencies_hz.shape == res.bound.shape == (60, 10) and res.meas_shapes.shape == (60, 21, 10)
    assert res.fallback.mean() < 0.2  # measured: none at r ≈ 170
    raw = evaluate(rb, test, 10, tol=np.inf)
    for i, pat in enumerate(test):
        f_ref = np.sqrt(_exact(model.K(model.parameters(pat)), model.M, 10)) / (2 * np.pi)
        err = np.abs(raw.frequencies_hz[i] / f_ref - 1)
        assert np.all(err <= raw.bound[i] + 1e-11) and np.all(err <= raw.kb_bound[i] + 1e-11)
        assert res.fallback[i] or np.all(res.bound[i] <= tol)
        assert np.all(np.abs(res.frequencies_hz[i] / f_ref - 1) <= tol + 1e-8)
    direct = solve_spring_d1b(model, test[0], 10)
    macs = [abs(a @ b) ** 2 / ((a @ a) * (b @ b)) for a, b in zip(res.meas_shapes[0].T, direct.meas_shapes.T,
                                                                   strict=True)]
    assert min(macs) > 0.999


def test_bounds_hold_on_a_poor_basis_and_with_mistuning(model):
    """A tiny basis: errors of per cent, and still never above their bounds (nor the unconditional ones above
    the distance to the nearest eigenfrequency); every row falls back at the default tolerance."""
    poor = reduce_spring_d1b(model, n_train=3, rank=14, seed=2)
    test = plausible_patterns(model.grid, 8, seed=7)
    deltas = np.random.default_rng(1).uniform(-0.05, 0.05, (8, 6))
    res = evaluate(poor, test, 10, tol=np.inf, deltas=deltas)
    for i, pat in enumerate(test):
        f_all = np.sqrt(_exact(model.K(model.parameters(pat, deltas[i])), model.M, 40)) / (2 * np.pi)
        err = np.abs(res.frequencies_hz[i] / f_all[:10] - 1)
        nearest = np.min(np.abs(res.frequencies_hz[i][:, None] / f_all[None, :] - 1), axis=1)
        assert np.all(err <= res.bound[i]) and np.all(nearest <= res.kb_bound[i])
    assert np.max(err) > 1e-3
    assert evaluate(poor, test, 10, deltas=deltas).fallback.all()


def test_frequency_bounds_on_a_diagonal_pencil():
    """K = diag(λ), M = I, perturbed unit vectors: the Ritz values and residuals are known in closed form."""
    lam = np.array([1.0, 4.0, 9.0, 16.0]) * 1e6
    eps = 1e-3
    # v_k = (e_k + eps e_4)/‖·‖ for k = 0..2: Rayleigh quotient and A⁻¹-norm residual exact.
    rq = (lam[:3] + eps**2 * lam[3]) / (1 + eps**2)
    a = 1.0 / np.sqrt(1 + eps**2)
    res2 = a**2 * ((lam[:3] - rq) ** 2 / (lam[:3] - SIGMA) + eps**2 * (lam[3] - rq) ** 2 / (lam[3] - SIGMA))
    bound, kb = frequency_bounds(rq, res2, SIGMA)
    err = np.sqrt(rq / lam[:3]) - 1
    assert np.all(err > 0) and np.all(err <= bound) and np.all(err <= kb)
    assert np.all(bound[:2] < 10 * err[:2])  # Kato–Temple: quadratic, close to the true error


def test_bad_input_gives_clear_errors(model, rb):
    grid = model.grid
    with pytest.raises(ValueError, match=r"grid shape \(3, 5\)"):
        evaluate(rb, [ContactPattern.full((3, 5))])
    with pytest.raises(ValueError, match="must be a ContactPattern, got ndarray"):
        evaluate(rb, [np.ones(grid, bool)])
    with pytest.raises(ValueError, match=r"boolean \(only 0/1\), got 2"):
        ContactPattern(np.full(grid, 2), np.ones(grid))
    with pytest.raises(ValueError, match="positive number in N/m³, got -1000"):
        ContactStiffness(-1e14, 7e13)
    with pytest.raises(ValueError, match="stiffness must be a ContactStiffness"):
        spring_d1b(rom_models.disk_cb(), rom_models.blade(keep_basis=False), blade_compliance_parts(
            rom_models.bladed_disk().blade), -1e14)
    with pytest.raises(ValueError, match="n_modes must be an integer in 1..."):
        evaluate(rb, plausible_patterns(grid, 1), n_modes=rb.r)
    with pytest.raises(ValueError, match="tol must be a positive relative frequency error, got -1"):
        evaluate(rb, plausible_patterns(grid, 1), tol=-1)
    with pytest.raises(ValueError, match=r"one δ per pattern \(1\), got 2"):
        evaluate(rb, plausible_patterns(grid, 1), deltas=[0.0, 0.0])
    with pytest.raises(ValueError, match="delta entries must be > -1"):
        evaluate(rb, plausible_patterns(grid, 1), deltas=[[-1.5]])
    with pytest.raises(ValueError, match=r"rank must be an integer in 12..42 \(the snapshots\), got 50"):
        reduce_spring_d1b(model, n_train=3, rank=50)
    with pytest.raises(ValueError, match=r"fraction must be a range inside \(0, 1\], got \(0.5, 1.5\)"):
        plausible_patterns(grid, 2, fraction=(0.5, 1.5))
