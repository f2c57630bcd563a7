"""Dense mode families (issue 31, item 1): the structured rank-one fit against a known modal model.

The truth imitates one blade family of a mistuned bladed disk: 10 modes within 0.5 % of 500 Hz, 0.2-0.35 Hz
apart (0.04-0.07 %), with 0.1-0.3 % damping (half-power bandwidths of 1-3 Hz, so every neighbour overlaps),
on 0.5 Hz lines, with two isolated modes beside the family. 24 outputs, 4 references among them; each mode is
localised on a few outputs (as mistuned modes localise on a few blades). Mobility with 0.5 % proportional and
0.2 % additive noise, as the virtual rig's.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ema import FRFSet, fit
from ema.family import fit_family
from ema.mac import mac, pair_by_frequency
from ema.modal import modal_from_pole, pole_from_modal

from .synth import modal_frfs, rig_noise

TOL = 5e-4  # 0.05 %
N_OUT, N_IN = 24, 4


def _truth(seed: int = 3):
    rng = np.random.default_rng(seed)
    fam = 500.0 + np.cumsum(rng.uniform(0.2, 0.35, 10))
    fn = np.r_[430.0, fam, 590.0]
    zeta = np.r_[0.002, rng.uniform(0.001, 0.003, 10), 0.002]
    phi = 0.2 * rng.standard_normal((N_OUT, fn.size))
    for r in range(fn.size):  # localised: a few outputs carry most of the motion
        phi[rng.choice(N_OUT, 3, replace=False), r] += rng.choice([-1.0, 1.0], 3) * rng.uniform(0.8, 1.5, 3)
    return fn, zeta, phi


def _frfs(fn, zeta, phi, seed: int = 7) -> FRFSet:
    rng = np.random.default_rng(seed)
    freq = 0.5 * np.arange(760, 1281)   # 380-640 Hz
    H = modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility")
    H = rig_noise(H, rng)
    outputs = [(k + 1, 3) for k in range(N_OUT)]
    return FRFSet(freq, H, outputs, outputs[:N_IN], form="mobility")


def _one_to_one(f_est: np.ndarray, f_true: np.ndarray, tol: float = TOL) -> list[tuple[int, int]]:
    rows, cols = pair_by_frequency(f_est, f_true, tol)
    return list(zip(rows.tolist(), cols.tolist(), strict=True))


@pytest.fixture(scope="module")
def family():
    fn, zeta, phi = _truth()
    return _frfs(fn, zeta, phi), fn, zeta, phi


@pytest.fixture(scope="module")
def fits(family):
    frf = family[0]
    return fit(frf, band=(400.0, 620.0)), fit(frf, band=(400.0, 620.0), families=True)


def test_the_ordinary_fit_merges_the_family(family, fits):
    """The case is hard for free residues: the ordinary fit misses members of the family."""
    _, fn, _, _ = family
    assert len(_one_to_one(fits[0].model.frequencies_hz, fn)) < fn.size


def test_families_resolve_every_mode(family, fits):
    _, fn, _, phi = family
    model = fits[1].model
    pairs = _one_to_one(model.frequencies_hz, fn)
    assert len(pairs) == fn.size, (model.frequencies_hz, fn)
    # nothing spurious: every identified mode is one of the truth's
    assert model.n_modes == fn.size
    # shapes: the rank-one residues' shapes against the truth's (the ordinary fit's family shapes: MAC 0.003-0.99)
    macs = np.array([float(np.squeeze(mac(model.shapes[:, i], phi[:, j]))) for i, j in pairs])
    assert macs.mean() >= 0.95 and macs.min() >= 0.9, macs


def test_family_modes_carry_finite_standard_deviations(fits):
    model = fits[1].model
    assert np.all(np.isfinite(model.frequency_std_hz)) and np.all(model.frequency_std_hz > 0)


def test_no_growth_on_a_lone_mode():
    """A window with one mode and noise gains no pole: a pole fitted to noise explains less than the noise."""
    fn, zeta, phi = np.array([500.0]), np.array([0.002]), np.random.default_rng(1).standard_normal((N_OUT, 1))
    frf = _frfs(fn, zeta, phi)
    out = fit_family(frf, pole_from_modal(fn * 1.0002, zeta), (480.0, 520.0), (485.0, 515.0))
    assert out.n_modes == 1
    assert abs(np.abs(out.poles[0]) / (2 * np.pi) - fn[0]) / fn[0] < 1e-4


def test_cli_families(family, tmp_path, capsys):
    """``bladetwin ema fit --families`` gives the library's answer; without the flag the family stays merged."""
    import json

    from bladetwin.cli import main
    from ema import write_frfs

    frf, fn, _, _ = family
    path = tmp_path / "family.uff"
    write_frfs(path, frf)
    found = []
    for extra in ([], ["--families"]):
        assert main(["ema", "fit", str(path), "--band", "400", "620", "--json", *extra]) == 0
        found.append(np.array([rec["frequency_hz"] for rec in json.loads(capsys.readouterr().out)["modes"]]))
    assert len(_one_to_one(found[0], fn)) < fn.size
    assert len(_one_to_one(found[1], fn)) == fn.size == found[1].size


def test_one_reference():
    """With one hammer the participations are scalars: the fit still runs, keeps what the ordinary fit resolved
    and adds nothing more than 1 % from every true mode."""
    fn, zeta, phi = _truth()
    rng = np.random.default_rng(11)
    freq = 0.5 * np.arange(760, 1281)
    H = modal_frfs(freq, fn, zeta, phi, phi[:1], "mobility")
    H = H * (1 + 0.005 * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2))
    outputs = [(k + 1, 3) for k in range(N_OUT)]
    frf = FRFSet(freq, H, outputs, outputs[:1], form="mobility")
    plain = fit(frf, band=(400.0, 620.0)).model
    model = fit(frf, band=(400.0, 620.0), families=True).model
    assert len(_one_to_one(model.frequencies_hz, fn)) >= len(_one_to_one(plain.frequencies_hz, fn))
    assert all(np.min(np.abs(f - fn) / fn) <= 0.01 for f in model.frequencies_hz)


def test_plot_families_one_panel_per_window(family, fits):
    """The report's zoom: a panel per dense window, titled with the number of modes the model has there."""
    from ema.plots import plot_families

    frf = family[0]
    model = fits[1].model
    windows = [(495.0, 510.0), (420.0, 440.0)]
    fig = plot_families(frf, model, windows)
    assert len(fig.axes) == 2
    for ax, (lo, hi) in zip(fig.axes, windows, strict=True):
        n = int(np.count_nonzero((model.frequencies_hz >= lo) & (model.frequencies_hz <= hi)))
        assert ax.get_title().endswith(f"{n} modes")
    assert fig.axes[0].get_title().endswith("10 modes")


def test_a_second_merge_keeps_the_structured_shapes(family, fits):
    """merge_families refits free residues for the merged poles; the modes of an earlier structured fit keep
    their rank-one shapes (a second merge, as the residual scan makes, once mixed the family's shapes again)."""
    from ema.families import merge_families

    frf = family[0]
    model = fits[1].model
    structured = np.isnan(model.quality)
    assert structured.sum() >= 8
    again = merge_families(frf, model, [fit_family(frf, model.poles[-1:], (570.0, 610.0), (580.0, 600.0))])
    keep = np.isin(np.round(again.frequencies_hz, 9), np.round(model.frequencies_hz[structured], 9))
    assert keep.sum() == structured.sum()
    assert np.array_equal(again.shapes[:, keep], model.shapes[:, structured])


def test_standard_deviations_cover_the_truth(family, fits):
    """The truth lies within ± 2 standard deviations for at least 85 % of the family's modes, pooled over three
    noise and truth draws (measured 0.92; White's sandwich alone, whose meat rests on the one or two peak lines of
    each lightly damped mode, gave 0.78)."""
    z = []
    cases = [(family[1], fits[1].model)]
    for seed in (4, 5):
        fn, zeta, phi = _truth(seed)
        cases.append((fn, fit(_frfs(fn, zeta, phi), band=(400.0, 620.0), families=True).model))
    for fn, model in cases:
        rows, cols = pair_by_frequency(model.frequencies_hz, fn, TOL)
        z.append(np.abs(model.frequencies_hz[rows] - fn[cols]) / model.frequency_std_hz[rows])
    z = np.concatenate(z)
    assert z.size >= 30 and np.mean(z <= 2) >= 0.85, np.round(z, 1)


def test_a_window_that_grew_nothing_adds_no_mode_that_answers_for_none(family, fits):
    """A structured mode that matches no ordinary mode is new only where the window grew; in a window that grew
    nothing it is a starting mode that left its own (seed 12 once kept one 2.7 % from every true mode), and the
    ordinary mode stays."""
    from dataclasses import replace

    from ema.families import merge_families

    frf = family[0]
    model = fits[0].model
    lone = int(np.argmin(np.abs(model.frequencies_hz - 590.0)))
    fit_ = fit_family(frf, model.poles[[lone]], (570.0, 610.0), (580.0, 600.0), max_added=0)
    assert fit_.n_start == fit_.n_modes == 1
    moved = replace(fit_, poles=pole_from_modal(np.array([600.0]), np.array([0.002])))   # 1.7 % off
    merged = merge_families(frf, model, [moved])
    assert merged.n_modes == model.n_modes and np.min(np.abs(merged.frequencies_hz - 600.0)) > 5.0
    # grown, the same mode is new
    grown = merge_families(frf, model, [replace(moved, n_start=0)])
    assert grown.n_modes == model.n_modes + 1 and np.min(np.abs(grown.frequencies_hz - 600.0)) < 1e-6


def test_a_heavily_damped_pole_does_not_stretch_its_family_s_window():
    """Windows follow their poles' damping; one pole at 5 % among poles at 0.1-0.3 % would span ± 10 ζ f = ± 270 Hz
    around 540 Hz, over the family at 500 Hz and the mode at 590 Hz. Capped at the poles' outlier bound
    (Hampel's rule, computed here by hand), it spans what the others' damping gives and merges with none."""
    from ema.family_windows import damping_outlier_bound, family_windows
    from ema.lsfd import LOCAL_HALF_WIDTHS

    fn, zeta, phi = _truth()
    frf = _frfs(fn, zeta, phi)
    f = np.r_[fn, 540.0]
    z = np.r_[zeta, 0.05]
    med = np.median(z)
    bound = med + 3 * 1.4826 * np.median(np.abs(z - med))
    assert damping_outlier_bound(z) == pytest.approx(bound, rel=1e-12) and bound < 0.01
    windows = [w for w, _ in family_windows(pole_from_modal(f, z), frf, (380.0, 640.0))]
    own = next(w for w in windows if w[0] <= 540.0 <= w[1])
    assert own == pytest.approx((540.0 - LOCAL_HALF_WIDTHS * bound * 540.0, 540.0 + LOCAL_HALF_WIDTHS * bound * 540.0))
    assert not own[0] <= fn[1] <= own[1] and not own[0] <= 590.0 <= own[1]
    # fewer than three poles measure no spread: no bound
    assert damping_outlier_bound(np.array([0.001, 0.05])) == np.inf


def test_a_mode_the_window_leaves_undetermined_is_dropped_and_the_rest_refined(monkeypatch):
    """A mode whose frequency σ is wider than its window is dropped, the others refined again; σ within it is kept.

    The 24-blade campaign's window at 1189-1258 Hz kept one pole twice, each with σ 1.7e6 Hz (the data leave a
    pole fitted twice undetermined). That is hard to provoke on a small case, so the first covariance here is
    made to report it: a real pair at 500.0 and 500.3 Hz, started from three poles (500.3 Hz twice). Unchanged,
    the fit keeps a third, spurious mode with σ 0.07 Hz (within its 40 Hz window: kept, as a dense family's
    real modes with σ above their half-power width are).
    """
    import ema.family as family_module

    rng = np.random.default_rng(0)
    fn, zeta = np.array([500.0, 500.3]), np.array([0.002, 0.0025])
    phi = rng.standard_normal((N_OUT, 2))
    freq = 0.5 * np.arange(900, 1101)
    frf = FRFSet(freq, rig_noise(modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility"), rng),
                 [(k + 1, 3) for k in range(N_OUT)], [(k + 1, 3) for k in range(N_IN)], form="mobility")
    start = pole_from_modal(np.r_[fn, fn[1]] * 1.0002, np.r_[zeta, zeta[1]])
    plain = fit_family(frf, start, (480.0, 520.0), (485.0, 515.0), max_added=0)
    spurious = np.abs(np.abs(plain.poles) / (2 * np.pi) - fn[:, None]).min(axis=0) > 0.05
    assert plain.n_modes == 3 and spurious.sum() == 1 and plain.frequency_std_hz[spurious][0] < 40.0

    real, calls = family_module._result, []

    def undetermined_first(win, window, f, *rest):
        fit_ = real(win, window, f, *rest)
        if not calls:  # the first covariance: the spurious mode's σ as the 24-blade window's
            off = np.abs(np.sort(f)[:, None] - fn).min(axis=1) > 0.05
            fit_ = replace(fit_, frequency_std_hz=np.where(off, 1.7e6, fit_.frequency_std_hz))
        calls.append(f.size)
        return fit_

    monkeypatch.setattr(family_module, "_result", undetermined_first)
    out = fit_family(frf, start, (480.0, 520.0), (485.0, 515.0), max_added=0)
    assert calls == [3, 2]
    assert out.n_modes == 2 and out.n_start == 2
    np.testing.assert_allclose(np.sort(np.abs(out.poles)) / (2 * np.pi), fn, rtol=TOL)
    assert np.all(out.frequency_std_hz < 0.01)


def test_a_participation_whose_pivot_should_be_small_is_scaled_anew():
    """A mode nearly still at its pivot reference: the refinement moves the pivot to its largest entry.

    Two modes 0.1 % apart; the second barely moves at reference 1 (1e-3 of its other entries), and its start
    participation holds reference 1 at 1 with the others at 0.5. The true participation then has entries about
    1000 times its pivot's; re-pivoted, it is held at its largest entry and still reaches the true poles and
    participation (design §8.60). This small case converges without re-pivoting as well; the 36-blade window
    where it mattered is too large for a test.
    """
    from ema.family import REPIVOT, FamilyWindow, _refine, normalised_participations

    rng = np.random.default_rng(4)
    fn, zeta = np.array([500.0, 500.5]), np.array([0.002, 0.002])
    phi = rng.standard_normal((N_OUT, 2))
    phi[0, 1] = 1e-3
    freq = 0.5 * np.arange(960, 1041)
    frf = FRFSet(freq, rig_noise(modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility"), rng),
                 [(k + 1, 3) for k in range(N_OUT)], [(k + 1, 3) for k in range(N_IN)], form="mobility")
    win = FamilyWindow(frf, (480.0, 520.0))
    good, good_pivot = normalised_participations(phi[:N_IN, :1].astype(complex))
    start = np.c_[good, np.r_[1.0, 0.5, 0.5, 0.5]].astype(complex)
    f, z, part, pivot = _refine(win, fn * 1.0003, zeta, start, np.r_[good_pivot, 0])
    assert pivot[1] == np.argmax(np.abs(phi[:N_IN, 1])) and pivot[1] != 0
    assert np.all(np.abs(part) <= REPIVOT) and np.allclose(part[pivot, np.arange(2)], 1.0)
    np.testing.assert_allclose(f, fn, rtol=TOL / 10)
    assert mac(part[:, 1:], phi[:N_IN, 1:].astype(complex))[0, 0] > 0.999


def _edge_case(seed: int, fn: np.ndarray, zeta: np.ndarray, strong: int) -> tuple[FRFSet, np.ndarray]:
    """FRFs of modes ``fn`` on 480-520 Hz lines, mode ``strong`` five times the others; and the mode shapes."""
    rng = np.random.default_rng(seed)
    phi = rng.standard_normal((N_OUT, fn.size))
    phi[:, strong] *= 5
    freq = 0.5 * np.arange(960, 1041)
    frf = FRFSet(freq, rig_noise(modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility"), rng),
                 [(k + 1, 3) for k in range(N_OUT)], [(k + 1, 3) for k in range(N_IN)], form="mobility")
    return frf, phi


@pytest.mark.parametrize("seed", [0, 2])
def test_a_trial_stopped_at_a_bound_gets_the_full_refinements_verdict(seed):
    """A growth trial is stopped once its new mode is held at the window's edge (or at the upper damping bound);
    growth refuses it then, as it refuses the fully refined trial.

    Two modes in the window and a strong one at 524 Hz, beyond its 520 Hz edge, whose flank draws a trial pole
    started at 514 or 519.5 Hz to the edge: both refinements end refused, the stopped one after far fewer cost
    evaluations. Without the strong mode, a trial started at 490 Hz is never held, and the watched refinement
    runs to the full one's end.
    """
    from ema.family import FamilyWindow, _kept, _refine, normalised_participations

    for fn, zeta, starts in ((np.array([500.0, 500.5, 524.0]), np.array([0.002, 0.002, 0.01]), (514.0, 519.5)),
                             (np.array([500.0, 500.5]), np.array([0.002, 0.002]), (490.0,))):
        frf, phi = _edge_case(seed, fn, zeta, strong=fn.size - 1)
        win = FamilyWindow(frf, (480.0, 520.0))
        span = (win.freq[0], win.freq[-1])
        calls = []
        solve = win.solve
        win.solve = lambda *a, solve=solve, calls=calls: calls.append(1) or solve(*a)
        part, pivot = normalised_participations(phi[:N_IN, :2].astype(complex))
        new = np.r_[1.0, 0.3, -0.2, 0.5].astype(complex)
        for f0 in starts:
            start = (np.r_[fn[:2], f0], np.r_[zeta[:2], 0.002], np.c_[part, new], np.r_[pivot, 0])
            calls.clear()
            full = _refine(win, *start)
            n_full = len(calls)
            calls.clear()
            watched = _refine(win, *start, watch=2)
            assert _kept(watched, 2, span) == _kept(full, 2, span), f0
            if fn.size > 2:
                assert not _kept(full, 2, span) and len(calls) < n_full / 3, (f0, len(calls), n_full)
            else:
                np.testing.assert_allclose(watched[0], full[0], rtol=1e-12)


@pytest.mark.parametrize("seed", [0, 1])
def test_growth_keeps_a_mode_between_the_core_and_the_windows_edge(seed):
    """Trials start in the core, but a mode they converge on outside it is kept while its half-power band lies in
    the window: the bundled campaign's 618.3 Hz, between two windows' cores, was refused by a core rule (§8.62).
    Here 511 Hz, outside the 485-505 Hz core of a 480-520 Hz window, is found with the two modes the fit starts
    from, and no mode is more than 1 % from a true one (the rule as it was found only the two)."""
    rng = np.random.default_rng(seed)
    fn, zeta = np.array([500.0, 500.5, 511.0]), np.array([0.002, 0.002, 0.0015])
    phi = rng.standard_normal((N_OUT, fn.size))
    freq = 0.5 * np.arange(960, 1041)
    frf = FRFSet(freq, rig_noise(modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility"), rng),
                 [(k + 1, 3) for k in range(N_OUT)], [(k + 1, 3) for k in range(N_IN)], form="mobility")
    fit = fit_family(frf, pole_from_modal(fn[:2], zeta[:2]), (480.0, 520.0), (485.0, 505.0))
    found = modal_from_pole(fit.poles)[0]
    assert len(_one_to_one(found, fn)) == 3, found
    assert np.all(np.min(np.abs(found[:, None] / fn[None, :] - 1), axis=1) < 0.01), found



@pytest.mark.parametrize("seed", [3, 4])
def test_refusals_that_end_in_one_place_do_not_stop_growth(monkeypatch, seed):
    """Growth stops after RETRIES + 1 refusals in a row only if they ended in different places.

    A seed-7 36-blade campaign's 1192-1279 Hz window: four trials in a row, from neighbouring lines, each ended at
    1224.48 Hz explaining less than its band's noise, and growth stopped with 24 of its 38 true modes missing
    (design §8.67). Here the verdict on the first RETRIES + 2 trials that end where the first one did is made a
    refusal (as there): counting each, growth stops with true modes missing; not counting the repeats, it finds
    every mode of the window.
    """
    import ema.family as family_module

    rng = np.random.default_rng(seed)
    fn, zeta = np.array([500.0, 500.7, 501.4, 502.1]), np.full(4, 0.002)
    phi = rng.standard_normal((N_OUT, fn.size))
    freq = 0.5 * np.arange(960, 1041)
    frf = FRFSet(freq, rig_noise(modal_frfs(freq, fn, zeta, phi, phi[:N_IN], "mobility"), rng),
                 [(k + 1, 3) for k in range(N_OUT)], [(k + 1, 3) for k in range(N_IN)], form="mobility")
    real = family_module._explains

    def found_with(skip_repeats: bool) -> tuple[np.ndarray, list]:
        refused = []

        def refused_in_one_place(win, f, zeta_, part, r):
            same = not refused or abs(f[r] - refused[0][0]) <= refused[0][0] * refused[0][1]
            if len(refused) < family_module.RETRIES + 2 and same and not family_module._at_bound(zeta_[r]):
                refused.append((f[r], zeta_[r]))
                return False
            return real(win, f, zeta_, part, r)

        monkeypatch.setattr(family_module, "_explains", refused_in_one_place)
        fit = fit_family(frf, pole_from_modal(fn[:1], zeta[:1]), (480.0, 520.0), (485.0, 515.0),
                         skip_repeats=skip_repeats)
        return modal_from_pole(fit.poles)[0], refused

    counted, refused = found_with(False)
    assert len(refused) == family_module.RETRIES + 1 and len(_one_to_one(counted, fn)) < fn.size, counted
    found, refused = found_with(True)
    assert len(refused) == family_module.RETRIES + 2, refused
    assert len(_one_to_one(found, fn)) == fn.size, found
