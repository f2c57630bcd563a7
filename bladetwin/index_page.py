"""The index page of a run on several campaigns: their Table 8 and every joint's identified contact side by side.

Like :mod:`bladetwin.report`, it only reads what the run wrote (each campaign's ``summary.json`` and the files it
lists) and computes nothing; its numbers follow the report's one formatting rule (:mod:`bladetwin.report_cells`).
Labs re-test one disk after each re-assembly; this page shows how the joints seated each time and marks the
joints whose contact changed between two campaigns (:mod:`bladetwin.index_compare` states the rule), with each
campaign's contact maps and films side by side and Table 8 of the paper's and the updated ROM.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from .index_compare import (
    CHANGED,
    FILM_CHANGE_PP,
    change_marks,
    contact_maps,
    film_views,
    read_contact,
    updated_table8,
)
from .report_cells import UNAVAILABLE, format_column, format_number
from .report_tables import FOLD_ROWS
from .util import atomic_write_text

__all__ = ["INDEX_NAME", "index_rows", "render_index"]

INDEX_NAME = "index.html"
_CASES = (("A", "Case A"), ("B", "Case B"), ("B_no_bias", "Case B, no bias"), ("C", "Case C"))


def _column(values: list, percent: bool) -> list[str]:
    """A column of the page by the report's one formatting rule; "unavailable" where a case was not computed."""
    texts = format_column(values, percent=percent)
    return [UNAVAILABLE if v is None else t for v, t in zip(values, texts, strict=True)]


def index_rows(summaries: list[dict]) -> dict:
    """Table 8 rows (case → cells per campaign) and joint rows (joint → areas per campaign) of the summaries.

    Numbers follow :func:`bladetwin.report_cells.format_column`, one number of decimals down each column, as in
    the campaigns' reports.
    """
    keys = [*_CASES, ("baseline_B", "baseline (as Case B)")]
    columns = []
    for s in summaries:
        cases = s["cases"]
        found = [cases["baseline"]["B"] if key == "baseline_B" else cases.get(key) for key, _ in keys]
        columns.append(_column([None if v is None else v["mean_abs_df_pct"] for v in found], percent=True))
        columns.append(_column([None if v is None else v["mean_mac"] for v in found], percent=False))
    table8 = [[label, *(col[i] for col in columns)] for i, (_, label) in enumerate(keys)]
    n = max(s["n_blades"] for s in summaries)
    columns = []
    for s in summaries:
        rows = [next((r for r in s["joints"] if r["joint"] == j), None) for j in range(1, n + 1)]
        columns.append(["—" if r is None else r["source"] for r in rows])
        for side in ("L", "R"):
            values = [None if r is None else r[f"area_fraction_{side}_pct"] for r in rows]
            columns.append(["—" if v is None else t for v, t in zip(values, format_column(values, percent=True),
                                                                   strict=True)])
    joints = [[j, *(col[j - 1] for col in columns)] for j in range(1, n + 1)]
    return {"table8": table8, "joints": joints}


def render_index(root: str | os.PathLike, outs: list[Path]) -> Path:
    """Write ``root/index.html`` comparing the campaigns whose output folders are ``outs``.

    Parameters
    ----------
    root : path
        The run's output folder (the page's links are relative to it).
    outs : list of Path
        Each campaign's output folder, in the order compared (a re-assembly after the one before).

    Returns
    -------
    Path
        The page written.
    """
    import jinja2

    root = Path(root)
    outs = [Path(o) for o in outs]
    summaries = [json.loads((o / "summary.json").read_text(encoding="utf-8")) for o in outs]
    env = jinja2.Environment(loader=jinja2.PackageLoader("bladetwin", "templates"), autoescape=True)
    links = [{"name": s["campaign"], "href": os.path.relpath(o / s.get("report", "report.html"), root),
              "known": s["known_joints"], "kind": s.get("kind", "")} for s, o in zip(summaries, outs, strict=True)]
    rows = index_rows(summaries)
    contacts = [read_contact(s, o) for s, o in zip(summaries, outs, strict=True)]
    updated = updated_table8(summaries)
    html = env.get_template("index.html.j2").render(
        campaigns=links, fold_rows=FOLD_ROWS, **rows, updated=updated,
        updated_missing=any(UNAVAILABLE in row for row in updated),
        changes=change_marks(summaries, contacts, len(rows["joints"])), maps=contact_maps(summaries, outs, root),
        films=film_views(summaries, root), changed_symbol=CHANGED,
        film_change_pp=format_number(FILM_CHANGE_PP))
    return atomic_write_text(root / INDEX_NAME, html)
