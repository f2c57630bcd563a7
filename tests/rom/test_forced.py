"""Forced response under engine-order excitation and the amplification factor (rom.forced), against references.

References: the direct harmonic solve (K − ω² M + i ω C) X = F of a lumped ring of blades (one DOF each, on its
own spring to ground, neighbours coupled by springs) with modal damping C = M Φ diag(2 ζ ω) Φᵀ M, so that the
modal and the direct model are the same; the single-DOF peak 1 / (2 ζ ω_h² √(1 − ζ²)) of a tuned ring's
travelling wave; the ring's analytical eigenvalues; Whitehead's (1966) bound (1 + √N)/2.
"""

import math

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import minimize_scalar

from rom.errors import ROMError
from rom.fe_assembly import AssemblyModes
from rom.forced import (
    BladeModes,
    amplification_factor,
    amplification_factors,
    blade_modes,
    engine_order_force,
    family_band,
    family_damping,
    forced_response,
    modal_forces,
    receptance,
    tuned_references,
    whitehead_limit,
)
from rom.forced.model import blade_power_slopes
from rom.rom_assembly import measurement_labels

K_GROUND = (2 * math.pi * 100.0) ** 2  # N/m on a 1 kg blade: 100 Hz alone
MASS = 1.0


def ring(n: int, coupling: float, delta=None, mass: float = MASS):
    """K, M of N unit masses on springs k (1 + δ_j) to ground, neighbours coupled by springs ``coupling``·k."""
    d = np.zeros(n) if delta is None else np.asarray(delta)
    kc = coupling * K_GROUND
    K = np.diag(K_GROUND * (1 + d) + 2 * kc)
    for j in range(n):
        K[j, (j + 1) % n] -= kc
        K[(j + 1) % n, j] -= kc
    return K, mass * np.eye(n)


def ring_modes(K, M, zeta):
    lam, Phi = sla.eigh(K, M)  # mass-normalised: Φᵀ M Φ = I
    return BladeModes(np.sqrt(lam) / (2 * math.pi), zeta, Phi), Phi, np.sqrt(lam)


def direct(K, M, C, F, f_hz):
    """The direct harmonic solve, one frequency at a time: shape (n_freq, n)."""
    out = []
    for f in np.atleast_1d(f_hz):
        w = 2 * math.pi * f
        out.append(np.linalg.solve(K - w**2 * M + 1j * w * C, F))
    return np.array(out)


@pytest.fixture(scope="module")
def mistuned_chain():
    n = 9
    rng = np.random.default_rng(7)
    K, M = ring(n, 0.03, 0.03 * rng.standard_normal(n))
    zeta = rng.uniform(0.002, 0.01, n)
    model, Phi, w = ring_modes(K, M, zeta)
    C = M @ Phi @ np.diag(2 * zeta * w) @ Phi.T @ M
    return K, M, C, model


@pytest.mark.parametrize("form", ["receptance", "mobility", "accelerance"])
def test_modal_superposition_matches_the_direct_harmonic_solve(mistuned_chain, form):
    K, M, C, model = mistuned_chain
    f = np.r_[np.linspace(60, 160, 13), model.frequencies_hz[[0, 4, 8]]]  # at resonances too
    for eo in range(model.n_blades // 2 + 1):
        F = engine_order_force(model.n_blades, eo, 3.5)
        X = direct(K, M, C, F, f)
        w = 2 * math.pi * f[:, None]
        ref = {"receptance": X, "mobility": 1j * w * X, "accelerance": -(w**2) * X}[form]
        got = receptance(model, F, f, form)
        assert np.linalg.norm(got - ref) / np.linalg.norm(ref) < 1e-10


def test_each_blade_peak_matches_the_direct_solve_maximised(mistuned_chain):
    K, M, C, model = mistuned_chain
    band = (0.97 * model.frequencies_hz.min(), 1.03 * model.frequencies_hz.max())
    eo = 2
    F = engine_order_force(model.n_blades, eo, 2.0)
    res = forced_response(model, eo, band, amplitude_n=2.0)
    # Reference: a dense grid of direct solves, then a bounded 1-D maximisation of the direct solve per blade.
    grid = np.linspace(*band, 6001)
    amp = np.abs(direct(K, M, C, F, grid))
    for j in range(model.n_blades):
        i = int(np.argmax(amp[:, j]))
        opt = minimize_scalar(lambda f, j=j: -abs(direct(K, M, C, F, f)[0, j]),
                              bounds=(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]),
                              method="bounded", options={"xatol": 1e-9})
        assert res.peaks[j] == pytest.approx(-opt.fun, rel=1e-9)
        assert res.peak_hz[j] == pytest.approx(opt.x, abs=1e-5)  # the peak is flat: 1e-5 Hz ≪ 0.2–0.9 Hz bandwidths
    assert res.worst_blade == int(np.argmax(res.peaks)) + 1
    assert res.eo == eo and res.sweep_hz is None


@pytest.mark.parametrize("form", ["receptance", "mobility", "accelerance"])
def test_the_peak_slopes_are_the_derivatives_of_the_response_power(mistuned_chain, form):
    """d|Y|²/dω and d²|Y|²/dω² of the Newton refinement against central differences of |Y|² from the modal sum."""
    _, _, _, model = mistuned_chain
    F = engine_order_force(model.n_blades, 1)
    f = model.frequencies_hz[2] * (1 + np.linspace(-0.004, 0.004, model.n_blades))  # each blade its own frequency
    _, g, h = blade_power_slopes(model, modal_forces(model, F), form)(f)
    dw = 2 * math.pi * f * 1e-6

    def power(x):
        return np.abs(np.diagonal(receptance(model, F, x, form))) ** 2

    p0, pp, pm = power(f), power(f + dw / (2 * math.pi)), power(f - dw / (2 * math.pi))
    np.testing.assert_allclose(g, (pp - pm) / (2 * dw), rtol=1e-5, atol=1e-8 * np.abs(g).max())
    np.testing.assert_allclose(h, (pp - 2 * p0 + pm) / dw**2, rtol=1e-3, atol=1e-5 * np.abs(h).max())


@pytest.mark.parametrize("form", ["mobility", "accelerance"])
def test_each_blade_peak_of_every_form_matches_a_bounded_maximisation(mistuned_chain, form):
    """The refined peaks of the velocity and acceleration responses against scipy's bounded maximisation of the
    same response (the modal sum, checked against the direct solve above), on a grid as fine as the sweep's."""
    _, _, _, model = mistuned_chain
    band = (0.97 * model.frequencies_hz.min(), 1.03 * model.frequencies_hz.max())
    F = engine_order_force(model.n_blades, 1)
    res = forced_response(model, 1, band, form=form)
    grid = np.linspace(*band, 6001)
    amp = np.abs(receptance(model, F, grid, form))
    for j in range(model.n_blades):
        i = int(np.argmax(amp[:, j]))
        opt = minimize_scalar(lambda f, j=j: -abs(receptance(model, F, [f], form)[0, j]),
                              bounds=(grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]),
                              method="bounded", options={"xatol": 1e-9})
        assert res.peaks[j] == pytest.approx(-opt.fun, rel=1e-9)


def test_two_modes_closer_than_the_grid_step_give_the_bracket_s_maximum():
    """Two modes 2e-4 apart (a tenth of the narrowest bandwidth) share one grid bracket: the peak found is the
    bracket's maximum (scipy's bounded search of the modal sum) and never below the grid's."""
    model = BladeModes(np.array([100.0, 100.02]), np.array([0.001, 0.001]), np.array([[1.0, 0.6], [0.3, -1.0]]))
    res = forced_response(model, 0, (99.0, 101.0), keep_sweep=True)
    F, g = engine_order_force(2, 0), res.sweep_hz
    for j in range(2):
        i = int(np.argmax(res.sweep_amplitude[:, j]))
        opt = minimize_scalar(lambda f, j=j: -abs(receptance(model, F, [f])[0, j]),
                              bounds=(g[max(i - 1, 0)], g[min(i + 1, g.size - 1)]), method="bounded",
                              options={"xatol": 1e-10})
        assert res.peaks[j] == pytest.approx(-opt.fun, rel=1e-9)
        assert res.peaks[j] >= res.sweep_amplitude[i, j]


def test_a_peak_beyond_the_band_falls_back_to_the_golden_section_at_the_edge(monkeypatch):
    """Blade 1 sees mostly a resonance above the band: Newton's step leaves its last grid bracket, the golden-section
    search runs and its peak is the response at the band's edge (it rises all the way there)."""
    import rom.forced.sweep as sweep

    calls = []
    golden = sweep._golden
    monkeypatch.setattr(sweep, "_golden", lambda *a: calls.append(1) or golden(*a))
    model = BladeModes(np.array([97.0, 100.0]), np.array([0.002, 0.002]), np.array([[0.01, 1.0], [1.0, 0.01]]))
    res = forced_response(model, 0, (95.0, 99.5))
    edge = np.abs(receptance(model, engine_order_force(2, 0), [99.5]))[0, 0]
    assert calls and res.peaks[0] == pytest.approx(edge, rel=1e-9)
    assert res.peak_hz[0] == pytest.approx(99.5, rel=1e-6)


@pytest.mark.parametrize("n", [6, 7])
def test_tuned_ring_responds_only_in_its_nodal_diameter(n):
    model, Phi, w = ring_modes(*ring(n, 0.05), 0.004)
    nd = np.argmax(np.abs(np.fft.rfft(Phi, axis=0)), axis=0)  # each tuned mode's nodal diameter
    # The analytical tuned frequencies: ω_h² = (k + 2 k_c (1 − cos 2πh/N)) / m.
    np.testing.assert_allclose(w**2, (K_GROUND + 2 * 0.05 * K_GROUND * (1 - np.cos(2 * np.pi * nd / n))) / MASS,
                               rtol=1e-12)
    for eo in range(n // 2 + 1):
        q = modal_forces(model, engine_order_force(n, eo))
        assert np.abs(q[nd != eo]).max() < 1e-13 * np.abs(q).max()
        assert np.abs(q[nd == eo]).max() > 0.5
        X = receptance(model, engine_order_force(n, eo), np.linspace(90, 130, 9))
        np.testing.assert_allclose(np.abs(X), np.abs(X[:, :1]) * np.ones(n), rtol=1e-12)


def test_tuned_peak_is_the_single_dof_resonance():
    n, zeta = 8, 0.003
    model, _, _ = ring_modes(*ring(n, 0.05), zeta)
    band = family_band(model, 1)
    for eo in range(n // 2 + 1):
        wh2 = (K_GROUND + 2 * 0.05 * K_GROUND * (1 - math.cos(2 * math.pi * eo / n))) / MASS
        res = forced_response(model, eo, band, amplitude_n=5.0)
        np.testing.assert_allclose(res.peaks, 5.0 / (MASS * 2 * zeta * wh2 * math.sqrt(1 - zeta**2)), rtol=1e-10)
        np.testing.assert_allclose(res.peak_hz, math.sqrt(wh2 * (1 - 2 * zeta**2)) / (2 * math.pi), rtol=1e-9)


def test_af_is_one_for_a_tuned_ring_in_another_modal_basis():
    n = 10
    tuned, Phi, w = ring_modes(*ring(n, 0.02), 0.005)
    # The same ring with each degenerate pair rotated and the modes reordered: another valid mass-normalised basis.
    rng = np.random.default_rng(3)
    Phi2 = Phi.copy()
    for j in range(1, n - 1, 2):
        t = rng.uniform(0, 2 * np.pi)
        Phi2[:, j : j + 2] = Phi[:, j : j + 2] @ np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    order = rng.permutation(n)
    other = BladeModes(w[order] / (2 * math.pi), 0.005, Phi2[:, order])
    afs = amplification_factors(other, tuned, families=(1,))
    assert [a.eo for a in afs] == list(range(n // 2 + 1))
    for a in afs:
        assert a.af == pytest.approx(1.0, abs=1e-9)
        assert a.family == 1
        np.testing.assert_allclose(a.mistuned.peaks, a.tuned_peak, rtol=1e-9)


def test_whitehead_limit_holds_on_random_small_mistuning():
    n, zeta = 12, 0.002
    assert whitehead_limit(n) == pytest.approx((1 + math.sqrt(12)) / 2)
    tuned, _, _ = ring_modes(*ring(n, 0.01), zeta)
    band = family_band(tuned, 1, margin=0.05)
    rng = np.random.default_rng(2024)
    worst = []
    for _ in range(50):
        mis, _, _ = ring_modes(*ring(n, 0.01, 0.02 * rng.standard_normal(n)), zeta)
        worst.append(max(amplification_factor(mis, tuned, eo, band).af for eo in range(n // 2 + 1)))
    assert max(worst) <= whitehead_limit(n)
    assert max(worst) > 1.2  # mistuning amplifies


def test_family_band_spans_the_tuned_family():
    n = 8
    tuned, _, w = ring_modes(*ring(n, 0.05), 0.01)
    lo, hi = family_band(tuned, 1, margin=0.0)
    assert lo == pytest.approx(w.min() / (2 * math.pi), rel=1e-12)
    assert hi == pytest.approx(w.max() / (2 * math.pi), rel=1e-12)
    lo2, hi2 = family_band(tuned, 1, margin=0.02)
    assert (lo2, hi2) == pytest.approx((0.98 * lo, 1.02 * hi))


def test_tuned_references_serve_many_mistuned_models():
    n, zeta = 8, 0.004
    tuned, _, _ = ring_modes(*ring(n, 0.02), zeta)
    mis, _, _ = ring_modes(*ring(n, 0.02, 0.02 * np.random.default_rng(5).standard_normal(n)), zeta)
    refs = tuned_references(tuned, families=(1,), amplitude_n=2.0, form="mobility")
    assert list(refs) == [(1, eo) for eo in range(n // 2 + 1)]
    with_refs = amplification_factors(mis, tuned, references=refs, amplitude_n=2.0, form="mobility")
    alone = amplification_factors(mis, tuned, families=(1,), amplitude_n=2.0, form="mobility")
    assert [a.af for a in with_refs] == [a.af for a in alone]
    assert [a.worst_blade for a in with_refs] == [int(np.argmax(a.mistuned.peaks)) + 1 for a in alone]
    # Mobility peaks of a tuned travelling wave sit at ω_h exactly, and are 1 / (2 ζ ω_h m) per newton.
    for (_, eo), ref in refs.items():
        wh = math.sqrt(K_GROUND * (1 + 2 * 0.02 * (1 - math.cos(2 * math.pi * eo / n))) / MASS)
        np.testing.assert_allclose(ref.peaks, 2.0 / (2 * zeta * wh * MASS), rtol=1e-10)
        np.testing.assert_allclose(ref.peak_hz, wh / (2 * math.pi), rtol=1e-9)


def test_family_damping_gives_each_mode_its_family_ratio():
    z = family_damping([99.0, 100.0, 150.0, 290.0, 305.0, 900.0], [(95.0, 105.0), (295.0, 310.0)], [0.01, 0.003])
    np.testing.assert_array_equal(z, [0.01, 0.01, 0.01, 0.003, 0.003, 0.003])


def test_keep_sweep_keeps_the_grid_and_its_amplitudes(mistuned_chain):
    _, _, _, model = mistuned_chain
    band = (0.97 * model.frequencies_hz.min(), 1.03 * model.frequencies_hz.max())
    res = forced_response(model, 1, band, keep_sweep=True)
    assert res.sweep_hz[0] == band[0] and res.sweep_hz[-1] == band[1]
    assert res.step_hz <= 2 * (model.damping_ratio * model.frequencies_hz).min() / 8 * (1 + 1e-12)
    np.testing.assert_allclose(res.sweep_amplitude, np.abs(receptance(model, engine_order_force(9, 1), res.sweep_hz)))
    assert np.all(res.peaks >= res.sweep_amplitude.max(axis=0))


def test_blade_modes_picks_one_point_per_slot_in_slot_order():
    n, n_meas = 5, 3
    labels = measurement_labels(n, range(1, n + 1), n_meas)
    shapes = np.arange(len(labels) * 2, dtype=float).reshape(len(labels), 2)
    modes = AssemblyModes(np.array([100.0, 200.0]), shapes, labels)
    bm = blade_modes(modes, 0.01, point=2)
    rows = [labels.index(("blade", s, 2, 1)) for s in range(1, n + 1)]
    np.testing.assert_array_equal(bm.shapes, shapes[rows])
    with pytest.raises(ROMError, match="blade point 4 is not measured"):
        blade_modes(modes, 0.01, point=4)


@pytest.mark.parametrize(("call", "message"), [
    (lambda m: forced_response(m, 4, (90, 130)), r"engine order 4 outside 0\.\.3 \(N = 6 blades\)"),
    (lambda m: forced_response(m, -1, (90, 130)), r"engine order -1 outside 0\.\.3"),
    (lambda m: forced_response(m, 1.5, (90, 130)), r"engine order 1\.5 outside"),
    (lambda m: forced_response(m, 1, (300, 400)), r"no mode in the band 300–400 Hz"),
    (lambda m: forced_response(m, 1, (130, 90)), r"must satisfy 0 < low < high"),
    (lambda m: forced_response(m, 1, (90, 130), form="velocity"), r"form 'velocity' not one of"),
    (lambda m: family_band(m, 2), r"family 2 has no modes"),
    (lambda m: BladeModes(m.frequencies_hz, 0.01, m.shapes[:, :-1]), r"shapes have shape \(6, 5\), expected \(n_"),
    (lambda m: BladeModes(m.frequencies_hz, 0.0, m.shapes), r"damping ratio 0\.0 outside \(0, 1\)"),
    (lambda m: BladeModes(m.frequencies_hz, -0.01 * np.ones(6), m.shapes), r"damping ratio -0\.01 outside"),
    (lambda m: BladeModes(m.frequencies_hz, np.ones(5) * 0.01, m.shapes), r"5 damping ratios for 6 modes"),
    (lambda m: modal_forces(m, np.ones(5)), r"force has shape \(5,\), expected \(6,\)"),
    (lambda m: amplification_factor(m, ring_modes(*ring(7, 0.05), 0.01)[0], 1, (90, 130)),
     r"mistuned model has 6 blades, the tuned one 7"),
    (lambda m: whitehead_limit(0), r"number of blades must be ≥ 1"),
    (lambda m: amplification_factor(m, m, 2, (90, 130), tuned_response=forced_response(m, 1, (90, 130))),
     r"tuned response is of EO 1, band \(90\.0, 130\.0\) Hz, 1\.0 N, receptance; expected EO 2"),
    (lambda m: family_damping(m.frequencies_hz, [(90, 130)], [0.01, 0.02]), r"2 damping ratios for 1 family bands"),
])
def test_bad_input_is_refused_in_one_line(call, message):
    model, _, _ = ring_modes(*ring(6, 0.05), 0.01)
    with pytest.raises(ValueError, match=message) as exc:
        call(model)
    assert "\n" not in str(exc.value)
