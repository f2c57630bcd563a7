"""The rows and cells of the HTML report (:mod:`bladetwin.report`), built from ``summary.json``.

Everything the template shows is plain data made here: numbers formatted, heat-map colours chosen, figures
embedded as base64 data URIs, file links made relative to the page. Nothing is computed from the results.
"""

from __future__ import annotations

import base64
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .report_cells import (
    MISSING,
    SUMMARY_NAME,
    UNAVAILABLE,
    ReportError,
    as_float,
    as_list,
    format_number,
    one_line,
    read_csv_table,
)
from .report_header import fact_items, header_items, timing_rows
from .rom_summary import CONTROL_TEXT

__all__ = ["report_context"]

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
#: A table row's label (first column) → the line the table's caption gains where the row is there.
_ROW_TEXT = {"B_baseline": CONTROL_TEXT}
_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".gif": "image/gif",
         ".svg": "image/svg+xml", ".webp": "image/webp"}


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-") or "section"


def _diverging(t: float) -> str:
    """Inline style for a value scaled to [-1, 1]: blue below 0, white at 0, red above (RdBu-like)."""
    t = max(-1.0, min(1.0, t))
    end = (178, 24, 43) if t > 0 else (33, 102, 172)
    a = abs(t) ** 0.8  # lift small values a little so they remain visible
    r, g, b = (round(255 + (e - 255) * a) for e in end)
    text = "#fff" if a > 0.6 else "#111"
    return f"background:#{r:02x}{g:02x}{b:02x};color:{text}"


# ------------------------------------------------------------------------------------------ view models


@dataclass
class _Cell:
    text: str
    numeric: bool = False
    style: str | None = None
    title: str | None = None
    header: bool = False


@dataclass
class _Table:
    anchor: str
    number: int
    caption: str
    file: str
    href: str
    header: list[str]
    rows: list[list[_Cell]]
    heatmap: bool = False
    scale: str | None = None


@dataclass
class _Figure:
    anchor: str
    number: int
    caption: str
    alt: str
    file: str
    href: str
    data_uri: str


@dataclass
class _Section:
    anchor: str
    title: str
    paragraphs: list[str]
    figures: list[_Figure] = field(default_factory=list)
    tables: list[_Table] = field(default_factory=list)


class _Folder:
    """Resolves the files that ``summary.json`` names, relative to the folder and to the report."""

    def __init__(self, out_dir: Path, report_path: Path):
        self.out_dir = out_dir
        self.report_dir = report_path.parent

    def path(self, name: Any, where: str) -> Path:
        if not isinstance(name, str) or not name.strip():
            raise ReportError(f"{self.out_dir / SUMMARY_NAME}: {where} has no file name")
        p = self.out_dir / name
        if not p.is_file():
            raise ReportError(f"{p}: file not found ({where} in {SUMMARY_NAME})")
        return p

    def href(self, p: Path) -> str:
        rel = os.path.relpath(p.resolve(), self.report_dir.resolve())
        return Path(rel).as_posix()


def _data_uri(p: Path) -> str:
    mime = _MIME.get(p.suffix.lower())
    if mime is None:
        raise ReportError(f"{p}: not an image the report can embed (use PNG)")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ReportError(f"{p}: cannot read the figure ({exc.strerror or one_line(exc)})") from None
    if mime == "image/png" and not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ReportError(f"{p}: not a PNG file")
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def _table_view(folder: _Folder, spec: Any, where: str, number: int) -> _Table:
    if not isinstance(spec, dict):
        raise ReportError(f"{folder.out_dir / SUMMARY_NAME}: {where} must be an object with a 'file'")
    p = folder.path(spec.get("file"), where)
    header, raw = read_csv_table(p)
    heatmap = bool(spec.get("heatmap"))
    rows: list[list[_Cell]] = []
    for r in raw:
        cells = []
        for text in r:
            value = as_float(text)
            shown = format_number(text) if value is not None else text
            cells.append(_Cell(shown, numeric=value is not None, title=text if shown != text else None))
        rows.append(cells)
    scale = None
    if heatmap:
        # The first column labels the rows (blade, joint): it is a row header, not a value to colour.
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
        if vmax > 0:
            scale = format_number(vmax)
    caption = str(spec.get("caption") or p.name)
    caption = " ".join([caption, *(_ROW_TEXT[r[0]] for r in raw if r and r[0] in _ROW_TEXT)])
    name = Path(spec["file"]).as_posix()
    return _Table(f"tab-{number}", number, caption, name, folder.href(p), header, rows, heatmap, scale)


def _figure_view(folder: _Folder, spec: Any, where: str, number: int) -> _Figure:
    if not isinstance(spec, dict):
        raise ReportError(f"{folder.out_dir / SUMMARY_NAME}: {where} must be an object with a 'file'")
    p = folder.path(spec.get("file"), where)
    caption = str(spec.get("caption") or "")
    alt = caption or f"figure {p.name}"
    return _Figure(f"fig-{number}", number, caption, alt, Path(spec["file"]).as_posix(), folder.href(p), _data_uri(p))


def _paragraphs(text: Any) -> list[str]:
    if text is None:
        return []
    if isinstance(text, str):
        text = [text]
    return [str(t) for t in text if str(t).strip()]


def _sections(folder: _Folder, summary: dict) -> list[_Section]:
    raw = summary.get("sections") or []
    if not isinstance(raw, list):
        raise ReportError(f"{folder.out_dir / SUMMARY_NAME}: 'sections' must be a list")
    sections, seen = [], {"top", "summary", "joints", "contents"}
    n_fig = n_tab = 0
    for i, s in enumerate(raw):
        where = f"sections[{i}]"
        if not isinstance(s, dict):
            raise ReportError(f"{folder.out_dir / SUMMARY_NAME}: {where} must be an object")
        title = str(s.get("title") or s.get("id") or f"Section {i + 1}")
        anchor = base = f"sec-{_slug(s.get('id') or title)}"
        k = 2
        while anchor in seen:
            anchor, k = f"{base}-{k}", k + 1
        seen.add(anchor)
        section = _Section(anchor, title, _paragraphs(s.get("text")))
        for j, f in enumerate(as_list(s.get("figures"))):
            n_fig += 1
            section.figures.append(_figure_view(folder, f, f"{where}.figures[{j}]", n_fig))
        for j, t in enumerate(as_list(s.get("tables"))):
            n_tab += 1
            section.tables.append(_table_view(folder, t, f"{where}.tables[{j}]", n_tab))
        sections.append(section)
    return sections


def _metric(case: Any, key: str) -> _Cell:
    if not isinstance(case, dict):
        return _Cell(UNAVAILABLE, title="not computed for this campaign")
    if key not in case:
        return _Cell(MISSING, title="not reported")
    value = case[key]
    if value is None:
        return _Cell(UNAVAILABLE, title="not computed for this campaign")
    return _Cell(format_number(value), numeric=as_float(value) is not None)


def _table8(summary: dict) -> dict:
    cases = summary.get("cases") if isinstance(summary.get("cases"), dict) else {}
    baseline = cases.get("baseline") if isinstance(cases.get("baseline"), dict) else {}
    paper = summary.get("paper_table8") if isinstance(summary.get("paper_table8"), dict) else {}
    columns = [(label, desc, cases.get(key)) for key, label, desc in _CASE_COLUMNS]
    columns += [(label, desc, baseline.get(key)) for key, label, desc in _BASELINE_COLUMNS]
    n_ours = len(columns)
    if paper:
        columns += [(label, "published value (paper Table 8)", paper.get(key)) for key, label in _PAPER_COLUMNS]
    rows = [(label, [_metric(c, key) for _, _, c in columns]) for key, label in _METRIC_ROWS]
    for k, (_, _, c) in enumerate(columns[n_ours:]):  # the paper gives no mode count
        if isinstance(c, dict) and "n_modes" not in c:
            rows[2][1][n_ours + k] = _Cell(MISSING, title="not given in the paper")
    head = [(label, desc) for label, desc, _ in columns]
    return {"columns": head, "rows": rows, "n_ours": n_ours, "n_paper": len(columns) - n_ours}


def _joints(summary: dict) -> list[list[_Cell]]:
    rows = []
    for j in as_list(summary.get("joints")):
        if not isinstance(j, dict):
            continue
        row = [_Cell(format_number(j.get("joint", MISSING)), header=True), _Cell(str(j.get("source") or MISSING))]
        row += [_Cell(str(j.get(k) or MISSING)) for k in ("pattern_L", "pattern_R")]
        for k in ("area_fraction_L_pct", "area_fraction_R_pct", "reference_area_L_pct", "reference_area_R_pct"):
            v = j.get(k)
            row.append(_Cell(MISSING, title="no reference") if v is None else _Cell(format_number(v), numeric=True))
        v = j.get("beyond_family_pct")
        if v is None:
            row.append(_Cell(MISSING, title="not identified by the k-NN"))
        elif j.get("outside_family"):
            row.append(_Cell(format_number(v) + " ⚠", numeric=True,
                             title="beyond the synthetic pairs' reach by more than twice the ROM's scatter on the "
                                   "filmed joints: the pattern is the family's nearest edge, not a match"))
        else:
            row.append(_Cell(format_number(v), numeric=True,
                             title="within reach of the synthetic pairs, or within twice the ROM's scatter"))
        rows.append(row)
    return rows


def _bias_table(summary: dict) -> dict | None:
    bias = summary.get("bias")
    if not isinstance(bias, dict) or not bias.get("enabled", False):
        return None
    per_mode, spread = as_list(bias.get("per_mode_pct")), as_list(bias.get("spread_pct"))
    if not per_mode:
        return None
    modes = as_list(summary.get("feature_modes"))
    labels = [f"mode {format_number(m)}" for m in modes] if len(modes) == len(per_mode) else [
        f"#{k + 1}" for k in range(len(per_mode))]
    rows = [("bias (%)", [_Cell(format_number(v), numeric=v is not None) for v in per_mode])]
    if spread:
        cells = [_Cell(format_number(v), numeric=v is not None) for v in spread]
        rows.append(("spread over the filmed joints (%)", cells + [_Cell(MISSING)] * (len(per_mode) - len(cells))))
    return {"labels": labels, "rows": rows}


# -------------------------------------------------------------------------------------------- rendering


def report_context(out_dir: Path, path: Path, summary: dict) -> dict:
    """The template's variables for the page ``path`` of the output folder ``out_dir`` and its ``summary.json``."""
    folder = _Folder(out_dir, path)
    notes = [str(n) for n in as_list(summary.get("notes")) if str(n).strip()]
    if isinstance(summary.get("notes"), str):
        notes = [summary["notes"]]
    sections = _sections(folder, summary)
    return {
        "campaign": str(summary.get("campaign") or out_dir.resolve().name),
        "command": summary.get("command"),
        "header": header_items(summary),
        "facts": fact_items(summary),
        "bias": _bias_table(summary),
        "table8": _table8(summary),
        "notes": notes,
        "warnings": [str(w) for w in as_list(summary.get("warnings")) if str(w).strip()],
        "timings": timing_rows(summary),
        "joints": _joints(summary),
        "sections": sections,
        "lead": _lead(sections),
    }


def _lead(sections: list[_Section]) -> _Figure | None:
    """The answer the summary leads with: the contact posterior's figure of every unfilmed joint, where it ran."""
    return next((s.figures[0] for s in sections if s.anchor == "sec-posterior" and s.figures), None)
