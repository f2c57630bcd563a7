"""Dataset benchmark: build time, accuracy and memory of the reanalysis dataset against direct solves (issue 10).

Builds the paper's dataset (§6.3) on the academic twin: 10 × 10 synthetic pattern pairs (PCA sampler of
:mod:`identify.sampler` fed with smooth, similar "known" film maps, fixed seed) and a δ grid of 6 values
for 3 blade modes, made by :func:`identify.delta_grid.grid_from_deltas` from fixed-seed "measured" deltas in
[−0.5 %, 2 %]: 6 × 6 × 6 × 100 = 21,600 samples. In the same run it times the reference, one direct
disk–one-blade solve per sample (:func:`rom.solve_d1b`: assembly with δ, then the dense eigen-solve), on
``--n-direct`` random samples, and extrapolates it to the whole dataset. Every checked sample's stored
frequencies are compared with the direct ones (each stored frequency against the nearest of the direct
solve's ``n_modes + n_extra`` frequencies; the tests check the tracking itself).

Reduced models come from the cache (:mod:`rom.cache`, default folder); a first run at the default level
builds them (minutes). Peak memory is ``ru_maxrss`` of this process; the FE model built to find the cache
entries is part of it, and ``baseline_rss_gb`` is the peak before the dataset build.

Run::

    .venv/bin/python benchmarks/dataset.py [--level default] [--n-direct 50] [--json out.json]

Targets (default level): every stored frequency within 0.01 % of the direct solve; ≥ 100× faster than
direct; ≤ 60 s; peak memory ≤ 4 GB.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import _paths  # noqa: F401  (must precede the package imports)
import numpy as np


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2  # Linux: kB


def known_maps(grid: tuple[int, int], n_known: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth, similar grayscale "film" maps in [0, 1], shape (n_known, rows, cols).

    A shared imprint (contact strongest towards the top of the slot and the middle of the thickness) plus
    a smooth random field per joint, as the paper's slot-to-slot similarity (§3).
    """
    from scipy.ndimage import gaussian_filter

    rows, cols = grid
    u = np.linspace(-1, 1, rows)[:, None]
    v = np.linspace(0, 1, cols)[None, :]
    base = 0.55 + 0.35 * v - 0.25 * u**2
    out = np.empty((n_known, rows, cols))
    for k in range(n_known):
        noise = gaussian_filter(rng.standard_normal(grid), sigma=(max(rows / 5, 0.7), max(cols / 6, 0.7)),
                                mode="nearest")
        out[k] = np.clip(base + 0.8 * noise / max(noise.std(), 1e-12) * 0.25, 0.0, 1.0)
    return out


def check_against_direct(ds, disk, blade, pats, picks) -> tuple[list[float], list[float]]:
    """Time (s) of a direct ``rom.solve_d1b`` of each picked sample, and the largest relative difference of
    its stored frequencies from the nearest direct ones (the tests check the tracking itself)."""
    from rom import ContactPattern, solve_d1b

    n_cand = ds.frequencies_hz.shape[1] + int(ds.meta["n_extra"])
    times, errs = [], []
    for s in picks:
        i_L, i_R = ds.pair[s]
        t = time.perf_counter()
        ref = solve_d1b(disk, blade, ContactPattern(pats.L[i_L], pats.R[i_R]), n_modes=n_cand, delta=ds.deltas[s])
        times.append(time.perf_counter() - t)
        f = ds.frequencies_hz[s]
        near = ref.frequencies_hz[np.argmin(np.abs(f[:, None] - ref.frequencies_hz[None, :]), axis=1)]
        errs.append(float(np.abs(f / near - 1).max()))
    return times, errs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--level", default="default", choices=["coarse", "default", "fine"])
    ap.add_argument("--n-patterns", type=int, default=10, help="synthetic patterns per flank (default 10)")
    ap.add_argument("--n-direct", type=int, default=50, help="samples checked against direct solves (default 50)")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--cache-dir", default=None, help="reduced-model cache (default: rom.cache.default_cache_dir())")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    args = ap.parse_args(argv)

    from identify.dataset_build import build_dataset
    from identify.delta_grid import grid_from_deltas
    from identify.synthetic import sample_patterns
    from rom import ContactPattern, solve_d1b
    from rom.academic import AcademicParams, build_bladed_disk
    from rom.cache import cached_reduce_blade, cached_reduce_disk

    rng = np.random.default_rng(args.seed)
    t = time.perf_counter()
    bd = build_bladed_disk(AcademicParams(level=args.level))
    disk = cached_reduce_disk(bd, (1,), cache_dir=args.cache_dir)
    blade = cached_reduce_blade(bd, cache_dir=args.cache_dir)
    grid, n_blades = bd.params.grid, bd.n_slots
    del bd  # only the reduced models are needed from here on
    t_models = time.perf_counter() - t
    pats = sample_patterns(known_maps(grid, 5, rng), known_maps(grid, 5, rng), n_patterns=args.n_patterns,
                           random_state=args.seed)
    measured = rng.uniform(-0.005, 0.02, (n_blades, 11))
    measured[0, :3], measured[1, :3] = -0.005, 0.02  # the paper's span (§6.3): 6 values of 0.5 %
    delta_grid = grid_from_deltas(measured, step=0.005, n_delta_modes=3)
    base_gb = _peak_gb()

    t = time.perf_counter()
    ds = build_dataset(disk, blade, pats.L, pats.R, delta_grid, progress=not args.no_progress)
    build_s = time.perf_counter() - t
    peak_build = _peak_gb()

    n_modes, n_extra = ds.frequencies_hz.shape[1], int(ds.meta["n_extra"])
    picks = rng.choice(ds.n_samples, size=min(args.n_direct, ds.n_samples), replace=False)
    i_L, i_R = ds.pair[picks[0]]
    solve_d1b(disk, blade, ContactPattern(pats.L[i_L], pats.R[i_R]), n_modes=n_modes + n_extra)  # warm-up
    times, errs = check_against_direct(ds, disk, blade, pats, picks)
    direct_s = float(np.mean(times))
    out = {
        "level": args.level,
        "n_samples": ds.n_samples,
        "n_pairs": int(len(pats.L) * len(pats.R)),
        "n_delta_rows": int(delta_grid.size ** 3),
        "delta_grid": delta_grid.tolist(),
        "models_s": t_models,
        "build_s": build_s,
        "build_s_per_pair": build_s / (len(pats.L) * len(pats.R)),
        "direct_s_per_sample": direct_s,
        "direct_s_extrapolated": direct_s * ds.n_samples,
        "speedup": direct_s * ds.n_samples / build_s,
        "n_direct_checked": int(len(picks)),
        "max_rel_err": float(np.max(errs)),
        "max_error_bound": float(ds.meta["max_error_bound"]),
        "n_fallbacks": int(ds.meta["n_fallbacks"]),
        "min_mac_tracking": float(np.nanmin(ds.mac_min)),
        # Samples whose tracked modes are out of ascending order: tracking by index would mix them up.
        "n_samples_reordered": int(np.any(np.diff(ds.frequencies_hz, axis=1) < 0, axis=1).sum()),
        "feature_modes": list(ds.feature_modes),
        "peak_rss_gb": max(peak_build, _peak_gb()),
        "baseline_rss_gb": base_gb,
    }
    print(f"level {args.level}: {out['n_samples']} samples ({out['n_pairs']} pattern pairs × {out['n_delta_rows']} "
          f"δ rows, grid {np.round(100 * delta_grid, 2).tolist()} %)")
    print(f"{'reanalysis dataset build':<36s} {build_s:9.2f} s  ({1e3 * build_s / ds.n_samples:.3f} ms/sample, "
          f"{out['build_s_per_pair']:.3f} s/pair)")
    print(f"{'direct solve_d1b, extrapolated':<36s} {out['direct_s_extrapolated']:9.2f} s  "
          f"({1e3 * direct_s:.1f} ms/sample, mean of {len(picks)})")
    print(f"{'speed-up (direct / reanalysis)':<36s} {out['speedup']:9.1f} ×")
    print(f"max |rel err| vs direct on {len(picks)} samples: {100 * out['max_rel_err']:.2e} % "
          f"(bound over all samples {100 * out['max_error_bound']:.2e} %), fallbacks {out['n_fallbacks']}, "
          f"min tracking MAC {out['min_mac_tracking']:.3f}, samples with reordered modes {out['n_samples_reordered']}")
    print(f"peak memory {out['peak_rss_gb']:.2f} GB (before the build: {base_gb:.2f} GB); "
          f"feature modes (1-based) {[m + 1 for m in ds.feature_modes]}")
    if args.json:
        from rom.fileio import atomic_path

        with atomic_path(args.json) as tmp, open(tmp, "w") as fh:
            json.dump(out, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
