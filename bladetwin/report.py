"""The HTML report of ``bladetwin run``: one self-contained page rendered from an output folder.

The renderer only reads the folder that ``bladetwin run`` wrote (``summary.json``, the PNG figures and the
CSV tables it names) and computes nothing: re-rendering is cheap and never re-runs a stage. The page embeds
its images as base64 data URIs and its CSS inline, needs no JavaScript and no network, and links each figure
and table to its file beside the report.

The layout lives in ``bladetwin/templates/report.html.j2`` (Jinja2, autoescaped). This module checks the
folder, hands ``summary.json`` to :mod:`bladetwin.report_rows`, which turns it into plain rows and cells
(numbers by the one formatting rule of :mod:`bladetwin.report_cells`, heat-map colours, the first screen's
words from :mod:`bladetwin.report_answer`), and gives those to the template, so the template holds markup only.
The page's ``@media print`` stylesheet prints it without cut tables or figures, every fold open.
"""

from __future__ import annotations

import json
from pathlib import Path

from .report_cells import DEFAULT_REPORT_NAME, SUMMARY_NAME, ReportError, format_number, one_line, read_csv_table
from .report_rows import report_context
from .util import atomic_write_text

__all__ = ["ReportError", "render_report", "read_csv_table", "format_number", "DEFAULT_REPORT_NAME"]


def _load_summary(out_dir: Path) -> dict:
    path = out_dir / SUMMARY_NAME
    if not out_dir.is_dir():
        raise ReportError(f"{out_dir}: no such output folder (run `bladetwin run` first)")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ReportError(f"{path}: not found (run `bladetwin run` first to create the outputs)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ReportError(f"{path}: cannot read ({one_line(exc)})") from None
    try:
        summary = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ReportError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})") from None
    if not isinstance(summary, dict):
        raise ReportError(f"{path}: must hold a JSON object")
    return summary


def _environment():
    import jinja2

    return jinja2.Environment(
        loader=jinja2.PackageLoader("bladetwin", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )


def render_report(out_dir: str | Path, *, path: str | Path | None = None) -> Path:
    """Render the HTML report of an output folder of ``bladetwin run``.

    Parameters
    ----------
    out_dir : str or Path
        The output folder: ``summary.json`` and the figures and tables it names (paths relative to it).
    path : str or Path, optional
        Where to write the page. Default: ``out_dir / summary["report"]``, or ``out_dir / "report.html"``.
        Links to the figure and table files are relative to this page's folder.

    Returns
    -------
    Path
        The page written (atomically, UTF-8).

    Raises
    ------
    ReportError
        A missing folder or ``summary.json``, invalid JSON, a malformed entry, or a figure or table that
        ``summary.json`` names but the folder lacks; the one-line message names the file.
    """
    out_dir = Path(out_dir)
    summary = _load_summary(out_dir)
    if path is None:
        name = summary.get("report") or DEFAULT_REPORT_NAME
        if not isinstance(name, str):
            raise ReportError(f"{out_dir / SUMMARY_NAME}: 'report' must be a file name")
        path = out_dir / name
    path = Path(path)
    context = report_context(out_dir, path, summary)
    html = _environment().get_template("report.html.j2").render(**context)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(path, html)
