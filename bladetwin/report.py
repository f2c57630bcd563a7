"""The HTML report of ``bladetwin run``: one self-contained page rendered from an output folder.

The renderer only reads the folder that ``bladetwin run`` wrote (``summary.json``, the PNG figures and the
CSV tables it names) and computes nothing: re-rendering is cheap and never re-runs a stage. The page embeds
its images as base64 data URIs and its CSS inline, needs no JavaScript and no network, and links each figure
and table to its file beside the report.

The layout lives in ``bladetwin/templates/report.html.j2`` (Jinja2, autoescaped). This module checks the
folder, hands ``summary.json`` to :mod:`bladetwin.report_rows`, which turns it into plain rows and cells
(formatting numbers, choosing heat-map colours), and gives those to the template, so the template holds
markup only.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path
from typing import Any

from .util import atomic_write_text

__all__ = ["ReportError", "render_report", "read_csv_table", "format_number", "DEFAULT_REPORT_NAME"]

DEFAULT_REPORT_NAME = "report.html"
SUMMARY_NAME = "summary.json"
UNAVAILABLE = "unavailable"
MISSING = "—"

_INT_RE = re.compile(r"^[+-]?\d+$")


class ReportError(ValueError):
    """The output folder cannot be rendered; the message is one line naming the file at fault."""


# --------------------------------------------------------------------------------------------------- helpers


def format_number(value: Any, digits: int = 4) -> str:
    """Format a number for display: integers as they are, floats to ``digits`` significant digits.

    Parameters
    ----------
    value : Any
        A number, a string holding one, or anything else (returned as ``str``).
    digits : int, optional
        Significant digits of a float (default 4).

    Returns
    -------
    str
        ``"12"``, ``"0.9512"``, ``"-1.235e+05"``, ``"NaN"``; ``"unavailable"`` for ``None``.
    """
    if value is None:
        return UNAVAILABLE
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    number = as_float(value)
    if number is None:
        return str(value)
    if isinstance(value, str) and _INT_RE.match(value.strip()):
        return value.strip()
    if math.isnan(number):
        return "NaN"
    if math.isinf(number):
        return "∞" if number > 0 else "−∞"
    return f"{number:.{digits}g}"


def as_float(value: Any) -> float | None:
    """``value`` as a float: a number, or a string holding one; None for anything else (booleans too)."""
    if isinstance(value, bool) or value is None:
        return None
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value.strip())
        except ValueError:
            return None
    return None


def read_csv_table(path: str | Path) -> tuple[list[str], list[list[str]]]:
    """Read a CSV table with a header row.

    Parameters
    ----------
    path : str or Path
        The CSV file (UTF-8, comma-separated, a header row first).

    Returns
    -------
    header : list of str
        The column names.
    rows : list of list of str
        The body rows as strings, padded with ``""`` (or extended with unnamed columns) to one width.
        Blank lines are skipped.

    Raises
    ------
    ReportError
        When the file cannot be read or decoded, or has no header row.
    """
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            lines = [row for row in csv.reader(fh) if any(cell.strip() for cell in row)]
    except FileNotFoundError:
        raise ReportError(f"{path}: table file not found") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ReportError(f"{path}: cannot read the table ({one_line(exc)})") from None
    if not lines:
        raise ReportError(f"{path}: the table is empty (a header row is needed)")
    header, rows = [h.strip() for h in lines[0]], lines[1:]
    width = max([len(header), *(len(r) for r in rows)])
    header += [""] * (width - len(header))
    return header, [r + [""] * (width - len(r)) for r in rows]


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (its type's name when it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__



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
    # Imported here, not at the top: report_rows imports ReportError and format_number from this module.
    from .report_rows import report_context

    context = report_context(out_dir, path, summary)
    html = _environment().get_template("report.html.j2").render(**context)
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(path, html)
