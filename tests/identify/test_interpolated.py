"""δ-interpolated pattern matching (identify.interpolated) against hand-built datasets with known answers."""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np
import pytest

from identify.errors import IdentifyError
from identify.interpolated import match_interpolated, pair_grid

GRID = np.array([-0.005, 0.0, 0.005, 0.01])


def _dataset(rng, n_pairs=6, shuffle=True):
    """Frequencies affine in δ per pair (so multilinear interpolation is exact), 3 δ modes, 4 tracked modes."""
    rows = np.array(list(itertools.product(GRID, repeat=3)))
    base = 1000 + 50 * rng.random((n_pairs, 4))
    slope = 100 * rng.random((n_pairs, 3, 4))
    deltas, pair, freq = [], [], []
    for p in range(n_pairs):
        for d in rows:
            deltas.append(d)
            pair.append((p // 3, p % 3))
            freq.append(base[p] + d @ slope[p])
    deltas, pair, freq = np.array(deltas), np.array(pair), np.array(freq)
    if shuffle:
        order = rng.permutation(len(deltas))
        deltas, pair, freq = deltas[order], pair[order], freq[order]
    ds = SimpleNamespace(deltas=deltas, pair=pair, frequencies_hz=freq, delta_grid=GRID, feature_modes=(0, 2, 3),
                         weights=np.array([0.2, 0.3, 0.5]))
    return ds, base, slope


def test_exact_on_affine_data_and_finds_the_generating_pair():
    rng = np.random.default_rng(0)
    ds, base, slope = _dataset(rng)
    pairs, F = pair_grid(ds)
    assert F.shape == (6, 4, 4, 4, 4) and not np.isnan(F).any()
    d = np.array([[0.0013, -0.0031, 0.0072], [0.0099, 0.0004, -0.0049]])
    for p in range(6):
        y = base[p] + d @ slope[p]  # (2, 4): the pair's features at off-grid δ
        m = match_interpolated(ds, d, y[:, [0, 2, 3]], n_neighbors=6)
        iL, iR = pairs[p]
        assert [tuple(x) for x in m.label[:, 0]] == [(iL, iR)] * 2
        np.testing.assert_allclose(m.distance[:, 0], 0, atol=1e-9)
        np.testing.assert_allclose(m.features_hz[:, 0], y[:, [0, 2, 3]], rtol=1e-12)
        assert np.all(np.diff(m.distance, axis=1) >= 0)


def test_distance_is_eq33_with_eq39_normalisation():
    rng = np.random.default_rng(1)
    ds, base, slope = _dataset(rng)
    d = np.array([[0.002, 0.003, -0.001]])
    y = np.array([[1020.0, 1030.0, 1010.0]])
    m = match_interpolated(ds, d, y, n_neighbors=6)
    C = np.array([base[p] + d[0] @ slope[p] for p in range(6)])[:, [0, 2, 3]]
    ref = np.sqrt(np.sum(ds.weights * ((C - y) / C.std(axis=0)) ** 2, axis=1))
    pairs, _ = pair_grid(ds)
    got = {tuple(lab): dist for lab, dist in zip(m.label[0], m.distance[0], strict=True)}
    for p in range(6):
        assert got[tuple(pairs[p])] == pytest.approx(ref[p], rel=1e-10)


def test_extrapolation_warns_naming_joint_and_mode_and_bad_input_refused():
    rng = np.random.default_rng(2)
    ds, _, _ = _dataset(rng)
    with pytest.warns(UserWarning, match=r"joint 7, δ mode 2: 2 % lies outside"):
        match_interpolated(ds, [[0.0, 0.02, 0.0]], [[1000.0, 1000.0, 1000.0]], joints=[7])
    with pytest.raises(IdentifyError, match="expected"):
        match_interpolated(ds, [[0.0, 0.0]], [[1000.0, 1000.0, 1000.0]])
    with pytest.raises(IdentifyError, match="finite"):
        match_interpolated(ds, [[0.0, np.nan, 0.0]], [[1000.0, 1000.0, 1000.0]])
    partial = SimpleNamespace(**{**vars(ds), "deltas": ds.deltas[1:], "pair": ds.pair[1:],
                                 "frequencies_hz": ds.frequencies_hz[1:]})
    with pytest.raises(IdentifyError, match="not a full grid"):
        match_interpolated(partial, [[0.0, 0.0, 0.0]], [[1000.0, 1000.0, 1000.0]])
