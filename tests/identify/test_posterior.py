"""The contact posterior (identify.contact_prior, contact_surrogate, posterior) against known generating models."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from identify import IdentifyError, PatternSampler
from identify.contact_prior import contact_prior, held_out_projections
from identify.contact_surrogate import ContactSurrogate, fit_surrogate
from identify.posterior import (
    WIDTH_NAMES,
    joint_posterior,
    median_area_answer,
    noise_model,
    predictive_spread,
    prior_intervals,
    width_ratio,
)
from identify.validation import contact_area_fraction

GRID = (5, 9)


def _films(rng, n=5):
    """Smooth random pressure maps on GRID, each read at its own level (as a lab's calibrated films)."""
    r, c = np.meshgrid(np.linspace(-1, 1, GRID[0]), np.linspace(-1, 1, GRID[1]), indexing="ij")
    maps, films = [], []
    for _ in range(n):
        a, b, w = rng.normal(0, 0.4, 3)
        m = np.clip(0.5 + 0.25 * (np.cos(r + a) + np.cos(c * (1 + 0.3 * w) + b)) - 0.2, 0, 1)
        level = 0.4 + rng.normal(0, 0.03)
        maps.append(m)
        films.append(SimpleNamespace(level=level, contact=m > level))
    return np.array(maps), films


def _prior(seed=0, **kw):
    maps, films = _films(np.random.default_rng(seed))
    s = PatternSampler(threshold=0.4).fit(maps)
    return contact_prior(s, s, films, films, **kw)


def _linear_model(prior, rng, n_modes=4):
    """A surrogate that *is* the forward model: log f linear in the contact indicators."""
    n = 2 * np.prod(GRID)
    coef = rng.normal(0, 2e-3, (n, n_modes))
    return ContactSurrogate(coef, np.log(np.linspace(100, 400, n_modes)), 1.0, np.zeros(n_modes),
                            np.zeros(n_modes), 1, 1)


def _uv():
    return np.meshgrid(np.linspace(0, 8e-3, GRID[1]), np.linspace(0, 4e-3, GRID[0]))


def test_prior_settings_are_checked():
    with pytest.raises(IdentifyError, match="n_components must be a positive integer"):
        _prior(n_components=0)
    with pytest.raises(IdentifyError, match="at most 4"):
        _prior(n_components=5)
    with pytest.raises(IdentifyError, match="scale must be a positive number"):
        _prior(scale=-1.0)
    p = _prior(n_components=2)
    assert p.n_components == (2, 2) and p.n_dim == 6


def test_prior_level_spread_comes_from_the_films():
    maps, films = _films(np.random.default_rng(3))
    s = PatternSampler(threshold=0.4).fit(maps)
    p = contact_prior(s, s, films, films)
    levels = np.array([f.level for f in films])
    assert p.level[0] == pytest.approx(levels.mean())
    assert p.level_std[0] >= np.std(levels, ddof=1)  # the films' own scatter is part of it
    assert contact_prior(s, s, films, films, scale=2.0).level_std[0] == pytest.approx(2 * p.level_std[0])


def test_two_films_that_agree_on_one_flank_do_not_pin_its_level():
    """Left films identical (same map, same level): alone they would give that flank no level scatter at all.
    Pooled, both flanks get the scatter the right films show, at (n − 1)/(2n − 2) = half its variance, and each
    flank keeps its own mean level."""
    maps, films = _films(np.random.default_rng(3))
    s = PatternSampler(threshold=0.4).fit(maps)
    twins = [SimpleNamespace(level=films[0].level, contact=films[0].contact) for _ in films]
    right = contact_prior(s, s, films, films).level_std[1]
    p = contact_prior(s, s, twins, films)
    assert p.level_std[0] == p.level_std[1] == pytest.approx(right / np.sqrt(2))
    assert p.level[0] == pytest.approx(films[0].level)
    assert p.level[1] == pytest.approx(np.mean([f.level for f in films]))


def test_surrogate_recovers_a_log_linear_model_and_measures_its_error():
    rng = np.random.default_rng(1)
    prior = _prior()
    truth = _linear_model(prior, rng)
    grids = prior.grids(prior.draw(120, rng))
    fitted = fit_surrogate(grids, truth.predict_hz(grids))
    assert np.all(fitted.error_pct < 0.01)
    # a model it cannot follow (a product of two nodes) shows in the held-out error
    flat = grids.reshape(len(grids), 2, -1)
    a, b = (int(np.argmin(np.abs(flat[:, s].mean(axis=0) - 0.5))) for s in (0, 1))  # nodes that vary most
    bent = truth.predict_hz(grids) * (1 + 0.02 * (flat[:, 0, a] & flat[:, 1, b]))[:, None]
    assert np.all(fit_surrogate(grids, bent).error_pct > 0.2)


def test_posterior_intervals_cover_the_truth_and_are_narrower_than_the_prior():
    rng = np.random.default_rng(7)
    prior = _prior()
    model = _linear_model(prior, rng, n_modes=6)
    sigma = np.full(6, 2e-4)
    inside, width = [], []
    prior_area = contact_area_fraction(prior.grids(prior.draw(2000, rng)))
    prior_width = np.diff(np.percentile(prior_area, (5, 95), axis=0), axis=0)[0]
    for k in range(8):
        theta = prior.draw(1, rng)
        g = prior.grids(theta)
        y = model.predict_hz(g)[0] * np.exp(rng.normal(0, sigma))
        post = joint_posterior(prior, model, y, sigma, _uv(), n_walkers=24, n_steps=450, seed=k,
                               max_extensions=2)  # coverage at a fixed budget, not convergence
        a = contact_area_fraction(g[0])
        lo, hi = post.area_pct_ci90.T
        inside += list((lo <= a) & (a <= hi))
        width += list(hi - lo)
    assert np.mean(inside) >= 0.75
    assert np.median(width) < 0.8 * np.median(prior_width)


def test_same_seed_same_answer_and_bad_targets_refused():
    rng = np.random.default_rng(2)
    prior = _prior()
    model = _linear_model(prior, rng)
    y = model.predict_hz(prior.grids(prior.draw(1, rng)))[0]
    s = noise_model(np.full(4, 1e-3), np.zeros(4))
    a = joint_posterior(prior, model, y, s, _uv(), n_walkers=16, n_steps=60, seed=3)
    b = joint_posterior(prior, model, y, s, _uv(), n_walkers=16, n_steps=60, seed=3)
    assert np.array_equal(a.probability, b.probability) and np.array_equal(a.theta_map, b.theta_map)
    with pytest.raises(IdentifyError, match="no finite, positive frequency"):
        joint_posterior(prior, model, np.full(4, np.nan), s, _uv())
    with pytest.raises(IdentifyError, match="n_walkers"):
        joint_posterior(prior, model, y, s, _uv(), n_walkers=3)


def test_width_ratio_says_which_flank_the_data_pin_down():
    """A model that only feels the left flank narrows the left flank's area interval and leaves the right's at
    the prior's width."""
    rng = np.random.default_rng(11)
    films = _low_rank_films(rng, n=6)
    for f in films:
        f.contact = f.gray > f.level
    s = PatternSampler(threshold=0.45).fit([f.gray for f in films])
    prior = contact_prior(s, s, films, films)
    model = _linear_model(prior, rng, n_modes=6)
    n_side = np.prod(GRID)
    model = ContactSurrogate(np.r_[model.coef[:n_side] * 5, np.zeros_like(model.coef[n_side:])], model.intercept,
                             1.0, np.zeros(6), np.zeros(6), 1, 1)
    y = model.predict_hz(prior.grids(prior.draw(1, rng)))[0]
    post = joint_posterior(prior, model, y, np.full(6, 2e-4), _uv(), n_walkers=24, n_steps=1500, seed=1)
    ratio = dict(zip(WIDTH_NAMES, width_ratio(post, prior_intervals(prior, _uv())), strict=True))
    assert ratio["area L"] < 0.7 and 0.6 < ratio["area R"] < 1.4, ratio


def _low_rank_films(rng, n=5):
    """Maps of one affine family of two smooth directions, each read at its own level."""
    r, c = np.meshgrid(np.linspace(-1, 1, GRID[0]), np.linspace(-1, 1, GRID[1]), indexing="ij")
    w = rng.normal(0, 1, (n, 2))
    maps = 0.45 + 0.1 * r + w[:, :1, None] * 0.1 * np.cos(np.pi * c) + w[:, 1:, None] * 0.1 * r * c
    return [SimpleNamespace(gray=m, level=0.45 + rng.normal(0, 0.02)) for m in maps]


def test_held_out_projections_restore_a_family_member_and_miss_a_film_outside_it():
    films = _low_rank_films(np.random.default_rng(5))
    proj = held_out_projections(films, films, (2, 2))
    assert proj.shape == (5, 2, *GRID)
    for f, g in zip(films, proj, strict=True):  # any four films span the family: each film is restored
        assert np.array_equal(g[0], f.gray > f.level) and np.array_equal(g[1], f.gray > f.level)
    # a film with a contact patch no other film has is not restored: the family cannot draw it
    films[2].gray = films[2].gray.copy()
    films[2].gray[:2, :3] = 0.95
    assert not np.array_equal(held_out_projections(films, films, (2, 2))[2, 0], films[2].gray > films[2].level)
    with pytest.raises(IdentifyError, match="≥ 3 films"):
        held_out_projections(films[:2], films[:2], (1, 1))


def test_chains_run_on_until_they_converge_and_say_when_they_do_not():
    """Too few steps for the walkers to mix: with extensions the sampler runs on until R̂ and ESS pass (its
    diagnostics say how far it went); without, it stops and says it has not converged."""
    from identify.chains import ESS_MIN, RHAT_MAX

    rng = np.random.default_rng(5)
    prior = _prior()
    model = _linear_model(prior, rng, n_modes=6)
    y = model.predict_hz(prior.grids(prior.draw(1, rng)))[0]
    sigma = np.full(6, 2e-4)
    short = joint_posterior(prior, model, y, sigma, _uv(), n_walkers=24, n_steps=30, seed=2, max_extensions=0)
    assert short.diagnostics.n_steps == 30 and not short.diagnostics.converged
    longer = joint_posterior(prior, model, y, sigma, _uv(), n_walkers=24, n_steps=400, seed=2, max_extensions=4)
    d = longer.diagnostics
    assert d.converged and d.rhat <= RHAT_MAX and d.ess >= ESS_MIN and d.n_steps in (400, 800, 1200, 1600, 2000)


@pytest.mark.parametrize("n", [2, 3, 5])
def test_the_predictive_spread_gives_a_new_joint_s_interval_its_nominal_coverage(n):
    """n filmed joints' residuals, one new joint's: the interval mean ± t(0.95, n − 1) × predictive_spread holds
    the new one 90 % of the time (the textbook prediction interval, scipy's t as the reference); the plain
    population std in its place holds it far less often with two or three joints. 20 000 draws: 3σ of a
    binomial 0.9 is 0.0064."""
    rng = np.random.default_rng(7)
    x = rng.normal(0.01, 0.003, (20000, n + 1))  # relative residuals; the last column is the new joint
    mean, sd0 = x[:, :n].mean(1), x[:, :n].std(1)
    half = stats.t.ppf(0.95, n - 1) * predictive_spread(sd0, np.full(sd0.size, n))
    inside = np.abs(x[:, n] - mean) <= half
    assert abs(inside.mean() - 0.9) < 0.0064
    plain = np.abs(x[:, n] - mean) <= stats.norm.ppf(0.95) * sd0
    if n <= 3:
        assert plain.mean() < 0.75
    assert np.isnan(predictive_spread([0.01], [1])).all()


def test_the_answer_has_the_median_count_and_the_best_expected_node_agreement_of_that_count():
    """On a 2 × 3 flank pair, every pattern with the samples' median count is enumerated: none has a larger
    expected node agreement, Σ P(node as chosen) under the samples, than the answer; a flank whose median count
    is 0 stays empty."""
    from itertools import combinations

    rng = np.random.default_rng(4)
    p_true = rng.uniform(0.05, 0.95, (2, 2, 3))
    grids = rng.uniform(size=(301, 2, 2, 3)) < p_true
    grids[:, 1] &= rng.uniform(size=(301, 1, 1)) < 0.3  # flank R mostly empty: median count 0
    prob = grids.mean(axis=0)
    ans = median_area_answer(prob, grids)
    for f in range(2):
        n = int(np.median(grids[:, f].reshape(301, -1).sum(axis=1)))
        assert ans[f].sum() == n

        def agreement(mask, f=f):
            return float(np.sum(np.where(mask, prob[f].ravel(), 1 - prob[f].ravel())))

        best = max(agreement(np.isin(np.arange(6), c)) for c in combinations(range(6), n))
        assert agreement(ans[f].ravel()) == pytest.approx(best)
    assert not ans[1].any()
