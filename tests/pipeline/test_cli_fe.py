"""The ``bladetwin fe`` and ``bladetwin run`` commands: JSON contracts, files, errors, help."""

import json

import numpy as np
import pytest

from bladetwin.cli import main

SMALL = ["--level", "coarse", "--grid", "3x7"]


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_fe_info_json_contract(capsys):
    info = _json(capsys, ["fe", "info", *SMALL, "--json"])
    assert set(info["disk"]) >= {"n_dof", "n_nodes", "n_slots", "grid"}
    assert set(info["blade"]) >= {"n_dof", "n_nodes"}
    assert info["disk"]["n_slots"] == 18 and info["disk"]["grid"] == [3, 7]
    assert info["disk"]["n_dof"] == 3 * info["disk"]["n_nodes"]
    assert info["max_interface_gap_m"] <= 1e-9


def test_fe_modes_disk_json_contract(capsys):
    out = _json(capsys, ["fe", "modes", "--component", "disk", *SMALL, "--n", "6", "--json"])
    assert len(out["frequencies_hz"]) == 6 and out["n_rigid"] == 6
    assert len(out["nodal_diameters"]) == 6
    assert out["nodal_diameters"][:3] == [2, 2, 0]
    assert np.all(np.diff(out["frequencies_hz"]) >= 0)


def test_fe_modes_d1b_and_blade_have_no_nodal_diameters(capsys):
    for comp in ("blade", "d1b"):
        out = _json(capsys, ["fe", "modes", "--component", comp, *SMALL, "--n", "3", "--json"])
        assert "nodal_diameters" not in out and out["n_rigid"] == 6 and len(out["frequencies_hz"]) == 3


def test_fe_plot_writes_png(tmp_path, capsys):
    out = tmp_path / "sub" / "mesh.png"
    assert main(["fe", "plot", *SMALL, "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.parent.glob(".*tmp"))  # atomic write leaves no temporary file


def test_fe_demo(tmp_path, capsys):
    assert main(["fe", "demo", *SMALL, "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "FE demo" in text and "Table 1" in text and "Table 3" in text
    summary = json.loads((tmp_path / "fe_demo.json").read_text())
    assert summary["disk_table1"][0][3] == pytest.approx(1090.6, rel=1e-6)  # calibrated first mode
    assert (tmp_path / "mesh.png").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["fe", "info", "--grid", "7x30"], "grid[1]"),
        (["fe", "info", "--grid", "seven"], "ROWSxCOLS"),
        (["fe", "modes", *SMALL, "--n", "0"], "--n"),
    ],
)
def test_bad_input_is_one_clear_line(capsys, argv, message):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("bladetwin: error:") and message in err[-1]


@pytest.mark.parametrize("argv", [[], ["fe"], ["fe", "info"], ["fe", "modes"], ["fe", "plot"], ["fe", "demo"], ["run"],
                                  ["report"]])
def test_help_everywhere(capsys, argv):
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--help"])
    assert exc.value.code == 0
    assert "usage: bladetwin" in capsys.readouterr().out


def test_fe_modes_calibrate_puts_the_first_disk_mode_at_table1(capsys):
    raw = _json(capsys, ["fe", "modes", "--component", "disk", *SMALL, "--n", "4", "--json"])
    cal = _json(capsys, ["fe", "modes", "--component", "disk", *SMALL, "--n", "4", "--calibrate", "--json"])
    assert cal["frequencies_hz"][0] == pytest.approx(1090.6, rel=1e-9)
    # Calibrating E scales every frequency of the homogeneous disk by one factor.
    ratio = np.array(cal["frequencies_hz"]) / np.array(raw["frequencies_hz"])
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-8)
    d1b = _json(capsys, ["fe", "modes", "--component", "d1b", *SMALL, "--n", "2", "--calibrate", "--json"])
    assert len(d1b["frequencies_hz"]) == 2
