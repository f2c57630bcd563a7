"""Fixtures for the EMA tests (the synthetic truth lives in :mod:`tests.ema.synth`)."""

from __future__ import annotations

import pytest

from .synth import PYUFF_DIR


@pytest.fixture(scope="session")
def pyuff_dir():
    if not PYUFF_DIR.is_dir():
        pytest.skip(f"shared test data not found at {PYUFF_DIR} (../shared/external/pyuff from the repo root)")
    return PYUFF_DIR
