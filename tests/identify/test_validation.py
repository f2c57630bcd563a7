"""Validation metrics (paper §7, Eqs. 40–42, Table 8) against hand-computed references."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from ema.modal import ModalModel
from identify.errors import IdentifyError
from identify.knn import TwoStepKNN
from identify.validation import (
    compare_modes,
    contact_area_fraction,
    contact_centroid,
    d1b_validation,
    geometric_validation,
    grid_error,
    pair_patterns,
)
from rom import ContactPattern, solve_d1b
from rom.academic import flank_coordinates
from rom.fe_assembly import AssemblyModes

from ..rom.rom_models import blade, bladed_disk, disk_cb


# ------------------------------------------------------------------------------------------- Eq. 40
def test_grid_error_hand_computed():
    pred = [[0.010, 0.000, 0.010], [0.005, -0.005, 0.010]]
    ref = [[0.0112, 0.0024, 0.0126], [0.0075, -0.0050, 0.0074]]
    e = grid_error(pred, ref, 0.005)
    np.testing.assert_allclose(e.epsilon_pct, [[-24, -48, -52], [-50, 0, 52]], atol=1e-9)
    np.testing.assert_array_equal(e.nearest, [[True, True, False], [True, True, False]])
    e2 = grid_error(pred, ref, [0.005, 0.01, 0.02])  # one step per mode
    np.testing.assert_allclose(e2.epsilon_pct[0], [-24, -24, -13], atol=1e-9)
    with pytest.raises(IdentifyError, match="step"):
        grid_error(pred, ref, 0.0)
    with pytest.raises(IdentifyError, match="delta_pred"):
        grid_error(pred, ref[:1], 0.005)


def test_step_one_on_a_full_grid_is_always_within_half_a_step():
    # Paper §7: on a tensor grid spanning the data, the nearest δ row gives |ε| ≤ 50 % for every mode.
    rng = np.random.default_rng(2)
    grid = np.arange(-0.005, 0.0201, 0.005)
    D = np.stack(np.meshgrid(grid, grid, grid, indexing="ij"), -1).reshape(-1, 3)
    X = np.hstack([D, rng.normal(size=(D.shape[0], 2))])
    est = TwoStepKNN(n_delta_modes=3).fit(X, np.arange(D.shape[0]) % 4)
    dq = rng.uniform(-0.005, 0.02, (200, 3))
    e = grid_error(est.match(np.hstack([dq, np.zeros((200, 2))])).delta, dq, 0.005)
    assert e.nearest.all()
    assert np.abs(e.epsilon_pct).max() > 45  # the sample reaches the bound, so the check has teeth


# -------------------------------------------------------------------------------------- Eqs. 41, 42
def rectangle(shape, r0, r1, c0, c1):
    g = np.zeros(shape, bool)
    g[r0 : r1 + 1, c0 : c1 + 1] = True
    return g


def test_rectangle_area_and_centroid_on_uniform_coordinates():
    shape = (5, 9)
    u = np.broadcast_to((np.arange(5) * 2e-3 - 4e-3)[:, None], shape)  # axial, 2 mm pitch
    v = np.broadcast_to((0.09 + np.arange(9) * 1.5e-3)[None, :], shape)  # radial, 1.5 mm pitch
    g = rectangle(shape, 1, 3, 2, 6)
    assert contact_area_fraction(g) == pytest.approx(15 / 45 * 100)
    # Symmetric rectangle on a uniform grid: the centroid is the midpoint of its corner nodes.
    np.testing.assert_allclose(contact_centroid(g, u, v), [(u[1, 0] + u[3, 0]) / 2, (v[0, 2] + v[0, 6]) / 2],
                               rtol=1e-14)
    stack = np.array([g, np.zeros(shape, bool), np.ones(shape, bool)])
    np.testing.assert_allclose(contact_area_fraction(stack), [100 / 3, 0, 100])
    c = contact_centroid(stack, u, v)
    assert c.shape == (3, 2) and np.isnan(c[1]).all()
    np.testing.assert_allclose(c[2], [u.mean(), v.mean()], rtol=1e-14)


def test_geometric_validation_on_the_model_flank():
    bd = bladed_disk(4)
    u, v = flank_coordinates(bd)
    shape = u.shape  # (3, 7)
    ref = [ContactPattern(rectangle(shape, 0, 2, 0, 3), rectangle(shape, 0, 1, 2, 6))]
    pred = [ContactPattern(rectangle(shape, 0, 2, 1, 4), rectangle(shape, 0, 1, 2, 6))]
    gv = geometric_validation(pred, ref, bd)
    np.testing.assert_allclose(gv.area_pct_ref, [[12 / 21 * 100, 10 / 21 * 100]])
    np.testing.assert_allclose(gv.area_error_pct, [[0.0, 0.0]], atol=1e-12)
    # L moves one column outward: the centroid moves by one radial pitch, the R flank not at all.
    pitch = v[0, 1] - v[0, 0]
    np.testing.assert_allclose(gv.centroid_distance, [[pitch, 0.0]], atol=1e-15)
    np.testing.assert_allclose(gv.centroid_ref[0, 0], [u[:, 0].mean(), v[0, :4].mean()])
    arr = geometric_validation(np.array([[p.L, p.R] for p in pred]), np.array([[p.L, p.R] for p in ref]), (u, v))
    np.testing.assert_array_equal(arr.centroid_pred, gv.centroid_pred)


def test_pair_patterns_picks_flank_grids():
    rng = np.random.default_rng(0)

    @dataclass(frozen=True)
    class DS:
        patterns_L: np.ndarray
        patterns_R: np.ndarray

    ds = DS(rng.random((3, 2, 4)) < 0.5, rng.random((2, 2, 4)) < 0.5)
    g = pair_patterns(ds, np.array([[2, 0], [0, 1]]))
    assert g.shape == (2, 2, 2, 4)
    np.testing.assert_array_equal(g[0, 0], ds.patterns_L[2])
    np.testing.assert_array_equal(g[1, 1], ds.patterns_R[1])
    with pytest.raises(IdentifyError, match="pairs row 1: index 2 outside dataset.patterns_R"):
        pair_patterns(ds, np.array([[0, 0], [0, 2]]))


# ------------------------------------------------------------------------------------- dynamic (MAC)
def orthonormal_shapes(n_dof, n_modes, seed=0):
    return np.linalg.qr(np.random.default_rng(seed).normal(size=(n_dof, n_modes)))[0]


def test_identical_modes_give_mac_one_and_zero_error():
    f = np.array([100.0, 180.0, 250.0, 400.0])
    phi = orthonormal_shapes(12, 4)
    c = compare_modes((f, phi), (f, phi))
    np.testing.assert_array_equal(c.pairs, [[0, 0], [1, 1], [2, 2], [3, 3]])
    np.testing.assert_allclose(c.mac, 1.0, rtol=1e-12)
    np.testing.assert_allclose(c.freq_error_pct, 0.0)
    assert c.mean_abs_freq_error_pct == 0.0 and c.mean_mac == pytest.approx(1.0)


def test_permuted_scaled_modes_are_paired_back():
    f = np.array([100.0, 101.0, 250.0, 251.0, 400.0])
    phi = orthonormal_shapes(10, 5, seed=1)
    err = np.array([0.004, -0.002, 0.001, -0.003, 0.0])  # relative frequency errors of the prediction
    perm = np.array([1, 0, 3, 2, 4])  # predicted mode k is reference mode perm[k]: close pairs swapped
    scale = np.array([-2.0, 0.5, 3.0, -1.0, 1e3])  # MAC ignores scale and sign
    c = compare_modes((f, phi), (f[perm] * (1 + err[perm]), phi[:, perm] * scale))
    np.testing.assert_array_equal(c.pairs, np.column_stack([np.arange(5), np.argsort(perm)]))
    np.testing.assert_allclose(c.freq_error_pct, err * 100, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c.mac, 1.0, rtol=1e-12)
    assert c.mean_abs_freq_error_pct == pytest.approx(np.mean(np.abs(err)) * 100)
    # Index pairing would have matched the swapped modes (MAC 0): the assignment is what pairs them back.
    assert compare_modes((f, phi), (f[perm], phi[:, perm]), pairing="index").mean_mac == pytest.approx(0.2)


def test_mean_mac_of_rotated_shapes_and_frequency_window():
    f = np.array([100.0, 200.0, 300.0])
    e = np.eye(6)
    th = np.array([0.2, 0.5, 0.0])
    # Predicted mode j = cos θ e_j + sin θ e_{j+3}: its MAC with reference e_j is cos² θ.
    pred = e[:, :3] * np.cos(th) + e[:, 3:] * np.sin(th)
    c = compare_modes((f, e[:, :3]), (f * [1.0, 1.0, 1.5], pred))
    np.testing.assert_array_equal(c.pairs, [[0, 0], [1, 1]])  # mode 3 is 50 % away: outside the 10 % window
    np.testing.assert_allclose(c.mac, np.cos(th[:2]) ** 2, rtol=1e-12)
    assert c.mean_mac == pytest.approx(np.mean(np.cos(th[:2]) ** 2))
    np.testing.assert_array_equal(c.unpaired_ref, [2])
    np.testing.assert_array_equal(c.unpaired_pred, [2])
    c_all = compare_modes((f, e[:, :3]), (f * [1.0, 1.0, 1.5], pred), freq_window=None)
    assert c_all.pairs.shape == (3, 2) and c_all.mean_abs_freq_error_pct == pytest.approx(50 / 3)


def test_modal_model_rows_matched_by_dof_label_and_sign():
    f = np.array([120.0, 340.0])
    phi = orthonormal_shapes(4, 2, seed=3)
    dofs = ((1, 3), (2, 3), (3, 3), (4, 3))
    ref = ModalModel(f, np.zeros(2), phi, dofs)
    # The prediction lists the DOFs in another order, one with the opposite sign convention, plus an extra DOF.
    order = [2, 0, 3, 1]
    sign = np.array([1.0, 1.0, -1.0, 1.0])
    rows = np.vstack([phi[order] * sign[:, None], [[5.0, -7.0]]])
    pred = ModalModel(f, np.zeros(2), rows, ((3, 3), (1, 3), (4, -3), (2, 3), (9, 1)))
    c = compare_modes(ref, pred)
    np.testing.assert_allclose(c.mac, 1.0, rtol=1e-12)
    with pytest.raises(IdentifyError, match="no common DOF"):
        compare_modes(ref, ModalModel(f, np.zeros(2), phi, ((5, 1), (6, 1), (7, 1), (8, 1))))


def test_d1b_validation_on_rom_modes_matched_by_measurement_label():
    disk, bl = disk_cb(4), blade(4)
    rng = np.random.default_rng(7)
    pa, pb = (ContactPattern.random((3, 7), 0.5, rng) for _ in range(2))
    ma = solve_d1b(disk, bl, pa, n_modes=8)
    mb = solve_d1b(disk, bl, pb, n_modes=8, delta=[0.01])
    # The same modes with their measurement rows shuffled (labels carried along) must compare as equal.
    perm = rng.permutation(ma.meas_shapes.shape[0])
    ma_shuffled = AssemblyModes(ma.frequencies_hz, ma.meas_shapes[perm], [ma.meas_labels[k] for k in perm])
    v = d1b_validation([ma, ma], [ma_shuffled, mb], feature_modes=(4, 5, 7))
    np.testing.assert_allclose(v.freq_error_pct[0], 0.0, atol=1e-10)
    np.testing.assert_allclose(v.mac[0], 1.0, rtol=1e-10)
    np.testing.assert_allclose(v.freq_ref_hz, ma.frequencies_hz[[4, 5, 7]][None].repeat(2, 0))
    # Joint 2 is a genuinely different model: compare with the pairing done by hand on plain arrays.
    c = compare_modes((ma.frequencies_hz, ma.meas_shapes), (mb.frequencies_hz, mb.meas_shapes))
    for col, k in enumerate((4, 5, 7)):
        i = np.flatnonzero(c.pairs[:, 0] == k)
        if i.size:
            j = c.pairs[i[0], 1]
            assert v.freq_error_pct[1, col] == pytest.approx((mb.frequencies_hz[j] / ma.frequencies_hz[k] - 1) * 100)
        else:
            assert np.isnan(v.mac[1, col])
    assert not np.allclose(v.freq_error_pct[1], 0.0)
    with pytest.raises(IdentifyError, match="feature mode 9"):
        d1b_validation([ma], [mb], feature_modes=(9,))


def test_compare_modes_mac_min_leaves_a_mode_without_a_credible_partner_unpaired():
    # mode 2 of the "measurement" is noise-like: orthogonal to every predicted shape within the window
    ref_shapes = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    pred_shapes = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    f_ref, f_pred = np.array([100.0, 200.0]), np.array([100.5, 201.0])
    forced = compare_modes((f_ref, ref_shapes), (f_pred, pred_shapes))
    assert len(forced.pairs) == 2 and forced.mac[1] == pytest.approx(0.0)
    kept = compare_modes((f_ref, ref_shapes), (f_pred, pred_shapes), mac_min=0.3)
    assert kept.pairs.tolist() == [[0, 0]] and kept.unpaired_ref.tolist() == [1]
    assert kept.mean_mac == pytest.approx(1.0) and kept.mean_abs_freq_error_pct == pytest.approx(0.5)
    with pytest.raises(IdentifyError, match="mac_min"):
        compare_modes((f_ref, ref_shapes), (f_pred, pred_shapes), mac_min=1.0)
