"""The runner's forked workers: they finish, and build the same models as this process would.

The one-slot CB disk and the cyclic all-slot CB build on the runner's forked workers (design §8.17).
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
from rom.craig_bampton import reduce_disk
from rom.cyclic import reduce_disk_cyclic

PARAMS = dict(level="coarse", grid=(3, 7), n_blades=6)

SCRIPT = textwrap.dedent(f"""
    import sys

    from rom.academic import AcademicParams, build_bladed_disk
    from rom.craig_bampton import reduce_disk
    from bladetwin.stages import Node, Pipeline, Runner, Source, Store
    from bladetwin.stages.models import reduce_disk_all_slots, reduce_disk_cb

    bd = build_bladed_disk(AcademicParams(**{PARAMS!r}))
    reduce_disk(bd, (1,), 20)  # Pardiso in the parent first: MKL's OpenMP team now exists
    p = Pipeline([Node("cb", reduce_disk_cb, {{"bd": "bd"}}), Node("cyclic", reduce_disk_all_slots, {{"bd": "bd"}})])
    runner = Runner(Store(sys.argv[1]), 2, print)
    runner.run(p, ["cb", "cyclic"], {{"bd": Source(bd, "coarse")}})
    assert sorted(runner.computed) == ["cb", "cyclic"], runner.computed
""")


@pytest.mark.skipif(sys.platform == "win32", reason="no fork")
def test_disks_build_in_forked_processes_after_the_parent_ran_pardiso(tmp_path):
    try:
        done = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True,
                              timeout=300)
    except subprocess.TimeoutExpired:
        pytest.fail("the forked disk builds did not finish in 300 s (they take seconds): the MKL fork hang is back")
    assert done.returncode == 0, done.stderr[-2000:]
    # The workers' models (read back from the store) are this process's, to round-off: one BLAS thread there,
    # MKL's default here.
    from bladetwin.stages import codec

    bd = build_bladed_disk(AcademicParams(**PARAMS))
    (cb_file,) = (tmp_path / "nodes" / "reduce_disk_cb").glob("*.npz")
    (cyclic_file,) = (tmp_path / "nodes" / "reduce_disk_all_slots").glob("*.npz")
    forked, here = codec.load(cb_file), reduce_disk(bd, (1,))
    np.testing.assert_allclose(forked.Lambda, here.Lambda, rtol=1e-9)
    np.testing.assert_allclose(forked.kappa_bb, here.kappa_bb, rtol=1e-9, atol=1e-9 * np.abs(here.kappa_bb).max())
    forked_c, here_c = codec.load(cyclic_file).model, reduce_disk_cyclic(bd)
    np.testing.assert_allclose(forked_c.Lambda, here_c.Lambda, rtol=1e-9)
    np.testing.assert_allclose(forked_c.kappa_col, here_c.kappa_col, rtol=1e-9,
                               atol=1e-9 * np.abs(here_c.kappa_col).max())


def test_the_refinement_solve_memo_round_trips_and_reads_damage_as_absent(tmp_path):
    """The forked searches share their solves through a folder: atomic entries; a damaged one is solved again."""
    from bladetwin.stages import Store

    memo = Store(tmp_path).memo("solves")
    assert memo.get("a" * 32) is None  # nothing yet, not even the folder
    f = np.array([101.5, 202.25, 303.125])
    memo["a" * 32] = f
    np.testing.assert_array_equal(memo.get("a" * 32), f)
    folder = tmp_path / "memo" / "solves"
    assert [p.name for p in folder.iterdir()] == ["a" * 32 + ".npy"]  # no temporary left
    (folder / ("b" * 32 + ".npy")).write_bytes(b"\x93NUMPY truncated")
    assert memo.get("b" * 32) is None
    (folder / ("c" * 32 + ".npy")).write_bytes(b"")
    assert memo.get("c" * 32) is None
