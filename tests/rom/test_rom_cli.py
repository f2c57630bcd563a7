"""``bladetwin rom`` commands on the coarse model (cache in a temporary folder)."""

import argparse
import json

import numpy as np
import pytest

from bladetwin import cli_rom
from rom.contact import ContactPattern
from rom.pattern_io import save_patterns


def _run(argv, capsys):
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command")
    cli_rom.register(sub)
    args = parser.parse_args(argv)
    rc = args.func(args)
    return rc, capsys.readouterr().out


COMMON = ["--level", "coarse", "--grid", "3x7", "--n-cb", "40", "--n-free", "20"]


def test_build_modes_and_validate(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("BLADETWIN_CACHE", str(tmp_path / "cache"))
    rc, out = _run(["rom", "build", *COMMON, "--json"], capsys)
    assert rc == 0 and json.loads(out)["disk_cb"]["n_k"] == 40
    assert len(list((tmp_path / "cache").glob("*.npz"))) == 2

    pat = ContactPattern(np.ones((3, 7), bool), np.eye(3, 7, dtype=bool))
    save_patterns(tmp_path / "p.npz", [pat])
    rc, out = _run(["rom", "modes", *COMMON, "--assembly", "d1b", "--slot", "4", "--pattern", str(tmp_path / "p.npz"),
                    "--delta", "0.01", "-0.005", "--json"], capsys)
    res = json.loads(out)
    assert rc == 0 and len(res["frequencies_hz"]) == 10
    assert res["meas_labels"][-1] == ["blade", 4, 3, 1]

    rc, out = _run(["rom", "validate", *COMMON, "--parts", "blade", "d1b", "--json"], capsys)
    res = json.loads(out)
    assert rc == 0 and {"blade", "d1b"} <= set(res)
    assert res["d1b"]["max_rel_err"] < 0.01 and res["d1b"]["min_mac"] > 0.99


def test_bad_delta_and_pattern_arguments(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("BLADETWIN_CACHE", str(tmp_path / "cache"))
    with pytest.raises(ValueError, match="--delta takes numbers"):
        cli_rom.parse_delta(["abc"], 18, "d1b", 50)
    with pytest.raises(FileNotFoundError):
        _run(["rom", "modes", *COMMON, "--assembly", "d1b", "--pattern", str(tmp_path / "none.npz")], capsys)
    d = cli_rom.parse_delta(["0.01", "0.02"], 18, "full", 50)
    assert d.shape == (18, 50) and np.all(d[:, :2] == [0.01, 0.02]) and not d[:, 2:].any()
