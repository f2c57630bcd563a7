"""Campaign tables, MAC and pairing against constructed truth."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ema import ModalModel, blade_deltas, disk_modes, joint_frequencies, mac, nodal_diameters, pair_modes, write_table
from ema.campaign import nodal_diameter_purity
from ema.mac import automac


def _blade_campaign(n_blades=18, seed=5):
    rng = np.random.default_rng(seed)
    dofs = [(k, 3) for k in range(1, 10)]
    base_f = np.array([300.0, 800.0, 805.0, 1500.0, 2200.0])
    shapes = np.linalg.qr(rng.standard_normal((9, 5)))[0]
    true_delta = rng.uniform(-0.02, 0.02, (n_blades, 5))  # relative eigenvalue perturbations
    models, perms = {}, []
    f = base_f[None, :] * np.sqrt(1 + true_delta)
    for b in range(n_blades):
        perm = rng.permutation(5)  # stored in arbitrary order; modes 2/3 swap in frequency blade to blade
        perms.append(perm)
        phi = shapes + 0.02 * rng.standard_normal(shapes.shape)
        models[f"blade{b + 1:02d}"] = ModalModel(f[b, perm], np.full(5, 0.001), phi[:, perm], dofs)
    expected = (f**2 - np.mean(f**2, axis=0)) / np.mean(f**2, axis=0) * 100
    return models, expected, f


def test_blade_deltas_track_swapping_modes():
    models, expected, f = _blade_campaign()
    # modes 2 and 3 (800 / 805 Hz, +-1 % scatter) really do swap order on some blades
    assert np.any(f[:, 1] > f[:, 2]) and np.any(f[:, 1] < f[:, 2])
    table = blade_deltas(models)
    assert table.shape == (18, 5) and table.index.name == "blade"
    assert np.max(np.abs(table.to_numpy() - expected)) < 0.05


def test_joint_frequencies_and_csv(tmp_path):
    models, _, f = _blade_campaign(n_blades=4)
    table = joint_frequencies(models)
    np.testing.assert_allclose(table.to_numpy(), f, rtol=1e-12)
    path = write_table(table, tmp_path / "sub" / "joint_frequencies.csv")
    back = pd.read_csv(path, index_col=0)
    np.testing.assert_allclose(back.to_numpy(), f, rtol=1e-5)
    assert not [p for p in path.parent.iterdir() if p.suffix == ".tmp"]


def test_disk_nodal_diameters_0_to_4():
    n = 18
    theta = 2 * np.pi * np.arange(n) / n
    rng = np.random.default_rng(6)
    nds = np.array([2, 0, 3, 1, 4, 4, 1])
    shapes = np.column_stack([np.cos(k * theta + rng.uniform(0, np.pi)) for k in nds])
    shapes += 0.05 * rng.standard_normal(shapes.shape)
    nd = nodal_diameters(shapes)
    assert isinstance(nd, np.ndarray) and nd.dtype.kind == "i" and nd.shape == (nds.size,)
    np.testing.assert_array_equal(nd, nds)
    assert np.all(nodal_diameter_purity(shapes) > 0.9)
    # travelling (complex) shape and DOF ordering by node through disk_modes
    order = rng.permutation(n)
    dofs = [(int(100 + k), 3) for k in range(n)]
    model = ModalModel(np.arange(1, 8) * 100.0, np.full(7, 0.002), shapes[order], [dofs[k] for k in order])
    table = disk_modes(model)
    np.testing.assert_array_equal(table["nodal_diameter"].to_numpy(), nds)
    assert table["nd_purity"].to_numpy().min() > 0.9
    assert nodal_diameters(np.exp(1j * 3 * theta))[0] == 3


def test_mac_and_pairing():
    rng = np.random.default_rng(7)
    phi = np.linalg.qr(rng.standard_normal((10, 4)))[0]
    np.testing.assert_allclose(automac(phi), np.eye(4), atol=1e-12)
    assert mac(phi[:, 0], 2j * phi[:, 0]).shape == (1, 1) and np.isclose(mac(phi[:, 0], -phi[:, 0])[0, 0], 1)
    dofs = [(k, 3) for k in range(10)]
    a = ModalModel([100, 200, 300, 400], np.full(4, 0.01), phi, dofs)
    # b: swapped order, one mode missing, one extra far away, one sign-flipped DOF label
    b_phi = np.column_stack([phi[:, 1], phi[:, 0], phi[:, 3], rng.standard_normal(10)])
    b_phi[0] *= -1
    b_dofs = [(0, -3)] + dofs[1:]
    b = ModalModel([201, 99, 401, 1000], np.full(4, 0.01), b_phi, b_dofs)
    p = pair_modes(a, b, freq_window=0.05)
    assert p.pairs.tolist() == [[0, 1], [1, 0], [3, 2]]
    assert np.all(p.mac > 0.999)
    assert p.unpaired_a.tolist() == [2] and p.unpaired_b.tolist() == [3]
