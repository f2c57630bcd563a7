"""The contact posterior (issue 32) for every unfilmed joint, against the k-NN with its refinement, same inputs.

Both methods run through the pipeline's own runner and workers, from a store in which everything they need
(models, EMA, dataset, features) is already computed: a hard-linked copy of the repository's store (filled first
if needed) with both methods' nodes removed. The reference measured in the same run is the k-NN with its
refinement (``bladetwin run``'s default ``--refine``) on the same joints, for the experimental input. Timed:

* **k-NN**: the two-step k-NN's predictions and each joint's refinement (``patterns/experimental``);
* **posterior**: the prior, the surrogate's direct solves and fit, the family's error on the films, the δ
  factors and each joint's sampler (``patterns/posterior_experimental``).

Target (issue 32): the posterior for 13 joints ≤ 180 s on 2 cores.

Run: ``.venv/bin/python benchmarks/posterior.py [CAMPAIGN] [--workers 2] [--json out.json]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import _paths  # noqa: F401  (puts the repository first on sys.path)

#: Store folders (node functions) of each method's nodes, removed from the copy so that they are computed.
METHOD_NODES = {"knn": ("predict", "refine_joint"),
                "posterior": ("prior_node", "surrogate_solves", "surrogate_node", "representation_error",
                              "delta_factors", "posterior_joint")}
TARGETS = {"knn": "patterns/experimental", "posterior": "patterns/posterior_experimental"}


def _link_or_copy(src: str, dst: str) -> None:
    """Hard-link a store entry; copy it where the file system cannot link."""
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _timed(campaign, opts, name: str) -> tuple[float, int]:
    """Wall seconds of one method's nodes from a store that lacks them, and how many nodes it computed."""
    from bladetwin.run import run_nodes

    t = time.perf_counter()
    _, runner = run_nodes(campaign, [TARGETS[name]], opts)
    return time.perf_counter() - t, len(runner.computed)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=str(_paths.REPO / "measurements" / "academic"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the figures to this JSON file")
    args = ap.parse_args(argv)

    from bladetwin.campaign import read_campaign
    from bladetwin.run import run_nodes
    from bladetwin.stages import RunOptions
    from bladetwin.util import atomic_write_text
    from rom.cache import default_cache_dir

    campaign = read_campaign(args.campaign)
    store = default_cache_dir()
    print(f"filling {store} with what both methods need (warm after `make run`) ...", flush=True)
    run_nodes(campaign, list(TARGETS.values()), RunOptions(cache_dir=store, workers=args.workers, method="both"))
    joints = [t.index for t in campaign.of_type("d1b") if t.index not in campaign.known_joints]
    # beside the store, so that its entries can be hard-linked (entries are replaced atomically, never edited)
    with tempfile.TemporaryDirectory(prefix="bladetwin-posterior-", dir=store.parent) as tmp:
        copy = Path(tmp) / "store"
        shutil.copytree(store, copy, copy_function=_link_or_copy)
        for folders in METHOD_NODES.values():
            for f in folders:
                shutil.rmtree(copy / "nodes" / f, ignore_errors=True)
        for memo in (copy / "memo").glob("refine-solves-*"):  # the refinement's d1b solves, shared by its joints
            shutil.rmtree(memo)
        opts = RunOptions(cache_dir=copy, workers=args.workers, method="both")
        knn_s, knn_n = _timed(campaign, opts, "knn")
        post_s, post_n = _timed(campaign, opts, "posterior")
    figures = {"campaign": campaign.name, "workers": args.workers, "cpu_count": os.cpu_count(),
               "n_joints": len(joints), "knn_s": knn_s, "posterior_s": post_s, "ratio": post_s / knn_s,
               "knn_nodes": knn_n, "posterior_nodes": post_n, "target_s": 180.0}
    print(f"{'method (experimental input)':<44}{'time [s]':>10}{'ratio':>8}{'nodes':>8}")
    print(f"{'k-NN and refinement (reference)':<44}{knn_s:>10.1f}{1.0:>8.2f}{knn_n:>8}")
    print(f"{'contact posterior':<44}{post_s:>10.1f}{post_s / knn_s:>8.2f}{post_n:>8}")
    print(f"{len(joints)} unfilmed joints; target: the posterior ≤ 180 s on 2 cores "
          f"({'met' if post_s <= 180 else 'NOT met'})")
    if args.json:
        atomic_write_text(args.json, json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
