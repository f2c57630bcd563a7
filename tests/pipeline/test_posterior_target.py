"""What one unfilmed joint's posterior is given (bladetwin.stages.posterior): its target and its noise."""

import warnings

import numpy as np
import pytest

from bladetwin.stages.bias import Features
from bladetwin.stages.posterior import _target


def _features(measured, filmed):
    """Features of joints 1…n; ``filmed`` joints have a ROM prediction (their film), so they set the bias."""
    measured = np.asarray(measured, float)
    rom = {j: measured[j - 1] / 1.01 for j in filmed}  # each filmed test 1 % above its ROM, on every mode
    ratios = np.array([measured[j - 1] / rom[j] - 1 for j in filmed])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a mode no filmed joint found: NaN, then 0 (as the stage)
        spread = np.nan_to_num(np.nanstd(ratios, axis=0))
    return Features(np.arange(1, len(measured) + 1), measured, np.full(measured.shape[1], 0.01), spread, rom,
                    None, True)


@pytest.mark.parametrize("input", ["experimental", "experimental_no_bias"])
def test_a_mode_fewer_than_two_filmed_joints_found_is_left_out(input):
    """Mode 2 was found by one of the three filmed joints, mode 3 by none: their model error is unknown, so
    the unfilmed joint 4's posterior does not use them; the others keep their values (bias removed or not)."""
    nan = np.nan
    f = _features([[100.0, 200.0, nan], [101.0, nan, nan], [100.5, nan, nan], [100.2, 201.0, 301.0]],
                  filmed=[1, 2, 3])
    y, sigma = _target(f, None, None, None, 4, input, None, np.zeros(3), None)
    expected = 100.2 / 1.01 if input == "experimental" else 100.2
    assert y[0] == pytest.approx(expected) and np.isnan(y[1:]).all()
    # the scatter of three joints about their median, widened for a new joint: √((n + 1)/(n − 1)) = √2
    assert sigma[0] == pytest.approx(np.sqrt(2) * f.spread[0])


def test_with_one_filmed_joint_every_mode_it_found_is_used():
    """One filmed joint measures no scatter on any mode: the modes it found stay (noise without a scatter)."""
    f = _features([[100.0, 200.0, np.nan], [100.2, 201.0, 301.0]], filmed=[1])
    y, sigma = _target(f, None, None, None, 2, "experimental", None, np.zeros(3), None)
    assert np.isfinite(y[:2]).all() and np.isnan(y[2])
    assert np.all(sigma[:2] == 0)
