"""Dense eigen-solves: the in-place option changes nothing but the caller's (throw-away) matrices."""

import numpy as np
import scipy.linalg as sla

from rom.contact import ContactPattern
from rom.modal import dense_modes
from rom.rom_assembly import assemble_d1b, solve_assembly, solve_d1b

from . import rom_models


def test_default_leaves_inputs_untouched_and_in_place_agrees():
    asm = assemble_d1b(rom_models.disk_cb(), rom_models.blade(), ContactPattern.full((3, 7)))
    K0, M0 = asm.K.copy(), asm.M.copy()
    ref = dense_modes(asm.K, asm.M, 8)
    np.testing.assert_array_equal(asm.K, K0)
    np.testing.assert_array_equal(asm.M, M0)
    inplace = dense_modes(K0, M0, 8, overwrite=True)
    np.testing.assert_allclose(inplace.frequencies_hz, ref.frequencies_hz, rtol=1e-12)
    # ... and both are the pencil's eigenvalues from an independent full solve (another LAPACK driver).
    # Backward-stable solvers agree to about n·ε·max|λ| in absolute terms, so the check is on λ with that bound.
    lam_full = sla.eigh(asm.K, asm.M, eigvals_only=True)
    lam_ref = (2 * np.pi * ref.frequencies_hz) ** 2
    bound = 10 * asm.K.shape[0] * np.finfo(float).eps * np.abs(lam_full).max()
    np.testing.assert_allclose(lam_ref, lam_full[ref.n_rigid : ref.n_rigid + 8], rtol=0, atol=bound)
    assert bound < 1e-4 * lam_ref[0]  # still ~100x tighter than the 0.3 % (in frequency) model tolerance


def test_solve_d1b_equals_assemble_then_solve():
    pat = ContactPattern.random((3, 7), 0.5, np.random.default_rng(11))
    disk, blade = rom_models.disk_cb(), rom_models.blade()
    a = solve_d1b(disk, blade, pat)
    b = solve_assembly(assemble_d1b(disk, blade, pat), 10)
    np.testing.assert_allclose(a.frequencies_hz, b.frequencies_hz, rtol=1e-12)
    np.testing.assert_allclose(np.abs(a.meas_shapes), np.abs(b.meas_shapes), rtol=1e-8, atol=1e-12)
