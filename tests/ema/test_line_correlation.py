"""ema.line_correlation against analytical long-run variances of autocorrelated noise."""

from __future__ import annotations

import numpy as np
import pytest

from ema.line_correlation import correlate_lines, line_correlation, scores_variance


def _ar1(rng, shape, rho):
    """AR(1) noise over the last axis, unit variance: long-run variance ratio (1 + ρ)/(1 − ρ)."""
    w = rng.standard_normal(shape)
    out = np.empty_like(w)
    out[..., 0] = w[..., 0]
    for j in range(1, shape[-1]):
        out[..., j] = rho * out[..., j - 1] + np.sqrt(1 - rho**2) * w[..., j]
    return out


def test_white_noise_keeps_white_s_estimator():
    z = np.random.default_rng(0).standard_normal((100, 200))
    rho, weights = line_correlation(z, axis=1)
    assert rho.tolist() == [1.0] and weights.tolist() == [1.0]


@pytest.mark.parametrize("rho1", [0.4, 0.7])
def test_newey_west_variance_of_a_sum_matches_the_long_run_variance(rho1):
    # the score of a mean over T lines: its variance is T (1 + ρ)/(1 − ρ) for AR(1) noise, not White's T
    rng = np.random.default_rng(1)
    T, reps = 400, 300
    z = _ar1(rng, (reps, 20, T), rho1)       # 20 series per record, pooled as a window's FRFs are
    truth = T * (1 + rho1) / (1 - rho1)
    est = []
    for rec in z:
        _, weights = line_correlation(rec, axis=1)
        est.append(scores_variance(rec[0][:, None], weights)[0])
    ratio = np.mean(est) / truth
    # Bartlett's taper and a finite bandwidth bias the estimate down (Andrews 1991, Table II: 10-20 % at ρ 0.5-0.7,
    # T 128); White's would give (1 − ρ)/(1 + ρ): 0.43 and 0.18 here
    assert 0.75 < ratio < 1.1, ratio
    assert np.mean([scores_variance(rec[0][:, None], np.ones(1))[0] for rec in z]) / truth < 0.5


def test_drawn_lines_are_correlated_as_estimated():
    rng = np.random.default_rng(2)
    z = _ar1(rng, (50, 300), 0.7)
    rho, weights = line_correlation(z, axis=1)
    assert 0.55 < rho[1] < 0.72 and weights.size > 2
    d = correlate_lines(np.random.default_rng(3).standard_normal((400, 300)), rho)
    emp = [np.mean(d[:, :d.shape[1] - k] * d[:, k:]) for k in range(rho.size)]
    assert np.allclose(emp, rho, atol=0.02)
    # nothing beyond the bandwidth: the sum over its lags is the draws' whole long-run variance
    assert abs(np.mean(d[:, :-rho.size] * d[:, rho.size:])) < 0.02
