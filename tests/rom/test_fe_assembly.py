"""FE reference assembly: ties, cyclic symmetry of the placement, contact-pattern validation."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from rom.contact import ContactPattern
from rom.fe_assembly import assemble_fe, solve_fe
from rom.solver import solve_modes

GRID = (3, 7)


def test_bonded_disk_one_blade_is_one_free_body(coarse_bd):
    asm = assemble_fe(coarse_bd, {1: ContactPattern.full(GRID)})
    sol = solve_modes(asm.K, asm.M, 4, max_rigid=8)
    assert sol.n_rigid == 6  # a wrong tie (e.g. a rotation error) would add or remove rigid-body modes
    # A rigid translation along global x is representable exactly (disk: e_x, blade in its frame: Rᵀ e_x)
    # and carries the total mass of disk + blade.
    nd, nb = coarse_bd.disk.n_dof, coarse_bd.blade.n_dof
    t = np.zeros(asm.Z.shape[0])
    t[:nd:3] = 1.0
    t[nd:] = np.tile(coarse_bd.slot_rotation(1).T @ np.array([1.0, 0.0, 0.0]), nb // 3)
    q = spla.spsolve((asm.Z.T @ asm.Z).tocsc(), asm.Z.T @ t)
    np.testing.assert_allclose(asm.Z @ q, t, atol=1e-12)
    assert q @ (asm.M @ q) == pytest.approx(coarse_bd.disk.mass() + coarse_bd.blade.mass(), rel=1e-12)
    assert q @ (asm.K @ q) == pytest.approx(0.0, abs=1e-6 * abs(asm.K).max())


def test_every_slot_gives_the_same_disk_one_blade_frequencies(coarse_bd):
    """The placement rotation and the tie must respect cyclic symmetry exactly."""
    pat = ContactPattern.random(GRID, 0.5, np.random.default_rng(3))
    f1 = solve_fe(assemble_fe(coarse_bd, {1: pat}), 8).frequencies_hz
    f7 = solve_fe(assemble_fe(coarse_bd, {7: pat}), 8).frequencies_hz
    np.testing.assert_allclose(f7, f1, rtol=1e-8)


def test_less_contact_is_more_flexible(coarse_bd):
    """Removing ties removes constraints: by Rayleigh's principle, no frequency may rise."""
    rng = np.random.default_rng(5)
    full = ContactPattern.full(GRID)
    part = ContactPattern(full.L & (rng.random(GRID) < 0.5), full.R)
    f_full = solve_fe(assemble_fe(coarse_bd, {1: full}), 10).frequencies_hz
    f_part = solve_fe(assemble_fe(coarse_bd, {1: part}), 10).frequencies_hz
    assert np.all(f_part <= f_full * (1 + 1e-9))


def test_measurement_labels(coarse_bd):
    asm = assemble_fe(coarse_bd, {2: ContactPattern.full(GRID), 5: ContactPattern.full(GRID)})
    blade = [lab for lab in asm.meas_labels if lab[0] == "blade"]
    assert blade == [("blade", s, p, 1) for s in (2, 5) for p in (1, 2, 3)]
    assert sum(lab[0] == "disk" for lab in asm.meas_labels) == coarse_bd.n_slots


@pytest.mark.parametrize(
    ("L", "R", "match"),
    [
        (np.zeros(GRID, bool), np.zeros(GRID, bool), "float free"),
        (np.zeros((3, 8), bool), np.ones((3, 8), bool), None),
        (np.ones(GRID, bool), np.ones((3, 5), bool), "same shape"),
        (np.full(GRID, 2), np.ones(GRID, bool), "boolean"),
    ],
)
def test_bad_patterns(L, R, match):
    if match is None:  # valid pattern, but the wrong grid for this model
        pat = ContactPattern(L, R)
        with pytest.raises(ValueError, match="grid shape"):
            pat.check_shape(GRID)
    else:
        with pytest.raises(ValueError, match=match):
            ContactPattern(L, R)


def test_slot_out_of_range(coarse_bd):
    with pytest.raises(ValueError, match="slot must be an integer in 1..18"):
        assemble_fe(coarse_bd, {19: ContactPattern.full(GRID)})
