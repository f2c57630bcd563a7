"""Craig–Bampton disk reduction (paper Eqs. 2–6) against the FE disk."""

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from rom.craig_bampton import craig_bampton, disk_boundary_dofs, reduce_disk
from rom.solver import solve_modes

from . import rom_models


def test_free_disk_first_20_modes_within_0p3_percent_and_never_below_fe():
    bd = rom_models.bladed_disk()
    fe = solve_modes(bd.disk.K, bd.disk.M, 20).frequencies_hz
    rom = rom_models.disk_cb().free_modes(20).frequencies_hz
    rel = rom / fe - 1
    assert np.abs(rel).max() <= 3e-3
    assert rel.min() >= -1e-9  # Rayleigh–Ritz: a reduced model is never softer than the FE model


def test_hardware_on_a_slot_against_the_fe_disk_with_the_masses_put_on_by_hand():
    """Lumped masses (the bolts of ``[masses] slot_hardware_kg``) on slot 1's flank nodes: the mass they add, and
    the CB disk reduced with them against an FE solve of the FE disk with the same masses assembled here."""
    bd, kg = rom_models.bladed_disk(), 0.05
    nodes = np.concatenate([bd.disk.node_set("slot1_L").ravel(), bd.disk.node_set("slot1_R").ravel()])
    heavy = bd.disk.with_node_masses([nodes], kg)
    assert heavy.mass() == pytest.approx(bd.disk.mass() + kg, rel=1e-12)
    assert bd.disk.with_node_masses([nodes], 0.0) is bd.disk
    with pytest.raises(ValueError, match="kg_each"):
        bd.disk.with_node_masses([nodes], -1.0)
    d = np.zeros(bd.disk.n_dof)
    for k in range(3):
        d[3 * nodes + k] = kg / nodes.size
    fe = solve_modes(bd.disk.K, bd.disk.M + sp.diags(d), 20).frequencies_hz
    rom = reduce_disk(replace(bd, disk=heavy), (1,)).free_modes(20).frequencies_hz
    rel = rom / fe - 1
    assert np.abs(rel).max() <= 3e-3 and rel.min() >= -1e-9
    assert (rom_models.disk_cb().free_modes(20).frequencies_hz / rom - 1).max() > 1e-3  # the ROM sees the mass


def test_reduced_matrices_are_the_projection_with_the_block_structure_of_eqs_4_5():
    bd = rom_models.bladed_disk(6)
    cb = rom_models.disk_cb(6, (2,), 30, keep_basis=True)
    R = cb.reconstruct(np.eye(cb.n))  # R_CB of Eq. 3 in physical DOFs, (n_dof, n_k + n_b)
    KR = R.T @ (bd.disk.K @ R)
    MR = R.T @ (bd.disk.M @ R)
    k = cb.n_k
    # Eq. 4: K̃ = blockdiag(Λ, κ_bb); Eq. 5: M̃ = [[I, μ_beᵀ], [μ_be, μ_bb]].
    np.testing.assert_allclose(np.diag(KR[:k, :k]), cb.Lambda, rtol=1e-8)
    assert np.abs(KR[:k, k:]).max() <= 1e-8 * np.abs(KR).max()
    np.testing.assert_allclose(MR[:k, :k], np.eye(k), atol=1e-8)
    np.testing.assert_allclose(cb.K(), KR, atol=1e-8 * np.abs(KR).max())
    np.testing.assert_allclose(cb.M(), MR, atol=1e-8 * np.abs(MR).max())


def test_constraint_modes_are_static_and_boundary_is_in_the_slot_frame():
    bd = rom_models.bladed_disk(6)
    cb = rom_models.disk_cb(6, (2,), 30, keep_basis=True)
    rng = np.random.default_rng(0)
    q = np.r_[np.zeros(cb.n_k), rng.standard_normal(cb.n_b)]
    x = cb.reconstruct(q)
    f = bd.disk.K @ x
    excess = np.setdiff1d(np.arange(bd.disk.n_dof), cb.boundary_dofs)
    assert np.abs(f[excess]).max() <= 1e-8 * np.abs(f).max()  # Ψ = −K_ee⁻¹ K_eb: no excess forces
    # Boundary coordinates are in the slot (blade-local) frame: x_phys = R_s x_b.
    dofs, _ = disk_boundary_dofs(bd, (2,))
    R = bd.slot_rotation(2)
    np.testing.assert_allclose(x[dofs].reshape(-1, 3), q[cb.n_k :].reshape(-1, 3) @ R.T, atol=1e-14)
    # Outputs are rows of the same basis.
    np.testing.assert_allclose(cb.outputs(q), x[cb.output_dofs], atol=1e-12)


def test_truncated_model_equals_a_fresh_reduction():
    bd = rom_models.bladed_disk(6)
    small = reduce_disk(bd, (2,), 12)
    trunc = rom_models.disk_cb(6, (2,), 30, keep_basis=True).truncated(12)
    np.testing.assert_allclose(small.Lambda, trunc.Lambda, rtol=1e-9)
    f0, f1 = small.free_modes(8).frequencies_hz, trunc.free_modes(8).frequencies_hz
    np.testing.assert_allclose(f0, f1, rtol=1e-8)


def test_bad_inputs_raise_value_errors():
    bd = rom_models.bladed_disk(6)
    with pytest.raises(ValueError, match="boundary_dofs must not be empty"):
        craig_bampton(bd.disk, np.array([], int), 5)
    with pytest.raises(ValueError, match="n_modes"):
        craig_bampton(bd.disk, np.arange(6), 0)
    with pytest.raises(ValueError, match="slot must be an integer in 1..6"):
        reduce_disk(bd, (7,), 5)
    with pytest.raises(ValueError, match="duplicates"):
        reduce_disk(bd, (1, 1), 5)
    with pytest.raises(ValueError, match="keep_basis=False"):
        rom_models.disk_cb().reconstruct(np.zeros(rom_models.disk_cb().n))
