"""Reduced models shared by the ROM tests (built once per test session; coarse 3×7 academic disk).

Not a test module: the ``test_*`` files import it. Models depend only on the ``coarse_bd`` fixture's
parameters, so they are memoised on those.
"""

from __future__ import annotations

from functools import cache

from rom.academic import AcademicParams, build_bladed_disk
from rom.craig_bampton import DEFAULT_N_CB_MODES, reduce_disk
from rom.rubin import DEFAULT_N_FREE_MODES, reduce_blade

COARSE = AcademicParams(level="coarse", grid=(3, 7))


@cache
def bladed_disk(n_blades: int = 18):
    return build_bladed_disk(COARSE.with_(n_blades=n_blades))


@cache
def disk_cb(n_blades: int = 18, slots: tuple[int, ...] = (1,), n_modes: int = DEFAULT_N_CB_MODES, keep_basis=False):
    return reduce_disk(bladed_disk(n_blades), slots, n_modes, keep_basis=keep_basis)


@cache
def blade(n_blades: int = 18, n_modes: int = DEFAULT_N_FREE_MODES, keep_basis: bool = True):
    return reduce_blade(bladed_disk(n_blades), n_modes, keep_basis=keep_basis)
