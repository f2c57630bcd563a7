"""Atomic output (``rom.fileio`` and its floor-1 twin ``ema.fileio``): all or nothing, normal permissions."""

import os
import stat

import pytest

import ema.fileio
import rom.fileio


@pytest.mark.parametrize("mod", [rom.fileio, ema.fileio], ids=["rom", "ema"])
def test_atomic_path_all_or_nothing(tmp_path, mod):
    target = tmp_path / "sub" / "table.csv"
    with mod.atomic_path(target) as tmp:
        tmp.write_text("new")
        assert not target.exists()  # nothing visible until the block succeeds
    assert target.read_text() == "new"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
    with pytest.raises(RuntimeError), mod.atomic_path(target) as tmp:
        tmp.write_text("half-written")
        raise RuntimeError("writer failed")
    assert target.read_text() == "new"  # the old file survives a failed write
    assert sorted(p.name for p in target.parent.iterdir()) == ["table.csv"]  # no temporary left behind
