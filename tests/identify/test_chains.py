"""Convergence figures (identify.chains) against chains of known behaviour: independent draws, AR(1) chains
of known integrated autocorrelation time τ = (1 + φ)/(1 − φ), and chains that disagree in location or scale."""

import numpy as np
import pytest

from identify.chains import ESS_MIN, RHAT_MAX, diagnose, effective_sample_size, split_rhat


def _ar1(n: int, m: int, phi: float, seed: int) -> np.ndarray:
    """m AR(1) chains of n draws, stationary unit variance, shape (n, m)."""
    rng = np.random.default_rng(seed)
    x = np.empty((n, m))
    x[0] = rng.standard_normal(m)
    e = np.sqrt(1 - phi**2) * rng.standard_normal((n, m))
    for t in range(1, n):
        x[t] = phi * x[t - 1] + e[t]
    return x


def test_independent_draws_have_rhat_one_and_every_draw_effective():
    x = np.random.default_rng(0).standard_normal((1000, 32))
    assert 1.0 <= split_rhat(x) < 1.01
    ess = effective_sample_size(x[..., None])[0]
    assert 0.8 * x.size < ess < 1.25 * x.size, ess


@pytest.mark.parametrize("phi", [0.5, 0.9])
def test_the_ess_of_ar1_chains_is_the_draws_over_their_known_tau(phi):
    x = _ar1(4000, 16, phi, seed=1)
    tau = (1 + phi) / (1 - phi)
    ess = effective_sample_size(x[..., None])[0]
    assert abs(ess / (x.size / tau) - 1) < 0.2, (ess, x.size / tau)


def test_a_walker_stuck_apart_or_wider_raises_rhat():
    rng = np.random.default_rng(2)
    x = rng.standard_normal((1000, 32))
    stuck = x.copy()
    stuck[:, :4] += 3.0  # four walkers three σ away
    assert split_rhat(stuck) > RHAT_MAX
    wide = x.copy()
    wide[:, :16] *= 3.0  # same centre, half the walkers three times as wide: only the folded R̂ sees it
    assert split_rhat(wide) > RHAT_MAX
    drifting = x + np.linspace(0, 2, 1000)[:, None]  # every walker still drifting: the split halves disagree
    assert split_rhat(drifting) > RHAT_MAX


def test_diagnose_takes_the_worst_parameter_and_a_constant_is_converged():
    rng = np.random.default_rng(3)
    good = rng.standard_normal((800, 24, 2))
    d = diagnose(good, np.zeros((800, 24, 1)), n_steps=1200)
    assert d.converged and d.n_steps == 1200 and d.rhat < 1.01 and d.ess > ESS_MIN
    slow = np.concatenate([good, _ar1(800, 24, 0.995, seed=4)[..., None]], axis=2)
    d = diagnose(slow)
    assert not d.converged and d.ess < ESS_MIN
    stuck = good.copy()
    stuck[:, 3, 0] = stuck[0, 3, 0]  # one walker never moves in one parameter: no effective draws there
    assert effective_sample_size(stuck)[0] == 0 and not diagnose(stuck).converged
    assert np.isnan(effective_sample_size(np.zeros((10, 4, 1))))[0]
    with pytest.raises(ValueError):
        split_rhat(np.zeros((3, 4)))
