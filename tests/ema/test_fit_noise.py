"""Each FRF's noise from its own lines (ema.fit_noise.difference_floor), and the structured fit weighted by it.

The truths are modal FRFs written out in ``tests/ema/synth.py`` with complex Gaussian noise of a known level per
FRF: the estimate is checked against that level, and the weighted family fit against the true poles.
"""

from __future__ import annotations

import numpy as np
import pytest

from ema import FRFSet
from ema.families import resolve_families
from ema.family import fit_family
from ema.family_windows import family_windows
from ema.fit_noise import difference_floor, noise_scale
from ema.modal import modal_from_pole, pole_from_modal

from .synth import modal_frfs, rig_noise

N_OUT, N_IN = 16, 2


def _noise(shape, rng):
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)


def test_difference_floor_recovers_each_frf_s_noise_level():
    # five modes on 1601 lines, noise from 1e-6 to 1e-3 of the peak level (the rig's 0.2 % of each FRF's RMS is
    # 1e-5 to 1e-4 of its peak), different in every FRF
    rng = np.random.default_rng(0)
    freq = np.linspace(200.0, 600.0, 1601)
    fn, zeta = np.array([250.0, 320.0, 400.0, 470.0, 550.0]), np.full(5, 0.003)
    phi = rng.standard_normal((N_OUT, fn.size))
    H = modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility")
    sigma = 10.0 ** rng.uniform(-6, -3, (N_OUT, N_IN)) * np.abs(H).max()
    est = difference_floor(H + sigma[:, :, None] * _noise(H.shape, rng))
    # the median of 1597 exponential powers: about 3 % standard error in σ; the response's own fourth difference
    # lifts the estimate where the noise is smallest, by up to 18 % at 1e-6 (second differences: up to 4.3 times)
    np.testing.assert_allclose(est, sigma, rtol=0.2)


def test_difference_floor_is_ones_without_five_lines():
    np.testing.assert_array_equal(difference_floor(np.ones((3, 2, 4), complex)), np.ones((3, 2)))


def test_noise_scale_is_exact_for_a_rank_one_noise_level():
    # σ_oi = a_o b_i: the scale is the level itself (up to the estimator's error), so the scaled FRFs have unit noise
    rng = np.random.default_rng(1)
    freq = np.linspace(100.0, 300.0, 2001)
    a, b = 10.0 ** rng.uniform(-3, 0, N_OUT), 10.0 ** rng.uniform(-1, 0, N_IN)
    H = a[:, None, None] * b[None, :, None] * _noise((N_OUT, N_IN, freq.size), rng)
    scale = noise_scale(FRFSet(freq, H, [(k + 1, 3) for k in range(N_OUT)], [(1, 3), (2, 3)], form="mobility"),
                        (100.0, 300.0))
    np.testing.assert_allclose(scale, a[:, None] * b[None, :], rtol=0.1)


def _quiet_mode_case(seed: int = 4):
    """Two strong modes that every output sees, and between them a third that only four quiet outputs see.

    The quiet outputs (a bladed disk's disk points, under its blades) see the strong modes at 1 % of the others'
    level, the references (at strong points) excite the quiet mode weakly, and each FRF has the virtual rig's
    noise (0.5 % proportional, 0.2 % of its RMS additive): the quiet mode stands far above its own FRFs' noise
    and under the strong FRFs'.
    """
    rng = np.random.default_rng(seed)
    fn, zeta = np.array([300.0, 301.5, 303.0]), np.array([0.002, 0.0015, 0.002])
    phi = np.zeros((N_OUT, 3))
    phi[:, [0, 2]] = rng.choice([-1.0, 1.0], (N_OUT, 2)) * rng.uniform(0.7, 1.3, (N_OUT, 2))
    quiet = np.arange(N_OUT - 4, N_OUT)
    phi[quiet, 0], phi[quiet, 2] = 0.01 * phi[quiet, 0], 0.01 * phi[quiet, 2]
    phi[quiet, 1] = rng.choice([-1.0, 1.0], 4) * rng.uniform(0.7, 1.3, 4) * 0.02
    phi[:N_IN, 1] = 0.05               # the hammers (at strong points) excite it weakly
    freq = np.arange(285.0, 320.0, 0.0625)
    H = rig_noise(modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility"), rng)
    outputs = [(k + 1, 3) for k in range(N_OUT)]
    return FRFSet(freq, H, outputs, outputs[:N_IN], form="mobility"), fn, zeta


@pytest.fixture(scope="module")
def quiet_case():
    return _quiet_mode_case()


def test_the_weighted_family_fit_finds_a_mode_only_quiet_frfs_see(quiet_case):
    frf, fn, zeta = quiet_case
    band = (285.0, 320.0)
    fits = resolve_families(frf, pole_from_modal(fn[[0, 2]], zeta[[0, 2]]) * (1 + 2e-4), band)
    f = np.concatenate([modal_from_pole(fit.poles)[0] for fit in fits])
    for true in fn:
        assert np.min(np.abs(f - true)) / true < 5e-4, (true, f)


def test_unweighted_the_strong_frfs_noise_buries_that_mode(quiet_case):
    # why the weighting: the same window fitted on the FRFs as measured does not find the quiet mode
    frf, fn, zeta = quiet_case
    poles = pole_from_modal(fn[[0, 2]], zeta[[0, 2]]) * (1 + 2e-4)
    (window, core), = family_windows(poles, frf, (285.0, 320.0))
    f = modal_from_pole(fit_family(frf, poles, window, core).poles)[0]
    assert np.min(np.abs(f - fn[1]), initial=np.inf) / fn[1] > 5e-4, f
