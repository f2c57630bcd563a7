"""Full-assembly EMA: the ordinary fit and the dense-family fit side by side, against the campaign's truth.

For a virtual campaign (a folder with ``truth/truth.json``, written by ``bladetwin lab simulate``), fits the
full-assembly test at the manifest's ``max_order`` if it has one (or ``--order``; ``--no-hint`` ignores the
manifest's, for campaigns written when the rig still gave it) with ``ema.fit`` and with
``ema.fit(families=True)`` in the same run, and prints for each: the visible modes that get a one-to-one EMA
mode within 0.05 % (issue 31's coverage), the EMA modes more than 1 % from every true mode, the share of found
modes whose truth lies within ± 2 standard deviations, the paired shapes' mean MAC against the exact shapes
(all pairs, and the disk-dominated ones; campaigns with ``truth/assembly_modes.npz``), and the time (target: the
family fit ≤ 60 s on 2 cores). It also prints the mean shape MAC that the test's noise allows
(:func:`lab.judge.shape_mac_bound`), the ceiling of the shape score. The scores are
:func:`lab.judge.assembly_scores`, as in ``summary.json``.

Run: ``.venv/bin/python benchmarks/ema_families.py [CAMPAIGN] [--order N | --no-hint] [--json out.json]``
(default CAMPAIGN: measurements/academic)
"""

from __future__ import annotations

import argparse
import json
import time
import tomllib
from pathlib import Path

import _paths  # noqa: F401  (must precede the package imports)

import ema
from bladetwin.util import atomic_write_text
from lab.judge import assembly_scores, load_assembly_truth, shape_mac_bound


def figures(model, truth, seconds: float) -> dict:
    return assembly_scores(model, truth) | {"time_s": seconds}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=str(_paths.REPO / "measurements" / "academic"))
    ap.add_argument("--order", type=int, default=None, help="model order (default: the manifest's, else 60)")
    ap.add_argument("--no-hint", action="store_true",
                    help="ignore the manifest's max_order: the default order 60, as a campaign without the hint")
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the figures to this JSON file")
    args = ap.parse_args()
    root = Path(args.campaign)
    truth = load_assembly_truth(root / "truth")
    if truth is None:
        raise SystemExit(f"{root}: no truth/truth.json with the full assembly's modes (not a virtual campaign)")
    manifest = tomllib.loads((root / "campaign.toml").read_text())
    test = next(t for t in manifest["tests"] if t["type"] == "assembly")
    order = args.order or (60 if args.no_hint else test.get("max_order", 60))
    frf = ema.read_uff(root / test["file"])
    out = {"campaign": str(root), "n_visible": int(truth.frequencies_hz.size), "max_order": order}
    for name, families in (("ordinary", False), ("families", True)):
        t0 = time.perf_counter()
        res = ema.fit(frf, max_order=order, families=families)
        out[name] = figures(res.model, truth, time.perf_counter() - t0)
    ref = out["ordinary"]
    print(f"{root.name}: {truth.frequencies_hz.size} visible modes, order {order}")
    print(f"{'fit':<12}{'modes':>7}{'1:1 ≤0.05 %':>14}{'>1 % off':>10}{'±2σ':>7}{'MAC':>6}{'disk':>6}"
          f"{'time [s]':>10}{'ratio':>7}")
    for name in ("ordinary", "families"):
        r = out[name]
        w2, mac, disk = (f"{r[k]:.2f}" if r.get(k) is not None else "-"
                         for k in ("within_2sd", "mean_shape_mac", "mean_shape_mac_disk"))
        print(f"{name:<12}{r['n_modes']:>7}{r['n_within_0p05pct']:>7} ({r['one_to_one_within_0p05pct']:.2f})"
              f"{r['n_more_than_1pct_off']:>10}{w2:>7}{mac:>6}{disk:>6}{r['time_s']:>10.1f}"
              f"{r['time_s'] / ref['time_s']:>7.2f}")
    if truth.shapes is not None and truth.damping_ratio is not None:
        # what the test's noise allows: no estimator beats the first figure on average (lab.judge)
        out["shape_mac_bound"] = float(shape_mac_bound(truth, frf).mean())
        out["shape_mac_bound_zeroed_below_3sd"] = float(shape_mac_bound(truth, frf, threshold=3.0).mean())
        out["shape_mac_bound_joint"] = float(shape_mac_bound(truth, frf, joint=True).mean())
        print(f"mean shape MAC that the test's noise allows (Cramér–Rao, every other mode known): "
              f"{out['shape_mac_bound']:.2f}; with entries below 3 σ zeroed: "
              f"{out['shape_mac_bound_zeroed_below_3sd']:.2f}; the neighbours' shapes unknown too: "
              f"{out['shape_mac_bound_joint']:.2f}")
    out["families_time_target_met"] = out["families"]["time_s"] <= 60.0
    print("time target (≤ 60 s) met" if out["families_time_target_met"] else "TIME TARGET MISSED")
    if args.json:
        atomic_write_text(args.json, json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
