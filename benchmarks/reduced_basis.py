"""Certified reduced basis of the disk–one-blade ROM on contact springs (issue 46, item 1) against direct solves.

Builds the affine spring model (``rom.spring_assembly``) and its reduced basis (``rom.reduced_basis``) at the
truth twin's joint stiffness (1e14 N/m³ normal, 0.7 of it tangential), then on held-out patterns (another
seed than the training's):

* **time per RB evaluation**: ``evaluate`` on the whole batch with no tolerance (every answer from the basis),
  divided by the batch size, against the median of one direct d1b solve measured in the same run: the
  pipeline's (``solve_d1b`` of the blade with the springs' compliance) and the spring model's own;
* **accuracy**: the certified bound and the true error of every Ritz frequency against the spring model's
  direct solve (10 modes), and how many true errors exceed their bound (the direct solver's own scatter,
  ~1e-7 at the default level, counts as slack);
* **fallbacks**: ``evaluate`` at the tolerance with the pipeline's solve as the fallback; share and time.

Target (issue 46): an RB evaluation ≥ 100× faster than a direct solve, bounds ≤ 5e-5.

Run: ``.venv/bin/python benchmarks/reduced_basis.py [--level default] [--json out.json]`` (default level: a few
minutes; its disk model comes from the ROM cache).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import _paths  # noqa: F401  (benchmarks/rom.py would shadow the rom package)
import numpy as np

N_TRAIN = {"coarse": 30, "default": 110}


def _median_time(fn, items) -> float:
    times = []
    for it in items:
        t = time.perf_counter()
        fn(it)
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--level", default="default", choices=["coarse", "default"])
    ap.add_argument("--n-train", type=int, default=None, help="training patterns (default: 30 coarse, 110 default)")
    ap.add_argument("--rank", type=int, default=None, help="basis size r (default: from the POD's tolerance)")
    ap.add_argument("--n-test", type=int, default=200)
    ap.add_argument("--tol", type=float, default=5e-5)
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the figures to this JSON file")
    args = ap.parse_args(argv)

    from rom import cache
    from rom.academic import AcademicParams, build_bladed_disk
    from rom.contact_stiffness import (
        ContactStiffness,
        blade_compliance_parts,
        interface_compliance,
        with_contact_stiffness,
    )
    from rom.fileio import atomic_path
    from rom.modal import single_thread_blas
    from rom.reduced_basis import evaluate, plausible_patterns, reduce_spring_d1b
    from rom.rom_assembly import solve_d1b
    from rom.spring_assembly import solve_spring_d1b, spring_d1b

    bd = build_bladed_disk(AcademicParams(level=args.level))
    disk, blade = cache.cached_reduce_disk(bd, (1,)), cache.cached_reduce_blade(bd)
    parts, stiff = blade_compliance_parts(bd.blade), ContactStiffness(1e14, 7e13)
    sprung = with_contact_stiffness(blade, interface_compliance(parts, stiff))
    t = time.perf_counter()
    model = spring_d1b(disk, blade, parts, stiff)
    model_s = time.perf_counter() - t
    n_train = N_TRAIN[args.level] if args.n_train is None else args.n_train
    t = time.perf_counter()
    rb = reduce_spring_d1b(model, n_train=n_train, rank=args.rank, seed=1)
    build_s = time.perf_counter() - t
    print(f"{args.level}: spring model n = {model.n} ({model_s:.1f} s); basis r = {rb.r} from {n_train} training "
          f"patterns in {build_s:.1f} s", flush=True)

    test = plausible_patterns(model.grid, args.n_test, seed=99)
    evaluate(rb, test[:5], 10, tol=np.inf)  # warm-up (BLAS, first touch)
    t = time.perf_counter()
    res = evaluate(rb, test, 10, tol=np.inf)
    rb_s = (time.perf_counter() - t) / len(test)
    compliance = lambda p, d=None, n=10: solve_d1b(disk, sprung, p, n_modes=n, delta=d)  # noqa: E731
    direct_s = _median_time(compliance, test[:10])
    with single_thread_blas():
        t = time.perf_counter()
        ref = np.array([solve_spring_d1b(model, p, 10).frequencies_hz for p in test])
        primal_s = (time.perf_counter() - t) / len(test)
    err = np.abs(res.frequencies_hz / ref - 1)
    t = time.perf_counter()
    tol_res = evaluate(rb, test, 10, tol=args.tol, solver=compliance)
    tol_s = (time.perf_counter() - t) / len(test)

    figures = {
        "level": args.level, "n": model.n, "r": rb.r, "n_train": n_train, "n_test": len(test), "tol": args.tol,
        "spring_model_build_s": model_s, "rb_build_s": build_s,
        "rb_eval_s": rb_s, "direct_d1b_solve_s": direct_s, "direct_spring_solve_s": primal_s,
        "speedup_vs_d1b": direct_s / rb_s, "speedup_vs_spring": primal_s / rb_s,
        "bound_max": float(res.bound.max()), "bound_median": float(np.median(res.bound)),
        "true_error_max": float(err.max()), "true_error_median": float(np.median(err)),
        "errors_above_bound": int(np.sum(err > res.bound + 1e-7)),
        "fallback_share": float(tol_res.fallback.mean()), "eval_with_fallbacks_s": tol_s,
    }
    figures["target_met"] = bool(figures["speedup_vs_d1b"] >= 100 and figures["fallback_share"] == 0)
    print(f"time per RB evaluation (batch of {len(test)}): {1e3 * rb_s:.2f} ms; direct d1b solve "
          f"{1e3 * direct_s:.1f} ms (ratio {direct_s / rb_s:.1f}), spring model's direct solve {1e3 * primal_s:.1f} ms "
          f"(ratio {primal_s / rb_s:.1f})")
    print(f"bound: max {figures['bound_max']:.2e}, median {figures['bound_median']:.2e}; true error: max "
          f"{figures['true_error_max']:.2e}, median {figures['true_error_median']:.2e}; "
          f"{figures['errors_above_bound']} above their bound (+1e-7)")
    print(f"at tol {args.tol:g}: {100 * figures['fallback_share']:.1f} % fallbacks, {1e3 * tol_s:.1f} ms per pattern")
    print(f"target ≥ 100× faster with every bound ≤ {args.tol:g}: {'met' if figures['target_met'] else 'NOT met'}")
    if args.json:
        with atomic_path(args.json) as tmp, open(tmp, "w") as fh:
            json.dump(figures, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
