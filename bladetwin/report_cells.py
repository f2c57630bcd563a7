"""The report's plain helpers: its error, number formatting and CSV reading (shared by :mod:`bladetwin.report` and
:mod:`bladetwin.report_rows`, which import this module and never each other's internals).

The formatting rule is here once (:func:`decimals_for`, :func:`format_number`, :func:`format_column`) and serves
every page a person reads: the report, the index page of several campaigns and the README's tables
(:mod:`bladetwin.results_doc`). About 3 significant digits, percentages at most 2 decimals, one number of decimals
down a column (one more where the column's values lie closer together than that); the exact values stay in
``summary.json`` and the CSV files.
"""

from __future__ import annotations

import csv
import math
import re
import statistics
from pathlib import Path
from typing import Any

__all__ = ["ReportError", "format_number", "format_column", "decimals_for", "is_percent", "DIGITS",
           "PERCENT_DECIMALS", "as_float", "as_list", "read_csv_table", "one_line", "DEFAULT_REPORT_NAME",
           "SUMMARY_NAME", "UNAVAILABLE", "MISSING"]

DEFAULT_REPORT_NAME = "report.html"
SUMMARY_NAME = "summary.json"
UNAVAILABLE = "unavailable"
MISSING = "—"

_INT_RE = re.compile(r"^[+-]?\d+$")


class ReportError(ValueError):
    """The output folder cannot be rendered; the message is one line naming the file at fault."""


# --------------------------------------------------------------------------------------------------- helpers


#: Significant digits a person reads: trust in the results lives in the second digit, the third is margin.
DIGITS = 3
#: A percentage never shows more decimals than this: 0.41 %, not 0.4117 %.
PERCENT_DECIMALS = 2
#: Beyond these magnitudes a number is written with an exponent (2.68e+11, 3.21e-05), never as a row of zeros.
_LARGE, _SMALL = 1e6, 1e-3
_PERCENT_HEADER = re.compile(r"\(%|%\)|pct|\(pp\)")


def is_percent(header: str) -> bool:
    """Whether a column named ``header`` holds percentages (``(%)``, ``(% of …)``, ``_pct``, ``(pp)``)."""
    return bool(_PERCENT_HEADER.search(str(header)))


def decimals_for(value: float, *, percent: bool = False, digits: int = DIGITS, near_one: bool = True) -> int | None:
    """The decimals the formatting rule gives ``value``; None where it takes an exponent instead.

    The rule: ``digits`` significant digits, but never fewer than the whole integer part (1993, not 1.99e+03);
    a percentage at most :data:`PERCENT_DECIMALS` decimals; no trailing zero a value given with fewer
    decimals does not have (0.5 stays 0.5); a number just below 1 (a MAC, a fit quality)
    keeps the decimals that tell it from 1 (0.9996, not 1.000) unless ``near_one`` is False (a column: its
    other values would gain digits no one reads); beyond 1e6 or below 1e-3 (not a percentage) an exponent.
    """
    x = abs(float(value))
    if x == 0 or not math.isfinite(x):
        return 0
    if x >= _LARGE or (x < _SMALL and not percent):
        return None
    decimals = max(0, digits - 1 - math.floor(math.log10(x)))
    if decimals and round(x, decimals) >= 10 ** (math.floor(math.log10(x)) + 1):
        decimals -= 1  # rounding carries into a new digit (0.9996 → 1.00, not 1.000)
    if percent:
        return min(decimals, PERCENT_DECIMALS)
    if near_one and 0.99 <= x < 1:
        decimals = max(decimals, min(6, -math.floor(math.log10(1 - x))))
    return decimals


def _unpadded(numbers: list[float], decimals: int | None) -> int | None:
    """``decimals`` less the trailing zeros every one of ``numbers`` has exactly: a value given as 0.91 (the
    paper's) prints 0.91, not 0.910; a computed 0.1996 keeps its 0.200."""
    if decimals is None:
        return None
    while decimals > 0 and all(abs(x - round(x, decimals - 1)) <= 1e-12 * max(1.0, abs(x)) for x in numbers):
        decimals -= 1
    return decimals


def _spread(numbers: list[float], decimals: int | None, percent: bool) -> int | None:
    """One decimal more where a column's values lie closer together than its last digit (a dense mode family:
    194, 194, 194 Hz tells a reader nothing that 193.7, 194.1, 194.4 Hz does)."""
    if decimals is None or (percent and decimals >= PERCENT_DECIMALS):
        return decimals
    values = sorted({round(x, decimals + 1) for x in numbers})  # as they would be shown with the extra digit
    gaps = [b - a for a, b in zip(values, values[1:], strict=False)]
    if len(values) >= 3 and statistics.median(gaps) < 10.0 ** -decimals:
        return decimals + 1
    return decimals


def _fixed(number: float, decimals: int | None, digits: int = DIGITS) -> str:
    if math.isnan(number):
        return MISSING
    if math.isinf(number):
        return "∞" if number > 0 else "−∞"
    if decimals is None:
        return f"{number:.{digits - 1}e}"
    text = f"{number:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text  # no "-0.00"


def format_number(value: Any, digits: int = DIGITS, *, percent: bool = False) -> str:
    """Format one number for a person, by the report's one rule (:func:`decimals_for`).

    Parameters
    ----------
    value : Any
        A number, a string holding one, or anything else (returned as ``str``).
    digits : int, optional
        Significant digits of a float (default :data:`DIGITS`, 3).
    percent : bool, optional
        The value is a percentage: at most :data:`PERCENT_DECIMALS` decimals.

    Returns
    -------
    str
        ``"12"``, ``"0.951"``, ``"1993"``, ``"0.41"`` (percent), ``"2.68e+11"``; ``"—"`` for NaN (a value the
        run did not find), ``"unavailable"`` for ``None``. Integers (and strings holding one) stay as they
        are. The exact values stay in ``summary.json`` and the CSV files.
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
    decimals = _unpadded([number], decimals_for(number, percent=percent, digits=digits))
    return _fixed(number, decimals, digits)


def format_column(values: list, *, percent: bool = False, digits: int = DIGITS) -> list[str]:
    """Format a column of numbers with one number of decimals down the column.

    The column's largest finite magnitude sets the decimals (:func:`decimals_for`): it shows ``digits``
    significant digits and the others line up with it; no zero is added that no value of the column has (a
    column of values given to 2 decimals stays at 2); and one decimal more where the values lie closer
    together than the last digit (a dense mode family, each joint's frequency of one mode). A column of
    integers stays as it is; text and missing values pass through as :func:`format_number` gives them.

    Parameters
    ----------
    values : list
        The column's cells: numbers, strings (CSV cells), None.
    percent : bool, optional
        The column holds percentages.
    digits : int, optional
        Significant digits of the column's largest value.

    Returns
    -------
    list of str
        One text per value.
    """
    numbers = [None if isinstance(v, bool) else as_float(v) for v in values]
    ints = [isinstance(v, int) or (isinstance(v, str) and bool(_INT_RE.match(v.strip()))) for v in values]
    floats = [x for x, whole in zip(numbers, ints, strict=True) if x is not None and not whole and math.isfinite(x)]
    if not floats:  # a column of integers (joints, modes, counts) stays as written
        return [format_number(v, digits, percent=percent) for v in values]
    decimals = decimals_for(max(floats, key=abs), percent=percent, digits=digits, near_one=False)
    decimals = _unpadded(floats, _spread(floats, decimals, percent))
    out = []
    for v, x in zip(values, numbers, strict=True):
        out.append(format_number(v, digits, percent=percent) if x is None else _fixed(x, decimals, digits))
    return out


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
