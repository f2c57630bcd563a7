"""The order from the data (issue 31, item 2): modes a fit missed are found where the residual stands above noise.

The truth: three strong modes seen at every output, and two weak ones between them that only two of 24
outputs see (as a disk mode at a bladed disk's tips), with the virtual rig's noise (0.5 % proportional,
0.2 % of each FRF's RMS additive). The weak modes stand far above the floor of their two FRFs and vanish in
any sum over all FRFs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ema import FRFSet
from ema.lsfd import modal_model
from ema.mac import mac_paired, pair_by_frequency
from ema.modal import ModalModel, pole_from_modal
from ema.uncertainty import pole_std
from ema.unexplained import fill_unexplained, missed_beside, unexplained_lines, with_margins

from .synth import modal_frfs, rig_noise

N_OUT, N_IN = 24, 3
FN = np.array([300.0, 352.0, 410.0, 455.0, 520.0])
ZETA = np.array([0.003, 0.001, 0.002, 0.0012, 0.003])
WEAK = np.array([False, True, False, True, False])
BAND = (260.0, 560.0)


def _case(seed: int = 5):
    rng = np.random.default_rng(seed)
    phi = rng.standard_normal((N_OUT, FN.size))
    phi[:N_IN] = np.sign(phi[:N_IN]) * rng.uniform(0.7, 1.3, (N_IN, FN.size))
    for r in np.flatnonzero(WEAK):   # seen by two outputs (and weakly by a reference, which excites it)
        phi[:, r] = 0.0
        phi[rng.choice(np.arange(N_IN, N_OUT), 2, replace=False), r] = 1.0
        phi[0, r] = 0.05
    freq = 0.25 * np.arange(1000, 2321)   # 250-580 Hz
    H = modal_frfs(freq, FN, ZETA, phi, phi[:N_IN], "mobility")
    H = rig_noise(H, rng)
    outputs = [(k + 1, 3) for k in range(N_OUT)]
    return FRFSet(freq, H, outputs, outputs[:N_IN], form="mobility"), phi


def _model(frf: FRFSet, keep: np.ndarray):
    """The LSFD model at some of the true poles, with standard deviations (as ema.fit returns it)."""
    model = modal_model(frf, pole_from_modal(FN[keep], ZETA[keep]), BAND)
    f_std, z_std = pole_std(frf, model.poles, BAND)

    return replace(model, frequency_std_hz=f_std, damping_std=z_std)


@pytest.fixture(scope="module")
def case():
    return _case()


def test_the_weak_modes_stand_out_only_where_the_model_lacks_them(case):
    frf, _ = case
    freq, z, threshold, floor = unexplained_lines(frf, _model(frf, ~WEAK), BAND)
    above = freq[z > threshold]
    assert above.size, "the missing modes must be flagged"
    # every flagged line lies nearer a missing mode than any modelled one, and each missing mode's own line
    # is flagged
    nearest = np.argmin(np.abs(above[:, None] - FN[None, :]), axis=1)
    assert np.all(WEAK[nearest]), above[~WEAK[nearest]]
    for f in FN[WEAK]:
        assert np.any(np.abs(above - f) <= 2 * 0.25), f
    assert floor.shape == (N_OUT, N_IN) and np.all(floor > 0)


def test_noise_alone_stays_below_the_threshold(case):
    frf, _ = case
    freq, z, threshold, _ = unexplained_lines(frf, _model(frf, np.ones(FN.size, bool)), BAND)
    assert np.max(z) <= threshold, freq[np.argmax(z)]


def test_fill_unexplained_finds_the_missing_modes_and_nothing_else(case):
    frf, phi = case
    filled = fill_unexplained(frf, _model(frf, ~WEAK), BAND)
    rows, cols = pair_by_frequency(filled.frequencies_hz, FN, 5e-4)
    assert filled.n_modes == FN.size and rows.size == FN.size, filled.frequencies_hz
    # the found modes' shapes are the truth's (rank-one residues, scaled back from the noise weighting)
    weak = np.flatnonzero(WEAK[cols])
    m = mac_paired(filled.shapes[:, rows[weak]].T, phi[:, cols[weak]].T)
    assert np.all(m >= 0.95), m
    assert np.all(np.isfinite(filled.frequency_std_hz))


def test_a_complete_model_is_left_alone(case):
    frf, _ = case
    model = _model(frf, np.ones(FN.size, bool))
    assert fill_unexplained(frf, model, BAND).n_modes == FN.size


def test_the_family_zoom_shows_modes_that_few_points_see(case):
    """plot_families divides each FRF by its own median: a mode seen by 2 of 24 outputs stands higher above the
    curve beside it than in a plain RMS over the FRFs (measured: 1.54 and 1.29 against 1.33 and 1.12)."""
    from ema.plots import plot_families

    frf, _ = case
    model = _model(frf, np.ones(FN.size, bool))
    for f0 in FN[WEAK]:
        fig = plot_families(frf, model, [(f0 - 8.0, f0 + 8.0)])
        x, y = fig.axes[0].lines[0].get_data()
        shown = y[np.argmin(np.abs(x - f0))] / np.median(y)
        mask = (frf.freq_hz >= f0 - 8.0) & (frf.freq_hz <= f0 + 8.0)
        plain = np.sqrt(np.mean(np.abs(frf.H[:, :, mask]) ** 2, axis=(0, 1)))
        assert shown >= 1.25 and shown > 1.1 * plain[np.argmin(np.abs(frf.freq_hz[mask] - f0))] / np.median(plain)


def test_repeated_merges_label_the_method_once(case):
    """Each window the scan fills is one merge; the model's method says "+families" once (the report's title)."""
    frf, _ = case
    model = _model(frf, ~WEAK)
    filled = fill_unexplained(frf, replace(model, method="lsrf"), BAND)
    assert filled.method == "lsrf+families", filled.method


def test_a_model_pole_that_moves_onto_the_missing_line_still_brings_its_mode_in(case):
    """The window opened at 352 Hz holds a pole of the model 3 Hz off (as a neighbour's at a window's edge): its
    refinement moves that pole onto the missing mode and growth adds none ("1 modes -> 1"). The mode on the line
    is new all the same (a 36-blade campaign lost its true 608.48 Hz this way). The model's own pole is left to
    merge_families' rule for a mode the structured fit lost; here it is not a true mode, and it stays."""
    frf, _ = case
    f = np.r_[FN[~WEAK], 349.0]
    z = np.r_[ZETA[~WEAK], 0.001]
    model = modal_model(frf, pole_from_modal(f, z), BAND)
    f_std, z_std = pole_std(frf, model.poles, BAND)
    filled = fill_unexplained(frf, replace(model, frequency_std_hz=f_std, damping_std=z_std), BAND)
    rows, cols = pair_by_frequency(filled.frequencies_hz, FN, 5e-4)
    assert set(FN[cols]) == set(FN), filled.frequencies_hz


def test_a_scan_window_takes_in_the_modes_whose_half_power_band_reaches_into_it():
    """``with_margins``: the window grows to take in, with its half-power band f(1 ± ζ), each mode outside it whose
    band reaches across an edge; once, not on to the modes whose bands reach into those margins; never beyond the
    band; a window no band reaches into is left alone. The expected edges are worked out by hand from f(1 ± ζ)."""
    f = np.array([190.0, 199.0, 200.8, 201.6, 205.0, 230.0])
    zeta = np.array([0.004, 0.002, 0.003, 0.003, 0.002, 0.002])
    model = ModalModel(f, zeta, np.ones((1, f.size), complex), ((1, 3),))
    # 200.8 Hz reaches down to 200.198 Hz, across 200.5: the edge moves to 200.8 × 1.003 = 201.4024 Hz. 201.6 Hz
    # (from 200.9952 Hz) reaches into that margin only, and 205.0 Hz (from 204.59 Hz) into nothing. Below, 190.0 Hz
    # reaches up to 190.76 Hz, across 190.5: the edge moves to 190 × 0.996 = 189.24 Hz.
    lo, hi = with_margins((190.5, 200.5), model, (180.0, 240.0))
    assert lo == pytest.approx(189.24, rel=1e-12) and hi == pytest.approx(200.8 * 1.003, rel=1e-12)
    assert with_margins((192.0, 198.0), model, (180.0, 240.0)) == (192.0, 198.0)
    assert with_margins((190.5, 200.5), model, (189.5, 201.0)) == (189.5, 201.0)   # the band bounds it


def _peaks(freq: np.ndarray, centres: list[float], heights: list[float], width: float = 0.4) -> np.ndarray:
    """A scaled residual with Lorentzian peaks over a floor of 1 (the scan's z: noise alone stays near 1)."""
    return 1.0 + sum(h / (1.0 + ((freq - c) / width) ** 2) for c, h in zip(centres, heights, strict=True))


def test_a_missed_mode_just_outside_a_scan_window_is_named_as_its_margin():
    """``missed_beside``: beyond an edge whose line stands above the threshold, the highest peak of the scaled
    residual within the window's half-width that rises above the edge's line; nothing where the edge is below the
    threshold, where the peak lies beyond that reach, or where the residual only falls away from the edge (the tail
    of the window's own mode)."""
    freq = 0.25 * np.arange(1440, 1841)                          # 360-460 Hz
    threshold = 20.0
    # the window's own mode at 401 Hz; a missed one at 408.5 Hz (inside the reach 405-410 Hz) and a stronger one at
    # 414 Hz (beyond it); below the window, a peak at 392 Hz whose tail stays under the threshold at 395 Hz
    z = _peaks(freq, [401.0, 408.5, 414.0, 392.0], [2e3, 3e3, 1e4, 30.0])
    assert z[np.argmin(np.abs(freq - 405.0))] > threshold and z[np.argmin(np.abs(freq - 395.0))] < threshold
    np.testing.assert_allclose(missed_beside((395.0, 405.0), freq, z, threshold), [408.5])
    # the same residual, the 408.5 Hz peak gone: the only rise within reach is 414 Hz's tail, not a peak
    z2 = _peaks(freq, [401.0, 414.0, 392.0], [2e3, 1e4, 30.0])
    assert missed_beside((395.0, 405.0), freq, z2, threshold).size == 0
    # a window whose edges stand under the threshold is left alone
    assert missed_beside((430.0, 440.0), freq, np.ones(freq.size), threshold).size == 0
    # below the window as above: a missed mode at 391.5 Hz whose tail crosses the lower edge
    z3 = _peaks(freq, [401.0, 391.5], [5e4, 4e4])
    np.testing.assert_allclose(missed_beside((395.0, 405.0), freq, z3, threshold), [391.5])
