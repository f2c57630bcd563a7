"""``bladetwin run``'s forked disk builds: they finish, and build the same models as this process would.

The one-slot CB disk and the cyclic all-slot CB build in forked processes while the EMA runs (design §8.17).
A child forked after its parent has run MKL's OpenMP thread team (any earlier Pardiso factorization there, as
in a test session or a notebook) waited forever in its own threaded Pardiso factorization, which hung the test
suite. The children now run on one BLAS thread. The check runs in a subprocess under a timeout, so a
regression fails here instead of hanging the suite.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from rom.academic import AcademicParams, build_bladed_disk
from rom.cache import cache_file, cached_reduce_disk, cached_reduce_disk_cyclic, cyclic_disk_key, disk_key
from rom.craig_bampton import reduce_disk
from rom.cyclic import reduce_disk_cyclic

PARAMS = dict(level="coarse", grid=(3, 7), n_blades=6)

SCRIPT = textwrap.dedent(f"""
    import sys
    from pathlib import Path

    from rom.academic import AcademicParams, build_bladed_disk
    from rom.cache import cyclic_disk_key, disk_key
    from rom.craig_bampton import reduce_disk
    from bladetwin import run

    bd = build_bladed_disk(AcademicParams(**{PARAMS!r}))
    reduce_disk(bd, (1,), 20)  # Pardiso in the parent first: MKL's OpenMP team now exists
    run._MODELS["bd"] = bd
    bg = run._Background(2, print, processes=2)
    assert bg.pool is not None, "no fork here"
    key = disk_key(bd)
    bg.submit(run._disk_job, ("cb", Path(sys.argv[1]), True, key), "Craig–Bampton disk built")
    bg.submit(run._disk_job, ("cyclic", Path(sys.argv[1]), True, cyclic_disk_key(bd, base_key=key)), "cyclic built")
    bg.wait()
""")


@pytest.mark.skipif(sys.platform == "win32", reason="no fork")
def test_disks_build_in_forked_processes_after_the_parent_ran_pardiso(tmp_path):
    try:
        done = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True,
                              timeout=300)
    except subprocess.TimeoutExpired:
        pytest.fail("the forked disk builds did not finish in 300 s (they take seconds): the MKL fork hang is back")
    assert done.returncode == 0, done.stderr[-2000:]
    # The child's model (read back from the cache) is this process's, to round-off: one BLAS thread there,
    # MKL's default here.
    bd = build_bladed_disk(AcademicParams(**PARAMS))
    assert cache_file("disk-cb", disk_key(bd), tmp_path).is_file()  # read back, not rebuilt here
    forked = cached_reduce_disk(bd, (1,), cache_dir=tmp_path)
    here = reduce_disk(bd, (1,))
    np.testing.assert_allclose(forked.Lambda, here.Lambda, rtol=1e-9)
    np.testing.assert_allclose(forked.kappa_bb, here.kappa_bb, rtol=1e-9, atol=1e-9 * np.abs(here.kappa_bb).max())
    assert cache_file("disk-cyclic", cyclic_disk_key(bd), tmp_path).is_file()
    forked_c = cached_reduce_disk_cyclic(bd, cache_dir=tmp_path)
    here_c = reduce_disk_cyclic(bd)
    np.testing.assert_allclose(forked_c.Lambda, here_c.Lambda, rtol=1e-9)
    np.testing.assert_allclose(forked_c.kappa_col, here_c.kappa_col, rtol=1e-9,
                               atol=1e-9 * np.abs(here_c.kappa_col).max())


def test_the_refinement_solve_memo_round_trips_and_reads_damage_as_absent(tmp_path):
    """The forked searches share their solves through a folder: atomic entries; a damaged one is solved again."""
    from bladetwin.run import _SolveMemo

    memo = _SolveMemo(tmp_path / "solves")
    assert memo.get("a" * 32) is None  # nothing yet, not even the folder
    f = np.array([101.5, 202.25, 303.125])
    memo["a" * 32] = f
    np.testing.assert_array_equal(memo.get("a" * 32), f)
    assert [p.name for p in (tmp_path / "solves").iterdir()] == ["a" * 32 + ".npy"]  # no temporary left
    (tmp_path / "solves" / ("b" * 32 + ".npy")).write_bytes(b"\x93NUMPY truncated")
    assert memo.get("b" * 32) is None
    (tmp_path / "solves" / ("c" * 32 + ".npy")).write_bytes(b"")
    assert memo.get("c" * 32) is None
