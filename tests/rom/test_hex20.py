"""The hex20 element and mesher against analytic beam theory (independent references)."""

import math

import numpy as np
import pytest

from rom.hex20 import assemble, element_volumes, shape_functions
from rom.mesh import structured_hex20
from rom.solver import solve_modes

E, NU, RHO = 210e9, 0.3, 7800.0


def _box(L, b, h, n):
    cells = (n[0], n[1], n[2])
    return structured_hex20(
        cells, lambda I, J, K: np.stack([I / (2 * cells[0]) * L, J / (2 * cells[1]) * b, K / (2 * cells[2]) * h], 1)
    )


def _clamped_modes(mesh, n):
    K, M = assemble(mesh.coords, mesh.conn, E, NU, RHO)
    fixed = np.flatnonzero(mesh.coords[:, 0] < 1e-12)
    keep = np.setdiff1d(np.arange(K.shape[0]), (3 * fixed[:, None] + np.arange(3)).ravel())
    return solve_modes(K[keep][:, keep], M[keep][:, keep], n, backend="superlu", max_rigid=0)


def test_shape_functions_partition_of_unity_and_kronecker():
    rng = np.random.default_rng(0)
    N, dN = shape_functions(rng.uniform(-1, 1, (10, 3)))
    np.testing.assert_allclose(N.sum(axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(dN.sum(axis=1), 0.0, atol=1e-13)
    from rom.hex20 import REF_NODES

    np.testing.assert_allclose(shape_functions(REF_NODES)[0], np.eye(20), atol=1e-14)


def test_clamped_beam_bending_and_torsion_within_2_percent():
    """Square cantilever, L/a = 25: Euler–Bernoulli bending and Saint-Venant torsion (J = 0.1406 a⁴)."""
    L, a = 0.1, 0.004
    sol = _clamped_modes(_box(L, a, a, (16, 2, 2)), 8)
    A, I = a * a, a**4 / 12
    f_bend = 1.8751**2 / (2 * math.pi * L**2) * math.sqrt(E * I / (RHO * A))
    G = E / (2 * (1 + NU))
    f_tors = 1 / (4 * L) * math.sqrt(G * 0.1406 * a**4 / (RHO * a**4 / 6))
    f = sol.frequencies_hz
    # The two bending directions are degenerate for a square section.
    assert abs(f[0] / f_bend - 1) < 0.02 and abs(f[1] / f_bend - 1) < 0.02
    torsion = f[np.argmin(abs(f / f_tors - 1))]
    assert abs(torsion / f_tors - 1) < 0.02


def test_frequencies_converge_from_above_under_refinement():
    L, b, h = 0.1, 0.01, 0.002
    seq = [_clamped_modes(_box(L, b, h, (n, 1, 1)), 3).frequencies_hz for n in (3, 6, 12, 24)]
    for coarse, fine in zip(seq[:-1], seq[1:], strict=True):
        assert np.all(fine <= coarse * (1 + 1e-10))
    # ... and towards the plate-strip limit between beam theory and plate (1/√(1-ν²)) theory.
    I = b * h**3 / 12
    f_beam = 1.8751**2 / (2 * math.pi * L**2) * math.sqrt(E * I / (RHO * b * h))
    assert f_beam < seq[-1][0] < f_beam / math.sqrt(1 - NU**2)


def test_volume_of_distorted_mapped_block_is_exact():
    # A quarter annulus: quadratic elements represent the arc to high order.
    ri, ro, t = 0.02, 0.05, 0.01
    n = 8

    def pos(I, J, K):
        th = J / (2 * n) * math.pi / 2
        r = ri + I / 4 * (ro - ri)
        return np.stack([r * np.cos(th), r * np.sin(th), K / 2 * t], 1)

    m = structured_hex20((2, n, 1), pos)
    vol = element_volumes(m.coords, m.conn).sum()
    assert abs(vol / (math.pi / 4 * (ro**2 - ri**2) * t) - 1) < 1e-5


def test_bad_material_raises():
    m = _box(1, 1, 1, (1, 1, 1))
    with pytest.raises(ValueError, match="nu"):
        assemble(m.coords, m.conn, E, 0.5, RHO)
