"""identify.refine_pattern: the compass search after the k-NN (beyond the paper), at the coarse level.

The target is a member of the synthetic family that no pre-drawn pair holds: PCA coefficients from another
seed, at a lower contact level (a joint seated deeper). Its tracked frequencies come from a direct solve
(:class:`identify.tracking.ModeTracker`), the independent reference. The best any lookup among the dataset's
pairs can do is computed by brute force over all of them.
"""

from __future__ import annotations

import numpy as np
import pytest

from identify.dataset_build import build_dataset
from identify.errors import IdentifyError
from identify.refine import refine_pattern
from identify.sampler import PatternSampler
from identify.synthetic import sample_patterns
from identify.tracking import ModeTracker
from rom.contact import ContactPattern

from ..rom.rom_models import blade, disk_cb
from .test_identification import GRID, _family

DELTA = np.array([0.003, -0.002, 0.006])


@pytest.fixture(scope="module")
def setup():
    rng = np.random.default_rng(11)
    known_L, known_R = _family(rng, 5)
    sp = sample_patterns(known_L, known_R, n_patterns=4, threshold=0.5, random_state=0)
    ds = build_dataset(disk_cb(), blade(), sp.L, sp.R, np.array([0.0, 0.005]), progress=False)
    tracker = ModeTracker.from_dataset(disk_cb(), blade(), ds)
    samplers = (PatternSampler(threshold=0.5).fit(known_L), PatternSampler(threshold=0.5).fit(known_R))
    held = sample_patterns(known_L, known_R, n_patterns=1, threshold=0.5, random_state=99)
    # The same held-out maps, read at a lower level: more contact than the family's threshold gives.
    target = ContactPattern(held.gray_L[0] > 0.3, held.gray_R[0] > 0.3)
    feat = list(ds.feature_modes)
    f_target = tracker.track(target, DELTA).frequencies_hz[feat]
    return sp, ds, tracker, samplers, target, feat, f_target


def _err_pct(tracker, pattern, feat, f_target) -> float:
    f = tracker.track(pattern, DELTA).frequencies_hz[feat]
    return 100 * float(np.mean(np.abs(f / f_target - 1)))


def test_refinement_beats_every_pre_drawn_pair(setup):
    sp, ds, tracker, samplers, target, feat, f_target = setup
    lookup = {(i, j): _err_pct(tracker, sp.pattern(i, j), feat, f_target)
              for i in range(len(sp.L)) for j in range(len(sp.R))}
    (i0, j0), best_lookup = min(lookup.items(), key=lambda kv: kv[1])
    assert not any(np.array_equal(target.L, a) and np.array_equal(target.R, b) for a in sp.L for b in sp.R)
    res = refine_pattern(tracker, *samplers, f_target, feat, sp.gray_L[i0], sp.gray_R[j0], delta=DELTA,
                         max_solves=60)
    assert res.start_error_pct == pytest.approx(best_lookup, rel=1e-9)
    assert res.n_solves <= 60
    # The reported error is the refined pattern's, recomputed by an independent solve.
    assert res.error_pct == pytest.approx(_err_pct(tracker, res.pattern, feat, f_target), rel=1e-9)
    # A lookup can do no better than its best pair; the search reaches well below it.
    assert res.error_pct < 0.5 * best_lookup
    # Its grids are what its coefficients and levels give.
    assert np.array_equal(res.pattern.L, samplers[0].inverse_transform(res.kappa_L[None])[0] > res.level_L)
    assert np.array_equal(res.pattern.R, samplers[1].inverse_transform(res.kappa_R[None])[0] > res.level_R)


def test_refinement_is_deterministic_and_respects_the_budget(setup):
    sp, ds, tracker, samplers, target, feat, f_target = setup
    a = refine_pattern(tracker, *samplers, f_target, feat, sp.gray_L[1], sp.gray_R[2], delta=DELTA, max_solves=8)
    b = refine_pattern(tracker, *samplers, f_target, feat, sp.gray_L[1], sp.gray_R[2], delta=DELTA, max_solves=8)
    assert a.n_solves <= 8 and a.error_pct <= a.start_error_pct
    assert np.array_equal(a.pattern.L, b.pattern.L) and np.array_equal(a.pattern.R, b.pattern.R)
    assert a.error_pct == b.error_pct
    # A tolerance at the start's error stops the search before its first poll (measured targets: the model
    # error); halfway down it stops as soon as the error is at most that, within the same solves.
    c = refine_pattern(tracker, *samplers, f_target, feat, sp.gray_L[1], sp.gray_R[2], delta=DELTA, max_solves=8,
                       tol_pct=a.start_error_pct)
    assert c.n_solves == 1 and c.error_pct == c.start_error_pct
    full = refine_pattern(tracker, *samplers, f_target, feat, sp.gray_L[1], sp.gray_R[2], delta=DELTA,
                          max_solves=60)
    tol = 0.5 * (full.start_error_pct + full.error_pct)
    d = refine_pattern(tracker, *samplers, f_target, feat, sp.gray_L[1], sp.gray_R[2], delta=DELTA, max_solves=60,
                       tol_pct=tol)
    assert d.error_pct <= tol and d.n_solves <= full.n_solves


def test_refinement_refuses_bad_input(setup):
    sp, ds, tracker, samplers, target, feat, f_target = setup
    args = (sp.gray_L[0], sp.gray_R[0])
    with pytest.raises(IdentifyError, match="target_hz must hold 3"):
        refine_pattern(tracker, *samplers, f_target[:2], feat, *args)
    with pytest.raises(IdentifyError, match="feature_modes"):
        refine_pattern(tracker, *samplers, f_target, [0, 1, 99], *args)
    with pytest.raises(IdentifyError, match="sampler_R must be a fitted"):
        refine_pattern(tracker, samplers[0], PatternSampler(), f_target, feat, *args)
    with pytest.raises(IdentifyError, match="tol_pct"):
        refine_pattern(tracker, *samplers, f_target, feat, *args, tol_pct=-1)
    with pytest.raises(IdentifyError, match="max_solves"):
        refine_pattern(tracker, *samplers, f_target, feat, *args, max_solves=0)
    with pytest.raises(IdentifyError, match=r"maps must have shape \(n, 3, 7\)"):
        refine_pattern(tracker, *samplers, f_target, feat, np.zeros((4, 4)), sp.gray_R[0])
    assert GRID == (3, 7)



def test_a_shared_memo_saves_solves_and_changes_no_result(setup, monkeypatch):
    """Two targets from one start share their first poll; through a memo the second search solves less."""
    sp, ds, tracker, samplers, target, feat, f_target = setup
    other = f_target * (1 + np.array([0.002, -0.001, 0.001])[: len(feat)])
    plain = [refine_pattern(tracker, *samplers, f, feat, sp.gray_L[1], sp.gray_R[2], delta=DELTA, max_solves=20)
             for f in (f_target, other)]
    calls = []
    track = ModeTracker.track
    monkeypatch.setattr(ModeTracker, "track", lambda self, p, d=None: calls.append(1) or track(self, p, d))
    memo: dict = {}
    shared = [refine_pattern(tracker, *samplers, f, feat, sp.gray_L[1], sp.gray_R[2], delta=DELTA, max_solves=20,
                             memo=memo) for f in (f_target, other)]
    for a, b in zip(plain, shared, strict=True):  # the memo changes no decision: hits count as solves
        assert np.array_equal(a.pattern.L, b.pattern.L) and np.array_equal(a.pattern.R, b.pattern.R)
        assert (a.error_pct, a.start_error_pct, a.n_solves) == (b.error_pct, b.start_error_pct, b.n_solves)
    # Every grid was solved once: the second search's first poll came from the memo.
    assert len(calls) == len(memo) < plain[0].n_solves + plain[1].n_solves
    # An entry holds every tracked mode (Hz), not only the features: a memo serves any target.
    key, f = next(iter(memo.items()))
    assert isinstance(key, str) and f.shape == (tracker.n_modes,)
    # Another δ is another key: the same grids at another δ are solved again. So is a scalar δ beside the
    # vector of its value: the scalar perturbs every blade mode, the vector only the first.
    for delta in (2 * DELTA, DELTA[0], DELTA[:1]):
        calls.clear()
        refine_pattern(tracker, *samplers, f_target, feat, sp.gray_L[1], sp.gray_R[2], delta=delta, max_solves=3,
                       memo=memo)
        assert len(calls) == 3, delta
