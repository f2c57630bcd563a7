"""The one MAC implementation of ema: matrix and row-paired forms, scale safety, the distinct-vector bound."""

from __future__ import annotations

import numpy as np
import pytest

from ema import EMAError
from ema.mac import ScaledRows, distinct_mac, mac, mac_paired


def _direct(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Textbook MAC of the columns, |a^H b|^2 / ((a^H a)(b^H b)), at unit scale."""
    out = np.empty((a.shape[1], b.shape[1]))
    for i in range(a.shape[1]):
        for j in range(b.shape[1]):
            out[i, j] = abs(np.vdot(a[:, i], b[:, j])) ** 2 / (np.vdot(a[:, i], a[:, i]).real
                                                              * np.vdot(b[:, j], b[:, j]).real)
    return out


def _shapes(seed: int, n_dof: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n_dof, n)) + 1j * rng.standard_normal((n_dof, n))


def test_mac_matches_direct_formula_at_unit_scale():
    a, b = _shapes(1, 7, 4), _shapes(2, 7, 5)
    M = mac(a, b)
    assert M.shape == (4, 5)
    np.testing.assert_allclose(M, _direct(a, b), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.diag(mac(a, a)), 1.0, rtol=1e-12)


@pytest.mark.parametrize("scale", [1e-156, 1e-300, 1e144, 1e300])
def test_mac_is_scale_safe(scale):
    # the products of shapes of these magnitudes under- or overflow float64 when formed directly
    a, b = _shapes(3, 6, 3), _shapes(4, 6, 2)
    expected = _direct(a, b)
    np.testing.assert_allclose(mac(scale * a, b), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(mac(scale * a, scale * b), expected, rtol=1e-12, atol=1e-15)
    # one column tiny, the other huge, in the same set
    mixed = a * np.array([scale, 1.0 / scale, 1.0])
    np.testing.assert_allclose(mac(mixed, b), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(mac_paired(scale * a.T[:2], b.T), np.diag(expected[:2, :2]), rtol=1e-12)


def test_mac_paired_is_the_diagonal():
    a, b = _shapes(5, 9, 6), _shapes(6, 9, 6)
    p = mac_paired(a.T, b.T)
    assert p.shape == (6,)
    np.testing.assert_allclose(p, np.diag(_direct(a, b)), rtol=1e-12, atol=1e-15)
    # scale and phase of either vector do not matter
    np.testing.assert_allclose(mac_paired(3j * a.T, -0.5 * b.T), p, rtol=1e-12)


def test_zero_vectors_and_bad_shapes():
    a = _shapes(7, 5, 2)
    a[:, 1] = 0.0
    M = mac(a, a)
    assert M[1, 1] == 0.0 and M[0, 1] == 0.0 and np.isclose(M[0, 0], 1.0)
    assert mac_paired(a.T, a.T).tolist() == [pytest.approx(1.0), 0.0]
    assert mac(a[:, 0], 2j * a[:, 0]).shape == (1, 1)
    with pytest.raises(EMAError, match="mac"):
        mac(np.ones((3, 2)), np.ones((4, 2)))
    with pytest.raises(EMAError, match="mac_paired"):
        mac_paired(np.ones((3, 2)), np.ones((2, 3)))


def test_distinct_mac_bound():
    # two vectors each within the linking angle of a mode's vector are within twice that angle
    assert distinct_mac(0.95) == pytest.approx(np.cos(2 * np.arccos(np.sqrt(0.95))) ** 2)
    assert 0.80 < distinct_mac(0.95) < 0.82
    assert distinct_mac(1.0) == pytest.approx(1.0)
    assert distinct_mac(0.5) == pytest.approx(0.0, abs=1e-15)
    assert distinct_mac(0.0) == pytest.approx(0.0, abs=1e-15)


def test_scaled_rows_give_mac_paired_bit_for_bit():
    """Scaling each vector once, then gathering pairs (in any blocks), gives mac_paired's values exactly."""
    rng = np.random.default_rng(3)
    v = rng.standard_normal((40, 9)) + 1j * rng.standard_normal((40, 9))
    v[3] *= 1e-150  # the scaling must keep its squares in range
    v[7] *= 1e150
    v[11] = 0.0
    i, j = rng.integers(0, 40, 500), rng.integers(0, 40, 500)
    s = ScaledRows.of(v)
    expected = mac_paired(v[i], v[j])
    assert np.array_equal(s.mac(i, s, j), expected)
    assert np.array_equal(s.mac(i, s, j, block_entries=9 * 7), expected)  # 7 pairs per block
    w = rng.standard_normal((5, 9))
    assert np.array_equal(ScaledRows.of(w).mac([0, 4], s, [7, 11]), mac_paired(w[[0, 4]], v[[7, 11]]))
    with pytest.raises(EMAError, match="row indices"):
        s.mac([0, 1], s, [2])
    with pytest.raises(EMAError, match="2-D"):
        ScaledRows.of(np.ones(3))


def test_weighted_mac_against_its_definition():
    """The mass-weighted MAC the identification tracks modes with, against (aᵀWb)²/((aᵀWa)(bᵀWb))."""
    rng = np.random.default_rng(0)
    A, B = rng.standard_normal((6, 2)), rng.standard_normal((6, 3))
    C = rng.standard_normal((6, 6))
    W = C @ C.T + 6 * np.eye(6)
    expect = [[(a @ W @ b) ** 2 / ((a @ W @ a) * (b @ W @ b)) for b in B.T] for a in A.T]
    np.testing.assert_allclose(mac(A, B, weight=W), expect, rtol=1e-12)
    # a zero shape gives 0, not NaN, weighted or not
    A[:, 0] = 0.0
    assert np.all(mac(A, B, weight=W)[0] == 0.0) and np.all(mac(A, B)[0] == 0.0)
    with pytest.raises(EMAError, match="weight"):
        mac(A, B, weight=np.eye(5))


def test_pair_by_frequency_with_an_unpaired_cost_leaves_a_mode_rather_than_push_two_off():
    from ema.mac import pair_by_frequency

    # 100 Hz has 100.2 Hz beside it; 104 Hz has only 100.2 Hz within 5 % (3.7 %), and 100 Hz also 96 Hz (4 %)
    fa, fb = np.array([100.0, 104.0]), np.array([96.0, 100.2])
    rows, cols = pair_by_frequency(fa, fb, 0.05)  # as many pairs as possible: 100 → 96, 104 → 100.2
    assert rows.tolist() == [0, 1] and cols.tolist() == [0, 1]
    # 104 Hz left unpaired costs 5 %: 0.2 % + 5 % is less than 4 % + 3.7 %
    rows, cols = pair_by_frequency(fa, fb, 0.05, unpaired_cost=True)
    assert rows.tolist() == [0] and cols.tolist() == [1]
    # a pair further than the window is never made, with or without the cost
    assert pair_by_frequency([100.0], [200.0], 0.05, unpaired_cost=True)[0].size == 0
