"""Stage nodes on the measurements: the EMA of each test, and the blade table (Eq. 37)."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import ema
from ema.stabilization import StabilizationDiagram

__all__ = ["TestFit", "BladeTests", "test_key", "fit_test", "blade_table"]


@dataclass(frozen=True, eq=False)
class TestFit:
    """One test's EMA: its modal model, the fit quality per FRF, how its poles were chosen, its diagram.

    Attributes
    ----------
    model : ema.ModalModel
    fit_quality : ndarray, shape (n_outputs, n_inputs)
        1 − relative squared error of the synthesis over the band.
    method : str
        The pole estimator (``"lsrf"``, ``"lscf"``).
    picked : bool
        The poles came from the test's picks file.
    diagram : ema.StabilizationDiagram
        What the writer draws (the stage itself draws nothing).
    """

    model: ema.ModalModel
    fit_quality: np.ndarray
    method: str
    picked: bool
    diagram: StabilizationDiagram


@dataclass(frozen=True, eq=False)
class BladeTests:
    """EMA of the free blades: the tracked frequencies (Hz) and deltas (%, Eq. 37), shape (n_blades, k)."""

    models: dict
    frequencies_hz: np.ndarray
    deltas_pct: np.ndarray


def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_key(file: Path, picks: Path | None, max_order: int | None) -> str:
    """A test's identity for the store: its file's bytes, its picks file's bytes and its order override."""
    from rom.cache import hash_inputs

    return hash_inputs("test", _sha(file), _sha(picks) if picks is not None else "", max_order)


def fit_test(test) -> TestFit:
    """EMA of one test (a :class:`bladetwin.campaign.TestEntry`): its picks file, else automatic selection."""
    frf = ema.read_uff(test.file)
    if test.picks is not None:
        # the full assembly's picks may cover one family (notebooks/pick_poles.ipynb): the automatic fit gives
        # the modes outside their band; other tests' picks are the whole answer, as before
        elsewhere = {"max_order": test.max_order, "families": True} if test.type == "assembly" else None
        res = ema.fit_with_picks(frf, ema.load_picks(test.picks), elsewhere=elsewhere)
    else:
        # every test: the order from the data and the local LSRF check (ema.fit's defaults); a whole bladed disk's
        # blade families are dense: resolved by the structured fit and its residual scan (docs/ema.md). The scan's
        # noise model is the frequency-domain rig's: on a time-domain hammer test of a blade it grew 2 modes into
        # 11 (tests/ema/test_close_pairs.py's data), so it stays on the full assembly alone
        res = ema.fit(frf, max_order=test.max_order, families=test.type == "assembly")
    return TestFit(res.model, np.asarray(res.quality, float), res.diagram.method, test.picks is not None, res.diagram)


def blade_table(**fits: TestFit) -> BladeTests:
    """Blade frequencies and deltas (Eq. 37, modes tracked by MAC) from every blade test's EMA, by test name."""
    models = {name: fits[name].model for name in sorted(fits, key=lambda n: int(n.rsplit("_", 1)[1]))}
    return BladeTests(models, ema.campaign.frequency_table(models).to_numpy(), ema.blade_deltas(models).to_numpy())
