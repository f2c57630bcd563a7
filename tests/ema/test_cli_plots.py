"""Command line (bladetwin ema ...) and plots (Agg backend)."""

from __future__ import annotations

import argparse
import json

import matplotlib
import numpy as np
import pytest

from bladetwin import cli_ema
from ema import FitSettings, FRFSet, ModalModel, fit, write_frfs
from ema.plots import plot_frf_fit, plot_mac, plot_stabilization

from .synth import FN, ZETA, synthetic_case

matplotlib.use("Agg")


def _run(argv):
    parser = argparse.ArgumentParser(prog="bladetwin")
    sub = parser.add_subparsers(dest="command")
    cli_ema.register(sub)
    args = parser.parse_args(argv)
    return args.func(args)


@pytest.fixture(scope="module")
def uff_file(tmp_path_factory):
    freq, H, _ = synthetic_case("accelerance")
    frf = FRFSet(freq, H, [(k + 1, 3) for k in range(H.shape[0])], [(1, 3)], form="accelerance")
    path = tmp_path_factory.mktemp("cli") / "synthetic.uff"
    write_frfs(path, frf)
    return path, frf


def test_fit_json(uff_file, capsys, tmp_path):
    png = tmp_path / "stab.png"
    rc = _run(["ema", "fit", str(uff_file[0]), "--method", "lscf", "--band", "20", "980", "--order", "60",
               "--auto", "--json", "--plot", str(png)])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "lscf" and out["band_hz"] == [20.0, 980.0]
    found = np.array([m["frequency_hz"] for m in out["modes"]])
    assert found.size == FN.size and np.allclose(found, FN, rtol=5e-4)
    assert all("damping_ratio" in m for m in out["modes"])
    assert png.stat().st_size > 0


def test_fit_bands_json(uff_file, capsys):
    """--bands: band-by-band LSRF, merged; the JSON names the local method and the full band."""
    rc = _run(["ema", "fit", str(uff_file[0]), "--method", "lsrf", "--band", "20", "980", "--order", "40",
               "--bands", "3", "--auto", "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "lsrf/local" and out["band_hz"] == [20.0, 980.0]
    found = np.array([m["frequency_hz"] for m in out["modes"]])
    zeta = np.array([m["damping_ratio"] for m in out["modes"]])
    assert found.size == FN.size and np.allclose(found, FN, rtol=5e-4)
    assert np.max(np.abs(zeta - ZETA) / ZETA) < 0.10
    assert out["fit_quality"]["min"] > 0.99


def test_fit_table_and_freqs(uff_file, capsys):
    rc = _run(["ema", "fit", str(uff_file[0]), "--method", "lsrf", "--band", "20", "980", "--order", "60",
               "--freqs", "350", "780"])
    assert rc == 0
    text = capsys.readouterr().out
    rows = [line.split() for line in text.splitlines() if line.strip()[:1].isdigit()]
    found = np.array([float(r[1]) for r in rows])
    assert np.allclose(found, [350.0, 780.0], rtol=1e-3)


def test_blades_command(tmp_path, capsys):
    rng = np.random.default_rng(9)
    freq = np.linspace(0, 1000, 2001)[1:]
    phi = rng.standard_normal((6, 3))
    phi[0] = np.abs(phi[0]) + 0.7
    truth = []
    for b in range(3):
        fn = np.array([150.0, 420.0, 700.0]) * (1 + 0.01 * rng.standard_normal(3))
        truth.append(fn)
        w, wn = 2 * np.pi * freq, 2 * np.pi * fn
        H = np.einsum("or,r,rf->of", phi, phi[0], 1 / (wn[:, None] ** 2 - w**2 + 2j * 0.005 * wn[:, None] * w))
        write_frfs(tmp_path / f"blade{b}.uff", FRFSet(freq, H[:, None], [(k, 3) for k in range(6)], [(0, 3)]))
    out = tmp_path / "out"
    assert _run(["ema", "blades", str(tmp_path), "--order", "30", "--band", "50", "950", "--out", str(out)]) == 0
    truth = np.array(truth)
    expected = (truth**2 - (truth**2).mean(0)) / (truth**2).mean(0) * 100
    import pandas as pd

    table = pd.read_csv(out / "blade_deltas.csv", index_col=0)
    np.testing.assert_allclose(table.to_numpy(), expected, atol=0.05)


def test_errors_are_value_errors(tmp_path):
    bad = tmp_path / "bad.uff"
    bad.write_text("nothing here\n")
    with pytest.raises(ValueError):
        _run(["ema", "fit", str(bad)])
    with pytest.raises(FileNotFoundError):
        _run(["ema", "disk", str(tmp_path / "nope")])


def test_plots_only_read(uff_file):
    _, frf = uff_file
    result = fit(frf, (20, 980), FitSettings(method="lscf", refine=False), max_order=40)
    fig = plot_stabilization(result.diagram, frf, selected_hz=result.model.frequencies_hz)
    assert fig.axes
    fig = plot_stabilization(result.diagram, frf, indicator="cmif")
    fig = plot_mac(np.eye(3) * 0.9 + 0.05)
    fig = plot_frf_fit(frf, result.model, output=2)
    assert len(fig.axes[0].lines) >= 2
    assert isinstance(result.model, ModalModel)
