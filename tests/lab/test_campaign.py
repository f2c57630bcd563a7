"""``bladetwin lab simulate``: a complete small campaign, read back by ``ema``, that recovers the truth.

Issue 9 acceptance, on a small campaign (coarse mesh, 6 blades, 3×7 grid): every file readable, the EMA
front end (automatic selection, no frequencies given) recovers ``truth.json``, and bad arguments give one
line naming the value.
"""

import json
import tomllib

import numpy as np
import pytest

import ema
from bladetwin.cli import main

#: The ideal twin: these tests isolate the rig and the EMA (tests/lab/test_specimen.py has the realistic one).
SMALL = ["--level", "coarse", "--blades", "6", "--grid", "3x7", "--realism", "ideal"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("lab") / "small"
    assert main(["lab", "simulate", *SMALL, "--seed", "3", "--out", str(out)]) == 0
    return out, json.loads((out / "truth" / "truth.json").read_text())


def _fit(path):
    return ema.fit(ema.read_uff(path)).model


def _errors_pct(found, truth):
    """For each truth frequency, the relative distance (%) to the nearest found one."""
    found = np.asarray(found)
    return np.array([np.min(np.abs(found / f - 1)) * 100 if found.size else np.inf for f in truth])


def test_campaign_is_complete_and_every_file_reads(campaign):
    out, truth = campaign
    manifest = tomllib.loads((out / "campaign.toml").read_text())
    assert manifest["campaign"]["n_blades"] == 6 and manifest["campaign"]["grid"] == [3, 7]
    kinds = [t["type"] for t in manifest["tests"]]
    assert kinds.count("blade") == 6 and kinds.count("d1b") == 6 and kinds.count("disk") == kinds.count("assembly") == 1
    for test in manifest["tests"]:
        frf = ema.read_uff(out / test["file"])
        assert frf.form == "mobility" and frf.n_outputs >= 1
    known = manifest["campaign"]["known_joints"]
    assert sorted({f["joint"] for f in manifest["films"]}) == known and len(manifest["films"]) == 2 * len(known)
    for f in manifest["films"]:
        assert (out / f["file"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(list((out / "truth" / "films").glob("*.png"))) == 12
    with np.load(out / "truth" / "patterns.npz") as z:
        assert z["L"].shape == z["R"].shape == (6, 3, 7) and z["L"].dtype == bool
    for key in ("seed", "n_blades", "grid", "known_joints", "blade_deltas_pct", "frequencies_hz", "damping_ratios"):
        assert key in truth
    assert set(truth["frequencies_hz"]) == {"blades", "disk", "d1b", "assembly"}
    zeta = np.concatenate([np.ravel(z) for z in truth["damping_ratios"]["blades"]])
    assert np.all((zeta >= 0.0005) & (zeta <= 0.005))
    assert not list(out.parent.glob(".small.*"))  # the temporary folder was renamed, nothing left beside it


def test_ema_recovers_blades_disk_and_joints(campaign):
    out, truth = campaign
    f = truth["frequencies_hz"]
    models = {}
    for s in range(1, 7):
        m = _fit(out / "blades" / f"blade_{s:02d}.uff")
        models[f"blade_{s:02d}"] = m
        assert np.max(_errors_pct(m.frequencies_hz, f["blades"][s - 1][:8])) <= 0.05, s
    disk = ema.fit(ema.read_uff(out / "disk" / "disk.uff")).model
    table = ema.disk_modes(disk)
    err = _errors_pct(table["frequency_hz"], f["disk"][:7])
    assert np.max(err) <= 0.1, err
    for k, ft in enumerate(f["disk"][:7]):
        j = int(np.argmin(np.abs(table["frequency_hz"].to_numpy() - ft)))
        assert int(table["nodal_diameter"].iloc[j]) == truth["disk_nodal_diameters"][k]
    for s in range(1, 7):
        m = _fit(out / "d1b" / f"joint_{s:02d}.uff")
        assert np.max(_errors_pct(m.frequencies_hz, f["d1b"][s - 1][:10])) <= 0.1, s
    deltas = ema.blade_deltas(models)
    exact = np.array(truth["blade_deltas_pct"])
    n = min(deltas.shape[1], exact.shape[1], 8)
    np.testing.assert_allclose(deltas.to_numpy()[:, :n], exact[:, :n], atol=0.05)


def test_ema_recovers_the_full_assembly(campaign):
    out, truth = campaign
    m = _fit(out / "assembly" / "assembly.uff")
    visible = truth["frequencies_hz"]["assembly"]
    err = _errors_pct(m.frequencies_hz, visible)
    assert np.mean(err <= 0.2) >= 0.9, err
    every = np.asarray(truth["all_frequencies_hz"]["assembly"])
    worst = max(np.min(np.abs(every / fe - 1)) * 100 for fe in m.frequencies_hz)
    assert worst <= 1.0, worst


def test_case_c_pairs_the_rom_with_the_measured_modes(campaign, tmp_path):
    """Case C runs on a campaign as a user's pipeline would, and the model error stays that of a model."""
    from lab.model_error import case_c

    out, _ = campaign
    err = case_c(out, cache_dir=tmp_path / "cache").summary()
    assert err["full"]["n_paired"] >= 0.7 * err["full"]["n_ema_modes"]
    assert 0 < err["full"]["mean_abs_df_pct"] < 2.0 and err["full"]["mean_mac"] > 0.7
    # d1b modes are paired by frequency: seen from 3 blade points and one point per sector, the blade tip
    # dominates every shape and MAC cannot tell them apart (lab.model_error._pair).
    assert 0 < err["d1b"]["mean_abs_df_pct"] < 1.0 and err["d1b"]["max_abs_df_pct"] < 3.0


def test_same_seed_same_campaign(tmp_path):
    # the realistic twin on the smallest disk it takes (2 blades, both filmed: fewer blades than the assembly
    # test's hammer references, which once indexed past the last tip)
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["lab", "simulate", "--level", "coarse", "--blades", "2", "--known", "1,2", "--grid", "3x7",
                     "--seed", "8", "--out", str(out), "--json"]) == 0
    ta, tb = (json.loads((p / "truth" / "truth.json").read_text()) for p in (a, b))
    with np.load(a / "truth" / "patterns.npz") as za, np.load(b / "truth" / "patterns.npz") as zb:
        np.testing.assert_array_equal(za["L"], zb["L"])
        np.testing.assert_array_equal(za["R"], zb["R"])
    for group in ("blades", "d1b"):
        for fa, fb in zip(ta["frequencies_hz"][group], tb["frequencies_hz"][group], strict=True):
            np.testing.assert_allclose(fa, fb, rtol=1e-9)
    np.testing.assert_allclose(ta["frequencies_hz"]["assembly"], tb["frequencies_hz"]["assembly"], rtol=1e-9)


@pytest.mark.parametrize("args, needle", [
    (["--blades", "1"], "n_blades"),
    (["--blades", "0"], "n_blades"),
    (["--grid", "3x6"], "grid[1]"),
    (["--grid", "1x7"], "grid[0]"),
    (["--known", "2,9"], "known joints [2, 9]"),
    (["--known", "a"], "--known"),
])
def test_bad_arguments_are_one_line_errors(tmp_path, capsys, args, needle):
    out = tmp_path / "c"
    rc = main(["lab", "simulate", "--level", "coarse", "--grid", "3x7", "--blades", "4", *args, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and needle in err, err
    assert not out.exists()


def test_unwritable_output_folder(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    (locked / "file").write_text("x")
    rc = main(["lab", "simulate", *SMALL, "--out", str(locked / "file" / "c")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "file" in err, err
    rc = main(["lab", "simulate", *SMALL, "--out", str(locked)])  # not empty
    err = capsys.readouterr().err.strip()
    assert rc == 2 and str(locked) in err and "not an empty folder" in err


def test_the_assembly_truth_shapes_judge_the_ema(campaign):
    """truth/assembly_modes.npz holds the visible modes' exact shapes at the test's outputs: an EMA of the test
    pairs with them (lab.judge), and a shape judged against a wrong mode scores low."""
    from lab.judge import assembly_scores, load_assembly_truth

    out, truth = campaign
    at = load_assembly_truth(out / "truth")
    assert np.allclose(at.frequencies_hz, truth["frequencies_hz"]["assembly"])
    frf = ema.read_uff(out / "assembly" / "assembly.uff")
    assert at.shapes.shape == (frf.n_outputs, at.frequencies_hz.size) and set(at.outputs) == set(frf.outputs)
    model = ema.fit(frf).model
    scores = assembly_scores(model, at)
    assert scores["n_visible"] == at.frequencies_hz.size and scores["n_within_0p05pct"] >= 1
    # the blade family's modes match the truth's shapes (MAC 1.000 on this campaign; the split disk doublets,
    # 0.1-0.6 % apart, score 0.01-0.96: issue 31's shape item, docs/ema.md); the mean then lies above 0.75
    from ema.mac import mac_paired, pair_by_frequency

    rows, cols = pair_by_frequency(model.frequencies_hz, at.frequencies_hz, 5e-4)
    idx = [list(model.outputs).index(d) for d in at.outputs]
    m = mac_paired(model.shapes[idx][:, rows].T, at.shapes[:, cols].T)
    assert np.median(m) >= 0.99 and abs(np.mean(m) - scores["mean_shape_mac"]) < 1e-12, m
    shuffled = type(at)(at.frequencies_hz, at.all_frequencies_hz, at.shapes[:, ::-1], at.blade_energy, at.outputs)
    assert assembly_scores(model, shuffled)["mean_shape_mac"] < scores["mean_shape_mac"]


def test_the_families_fit_keeps_no_pole_at_the_damping_bound(campaign):
    """On this 6-blade campaign the families fit once kept modes whose damping refinement drove to a bound (5 %,
    1.2 % and 2.8 % from every true mode; 0.001 %, 3.8 % off) and a scan-grown mode 1.35 Hz beside the line that
    opened its window (2.8 % off); they are dropped or refused, and the fit still pairs 19 of the 20 visible
    modes within 0.05 % (the ordinary fit: 20; docs/ema.md, limits)."""
    from ema.family import ZETA_BOUNDS
    from lab.judge import assembly_scores, load_assembly_truth

    out, _ = campaign
    model = ema.fit(ema.read_uff(out / "assembly" / "assembly.uff"), families=True).model
    assert np.all((model.damping_ratio < ZETA_BOUNDS[1] / 1.5) & (model.damping_ratio > 1.5 * ZETA_BOUNDS[0]))
    scores = assembly_scores(model, load_assembly_truth(out / "truth"))
    assert scores["n_within_0p05pct"] >= scores["n_visible"] - 1 and scores["n_more_than_1pct_off"] == 0, scores
