"""Full 18-blade ROM (sparse hybrid and dense CB) against the FE reference, and mistuning facts (Eq. 19)."""

import numpy as np
import pytest

from rom.contact import ContactPattern
from rom.fe_assembly import solve_fe
from rom.rom_assembly import assemble_full, solve_full
from rom.solver import nodal_diameters
from rom.validation import compare, fe_assembly_mistuned, random_patterns

from . import rom_models

GRID = (3, 7)
N = 18


@pytest.fixture(scope="module")
def mistuned_case():
    rng = np.random.default_rng(2026)
    pats = random_patterns(GRID, range(1, N + 1), rng)
    delta = rng.uniform(-0.02, 0.02, N)
    fe = solve_fe(fe_assembly_mistuned(rom_models.bladed_disk(), pats, delta), 3 * N)
    return pats, delta, fe


@pytest.mark.parametrize("formulation", ["exact", "paper"])
def test_full_assembly_first_three_families_within_0p5_percent_and_mac_0p95(mistuned_case, formulation):
    pats, delta, fe = mistuned_case
    deltas = np.repeat(delta[:, None], rom_models.blade().m, axis=1)  # FE blade j has stiffness (1 + δ_j) K
    rom = solve_full(rom_models.bladed_disk(), rom_models.blade(), pats, deltas, n_modes=3 * N + 12,
                     formulation=formulation)
    c = compare("full", fe, rom, 3 * N)  # paired by MAC (Hungarian in a frequency window), not by index
    assert c.f_fe.size == 3 * N
    assert c.max_rel_err <= 5e-3
    assert c.min_mac >= 0.95


def test_full_assembly_with_mode_dependent_delta_matches_the_modal_fe_counterpart():
    """Six blades: what is tested is the δ per blade and mode (the 18-blade assembly is the test above)."""
    n = 6
    bd, b = rom_models.bladed_disk(n), rom_models.blade(n)
    rng = np.random.default_rng(7)
    pats = random_patterns(GRID, range(1, n + 1), rng)
    deltas = rng.uniform(-0.02, 0.02, (n, b.m))
    fe = solve_fe(fe_assembly_mistuned(bd, pats, deltas, kind="modal", Phi_f=b.Phi_f, omega2=b.omega2_tuned), 3 * n)
    c = compare("full", fe, solve_full(bd, b, pats, deltas, n_modes=3 * n + 6), 3 * n)
    assert c.max_rel_err <= 5e-3
    assert c.min_mac >= 0.95


def test_dense_cb_full_assembly_matches_fe_on_a_small_disk():
    """The paper's dense CB+Rubin assembly (disk reduced on all slots), 6 blades."""
    n = 6
    bd = rom_models.bladed_disk(n)
    b = rom_models.blade(n)
    cb = rom_models.disk_cb(n, tuple(range(1, n + 1)))
    rng = np.random.default_rng(5)
    pats = random_patterns(GRID, range(1, n + 1), rng)
    delta = rng.uniform(-0.02, 0.02, n)
    fe = solve_fe(fe_assembly_mistuned(bd, pats, delta), 3 * n)
    rom = solve_full(cb, b, pats, delta[:, None] * np.ones(b.m), n_modes=3 * n + 6)
    c = compare("full-cb", fe, rom, 3 * n)
    assert c.max_rel_err <= 5e-3
    assert c.min_mac >= 0.95


def test_tuned_assembly_has_degenerate_nd_pairs_that_mistuning_splits():
    bd, b = rom_models.bladed_disk(), rom_models.blade()
    tuned = solve_full(bd, b, ContactPattern.full(GRID), n_modes=N)
    f = tuned.frequencies_hz
    # Family 1 of a tuned 18-blade disk: nodal diameters 0 and 9 single, 1..8 in degenerate pairs.
    nd = nodal_diameters(tuned.select("blade")[0][0::3])  # blade point 1 of every slot
    assert sorted(set(nd.tolist())) == list(range(10))
    pairs = [np.flatnonzero(nd == k) for k in range(1, 9)]
    assert all(p.size == 2 for p in pairs)
    assert max(abs(f[p[1]] / f[p[0]] - 1) for p in pairs) <= 1e-7
    # δ = 0 reproduces the tuned model exactly.
    zero = assemble_full(bd, b, ContactPattern.full(GRID), np.zeros((N, b.m)))
    ref = assemble_full(bd, b, ContactPattern.full(GRID))
    assert (zero.K != ref.K).nnz == 0 and (zero.M != ref.M).nnz == 0
    # Random blade mistuning splits every pair.
    rng = np.random.default_rng(1)
    mist = solve_full(bd, b, ContactPattern.full(GRID), rng.uniform(-0.02, 0.02, (N, 1)), n_modes=N)
    gaps = np.diff(mist.frequencies_hz) / mist.frequencies_hz[:-1]
    assert gaps.min() >= 1e-5


def test_bad_inputs_give_clear_errors():
    bd, b = rom_models.bladed_disk(), rom_models.blade()
    full = ContactPattern.full(GRID)
    with pytest.raises(ValueError, match=r"missing \[18\]"):
        assemble_full(bd, b, {s: full for s in range(1, N)})
    with pytest.raises(ValueError, match="slot must be an integer in 1..18"):
        assemble_full(bd, b, {**{s: full for s in range(1, N + 1)}, 19: full})
    with pytest.raises(ValueError, match="one row per blade"):
        assemble_full(bd, b, full, np.zeros((N - 1, 3)))
    with pytest.raises(ValueError, match="finite"):
        assemble_full(bd, b, full, np.full((N, 3), np.nan))
    with pytest.raises(ValueError, match="grid shape"):
        assemble_full(bd, b, ContactPattern.full((3, 9)))
    with pytest.raises(ValueError, match="reduced on all slots"):
        assemble_full(rom_models.disk_cb(), b, full)
