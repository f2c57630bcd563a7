"""``bladetwin run`` end to end on a small simulated campaign (issue 11), checked against the rig's truth.

One module-scoped campaign (coarse mesh, 6 blades, 3×7 grid, joints 3 and 4 filmed) and one cold run; the
other tests reuse its caches (warm runs), so the module stays around a minute on 2 cores.
"""

from __future__ import annotations

import csv
import json
import re
import shutil
import tomllib
from html.parser import HTMLParser

import numpy as np
import pytest
import tomli_w

import ema
from bladetwin.campaign import read_campaign
from bladetwin.cli import main
from bladetwin.stages import RunOptions
from bladetwin.stages.patterns import film_patterns, read_films
from identify.film_next import outside_family_pp
from identify.posterior import MAX_EXTENSIONS
from identify.rom_update import ROM_ERROR
from identify.validation import contact_area_fraction
from rom.pattern_io import load_patterns

SMALL = ["--level", "coarse", "--blades", "6", "--grid", "3x7", "--known", "3,4"]
#: The paper's k-NN alone (no refinement, no posterior): every test but the refinement's and the posterior's runs
#: it, so the module stays short; those two run their method explicitly.
KNN_ONLY = ["--refine", "0", "--method", "knn"]
#: Runs that check something else than the ROM update or the posterior skip both (they only add time there).
PAPER_ROM = ["--rom", "paper", "--method", "knn"]
#: The module runs the realistic twin end to end, with the paper's calibration: uncalibrated, the coarse model is
#: off by more than the k-NN's 5 % window on some joints' feature modes and they keep the baseline (issue 44).
RUN = ["run", "--calibrate"]
#: Runs whose figures no test looks at skip drawing them (most of a warm small run's time); the cold run and the
#: report tests draw them.
NOFIG = ["--no-figures"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    root = tmp_path_factory.mktemp("run")
    camp = root / "small"
    assert main(["lab", "simulate", *SMALL, "--seed", "3", "--out", str(camp)]) == 0
    return root, camp


@pytest.fixture(scope="module")
def cold(campaign):
    root, camp = campaign
    out = root / "out"
    assert main([*RUN, str(camp), *KNN_ONLY, "--out", str(out), "--cache-dir", str(root / "cache"), "--quiet"]) == 0
    return out, json.loads((out / "summary.json").read_text())


def _edit_manifest(folder, edit) -> None:
    path = folder / "campaign.toml"
    doc = tomllib.loads(path.read_text())
    edit(doc)
    path.write_text(tomli_w.dumps(doc))


def _truth_frequencies(camp) -> list:
    """The full assembly's visible modes (Hz) in the campaign's truth."""
    return json.loads((camp / "truth" / "truth.json").read_text())["frequencies_hz"]["assembly"]


def test_the_realistic_rig_hammers_in_the_time_domain_and_exports_the_coherence(campaign):
    """Every file carries a coherence record per FRF (the default ``--coherence all``), near 1 at the resonances
    (the response stands far above its channel noise there); the exponential window's damping and the poles it
    moves are in the truth: Δζ = 1/(τ ω) with one τ per test, and f √(1 + 2ζΔζ + Δζ²)."""
    _, camp = campaign
    truth = json.loads((camp / "truth" / "truth.json").read_text())
    manifest = tomllib.loads((camp / "campaign.toml").read_text())
    for test in manifest["tests"]:
        frf = ema.read_uff(camp / test["file"])
        coh = ema.read_coherence(camp / test["file"])
        assert coh is not None and coh.shape == frf.H.shape and not np.isnan(coh).any()
        assert ((coh >= 0) & (coh <= 1)).all()
    f = np.asarray(truth["frequencies_hz"]["assembly"])
    zeta = np.asarray(truth["damping_ratios"]["assembly"])
    window = np.asarray(truth["window_damping"]["assembly"])
    tau = 1 / (window * 2 * np.pi * f)
    np.testing.assert_allclose(tau, tau[0], rtol=1e-9)   # one exponential window for the whole test
    np.testing.assert_allclose(truth["apparent_frequencies_hz"]["assembly"], f * np.sqrt(1 + 2 * zeta * window
                                                                                        + window**2), rtol=1e-12)
    frf = ema.read_uff(camp / "assembly" / "assembly.uff")
    coh = ema.read_coherence(camp / "assembly" / "assembly.uff")
    peaks = [int(np.argmin(np.abs(frf.freq_hz - fr))) for fr in f]
    best = coh.max(axis=(0, 1))
    assert np.median(best[peaks]) > 0.99


def test_summary_has_every_field_and_the_truth_confirms_the_identification(campaign, cold):
    _, camp = campaign
    out, s = cold
    for key in ("campaign", "report", "feature_modes", "step1", "joints", "cases", "timings_s"):
        assert key in s
    assert set(s["timings_s"]) >= {"ema", "rom", "dataset", "identify", "validation", "report", "total"}
    assert [j["joint"] for j in s["joints"]] == list(range(1, 7))
    # The ε calibration warns once per blade and mode, for the exported ROM only: its controls (the baseline's
    # and the true patterns' updates) stay quiet instead of repeating it with other figures.
    calib = [re.match(r"blade (\d+)(, free mode (\d+)|: its disk)", w) for w in s["warnings"]]
    keys = [m.group(0) for m in calib if m]
    assert len(keys) == len(set(keys)), s["warnings"]
    assert abs(s["step1"]["max_abs_eps_pct"]) <= 50 + 1e-9  # step 1 picks the nearest grid row

    truth = load_patterns(camp / "truth" / "patterns.npz")
    pats = load_patterns(out / "identified_patterns.npz")  # the file `bladetwin rom modes --pattern` reads
    assert len(pats) == 6
    known = film_patterns(read_films(read_campaign(camp)))
    for j, row in zip(range(1, 7), s["joints"], strict=True):
        area = contact_area_fraction(np.stack([pats[j - 1].L, pats[j - 1].R]))
        assert np.allclose(area, [row["area_fraction_L_pct"], row["area_fraction_R_pct"]])
        ref = contact_area_fraction(np.stack([truth[j - 1].L, truth[j - 1].R]))
        assert np.allclose(ref, [row["reference_area_L_pct"], row["reference_area_R_pct"]])
        if j in known:  # the filmed joints keep their films
            assert row["source"] == "film"
            assert np.array_equal(pats[j - 1].L, known[j].L) and np.array_equal(pats[j - 1].R, known[j].R)
            assert row["beyond_family_pct"] is None and row["outside_family"] is None
        else:
            assert row["source"] == "k-NN" and row["pattern_L"].startswith("SP-")
            assert row["beyond_family_pct"] >= 0
            assert not (row["outside_family"] and row["beyond_family_pct"] == 0)  # flagged only if beyond reach
    # A joint beyond the synthetic family's reach is named in a note, and only then.
    outside = [row["joint"] for row in s["joints"] if row["outside_family"]]
    flagged = [n for n in s["notes"] if "outside the range the" in n]
    assert bool(flagged) == bool(outside)
    if outside:
        assert f"Joints {outside}:" in flagged[0]

    cases = s["cases"]
    for key in ("A", "B", "B_no_bias", "C"):
        assert cases[key]["n_modes"] >= 6 and 0 < cases[key]["mean_mac"] <= 1
    # Case A (identified vs true patterns, both in the ROM) against the baseline that gives every unfilmed joint
    # the films' majority pattern: on this realistic campaign the k-NN alone does not beat it (0.065 % against
    # 0.042 %, issue 44's note); the ideal twin's (test_one_path, several campaigns) asserts that it does there.
    assert cases["A"]["mean_abs_df_pct"] < 3 * cases["baseline"]["A"]["mean_abs_df_pct"]
    assert cases["A"]["mean_mac"] > 0.8
    # Case B (identified, against measurement) is within the model error (Case C) plus a small margin
    assert cases["B"]["mean_abs_df_pct"] - cases["C"]["mean_abs_df_pct"] <= 0.2
    # the identified ROM's disk–one-blade feature frequencies follow the measured ones within 1 %
    assert s["d1b"]["experimental_mean_abs_df_pct"] < 1.0
    # every test's modes, and the full assembly's scores against the truth (lab.judge, recomputed here)
    asm = s["ema"]["assembly"]
    assert asm["n_modes"] == len(asm["modes"]) and asm["n_visible"] == len(_truth_frequencies(camp))
    assert asm["one_to_one_within_0p05pct"] >= 0.9 and asm["mean_shape_mac"] > 0.5
    assert all(s["ema"][name]["n_modes"] == len(s["ema"][name]["modes"]) for name in s["ema"])


def test_outputs_report_and_uff55_are_complete(cold):
    out, s = cold
    for sec in s["sections"]:
        for item in sec["figures"] + sec["tables"]:
            assert (out / item["file"]).is_file(), item["file"]
    modes = ema.read_modes(out / "identified_rom_modes.uff")  # a lab's correlation tool reads UFF 55
    pairs = list(csv_rows(out / "full_pairs_B.csv"))
    assert modes.n_modes >= len(pairs) > 0

    class Page(HTMLParser):
        imgs: list = []
        tables = 0

        def handle_starttag(self, tag, attrs):
            if tag == "img":
                self.imgs.append(dict(attrs)["src"])
            self.tables += tag == "table"

    page = Page()
    page.feed((out / "report.html").read_text())
    n_fig = sum(len(sec["figures"]) for sec in s["sections"])
    assert len(page.imgs) == n_fig and all(src.startswith("data:image/png;base64,") for src in page.imgs)
    assert page.tables >= sum(len(sec["tables"]) for sec in s["sections"])
    # `bladetwin report` re-renders from the outputs alone
    (out / "report.html").unlink()
    assert main(["report", str(out)]) == 0 and (out / "report.html").is_file()


def csv_rows(path):
    import csv

    with open(path) as fh:
        yield from list(csv.reader(fh))[1:]


def test_warm_rerun_recomputes_nothing_and_gives_the_same_answer(campaign, cold, capsys):
    root, camp = campaign
    out, s = cold
    capsys.readouterr()
    assert main([*RUN, str(camp), *KNN_ONLY, *NOFIG, "--out", str(root / "warm"), "--cache-dir",
                 str(root / "cache")]) == 0
    err = capsys.readouterr().err
    # every stage node is read from the store: no EMA, no model build, no dataset, no solve
    assert "EMA " not in err and "  dataset" not in err and "solved" not in err, err
    assert "disk built" not in err and "0 read from the store" not in err, err
    w = json.loads((root / "warm" / "summary.json").read_text())
    assert w["joints"] == s["joints"] and w["cases"] == s["cases"]
    # --no-figures: the same figures in summary.json, every table, no PNG, a report that says so
    assert not list((root / "warm").glob("*.png")) and list(out.glob("*.png"))
    assert [t["file"] for sec in w["sections"] for t in sec["tables"]] == \
        [t["file"] for sec in s["sections"] for t in sec["tables"]]
    assert not any(sec["figures"] for sec in w["sections"])
    assert any("--no-figures" in n for n in w["notes"]) and not any("--no-figures" in n for n in s["notes"])
    assert "--no-figures" in (root / "warm" / "report.html").read_text()


def test_a_disk_the_cyclic_reduction_refused_falls_back_on_the_sparse_hybrid(campaign, cold, tmp_path, capsys):
    """The full solves then run on the hybrid (FE disk + Rubin blades), the reference implementation: the same
    Table 8 to the two ROMs' difference, and a note that says why. With one worker: every job runs in this
    process, after the run has let go of the models it handed to the disk builds."""
    root, camp = campaign
    out, s = cold
    from bladetwin.stages import codec
    from bladetwin.stages.models import CyclicBuild

    cache = tmp_path / "cache"
    shutil.copytree(root / "cache", cache, ignore=shutil.ignore_patterns("solve_assembly", "solve_updated"))
    (cyclic,) = (cache / "nodes" / "reduce_disk_all_slots").glob("*.npz")  # the cold run built it
    built = codec.load(cyclic)
    codec.save(cyclic, CyclicBuild(None, "the disk is not cyclic (marked by the test)", built.hardware_kg))
    capsys.readouterr()
    assert main([*RUN, str(camp), *KNN_ONLY, *PAPER_ROM, *NOFIG, "--workers", "1", "--out", str(tmp_path / "out"),
                 "--cache-dir", str(cache)]) == 0
    err = capsys.readouterr().err
    assert "full-assembly ROM 'baseline' solved" in err and "disk built" not in err, err
    h = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert any("sparse hybrid" in n and "marked by the test" in n for n in h["notes"]), h["notes"]
    assert any("cyclic all-slot" in n for n in s["notes"])
    for case in ("A", "B", "C"):
        assert h["cases"][case]["mean_abs_df_pct"] == pytest.approx(s["cases"][case]["mean_abs_df_pct"], abs=2e-3)
        assert h["cases"][case]["mean_mac"] == pytest.approx(s["cases"][case]["mean_mac"], abs=5e-3)


def test_refinement_improves_the_feature_match_and_is_cached(campaign, cold, capsys):
    root, camp = campaign
    out, s = cold
    args = [*RUN, str(camp), *PAPER_ROM, *NOFIG, "--cache-dir", str(root / "cache")]  # the default: refinement on
    capsys.readouterr()
    assert main([*args, "--out", str(root / "refined")]) == 0
    err = capsys.readouterr().err
    assert "refined (experimental input)" in err and "EMA " not in err and "  dataset" not in err, err
    r = json.loads((root / "refined" / "summary.json").read_text())
    # the CLI's default is RunOptions' (the Python API and the command line refine alike)
    assert r["settings"]["refine_max_solves"] == RunOptions().refine > 0
    assert (r["settings"]["rom"], s["settings"]["rom"]) == ("paper", RunOptions().rom)  # the run says which ROM
    note = next(n for n in r["notes"] if "refined after the k-NN" in n)
    # Each search only accepts improvements: refined ≤ k-NN on every input (the note gives both, per input).
    pairs = re.findall(r"input ([0-9.]+) % → ([0-9.]+) %", note)
    assert len(pairs) == 3 and all(float(a) <= float(b) for b, a in pairs), note
    # The numerical input's refined patterns reproduce the true patterns' d1b features at least as well as
    # the k-NN's did (both against the ROM with the truth: the summary's figure, recomputed by the run).
    assert r["d1b"]["numerical_mean_abs_df_pct"] <= s["d1b"]["numerical_mean_abs_df_pct"] + 1e-12
    for j in r["joints"]:
        assert j["source"] in ("film", "k-NN + refinement")
    assert main([*args, "--out", str(root / "refined2")]) == 0  # warm: every search comes from the cache
    assert "refined (" not in capsys.readouterr().err
    assert json.loads((root / "refined2" / "summary.json").read_text())["joints"] == r["joints"]


def test_campaign_without_truth_reports_cases_a_and_c_unavailable(campaign, cold, tmp_path):
    root, camp = campaign
    lab = tmp_path / "lab"
    shutil.copytree(camp, lab, ignore=shutil.ignore_patterns("truth"))
    out = tmp_path / "out"
    assert main([*RUN, str(lab), *KNN_ONLY, *NOFIG, "--out", str(out), "--cache-dir", str(root / "cache"),
                 "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["cases"]["A"] is None and s["cases"]["C"] is None and s["cases"]["baseline"]["A"] is None
    assert set(s["ema"]["assembly"]) == {"n_modes", "modes"}  # no truth, no scores
    assert s["cases"]["B"]["n_modes"] > 0
    assert any("unavailable" in n for n in s["notes"])
    assert all(j["reference_area_L_pct"] is None for j in s["joints"])
    html = (out / "report.html").read_text()
    assert "unavailable" in html


#: Steps per round of the posterior test's chains: short, so that the rounds and their diagnostics run (the
#: chains' accuracy is tests/identify/test_posterior.py's); with rounds of 500 a joint ran 2000–3000 steps.
STEPS = 100


def test_posterior_runs_without_truth_and_answers_every_unfilmed_joint(campaign, cold, tmp_path):
    root, camp = campaign
    lab = tmp_path / "lab"
    shutil.copytree(camp, lab, ignore=shutil.ignore_patterns("truth"))
    out = tmp_path / "out"
    assert main([*RUN, str(lab), *KNN_ONLY, *PAPER_ROM, "--method", "both", "--posterior-steps", str(STEPS),
                 "--out", str(out), "--cache-dir",
                 str(root / "cache"), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    known = set(s["known_joints"])
    assert all(j["source"] == ("film" if j["joint"] in known else "posterior") for j in s["joints"])
    post = s["methods"]["posterior"]
    assert post["cases"]["B"]["n_modes"] > 0 and post["cases"]["A"] is None
    assert "experimental" not in post  # no reference patterns: no geometry figures
    ratio = post["width_ratio"]["experimental"]  # but what the data pin down needs none
    assert set(ratio) == {"area L", "area R", "centroid u L", "centroid v L", "centroid u R", "centroid v R"}
    # 0 where the data pin a flank to one pattern of the 3×7 grid (a converged chain can: issue 46's design
    # §8.51), never beyond twice the prior's width
    assert all(0 <= r < 2 for r in ratio.values()), ratio
    # every unfilmed joint's chains: R̂ and ESS as identify.chains computes them, and a warning where they fail
    diag = post["diagnostics"]["experimental"]
    unfilmed = {j["joint"] for j in s["joints"] if j["joint"] not in known}
    assert {int(j) for j in diag} == unfilmed
    for j, d in diag.items():
        rounds = range(STEPS, STEPS * (MAX_EXTENSIONS + 1) + 1, STEPS)
        assert d["rhat"] >= 1.0 and d["ess"] > 0 and d["n_steps"] in rounds
        assert d["converged"] == (d["rhat"] <= 1.05 and d["ess"] >= 400)
        assert d["converged"] != any(w.startswith(f"joint {j}, experimental input: the contact posterior's chains")
                                     for w in s["warnings"])
    rows = list(csv.reader((out / "posterior_contact.csv").read_text().splitlines()))[1:]
    assert sorted(int(r[0]) for r in rows) == sorted(j["joint"] for j in s["joints"] if j["joint"] not in known)
    assert all(r[7] == r[8] == "" for r in rows)  # reference areas blank, not "None"
    freq = list(csv.DictReader((out / "posterior_frequencies.csv").read_text().splitlines()))
    assert {int(r["joint"]) for r in freq} == {int(r[0]) for r in rows}
    # film next: every unfilmed joint once, its distance outside the films' areas as the table's answer gives it
    films = [[j["area_fraction_L_pct"], j["area_fraction_R_pct"]] for j in s["joints"] if j["joint"] in known]
    nxt = post["film_next"]
    assert sorted(c["joint"] for c in nxt) == sorted(unfilmed)
    by_joint = {int(r[0]): r for r in rows}
    for c in nxt:
        r = by_joint[c["joint"]]
        assert c["outside_pp"] == pytest.approx(outside_family_pp([float(r[1]), float(r[4])], films), abs=1e-3)
        assert c["width_pp"] == pytest.approx((float(r[3]) - float(r[2]) + float(r[6]) - float(r[5])) / 2, abs=1e-3)
    keys = [(-c["outside_pp"], -c["width_pp"], c["joint"]) for c in nxt]
    assert keys == sorted(keys)
    for r in freq:  # an interval, and the answer's offset from the test as written
        f = float(r["answer (Hz)"])
        assert float(r["5 % (Hz)"]) <= float(r["95 % (Hz)"])
        if r["measured, bias removed (Hz)"]:
            y = float(r["measured, bias removed (Hz)"])
            assert float(r["answer − measured (%)"]) == pytest.approx(100 * (f / y - 1), abs=2e-3)  # 6 digits
    html = (out / "report.html").read_text()
    assert "Contact posterior" in html and "What the data pin down" in html and "Film next: joint" in html
    assert html.index("The answer.") < html.index("Full-assembly validation")  # the summary leads with it


def test_updated_rom_beats_the_papers_on_the_measured_assembly(cold):
    """The ROM updated on the disk–one-blade tests against the rig's full-assembly measurement (never fitted)."""
    out, s = cold
    rom = s["rom"]
    paper, upd = rom["paper"]["cases"], rom["updated"]["cases"]
    assert set(paper) == set(upd) == {"A", "B", "B_baseline", "C"}
    assert paper["B"] == s["cases"]["B"] and paper["C"] == s["cases"]["C"]
    assert paper["B_baseline"] == s["cases"]["baseline"]["B"]  # the paper ROM's control: Table 8's baseline B
    assert upd["B"]["mean_abs_df_pct"] < paper["B"]["mean_abs_df_pct"]
    assert upd["B"]["mean_mac"] > paper["B"]["mean_mac"]
    p = rom["updated"]["parameters"]
    assert p["d1b_rms_residual_pct"]["updated"] < 0.5 * p["d1b_rms_residual_pct"]["paper"]
    k = p["contact_stiffness"]
    assert k["fitted_on_joints"] == s["known_joints"] and k["normal_n_per_m3"] > 0
    text = " ".join(next(x for x in s["sections"] if x["id"] == "rom_update")["text"])
    assert ("stopped at its limit" in text) == (not k["settled"])  # the report says when the fit did not settle
    assert all(b["calibrated"] and b["free_modes"] for b in p["blades"])
    assert {f["file"] for f in next(x for x in s["sections"] if x["id"] == "rom_update")["tables"]} == {
        "rom_cases.csv", "rom_corrections.csv", "rom_families.csv"}
    import pyuff

    assert "updated ROM" in pyuff.UFF(str(out / "identified_rom_modes.uff")).read_sets(0)["id1"]


def test_the_updated_roms_control_is_case_b_with_the_baseline_and_with_the_truth_case_c(campaign, cold):
    """The control (issue 44): the updated ROM's Case B with the films' majority at every unfilmed joint, each
    blade's in-situ correction re-fitted for it. Recomputed here through the public nodes (as
    ../shared/notes/updated_rom_control_probe.py does): every upstream node from the run's store, then the ROM
    update, the full solve and the validation with only the patterns changed. With the true patterns instead of
    the baseline, the same path gives Case C: the control is Case B's path, on other patterns."""
    import warnings

    from threadpoolctl import threadpool_limits

    from bladetwin.rom_summary import CONTROL_TEXT
    from bladetwin.run import run_nodes
    from bladetwin.stages import rom_update, validation

    root, camp = campaign
    out, s = cold
    cases = s["rom"]["updated"]["cases"]
    control = cases["B_baseline"]
    assert control["n_modes"] > 0 and 0 < control["mean_mac"] <= 1
    names = ["validation", "rom_update/answer", "rom_update/baseline", "full/updated", "full/updated_baseline",
             "patterns/baseline", "reference", "known", "n_full_modes"]
    opts = RunOptions(cache_dir=root / "cache", refine=0, method="knn", calibrate=True, workers=1)
    res, runner = run_nodes(read_campaign(camp), names, opts)
    # the control is two stored nodes of the run (its in-situ corrections and its full solve), read back here
    assert {"rom_update/baseline", "full/updated_baseline"} <= set(runner.reused), runner.computed
    pipe = runner.pipeline
    args = {n: {a: res[src] for a, src in pipe[n].inputs.items()} for n in ("rom_update/answer", "full/updated")}
    val = pipe["validation"]
    val_args = {a: res[src] for a, src in val.inputs.items()}

    def case_b(patterns: list) -> dict:
        with threadpool_limits(1), warnings.catch_warnings():  # as on the run's workers, which record them
            warnings.simplefilter("ignore")
            upd = rom_update.update_node(**{**args["rom_update/answer"], "patterns": patterns})
            solve = rom_update.solve_updated(**{**args["full/updated"], "patterns": patterns, "update": upd})
        return validation.full_validation(**{**val_args, "updated": solve}, **val.params).cases["rom"]["updated"]["B"]

    def same(a: dict, b: dict) -> bool:
        return a["n_modes"] == b["n_modes"] and np.allclose([a["mean_abs_df_pct"], a["mean_mac"]],
                                                            [b["mean_abs_df_pct"], b["mean_mac"]], rtol=1e-6, atol=0)

    assert same(case_b(res["patterns/baseline"]), control)
    assert same(case_b(res["reference"]), cases["C"])
    # teeth: the control is neither Case C nor the answer's Case B, and its re-fitted ε differs from the answer's
    # at the unfilmed joints; at a filmed one (its film in both sets of patterns) only in a mode its test cannot
    # see, which takes the blades' common value (identify.in_situ) that the unfilmed joints' patterns move
    assert not same(control, cases["C"]) and not same(control, cases["B"])
    eps_base, eps_answer = res["rom_update/baseline"].corrections, res["rom_update/answer"].corrections
    filmed = np.array([j - 1 for j in res["known"]])
    moved = ~np.isclose(eps_base[filmed], eps_answer[filmed], rtol=1e-5, atol=1e-9)
    assert np.all(moved.sum(axis=1) <= 1), (eps_base[filmed], eps_answer[filmed])
    assert not np.allclose(np.delete(eps_base, filmed, 0), np.delete(eps_answer, filmed, 0))
    # the report: the control beside B (the run's answer) and C (the true patterns), and what it means
    assert [r[0] for r in csv_rows(out / "rom_cases.csv")] == ["A", "B", "B_baseline", "C"]
    assert CONTROL_TEXT.replace("'", "&#39;") in (out / "report.html").read_text()


def test_the_rom_update_never_reads_the_assembly_test(campaign, cold, tmp_path):
    """Calibrating without the full-assembly test (fresh store) gives the same parameters."""
    from bladetwin.run import run_nodes

    root, camp = campaign
    lab = tmp_path / "no_assembly"
    shutil.copytree(camp, lab)
    _edit_manifest(lab, lambda doc: doc.update(tests=[t for t in doc["tests"] if t["type"] != "assembly"]))
    names = ["rom_update/stiffness", "rom_update/answer"]
    opts = dict(refine=0, workers=1, method="knn")
    # The other tests' EMA fits, keyed by their files' bytes, are the same; the models and the fit are rebuilt.
    shutil.copytree(root / "cache" / "nodes" / "fit_test", tmp_path / "cache" / "nodes" / "fit_test")
    got, _ = run_nodes(read_campaign(lab), names, RunOptions(cache_dir=tmp_path / "cache", **opts))
    ref, _ = run_nodes(read_campaign(camp), names, RunOptions(cache_dir=root / "cache", **opts))
    # The fresh store rebuilds the models, whose last bits differ with BLAS threading (the reference store was
    # filled by `bladetwin run`): the parameters agree to round-off, far inside the fit's own uncertainty.
    # Had the assembly test entered the fit, they would move by a share of their standard deviation.
    a, b = got["rom_update/stiffness"], ref["rom_update/stiffness"]
    k = lambda s: np.log([s.stiffness.normal_n_per_m3, s.stiffness.tangential_n_per_m3])  # noqa: E731
    # ε is a relative eigenvalue fitted to frequencies no closer than ROM_ERROR: its standard deviation is at
    # least 2 ROM_ERROR, and 5 % of it is the tolerance (the stiffness fit can end on a shallow valley of k_n
    # and ε, where round-off moves ε by about 1e-6).
    assert np.all(np.abs(k(a) - k(b)) <= 1e-3 * b.log_std)
    tol = 0.05 * 2 * ROM_ERROR
    np.testing.assert_allclose(a.corrections, b.corrections, rtol=0, atol=tol)
    np.testing.assert_allclose(got["rom_update/answer"].corrections, ref["rom_update/answer"].corrections,
                               rtol=0, atol=tol)


def test_a_picks_file_replaces_the_automatic_selection(campaign, cold, tmp_path):
    root, camp = campaign
    lab = tmp_path / "picked"
    shutil.copytree(camp, lab)
    c = read_campaign(lab)
    test = c.of_type("assembly")[0]
    frf = ema.read_uff(test.file)
    auto = ema.fit(frf, max_order=test.max_order)
    d = auto.diagram
    # keep every other automatic mode: the pole of the highest order nearest to it
    top = d.order == d.order.max()
    chosen = []
    for f in auto.model.frequencies_hz[::2]:
        k = np.flatnonzero(top)[np.argmin(np.abs(d.frequencies_hz[top] - f))]
        chosen.append((int(d.order[k]), float(d.frequencies_hz[k])))
    (lab / "picks").mkdir()
    ema.save_picks(lab / "picks" / "assembly.json",
                   ema.Picks(file="assembly/assembly.uff", method="lsrf", band_hz=None, max_order=test.max_order,
                             picks=tuple(chosen)))

    def add_picks(doc):
        for t in doc["tests"]:
            if t["type"] == "assembly":
                t["picks"] = "picks/assembly.json"

    _edit_manifest(lab, add_picks)
    out = tmp_path / "out"
    assert main([*RUN, str(lab), *KNN_ONLY, *PAPER_ROM, *NOFIG, "--out", str(out), "--cache-dir",
                 str(root / "cache"), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    rows = list(csv_rows(out / "assembly_modes.csv"))
    assert len(rows) == len(chosen) < auto.model.n_modes
    assert np.allclose([float(r[1]) for r in rows], [f for _, f in chosen], rtol=0.01)
    assert any("Picks files" in n and "assembly.uff" in n for n in s["notes"])
    assert "picks file assembly.json" in (out / "ema_quality.csv").read_text()


def _swap_film(doc):
    doc["films"][0]["file"], doc["films"][2]["file"] = doc["films"][2]["file"], doc["films"][0]["file"]


def _blade_twice(doc):
    doc["tests"][1]["blade"] = 1


def _one_known(doc):
    doc["campaign"]["known_joints"] = doc["campaign"]["known_joints"][:1]


def _wrong_units(doc):
    doc["campaign"]["frf_units"] = "m/s^2/N"


def _missing_uff(doc):
    doc["tests"][0]["file"] = "blades/nowhere.uff"


@pytest.mark.parametrize("edit, needles", [
    (_missing_uff, ["blades/nowhere.uff", "not found", "tests[0]"]),
    (_blade_twice, ["blade 1 is named twice", "tests[1]"]),
    (_swap_film, ["joint_04_L.png", "film of joint 4", "joint 3"]),
    (_one_known, ["known_joints", "at least 2"]),
    (_wrong_units, ["blade_01.uff", "m/s/N", "m/s^2/N"]),
], ids=["missing-uff", "blade-twice", "film-of-wrong-joint", "one-known-joint", "units"])
def test_bad_campaigns_fail_fast_with_one_line(campaign, tmp_path, capsys, edit, needles):
    _, camp = campaign
    bad = tmp_path / "bad"
    shutil.copytree(camp, bad)
    _edit_manifest(bad, edit)
    capsys.readouterr()
    assert main([*RUN, str(bad), "--out", str(tmp_path / "out"), "--cache-dir", str(tmp_path / "cache")]) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("bladetwin: error")]
    assert len(lines) == 1 and all(n in lines[0] for n in needles), err
    assert "EMA " not in err and not (tmp_path / "cache" / "nodes").exists()  # refused before any long stage


def test_campaign_init_s_filled_draft_runs_to_the_campaign_s_figures(campaign, cold):
    """``bladetwin campaign init`` on this campaign with its manifest taken away; once the fields nothing in the
    files tells (grid, model, masses, the films' metadata) are given from the original, the run gives the cold
    run's figures. In the same folder, so that the run reuses the cold run's store (its keys name the files)."""
    from .test_campaign_init import filled_draft

    root, camp = campaign
    out, ref = cold
    manifest = camp / "campaign.toml"
    text = manifest.read_text()
    try:
        manifest.unlink()
        assert main(["campaign", "init", str(camp)]) == 0
        manifest.write_text(tomli_w.dumps(filled_draft(tomllib.loads(manifest.read_text()), tomllib.loads(text))))
        draft_out = root / "draft_out"
        assert main([*RUN, str(camp), *KNN_ONLY, *NOFIG, "--out", str(draft_out), "--cache-dir",
                     str(root / "cache"), "--quiet"]) == 0
    finally:
        manifest.write_text(text)
    got = json.loads((draft_out / "summary.json").read_text())
    assert got["cases"] == ref["cases"] and got["joints"] == ref["joints"]
    a, b = (np.load(o / "identified_patterns.npz") for o in (out, draft_out))
    assert sorted(a.files) == sorted(b.files) and all(np.array_equal(a[k], b[k]) for k in a.files)
