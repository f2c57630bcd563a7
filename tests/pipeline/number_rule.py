"""The pages' one formatting rule, checked on the text a person reads (independent of its implementation).

The rule (``bladetwin.report_cells``): about 3 significant digits (the whole integer part always shown), a
percentage at most 2 decimals, one number of decimals down a column, an exponent beyond 1e6 or below 1e-3.
"""

from __future__ import annotations

import re
import statistics

__all__ = ["check_column", "numbers_in", "is_percent_header", "NOT_A_NUMBER"]

#: Cell texts that stand for no number.
NOT_A_NUMBER = {"", "—", "unavailable", "not measured", "NaN", "∞", "−∞", "yes", "no"}
_NUMBER = re.compile(r"^-?\d+(\.\d+)?(e[+-]\d+)?$")


def is_percent_header(header: str) -> bool:
    """A column of percentages: its name says "(%)", "(% of …)", "(pp)", "%)", "pct" or "|Δf| %"."""
    return bool(re.search(r"\(%|%\)|pct|\(pp\)|Δf\\?\| %", header))


def numbers_in(text: str) -> list[str] | None:
    """The numbers a cell shows: one, or a value with its interval ("73.3 [51.6, 86.2]"); None for text."""
    text = text.replace("⚠", "").strip()
    m = re.fullmatch(r"(\S+) \[(\S+), (\S+)\]", text)
    parts = list(m.groups()) if m else [text]
    return parts if all(_NUMBER.match(p) for p in parts) else None


def _decimals(text: str) -> int:
    mantissa = text.split("e")[0]
    return len(mantissa.split(".")[1]) if "." in mantissa else 0


def _significant(text: str) -> int:
    digits = text.split("e")[0].lstrip("-").replace(".", "").lstrip("0")
    return len(digits)


def check_column(texts: list[str], *, percent: bool = False, where: str = "") -> int:
    """Assert the rule on one column (or one row of a table whose rows each hold one quantity).

    Returns the number of numeric cells checked (text cells, "2 min 27 s", "39 of 47", are not numbers). A
    column of integers passes as written.
    """
    numbers = []
    for t in texts:
        found = None if t.strip() in NOT_A_NUMBER else numbers_in(t)
        numbers += found or []
    if not numbers:
        return 0
    if all("." not in n and "e" not in n for n in numbers):
        return len(numbers)  # integers (joints, modes, counts), or a column rounded to whole units
    exponent = ["e" in n for n in numbers]
    assert all(exponent) or not any(exponent), f"{where}: exponent and fixed notation mixed: {numbers}"
    decimals = {_decimals(n) for n in numbers}
    assert len(decimals) == 1, f"{where}: the column's decimals differ: {numbers}"
    largest = max(numbers, key=lambda n: abs(float(n)))
    d = decimals.pop()
    if percent:
        assert d <= 2, f"{where}: a percentage with {d} decimals: {largest}"
    if d > 0 and not all(exponent):
        # the largest value carries the column's precision: at most 3 significant digits (or its whole integer
        # part); one more where one digit less would not tell the column's values apart (median gap under a unit
        # of that digit); up to 6 for a single value just below 1 that keeps the digit telling it from 1 (0.9996)
        near_one = len(numbers) == 1 and 0.99 <= abs(float(largest)) < 1
        values = sorted({float(n) for n in numbers})
        gaps = sorted(b - a for a, b in zip(values, values[1:], strict=False))
        dense = len(values) >= 3 and statistics.median(gaps) < 10.0 ** (1 - d) * (1 + 1e-9)
        whole = len(str(int(abs(float(largest))))) if abs(float(largest)) >= 1 else 0  # 1993: all shown
        allowed = 6 if near_one else max(3, whole) + (1 if dense else 0)
        assert _significant(largest) <= allowed, f"{where}: {largest} has too many digits"
    else:
        assert all(_significant(n) <= 3 for n in numbers if "e" in n), f"{where}: {numbers}"
    return len(numbers)
