"""Two-step weighted k-NN (paper §6.4, Eqs. 33–36, 39).

References: a brute-force numpy implementation of the two steps written from the equations; scikit-learn's
weighted Minkowski metric (p = 2 is Eq. 33); a small dataset of real disk–one-blade solves (coarse model),
where each sample must be found again from its own δ and frequencies.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cache

import numpy as np
import pytest
from sklearn.neighbors import NearestNeighbors
from sklearn.utils.estimator_checks import parametrize_with_checks

from identify.errors import IdentifyError
from identify.knn import ExtrapolationWarning, TwoStepKNN, dataset_xy, query_matrix
from rom import ContactPattern, solve_d1b

from ..rom.rom_models import blade, disk_cb


@dataclass(frozen=True)
class Dataset:
    """The fields of identify.dataset's dataset that the estimator reads (duck-typed)."""

    deltas: np.ndarray
    pair: np.ndarray
    frequencies_hz: np.ndarray
    patterns_L: np.ndarray
    patterns_R: np.ndarray
    feature_modes: tuple[int, ...]
    weights: np.ndarray
    delta_grid: np.ndarray
    model_key: str = "test"


def synthetic(seed=0, grid=(-0.005, 0.0, 0.005), n_L=3, n_R=4, n_feat=3):
    """Tensor dataset δ¹ × δ² × pattern pairs with random, δ- and pattern-dependent frequencies (Hz)."""
    rng = np.random.default_rng(seed)
    g = np.asarray(grid)
    d1, d2, iL, iR = (a.ravel() for a in np.meshgrid(g, g[:2], np.arange(n_L), np.arange(n_R), indexing="ij"))
    D = np.column_stack([d1, d2])
    base = np.array([1000.0, 1500.0, 2600.0])[:n_feat]
    effL, effR = rng.normal(0, 5, (n_L, n_feat)), rng.normal(0, 20, (n_R, n_feat))
    F = base * (1 + 0.5 * d1[:, None] + 0.3 * d2[:, None]) + effL[iL] + effR[iR] + rng.normal(0, 0.5, (d1.size, n_feat))
    return D, F, np.column_stack([iL, iR])


def brute_two_step(D, F, y, w, Dq, Fq, k, normalize):
    """Eqs. 33/39 literally: nearest δ row; z-scores (population std); sqrt(Σ w (x − y)²); stable argsort."""
    rows = np.unique(D, axis=0)
    idx, dist, dsel = [], [], []
    for d, f in zip(Dq, Fq, strict=True):
        g = rows[np.argmin(np.sum((rows - d) ** 2, axis=1))]
        members = np.flatnonzero(np.all(D == g, axis=1))
        ref = F[members] if normalize == "subset" else F
        mu, sd = ref.mean(axis=0), ref.std(axis=0)
        dj = np.sqrt(np.sum(w * ((F[members] - mu) / sd - (f - mu) / sd) ** 2, axis=1))
        o = np.argsort(dj, kind="stable")[:k]
        idx.append(members[o])
        dist.append(dj[o])
        dsel.append(g)
    return np.array(idx), np.array(dist), np.array(dsel)


def queries(D, F, n=25, seed=1):
    rng = np.random.default_rng(seed)
    lo, hi = D.min(axis=0), D.max(axis=0)
    Dq = rng.uniform(lo, hi, (n, D.shape[1]))
    Fq = F[rng.integers(0, F.shape[0], n)] + rng.normal(0, 8, (n, F.shape[1]))
    return Dq, Fq


@pytest.mark.parametrize("normalize", ["subset", "dataset"])
def test_two_steps_match_brute_force_equations(normalize):
    D, F, y = synthetic()
    w = np.array([0.7, 2.0, 0.3])
    est = TwoStepKNN(n_delta_modes=2, n_neighbors=4, weights=w, normalize=normalize).fit(np.hstack([D, F]), y)
    Dq, Fq = queries(D, F)
    m = est.match(np.hstack([Dq, Fq]))
    idx, dist, dsel = brute_two_step(D, F, y, w, Dq, Fq, 4, normalize)
    np.testing.assert_allclose(m.distance, dist, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(m.index, idx)
    np.testing.assert_array_equal(m.delta, dsel)
    np.testing.assert_array_equal(m.label, y[idx])  # (n_queries, k, 2) pattern pairs
    np.testing.assert_array_equal(est.predict(np.hstack([Dq, Fq])), y[idx[:, 0]])
    assert np.all(np.diff(m.distance, axis=1) >= 0)  # ranked


def test_beyond_measures_how_far_a_query_lies_outside_its_subsets_features():
    D, F, y = synthetic(seed=5)
    est = TwoStepKNN(n_delta_modes=2, n_neighbors=1).fit(np.hstack([D, F]), y)
    g = np.unique(D, axis=0)[2]
    members = np.all(D == g, axis=1)
    lo, hi = F[members].min(axis=0), F[members].max(axis=0)
    inside = 0.5 * (lo + hi)  # inside the bounding box of the subset's features on every axis
    q = np.array([inside,
                  [hi[0] + 3.0, inside[1], lo[2] - 7.5],  # above on the first feature, below on the third
                  F[np.flatnonzero(members)[0]]])  # a training sample itself: on the range, not beyond it
    m = est.match(np.hstack([np.repeat(g[None], 3, axis=0), q]))
    assert m.beyond.shape == (3, F.shape[1])
    np.testing.assert_array_equal(m.beyond[0], 0.0)
    np.testing.assert_allclose(m.beyond[1], [3.0, 0.0, -7.5], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(m.beyond[2], 0.0)
    # Another subset has another range: the same features can be inside one and outside the other.
    other = np.unique(D, axis=0)[0]
    lo2, hi2 = F[np.all(D == other, axis=1)].min(axis=0), F[np.all(D == other, axis=1)].max(axis=0)
    m2 = est.match(np.hstack([other, q[1]])[None])
    expect = np.maximum(q[1] - hi2, 0) + np.minimum(q[1] - lo2, 0)
    np.testing.assert_allclose(m2.beyond[0], expect, rtol=0, atol=1e-9)


def test_sensitivity_weights_are_pooled_within_subset_std():
    D, F, y = synthetic(seed=3)
    est = TwoStepKNN(n_delta_modes=2, n_neighbors=2).fit(np.hstack([D, F]), y)
    groups = [np.all(D == g, axis=1) for g in np.unique(D, axis=0)]
    w = np.mean([F[g].std(axis=0) for g in groups], axis=0)  # paper §6.2, averaged over the δ subsets
    np.testing.assert_allclose(est.weights_, w, rtol=1e-12)
    Dq, Fq = queries(D, F, seed=4)
    idx, dist, _ = brute_two_step(D, F, y, w, Dq, Fq, 2, "subset")
    d, i = est.kneighbors(np.hstack([Dq, Fq]))
    np.testing.assert_array_equal(i, idx)
    np.testing.assert_allclose(d, dist, rtol=1e-12)


def test_weighted_distance_equals_sklearn_weighted_minkowski():
    # Without δ columns and normalisation, Eq. 33 is sklearn's Minkowski metric with weights w and p = 2.
    rng = np.random.default_rng(5)
    F, Fq, w = rng.normal(size=(40, 3)) * [1, 10, 100], rng.normal(size=(9, 3)) * [1, 10, 100], np.array([3, 0.2, 1e-3])
    est = TwoStepKNN(n_delta_modes=0, n_neighbors=5, weights=w, normalize=None).fit(F, np.arange(40) % 7)
    ref = NearestNeighbors(n_neighbors=5, algorithm="brute", metric="minkowski", p=2, metric_params={"w": w}).fit(F)
    d_ref, i_ref = ref.kneighbors(Fq)
    d, i = est.kneighbors(Fq)
    np.testing.assert_array_equal(i, i_ref)
    np.testing.assert_allclose(d, d_ref, rtol=1e-10)


@cache
def d1b_dataset() -> Dataset:
    """2 × 2 patterns × δ grid {0, 1 %}² on the first two blade modes: 16 coarse disk–one-blade solves (≈ 0.5 s)."""
    rng = np.random.default_rng(11)
    disk, bl = disk_cb(4), blade(4)
    pats = [ContactPattern.random((3, 7), 0.55, rng) for _ in range(2)]
    PL, PR = np.array([p.L for p in pats]), np.array([p.R for p in pats])
    grid = np.array([0.0, 0.01])
    rows, f = [], []
    for d1 in grid:
        for d2 in grid:
            for iL in range(2):
                for iR in range(2):
                    modes = solve_d1b(disk, bl, ContactPattern(PL[iL], PR[iR]), n_modes=6, delta=[d1, d2])
                    rows.append((d1, d2, iL, iR))
                    f.append(modes.frequencies_hz)
    rows, f = np.array(rows), np.array(f)
    feat = (3, 4, 5)
    return Dataset(rows[:, :2], rows[:, 2:].astype(int), f, PL, PR, feat, f[:4][:, feat].std(axis=0), grid)


def test_exact_recovery_of_dataset_samples():
    ds = d1b_dataset()
    X, y = dataset_xy(ds)
    assert X.shape == (16, 5) and y.shape == (16, 2)
    # The four pattern pairs give distinct frequency signatures, otherwise recovery would be luck.
    assert np.min(np.ptp(X[:4, 2:], axis=0)) > 1e-3
    est = TwoStepKNN.from_dataset(ds, n_neighbors=4)
    np.testing.assert_array_equal(est.weights_, ds.weights)
    q = query_matrix(ds.deltas, ds.frequencies_hz[:, list(ds.feature_modes)])
    m = est.match(q)
    np.testing.assert_array_equal(m.index[:, 0], np.arange(16))
    np.testing.assert_array_equal(m.label[:, 0], ds.pair)
    np.testing.assert_allclose(m.distance[:, 0], 0.0, atol=1e-12)
    np.testing.assert_array_equal(m.delta, ds.deltas)
    # Ranking: every candidate lies in the query's δ subset, all 4 pairs appear, distances ascend.
    for r in range(16):
        assert set(m.index[r]) == set(np.flatnonzero(np.all(ds.deltas == ds.deltas[r], axis=1)))
    assert np.all(np.diff(m.distance, axis=1) > 0)
    np.testing.assert_array_equal(est.predict(q), ds.pair)
    assert est.score(q, ds.pair) == 1.0
    # A δ off the grid by less than half a step selects the same subset.
    q2 = q.copy()
    q2[:, :2] += 0.002
    np.testing.assert_array_equal(est.predict(q2), ds.pair)


def test_extrapolated_delta_warns_naming_row_mode_and_value():
    D, F, y = synthetic()
    est = TwoStepKNN(n_delta_modes=2).fit(np.hstack([D, F]), y)
    q = np.hstack([D[:3], F[:3]])
    q[0, 0] = -0.0074  # range −0.005…0.005, step 0.005: 0.0024 outside is within half a step
    q[1, 1] = 0.0026  # mode 2 spans −0.005…0 (step 0.005): 0.0026 is more than half a step above
    q[2, 0] = 0.0081
    with pytest.warns(ExtrapolationWarning) as rec:
        est.predict(q)
    msgs = [str(r.message) for r in rec]
    assert len(msgs) == 2
    assert "row 1" in msgs[0] and "δ mode 2" in msgs[0] and "0.0026" in msgs[0]
    assert "row 2" in msgs[1] and "δ mode 1" in msgs[1] and "0.0081" in msgs[1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est.predict(q[:1])


def test_user_errors_are_one_line_identify_errors():
    D, F, y = synthetic()
    X = np.hstack([D, F])
    with pytest.raises(IdentifyError, match="n_neighbors=13 exceeds the 12 sample"):
        TwoStepKNN(n_delta_modes=2, n_neighbors=13).fit(X, y)
    with pytest.raises(IdentifyError, match=r"weights has shape \(2,\), expected \(3,\)"):
        TwoStepKNN(n_delta_modes=2, weights=[1, 2]).fit(X, y)
    with pytest.raises(IdentifyError, match="expected finite values ≥ 0"):
        TwoStepKNN(n_delta_modes=2, weights=[1, -1, 1]).fit(X, y)
    with pytest.raises(IdentifyError, match="X has 5 feature"):
        TwoStepKNN(n_delta_modes=5).fit(X, y)
    with pytest.raises(IdentifyError, match="normalize='zscore'"):
        TwoStepKNN(n_delta_modes=2, normalize="zscore").fit(X, y)
    est = TwoStepKNN(n_delta_modes=2).fit(X, y)
    with pytest.raises(IdentifyError, match="n_neighbors=20 exceeds"):
        est.kneighbors(X[:2], n_neighbors=20)
    bad = Dataset(D, y.astype(float), F, None, None, (0, 1), np.ones(2), None)
    with pytest.raises(IdentifyError, match="dataset.pair has dtype float64"):
        dataset_xy(bad)
    bad = Dataset(D, y, F, None, None, (0, 3), np.ones(2), None)
    with pytest.raises(IdentifyError, match=r"feature_modes \(0, 3\)"):
        dataset_xy(bad)
    with pytest.raises(IdentifyError, match="same number of rows"):
        query_matrix(D[:3], F[:2])


# The scikit-learn contract. The default n_delta_modes=3 needs ≥ 4 columns, while the checks' data have 1–4,
# so the checks run with 1 δ column (both steps; continuous δ makes one subset per sample) and with none
# (a plain weighted k-NN); with these, no check is expected to fail.
@parametrize_with_checks([TwoStepKNN(n_delta_modes=1), TwoStepKNN(n_delta_modes=0, weights=None, normalize=None)])
def test_sklearn_estimator_contract(estimator, check):
    check(estimator)


def test_a_joint_missing_a_feature_mode_is_matched_on_the_others():
    """``bladetwin run``'s k-NN node: a joint whose EMA missed feature mode 2 (NaN) gets the pair that the two
    steps of the equations, computed by brute force on features 1 and 3 alone, give; one that found no feature
    gets none (the baseline); one that found all is unchanged."""
    from bladetwin.stages.knn import _query

    D, F, y = synthetic(seed=3)
    w = np.array([1.0, 2.0, 0.5])
    n = int(y.max()) + 1
    ones = np.ones((n, 3, 3), bool)
    ds = Dataset(D, y, F, ones, ones, (0, 1, 2), w, np.unique(D[:, 0]))
    knn = TwoStepKNN.from_dataset(ds)
    Dq, Fq = queries(D, F, n=12, seed=4)
    Fq[::3, 1] = np.nan
    Fq[1] = np.nan
    pats, labels, _ = _query(knn, ds, np.arange(1, 13), Dq, Fq)
    assert 2 not in labels and set(labels) == set(range(1, 13)) - {2}
    keep = [0, 2]
    idx, _, _ = brute_two_step(D, F[:, keep], y, w[keep], Dq[::3], Fq[::3][:, keep], 1, "subset")
    for r, k in enumerate(range(0, 12, 3)):
        assert labels[k + 1][:2] == tuple(y[idx[r, 0]])
    full = [k for k in range(12) if k % 3 and k != 1]
    idx, _, _ = brute_two_step(D, F, y, w, Dq[full], Fq[full], 1, "subset")
    for r, k in enumerate(full):
        assert labels[k + 1][:2] == tuple(y[idx[r, 0]])


def test_every_input_is_refined_down_to_its_model_error_and_the_numerical_one_to_the_experimentals():
    """``bladetwin run``'s k-NN node: the targets and where each input's refinement stops. The experimental input
    is the measured features with the ROM's bias divided out, fitted down to the ROM's scatter on the filmed joints
    (the mean over the feature modes, in %); without the bias correction, bias and scatter add in quadrature. The
    numerical input is the control of the same procedure (the paper's Case A), so it stops where the experimental
    one does, not at zero (design §8.71)."""
    from bladetwin.stages.bias import Features
    from bladetwin.stages.knn import _targets

    measured = np.array([[500.0, 700.0, 900.0, 1100.0], [510.0, np.nan, 905.0, 1090.0]])
    bias = np.array([0.01, -0.02, 0.003, 0.0])
    spread = np.array([0.002, 0.004, 0.001, 0.5])
    numerical = np.array([[499.0, 901.0], [509.0, 903.0]])
    f = Features(np.array([2, 5]), measured, bias, spread, {}, numerical, True)
    targets, tol = _targets(f, [0, 2], bias=True)
    np.testing.assert_allclose(targets["experimental"], measured[:, [0, 2]] / (1 + bias[[0, 2]]), rtol=1e-15)
    np.testing.assert_array_equal(targets["experimental_no_bias"], measured[:, [0, 2]])
    np.testing.assert_array_equal(targets["numerical"], numerical)
    assert tol["experimental"] == pytest.approx(100 * (0.002 + 0.001) / 2, rel=1e-12)
    assert tol["experimental_no_bias"] == pytest.approx(100 * (np.hypot(0.01, 0.002) + np.hypot(0.003, 0.001)) / 2,
                                                        rel=1e-12)
    assert tol["numerical"] == tol["experimental"] > 0
    _, tol = _targets(f, [0, 2], bias=False)
    assert set(tol) == {"experimental", "numerical"}
    # no reference patterns: no numerical input
    _, tol = _targets(Features(np.array([2, 5]), measured, bias, spread, {}, None, True), [0, 2], bias=True)
    assert "numerical" not in tol
