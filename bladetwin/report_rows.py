"""The rows and cells of the HTML report (:mod:`bladetwin.report`), built from ``summary.json``.

Everything the template shows is plain data made here: numbers formatted, heat-map colours chosen, figures
embedded as base64 data URIs, file links made relative to the page. Nothing is computed from the results.

The page opens on the lab's three questions: every unfilmed joint's contact (the figure :func:`_lead` picks),
the ROM to take away and how far to trust both (:mod:`bladetwin.report_answer`); notes and warnings follow,
folded under one-line headlines. A table longer than :data:`bladetwin.report_tables.FOLD_ROWS` rows is folded,
under the figure that shows it where ``summary.json`` names one (a table's ``figure``).
"""

from __future__ import annotations

import base64
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .report_answer import headline, rom_choice, trust_paragraphs
from .report_cells import (
    SUMMARY_NAME,
    ReportError,
    as_list,
    one_line,
    read_csv_table,
)
from .report_header import fact_items, header_items, timing_rows
from .report_tables import FOLD_ROWS, Table, bias_view, color_heatmap, joint_rows, table8_view, table_cells
from .rom_summary import CONTROL_TEXT

__all__ = ["report_context"]

#: A table row's label (first column) → the line the table's caption gains where the row is there.
_ROW_TEXT = {"B_baseline": CONTROL_TEXT}
_MIME = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".gif": "image/gif",
         ".svg": "image/svg+xml", ".webp": "image/webp"}


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-") or "section"


# ------------------------------------------------------------------------------------------ view models


@dataclass
class _Figure:
    anchor: str
    number: int
    caption: str
    alt: str
    file: str
    href: str
    data_uri: str
    tables: list[Table] = field(default_factory=list)  # the tables it shows, placed under it
    home: str | None = None  # its section's anchor, where it leads the page from the first screen


@dataclass
class _Section:
    anchor: str
    title: str
    paragraphs: list[str]
    figures: list[_Figure] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)


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


def _table_view(folder: _Folder, spec: Any, where: str, number: int) -> Table:
    if not isinstance(spec, dict):
        raise ReportError(f"{folder.out_dir / SUMMARY_NAME}: {where} must be an object with a 'file'")
    p = folder.path(spec.get("file"), where)
    header, raw = read_csv_table(p)
    heatmap = bool(spec.get("heatmap"))
    shown_header, rows = table_cells(header, raw)
    scale = color_heatmap(raw, rows) if heatmap else None
    caption = str(spec.get("caption") or p.name)
    caption = " ".join([caption, *(_ROW_TEXT[r[0]] for r in raw if r and r[0] in _ROW_TEXT)])
    if len(shown_header) < len(header):
        caption += " [a, b]: the 90 % interval (its 5 % and 95 % quantiles, each a column of the CSV file)."
    name = Path(spec["file"]).as_posix()
    figure = spec.get("figure") if isinstance(spec.get("figure"), str) else None
    return Table(f"tab-{number}", number, caption, name, folder.href(p), shown_header, rows, heatmap, scale,
                 folded=len(rows) > FOLD_ROWS, figure=figure)


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
        by_file = {f.file: f for f in section.figures}
        for j, t in enumerate(as_list(s.get("tables"))):
            table = _table_view(folder, t, f"{where}.tables[{j}]", 0)
            # a table goes under the figure that shows it, where summary.json names one in its section
            owner = by_file.get(table.figure) if table.figure else None
            (owner.tables if owner else section.tables).append(table)
        for table in [t for f in section.figures for t in f.tables] + section.tables:  # numbered as they read
            n_tab += 1
            table.number, table.anchor = n_tab, f"tab-{n_tab}"
        sections.append(section)
    return sections


# -------------------------------------------------------------------------------------------- rendering


def report_context(out_dir: Path, path: Path, summary: dict) -> dict:
    """The template's variables for the page ``path`` of the output folder ``out_dir`` and its ``summary.json``."""
    folder = _Folder(out_dir, path)
    notes = [str(n) for n in as_list(summary.get("notes")) if str(n).strip()]
    if isinstance(summary.get("notes"), str):
        notes = [summary["notes"]]
    warnings = [str(w) for w in as_list(summary.get("warnings")) if str(w).strip()]
    sections = _sections(folder, summary)
    return {
        "campaign": str(summary.get("campaign") or out_dir.resolve().name),
        "command": summary.get("command"),
        "header": header_items(summary),
        "facts": fact_items(summary),
        "bias": bias_view(summary),
        "table8": table8_view(summary),
        "notes": [(*headline(n), n) for n in notes],
        "warnings": [(*headline(w), w) for w in warnings],
        "timings": timing_rows(summary),
        "joints": joint_rows(summary),
        "sections": sections,
        "lead": _lead(sections),
        "rom": _rom(folder, summary),
        "trust": trust_paragraphs(summary),
        "fold_rows": FOLD_ROWS,
    }


def _rom(folder: _Folder, summary: dict) -> dict | None:
    """The ROM the lab takes away (first screen), with a link to its modes' file where the folder holds it."""
    rom = rom_choice(summary)
    if rom is None:
        return None
    name = _get_file(summary, "rom_modes_uff")
    p = folder.out_dir / name if name else None
    rom["file"] = name if p is not None and p.is_file() else None
    rom["href"] = folder.href(p) if rom["file"] else None
    return rom


def _get_file(summary: dict, key: str) -> str | None:
    files = summary.get("files")
    name = files.get(key) if isinstance(files, dict) else None
    return name if isinstance(name, str) and name.strip() else None


#: Where the first screen's contact figure comes from: the posterior's maps, else the k-NN's identified patterns.
_LEAD = (("sec-posterior", None), ("sec-identification", "identified_patterns_map.png"))


def _lead(sections: list[_Section]) -> _Figure | None:
    """The answer the page leads with: every unfilmed joint's contact (shown at the top, not in its section)."""
    for anchor, file in _LEAD:
        for s in sections:
            if s.anchor != anchor:
                continue
            figure = next((f for f in s.figures if file is None or f.file == file), None)
            if figure is not None:
                figure.home = s.anchor
                return figure
    return None
