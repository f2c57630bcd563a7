"""The AF's intervals over posterior samples (bladetwin.stages.response), against direct solves of each sample.

Reference: the lumped bladed disk of tests/rom/test_forced_perturbation.py. Each "posterior sample" changes the
root springs of the unfilmed joints; its disk–one-blade frequencies come from direct solves of each joint's
disk–one-blade model, and its AF from a direct eigen-solve of the whole changed disk. The stage sees only what a
run gives it: the answer's assembly modes, the samples' d1b frequencies, and one d1b solve's modes.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg as sla

from bladetwin.stages.response_intervals import contact_samples, family_changes, sample_afs
from rom.fe_assembly import AssemblyModes
from rom.forced import amplification_factor, family_band, forced_response

from ..rom.test_forced_perturbation import K_ROOT, N, blade_rows, bladed_disk, d1b_blade_mode

UNFILMED = (2, 5, 6, 10)  # 1-based joints with a posterior


def _d1b_modes(k_root, slot: int) -> AssemblyModes:
    """The disk–one-blade model's modes at its blade DOF, labelled as a run's solve labels them."""
    K, M = bladed_disk(k_root, [slot])
    lam, phi = sla.eigh(K, M)
    return AssemblyModes(np.sqrt(lam) / (2 * math.pi), phi[[N]], [("blade", slot + 1, 1, 1)])


def _f_d1b(k_root, slot: int) -> float:
    return math.sqrt(d1b_blade_mode(k_root, slot)[0]) / (2 * math.pi)


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(11)
    k_answer = K_ROOT * (1 + 0.01 * rng.standard_normal(N))
    draws = []
    for _ in range(6):  # each sample moves every unfilmed root spring by up to ±2 %
        k = k_answer.copy()
        k[[j - 1 for j in UNFILMED]] *= 1 + rng.uniform(-0.02, 0.02, len(UNFILMED))
        draws.append(k)
    posts = {j: SimpleNamespace(answer_hz=np.array([_f_d1b(k_answer, j - 1)]),
                                samples_hz=np.array([[_f_d1b(k, j - 1)] for k in draws])) for j in UNFILMED}
    return k_answer, draws, posts


def test_each_samples_af_matches_the_direct_solve_of_that_disk(case):
    k_answer, draws, posts = case
    mis, _, _ = blade_rows(*bladed_disk(k_answer))
    tuned, _, _ = blade_rows(*bladed_disk(np.full(N, K_ROOT)))
    band = family_band(tuned, 1)
    eos = tuple(range(N // 2 + 1))
    refs = {e: forced_response(tuned, eo, band) for e, eo in enumerate(eos)}
    samples = contact_samples(N, posts)
    assert samples.n_samples == len(draws)
    assert np.all(samples.rel[:, [j - 1 for j in range(1, N + 1) if j not in UNFILMED]] == 0)
    dl, psi, why = family_changes(samples, band, _d1b_modes(k_answer, 0))
    assert why == ""
    af, worst = sample_afs(mis, tuned, band, eos, refs, dl, psi)
    base = np.array([amplification_factor(mis, tuned, eo, band, tuned_response=refs[e]).af
                     for e, eo in enumerate(eos)])
    moved = 0.0
    for s, k in enumerate(draws):
        exact_model, _, _ = blade_rows(*bladed_disk(k))
        exact = [amplification_factor(exact_model, tuned, eo, band, tuned_response=refs[e]) for e, eo in
                 enumerate(eos)]
        for e, a in enumerate(exact):
            moved = max(moved, abs(a.af - base[e]))
            assert abs(af[s, e] - a.af) <= max(0.1 * abs(a.af - base[e]), 0.01 * a.af), (s, e, af[s, e], a.af)
    assert moved > 0.03  # the samples move some AF by more than 3 %: the check has something to see


def test_a_family_without_a_tracked_mode_in_its_band_has_no_interval(case):
    k_answer, _, posts = case
    tuned, _, _ = blade_rows(*bladed_disk(np.full(N, K_ROOT)))
    far = {j: SimpleNamespace(answer_hz=p.answer_hz * 3, samples_hz=p.samples_hz * 3) for j, p in posts.items()}
    dl, _, why = family_changes(contact_samples(N, far), family_band(tuned, 1), _d1b_modes(k_answer, 0))
    assert dl is None and why.startswith("no tracked disk–one-blade mode in the family's band")
    assert contact_samples(N, {3: None}) is None


def test_the_discrepancy_is_the_blade_scatter_not_the_offset_nor_one_coupled_mode():
    from bladetwin.stages.response_intervals import family_discrepancy

    rng = np.random.default_rng(2)
    model = 200 * (1 + 0.002 * np.arange(40))  # modes 0.2 % apart: frequency pairing cannot cross them
    test = model * 1.01 * (1 + 0.0004 * rng.standard_normal(40))  # a 1 % offset, 0.04 % scatter
    test[0] *= 1.015  # one disk-coupled mode 1.5 % further off
    sigma = family_discrepancy(model, test, (150.0, 250.0))
    assert 0.0003 < sigma < 0.00055, sigma
    assert np.isnan(family_discrepancy(model[:2], test[:2], (150.0, 250.0)))
