"""Full-assembly EMA: the ordinary fit and the dense-family fit side by side, against the campaign's truth.

For a virtual campaign (a folder with ``truth/truth.json``, written by ``bladetwin lab simulate``), fits the
full-assembly test at the manifest's ``max_order`` (or ``--order``) with ``ema.fit`` and with
``ema.fit(families=True)`` in the same run, and prints for each: the visible modes that get a one-to-one EMA
mode within 0.05 % (issue 31's coverage), the EMA modes more than 1 % from every true mode, the share of found
modes whose truth lies within ± 2 standard deviations, and the time (target: the family fit ≤ 60 s on 2 cores).

Run: ``.venv/bin/python benchmarks/ema_families.py [CAMPAIGN] [--order N] [--json out.json]``
(default CAMPAIGN: measurements/academic)
"""

from __future__ import annotations

import argparse
import json
import time
import tomllib
from pathlib import Path

import _paths  # noqa: F401  (must precede the package imports)
import numpy as np

import ema
from bladetwin.util import atomic_write_text
from ema.mac import pair_by_frequency


def figures(model, f_true: np.ndarray, seconds: float) -> dict:
    f = model.frequencies_hz
    rows, _ = pair_by_frequency(f, f_true, 5e-4)
    far = int(sum(np.min(np.abs(x - f_true) / f_true) > 0.01 for x in f))
    a, b = pair_by_frequency(f, f_true, 0.01)
    z = np.abs(f[a] - f_true[b]) / model.frequency_std_hz[a]
    return {"n_modes": int(model.n_modes), "one_to_one_within_0p05pct": rows.size / f_true.size,
            "n_within_0p05pct": int(rows.size), "n_more_than_1pct_off": far,
            "within_2sd": float(np.mean(z <= 2)) if z.size else None, "time_s": seconds}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=str(_paths.REPO / "measurements" / "academic"))
    ap.add_argument("--order", type=int, default=None, help="model order (default: the manifest's, else 60)")
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the figures to this JSON file")
    args = ap.parse_args()
    root = Path(args.campaign)
    truth = json.loads((root / "truth" / "truth.json").read_text())
    f_true = np.array(truth["frequencies_hz"]["assembly"])
    manifest = tomllib.loads((root / "campaign.toml").read_text())
    test = next(t for t in manifest["tests"] if t["type"] == "assembly")
    order = args.order or test.get("max_order", 60)
    frf = ema.read_uff(root / test["file"])
    out = {"campaign": str(root), "n_visible": int(f_true.size), "max_order": order}
    for name, families in (("ordinary", False), ("families", True)):
        t0 = time.perf_counter()
        res = ema.fit(frf, max_order=order, families=families)
        out[name] = figures(res.model, f_true, time.perf_counter() - t0)
    ref = out["ordinary"]
    print(f"{root.name}: {f_true.size} visible modes, order {order}")
    print(f"{'fit':<12}{'modes':>7}{'1:1 ≤0.05 %':>14}{'>1 % off':>10}{'±2σ':>7}{'time [s]':>10}{'ratio':>7}")
    for name in ("ordinary", "families"):
        r = out[name]
        w2 = f"{r['within_2sd']:.2f}" if r["within_2sd"] is not None else "-"
        print(f"{name:<12}{r['n_modes']:>7}{r['n_within_0p05pct']:>7} ({r['one_to_one_within_0p05pct']:.2f})"
              f"{r['n_more_than_1pct_off']:>10}{w2:>7}{r['time_s']:>10.1f}{r['time_s'] / ref['time_s']:>7.2f}")
    out["families_time_target_met"] = out["families"]["time_s"] <= 60.0
    print("time target (≤ 60 s) met" if out["families_time_target_met"] else "TIME TARGET MISSED")
    if args.json:
        atomic_write_text(args.json, json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
