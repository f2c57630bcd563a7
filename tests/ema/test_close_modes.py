"""Close modes and band edges: automatic selection against a known modal model (issue 8, item 10).

The truth imitates a mistuned bladed disk seen by one driving point and three more response points: 10
modes in 0-1000 Hz on 0.25 Hz lines, receptance, 1 % proportional noise, damping 0.15-1 % drawn at random.
Two mistuned pairs with orthogonal shapes (a sine and a cosine pattern, as on a disk) sit 0.3 % and 0.2 %
apart, i.e. 0.9 and 1.1 Hz, closer than most of their half-power bandwidths (up to 11 Hz). An isolated
mode sits 60 Hz above the first line, and user bands are chosen so that other modes sit 60 Hz inside
their edges with a close pair just outside.

Automatic selection must return both members of each pair and every isolated mode within 0.05 %, with
LSCF and with LSRF, through the library and through ``bladetwin ema fit --auto``, whatever band is
picked. The seed is one of twelve checked by hand (all twelve pass); in this one the weaker
member of the 290 Hz pair has a plain dominance of 0.57, under the 0.7 at which ``fit`` drops patches.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ema import FitSettings, FRFSet, fit, mac, write_frfs
from ema.lsfd import dominance
from ema.selection import cluster_poles
from ema.stabilization import STABLE_FD

from .synth import modal_frfs

SEED = 4
FN = np.array([60.0, 175.0, 290.0, 290.0 * 1.003, 420.0, 560.0, 560.0 * 1.002, 700.0, 830.0, 935.0])
PAIRS = [(2, 3), (5, 6)]
ISOLATED = [0, 1, 4, 7, 8, 9]
TOL = 5e-4  # 0.05 %
N_OUT = 4


def close_truth(seed: int = SEED) -> tuple[np.ndarray, np.ndarray]:
    """Damping ratios (n_modes,) and shapes (N_OUT, n_modes); the first row is the driving point."""
    rng = np.random.default_rng(seed)
    zeta = rng.uniform(0.0015, 0.01, FN.size)
    while True:
        phi = rng.standard_normal((N_OUT, FN.size))
        for a, b in PAIRS:  # a mistuned pair: orthogonal shapes of equal norm
            phi[:, b] -= phi[:, a] * (phi[:, a] @ phi[:, b]) / (phi[:, a] @ phi[:, a])
            phi[:, b] *= np.linalg.norm(phi[:, a]) / np.linalg.norm(phi[:, b])
        if np.all(np.abs(phi[0]) > 0.3):  # the driving point sees every mode
            return zeta, phi * np.sign(phi[0])


@pytest.fixture(scope="module")
def close():
    zeta, phi = close_truth()
    rng = np.random.default_rng(SEED + 1000)
    freq = 0.25 * np.arange(1, 4001)
    H = modal_frfs(freq, FN, zeta, phi, phi[:1], "receptance")
    H = H + 0.01 * np.abs(H) * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    outputs = [(k + 1, 3) for k in range(N_OUT)]
    return FRFSet(freq, H, outputs, outputs[:1], form="receptance"), zeta, phi


@pytest.fixture(scope="module")
def uff(close, tmp_path_factory):
    path = tmp_path_factory.mktemp("close") / "close_modes.uff"
    write_frfs(path, close[0])
    return path


def _errors(found: np.ndarray, fn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Relative error of the nearest found mode for each true one, and the found modes matching none."""
    err = np.array([np.min(np.abs(found - f)) / f for f in fn]) if found.size else np.full(fn.size, np.inf)
    extra = np.array([f for f in found if np.min(np.abs(fn - f) / fn) > TOL])
    return err, extra


def _check(found: np.ndarray, fn: np.ndarray) -> None:
    err, extra = _errors(np.asarray(found, float), fn)
    assert not extra.size, f"spurious modes {np.round(extra, 2)}"
    assert found.size == fn.size, f"found {np.round(found, 2)}"
    assert np.max(err) < TOL, f"errors in % at {np.round(fn, 2)}: {np.round(100 * err, 4)}"


def test_truth_has_close_pairs_and_an_edge_mode(close):
    frf, zeta, phi = close
    rel = [(FN[b] - FN[a]) / FN[a] for a, b in PAIRS]
    np.testing.assert_allclose(rel, [0.003, 0.002])
    assert 0.0015 <= zeta.min() and zeta.max() <= 0.01
    # each pair is closer than the sum of its half-power half-widths: one peak for both in every FRF
    for a, b in PAIRS:
        assert FN[b] - FN[a] < zeta[a] * FN[a] + zeta[b] * FN[b]
        assert mac(phi[:, a], phi[:, b])[0, 0] < 1e-20
    assert FN[0] - frf.freq_hz[0] == pytest.approx(60.0, abs=0.5)


@pytest.mark.parametrize("method", ["lscf", "lsrf"])
def test_auto_selection_separates_close_pairs(close, method):
    frf, zeta, phi = close
    result = fit(frf, settings=FitSettings(method=method), max_order=60)
    m = result.model
    _check(m.frequencies_hz, FN)
    np.testing.assert_allclose(m.damping_ratio, zeta, rtol=0.05)
    assert np.min(np.diag(mac(m.shapes, phi))) > 0.99
    assert not result.dropped_hz
    # the weaker member of the 290 Hz pair is covered by its partner at every response point: the plain
    # dominance calls it a patch; the dominance fit uses tells the pair apart by shape
    assert dominance(frf, m)[2] < 0.7 <= result.dominance[2]


@pytest.mark.parametrize("method", ["lscf", "lsrf"])
def test_cli_fit_auto_separates_close_pairs(uff, method, capsys):
    from bladetwin.cli import main

    assert main(["ema", "fit", str(uff), "--method", method, "--auto", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    _check(np.array([rec["frequency_hz"] for rec in out["modes"]]), FN)


@pytest.mark.parametrize("method", ["lscf", "lsrf"])
@pytest.mark.parametrize("band", [(360.0, 1000.0), (115.0, 640.0)])
def test_band_edges_do_not_decide_the_answer(close, method, band):
    """420 Hz (or 175 Hz) sits 60 Hz above the band start with the 290 Hz pair (or the 60 Hz mode) just
    below it; the other edge cuts between modes. Every mode of the band keeps its 0.05 %."""
    frf, _, _ = close
    result = fit(frf, band, FitSettings(method=method), max_order=60)
    assert result.diagram.band_hz == band and result.model.band_hz == band
    inside = FN[(FN >= band[0]) & (FN <= band[1])]
    assert np.min(inside) - band[0] == pytest.approx(60.0)
    _check(result.model.frequencies_hz, inside)
    assert np.all((result.diagram.frequencies_hz >= band[0]) & (result.diagram.frequencies_hz <= band[1]))
    assert np.all((result.selection.frequencies_hz >= band[0]) & (result.selection.frequencies_hz <= band[1]))


def test_no_cluster_holds_two_poles_of_one_order(close):
    frf, _, _ = close
    diagram = fit(frf, settings=FitSettings(refine=False), max_order=60).diagram
    idx, label = cluster_poles(diagram, STABLE_FD)
    for k in range(int(label.max()) + 1):
        orders = diagram.order[idx[label == k]]
        assert np.unique(orders).size == orders.size
    # both members of each pair are stable (f+d) at most high orders: the stabilization compares each pole
    # with the previous-order pole that matches it in frequency and vector, not with the nearer partner
    for a, b in PAIRS:
        for f in (FN[a], FN[b]):
            near = (np.abs(diagram.frequencies_hz - f) / f < 3e-4) & (diagram.order >= 40)
            stable = near & (diagram.stability >= STABLE_FD)
            assert np.unique(diagram.order[stable]).size >= 0.8 * 21, f"{f:.2f} Hz"


def test_clusters_do_not_depend_on_the_pair_block_size(close, monkeypatch):
    """``cluster_poles`` computes the candidate pairs' MACs in blocks to bound memory (the bundled
    full-assembly test took 19 GB in one block): blocks of a few pairs give exactly the clusters of one block."""
    import ema.selection as selection

    frf, _, _ = close
    diagram = fit(frf, settings=FitSettings(refine=False), max_order=60).diagram
    whole = cluster_poles(diagram, STABLE_FD)
    monkeypatch.setattr(selection, "_PAIR_BLOCK_ENTRIES", 3 * diagram.vector.shape[1])  # 3 pairs per block
    blocked = cluster_poles(diagram, STABLE_FD)
    assert whole[0].size > 10
    np.testing.assert_array_equal(whole[0], blocked[0])
    np.testing.assert_array_equal(whole[1], blocked[1])
