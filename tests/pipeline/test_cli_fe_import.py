"""``bladetwin fe export`` and ``bladetwin fe info|modes --import`` (issue 13 items 4 and 5).

References: the twin's own ``fe info``/``fe modes`` output, the frequencies ansys-mapdl-reader documents for its
example ``file.full``, and the exported files parsed by the standard library (tomllib, csv).
"""

import builtins
import csv
import json
import tomllib

import pytest

from bladetwin.cli import main

SMALL = ["--level", "coarse", "--grid", "3x5"]


def _json(capsys, argv):
    assert main(argv) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


def _error(capsys, argv, *needles):
    """Exit code 2 and one error line, after progress lines at most (no traceback)."""
    assert main(argv) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[-1].startswith("bladetwin: error: "), lines
    assert all(line.startswith(("… ", "  done")) for line in lines[:-1]), lines
    for n in needles:
        assert n in lines[-1], (n, lines[-1])


@pytest.fixture(scope="module")
def export_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("mtx")
    assert main(["fe", "export", "--format", "mtx", "--out", str(d), *SMALL]) == 0
    return d


def _blade(d):
    return ["--import", str(d / "blade_K.mtx"), "--mass", str(d / "blade_M.mtx"), "--dofmap",
            str(d / "blade_dofmap.csv"), "--coords", str(d / "blade_coords.csv"), "--node-sets",
            str(d / "blade_node_sets.csv")]


def test_fe_export_writes_every_file_the_model_table_names(export_dir):
    doc = tomllib.loads((export_dir / "model.toml").read_text())
    m = doc["model"]
    assert m["format"] == "mtx" and m["units"] == "SI"
    assert m["placement"]["n_slots"] == 18 and len(m["placement"]["angles_deg"]) == 18
    assert m["placement"]["angles_deg"][:4] == [0, 20, 40, 60] and m["placement"]["axis"] == [0, 0, -1]
    assert m["grids"]["shape"] == [3, 5] and m["placement"]["cyclic"] is True
    for key in ("disk", "blade"):
        for field in ("K", "M", "dofmap", "coords", "node_sets"):
            assert (export_dir / m[key][field]).is_file(), (key, field)
    assert (export_dir / m["grids"]["file"]).is_file()
    with open(export_dir / "grids.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == (18 + 1) * 2 * 3 * 5  # every slot and the blade, both flanks, 3 × 5 nodes
    assert not list(export_dir.glob(".*tmp"))  # atomic writes leave nothing behind


def test_fe_info_import_json(capsys, export_dir):
    twin = _json(capsys, ["fe", "info", *SMALL, "--json"])
    info = _json(capsys, ["fe", "info", *_blade(export_dir), "--json"])
    assert info["n_dof"] == twin["blade"]["n_dof"] and info["n_nodes"] == twin["blade"]["n_nodes"]
    assert info["component"] == "blade" and info["format"] == "mtx" and info["units"] == "SI"
    assert info["node_sets"] == {"L": 15, "R": 15, "meas": 3}
    assert info["n_constrained_dofs"] == 0 and "warnings" not in info
    lo, hi = info["bounding_box_m"]
    assert hi[1] - lo[1] == pytest.approx(0.206 - 0.0885, abs=2e-3)  # blade length along local y


def test_fe_modes_import_matches_the_twin(capsys, export_dir):
    ref = _json(capsys, ["fe", "modes", "--component", "blade", *SMALL, "--n", "5", "--json"])
    out = _json(capsys, ["fe", "modes", *_blade(export_dir), "--n", "5", "--json"])
    assert set(out) >= {"frequencies_hz", "n_rigid", "n_dof"} and out["n_rigid"] == ref["n_rigid"] == 6
    assert out["n_dof"] == ref["n_dof"]
    assert out["frequencies_hz"] == pytest.approx(ref["frequencies_hz"], rel=1e-9)


def test_fe_export_op4_and_import_disk(capsys, tmp_path):
    assert main(["fe", "export", "--format", "op4", "--out", str(tmp_path), *SMALL]) == 0
    capsys.readouterr()
    ref = _json(capsys, ["fe", "modes", "--component", "disk", *SMALL, "--n", "4", "--json"])
    out = _json(capsys, ["fe", "modes", "--import", str(tmp_path / "disk.op4"), "--dofmap",
                         str(tmp_path / "disk_dofmap.csv"), "--matrices", "KAA,MAA", "--n", "4", "--json"])
    assert out["frequencies_hz"] == pytest.approx(ref["frequencies_hz"], rel=1e-9)


def test_fe_export_op4_text(capsys, tmp_path):
    assert main(["fe", "export", "--format", "op4", "--out", str(tmp_path), *SMALL, "--text"]) == 0
    capsys.readouterr()
    head = (tmp_path / "blade.op4").read_text().splitlines()[0]
    assert head[32:40].strip() == "KAA" and head.endswith("1P,3E23.16")  # a text OP4 header line
    ref = _json(capsys, ["fe", "modes", "--component", "blade", *SMALL, "--n", "3", "--json"])
    out = _json(capsys, ["fe", "modes", "--import", str(tmp_path / "blade.op4"), "--dofmap",
                         str(tmp_path / "blade_dofmap.csv"), "--n", "3", "--json"])
    assert out["frequencies_hz"] == pytest.approx(ref["frequencies_hz"], rel=1e-9)


def test_fe_import_ansys_full(capsys):
    pytest.importorskip("ansys.mapdl.reader")
    from ansys.mapdl.reader import examples

    out = _json(capsys, ["fe", "modes", "--import", examples.fullfile, "--archive", examples.hexarchivefile,
                         "--units", "in-lbf-s", "--n", "4", "--json"])
    assert out["frequencies_hz"] == pytest.approx([1283.20036921, 1283.20036921, 5781.97486169, 6919.39887714],
                                                  rel=1e-6)
    assert out["n_rigid"] == 0 and out["n_dof"] == 963
    info = _json(capsys, ["fe", "info", "--import", examples.fullfile, "--json"])
    assert info["n_constrained_dofs"] == 63 and info["bounding_box_m"] is None and info["format"] == "full"


def test_wrong_units_warn_in_one_line_and_in_the_json(capsys, export_dir):
    assert main(["fe", "info", *_blade(export_dir), "--units", "mm-t-s", "--json"]) == 0
    cap = capsys.readouterr()
    info = json.loads(cap.out)
    warn = [line for line in cap.err.splitlines() if line.startswith("bladetwin: warning:")]
    assert len(warn) == 1 and "units assumed were mm-t-s" in warn[0] and "kg" in warn[0]
    assert info["warnings"] and info["units"] == "mm-t-s"


def test_import_errors_are_one_line(capsys, export_dir, tmp_path, monkeypatch):
    d = export_dir
    _error(capsys, ["fe", "info", "--import", str(d / "blade_K.mtx"), "--dofmap", str(d / "blade_dofmap.csv")],
           "blade_K.mtx", "mass matrix")
    _error(capsys, ["fe", "info", *SMALL, "--dofmap", "x.csv"], "--dofmap", "only apply with --import")
    _error(capsys, ["fe", "modes", *_blade(d), "--component", "disk"], "not with --import")
    _error(capsys, ["fe", "info", *_blade(d), "--units", "furlong"], "units must be one of", "furlong")
    _error(capsys, ["fe", "info", "--import", str(tmp_path / "nothere.mtx"), "--mass", str(tmp_path / "m.mtx"),
                    "--dofmap", "x.csv"], "nothere.mtx")
    bad = tmp_path / "dofmap.csv"
    bad.write_text("\n".join((d / "blade_dofmap.csv").read_text().splitlines()[:-1]) + "\n")
    argv = _blade(d)
    argv[argv.index("--dofmap") + 1] = str(bad)
    _error(capsys, ["fe", "info", *argv], str(bad), "does not cover the matrix")

    real_import = builtins.__import__

    def no_ansys(name, *args, **kwargs):
        if name.startswith("ansys"):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ansys)
    _error(capsys, ["fe", "info", "--import", str(tmp_path / "disk.full")], "disk.full",
           'pip install "bladetwin[ansys]"')


def test_fe_export_help(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["fe", "export", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "--format" in out and "--out" in out and "--text" in out
