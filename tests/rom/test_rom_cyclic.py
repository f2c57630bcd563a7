"""Cyclic all-slot CB disk and the full-assembly solve on it (rom.cyclic, issue 12 item 4).

References: the dense all-slot Craig–Bampton reduction (every block computed from its own constraint modes,
no symmetry used), the FE full assembly, and the sparse hybrid (the reference implementation).
"""

from dataclasses import replace

import numpy as np
import pytest

from rom import cache
from rom.academic import build_bladed_disk
from rom.contact import ContactPattern
from rom.cyclic import reduce_disk_cyclic, solve_full_cyclic
from rom.errors import ROMError
from rom.fe_assembly import solve_fe
from rom.rom_assembly import solve_full
from rom.rubin import reduce_blade
from rom.validation import compare, fe_assembly_mistuned, random_patterns

from . import rom_models

GRID = (3, 7)
N_SMALL = 6


@pytest.fixture(scope="module")
def small_cyclic():
    return reduce_disk_cyclic(rom_models.bladed_disk(N_SMALL), 60)


def _clusters(lam: np.ndarray, rtol: float = 1e-8):
    """Index ranges of equal eigenvalues (a cyclic disk's cos/sin pairs), all but the last one: the n-th
    mode may be one of a pair whose partner is the (n+1)-th, and either copy is as right as the other."""
    j, out = 0, []
    while j < lam.size:
        k = j + 1
        while k < lam.size and abs(lam[k] - lam[j]) <= rtol * lam[j]:
            k += 1
        out.append(slice(j, k))
        j = k
    return out[:-1]


@pytest.mark.parametrize("n_blades", [N_SMALL, 5, 2])
def test_circulant_blocks_equal_the_dense_all_slot_reduction(n_blades, small_cyclic):
    """The sector-harmonic build gives the all-slot CB's own blocks (rotated frames, block-circulant).

    Reference: the dense all-slot Craig–Bampton reduction of the whole disk, every block from its own
    constraint modes. Within a repeated eigenvalue the fixed-interface modes are any basis of the eigenspace,
    so their couplings and outputs are compared through Σ φ φᵀ over each cluster.
    """
    n_k = 60 if n_blades == N_SMALL else 30
    cd = small_cyclic if n_blades == N_SMALL else reduce_disk_cyclic(rom_models.bladed_disk(n_blades), n_k)
    full = rom_models.disk_cb(n_blades, tuple(range(1, n_blades + 1)), n_k)
    n_i = cd.n_i
    scale_k, scale_m = np.abs(full.kappa_bb).max(), np.abs(full.mu_bb).max()
    for s in range(1, n_blades + 1):
        rs = slice((s - 1) * n_i, s * n_i)
        for t in range(1, n_blades + 1):
            ts = slice((t - 1) * n_i, t * n_i)
            assert np.abs(cd.kappa(s, t) - full.kappa_bb[rs, ts]).max() <= 1e-9 * scale_k
            assert np.abs(cd.mu(s, t) - full.mu_bb[rs, ts]).max() <= 1e-9 * scale_m
    np.testing.assert_allclose(cd.Lambda, full.Lambda, rtol=1e-9)
    np.testing.assert_allclose(cd.out_b1, full.output_basis[:, full.n_k : full.n_k + n_i], atol=1e-10)
    # μ_be of every slot and the output rows of the fixed-interface modes, cluster by cluster.
    mine = np.vstack([cd.mu_be.reshape(n_blades * n_i, -1), cd.out_eta])
    ref = np.vstack([full.mu_be, full.output_basis[:, : full.n_k]])
    clusters = _clusters(full.Lambda)
    assert sum(c.stop - c.start for c in clusters) >= n_k - 2
    for c in clusters:
        G, G0 = mine[:, c] @ mine[:, c].T, ref[:, c] @ ref[:, c].T
        assert np.abs(G - G0).max() <= 1e-8 * np.abs(ref).max() ** 2, c


def test_the_sector_partition_covers_the_disk():
    """Seven sectors of one interior, one face and one slot grid each make up the whole disk."""
    from rom.cyclic_partition import sector_blocks

    bd = build_bladed_disk(rom_models.COARSE.with_(n_blades=7, grid=(2, 5)))
    sb = sector_blocks(bd)
    assert sb.n_sectors == 7 and 7 * sb.n_own == bd.disk.n_dof
    assert sb.n_i == 3 * 2 * 2 * 5
    assert set(sb.K) == {0, 1, 6} and sb.asymmetry < 1e-12


@pytest.mark.parametrize(("n_blades", "grid"), [(N_SMALL, GRID), (18, GRID), (5, (2, 5))])
def test_full_solve_matches_the_fe_reference_like_the_hybrid(n_blades, grid, small_cyclic):
    """Even and odd blade counts (a harmonic N/2 or not) and another contact grid."""
    if grid == GRID:
        bd, b = rom_models.bladed_disk(n_blades), rom_models.blade(n_blades)
    else:
        bd = build_bladed_disk(rom_models.COARSE.with_(n_blades=n_blades, grid=grid))
        b = reduce_blade(bd)
    cd = small_cyclic if (n_blades, grid) == (N_SMALL, GRID) else reduce_disk_cyclic(bd, 60)
    rng = np.random.default_rng(2026 + n_blades)
    pats = random_patterns(grid, range(1, n_blades + 1), rng)
    delta = rng.uniform(-0.02, 0.02, n_blades)
    deltas = np.repeat(delta[:, None], b.m, axis=1)
    n = 3 * n_blades
    fe = solve_fe(fe_assembly_mistuned(bd, pats, delta), n)
    hybrid = solve_full(bd, b, pats, deltas, n_modes=n)
    sol = solve_full_cyclic(cd, b, pats, deltas, n_modes=n)
    c = compare("cyclic", fe, sol.modes, n)
    ch = compare("hybrid", fe, hybrid, n)
    assert c.f_fe.size == n
    assert c.max_rel_err <= max(2 * ch.max_rel_err, 2e-4)
    assert c.min_mac >= ch.min_mac - 5e-3
    # The same model error as the hybrid: frequencies agree far below it, and labels line up.
    np.testing.assert_allclose(sol.modes.frequencies_hz, hybrid.frequencies_hz, rtol=1e-4)
    assert sol.modes.meas_labels == hybrid.meas_labels
    assert sol.residuals.shape == (n,) and np.all(np.isfinite(sol.residuals))


def test_more_rounds_converge_to_the_cb_model(small_cyclic):
    """Each enrichment round lowers the residual; the frequencies then match the dense all-slot CB assembly."""
    b = rom_models.blade(N_SMALL)
    rng = np.random.default_rng(5)
    pats = random_patterns(GRID, range(1, N_SMALL + 1), rng)
    deltas = rng.uniform(-0.02, 0.02, (N_SMALL, b.m))
    full_cb = rom_models.disk_cb(N_SMALL, tuple(range(1, N_SMALL + 1)), 60)
    ref = solve_full(full_cb, b, pats, deltas, n_modes=3 * N_SMALL)
    res = []
    for rounds in (0, 1, 2):
        sol = solve_full_cyclic(small_cyclic, b, pats, deltas, n_modes=3 * N_SMALL, rounds=rounds)
        res.append(sol.residuals.max())
    assert res[0] > res[1] > res[2]
    np.testing.assert_allclose(sol.modes.frequencies_hz, ref.frequencies_hz, rtol=2e-7)


@pytest.mark.parametrize("matrix", ["K", "M"])
def test_a_disk_that_is_not_cyclic_is_refused(matrix):
    """One DOF next to slot 2's grid stiffer (or heavier): sector 2 no longer equals sector 1."""
    bd = rom_models.bladed_disk(N_SMALL)
    A = getattr(bd.disk, matrix).tolil(copy=True)
    node = int(bd.disk.node_set("slot2_L").ravel()[0])
    dof = next(j for j in A.rows[3 * node] if j // 3 != node)
    A[dof, dof] = A[dof, dof] * 1.5
    bad = replace(bd, disk=replace(bd.disk, **{matrix: A.tocsr()}))
    with pytest.raises(ROMError, match="not cyclic"):
        reduce_disk_cyclic(bad, 10)


def test_printed_coordinates_still_make_a_cyclic_mesh(small_cyclic):
    """Node positions known to 1e-8 of the radius (an exported mesh's digits) map onto the same sectors."""
    bd = rom_models.bladed_disk(N_SMALL)
    noise = np.random.default_rng(3).uniform(-1, 1, bd.disk.coords.shape)
    X = bd.disk.coords + 1e-8 * bd.params.disk_outer_radius * noise
    cd = reduce_disk_cyclic(replace(bd, disk=replace(bd.disk, coords=X)), 60)
    np.testing.assert_array_equal(cd.kappa_col, small_cyclic.kappa_col)
    np.testing.assert_array_equal(cd.Lambda, small_cyclic.Lambda)


def test_a_mesh_that_is_not_cyclic_is_refused():
    """One node of sector 3 moved by 1 % of the disk radius: sector 3 is no rotated copy of sector 1."""
    bd = rom_models.bladed_disk(N_SMALL)
    X = bd.disk.coords.copy()
    ang = np.arctan2(X[:, 0], X[:, 1]) % (2 * np.pi)
    node = int(np.flatnonzero(np.abs(ang - 2 * (2 * np.pi / N_SMALL)) < 0.2)[0])
    X[node, 2] += 0.01 * bd.params.disk_outer_radius
    bad = replace(bd, disk=replace(bd.disk, coords=X))
    with pytest.raises(ROMError, match="sector 3.*not cyclic"):
        reduce_disk_cyclic(bad, 10)


def test_bad_input_is_refused_with_a_message(small_cyclic):
    b = rom_models.blade(N_SMALL)
    pat = ContactPattern.full(GRID)
    with pytest.raises(ROMError, match=r"missing \[6\]"):
        solve_full_cyclic(small_cyclic, b, {s: pat for s in range(1, N_SMALL)})
    with pytest.raises(ROMError, match="grid"):
        solve_full_cyclic(replace(small_cyclic, meta={**small_cyclic.meta, "grid": [7, 31]}), b, pat)
    with pytest.raises(ROMError, match="n_cc"):
        reduce_disk_cyclic(rom_models.bladed_disk(N_SMALL), 10, n_cc=0)


def test_cache_round_trip_keeps_every_array(tmp_path, small_cyclic):
    bd = rom_models.bladed_disk(N_SMALL)
    key = cache.cyclic_disk_key(bd, 60)
    path = cache.cache_file("disk-cyclic", key, tmp_path)
    cache.save_model(path, small_cyclic, key)
    back = cache.cached_reduce_disk_cyclic(bd, 60, cache_dir=tmp_path)  # a hit: no build
    for name in ("Lambda", "kappa_col", "mu_col", "mu_be", "out_eta", "out_b1", "cc_modes", "cc_mass", "cc_omega2"):
        a, c = getattr(small_cyclic, name), getattr(back, name)
        assert a.dtype == c.dtype and np.array_equal(a, c), name
    assert back.meta == small_cyclic.meta
    assert cache.cyclic_disk_key(bd, 61) != key
