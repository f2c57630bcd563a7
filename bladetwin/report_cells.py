"""The report's plain helpers: its error, number formatting and CSV reading (shared by :mod:`bladetwin.report` and
:mod:`bladetwin.report_rows`, which import this module and never each other's internals)."""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path
from typing import Any

__all__ = ["ReportError", "format_number", "as_float", "as_list", "read_csv_table", "one_line", "DEFAULT_REPORT_NAME",
           "SUMMARY_NAME", "UNAVAILABLE", "MISSING"]

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


def as_list(value: Any) -> list:
    """``value`` as a list where it is a list or tuple in summary.json; an empty list otherwise."""
    return list(value) if isinstance(value, (list, tuple)) else []
