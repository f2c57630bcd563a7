"""Pole estimation, selection and LSFD against a known synthetic modal model (all three FRF forms)."""

from __future__ import annotations

import numpy as np
import pytest

from ema import FitSettings, FRFSet, fit, mac
from ema.lscf import lscf
from ema.lsrf import lsrf
from ema.stabilization import STABLE_FDV, StabilizationDiagram, stabilize

from .synth import FN, ZETA, synthetic_case


def _frfset(form, n_i=1):
    freq, H, phi = synthetic_case(form, n_i=n_i)
    outputs = [(k + 1, 3) for k in range(H.shape[0])]
    return FRFSet(freq, H, outputs, outputs[:n_i], form=form), phi


def _check(result, phi, refine):
    m = result.model
    assert m.n_modes == FN.size, f"selected {np.round(m.frequencies_hz, 2)}"
    assert np.max(np.abs(m.frequencies_hz - FN) / FN) < 5e-4
    assert np.max(np.abs(m.damping_ratio - ZETA) / ZETA) < 0.10
    assert np.all(np.diag(mac(m.shapes, phi)) >= 0.99)


@pytest.mark.parametrize("form", ["receptance", "mobility", "accelerance"])
@pytest.mark.parametrize("method", ["lscf", "lsrf"])
def test_estimators_recover_truth_without_refinement(method, form):
    frf, phi = _frfset(form)
    result = fit(frf, (20, 980), FitSettings(method=method, refine=False), max_order=80)
    _check(result, phi, refine=False)


@pytest.mark.parametrize("method", ["lscf", "lsrf"])
def test_refined_fit_recovers_truth(method):
    frf, phi = _frfset("accelerance")
    result = fit(frf, (20, 980), FitSettings(method=method, refine=True), max_order=80)
    _check(result, phi, refine=True)
    assert np.max(np.abs(result.model.damping_ratio - ZETA) / ZETA) < 0.02
    assert result.quality.min() > 0.999


def test_poly_reference_lscf_two_inputs():
    frf, phi = _frfset("receptance", n_i=2)
    result = fit(frf, (20, 980), FitSettings(method="lscf", refine=False), max_order=50)
    _check(result, phi, refine=False)


def test_noise_free_poles_exact_at_every_high_order():
    freq, H, _ = synthetic_case("mobility", noise=0.0)
    frf = FRFSet(freq, H, [(k + 1, 3) for k in range(H.shape[0])], [(1, 3)], form="mobility")
    for ps in (lscf(frf, band=(20, 980), orders=[60]), lsrf(frf, band=(20, 980), orders=[60])):
        f = ps.frequencies_hz
        for fn in FN:
            assert np.min(np.abs(f - fn)) / fn < 1e-8


def test_stabilization_classes_and_frozen():
    frf, _ = _frfset("receptance")
    diagram = stabilize(lscf(frf, band=(20, 980), max_order=30))
    assert isinstance(diagram, StabilizationDiagram)
    assert diagram.count(STABLE_FDV) > 0
    assert set(np.unique(diagram.stability)) <= {0, 1, 2, 3}
    with pytest.raises(AttributeError):
        diagram.method = "x"  # type: ignore[misc]
    with pytest.raises(ValueError):
        diagram.frequencies_hz[0] = 1.0


def test_select_near_and_picks():
    frf, _ = _frfset("receptance")
    near = fit(frf, (20, 980), FitSettings(method="lscf", refine=False), max_order=60, frequencies_hz=[350.5, 779.0])
    assert np.allclose(near.model.frequencies_hz, [350.0, 780.0], rtol=5e-4)
    picks = fit(frf, (20, 980), FitSettings(method="lscf", refine=False), max_order=60, picks=[(60, 480.0)])
    assert picks.model.n_modes == 1 and abs(picks.model.frequencies_hz[0] - 480.0) < 0.5
