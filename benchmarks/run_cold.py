"""`bladetwin run` on the bundled campaign with an empty store (cold), against the same run with every stage stored.

The reference measured in the same run is the warm rerun: it reads every stage's result from the store and
writes the outputs, so the ratio is what the store saves. Both runs use a fresh temporary store and output
folder; the repository's own store (``.cache/``) is not touched.

Run: ``.venv/bin/python benchmarks/run_cold.py [CAMPAIGN] [--workers 2] [--json out.json]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _paths  # noqa: F401  (puts the repository first on sys.path)

from rom.fileio import atomic_path

REPO = Path(__file__).resolve().parents[1]


def _run(campaign: str | None, out: Path, cache: Path, workers: int, log: str | None = None) -> tuple[float, dict]:
    """Wall seconds of one `bladetwin run`, and its summary.json; its progress (stderr) kept in ``log``."""
    cmd = [sys.executable, "-m", "bladetwin", "run", *([campaign] if campaign else []), "--out", str(out),
           "--workers", str(workers)]
    t = time.perf_counter()
    proc = subprocess.run(cmd, cwd=REPO, env={**os.environ, "BLADETWIN_CACHE": str(cache), "MPLBACKEND": "Agg"},
                          capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if log:
        with atomic_path(log) as tmp_path:
            tmp_path.write_text(proc.stderr)
    if proc.returncode != 0:
        raise SystemExit(f"bladetwin run failed (exit {proc.returncode}): {proc.stderr.strip()[-2000:]}")
    summaries = sorted(out.rglob("summary.json"))
    return seconds, json.loads(summaries[0].read_text())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=None, help="campaign folder (default: the bundled one)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the figures to this JSON file")
    ap.add_argument("--summary", default=None, metavar="PATH",
                    help="also keep the cold run's summary.json here (e.g. docs/results/summary.json)")
    ap.add_argument("--log", default=None, metavar="PATH", help="also keep the cold run's progress messages here")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bladetwin-cold-") as tmp:
        cache = Path(tmp) / "cache"
        cold_s, cold = _run(args.campaign, Path(tmp) / "cold", cache, args.workers, args.log)
        warm_s, warm = _run(args.campaign, Path(tmp) / "warm", cache, args.workers)
    figures = {
        "campaign": cold["campaign"], "workers": args.workers, "cpu_count": os.cpu_count(),
        "cold_s": cold_s, "warm_s": warm_s, "ratio": cold_s / warm_s,
        "cold_stages": cold.get("stages", {}), "warm_stages": warm.get("stages", {}),
        "same_figures": cold["cases"] == warm["cases"] and cold.get("geometric") == warm.get("geometric"),
    }
    print(f"{'run':<34}{'time [s]':>10}{'ratio':>10}{'stages computed':>18}")
    print(f"{'warm (every stage stored)':<34}{warm_s:>10.1f}{1.0:>10.2f}{warm['stages'].get('computed', '?'):>18}")
    print(f"{'cold (empty store)':<34}{cold_s:>10.1f}{cold_s / warm_s:>10.2f}{cold['stages'].get('computed', '?'):>18}")
    print(f"figures equal cold and warm: {figures['same_figures']}; target: cold ≤ 420 s on 2 cores "
          f"({'met' if cold_s <= 420 else 'NOT met'})")
    if args.json:
        with atomic_path(args.json) as tmp_path:
            tmp_path.write_text(json.dumps(figures, indent=2))
    if args.summary:
        with atomic_path(args.summary) as tmp_path:
            tmp_path.write_text(json.dumps(cold, indent=2, ensure_ascii=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
