"""Resumable dataset builds in Parquet parts (issue 12): in process, on a 2-worker Dask LocalCluster, and killed
(SIGKILL) mid-build then resumed, all give the table of the serial ``build_dataset``, bit for bit.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from identify.dataset_build import build_dataset
from identify.dataset_parts import MANIFEST, build_dataset_parts
from identify.errors import IdentifyError

from ..rom.rom_models import blade, disk_cb

REPO = Path(__file__).resolve().parents[2]
GRID = (3, 7)
DELTA_GRID = [-0.005, 0.0, 0.01]
N_SIDE = 5  # 25 pattern pairs: long enough to be killed in the middle


def patterns(seed: int = 11):
    rng = np.random.default_rng(seed)
    PL = rng.random((N_SIDE, *GRID)) < 0.6
    PR = rng.random((N_SIDE, *GRID)) < 0.6
    PL[:, 0, 0] = PR[:, 0, 0] = True  # never an empty flank
    return PL, PR


# The child loads the parent's reduced models from files: a reduction recomputed in another process may differ
# in the last bits (threaded BLAS), which would make it another model, hence another build.
SCRIPT = f"""
import sys
sys.path.insert(0, {str(REPO)!r})
from tests.identify.test_dataset_parts import patterns, DELTA_GRID
from identify.dataset_parts import build_dataset_parts
from rom.cache import load_model
PL, PR = patterns()
build_dataset_parts(load_model(sys.argv[2]), load_model(sys.argv[3]), PL, PR, DELTA_GRID, sys.argv[1])
"""


def _same(a, b) -> None:
    assert np.array_equal(a.frequencies_hz, b.frequencies_hz)
    assert np.array_equal(a.error_bound, b.error_bound, equal_nan=True)
    assert np.array_equal(a.fallback, b.fallback) and np.array_equal(a.mac_min, b.mac_min)
    assert np.array_equal(a.deltas, b.deltas) and np.array_equal(a.pair, b.pair)
    assert a.feature_modes == b.feature_modes and np.array_equal(a.weights, b.weights)


@pytest.fixture(scope="module")
def serial():
    PL, PR = patterns()
    return build_dataset(disk_cb(), blade(), PL, PR, DELTA_GRID, progress=False)


def test_in_process_parts_equal_the_serial_build_and_a_rerun_reads_them(serial, tmp_path):
    PL, PR = patterns()
    folder = tmp_path / "a"
    ds = build_dataset_parts(disk_cb(), blade(), PL, PR, DELTA_GRID, folder)
    _same(ds, serial)
    assert len(list(folder.glob("part-*.parquet"))) == N_SIDE**2 and (folder / MANIFEST).is_file()
    said = []
    again = build_dataset_parts(disk_cb(), blade(), PL, PR, DELTA_GRID, folder, say=said.append)
    _same(again, serial)
    assert "0 to compute" in said[0]
    # a different build (another δ grid) may not mix its parts with these
    with pytest.raises(IdentifyError, match="another dataset build"):
        build_dataset_parts(disk_cb(), blade(), PL, PR, [0.0, 0.01], folder)


def test_a_two_worker_local_cluster_gives_the_same_table(serial, tmp_path):
    pytest.importorskip("distributed")
    PL, PR = patterns()
    ds = build_dataset_parts(disk_cb(), blade(), PL, PR, DELTA_GRID, tmp_path / "b", workers=2)
    _same(ds, serial)


def test_a_build_killed_mid_way_resumes_without_recomputing_finished_parts(serial, tmp_path):
    from rom.cache import save_model

    folder = tmp_path / "c"
    models = [str(save_model(tmp_path / name, m)) for name, m in (("disk.npz", disk_cb()), ("blade.npz", blade()))]
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(folder), *models], cwd=REPO,
                            env={**os.environ, "MPLBACKEND": "Agg"})
    try:
        deadline = time.monotonic() + 240
        while not list(folder.glob("part-*.parquet")):
            assert proc.poll() is None, "the build ended before writing a part"
            assert time.monotonic() < deadline, "no part written in time"
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    finished = {p.name: p.stat().st_mtime_ns for p in folder.glob("part-*.parquet")}
    assert 0 < len(finished) < N_SIDE**2, len(finished)  # killed in the middle
    PL, PR = patterns()
    said = []
    ds = build_dataset_parts(disk_cb(), blade(), PL, PR, DELTA_GRID, folder, say=said.append)
    assert f"{len(finished)} pairs already in" in said[0]
    _same(ds, serial)
    # the finished parts were read, not recomputed
    assert all(folder.joinpath(n).stat().st_mtime_ns == t for n, t in finished.items())


def test_parts_cleared_by_a_concurrent_build_are_computed_again(serial, tmp_path, monkeypatch):
    """Two campaigns of one disk share a dataset's parts folder; the build that finishes first clears it. A part
    that vanishes between this build's listing and its reading is computed again, not reported as damaged."""
    import pyarrow.parquet as pq

    PL, PR = patterns()
    folder = tmp_path / "shared"
    build_dataset_parts(disk_cb(), blade(), PL, PR, DELTA_GRID, folder)   # every part on disk
    real = pq.read_table

    def cleared_first(path, *args, **kwargs):     # the other build's rmtree lands after the listing
        Path(path).unlink(missing_ok=True)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(pq, "read_table", cleared_first)
    said = []
    ds = build_dataset_parts(disk_cb(), blade(), PL, PR, DELTA_GRID, folder, say=said.append)
    assert f"0 pairs already in {folder}, {N_SIDE**2} to compute" in said[0]
    _same(ds, serial)


def test_two_dataset_nodes_of_one_grid_keep_apart_so_one_s_cleanup_leaves_the_other_s_parts(tmp_path):
    """A re-assembly's two campaigns share the model and the δ grid, not their blades' δ: two dataset nodes that
    run side by side. The one that finishes first removes its parts folder; the other's, half written, stays."""
    from types import SimpleNamespace

    from bladetwin.stages.dataset import DaskSettings, dataset_node, parts_key
    from bladetwin.stages.store import Store
    from identify.delta_grid import grid_from_deltas

    PL, PR = patterns()
    synthetic = SimpleNamespace(L=PL[:2], R=PR[:2])
    store = Store(tmp_path / "store")
    first = np.zeros((3, blade().m))
    first[:, 0] = [-0.004, 0.0, 0.008]
    second = first + 1e-5  # another test of the same blades: the same grid (rounded outward to 0.5 %)
    kw = {"n_features": 3, "n_delta_modes": 3, "step_pct": 0.5}
    grids = [grid_from_deltas(d[:, :3], step=0.005, n_delta_modes=3) for d in (first, second)]
    assert all(np.array_equal(a, b) for a, b in zip(*grids, strict=True))
    other = store.memo(f"dataset-parts-{parts_key(disk_cb(), blade(), synthetic, second, grids[1], 3, 3)}").folder
    other.mkdir(parents=True)
    (other / "part-L0000-R0000.parquet").write_bytes(b"the other node's part")
    ds = dataset_node(disk_cb(), blade(), synthetic, first, None, store, DaskSettings(), **kw)
    assert ds.frequencies_hz.shape[0] > 0
    assert (other / "part-L0000-R0000.parquet").read_bytes() == b"the other node's part"
