"""What the truth twin's effects do to the tests, and every headline figure of two twins side by side.

Two generated tables (``make twin-tables``; docs/twin.md shows them):

* ``effects``: the nominal model against a campaign's tests, before and after the material calibration (paper
  §5, Table 4): the free blades per mode, the free disk per nodal diameter with its doublet splits, and the
  disk–one-blade tests per mode. It reads a calibrated run's and an uncalibrated run's ``summary.json`` and the
  campaign's ``truth/truth.json`` (for the disk modes' nodal diameters only).
* ``compare``: every headline figure of two runs (the paper's Table 8, the updated ROM's cases, the contact's
  area error, centroid distance and coverage, the full-assembly EMA's scores), e.g. the ideal twin against
  the realistic one with the same code.

Nothing here computes a figure: it only pairs and formats what the runs measured.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .results_doc import lookup

__all__ = ["effects_markdown", "compare_markdown", "main"]


def _pct(x) -> str:
    return "–" if x is None else f"{x:+.2f}"


def _num(x, spec: str = ".3g") -> str:
    return "–" if x is None else format(x, spec)


def _modes(summary: dict, key: str) -> np.ndarray:
    return np.array([m["frequency_hz"] for m in summary.get("ema", {}).get(key, {}).get("modes", [])])


def _blade_rows(cal: dict) -> list[str]:
    """Free blades per mode: the test (√ of the mean f²), the blades' scatter, the model's error before/after."""
    rows = [r for r in lookup(cal, "calibration.modes") or [] if r["component"] == "blade"]
    blades = [_modes(cal, k) for k in sorted(cal.get("ema", {})) if k.startswith("blade_")]
    n = min((b.size for b in blades), default=0)
    spread = 100 * np.std([b[:n] for b in blades], axis=0) / np.mean([b[:n] for b in blades], axis=0) if n else []
    out = ["| mode | test (Hz) | blade-to-blade scatter (%) | model − test, uncalibrated (%) | calibrated (%) |",
           "|---|---|---|---|---|"]
    for k, r in enumerate(rows):
        s = _num(spread[k], ".2f") if k < len(spread) else "–"
        out.append(f"| {r['mode']} | {r['test_hz']:.1f} | {s} | {_pct(r['before_pct'])} | {_pct(r['after_pct'])} |")
    return out


def _disk_rows(cal: dict, truth: dict) -> list[str]:
    """The free disk per nodal diameter: its measured doublet split and the model's error before/after."""
    rows = [r for r in lookup(cal, "calibration.modes") or [] if r["component"] == "disk"]
    f_test = _modes(cal, "disk")
    f_true = np.asarray(truth.get("frequencies_hz", {}).get("disk") or [])
    nd = truth.get("disk_nodal_diameters") or []
    if not rows or not f_test.size or len(nd) != f_true.size:
        return ["(no disk test or no nodal diameters in the truth)"]
    # each measured mode takes the nodal diameter of its nearest true mode; a pair with one ND is a doublet
    label = [nd[int(np.argmin(np.abs(f_true - f)))] for f in f_test]
    out = ["| nodal diameter | test (Hz) | doublet split, test (Hz / %) | model − test, uncalibrated (%) | "
           "calibrated (%) |", "|---|---|---|---|---|"]
    done: set[int] = set()
    for k, f in enumerate(f_test):
        if k in done:
            continue
        pair = [i for i in range(k, f_test.size) if label[i] == label[k] and abs(f_test[i] / f - 1) < 0.02][:2]
        done.update(pair)
        g = f_test[pair]
        split = f"{np.ptp(g):.2f} / {100 * np.ptp(g) / g.mean():.3f}" if len(pair) == 2 else "single"
        r = min(rows, key=lambda r: abs(r["test_hz"] - f))
        out.append(f"| {label[k]} | {g.mean():.1f} | {split} | {_pct(r['before_pct'])} | {_pct(r['after_pct'])} |")
    return out


def _d1b_rows(cal: dict, nocal: dict) -> list[str]:
    """Disk–one-blade tests per mode: the ROM with the films' patterns on the filmed joints against the test."""
    # the bias is f_test / f_ROM − 1, its median over the filmed joints; exactly 0 where no joint found the mode
    def model_minus_test(values: list, k: int):
        return None if k >= len(values) or values[k] == 0 else 100 * (1 / (1 + values[k] / 100) - 1)

    before, after = lookup(nocal, "bias.per_mode_pct") or [], lookup(cal, "bias.per_mode_pct") or []
    spread = lookup(cal, "bias.spread_pct") or []
    out = ["| tracked mode | model − test, uncalibrated (%) | calibrated (%) | scatter over the filmed joints (%) |",
           "|---|---|---|---|"]
    for k in range(max(len(before), len(after))):
        b, a = model_minus_test(before, k), model_minus_test(after, k)
        s = spread[k] if k < len(spread) else None
        out.append(f"| {k + 1} | {_pct(b)} | {_pct(a)} | {_num(s, '.2f')} |")
    return out


def effects_markdown(cal: dict, nocal: dict, truth: dict) -> str:
    """The ``effects`` table (see the module notes) as Markdown."""
    joints = lookup(cal, "bias.joints") or []
    parts = [f"Campaign `{cal.get('campaign')}` ({cal.get('n_blades')} blades, realism "
             f"{truth.get('realism', 'ideal')}).", "",
             "**Free blades** (the calibration sets E on mode 1):", "", *_blade_rows(cal), "",
             "**Free disk** (the calibration sets E on its first measured mode):", "", *_disk_rows(cal, truth), "",
             f"**Disk–one-blade tests**, filmed joints {joints} with their films' patterns (the ROM's bias):", "",
             *_d1b_rows(cal, nocal), ""]
    return "\n".join(parts)


#: The headline figures of ``compare``: (label, key in summary.json, format).
HEADLINES = [
    ("Table 8 A, paper's ROM: mean |Δf| (%)", "cases.A.mean_abs_df_pct", ".3f"),
    ("Table 8 A: MAC", "cases.A.mean_mac", ".3f"),
    ("Table 8 B: mean |Δf| (%)", "cases.B.mean_abs_df_pct", ".3f"),
    ("Table 8 B: MAC", "cases.B.mean_mac", ".3f"),
    ("Table 8 C: mean |Δf| (%)", "cases.C.mean_abs_df_pct", ".3f"),
    ("Table 8 C: MAC", "cases.C.mean_mac", ".3f"),
    ("updated ROM A (%)", "rom.updated.cases.A.mean_abs_df_pct", ".3f"),
    ("updated ROM B (%)", "rom.updated.cases.B.mean_abs_df_pct", ".3f"),
    ("updated ROM B: MAC", "rom.updated.cases.B.mean_mac", ".3f"),
    ("updated ROM B, baseline pattern (%)", "rom.updated.cases.B_baseline.mean_abs_df_pct", ".3f"),
    ("updated ROM C (%)", "rom.updated.cases.C.mean_abs_df_pct", ".3f"),
    ("contact area error, k-NN (pp)", "methods.knn.experimental.area_error_pp", ".1f"),
    ("contact area error, posterior (pp)", "methods.posterior.experimental.area_error_pp", ".1f"),
    ("contact area error, baseline (pp)", "geometric.area_error_pp.baseline", ".1f"),
    ("centroid distance, k-NN (mm)", "methods.knn.experimental.centroid_distance_mm", ".2f"),
    ("centroid distance, posterior (mm)", "methods.posterior.experimental.centroid_distance_mm", ".2f"),
    ("posterior 90 % interval coverage of the area", "methods.posterior.experimental.ci90_coverage_area", ".2f"),
    ("full-assembly EMA: 1:1 within 0.05 %", "ema.assembly.one_to_one_within_0p05pct", ".2f"),
    ("full-assembly EMA: modes > 1 % off", "ema.assembly.n_more_than_1pct_off", "d"),
    ("full-assembly EMA: mean shape MAC", "ema.assembly.mean_shape_mac", ".3f"),
    ("full-assembly EMA: share within ± 2σ", "ema.assembly.within_2sd", ".2f"),
    ("calibration: disk E change (%)", "calibration.disk.E_change_pct", "+.2f"),
    ("calibration: blade E change (%)", "calibration.blade.E_change_pct", "+.2f"),
]


def compare_markdown(runs: dict[str, dict]) -> str:
    """Every headline figure (:data:`HEADLINES`) of each run (name → its ``summary.json``) as one Markdown table."""
    names = list(runs)
    out = ["| figure | " + " | ".join(names) + " | key in summary.json |",
           "|---|" + "---|" * len(names) + "---|"]
    for label, key, spec in HEADLINES:
        cells = [_num(lookup(runs[n], key), spec) for n in names]
        out.append(f"| {label} | " + " | ".join(cells) + f" | `{key}` |")
    return "\n".join(out) + "\n"


def _load(path: Path) -> dict:
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: expected a readable JSON file ({exc})") from None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bladetwin.twin_table", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("effects", help="the model against the tests, before and after calibration")
    e.add_argument("calibrated", type=Path, help="summary.json of a calibrated run")
    e.add_argument("uncalibrated", type=Path, help="summary.json of the same campaign run with --no-calibrate")
    e.add_argument("truth", type=Path, help="the campaign's truth/truth.json")
    c = sub.add_parser("compare", help="headline figures of several runs side by side")
    c.add_argument("runs", nargs="+", metavar="NAME=SUMMARY", help="e.g. ideal=out/ideal/summary.json")
    args = ap.parse_args(argv)
    try:
        if args.cmd == "effects":
            text = effects_markdown(_load(args.calibrated), _load(args.uncalibrated), _load(args.truth))
        else:
            pairs = [r.split("=", 1) for r in args.runs]
            if any(len(p) != 2 for p in pairs):
                raise ValueError(f"runs {args.runs}: expected NAME=path/to/summary.json each")
            text = compare_markdown({n: _load(Path(p)) for n, p in pairs})
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
