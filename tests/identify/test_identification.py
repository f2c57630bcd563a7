"""Identification on the numerical input (paper §6.4, the offline twin), end to end at the coarse level.

A family of smooth "known" contact maps feeds the PCA sampler; the dataset is built on its synthetic
patterns; held-out members of the same family (drawn with another seed, so not in the dataset) are applied
in the ROM with off-grid blade deltas, and their tracked frequencies go into the two-step k-NN. The reference
is a direct dense solve of the ROM with the held-out pattern (:class:`identify.tracking.ModeTracker`).
"""

from __future__ import annotations

import numpy as np
import pytest

from identify.dataset_build import build_dataset
from identify.knn import TwoStepKNN, query_matrix
from identify.synthetic import sample_patterns
from identify.tracking import ModeTracker
from identify.validation import contact_area_fraction, grid_error
from rom.contact import ContactPattern

from ..rom.rom_models import blade, disk_cb

GRID = (3, 7)
DELTA_GRID = np.array([-0.005, 0.0, 0.005, 0.01])


def _family(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Smooth maps sharing one dominant feature (a contact band whose position and tilt vary per joint)."""
    i, j = np.meshgrid(np.linspace(0, 1, GRID[0]), np.linspace(0, 1, GRID[1]), indexing="ij")
    out = []
    for _ in range(2 * n):
        c, tilt, width = rng.uniform(0.35, 0.65), rng.uniform(-0.3, 0.3), rng.uniform(0.35, 0.6)
        g = np.exp(-(((j - c - tilt * (i - 0.5)) / width) ** 2)) + 0.05 * rng.standard_normal(GRID)
        out.append(np.clip(g, 0, 1))
    out = np.array(out)
    return out[:n], out[n:]


@pytest.fixture(scope="module")
def setup():
    rng = np.random.default_rng(11)
    known_L, known_R = _family(rng, 5)
    sp = sample_patterns(known_L, known_R, n_patterns=4, threshold=0.5, random_state=0)
    ds = build_dataset(disk_cb(), blade(), sp.L, sp.R, DELTA_GRID, progress=False)
    tracker = ModeTracker.from_dataset(disk_cb(), blade(), ds)
    # Held-out family members: the same sampler, another seed; none may be a dataset pattern.
    held = sample_patterns(known_L, known_R, n_patterns=4, threshold=0.5, random_state=99)
    known = [ContactPattern(a > 0.5, b > 0.5) for a, b in zip(known_L, known_R, strict=True)]
    return ds, tracker, held, known


def test_held_out_members_beat_the_mean_known_pattern(setup):
    ds, tracker, held, known = setup
    knn = TwoStepKNN.from_dataset(ds)
    feat = list(ds.feature_modes)
    base = ContactPattern(np.mean([p.L for p in known], axis=0) >= 0.5, np.mean([p.R for p in known], axis=0) >= 0.5)
    rng = np.random.default_rng(5)
    err_pred, err_base, area_pred, area_base, eps = [], [], [], [], []
    for k in range(4):
        ref = held.pattern(k, (k + 1) % 4)
        assert not any(np.array_equal(ref.L, L) and np.array_equal(ref.R, R)
                       for L in ds.patterns_L for R in ds.patterns_R), "held-out pattern is in the dataset"
        # Off-grid δ for the 3 grid modes, plus a 4th measured mode the dataset does not vary ("all deltas").
        delta = np.append(rng.uniform(-0.004, 0.009, 3), rng.uniform(-0.01, 0.01))
        f_ref = tracker.track(ref, delta).frequencies_hz
        m = knn.match(query_matrix(delta[None, :3], f_ref[None, feat]))
        iL, iR = (int(x) for x in m.label[0, 0])
        pred = ContactPattern(ds.patterns_L[iL], ds.patterns_R[iR])
        f_pred = tracker.track(pred, delta).frequencies_hz
        f_base = tracker.track(base, delta).frequencies_hz
        err_pred.append(np.mean(np.abs(f_pred[feat] / f_ref[feat] - 1)))
        err_base.append(np.mean(np.abs(f_base[feat] / f_ref[feat] - 1)))
        a_ref = contact_area_fraction(np.stack([ref.L, ref.R]))
        area_pred.append(np.mean(np.abs(contact_area_fraction(np.stack([pred.L, pred.R])) - a_ref)))
        area_base.append(np.mean(np.abs(contact_area_fraction(np.stack([base.L, base.R])) - a_ref)))
        eps.append(grid_error(np.asarray(m.delta)[:1], delta[None, :3], DELTA_GRID[1] - DELTA_GRID[0]).epsilon_pct)
    # Step 1 picks the nearest δ row: |ε| ≤ 50 % of the step for every mode.
    assert np.all(np.abs(np.concatenate(eps)) <= 50 + 1e-9)
    # Step 2: the predicted pattern reproduces the held-out member's features better than the baseline.
    assert np.mean(err_pred) < np.mean(err_base)
    assert np.mean(area_pred) <= np.mean(area_base) + 1e-12


def test_tracker_matches_the_dataset_on_its_own_samples(setup):
    """The tracker (direct solve + MAC) reproduces stored samples: the numerical input is consistent."""
    ds, tracker, _, _ = setup
    for s in (0, len(ds.deltas) // 3, len(ds.deltas) - 1):
        iL, iR = ds.pair[s]
        f = tracker.track(ContactPattern(ds.patterns_L[iL], ds.patterns_R[iR]), ds.deltas[s]).frequencies_hz
        np.testing.assert_allclose(f, ds.frequencies_hz[s], rtol=1e-4)


def test_the_untracked_modes_are_the_solves_other_candidates(setup):
    """untracked_hz and track split the direct solve's candidates: every one once, none tracked twice."""
    from identify.tracking import d1b_pencil
    from rom.modal import dense_modes

    ds, tracker, _, _ = setup
    iL, iR = ds.pair[len(ds.deltas) // 2]
    pattern, delta = ContactPattern(ds.patterns_L[iL], ds.patterns_R[iR]), ds.deltas[len(ds.deltas) // 2]
    K, M = d1b_pencil(tracker.disk, tracker.blade, pattern.L, pattern.R, formulation=tracker.formulation,
                      delta=delta)
    every = dense_modes(K, M, tracker.n_modes + tracker.n_extra, max_rigid=6).frequencies_hz
    others = tracker.untracked_hz(pattern, delta)
    assert others.size == tracker.n_extra and np.all(np.diff(others) >= 0)
    both = np.sort(np.r_[tracker.track(pattern, delta).frequencies_hz, others])
    np.testing.assert_allclose(both, np.sort(every), rtol=1e-7)  # one BLAS thread there, several here
