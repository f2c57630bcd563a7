"""Benchmark: one virtual hammer test in the time domain (lab.hammer.hammer_test), wall time on one core.

A synthetic free–free structure: ``--modes`` elastic modes spread from 0.05 to 1.3 × f_max, 6 rigid-body
modes, ``--outputs`` laser points and ``--inputs`` hammer points, ``--lines`` lines of ``--df`` Hz from df,
default settings (5 averages). Target (issue: hammer test): 72 × 6 × 3500 lines, 80 modes in well under 20 s.

Usage: ``python benchmarks/hammer.py [--df 1.0] [--lines 3500] [--modes 80] [--json out.json]``
"""

from __future__ import annotations

import argparse
import json
import os
import time

import _paths  # noqa: F401  (benchmarks/rom.py would shadow the rom package)

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--df", type=float, default=1.0)
    ap.add_argument("--lines", type=int, default=3500)
    ap.add_argument("--modes", type=int, default=80)
    ap.add_argument("--outputs", type=int, default=72)
    ap.add_argument("--inputs", type=int, default=6)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()

    import numpy as np

    from lab.hammer import HammerSettings, analyser_grid, hammer_test
    from lab.rig import RigSetup, measure
    from rom.fe_assembly import AssemblyModes

    rng = np.random.default_rng(0)
    setup = RigSetup((args.df, args.df * args.lines), args.df)
    f_max = setup.band_hz[1]
    freq = np.sort(rng.uniform(0.05, 1.3, args.modes)) * f_max
    shapes = rng.standard_normal((args.outputs, args.modes)) * 0.3
    rigid = rng.standard_normal((args.outputs, 6)) * 0.1
    labels = [("blade", 1, p + 1, 1) for p in range(args.outputs)]
    modes = AssemblyModes(freq, shapes, labels, rigid_shapes=rigid)
    zeta = np.full(args.modes, 0.002)
    grid = analyser_grid(setup, HammerSettings())
    times = []
    for r in range(args.repeat):
        t0 = time.perf_counter()
        res = hammer_test(modes, zeta, setup, np.random.default_rng(r), inputs=range(args.inputs))
        times.append(time.perf_counter() - t0)
    # Reference in the same run: the frequency-domain rig (lab.rig.measure) on the same modes and lines.
    ref = []
    for r in range(args.repeat):
        t0 = time.perf_counter()
        measure(modes, zeta, setup, np.random.default_rng(r), inputs=range(args.inputs))
        ref.append(time.perf_counter() - t0)
    out = dict(outputs=args.outputs, inputs=args.inputs, lines=res.frf.n_freq, modes=args.modes, df_hz=args.df,
               f_max_hz=f_max, analyser_samples=grid.n_samples, simulation_factor=grid.factor,
               seconds=min(times), all_seconds=times, reference="lab.rig.measure (frequency domain)",
               reference_seconds=min(ref), ratio_to_reference=min(times) / min(ref))
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
