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


#: Seconds each long test file took on a fresh clone (2 cores, ``-n auto --dist loadfile``, pytest's durations
#: summed per file; the walkthrough notebook's after its smaller parameters). Only the order of the files uses
#: them: pytest-xdist hands out whole files in collection order (``make test`` turns off its reordering by test
#: count), and the longest first lets the short ones fill the gaps, instead of one worker starting a 90-second
#: file while the other runs out of work. A stale figure costs time, never a result.
_FILE_SECONDS = {
    "tests/pipeline/test_run.py": 187,
    "tests/pipeline/test_one_path.py": 104,
    "tests/lab/test_campaign.py": 70,
    "tests/pipeline/test_index_compare.py": 69,
    "tests/pipeline/test_interrupt.py": 68,
    "tests/pipeline/test_notebooks.py": 56,
    "tests/pipeline/test_cli_contract.py": 49,
    "tests/pipeline/test_run_imported.py": 43,
    "tests/rom/test_solver.py": 31,
    "tests/rom/test_rom_full.py": 31,
    "tests/identify/test_posterior.py": 28,
    "tests/ema/test_family_cyclic.py": 27,
    "tests/pipeline/test_campaign_init.py": 26,
    "tests/rom/test_importers.py": 26,
    "tests/pipeline/test_campaign_faults.py": 26,
    "tests/pipeline/test_calibration_stage.py": 21,
    "tests/identify/test_dataset_parts.py": 21,
    "tests/pipeline/test_response.py": 21,
    "tests/pipeline/test_cli_fe_import.py": 18,
    "tests/rom/test_rom_cyclic.py": 17,
    "tests/ema/test_family.py": 17,
    "tests/pipeline/test_cli_fe.py": 13,
    "tests/identify/test_plots.py": 13,
}


def pytest_collection_modifyitems(config, items) -> None:
    """Run the long files first (see :data:`_FILE_SECONDS`); the order within a file is kept."""
    # node ids start with the file's path from the root folder (the repository's, where pyproject.toml is);
    # the sort is stable, so files stay whole and in their own order
    items.sort(key=lambda item: -_FILE_SECONDS.get(item.nodeid.split("::")[0], 0))
