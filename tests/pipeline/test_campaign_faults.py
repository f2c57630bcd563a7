"""A lab's mistakes on a small simulated campaign (issue 30): each is refused in one line naming the file and the
field, or goes through with a note, never as a silent answer. Numbers in the test names are the issue's items."""

from __future__ import annotations

import json
import os
import shutil
import stat
import tomllib

import pytest
import tomli_w

import ema
from bladetwin.cli import main

#: The ideal twin: these tests check the pipeline's behaviour, not its accuracy on a realistic specimen.
SMALL = ["--level", "coarse", "--blades", "4", "--grid", "3x7", "--known", "1,3", "--seed", "5",
         "--realism", "ideal"]


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    root = tmp_path_factory.mktemp("faults") / "camp"
    assert main(["lab", "simulate", *SMALL, "--out", str(root)]) == 0
    return root


#: The runs below check what a fault does to the summary and the report, not the figures: the paper's k-NN alone, and
#: no figures drawn (the report is written all the same).
RUN = ["run", "--refine", "0", "--n", "4", "--rom", "paper", "--method", "knn", "--no-figures"]


@pytest.fixture(scope="module")
def store(pristine):
    """One store for the module's runs: what a fault leaves unchanged (the other files' EMA, the reduced models)
    is computed once; what it changes has other inputs, so other keys, and is computed again."""
    return pristine.parent / "store"


@pytest.fixture
def camp(pristine, tmp_path):
    dst = tmp_path / "camp"
    shutil.copytree(pristine, dst)
    return dst


def _manifest(camp) -> dict:
    return tomllib.loads((camp / "campaign.toml").read_text())


def _write_manifest(camp, doc) -> None:
    (camp / "campaign.toml").write_text(tomli_w.dumps(doc))


def _refused(camp, capsys, *needles, extra=()) -> str:
    """``bladetwin run`` refuses the campaign with exit 2 and one line holding every needle."""
    capsys.readouterr()
    out = camp.parent / "out"
    assert main(["run", str(camp), "--out", str(out), "--cache-dir", str(camp.parent / "store"), *extra]) == 2
    captured = capsys.readouterr().err
    errors = [line for line in captured.splitlines() if line.startswith("bladetwin: error")]
    assert len(errors) == 1 and "Traceback" not in captured, captured  # progress lines aside, one error line
    err = errors[0]
    for needle in needles:
        assert needle in err, (needle, err)
    assert not (out / "summary.json").exists()
    return err


def _test(doc, kind, index=None) -> dict:
    return next(t for t in doc["tests"] if t["type"] == kind and t.get("blade", t.get("joint")) == index)


def test_1_swapped_d1b_files_are_refused_by_their_node_numbers(camp, capsys):
    doc = _manifest(camp)
    a, b = _test(doc, "d1b", 1), _test(doc, "d1b", 2)
    a["file"], b["file"] = b["file"], a["file"]
    _write_manifest(camp, doc)
    _refused(camp, capsys, "joint_02.uff", "joint 1", "joint 2", "check_numbering")


def test_1_the_numbering_check_can_be_switched_off_for_a_test(camp):
    from bladetwin.campaign import read_campaign
    from bladetwin.campaign_checks import check_files

    doc = _manifest(camp)
    a, b = _test(doc, "d1b", 1), _test(doc, "d1b", 2)
    a["file"], b["file"] = b["file"], a["file"]
    a["check_numbering"] = b["check_numbering"] = False
    _write_manifest(camp, doc)
    check_files(read_campaign(camp))  # the lab said its numbering differs: no refusal


def test_2_a_blade_file_as_the_disk_test_and_the_disk_file_as_a_blade_test(camp, capsys):
    doc = _manifest(camp)
    _test(doc, "disk")["file"] = _test(doc, "blade", 2)["file"]
    _write_manifest(camp, doc)
    _refused(camp, capsys, "blade_02.uff", "disk test")
    doc = _manifest(camp)
    doc["tests"] = [t for t in doc["tests"] if t["type"] != "disk"]
    _test(doc, "blade", 3)["file"] = "disk/disk.uff"
    _write_manifest(camp, doc)
    _refused(camp, capsys, "disk.uff", "blade 3")


def test_2_a_d1b_file_as_a_blade_test(camp, capsys):
    doc = _manifest(camp)
    _test(doc, "blade", 2)["file"] = _test(doc, "d1b", 2)["file"]
    doc["tests"] = [t for t in doc["tests"] if not (t["type"] == "d1b" and t["joint"] == 2)]
    _write_manifest(camp, doc)
    _refused(camp, capsys, "joint_02.uff", "blade test", "slots [2]")


def test_3_one_blade_file_copied_under_another_name(camp, capsys):
    shutil.copy(camp / "blades" / "blade_01.uff", camp / "blades" / "blade_02.uff")
    _refused(camp, capsys, "blade_02.uff", "blade_01.uff", "same FRFs")


@pytest.mark.parametrize("where, key, value, hint", [
    ("campaign", "frf_unit", "m/s/N", "frf_units"),
    ("test", "max_ordr", 90, "max_order"),
    ("film", "pixel_siz", 1e-4, "pixel_size"),
    ("top", "film", [], "films"),
])
def test_5_typod_keys_are_refused_with_the_nearest_allowed_one(camp, capsys, where, key, value, hint):
    doc = _manifest(camp)
    table = {"campaign": doc["campaign"], "test": doc["tests"][0], "film": doc["films"][0], "top": doc}[where]
    table[key] = value
    _write_manifest(camp, doc)
    _refused(camp, capsys, f"unknown key {key!r}", f"did you mean {hint!r}")


def _film(camp, name="joint_01_L.png"):
    import numpy as np
    from PIL import Image

    path = camp / "films" / name
    with Image.open(path) as im:
        return path, np.asarray(im)


@pytest.mark.parametrize("fault, needles", [
    ("white", ["joint_01_L.png", "blank film"]),
    ("black", ["joint_01_L.png", "white = 235", "no unexposed film"]),
    ("pixel_size", ["joint_01_L.png", "pixel_size", "1.5", "larger"]),
])
def test_4_unusable_films_are_refused(camp, capsys, fault, needles):
    import numpy as np
    from PIL import Image

    path, image = _film(camp)
    if fault == "pixel_size":  # the scan at 1.5× the metadata's pixel size: its imprint overflows the grid's cells
        doc = _manifest(camp)
        film = next(f for f in doc["films"] if f["file"].endswith("joint_01_L.png"))
        film["pixel_size"] *= 1.5
        _write_manifest(camp, doc)
    else:
        Image.fromarray(np.full_like(image, 235 if fault == "white" else 25)).save(path)
    _refused(camp, capsys, *needles)


def test_4_a_16_bit_scan_is_read_on_its_metadatas_scale_and_says_so(camp, store, tmp_path, capfd):
    """The same film as 16 bits (× 257): read as 8-bit, with a warning on stderr (one line), in summary.json and
    in the report; the contact grid is the 8-bit scan's."""
    import numpy as np
    from PIL import Image

    from bladetwin.campaign import read_campaign
    from bladetwin.stages.patterns import read_films

    path, image = _film(camp)
    before = read_films(read_campaign(camp))[1][0].contact
    Image.fromarray(image.astype(np.uint16) * 257).save(path)
    capfd.readouterr()
    out = tmp_path / "out"
    assert main([*RUN, str(camp), "--out", str(out), "--cache-dir", str(store), "--quiet"]) == 0
    err = [line for line in capfd.readouterr().err.splitlines() if "joint_01_L.png" in line]
    assert len(err) == 1 and err[0].startswith("bladetwin: warning: film ") and "16-bit" in err[0], err
    summary = json.loads((out / "summary.json").read_text())
    assert [w for w in summary["warnings"] if "joint_01_L.png" in w and "divided by 257" in w]
    assert "divided by 257" in (out / "report.html").read_text()
    assert np.array_equal(read_films(read_campaign(camp))[1][0].contact, before)
    # The rig's flanks image as squares: a 90° rotation cannot be seen, and the run says how it read them.
    from identify.film import orientation_checked

    assert not orientation_checked(read_films(read_campaign(camp))[1][0])
    note = next(n for n in summary["notes"] if "cannot be told from the imprint" in n)
    assert "joint_01_L.png" in note


def test_6_units_mixed_across_files_without_a_manifest_label(camp, capsys):
    doc = _manifest(camp)
    del doc["campaign"]["frf_units"]
    _write_manifest(camp, doc)
    path = camp / "blades" / "blade_02.uff"
    ema.write_frfs(path, ema.read_uff(path).with_form("accelerance"))
    _refused(camp, capsys, "blade_02.uff", "FRF units", "m/s/N")


def test_7_a_joint_without_its_d1b_test_gets_a_note(camp, store, tmp_path, capsys):
    doc = _manifest(camp)
    doc["tests"] = [t for t in doc["tests"] if not (t["type"] == "d1b" and t["joint"] == 2)]
    _write_manifest(camp, doc)
    out = tmp_path / "out"
    assert main([*RUN, str(camp), "--out", str(out), "--cache-dir", str(store)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert any("Joints [2]: no disk-one-blade test" in n for n in summary["notes"])
    assert "no disk-one-blade test" in (out / "report.html").read_text()


def test_8_a_film_of_a_joint_that_is_not_known(camp, capsys):
    doc = _manifest(camp)
    doc["campaign"]["known_joints"] = [1, 3]
    extra = dict(doc["films"][0], joint=2)
    extra["file"] = doc["films"][0]["file"]
    doc["films"].append(extra)
    _write_manifest(camp, doc)
    _refused(camp, capsys, "films[", "joint 2 is not in known_joints")


def test_11_an_unwritable_out_is_refused_before_any_computation(camp, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    capsys.readouterr()
    assert main(["run", str(camp), "--out", str(blocker / "sub"), "--cache-dir", str(tmp_path / "store")]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "is a file" in err and "Traceback" not in err
    assert not (tmp_path / "store").exists()  # nothing was computed
    if os.geteuid() != 0:  # root writes anywhere: the permission case needs an ordinary user
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
        assert main(["run", str(camp), "--out", str(ro), "--cache-dir", str(tmp_path / "store")]) == 2
        assert "cannot write" in capsys.readouterr().err


@pytest.mark.parametrize("rel", ["../outside.uff", "/etc/hostname"])
def test_13_paths_outside_the_campaign_need_allow_outside(camp, capsys, rel):
    outside = camp.parent / "outside.uff"
    shutil.copy(camp / "blades" / "blade_02.uff", outside)
    if rel.startswith("/") and not os.path.exists(rel):
        pytest.skip(f"{rel} does not exist here")
    doc = _manifest(camp)
    _test(doc, "blade", 2)["file"] = rel
    _write_manifest(camp, doc)
    _refused(camp, capsys, repr(rel), "outside the campaign folder", "--allow-outside")


def test_13_allow_outside_reads_the_file(camp):
    from bladetwin.campaign import CampaignError, read_campaign

    shutil.move(camp / "blades" / "blade_02.uff", camp.parent / "outside.uff")
    doc = _manifest(camp)
    _test(doc, "blade", 2)["file"] = "../outside.uff"
    _write_manifest(camp, doc)
    with pytest.raises(CampaignError, match="outside the campaign folder"):
        read_campaign(camp)
    c = read_campaign(camp, allow_outside=True)
    assert c.of_type("blade")[1].file == (camp.parent / "outside.uff").resolve()


def test_14_a_reused_out_keeps_no_figure_of_an_earlier_run(tmp_path):
    from bladetwin.out_dir import listed_files, remove_stale

    out = tmp_path / "out"
    out.mkdir()
    before = {"sections": [{"figures": [{"file": "full_B.png"}, {"file": "a.png"}], "tables": [{"file": "t.csv"}]}],
              "files": {"patterns": "p.npz"}}
    after = {"sections": [{"figures": [{"file": "a.png"}], "tables": [{"file": "t.csv"}]}], "files": {}}
    for name in ("full_B.png", "a.png", "t.csv", "p.npz", "mine.txt"):
        (out / name).write_text("x")
    assert remove_stale(out, before, after) == ["full_B.png", "p.npz"]
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "mine.txt", "t.csv"]  # the user's own file stays
    assert listed_files({"sections": [{"figures": [{"file": "../escape.png"}]}]}) == {"summary.json", "report.html"}


def test_15_lab_simulate_writes_a_campaign_run_accepts(tmp_path, capsys):
    capsys.readouterr()
    assert main(["lab", "simulate", "--level", "coarse", "--blades", "4", "--grid", "3x7", "--known", "1",
                 "--out", str(tmp_path / "one")]) == 2
    assert "at least 2" in capsys.readouterr().err
    assert not (tmp_path / "one").exists()


def test_15_generated_by_and_folder_mode(pristine):
    doc = _manifest(pristine)
    assert f"--out {pristine}" in doc["campaign"]["generated_by"]
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(pristine.stat().st_mode) == 0o777 & ~mask


@pytest.mark.parametrize("change, needles", [
    ({"contact_level": "high"}, ["films[0]", "contact_level = 'high'", "number"]),
    ({"contact_level": 300.0, "white": 235.0}, ["films[0]", "contact_level = 300.0", "white = 235.0"]),
    ({"pixel_size": None}, ["films[0]", "lacks pixel_size"]),
    ({"spacing": [1.0]}, ["films[0]", "spacing = [1.0]", "two numbers"]),
])
def test_12_film_metadata_errors_name_the_film_and_field(camp, capsys, change, needles):
    doc = _manifest(camp)
    film = doc["films"][0]
    for key, value in change.items():
        if value is None:
            film.pop(key, None)
        else:
            film[key] = value
    _write_manifest(camp, doc)
    _refused(camp, capsys, *needles)


@pytest.mark.parametrize("argv", [["run", "{camp}", "--seed", "-1"],
                                  ["lab", "simulate", "--out", "{tmp}/x", "--seed", "-1"]])
def test_12_a_negative_seed_names_its_flag(camp, tmp_path, capsys, argv):
    capsys.readouterr()
    assert main([a.format(camp=camp, tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert "--seed -1" in err and "Traceback" not in err


@pytest.mark.parametrize("argv, needle", [(["--components", "0"], "--components 0"),
                                          (["--components", "99"], "--components 99"),
                                          (["--scale", "-1"], "--scale -1"),
                                          (["--posterior-steps", "5"], "--posterior-steps 5"),
                                          (["--method", "bayes"], "--method")])
def test_12_bad_posterior_settings_are_refused_before_any_computation(camp, tmp_path, capsys, argv, needle):
    capsys.readouterr()
    try:
        code = main(["run", str(camp), *argv, "--out", str(tmp_path / "o"), "--cache-dir", str(tmp_path / "s")])
    except SystemExit as exc:  # argparse refuses an unknown choice itself, with its usage line
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip()
    errors = [line for line in err.splitlines() if "error:" in line]
    assert len(errors) == 1 and needle in errors[0] and "Traceback" not in err, err
    assert not (tmp_path / "s" / "nodes").exists()  # nothing computed
