"""summary.json's posterior coverages (bladetwin.methods): area, centroid and frequency intervals against the truth."""

from types import SimpleNamespace

import numpy as np
import pytest

from bladetwin.methods import _calibration
from rom.contact import ContactPattern


def test_the_centroid_and_frequency_coverages_count_what_the_intervals_hold():
    """Two joints on a 2×3 grid. Joint 1's intervals hold its true centroid on both axes of the left flank and on
    u only of the right; joint 2's right flank has no contact (no centroid to hold) and its left misses v.
    Feature modes 0 and 2: joint 1's intervals hold both of the ROM's true-pattern frequencies, joint 2's one."""
    u, v = np.meshgrid([0.0, 1.0, 2.0], [0.0, 1.0])  # (rows, cols) = (2, 3), m
    ref1 = ContactPattern(np.array([[1, 1, 0], [1, 1, 0]], bool), np.array([[0, 0, 1], [0, 0, 1]], bool))
    ref2 = ContactPattern(np.array([[1, 1, 1], [1, 0, 0]], bool), np.zeros((2, 3), bool))
    # by hand: joint 1 L centroid (0.5, 0.5), R (2, 0.5); joint 2 L (0.75, 0.25)
    ci = np.zeros((2, 2, 2))
    post1 = SimpleNamespace(area_pct_ci90=np.array([[0.0, 100.0], [0.0, 100.0]]), probability=np.zeros((2, 2, 3)),
                            centroid_ci90=np.array([[[0.4, 0.6], [0.4, 0.6]], [[1.9, 2.1], [0.6, 0.9]]]),
                            frequencies_hz_ci90=np.array([[99.0, 101.0], [0.0, 1.0], [199.0, 201.0]]))
    ci[0] = [[0.7, 0.8], [0.3, 0.4]]
    post2 = SimpleNamespace(area_pct_ci90=np.array([[0.0, 100.0], [0.0, 100.0]]), probability=np.zeros((2, 2, 3)),
                            centroid_ci90=ci, frequencies_hz_ci90=np.array([[90.0, 95.0], [0.0, 1.0], [199.0, 201.0]]))
    features = SimpleNamespace(joints=np.array([1, 2]), numerical_hz=np.array([[100.0, 200.0], [100.0, 200.0]]))
    out = _calibration({1: post1, 2: post2}, [ref1, ref2], [1, 2], (u, v), features, [0, 2])
    assert out["ci90_coverage_centroid"] == pytest.approx(4 / 6)  # 2 + 1 of joint 1's four, 1 of joint 2's two
    assert out["ci90_coverage_frequency"] == pytest.approx(3 / 4)
    assert out["ci90_coverage_area"] == 1.0
    no_ref = SimpleNamespace(joints=features.joints, numerical_hz=None)
    assert _calibration({1: post1}, [ref1, ref2], [1], (u, v), no_ref, [0, 2])["ci90_coverage_frequency"] is None
