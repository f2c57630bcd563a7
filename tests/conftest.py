"""Shared fixtures: small model variants so the suite stays fast (the full default runs in benchmarks)."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"../shared not found at {SHARED}: real-data tests need the shared folder beside the repo")
    return SHARED


@pytest.fixture(scope="session")
def coarse_bd():
    """Coarse academic bladed disk with a 3×7 contact grid (disk ≈ 12k DOF)."""
    from rom.academic import AcademicParams, build_bladed_disk

    return build_bladed_disk(AcademicParams(level="coarse", grid=(3, 7)))
