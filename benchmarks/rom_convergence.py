"""Convergence study of the Craig–Bampton disk: free-disk and disk–one-blade errors vs n_k (docs/rom.md).

Run: ``.venv/bin/python benchmarks/rom_convergence.py [--level default] [--nk 25 50 75 100 150 200]``.
One CB reduction with the largest n_k is truncated to the smaller ones (the CB basis is nested).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import _paths  # noqa: F401  (benchmarks/rom.py would shadow the rom package)
import numpy as np

from rom.academic import AcademicParams, build_bladed_disk
from rom.craig_bampton import reduce_disk
from rom.fe_assembly import assemble_fe, solve_fe
from rom.rom_assembly import solve_d1b
from rom.rubin import reduce_blade
from rom.solver import solve_modes
from rom.validation import compare, one_flank_pattern, random_patterns


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--level", default="default")
    ap.add_argument("--grid", default=None, help="rows,cols (default: the level's default 7,31)")
    ap.add_argument("--nk", type=int, nargs="+", default=[25, 50, 75, 100, 150, 200])
    ap.add_argument("--json", default=None, help="write results to this JSON file")
    args = ap.parse_args(argv)
    kw = {"level": args.level}
    if args.grid:
        kw["grid"] = tuple(int(x) for x in args.grid.split(","))
    bd = build_bladed_disk(AcademicParams(**kw))
    grid = bd.params.grid
    t = time.perf_counter()
    fe_disk = solve_modes(bd.disk.K, bd.disk.M, 20)
    print(f"FE free disk 20 modes: {time.perf_counter() - t:.1f} s", file=sys.stderr)
    rng = np.random.default_rng(3)
    pats = {"all": None, "30%": random_patterns(grid, [1], rng, (0.3, 0.3))[1], "one flank": one_flank_pattern(grid)}
    from rom.contact import ContactPattern

    pats["all"] = ContactPattern.full(grid)
    fe_d1b = {}
    for name, p in pats.items():
        t = time.perf_counter()
        fe_d1b[name] = solve_fe(assemble_fe(bd, {1: p}), 10)
        print(f"FE d1b {name}: {time.perf_counter() - t:.1f} s", file=sys.stderr)
    blade = reduce_blade(bd)
    t = time.perf_counter()
    cb_max = reduce_disk(bd, (1,), max(args.nk))
    print(f"CB n_k={max(args.nk)}: {time.perf_counter() - t:.1f} s", file=sys.stderr)
    rows = []
    for nk in sorted(args.nk):
        cb = cb_max.truncated(nk)
        e_disk = cb.free_modes(20).frequencies_hz / fe_disk.frequencies_hz - 1
        row = {"n_k": nk, "disk_max_rel_err": float(np.abs(e_disk).max()), "disk_min_rel_err": float(e_disk.min())}
        for name, p in pats.items():
            for form in ("exact", "paper"):
                c = compare(name, fe_d1b[name], solve_d1b(cb, blade, p, formulation=form, n_modes=10), 10,
                            by_mac=False)
                row[f"d1b[{name}/{form}]"] = {"max_rel_err": c.max_rel_err, "min_mac": c.min_mac}
        rows.append(row)
        print(json.dumps(row))
    if args.json:
        from rom.fileio import atomic_path

        with atomic_path(args.json) as tmp, open(tmp, "w") as fh:
            json.dump({"level": args.level, "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
