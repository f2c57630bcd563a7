"""The settings that key the stages, as command-line flags: one definition for ``run`` and ``identify …``.

A stage command given the same flags as a run (and both take the same defaults, :class:`RunOptions`'s) asks
the store for the same keys, so it finds that run's results.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from identify.chains import ESS_MIN, RHAT_MAX
from identify.posterior import MAX_EXTENSIONS

from .stages import RunOptions

__all__ = ["add_stage_options", "stage_options"]

_DEFAULTS = RunOptions()


def add_stage_options(p) -> None:
    """Add ``--cache-dir --n --scale --seed --step --features --no-bias --refine --method --rom --components
    --posterior-steps --workers --dask-workers``."""
    d = _DEFAULTS
    p.add_argument("--allow-outside", action="store_true",
                   help="let the manifest name files outside the campaign folder (refused by default)")
    p.add_argument("--cache-dir", default=None,
                   help="the store of stage results and reduced models (default: $BLADETWIN_CACHE or .cache/bladetwin)")
    p.add_argument("--n", type=int, default=d.n_patterns, help="synthetic patterns per flank (default: %(default)s)")
    p.add_argument("--scale", type=float, default=d.scale, help="Eq. 31's Scale of the PCA sampler "
                   "(default: %(default)s)")
    p.add_argument("--seed", type=int, default=d.seed, help="seed of the PCA sampler (default: %(default)s)")
    p.add_argument("--step", type=float, default=d.step_pct, help="δ grid step in %% (default: %(default)s)")
    p.add_argument("--features", type=int, default=d.n_features, help="feature modes of the k-NN "
                   "(default: %(default)s)")
    p.add_argument("--calibrate", action=argparse.BooleanOptionalAction, default=d.calibrate,
                   help="calibrate the FE model's E and ρ on the free-disk and free-blade tests and the manifest's "
                        "[masses] before any reduction (paper §5; default: on; --no-calibrate keeps the model's "
                        "handbook materials)")
    p.add_argument("--no-bias", action="store_true", help="don't remove the ROM's bias estimated on the filmed joints")
    p.add_argument("--refine", type=int, default=d.refine, metavar="N",
                   help="refine each unfilmed joint's k-NN pattern by a compass search of at most N disk-one-blade "
                        "solves (beyond the paper; about N × 0.15 s per joint and input; default: %(default)s; "
                        "0: the k-NN's pattern, as the paper)")
    p.add_argument("--workers", type=int, default=d.workers, help="worker processes of the stage runner, each "
                   "single-threaded (default: %(default)s)")
    p.add_argument("--method", choices=("knn", "posterior", "both"), default=d.method,
                   help="how unfilmed joints are identified: the k-NN (and its refinement), the contact posterior "
                        "(beyond the paper: intervals and probability maps), or both side by side; the identified "
                        "ROM uses the posterior's answer when it ran (default: %(default)s)")
    p.add_argument("--rom", choices=("updated", "paper"), default=d.rom,
                   help="the ROM validated on the full assembly: 'updated' also calibrates in-situ blade corrections "
                        "and the contact stiffness on the disk-one-blade tests (beyond the paper, shown beside the "
                        "paper's ROM; the exported ROM), 'paper' the paper's ROM only (default: %(default)s)")
    p.add_argument("--components", type=int, default=None, metavar="K",
                   help="PCA components per flank of the contact posterior's prior (default: enough for 95 %% of "
                        "the films' variance; at most one fewer than the filmed joints)")
    p.add_argument("--posterior-steps", type=int, default=d.posterior_steps, metavar="N",
                   help="steps of each joint's posterior sampler per round; rounds run on until its chains "
                        f"converge (R̂ ≤ {RHAT_MAX}, ESS ≥ {ESS_MIN:.0f}), at most {MAX_EXTENSIONS + 1} "
                        "(default: %(default)s)")
    p.add_argument("--dask-workers", type=int, default=None, metavar="N",
                   help="build the dataset on a local Dask cluster of N worker processes (default: in a worker)")


def stage_options(args, *, scheduler: str | None = None) -> RunOptions:
    """The :class:`RunOptions` of parsed flags; one-line :class:`ValueError` for a value out of range."""
    for name, v, ok, expected in (
            ("--n", args.n, args.n >= 2, "an integer ≥ 2"), ("--scale", args.scale, args.scale > 0, "a positive value"),
            ("--step", args.step, args.step > 0, "a positive value"),
            ("--features", args.features, args.features >= 1, "a positive integer"),
            ("--workers", args.workers, args.workers >= 1, "a positive integer"),
            ("--refine", args.refine, args.refine >= 0, "an integer ≥ 0"),
            ("--seed", args.seed, args.seed >= 0, "a non-negative integer"),
            ("--dask-workers", args.dask_workers, args.dask_workers is None or args.dask_workers >= 1,
             "a positive integer"),
            ("--components", args.components, args.components is None or args.components >= 1,
             "a positive integer"),
            ("--posterior-steps", args.posterior_steps, args.posterior_steps >= 10, "an integer ≥ 10")):
        if not ok:
            raise ValueError(f"{name} {v}: expected {expected}")
    return RunOptions(cache_dir=Path(args.cache_dir) if args.cache_dir else None, n_patterns=args.n,
                      scale=args.scale, seed=args.seed, step_pct=args.step, n_features=args.features,
                      bias=not args.no_bias, workers=args.workers, dask_workers=args.dask_workers,
                      scheduler=scheduler, refine=args.refine,
                      method=args.method, n_components=args.components, posterior_steps=args.posterior_steps,
                      rom=args.rom,
                      calibrate=args.calibrate)
