"""Shared fixtures: small model variants so the suite stays fast (the full default runs in benchmarks)."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")


def _share_the_cores_between_workers() -> None:
    """Under pytest-xdist, give each worker its share of the cores for BLAS, LAPACK and MKL.

    Two workers with a BLAS thread per core each oversubscribe a 2-core machine, and OpenBLAS's spinning threads
    then slowed numerics-heavy tests 3–4× (tests/ema/test_family.py, tests/rom/test_modal.py and
    tests/rom/test_solver.py with ``-n 2``: 66–95 s, against 22–25 s with one thread per worker). The environment
    reaches processes the tests spawn; threadpoolctl limits the libraries this process has loaded already.
    """
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers <= 1:
        return
    threads = max(1, (os.cpu_count() or 1) // workers)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, str(threads))
    from threadpoolctl import threadpool_limits

    threadpool_limits(threads)


_share_the_cores_between_workers()

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
