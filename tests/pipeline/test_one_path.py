"""One path for every command (issue 29): the stage commands reuse what ``bladetwin run`` stored, a picks file
changes both alike, and several campaigns of one disk share its reduced models in one run."""

from __future__ import annotations

import json
import shutil
import tomllib
from html.parser import HTMLParser

import numpy as np
import pytest
import tomli_w

import ema
from bladetwin.campaign import read_campaign
from bladetwin.cli import main
from rom.pattern_io import load_patterns

#: The ideal twin: these tests check the pipeline's behaviour, not its accuracy on a realistic specimen.
SMALL = ["--level", "coarse", "--blades", "4", "--grid", "3x7", "--known", "1,3", "--realism", "ideal"]
#: The settings every command below shares (the stage commands' defaults are the run's; these only shorten it).
# --rom paper: the ROM update is tested in test_run.py; here it would only add time.
SETTINGS = ["--refine", "8", "--n", "6", "--rom", "paper", "--method", "knn"]
#: `bladetwin run` here checks stores, scheduling and pages, not figures: it skips drawing them.
RUN = ["run", "--no-figures"]


@pytest.fixture(scope="module")
def camp(tmp_path_factory):
    root = tmp_path_factory.mktemp("onepath")
    for seed, name in ((5, "first"), (6, "second")):
        assert main(["lab", "simulate", *SMALL, "--seed", str(seed), "--out", str(root / name)]) == 0
    return root


def _run(root, camps, out, capsys) -> str:
    capsys.readouterr()
    assert main([*RUN, *map(str, camps), *SETTINGS, "--out", str(out), "--cache-dir", str(root / "store")]) == 0
    return capsys.readouterr().err


def _no_solves(monkeypatch):
    """Any EMA fit, reduction or d1b solve now fails: a stage command must find them all in the store."""
    import identify.tracking
    import rom.craig_bampton
    import rom.cyclic

    def refuse(*a, **k):
        raise AssertionError("a stage was recomputed instead of read from the store")

    monkeypatch.setattr(ema, "fit", refuse)
    monkeypatch.setattr(identify.tracking.ModeTracker, "track", refuse)
    monkeypatch.setattr(rom.craig_bampton, "reduce_disk", refuse)
    monkeypatch.setattr(rom.cyclic, "reduce_disk_cyclic", refuse)


def test_stage_commands_after_a_run_recompute_nothing(camp, tmp_path, capsys, monkeypatch):
    _run(camp, [camp / "first"], tmp_path / "run", capsys)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    _no_solves(monkeypatch)
    common = [str(camp / "first"), *SETTINGS, "--cache-dir", str(camp / "store"), "--out", str(tmp_path / "id")]
    for sub in ("patterns", "sensitivity", "dataset", "predict", "validate"):
        capsys.readouterr()
        assert main(["identify", sub, *common, "--json"]) == 0, sub
        doc = json.loads(capsys.readouterr().out)
        assert doc, sub
        if sub == "predict":
            assert np.allclose(doc["bias_pct"], s["bias"]["per_mode_pct"], rtol=0, atol=1e-12)
        if sub == "sensitivity":
            assert doc["feature_modes"] == s["feature_modes"]
    for a, b in zip(load_patterns(tmp_path / "id" / "predicted.npz"),
                    load_patterns(tmp_path / "run" / "identified_patterns.npz"), strict=True):
        assert np.array_equal(a.L, b.L) and np.array_equal(a.R, b.R)


def _pick_every_other_mode(folder) -> None:
    """A picks file for the first filmed joint's d1b test: every other automatic mode (changes the bias)."""
    c = read_campaign(folder)
    test = next(t for t in c.of_type("d1b") if t.index == c.known_joints[0])
    auto = ema.fit(ema.read_uff(test.file), max_order=test.max_order)
    d = auto.diagram
    top = np.flatnonzero(d.order == d.order.max())
    chosen = [(int(d.order[k]), float(d.frequencies_hz[k])) for k in
              (top[np.argmin(np.abs(d.frequencies_hz[top] - f))] for f in auto.model.frequencies_hz[::2])]
    ema.save_picks(folder / "picks" / "d1b.json", ema.Picks(file=str(test.file.name), method=d.method, band_hz=None,
                                                             max_order=test.max_order, picks=tuple(chosen)))
    doc = tomllib.loads((folder / "campaign.toml").read_text())
    for t in doc["tests"]:
        if t["type"] == "d1b" and t.get("joint", t.get("index")) == test.index:
            t["picks"] = "picks/d1b.json"
    (folder / "campaign.toml").write_text(tomli_w.dumps(doc))


def test_a_picks_file_changes_the_stage_command_and_the_run_alike(camp, tmp_path, capsys):
    picked = tmp_path / "picked"
    shutil.copytree(camp / "first", picked)
    _pick_every_other_mode(picked)
    assert read_campaign(picked).of_type("d1b")[0].picks is not None, "the manifest names the picks file"
    _run(camp, [camp / "first"], tmp_path / "plain", capsys)
    _run(camp, [picked], tmp_path / "run", capsys)
    capsys.readouterr()
    assert main(["identify", "predict", str(picked), *SETTINGS, "--cache-dir", str(camp / "store"), "--out",
                 str(tmp_path / "id"), "--json", "--quiet"]) == 0
    pred = json.loads(capsys.readouterr().out)
    plain = json.loads((tmp_path / "plain" / "summary.json").read_text())
    run = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert any("Picks files" in n for n in run["notes"])
    assert not np.allclose(run["bias"]["per_mode_pct"], plain["bias"]["per_mode_pct"])  # the picks count
    assert np.allclose(pred["bias_pct"], run["bias"]["per_mode_pct"], rtol=0, atol=1e-12)  # the same way
    for a, b in zip(load_patterns(tmp_path / "id" / "predicted.npz"),
                    load_patterns(tmp_path / "run" / "identified_patterns.npz"), strict=True):
        assert np.array_equal(a.L, b.L) and np.array_equal(a.R, b.R)


class _Cells(HTMLParser):
    def __init__(self):
        super().__init__()
        self.cells, self._in = [], False

    def handle_starttag(self, tag, attrs):
        self._in = tag == "td"

    def handle_data(self, data):
        if self._in and data.strip():
            self.cells.append(data.strip())


def test_several_campaigns_of_one_disk_share_its_models_and_get_an_index(camp, tmp_path, capsys):
    store = camp / "store2"
    capsys.readouterr()
    assert main([*RUN, str(camp / "first"), str(camp / "second"), *SETTINGS, "--out", str(tmp_path / "both"),
                 "--cache-dir", str(store)]) == 0
    err = capsys.readouterr().err
    # the reduced models are built once for both campaigns, then found by the other's nodes
    for label in ("Craig–Bampton disk built", "Rubin blade built", "cyclic all-slot disk built"):
        assert err.count(label) == 1, (label, err)
    for kind in ("reduce_disk_cb", "reduce_blade_rubin", "reduce_disk_all_slots"):
        assert len(list((store / "nodes" / kind).glob("*.npz"))) == 1
    summaries = []
    for name in ("first", "second"):
        assert (tmp_path / "both" / name / "report.html").is_file()
        summaries.append(json.loads((tmp_path / "both" / name / "summary.json").read_text()))
    assert summaries[0]["joints"] != summaries[1]["joints"] or summaries[0]["cases"] != summaries[1]["cases"]
    page = (tmp_path / "both" / "index.html").read_text()
    assert 'href="first/report.html"' in page and 'href="second/report.html"' in page
    cells = _Cells()
    cells.feed(page)
    b = cells.cells[cells.cells.index("Case B") + 1:][:4]  # |Δf| and MAC of each campaign, from its summary
    expect = [summaries[k]["cases"]["B"][f] for k in (0, 1) for f in ("mean_abs_df_pct", "mean_mac")]
    # each printed to the report's rule (bladetwin.report_cells): within half a unit of its last printed digit
    for text, value in zip(b, expect, strict=True):
        decimals = len(text.split(".")[1]) if "." in text else 0
        assert abs(float(text) - value) <= 0.5 * 10.0**-decimals * (1 + 1e-9), (text, value)
    # one disk, one calibrated model: the two campaigns' calibrations are pooled (and said so); each summary keeps
    # its campaign's own calibration, the one it gets alone
    for s in summaries:
        assert any("share one calibrated model" in w for w in s["warnings"])
        # on the ideal twin the identification beats the films' majority against the truth (Case A)
        assert s["cases"]["A"]["mean_abs_df_pct"] < s["cases"]["baseline"]["A"]["mean_abs_df_pct"]
    _run(camp, [camp / "second"], tmp_path / "alone", capsys)
    alone = json.loads((tmp_path / "alone" / "summary.json").read_text())
    assert alone["calibration"] == summaries[1]["calibration"]
    assert not any("share one calibrated model" in w for w in alone["warnings"])


def test_scheduler_sends_each_campaign_graph_to_a_dask_cluster(camp, tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    _run(camp, [camp / "first"], tmp_path / "local", capsys)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as c:
        capsys.readouterr()
        assert main([*RUN, str(camp / "first"), str(camp / "second"), *SETTINGS, "--out", str(tmp_path / "dask"),
                     "--cache-dir", str(camp / "store"), "--scheduler", c.scheduler_address]) == 0
    err = capsys.readouterr().err
    assert "Dask scheduler" in err
    local = json.loads((tmp_path / "local" / "summary.json").read_text())
    remote = json.loads((tmp_path / "dask" / "first" / "summary.json").read_text())
    assert remote["cases"] == local["cases"] and remote["joints"] == local["joints"]
    assert (tmp_path / "dask" / "index.html").is_file()


def test_a_damaged_store_entry_is_recomputed_and_named_in_the_summary(camp, tmp_path, capsys):
    _run(camp, [camp / "first"], tmp_path / "ref", capsys)
    store = tmp_path / "store"
    shutil.copytree(camp / "store", store)
    # The store holds both campaigns' EMA entries (earlier tests ran them): damage every one, zero bytes, as a
    # full disk leaves them; the run of "first" must recompute its own and name them.
    entries = sorted((store / "nodes" / "fit_test").glob("*.npz"))
    for entry in entries:
        entry.write_bytes(b"")
    capsys.readouterr()
    assert main([*RUN, str(camp / "first"), *SETTINGS, "--out", str(tmp_path / "o"), "--cache-dir", str(store)]) == 0
    err = capsys.readouterr().err
    named = [e for e in entries if f"warning: {e}" in err]
    assert "Traceback" not in err and named
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    ref = json.loads((tmp_path / "ref" / "summary.json").read_text())
    assert all(any(str(e) in n and "recomputed" in n for n in s["warnings"]) for e in named)
    assert s["cases"] == ref["cases"] and s["joints"] == ref["joints"]
