"""Band-by-band (local) fitting of a dense, bladed-disk-like spectrum against a known modal model.

The truth imitates a full-assembly test of an 18-blade disk: 18 outputs (one per blade), one input at
blade 1 (driving point), mobility FRFs on 6400 lines of 0.25 Hz, 1 % noise. 29 modes in [300, 1500] Hz,
mostly in four nodal-diameter families whose mistuned pairs are 0.3-0.45 % apart with 0.1-0.2 % damping
(disk-dominated low-ND modes 0.4-1 %). Within a family the shapes are orthonormal: cos(n theta + psi)
for nodal diameter n, the two members of a pair in quadrature, plus a random localisation, then
orthonormalised. Four modes sit on or next to sub-band boundaries on purpose.

A single real-coefficient fit of the whole band (``FitSettings(n_bands=1)``) finds about half of these modes,
even at order 200; band-by-band fitting (``FitSettings(n_bands=3..6)``) must find all of them, and its merge
must neither duplicate nor lose the boundary modes. See docs/ema.md, "Band-by-band fitting".
"""

from __future__ import annotations

import numpy as np
import pytest

from ema import FitSettings, FRFSet, fit, mac
from ema.global_fit import local_poles
from ema.lsrf import lsrf
from ema.stabilization import stabilize

from .synth import modal_frfs

N_BLADES = 18
BAND = (300.0, 1500.0)
# (frequency Hz, damping ratio, nodal diameter); one list per family
FAMILIES = [
    [(380.0, 0.008, 0), (420.0, 0.005, 1), (441.0, 0.002, 2), (443.0, 0.0015, 2), (452.0, 0.0015, 3),
     (453.6, 0.001, 3), (459.0, 0.0012, 4), (460.5, 0.001, 4)],
    [(600.0, 0.006, 0)],
    [(700.0, 0.01, 0), (728.0, 0.006, 1), (745.0, 0.002, 2), (748.0, 0.0015, 2), (756.0, 0.0012, 3),
     (758.5, 0.001, 3)],
    [(980.0, 0.008, 0), (1020.0, 0.005, 1), (1036.0, 0.002, 2), (1040.0, 0.0018, 2), (1048.0, 0.0015, 3),
     (1051.2, 0.0012, 3), (1056.0, 0.001, 4)],
    [(1198.5, 0.004, 5)],
    [(1290.0, 0.006, 1), (1330.0, 0.004, 2), (1345.0, 0.002, 3), (1350.0, 0.0015, 3), (1357.0, 0.0012, 4),
     (1361.5, 0.001, 4)],
]
# modes placed on purpose on (or within 0.2 % of) the core boundaries of some n_bands over BAND:
# 600 and 1198.5 (n_bands=4: 600 | 900 | 1200), 700 (n_bands=3 and 6), 1020 (n_bands=5)
BOUNDARY_MODES = {3: [700.0], 4: [600.0, 1198.5], 5: [1020.0], 6: [700.0]}


def _truth(seed: int = 0):
    rng = np.random.default_rng(seed)
    theta = 2 * np.pi * np.arange(N_BLADES) / N_BLADES
    fn, zeta, cols = [], [], []
    for fam in FAMILIES:
        while True:
            phase: dict[int, float] = {}
            basis = []
            for _, _, nd in fam:
                psi = phase[nd] + np.pi / 2 if nd in phase else rng.uniform(0, 2 * np.pi)
                phase[nd] = psi
                basis.append(np.cos(nd * theta + psi))
            q, _ = np.linalg.qr(np.array(basis).T + 0.3 * rng.standard_normal((N_BLADES, len(fam))))
            if np.all(np.abs(q[0]) > 0.12):  # the driving point sees every mode
                break
        cols.append(q * np.sign(q[0]))
        fn += [m[0] for m in fam]
        zeta += [m[1] for m in fam]
    return np.array(fn), np.array(zeta), np.hstack(cols)


@pytest.fixture(scope="module")
def dense():
    fn, zeta, phi = _truth()
    rng = np.random.default_rng(1)
    freq = np.linspace(0.0, 1600.0, 6401)[1:]
    H = modal_frfs(freq, fn, zeta, phi, phi[:1], "mobility")
    H = H + 0.01 * np.abs(H) * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    outputs = [(b + 1, 3) for b in range(N_BLADES)]
    return FRFSet(freq, H, outputs, outputs[:1], form="mobility"), fn, zeta, phi


def test_truth_is_dense_and_has_boundary_modes(dense):
    _, fn, zeta, phi = dense
    assert fn.size == 29 and np.all(np.diff(fn) > 0)
    assert 0.003 < np.min(np.diff(fn) / fn[:-1]) < 0.0035
    assert zeta.min() == 0.001 and zeta.max() == 0.01
    for n_bands, modes in BOUNDARY_MODES.items():
        edges = np.linspace(*BAND, n_bands + 1)[1:-1]
        for f in modes:
            assert f in fn and np.min(np.abs(edges - f)) / f <= 0.002
    # mistuned pairs are orthogonal, so one input and 18 outputs can separate them
    close = np.flatnonzero(np.diff(fn) / fn[:-1] < 0.01)
    assert np.all(np.abs(np.sum(phi[:, close] * phi[:, close + 1], axis=0)) < 1e-12)


def _check(result, fn, zeta, phi, n_bands):
    m = result.model
    found = m.frequencies_hz
    # one-to-one: every true mode found once, nothing else
    nearest = np.argmin(np.abs(found[:, None] - fn[None, :]), axis=1)
    rel = np.abs(found - fn[nearest]) / fn[nearest]
    missing = [f for f in fn if np.min(np.abs(found - f)) / f > 5e-4]
    extra = found[rel > 5e-4]
    assert not missing and not extra.size, f"missing {missing}, extra {np.round(extra, 2)}"
    assert m.n_modes == fn.size, f"duplicates: {np.round(found, 2)}"
    assert np.array_equal(nearest, np.arange(fn.size))
    assert np.max(rel) < 5e-4
    assert np.max(np.abs(m.damping_ratio - zeta) / zeta) < 0.10
    assert np.min(np.diag(mac(m.shapes, phi))) >= 0.99
    # the merge at the sub-band boundaries: a boundary mode is one mode, and one pole per model order in
    # the diagram, present at (nearly) every order from 20 on; a hard cut at the boundary gives two
    # poles or none at an order when the neighbouring fits place the mode on opposite sides of it
    d = result.diagram
    for f in BOUNDARY_MODES.get(n_bands, []):
        assert np.sum(np.abs(found - f) / f < 0.005) == np.sum(np.abs(fn - f) / f < 0.005) == 1
        near = np.abs(d.frequencies_hz - f) / f < 1e-3
        per_order = np.bincount(d.order[near], minlength=max(d.orders) + 1)
        assert per_order.max() == 1, f"{f} Hz: {per_order.max()} poles in one order"
        assert np.count_nonzero(per_order[20:]) >= 0.9 * (per_order.size - 20), f"{f} Hz lost in the merge"


def test_band_by_band_fit_recovers_every_mode(dense):
    frf, fn, zeta, phi = dense
    result = fit(frf, BAND, FitSettings(n_bands=4), max_order=60)
    assert result.diagram.method == "lsrf/local"
    assert result.diagram.band_hz == BAND
    _check(result, fn, zeta, phi, 4)
    # refinement: damping well inside the 10 % tolerance, synthesis matches every FRF
    assert np.max(np.abs(result.model.damping_ratio - zeta) / zeta) < 0.02
    assert result.quality.min() > 0.99
    assert not result.dropped_hz


@pytest.mark.parametrize("n_bands", [3, 5, 6])
def test_band_count_does_not_matter(dense, n_bands):
    frf, fn, zeta, phi = dense
    result = fit(frf, BAND, FitSettings(n_bands=n_bands, refine=False), max_order=60)
    _check(result, fn, zeta, phi, n_bands)


def test_local_poles_merged_set(dense):
    frf, fn, _, _ = dense
    band = (400.0, 480.0)
    poles = local_poles(frf, 2, "lsrf", band, max_order=20)
    assert poles.method == "lsrf/local" and poles.band_hz == band and poles.orders == tuple(range(1, 21))
    assert poles.frequencies_hz.min() >= band[0] and poles.frequencies_hz.max() <= band[1]
    assert poles.vector.shape == (poles.pole.size, N_BLADES)
    diagram = stabilize(poles)
    top = diagram.frequencies_hz[diagram.order == 20]
    for f in fn[(fn > 405) & (fn < 475)]:
        assert np.min(np.abs(top - f)) / f < 5e-4
    with pytest.raises(ValueError):
        local_poles(frf, 0, "lsrf", band)
    with pytest.raises(ValueError):
        local_poles(frf, 2, "lsrf", band, overlap=1.5)
    with pytest.raises(ValueError):
        local_poles(frf, 2, "polymax", band)


def test_complex_lsrf_sends_noise_poles_to_negative_damping(dense):
    """Local (complex) LSRF: spare orders do not fill the band with near-zero-damping noise poles."""
    frf, fn, _, _ = dense
    band = (300.0, 675.0)
    n_true = int(np.sum((fn >= band[0]) & (fn <= band[1])))
    ps = lsrf(frf, band=band, orders=[60], coefficients="complex")
    physical = (ps.damping_ratio > 0) & (ps.damping_ratio < 0.2)
    assert n_true <= physical.sum() <= n_true + 5
    for f in fn[(fn >= band[0]) & (fn <= band[1])]:
        assert np.min(np.abs(ps.frequencies_hz[physical] - f)) / f < 5e-5
