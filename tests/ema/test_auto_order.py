"""The model order chosen from the data (ema.fit_auto_order) against known modal models (issue 31, item 2)."""

from __future__ import annotations

import numpy as np
import pytest

from bladetwin.cli import main
from ema import EMAError, FitSettings, FRFSet, fit, fit_auto_order, write_frfs

from .synth import modal_frfs
from .test_close_modes import FN, N_OUT, close_truth

TOL = 5e-4  # 0.05 %


def _close(seed: int) -> FRFSet:
    """The close-modes truth (10 modes, pairs 0.3 % and 0.2 % apart), 1 % noise, 0.25 Hz lines."""
    zeta, phi = close_truth(seed)
    freq = 0.25 * np.arange(1, 4001)
    H = modal_frfs(freq, FN, zeta, phi, phi[:1], "receptance")
    rng = np.random.default_rng(seed + 100)
    H = H + 0.01 * np.abs(H) * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    outputs = [(k + 1, 3) for k in range(N_OUT)]
    return FRFSet(freq, H, outputs, outputs[:1], form="receptance")


def _found(model, truth) -> int:
    return sum(bool(np.any(np.abs(model.frequencies_hz / f - 1) < TOL)) for f in truth)


def test_the_order_grows_until_close_pairs_are_resolved():
    frf = _close(3)  # a seed where order 40 merges modes: a fixed order that suits other data fails here
    fixed = FitSettings(method="lscf", grow=False, split=False)
    assert _found(fit(frf, settings=fixed, max_order=40).model, FN) < FN.size
    result, order = fit_auto_order(frf, settings=FitSettings(method="lscf", split=False))  # the ladder alone
    assert _found(result.model, FN) == FN.size and result.model.n_modes == FN.size
    assert order > 40 and order in (20 * 2 ** k for k in range(6))


def test_a_sparse_spectrum_keeps_a_low_order():
    fn, zeta = np.array([150.0, 420.0, 760.0]), np.array([0.01, 0.005, 0.008])
    freq = 0.25 * np.arange(1, 4001)
    phi = np.array([[1.0, 0.8, 1.2], [0.5, -0.9, 0.7]])
    H = modal_frfs(freq, fn, zeta, phi, phi[:1], "receptance")
    H = H + 0.01 * np.abs(H) * (np.random.default_rng(1).standard_normal(H.shape)) / np.sqrt(2)
    result, order = fit_auto_order(FRFSet(freq, H, [(1, 3), (2, 3)], [(1, 3)], form="receptance"),
                                   settings=FitSettings(method="lscf"))
    assert _found(result.model, fn) == fn.size and order <= 40


def test_ladder_settings_are_checked():
    frf = _close(3)
    for kwargs, needle in (({"start": 1}, "start"), ({"factor": 1}, "factor"), ({"max_order": 60}, "max_order")):
        with pytest.raises(EMAError, match=needle):
            fit_auto_order(frf, **kwargs)


def test_cli_order_auto_says_which_order_it_chose(tmp_path, capsys):
    path = tmp_path / "close.uff"
    write_frfs(path, _close(3))
    assert main(["ema", "fit", str(path), "--method", "lscf", "--order", "auto", "--auto"]) == 0
    out, err = capsys.readouterr()
    assert "model order chosen from the data:" in err and "10 modes" in out
    with pytest.raises(SystemExit) as exc:
        main(["ema", "fit", str(path), "--order", "many"])
    assert exc.value.code == 2 and "expected an integer ≥ 2 or 'auto'" in capsys.readouterr().err
