"""PCA pattern sampler (identify.sampler): Eqs. 25–32 against a direct SVD, reproducibility, the family guarantees."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError

from identify import IdentifyError
from identify.film import FilmGeometry, map_film
from identify.sampler import PatternSampler, draw_coefficients
from identify.synthetic import SyntheticPatterns, sample_patterns
from lab.films import render_film
from lab.patterns import simulate_pressure
from rom.academic import flank_coordinates
from rom.contact import ContactPattern


def known_maps(n, grid, rng) -> np.ndarray:
    """Film-like darkness maps in [0, 1]: a shared bearing core, moved, widened and tilted per joint, plus noise."""
    rows, cols = grid
    x, y = np.meshgrid(np.linspace(-0.5, 0.5, rows), np.linspace(-0.5, 0.5, cols), indexing="ij")
    maps = []
    for _ in range(n):
        cx, cy = rng.normal(0, 0.08, 2)
        w = 0.35 * rng.uniform(0.8, 1.25)
        gx, gy = rng.normal(0, 0.6, 2)
        z = 2.5 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * w * w)) - 1.2 + gx * x + gy * y
        maps.append(1 / (1 + np.exp(-2 * z)) * 0.85 + rng.normal(0, 0.02, grid))
    return np.clip(maps, 0, 1)


GRIDS = [(3, 7), (7, 31)]


@pytest.mark.parametrize("grid", GRIDS)
@pytest.mark.parametrize("n_components", [None, 2])
def test_pca_matches_a_direct_svd(grid, n_components):
    """Eqs. 26–30 by hand: mean, SVD of the centred data, Z = X_cent V, per-component mean and std (n − 1)."""
    rng = np.random.default_rng(1)
    X = known_maps(5, grid, rng).reshape(5, -1)
    est = PatternSampler(n_components=n_components).fit(X.reshape(5, *grid))
    k = 4 if n_components is None else n_components

    mu = X.mean(axis=0)  # Eq. 26
    Xc = X - mu  # Eq. 27
    U, S, Vt = np.linalg.svd(Xc, full_matrices=False)  # Eq. 28
    V = Vt[:k].T
    Z = Xc @ V  # Eq. 29

    assert np.allclose(est.mean_, mu, atol=1e-14)
    sign = np.sign(np.sum(est.components_ * V.T, axis=1))  # directions are defined up to sign
    assert np.allclose(est.components_, sign[:, None] * V.T, atol=1e-10)
    assert np.allclose(est.scores_, Z * sign, atol=1e-10)
    assert np.allclose(est.score_mean_, (Z * sign).mean(axis=0), atol=1e-12)  # Eq. 30, zero for centred data
    assert np.allclose(est.score_mean_, 0.0, atol=1e-12)
    assert np.allclose(est.score_std_, np.sqrt(((Z - Z.mean(0)) ** 2).sum(0) / 4), rtol=1e-10)  # Eq. 30
    assert np.allclose(est.score_std_, S[:k] / np.sqrt(4), rtol=1e-10)  # S² / (n − 1) is the variance
    assert np.allclose(est.transform(X), Z * sign, atol=1e-10)


def test_synthetic_maps_are_eq_32_and_thresholded():
    rng = np.random.default_rng(2)
    X = known_maps(5, (7, 31), rng)
    est = PatternSampler(threshold=0.4, random_state=3).fit(X)
    s = est.sample()
    assert s.kappa.shape == (10, 4) and s.gray.shape == (10, 7, 31) and s.contact.dtype == bool
    gray = (X.reshape(5, -1).mean(axis=0) + s.kappa @ est.components_).reshape(10, 7, 31)  # Eq. 32
    assert np.allclose(s.gray, gray, atol=1e-12)
    assert np.array_equal(s.contact, gray > 0.4)
    # With all components kept, a known map is reproduced from its own coefficients.
    assert np.allclose(est.inverse_transform(est.scores_), X, atol=1e-12)


def test_eq_31_draws_each_component_independently():
    """κ_z = μ_z + σ_z · scale · r_z: per-component mean and std, and no correlation between components (one scalar
    r per pattern would make them perfectly correlated)."""
    mean, std = np.array([0.3, -1.0, 2.0]), np.array([1.0, 0.5, 0.1])
    kappa = draw_coefficients(mean, std, 1.5, 40_000, np.random.default_rng(0))
    # Standard errors: σ/√n ≈ 0.0075 for the mean of the widest component; the bounds are ≥ 5 of them.
    assert np.allclose(kappa.mean(axis=0), mean, atol=5 * 1.5 * std / np.sqrt(40_000) + 1e-12)
    assert np.allclose(kappa.std(axis=0, ddof=1), 1.5 * std, rtol=0.02)
    corr = np.corrcoef(kappa.T)[np.triu_indices(3, 1)]
    assert np.abs(corr).max() < 0.03, corr
    assert np.array_equal(draw_coefficients(mean, std, 0.0, 3, np.random.default_rng(1)), np.tile(mean, (3, 1)))


def test_same_seed_same_patterns():
    rng = np.random.default_rng(4)
    L, R = known_maps(5, (3, 7), rng), known_maps(5, (3, 7), rng)
    a = sample_patterns(L, R, random_state=11)
    b = sample_patterns(L, R, random_state=11)
    c = sample_patterns(L, R, random_state=12)
    for name in ("L", "R", "gray_L", "gray_R"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.gray_L, c.gray_L)
    assert not np.array_equal(a.gray_L, a.gray_R)
    est = PatternSampler(random_state=5).fit(L)
    assert np.array_equal(est.sample().kappa, est.sample().kappa)  # an int seed restarts on every call
    gen = PatternSampler(random_state=np.random.default_rng(5)).fit(L)
    assert not np.array_equal(gen.sample().kappa, gen.sample().kappa)  # a Generator advances


def allowed_range(X, threshold, scale):
    """The documented family, computed independently: known range widened by max(scale · s_a, 1 / n_nodes)."""
    a = (X.reshape(len(X), -1) > threshold).mean(axis=1)
    w = max(scale * a.std(ddof=1), 1 / X[0].size)
    return max(a.min() - w, 0.0), min(a.max() + w, 1.0)


@pytest.mark.parametrize("grid", GRIDS)
@pytest.mark.parametrize("scale", [1.0, 2.5])
def test_family_guarantees_hold_over_many_seeds(grid, scale):
    rng = np.random.default_rng(6)
    L, R = known_maps(5, grid, rng), known_maps(5, grid, rng)
    lo_L, hi_L = allowed_range(L, 0.45, scale)
    lo_R, hi_R = allowed_range(R, 0.45, scale)
    draws = 0
    for seed in range(40):  # measured: 405–534 draws for the 400 patterns of each case
        sp = sample_patterns(L, R, scale=scale, threshold=0.45, random_state=seed)
        for grids, lo, hi in ((sp.L, lo_L, hi_L), (sp.R, lo_R, hi_R)):
            a = grids.mean(axis=(1, 2))
            assert (a > 0).all() and (a < 1).all()
            assert (a >= lo - 1e-12).all() and (a <= hi + 1e-12).all(), (a, lo, hi)
        assert np.array_equal(sp.L, sp.gray_L > 0.45) and np.array_equal(sp.R, sp.gray_R > 0.45)
        # Every left × right pair is a valid joint (each side alone holds ≥ 3 non-collinear contacts).
        for i in range(10):
            sp.pattern(i, i)
            sp.pattern(i, 9 - i)
        draws += PatternSampler(scale=scale, threshold=0.45, random_state=seed).fit(L).sample().n_draws
    assert draws > 400  # some draws left the family and were redrawn: the guarantees above were exercised


def test_redraws_keep_out_of_family_patterns_out():
    """A wide scale produces many out-of-range draws; none of them is returned."""
    rng = np.random.default_rng(7)
    X = known_maps(5, (5, 11), rng)
    est = PatternSampler(scale=6.0, threshold=0.45, n_patterns=50, random_state=0).fit(X)
    s = est.sample()
    assert s.n_draws > 50  # some were rejected
    lo, hi = allowed_range(X, 0.45, 6.0)
    a = s.contact.mean(axis=(1, 2))
    assert ((a >= lo) & (a <= hi) & (a > 0) & (a < 1)).all()
    assert est.fraction_range_ == pytest.approx((lo, hi))


def test_defaults_give_100_pairs_with_labels():
    rng = np.random.default_rng(8)
    sp = sample_patterns(known_maps(5, (3, 7), rng), known_maps(5, (3, 7), rng), random_state=0)
    assert isinstance(sp, SyntheticPatterns)
    assert sp.L.shape == sp.R.shape == (10, 3, 7) and sp.n_pairs == 100 and sp.grid == (3, 7)
    assert sp.labels_L == tuple(f"SP-{i}" for i in range(1, 11)) == sp.labels_R
    pairs = list(sp.pairs())
    assert len(pairs) == 100 and pairs[0] == ("SP-1", "SP-1") and pairs[1] == ("SP-1", "SP-2")
    assert sp.pattern("SP-2", "SP-10") == ContactPattern(sp.L[1], sp.R[9]) == sp.pattern(1, 9)
    with pytest.raises(IdentifyError, match="SP-11"):
        sp.pattern("SP-11", 0)
    with pytest.raises(IdentifyError, match=r"0\.\.9"):
        sp.pattern(0, 10)
    with pytest.raises(ValueError):
        sp.L[0, 0, 0] = True  # read-only
    assert sample_patterns(known_maps(3, (3, 7), rng), known_maps(3, (3, 7), rng), n_patterns=(4, 6),
                           random_state=0).n_pairs == 24


def test_otsu_threshold_by_default():
    rng = np.random.default_rng(9)
    X = known_maps(5, (7, 31), rng)
    est = PatternSampler().fit(X)
    assert 0.1 < est.threshold_ < 0.8
    assert np.allclose(est.known_fractions_, (X.reshape(5, -1) > est.threshold_).mean(axis=1))


def test_estimator_contract():
    X = known_maps(4, (3, 7), np.random.default_rng(10))
    est = PatternSampler(scale=0.5, random_state=1)
    with pytest.raises(NotFittedError):
        est.sample()
    assert clone(est).get_params() == est.get_params()
    assert est.fit(X) is est and est.n_features_in_ == 21 and est.grid_shape_ == (3, 7)
    flat = PatternSampler(grid=(3, 7), random_state=1).fit(X.reshape(4, -1))
    assert np.array_equal(flat.components_, PatternSampler().fit(X).components_)


def test_bad_input_is_named():
    rng = np.random.default_rng(11)
    X = known_maps(5, (3, 7), rng)
    with pytest.raises(IdentifyError, match="at least 2 known maps, got 1"):
        PatternSampler().fit(X[:1])
    with pytest.raises(IdentifyError, match=r"\(3, 7\), \(7, 31\)"):
        PatternSampler().fit([X[0], X[1], known_maps(1, (7, 31), rng)[0]])
    with pytest.raises(IdentifyError, match=r"flank R: .*L \(3, 7\), R \(5, 11\)"):
        sample_patterns(X, known_maps(5, (5, 11), rng))
    with pytest.raises(IdentifyError, match="flank L: PCA needs at least 2"):
        sample_patterns(X[:1], X)
    with pytest.raises(IdentifyError, match=r"n_components must be an integer in 1\.\.4"):
        PatternSampler(n_components=5).fit(X)
    with pytest.raises(IdentifyError, match="scale must be .* got -1"):
        PatternSampler(scale=-1.0).fit(X)
    with pytest.raises(IdentifyError, match="need grid"):
        PatternSampler().fit(X.reshape(5, -1))
    with pytest.raises(IdentifyError, match="non-finite"):
        PatternSampler().fit(np.where(X > 0.5, np.nan, X))
    # A threshold above every value: every known and synthetic grid is empty, so the family is empty.
    with pytest.raises(IdentifyError, match=r"0 of 10 synthetic patterns .* after 50 draws") as e:
        PatternSampler(threshold=2.0, max_draws=5).fit(X).sample()
    assert "\n" not in str(e.value)


def test_lab_films_to_synthetic_patterns(coarse_bd):
    """End to end on the virtual rig: 5 known joints' films → 10 × 10 valid synthetic joints."""
    u, v = flank_coordinates(coarse_bd)
    truth = simulate_pressure(u, v, 18, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    maps = {"L": [], "R": []}
    for joint in (3, 7, 10, 14, 17):  # paper §6.1's known roots
        for flank in "LR":
            image, meta = render_film(truth, joint, flank, rng)
            maps[flank].append(map_film(image, (3, 7), FilmGeometry.from_mapping(meta), threshold=meta.contact_level,
                                        white=meta.white))
    levels = tuple(float(np.mean([m.level for m in maps[f]])) for f in "LR")
    sp = sample_patterns(maps["L"], maps["R"], threshold=np.array(levels), random_state=0)
    assert sp.threshold == levels and sp.n_pairs == 100
    patterns = [sp.pattern(a, b) for a, b in sp.pairs()]
    assert all(isinstance(p, ContactPattern) for p in patterns)
    # Synthetic patterns resemble the known ones: the mean contact map stays close to the known mean.
    known = np.mean([m.gray > levels[0] for m in maps["L"]], axis=0)
    assert np.abs(sp.L.mean(axis=0) - known).mean() < 0.25


def test_non_collinear_batch_agrees_with_the_rank_of_the_contacting_nodes():
    from identify.sampler import non_collinear_batch

    rng = np.random.default_rng(4)
    grids = rng.random((400, 5, 7)) < rng.choice([0.03, 0.08, 0.5], (400, 1, 1))  # many with 0–4 nodes
    line = np.zeros((4, 5, 7), bool)
    line[0, 2, 1:6] = True  # a row
    line[1, :, 3] = True  # a column
    line[2, [0, 1, 2, 3, 4], [0, 1, 2, 3, 4]] = True  # a diagonal
    line[3, [0, 2, 4], [0, 3, 6]] = True  # a slope of 3/2 through grid points
    grids = np.concatenate([grids, line])

    def by_rank(g):  # the definition, one grid at a time: ≥ 3 nodes whose offsets span the plane
        pts = np.argwhere(g)
        return len(pts) >= 3 and np.linalg.matrix_rank(pts[1:] - pts[0]) >= 2

    expected = np.array([by_rank(g) for g in grids])
    assert np.array_equal(non_collinear_batch(grids), expected)
    assert not expected[-4:].any() and expected.any() and not expected.all()
