"""The index page of a run on several campaigns: their Table 8 and every joint's identified contact side by side.

Like :mod:`bladetwin.report`, it only reads what the run wrote (each campaign's ``summary.json``) and computes
nothing. Labs re-test one disk after each re-assembly; this page shows how the joints seated each time.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from .util import atomic_write_text

__all__ = ["INDEX_NAME", "index_rows", "render_index"]

INDEX_NAME = "index.html"
_CASES = (("A", "Case A"), ("B", "Case B"), ("B_no_bias", "Case B, no bias"), ("C", "Case C"))


def index_rows(summaries: list[dict]) -> dict:
    """Table 8 rows (case → cells per campaign) and joint rows (joint → areas per campaign) of the summaries."""
    table8 = []
    for key, label in (*_CASES, ("baseline_B", "baseline (as Case B)")):
        cells = []
        for s in summaries:
            cases = s["cases"]
            v = cases["baseline"]["B"] if key == "baseline_B" else cases.get(key)
            cells += ["unavailable"] * 2 if v is None else [f"{v['mean_abs_df_pct']:.3f}", f"{v['mean_mac']:.3f}"]
        table8.append([label, *cells])
    n = max(s["n_blades"] for s in summaries)
    joints = []
    for j in range(1, n + 1):
        cells = []
        for s in summaries:
            row = next((r for r in s["joints"] if r["joint"] == j), None)
            cells += ["—"] * 3 if row is None else [row["source"], f"{row['area_fraction_L_pct']:.1f}",
                                                    f"{row['area_fraction_R_pct']:.1f}"]
        joints.append([j, *cells])
    return {"table8": table8, "joints": joints}


def render_index(root: str | os.PathLike, outs: list[Path]) -> Path:
    """Write ``root/index.html`` comparing the campaigns whose output folders are ``outs``; returns its path."""
    import jinja2

    root = Path(root)
    summaries = [json.loads((Path(o) / "summary.json").read_text(encoding="utf-8")) for o in outs]
    env = jinja2.Environment(loader=jinja2.PackageLoader("bladetwin", "templates"), autoescape=True)
    links = [{"name": s["campaign"], "href": os.path.relpath(Path(o) / s.get("report", "report.html"), root),
              "known": s["known_joints"], "kind": s.get("kind", "")} for s, o in zip(summaries, outs, strict=True)]
    html = env.get_template("index.html.j2").render(campaigns=links, **index_rows(summaries))
    return atomic_write_text(root / INDEX_NAME, html)
