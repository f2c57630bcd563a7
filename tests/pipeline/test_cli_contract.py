"""Command-line contract: every ``--json`` prints exactly one JSON document; every user error is one line, exit 2.

Issue 8 items 6–8. Runs through :func:`bladetwin.cli.main`, as a user would, on small inputs: the coarse
3×7 model, and a folder of synthetic UFF files.
"""

import argparse
import json

import numpy as np
import pytest

from bladetwin import cli_rom
from bladetwin.cli import build_parser, error_message, main
from ema import FRFSet, write_frfs
from tests.ema.synth import modal_frfs

MODEL = ["--level", "coarse", "--grid", "3x7"]
#: The ideal twin for the simulated campaign: these tests check the commands' output, not accuracy.
IDEAL = ["--realism", "ideal"]
ROM = [*MODEL, "--n-cb", "30", "--n-free", "15"]


def _json_commands() -> set[tuple[str, ...]]:
    """Every (sub)command path whose parser has a ``--json`` option."""
    found: set[tuple[str, ...]] = set()

    def walk(parser: argparse.ArgumentParser, path: tuple[str, ...]) -> None:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, (*path, name))
            elif "--json" in action.option_strings:
                found.add(path)

    walk(build_parser(), ())
    return found


@pytest.fixture(scope="module")
def uff_dir(tmp_path_factory):
    """Three 'blades', 6 outputs each, three modes near 150, 420, 700 Hz, 0.5 % damping."""
    d = tmp_path_factory.mktemp("campaign")
    rng = np.random.default_rng(9)
    freq = np.linspace(0, 1000, 2001)[1:]
    phi = rng.standard_normal((6, 3))
    phi[0] = np.abs(phi[0]) + 0.7
    for b in range(3):
        fn = np.array([150.0, 420.0, 700.0]) * (1 + 0.01 * rng.standard_normal(3))
        H = modal_frfs(freq, fn, np.full(3, 0.005), phi, phi[:1])
        write_frfs(d / f"blade{b}.uff", FRFSet(freq, H, [(k + 1, 3) for k in range(6)], [(1, 3)]))
    # disk and assembly merge their folder's files into one FRF matrix: give them one file.
    (d / "one").mkdir()
    (d / "one" / "test.uff").write_bytes((d / "blade0.uff").read_bytes())
    return d


def test_every_json_output_is_one_document(uff_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("BLADETWIN_CACHE", str(tmp_path / "cache"))
    ema_opts = ["--order", "30", "--band", "50", "950", "--json"]
    runs = {
        ("fe", "info"): ["fe", "info", *MODEL, "--json"],
        ("fe", "modes"): ["fe", "modes", *MODEL, "--n", "3", "--json"],
        ("rom", "build"): ["rom", "build", *ROM, "--json"],
        ("rom", "modes"): ["rom", "modes", *ROM, "--assembly", "d1b", "--n", "4", "--json"],
        ("rom", "validate"): ["rom", "validate", *ROM, "--parts", "blade", "--json"],
        ("ema", "fit"): ["ema", "fit", str(uff_dir / "blade0.uff"), *ema_opts],
        ("ema", "blades"): ["ema", "blades", str(uff_dir), "--out", str(tmp_path / "b"), *ema_opts],
        ("ema", "joints"): ["ema", "joints", str(uff_dir), "--out", str(tmp_path / "j"), *ema_opts],
        ("ema", "disk"): ["ema", "disk", str(uff_dir / "one"), "--out", str(tmp_path / "d"), *ema_opts],
        ("ema", "assembly"): ["ema", "assembly", str(uff_dir / "one"), "--out", str(tmp_path / "a"), *ema_opts],
        ("lab", "simulate"): ["lab", "simulate", *MODEL, *IDEAL, "--blades", "4", "--out", str(tmp_path / "lab"),
                              "--json"],
    }
    # The identification stages run on the campaign just simulated (4 blades, joints 2 and 3 filmed), each
    # reading the previous stage's file from the same output folder.
    ident = [str(tmp_path / "lab"), "--out", str(tmp_path / "id"), "--quiet", "--json"]
    runs[("identify", "patterns")] = ["identify", "patterns", *ident, "--n", "3"]
    runs[("identify", "sensitivity")] = ["identify", "sensitivity", *ident, "--no-plot"]
    runs[("identify", "dataset")] = ["identify", "dataset", *ident, "--step", "1.0"]
    runs[("identify", "predict")] = ["identify", "predict", *ident]
    runs[("identify", "validate")] = ["identify", "validate", *ident]
    runs[("run",)] = ["run", str(tmp_path / "lab"), "--out", str(tmp_path / "run"), "--n", "3", "--refine", "0",
                       "--rom", "paper", "--method", "knn", "--no-figures", "--quiet", "--json"]
    assert set(runs) == _json_commands(), "a command with --json is not covered by this test"
    for key, argv in runs.items():
        assert main(argv) == 0, key
        out = capsys.readouterr().out
        doc = json.loads(out)  # raises on two documents ("Extra data") or on text around the JSON
        assert isinstance(doc, dict) and doc, key
    # The campaign tables keep their names in the one document.
    main(runs[("ema", "blades")])
    doc = json.loads(capsys.readouterr().out)
    assert {"blade_frequencies", "blade_deltas"} <= set(doc)
    assert len(doc["blade_deltas"]["index"]) == 3


def _one_line_error(capsys, argv, *needles):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("bladetwin: error: "), err
    for n in needles:
        assert n in err, (n, err)
    return err


def test_plot_path_that_is_a_directory(uff_dir, tmp_path, capsys):
    _one_line_error(capsys, ["ema", "fit", str(uff_dir / "blade0.uff"), "--plot", str(tmp_path)], str(tmp_path),
                    "directory")


@pytest.mark.parametrize("content, needle", [
    ({"L": np.array([[1, 2, 1], [1, 1, 1]]), "R": np.ones((2, 3))}, "only 0/1), got 2"),
    ({"L": np.array([[1, -1, 1], [1, 1, 1]]), "R": np.ones((2, 3))}, "only 0/1), got -1"),
    ({"L": np.array([[1.0, np.nan, 1], [1, 1, 1]]), "R": np.ones((2, 3))}, "only 0/1), got nan"),
    ({"L": np.ones((2, 3)), "R": np.ones((3, 3))}, "share a shape"),
    ({"L": np.stack([np.ones((3, 7)), np.zeros((3, 7))]), "R": np.stack([np.ones((3, 7)), np.zeros((3, 7))])},
     "joint 2: contact pattern has no contact"),
])
def test_bad_pattern_files_name_the_file_and_fail_before_the_build(tmp_path, capsys, monkeypatch, content, needle):
    def no_build(*a, **k):
        raise AssertionError("the ROM was built before the pattern file was checked")

    monkeypatch.setattr(cli_rom, "build_roms", no_build)
    path = tmp_path / "bad.npz"
    np.savez(path, **content)
    _one_line_error(capsys, ["rom", "modes", *ROM, "--assembly", "d1b", "--pattern", str(path)], str(path), needle)


def test_damaged_pattern_and_delta_files_are_one_line_errors(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli_rom, "build_roms", lambda *a, **k: pytest.fail("built before the inputs were checked"))
    good = tmp_path / "good.npz"
    np.savez(good, L=np.ones((3, 7), bool), R=np.ones((3, 7), bool))
    cut = tmp_path / "cut.npz"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    binary = tmp_path / "binary.txt"
    binary.write_bytes(bytes(range(256)) * 4)
    wrong_grid = tmp_path / "grid.npz"
    np.savez(wrong_grid, L=np.ones((3, 5), bool), R=np.ones((3, 5), bool))
    base = ["rom", "modes", *ROM, "--assembly", "d1b"]
    _one_line_error(capsys, [*base, "--pattern", str(cut)], str(cut), "not a readable .npz")
    _one_line_error(capsys, [*base, "--pattern", str(binary)], str(binary), "not a text pattern file")
    _one_line_error(capsys, [*base, "--pattern", str(wrong_grid)], str(wrong_grid), "(3, 5)", "(3, 7)")
    _one_line_error(capsys, [*base, "--pattern", str(tmp_path)], str(tmp_path), "directory")
    bad_delta = tmp_path / "delta.csv"
    bad_delta.write_text("0.01,nan\n")
    _one_line_error(capsys, [*base, "--delta", str(bad_delta)], str(bad_delta), "finite")
    _one_line_error(capsys, [*base, "--delta", "-1.5"], "--delta", "> -1")
    _one_line_error(capsys, ["rom", "modes", *ROM, "--assembly", "full", "--delta", str(good)], str(good))


def test_error_message_is_one_line_without_repr_quotes():
    assert error_message(KeyError("no node set 'x'; available: ['a']")) == "no node set 'x'; available: ['a']"
    assert error_message(IsADirectoryError(21, "Is a directory", "out/x")) == "out/x: Is a directory"
    assert "\n" not in error_message(ValueError("two\nlines"))
    assert "--order" in error_message(MemoryError())
