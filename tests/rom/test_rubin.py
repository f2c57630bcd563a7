"""Rubin free-interface reduction of the blade (Eqs. 7–17) and blade mistuning (Eq. 19)."""

import numpy as np
import pytest
import scipy.linalg as sla

from rom.rubin import blade_boundary_dofs, rubin
from rom.solver import solve_modes

from . import rom_models


def test_free_blade_first_20_modes_within_0p3_percent_and_never_below_fe():
    bd = rom_models.bladed_disk()
    fe = solve_modes(bd.blade.K, bd.blade.M, 20).frequencies_hz
    rom = rom_models.blade().free_modes(20).frequencies_hz
    rel = rom / fe - 1
    assert np.abs(rel).max() <= 3e-3
    assert rel.min() >= -1e-7  # Rayleigh–Ritz, up to the eigensolver tolerance


def test_residual_flexibility_equals_the_truncated_modal_sum_of_all_fe_modes():
    """A Ψ_r (Eq. 13's inverse) = Σ_{i > m} φ_i φ_iᵀ / ω_i² at the boundary, from a dense FE eigen-decomposition."""
    bd = rom_models.bladed_disk()
    b = rom_models.blade()
    w2, V = sla.eigh(bd.blade.K.toarray(), bd.blade.M.toarray())
    elastic = np.arange(6, w2.size)
    dofs, _ = blade_boundary_dofs(bd.blade)
    Vb = V[np.ix_(dofs, elastic[b.m :])]
    G = (Vb / w2[elastic[b.m :]]) @ Vb.T
    np.testing.assert_allclose(b.G_bb, G, atol=1e-6 * np.abs(G).max())
    np.testing.assert_allclose(b.omega2_tuned, w2[elastic[: b.m]], rtol=1e-7)  # Lanczos tolerance
    # Eq. 10: Ψ_rᵀ K Ψ_r equals A Ψ_r (the modal sum is K-orthonormal).
    np.testing.assert_allclose(b.G_rb, b.G_bb, atol=1e-6 * np.abs(G).max())


def test_reconstructed_super_element_modes_match_fe_shapes():
    bd = rom_models.bladed_disk()
    b = rom_models.blade()
    fe = solve_modes(bd.blade.K, bd.blade.M, 10)
    dm = b.free_modes(10)
    X = b.reconstruct(dm.shapes)
    mac = (np.abs(np.sum(X * (bd.blade.M @ fe.shapes), axis=0))) ** 2 / (
        np.sum(X * (bd.blade.M @ X), axis=0) * np.sum(fe.shapes * (bd.blade.M @ fe.shapes), axis=0)
    )
    assert mac.min() >= 1 - 1e-8


def test_mistuning_scales_free_interface_eigenvalue_i_by_exactly_one_plus_delta_i():
    b = rom_models.blade()
    rng = np.random.default_rng(4)
    delta = rng.uniform(-0.02, 0.02, 12)
    w2 = (2 * np.pi * b.with_delta(delta).free_modes(12).frequencies_hz) ** 2
    w2_0 = (2 * np.pi * b.free_modes(12).frequencies_hz) ** 2
    # The ±2 % perturbations may reorder close modes; compare sorted values.
    np.testing.assert_allclose(w2, np.sort(w2_0 * (1 + delta)), rtol=1e-8)
    np.testing.assert_array_equal(b.with_delta(delta).omega2, b.omega2_tuned * (1 + np.r_[delta, np.zeros(b.m - 12)]))


def test_zero_delta_reproduces_the_tuned_model_exactly():
    b = rom_models.blade()
    se0, se1 = b.superelement(), b.with_delta(np.zeros(b.m)).superelement()
    np.testing.assert_array_equal(se0.K, se1.K)
    np.testing.assert_array_equal(se0.M, se1.M)
    np.testing.assert_array_equal(b.with_delta(0.0).superelement().K, se0.K)


def test_force_free_elimination_keeps_only_the_chosen_boundary():
    b = rom_models.blade()
    keep = np.zeros(b.n_b, bool)
    keep[: b.n_interface // 2] = True
    keep[b.accessory_index] = True
    se = b.superelement(keep)
    assert se.n == b.n_r + b.m + keep.sum()
    np.testing.assert_array_equal(se.boundary_index, np.flatnonzero(keep))
    # Still a Rayleigh–Ritz model containing the free modes: its free spectrum starts with the FE modes.
    from rom.modal import dense_modes

    f = dense_modes(se.K, se.M, 5).frequencies_hz
    np.testing.assert_allclose(f, b.free_modes(5).frequencies_hz, rtol=1e-7)


@pytest.mark.parametrize("kept", [1.0, 0.95, 0.7, 0.3, 0.05])
def test_residual_blocks_both_routes_equal_a_plain_inverse(kept):
    """Eq. 13 and Eq. 17 on a kept subset: the Cholesky route and the Schur-complement update agree with
    ``numpy.linalg.inv`` of the flexibility sub-block, and come out exactly symmetric."""
    b = rom_models.blade()
    rng = np.random.default_rng(int(100 * kept))
    S = np.sort(rng.choice(b.n_b, max(int(kept * b.n_b), 1), replace=False))
    K_ref = np.linalg.inv(b.G_bb[np.ix_(S, S)])
    M_ref = K_ref @ b.M_rb[np.ix_(S, S)] @ K_ref
    for route in ("direct", "update", "auto"):
        K, M = b._residual_blocks(S, route)
        np.testing.assert_allclose(K, K_ref, rtol=0, atol=1e-12 * np.abs(K_ref).max())
        np.testing.assert_allclose(M, M_ref, rtol=0, atol=1e-12 * np.abs(M_ref).max())
        np.testing.assert_array_equal(K, K.T)
        np.testing.assert_array_equal(M, M.T)
    se = b.superelement(S)
    np.testing.assert_array_equal(se.K, se.K.T)
    np.testing.assert_array_equal(se.M, se.M.T)
    with pytest.raises(ValueError, match="route must be"):
        b._residual_blocks(S, "bogus")


def test_bad_delta_raises():
    b = rom_models.blade()
    with pytest.raises(ValueError, match="finite"):
        b.with_delta([0.01, np.nan])
    with pytest.raises(ValueError, match=f"1..{b.m} entries"):
        b.with_delta(np.zeros(b.m + 1))
    with pytest.raises(ValueError, match="> -1"):
        b.with_delta([-1.0])


def test_bad_inputs_raise():
    bd = rom_models.bladed_disk()
    with pytest.raises(ValueError, match="duplicates"):
        rubin(bd.blade, np.array([0, 0, 1]), 5)
    with pytest.raises(ValueError, match="n_modes"):
        rubin(bd.blade, np.arange(3), 0)


def test_the_shared_boundary_inverse_does_not_depend_on_the_first_callers_blas_threads():
    """Every solve of a model in a process shares one whole-boundary inverse (``rom.rubin._boundary_inverse``).
    Its bits must not depend on the BLAS threads of whoever asked first: a dataset part built in a worker process
    would otherwise differ in the last bits from the same part built in the parent (seen in the suite)."""
    from threadpoolctl import threadpool_limits

    import rom.rubin as rubin_module

    model = rom_models.blade()
    got = []
    for threads in (2, 1):
        rubin_module._INVERSE_MEMO.clear()
        with threadpool_limits(threads):
            got.append(rubin_module._boundary_inverse(model))
    rubin_module._INVERSE_MEMO.clear()
    assert np.array_equal(got[0][0], got[1][0]) and np.array_equal(got[0][1], got[1][1])
