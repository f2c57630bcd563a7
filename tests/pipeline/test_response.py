"""``bladetwin response`` and the run's ``response`` node (issue 47): bad input refused in one line, and the
amplification factors of a small virtual run checked against a direct harmonic solve of the same modes."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from bladetwin.campaign import read_campaign
from bladetwin.cli import main
from bladetwin.run import run_nodes
from bladetwin.stages import names
from bladetwin.stages.campaign_graph import RunOptions
from bladetwin.stages.full import solve_assembly

RUN_ARGS = ["--refine", "0", "--n", "3", "--rom", "paper", "--method", "knn", "--no-figures"]


def _error_line(capsys, argv) -> str:
    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert "Traceback" not in err[0]
    return err[0]


def _fake_out(tmp_path, response=True):
    block = {"n_blades": 4, "eos": [0, 1, 2], "families": [1, 2], "whitehead_limit": 1.5, "point": 1,
             "roms": {"paper": {"solve": "identified", "families": {}}}}
    summary = {"campaign": "x", "response": block if response else None}
    (tmp_path / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    return tmp_path


@pytest.mark.parametrize("argv, expected", [
    (["--eo", "3"], "--eo '3': expected one of 0, 1, 2"),
    (["--eo", "1,-1"], "--eo '-1': expected one of 0, 1, 2"),
    (["--family", "4"], "--family '4': expected one of 1, 2"),
    (["--family", "one"], "--family 'one': expected one of 1, 2"),
])
def test_bad_eo_or_family_is_refused_in_one_line(tmp_path, capsys, argv, expected):
    line = _error_line(capsys, ["response", str(_fake_out(tmp_path)), *argv])
    assert expected in line
    assert not (tmp_path / "response.csv").exists()


def test_out_dir_without_the_runs_modes_is_refused(tmp_path, capsys):
    line = _error_line(capsys, ["response", str(tmp_path)])
    assert "no summary.json" in line and str(tmp_path) in line
    line = _error_line(capsys, ["response", str(_fake_out(tmp_path, response=False))])
    assert "no 'response' block" in line


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("response")
    x, o, s = root / "X", root / "O", root / "S"
    assert main(["lab", "simulate", "--level", "coarse", "--blades", "4", "--grid", "3x7", "--known", "1,3",
                 "--realism", "ideal", "--seed", "5", "--out", str(x)]) == 0
    assert main(["run", str(x), *RUN_ARGS, "--out", str(o), "--cache-dir", str(s)]) == 0
    return x, o, s


def _direct_peaks(phi, f_hz, zeta, force, band, n=4001):
    """Each blade's largest |X| over a dense grid of the band by a direct solve of (Ω² − ω² + iω 2ZΩ) q = Φᵀ F,
    X = Φ q (modal coordinates: K = Ω², M = I, C = 2ZΩ), refined on a finer grid around each maximum."""
    w_r = 2 * math.pi * f_hz

    def amp(f):
        w = 2 * math.pi * f
        A = np.diag(w_r**2 - w**2 + 2j * zeta * w_r * w)
        return np.abs(phi @ np.linalg.solve(A, phi.T @ force))

    grid = np.linspace(*band, n)
    table = np.array([amp(f) for f in grid])
    peaks = []
    for j in range(phi.shape[0]):
        k = int(np.argmax(table[:, j]))
        fine = np.linspace(grid[max(k - 1, 0)], grid[min(k + 1, n - 1)], 801)
        peaks.append(max(amp(f)[j] for f in fine))
    return np.array(peaks)


def test_run_response_matches_a_direct_harmonic_solve(small_run, capsys):
    from rom.forced import blade_modes, family_damping

    x, o, s = small_run
    summary = json.loads((o / "summary.json").read_text(encoding="utf-8"))
    block = summary["response"]
    assert block["whitehead_limit"] == pytest.approx((1 + math.sqrt(4)) / 2)
    # the k-NN run has no posterior samples (no intervals); the virtual campaign has the truth's AF
    assert set(block["not_computed"]) == {"af_ci90", "p_worst"}
    assert "--method knn" in block["not_computed"]["af_ci90"]
    truth = block["truth"]["families"]
    for rom, r in block["roms"].items():
        for fam, f in r["families"].items():
            for eo, v in f.get("eo", {}).items():
                t = truth[fam].get("eo", {}).get(eo, {}).get("af")
                assert v["af_truth"] == t, (rom, fam, eo)
        scores = block["against_truth"][rom]
        assert scores["n_cases"] == sum(v["af"] is not None and v["af_truth"] is not None
                                        for f in r["families"].values() for v in f.get("eo", {}).values())
        assert scores["n_cases"] > 0 and scores["in_ci90"] is None
    section = next(sec for sec in summary["sections"] if sec["id"] == "response")
    # every (family, EO) without an AF is named in the report's text with its reason
    for rom, r in block["roms"].items():
        for fam, f in r["families"].items():
            if any("no_af" in v for v in f.get("eo", {}).values()):
                head = f"{rom} ROM, family {fam}: no amplification factor at EO"
                assert any(t.startswith(head) and "band's edge" in t for t in section["text"]), section["text"]
    # the command reads the run and recomputes nothing
    assert main(["response", str(o), "--family", "1"]) == 0
    rows = list(csv.DictReader((o / "response.csv").open(encoding="utf-8")))
    assert [(r["family"], r["eo"]) for r in rows] == [("1", "0"), ("1", "1"), ("1", "2")]
    assert (o / "response.png").stat().st_size > 0
    # the same modes, from the store (nothing recomputed), and the tuned disk solved here
    opts = RunOptions(cache_dir=s, n_patterns=3, refine=0, rom="paper", method="knn")
    res, runner = run_nodes(read_campaign(x), [names.full("identified"), names.DISK_CYCLIC, names.BLADE_RUBIN,
                                               names.BASELINE, names.DELTA_ALL, names.N_FULL_MODES], opts)
    assert not [n for n in runner.computed if n.startswith(names.FULL)]
    delta = res[names.DELTA_ALL]
    tuned = solve_assembly(res[names.DISK_CYCLIC], res[names.FE_MODEL], res[names.BLADE_RUBIN],
                           [res[names.BASELINE]] * 4, np.tile(delta.mean(axis=0), (4, 1)),
                           res[names.N_FULL_MODES]).modes
    fam = block["roms"]["paper"]["families"]
    bands = [fam[k]["band_hz"] for k in ("1", "2", "3")]
    ratios = [fam[k]["damping_ratio"] for k in ("1", "2", "3")]
    eo, band = 2, fam["1"]["band_hz"]
    force = np.exp(2j * math.pi * eo * np.arange(4) / 4)
    peaks = {}
    for which, modes in (("mistuned", res[names.full("identified")].modes), ("tuned", tuned)):
        bm = blade_modes(modes, 0.01, 1)
        z = family_damping(bm.frequencies_hz, bands, ratios)
        peaks[which] = _direct_peaks(bm.shapes, bm.frequencies_hz, z, force, band)
    ref = fam["1"]["eo"][str(eo)]
    assert peaks["tuned"].max() / peaks["tuned"].min() == pytest.approx(1.0, rel=1e-3)  # tuned: equal blades
    assert ref["af"] == pytest.approx(peaks["mistuned"].max() / peaks["tuned"].max(), rel=2e-3)
    assert ref["worst_blade"] == int(np.argmax(peaks["mistuned"])) + 1
    # an AF only where the tuned disk resonates inside the band: a tuned peak at the band's edge is the flank of
    # a neighbouring family (measured on this disk: family 2's tuned peak sat on its band's top at every EO)
    for f in fam.values():
        lo, hi = f["band_hz"]
        for v in f.get("eo", {}).values():
            inside = min(v["tuned_peak_hz"] - lo, hi - v["tuned_peak_hz"]) > 1e-3 * (hi - lo)
            assert (v["af"] is not None) == inside, (f["band_hz"], v)


def test_families_whose_bands_overlap_are_both_refused():
    """Two families' bands that overlap hold a mode neither owns alone (the bundled updated ROM's families 2 and
    3: 468–1234 and 631–1282 Hz): both are refused, with the overlap named; a disjoint family keeps its AF."""
    from bladetwin.stages.response import refuse_overlapping

    bands = np.array([[190.0, 240.0], [468.0, 1234.0], [631.0, 1282.0]])
    out = refuse_overlapping(bands, (1, 2, 3), ["", "", ""])
    assert out[0] == ""
    assert all("overlap (631–1234 Hz)" in w for w in out[1:]), out
    # a family refused already keeps its own reason and does not refuse its neighbour
    out = refuse_overlapping(bands, (1, 2, 3), ["", "family 2: solve more modes", ""])
    assert out == ["", "family 2: solve more modes", ""]


def test_a_run_whose_ema_gives_no_damping_refuses_every_family_and_goes_on(small_run):
    """Without a measured damping ratio the AF has no damping to use: each family is refused with the reason (the
    run's other results stand), instead of the node failing the run."""
    from types import SimpleNamespace

    from bladetwin.stages.response import rom_response_node

    x, _, s = small_run
    opts = RunOptions(cache_dir=s, n_patterns=3, refine=0, rom="paper", method="knn")
    res, _ = run_nodes(read_campaign(x), [names.full("identified"), names.RESPONSE_TUNED_PAPER, names.DELTA_ALL],
                       opts)
    undamped = SimpleNamespace(model=SimpleNamespace(frequencies_hz=np.array([200.0]),
                                                     damping_ratio=np.array([np.nan])))
    paper = rom_response_node(res[names.DELTA_ALL], res[names.full("identified")], res[names.RESPONSE_TUNED_PAPER],
                              rom="paper", solve="identified", assembly=undamped)
    assert all("no EMA mode with a damping ratio" in why for why in paper.refused), paper.refused
    assert np.all(np.isnan(paper.af))


def test_the_run_s_intervals_from_posterior_samples(small_run):
    """The node's intervals from (synthetic) posterior samples of the unfilmed joints' d1b frequencies: each
    family with an AF gets a 90 % interval and worst-blade probabilities summing to 1, with the discrepancy σ
    against the full-assembly test; samples equal to the answer give back the point AF exactly (contact only)."""
    from types import SimpleNamespace

    from bladetwin.stages.response import rom_response_node
    from bladetwin.stages.response_solves import d1b_node

    x, _, s = small_run
    opts = RunOptions(cache_dir=s, n_patterns=3, refine=0, rom="paper", method="knn")
    want = [names.full("identified"), names.RESPONSE_TUNED_PAPER, names.DELTA_ALL, names.DISK_CB,
            names.BLADE_RUBIN, names.FE_MODEL, names.BASELINE, names.ema("assembly")]
    campaign = read_campaign(x)
    tests = {f"d1bfit_{t.index:02d}": names.ema(names.test_name(t)) for t in campaign.of_type("d1b")}
    res, _ = run_nodes(campaign, want + list(tests.values()), opts)
    d1b = d1b_node(res[names.DISK_CB], res[names.BLADE_RUBIN], res[names.FE_MODEL], res[names.BASELINE],
                   res[names.DELTA_ALL])
    f = np.asarray(d1b.frequencies_hz)
    rng = np.random.default_rng(0)
    args = (res[names.DELTA_ALL], res[names.full("identified")], res[names.RESPONSE_TUNED_PAPER])
    kw = {"rom": "paper", "solve": "identified", "d1b": d1b, "assembly": res[names.ema("assembly")]}
    moved = {f"post_{j:02d}": SimpleNamespace(answer_hz=f, samples_hz=f * (1 + 0.003 * rng.standard_normal((40, 1))))
             for j in (2, 4)}
    still = {k: SimpleNamespace(answer_hz=f, samples_hz=np.tile(f, (40, 1))) for k in moved}
    paper = rom_response_node(*args, **kw, **moved)
    fixed = rom_response_node(*args, **kw, **still)
    fits = {k: res[v] for k, v in tests.items()}
    shaped = rom_response_node(*args, **kw, **moved, **fits)
    assert paper.n_samples == 40
    done = np.isfinite(paper.af)
    assert done.any()
    lo, hi = paper.af_ci90[..., 0][done], paper.af_ci90[..., 1][done]
    assert np.all(lo <= hi)
    np.testing.assert_allclose(np.nansum(paper.p_worst, axis=-1)[done], 1.0)
    assert np.all(np.isfinite(paper.discrepancy[done.any(axis=1)]))
    # the disk–one-blade tests' blade-point amplitudes scatter (the twin's blades differ in shape too): their
    # σ_a widens the intervals, and the contact's interval alone stays as it was
    fam = done.any(axis=1)
    assert np.all(np.isfinite(shaped.amplitude_discrepancy[fam]) & (shaped.amplitude_discrepancy[fam] > 0))
    assert np.all(np.isnan(paper.amplitude_discrepancy))
    np.testing.assert_allclose(shaped.af_ci90_contact[done], paper.af_ci90_contact[done])
    assert np.any(np.abs(shaped.af_ci90[done] - paper.af_ci90[done]) > 1e-6)
    # samples without a change: the contact's interval is the solved disk's AF itself
    np.testing.assert_allclose(fixed.af_ci90_contact[..., 0][done], paper.af[done], rtol=1e-9)
    np.testing.assert_allclose(fixed.af_ci90_contact[..., 1][done], paper.af[done], rtol=1e-9)
