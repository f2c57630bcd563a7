"""``rom.solver.solve_modes``: complete and deterministic whatever the start vector or the number of modes.

Issue 8 item 1: from an unlucky ARPACK start vector, the coarse disk–one-blade lost one copy of its six-fold
rigid-body eigenvalue (start vector ``default_rng(14)``, 3 elastic modes asked for, 5 rigid modes reported).
"""

import os
from pathlib import Path

import numpy as np
import pytest

from rom.contact import ContactPattern
from rom.fe_assembly import assemble_fe
from rom.solver import (
    available_backends,
    block_krylov_modes,
    factorize,
    nodal_diameters,
    solve_modes,
    solve_modes_factored,
)


@pytest.fixture(scope="module")
def d1b_fe(coarse_bd):
    asm = assemble_fe(coarse_bd, {1: ContactPattern.full(coarse_bd.params.grid)})
    return asm.K, asm.M


def _geometric_rigid_residual(coords: np.ndarray, shapes: np.ndarray) -> float:
    """Largest share of a rigid shape outside the span of the six geometric rigid-body motions."""
    x = coords - coords.mean(axis=0)
    n = x.shape[0]
    R = np.zeros((3 * n, 6))
    for d in range(3):
        R[d::3, d] = 1.0
    # Rotations about x, y, z: u = e × x.
    R[1::3, 3], R[2::3, 3] = -x[:, 2], x[:, 1]
    R[0::3, 4], R[2::3, 4] = x[:, 2], -x[:, 0]
    R[0::3, 5], R[1::3, 5] = -x[:, 1], x[:, 0]
    Q, _ = np.linalg.qr(R)
    out = shapes - Q @ (Q.T @ shapes)
    return float(np.max(np.linalg.norm(out, axis=0) / np.linalg.norm(shapes, axis=0)))


@pytest.mark.parametrize("n_modes", [1, 3, 7])
def test_rigid_count_and_frequencies_do_not_depend_on_start_vector_or_mode_count(d1b_fe, n_modes):
    K, M = d1b_fe
    n = K.shape[0]
    ref = solve_modes(K, M, 7)
    assert ref.n_rigid == 6
    for seed in (0, 13, 14, 21):
        sol = solve_modes(K, M, n_modes, v0=np.random.default_rng(seed).standard_normal(n))
        assert sol.n_rigid == 6, f"seed {seed}, {n_modes} modes: {sol.n_rigid} rigid modes"
        np.testing.assert_allclose(sol.frequencies_hz, ref.frequencies_hz[:n_modes], rtol=1e-8)


def test_default_start_vector_is_deterministic(d1b_fe):
    K, M = d1b_fe
    a, b = solve_modes(K, M, 4), solve_modes(K, M, 4)
    np.testing.assert_array_equal(a.frequencies_hz, b.frequencies_hz)
    np.testing.assert_array_equal(np.abs(a.shapes), np.abs(b.shapes))


def test_free_blade_rigid_modes_span_the_geometric_rigid_body_motions(coarse_bd):
    blade = coarse_bd.blade
    for seed in (0, 14):
        sol = solve_modes(blade.K, blade.M, 2, v0=np.random.default_rng(seed).standard_normal(blade.n_dof))
        assert sol.n_rigid == 6
        assert _geometric_rigid_residual(blade.coords, sol.rigid_shapes) < 1e-6


def test_cyclic_disk_keeps_both_copies_of_every_nodal_diameter_pair(coarse_bd):
    disk = coarse_bd.disk
    meas = 3 * disk.node_set("meas") + 2
    ref = solve_modes(disk.K, disk.M, 12)
    nd = nodal_diameters(ref.shapes[meas])
    # Every ND other than 0 and N/2 is a degenerate pair: equal frequencies, same ND, side by side.
    i = 0
    while i < 10:
        if nd[i] in (0, disk.node_set("meas").size // 2):
            i += 1
            continue
        assert nd[i + 1] == nd[i] and ref.frequencies_hz[i + 1] == pytest.approx(ref.frequencies_hz[i], rel=1e-6)
        i += 2
    for seed in (5, 14):
        sol = solve_modes(disk.K, disk.M, 10, v0=np.random.default_rng(seed).standard_normal(disk.n_dof))
        np.testing.assert_allclose(sol.frequencies_hz, ref.frequencies_hz[:10], rtol=1e-8)


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso is not installed here")
def test_pardiso_direct_solves_agree_with_superlu_and_the_residual(d1b_fe):
    """The phase-33 Pardiso solve (no refinement, index arrays made once) against SuperLU and A x − b.

    One vector, a block, and a non-contiguous block (the solver must not read a strided view as if it were
    Fortran-ordered); a second factorization of the same matrix gives the same bits (MKL_CBWR).
    """
    K, M = d1b_fe
    A = (K + (2 * np.pi * 200.0) ** 2 * M).tocsr()
    B = np.random.default_rng(3).standard_normal((A.shape[0], 6))
    pardiso, superlu = factorize(A, "pardiso"), factorize(A, "superlu")
    try:
        for b in (B[:, 0], B, B[:, ::2]):
            x, ref = pardiso.solve(b), superlu.solve(np.ascontiguousarray(b))
            assert x.shape == b.shape
            assert np.abs(x - ref).max() <= 1e-7 * np.abs(ref).max()
            assert np.linalg.norm(A @ x - b) <= 1e-8 * np.linalg.norm(b)
        again = factorize(A, "pardiso")
        np.testing.assert_array_equal(again.solve(B), pardiso.solve(B))
        again.free()
    finally:
        pardiso.free()
        superlu.free()


@pytest.fixture(scope="module")
def clamped_disk(coarse_bd):
    """The coarse disk's interior with slot 1's grids clamped: the pencil of the CB fixed-interface modes."""
    from rom.craig_bampton import disk_boundary_dofs

    dofs, _ = disk_boundary_dofs(coarse_bd, (1,))
    keep = np.setdiff1d(np.arange(coarse_bd.disk.n_dof), dofs)
    K, M = coarse_bd.disk.K, coarse_bd.disk.M
    return K[keep][:, keep].tocsr(), M[keep][:, keep].tocsr()


@pytest.mark.parametrize("backend", available_backends())
def test_block_krylov_modes_agree_with_arpack(clamped_disk, backend):
    """The block Krylov run against ARPACK (scipy's eigsh) on the same factorization: same eigenvalues and
    shapes, M-orthonormal; the CB reduction's fixed-interface modes on Pardiso take this route."""
    K, M = clamped_disk
    fac = factorize(K, backend)
    try:
        ref = solve_modes_factored(K, M, 30, fac, block=0)  # ARPACK
        got = solve_modes_factored(K, M, 30, fac, block=8)
    finally:
        fac.free()
    np.testing.assert_allclose(got.frequencies_hz, ref.frequencies_hz, rtol=1e-10)
    np.testing.assert_allclose(got.shapes.T @ (M @ got.shapes), np.eye(30), atol=1e-10)
    # Shapes up to sign, and up to a rotation inside any near-degenerate pair: compare the projectors' overlap.
    overlap = np.abs(ref.shapes.T @ (M @ got.shapes))
    assert np.sum(overlap**2, axis=1).min() > 1 - 1e-8


def test_block_krylov_modes_keep_both_copies_of_repeated_eigenvalues(coarse_bd):
    """A free cyclic disk: six rigid-body modes and exact nodal-diameter doublets, all found from one block,
    against :func:`solve_modes` (ARPACK with its deflated completeness check)."""
    disk = coarse_bd.disk
    ref = solve_modes(disk.K, disk.M, 12)
    sigma = -((2 * np.pi * 200.0) ** 2)
    fac = factorize((disk.K - sigma * disk.M).tocsr(), "superlu")
    try:
        vals, vecs = block_krylov_modes(disk.M, sigma, fac, 20, 8)  # 6 rigid, 12 elastic, one more doublet
    finally:
        fac.free()
    assert np.abs(vals[:6]).max() < 1e-6 * abs(sigma)  # rigid-body modes
    np.testing.assert_allclose(np.sqrt(vals[6:18]) / (2 * np.pi), ref.frequencies_hz, rtol=1e-9)
    # Each doublet's plane is spanned (the 12th mode's partner is the 13th): the reference shapes lie in the
    # span of the modes found.
    inside = vecs.T @ (disk.M @ ref.shapes)
    assert np.sum(inside**2, axis=0).min() > 1 - 1e-8


def test_m_orthonormalise_keeps_the_rank_of_a_nearly_dependent_block(clamped_disk):
    """Two columns equal to 1e-4 give two M-orthonormal vectors; equal to 1e-10 (a Krylov block near
    convergence), one. Either way M-orthogonal to the vectors already kept, to round-off."""
    from rom.block_krylov import m_orthonormalise

    K, M = clamped_disk
    rng = np.random.default_rng(0)
    V0 = rng.standard_normal((K.shape[0], 4))
    V, _ = m_orthonormalise(V0, M @ V0, V0[:, :0], V0[:, :0])
    MV = M @ V
    x, y = rng.standard_normal((2, K.shape[0], 1))
    for eps, rank in ((1e-4, 2), (1e-10, 1)):
        X = np.hstack([x, x + eps * y])
        Q, _ = m_orthonormalise(X, M @ X, V, MV)
        assert Q.shape[1] == rank
        np.testing.assert_allclose(Q.T @ (M @ Q), np.eye(rank), atol=1e-12)
        assert np.abs(V.T @ (M @ Q)).max() < 1e-12


@pytest.mark.skipif("pardiso" not in available_backends(), reason="pypardiso is not installed here")
def test_solve_modes_on_pardiso_takes_the_block_run_and_agrees_with_arpack(coarse_bd):
    """On a Pardiso factor `solve_modes` starts from the block Krylov run; on SuperLU from ARPACK. A free cyclic
    disk gives both the same six rigid-body modes and the same doublets."""
    disk = coarse_bd.disk
    ref = solve_modes(disk.K, disk.M, 12, backend="superlu")
    got = solve_modes(disk.K, disk.M, 12, backend="pardiso")
    assert got.n_rigid == ref.n_rigid == 6
    np.testing.assert_allclose(got.frequencies_hz, ref.frequencies_hz, rtol=1e-9)


def test_mkl_runtime_is_named_from_its_package_record_and_only_if_it_loads(monkeypatch, tmp_path):
    """pypardiso is told where MKL's runtime is (sparing its recursive glob over the environment) only when the
    ``mkl`` package's record names a library that loads: pypardiso loads a named one without a guard."""
    from importlib import metadata

    from rom import solver

    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    try:
        record = [f for f in metadata.files("mkl") or [] if f.name.startswith("libmkl_rt")]
    except metadata.PackageNotFoundError:
        record = []
    if record:
        solver._name_mkl_runtime()
        assert Path(os.environ["PYPARDISO_MKL_RT"]).is_file()
        assert "pardiso" in solver.available_backends()
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    damaged = tmp_path / "libmkl_rt.so.9"
    damaged.write_bytes(b"not a shared library")

    class Entry:
        name = damaged.name

        def locate(self):
            return damaged

    monkeypatch.setattr(metadata, "files", lambda name: [Entry()])
    solver._name_mkl_runtime()
    assert "PYPARDISO_MKL_RT" not in os.environ
