"""The report's tables as a person reads them: cells formatted by the one rule, intervals merged, heat maps coloured.

Two kinds: the CSV tables a run writes (:func:`table_cells`, :func:`color_heatmap`) and the tables the report
builds from ``summary.json`` itself (Table 8, the joints, the bias). Every number goes through
:func:`bladetwin.report_cells.format_column`: one number of decimals down a column (along a row where a row holds
one quantity, as in Table 8), the exact value in the cell's tooltip.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from .report_cells import MISSING, UNAVAILABLE, as_float, as_list, format_column, format_number, is_percent

__all__ = ["Cell", "Table", "FOLD_ROWS", "table_cells", "color_heatmap", "table8_view", "joint_rows", "bias_view"]

# Table 8 of the paper: the pipeline's cases, each described for a reader who did not run it.
_CASE_COLUMNS = (
    ("A", "Case A", "ROM with the predicted patterns vs ROM with the reference patterns"),
    ("B", "Case B", "ROM with the predicted patterns vs the measured assembly"),
    ("B_no_bias", "Case B, no bias correction", "as Case B, with the k-NN run without the bias correction"),
    ("C", "Case C", "ROM with the reference patterns vs the measured assembly"),
)
_BASELINE_COLUMNS = (
    ("A", "Baseline A", "as Case A, every unfilmed joint given the films' majority pattern"),
    ("B", "Baseline B", "as Case B, every unfilmed joint given the films' majority pattern"),
)
_PAPER_COLUMNS = (("A", "Paper A"), ("B", "Paper B"), ("C", "Paper C"))
_METRIC_ROWS = (
    ("mean_abs_df_pct", "mean |Δf| (%)"),
    ("mean_mac", "mean MAC"),
    ("n_modes", "n modes (paired)"),
)
#: A table longer than this is folded (``<details>``) under the figure that shows it: people look at figures and
#: look values up in tables.
FOLD_ROWS = 20
#: A column "X" followed by "… 5 %" and "… 95 %" is shown as one column, "value [low, high]": the posterior's
#: tables stay within the page without losing their intervals.
_LOW, _HIGH = re.compile(r"(^|\s)5 %"), re.compile(r"(^|\s)95 %")


def _diverging(t: float) -> str:
    """Inline style for a value scaled to [-1, 1]: blue below 0, white at 0, red above (RdBu-like)."""
    t = max(-1.0, min(1.0, t))
    end = (178, 24, 43) if t > 0 else (33, 102, 172)
    a = abs(t) ** 0.8  # lift small values a little so they remain visible
    r, g, b = (round(255 + (e - 255) * a) for e in end)
    text = "#fff" if a > 0.6 else "#111"
    return f"background:#{r:02x}{g:02x}{b:02x};color:{text}"


@dataclass
class Cell:
    """One cell as shown: its text, whether it is a number (right-aligned), its style and tooltip."""

    text: str
    numeric: bool = False
    style: str | None = None
    title: str | None = None
    header: bool = False
    sub: str | None = None  # a 90 % interval shown after the value


@dataclass
class Table:
    """One CSV table of a section as shown; ``folded`` past :data:`FOLD_ROWS` rows."""

    anchor: str
    number: int
    caption: str
    file: str
    href: str
    header: list[str]
    rows: list[list[Cell]]
    heatmap: bool = False
    scale: str | None = None
    folded: bool = False
    figure: str | None = None  # the file of the figure that shows it, where summary.json names one


def _columns(header: list[str]) -> list[tuple[int, ...]]:
    """The shown columns: (j,) a CSV column, (j, low, high) a value with its interval's columns beside it."""
    out, j = [], 0
    while j < len(header):
        if j + 2 < len(header) and _LOW.search(header[j + 1]) and _HIGH.search(header[j + 2]) \
                and not _LOW.search(header[j]):
            out.append((j, j + 1, j + 2))
            j += 3
        else:
            out.append((j,))
            j += 1
    return out


def table_cells(header: list[str], raw: list[list[str]]) -> tuple[list[str], list[list[Cell]]]:
    """The table's header and cells as shown: one number of decimals per column, intervals merged."""
    columns = _columns(header)
    shown_header, texts = [], []
    for col in columns:
        percent = is_percent(header[col[0]])
        if len(col) == 1:
            shown_header.append(header[col[0]])
            texts.append(format_column([r[col[0]] for r in raw], percent=percent))
        else:  # the value and its bounds share their decimals
            shown_header.append(f"{header[col[0]]} [90 % interval]")
            n = len(raw)
            texts.append(format_column([r[k] for k in col for r in raw], percent=percent))
            texts[-1] = [tuple(texts[-1][i + n * k] for k in range(3)) for i in range(n)]
    rows = []
    for i, r in enumerate(raw):
        cells = []
        for col, text in zip(columns, texts, strict=True):
            t, raw_text = text[i], r[col[0]]
            if len(col) == 1:
                numeric = as_float(raw_text) is not None
                cells.append(Cell(t, numeric=numeric, title=raw_text if t != raw_text else None))
            elif as_float(raw_text) is None:
                cells.append(Cell(t[0]))
            else:
                bounds = f"[{t[1]}, {t[2]}]" if t[1] and t[2] else None  # a bound the CSV left blank: none
                cells.append(Cell(t[0], numeric=True, sub=bounds, title=f"{raw_text} [{r[col[1]]}, {r[col[2]]}]"))
        rows.append(cells)
    return shown_header, rows


def color_heatmap(raw: list[list[str]], rows: list[list[Cell]]) -> str | None:
    """Colour a heat map's cells (the first column labels the rows: a row header, uncoloured); its scale's text."""
    for r in rows:
        if r:
            r[0].header = True
    values = [v for r in raw for v in (as_float(t) for t in r[1:]) if v is not None and math.isfinite(v)]
    vmax = max((abs(v) for v in values), default=0.0)
    for r, cells in zip(raw, rows, strict=True):
        for text, cell in zip(r[1:], cells[1:], strict=True):
            v = as_float(text)
            if v is not None and math.isfinite(v):
                cell.style = _diverging(v / vmax if vmax > 0 else 0.0)
    return format_number(vmax) if vmax > 0 else None


def _metric_row(cases: list, key: str) -> list[Cell]:
    """One metric of Table 8 across its cases: one number of decimals along the row (a row holds one metric)."""
    texts = format_column([c.get(key) if isinstance(c, dict) else None for c in cases],
                          percent=key.endswith("_pct"))
    cells = []
    for c, text in zip(cases, texts, strict=True):
        if not isinstance(c, dict) or (key in c and c[key] is None):
            cells.append(Cell(UNAVAILABLE, title="not computed for this campaign"))
        elif key not in c:
            cells.append(Cell(MISSING, title="not reported"))
        else:
            cells.append(Cell(text, numeric=as_float(c[key]) is not None, title=str(c[key])))
    return cells


def table8_view(summary: dict) -> dict:
    cases = summary.get("cases") if isinstance(summary.get("cases"), dict) else {}
    baseline = cases.get("baseline") if isinstance(cases.get("baseline"), dict) else {}
    paper = summary.get("paper_table8") if isinstance(summary.get("paper_table8"), dict) else {}
    columns = [(label, desc, cases.get(key)) for key, label, desc in _CASE_COLUMNS]
    columns += [(label, desc, baseline.get(key)) for key, label, desc in _BASELINE_COLUMNS]
    n_ours = len(columns)
    if paper:
        columns += [(label, "published value (paper Table 8)", paper.get(key)) for key, label in _PAPER_COLUMNS]
    rows = [(label, _metric_row([c for _, _, c in columns], key)) for key, label in _METRIC_ROWS]
    for k, (_, _, c) in enumerate(columns[n_ours:]):  # the paper gives no mode count
        if isinstance(c, dict) and "n_modes" not in c:
            rows[2][1][n_ours + k] = Cell(MISSING, title="not given in the paper")
    head = [(label, desc) for label, desc, _ in columns]
    return {"columns": head, "rows": rows, "n_ours": n_ours, "n_paper": len(columns) - n_ours}


def _area_cells(joints: list[dict], key: str) -> list[Cell]:
    texts = format_column([j.get(key) for j in joints], percent=True)
    return [Cell(MISSING, title="no reference") if j.get(key) is None else
            Cell(t, numeric=True, title=str(j[key])) for j, t in zip(joints, texts, strict=True)]


def joint_rows(summary: dict) -> list[list[Cell]]:
    joints = [j for j in as_list(summary.get("joints")) if isinstance(j, dict)]
    areas = [_area_cells(joints, k) for k in ("area_fraction_L_pct", "area_fraction_R_pct", "reference_area_L_pct",
                                              "reference_area_R_pct")]
    beyond = format_column([j.get("beyond_family_pct") for j in joints], percent=True)
    rows = []
    for i, j in enumerate(joints):
        row = [Cell(format_number(j.get("joint", MISSING)), header=True), Cell(str(j.get("source") or MISSING))]
        row += [Cell(str(j.get(k) or MISSING)) for k in ("pattern_L", "pattern_R")]
        row += [col[i] for col in areas]
        if j.get("beyond_family_pct") is None:
            row.append(Cell(MISSING, title="not identified by the k-NN"))
        elif j.get("outside_family"):
            row.append(Cell(beyond[i] + " ⚠", numeric=True,
                             title="beyond the synthetic pairs' reach by more than twice the ROM's scatter on the "
                                   "filmed joints: the pattern is the family's nearest edge, not a match"))
        else:
            row.append(Cell(beyond[i], numeric=True,
                             title="within reach of the synthetic pairs, or within twice the ROM's scatter"))
        rows.append(row)
    return rows


def bias_view(summary: dict) -> dict | None:
    bias = summary.get("bias")
    if not isinstance(bias, dict) or not bias.get("enabled", False):
        return None
    per_mode, spread = as_list(bias.get("per_mode_pct")), as_list(bias.get("spread_pct"))
    if not per_mode:
        return None
    modes = as_list(summary.get("feature_modes"))
    labels = [f"mode {format_number(m)}" for m in modes] if len(modes) == len(per_mode) else [
        f"#{k + 1}" for k in range(len(per_mode))]
    # bias and spread are one quantity (%): one number of decimals for both rows
    texts = format_column([*per_mode, *spread], percent=True)
    rows = [("bias (%)", [Cell(t, numeric=v is not None) for v, t in zip(per_mode, texts, strict=False)])]
    if spread:
        cells = [Cell(t, numeric=v is not None) for v, t in zip(spread, texts[len(per_mode):], strict=True)]
        rows.append(("spread over the filmed joints (%)", cells + [Cell(MISSING)] * (len(per_mode) - len(cells))))
    return {"labels": labels, "rows": rows}
