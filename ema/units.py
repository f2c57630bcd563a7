"""FRF unit labels: their factor to SI and their dimension, so that FRFs stated in other units can be merged.

A label such as ``"mm/N"``, ``"(1/N)*(m/s²)"`` or ``"g/lbf"`` is parsed into a factor to (m, s, N) and the powers
of (length, time, force) (:func:`parse_units`); :func:`unit_factor` converts between two labels of one dimension.
"""

from __future__ import annotations

import math
import re

__all__ = ["UNIT_FACTORS", "parse_units", "unit_factor", "clean_label"]

# Dimensions of a unit as powers of (length, time, force). FRF labels are ratios of these; mass would only
# enter through force, which every FRF label states directly.
_Dims = tuple[int, int, int]

#: Units recognised in FRF unit labels: factor to SI (m, s, N) and dimension (length, time, force).
#: "g" is the standard acceleration 9.80665 m/s^2; "lb" in an FRF label is pound-force. Names are matched
#: case-insensitively (UFF labels are often upper case), so only names that stay unambiguous are listed
#: (no "nm": nanometre or newton-metre).
UNIT_FACTORS: dict[str, tuple[float, _Dims]] = {
    "m": (1.0, (1, 0, 0)),
    "cm": (1e-2, (1, 0, 0)),
    "mm": (1e-3, (1, 0, 0)),
    "um": (1e-6, (1, 0, 0)),
    "\u00b5m": (1e-6, (1, 0, 0)),  # micro sign
    "\u03bcm": (1e-6, (1, 0, 0)),  # Greek mu
    "in": (0.0254, (1, 0, 0)),
    "ft": (0.3048, (1, 0, 0)),
    "s": (1.0, (0, 1, 0)),
    "sec": (1.0, (0, 1, 0)),
    "g": (9.80665, (1, -2, 0)),
    "n": (1.0, (0, 0, 1)),
    "kn": (1e3, (0, 0, 1)),
    "lbf": (4.4482216152605, (0, 0, 1)),
    "lb": (4.4482216152605, (0, 0, 1)),
    "rad": (1.0, (0, 0, 0)),
}

_TOKEN = re.compile(r"\s*(?:(\*\*|[*/^()-])|([0-9]+(?:\.[0-9]*)?(?:[eE][-+]?[0-9]+)?)|([A-Za-z\u00b5\u03bc]+)([0-9]*))")
_SUPERSCRIPT = str.maketrans({"\u00b2": "^2", "\u00b3": "^3", "\u00b7": "*", "\u22c5": "*"})


def parse_units(label: str) -> tuple[float, _Dims] | None:
    """Factor to SI and dimension of an FRF unit label such as ``"mm/N"``, ``"(1/N)*(m/s²)"`` or ``"g/lbf"``.

    Parameters
    ----------
    label : str
        Products and quotients of the units in :data:`UNIT_FACTORS`, with parentheses, numbers and
        integer exponents (``s^2``, ``s**2``, ``s2``, ``s²``, ``s^-2``); juxtaposition multiplies.

    Returns
    -------
    (factor, dims) or None
        ``value_SI = value * factor``; dims are the powers of (length, time, force). None when the label is
        empty or not understood.
    """
    text = str(label).translate(_SUPERSCRIPT).strip()
    if not text or text.upper() == "NONE":
        return None
    tokens: list[tuple[str, str]] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            if text[pos:].strip() == "":
                break
            return None
        op, num, name, exp = m.groups()
        if op is not None:
            tokens.append(("op", "^" if op == "**" else op))
        elif num is not None:
            tokens.append(("num", num))
        else:
            tokens.append(("unit", name))
            if exp:
                tokens += [("op", "^"), ("num", exp)]
        pos = m.end()
    try:
        value, rest = _parse_product(tokens)
    except (ValueError, OverflowError, IndexError):
        return None
    if rest or not (math.isfinite(value[0]) and value[0] > 0):
        return None
    return value


def _combine(a: tuple[float, _Dims], b: tuple[float, _Dims], power: int) -> tuple[float, _Dims]:
    dims = (a[1][0] + power * b[1][0], a[1][1] + power * b[1][1], a[1][2] + power * b[1][2])
    return a[0] * b[0] ** power, dims


def _parse_product(tokens: list[tuple[str, str]]) -> tuple[tuple[float, _Dims], list[tuple[str, str]]]:
    """product := power (("*" | "/" | juxtaposition) power)*, left to right (a/b/c = a/(b c))."""
    value, tokens = _parse_power(tokens)
    while tokens and tokens[0] != ("op", ")"):
        sign = 1
        if tokens[0] in (("op", "*"), ("op", "/")):
            sign = -1 if tokens[0][1] == "/" else 1
            tokens = tokens[1:]
        factor, tokens = _parse_power(tokens)
        value = _combine(value, factor, sign)
    return value, tokens


def _parse_power(tokens: list[tuple[str, str]]) -> tuple[tuple[float, _Dims], list[tuple[str, str]]]:
    """power := atom ("^" ["-"] integer)?; atom := number | unit | "(" product ")"."""
    kind, text = tokens[0]
    if (kind, text) == ("op", "("):
        value, tokens = _parse_product(tokens[1:])
        if not tokens or tokens[0] != ("op", ")"):
            raise ValueError("unbalanced parentheses")
        tokens = tokens[1:]
    elif kind == "num":
        value, tokens = (float(text), (0, 0, 0)), tokens[1:]
    elif kind == "unit":
        if text.lower() not in UNIT_FACTORS:
            raise ValueError(f"unknown unit {text!r}")
        value, tokens = UNIT_FACTORS[text.lower()], tokens[1:]
    else:
        raise ValueError(f"unexpected {text!r}")
    if tokens and tokens[0] == ("op", "^"):
        tokens = tokens[1:]
        sign = 1
        if tokens[0] == ("op", "-"):
            sign, tokens = -1, tokens[1:]
        kind, text = tokens[0]
        if kind != "num" or not text.isdigit():
            raise ValueError("exponent is not an integer")
        value = _combine((1.0, (0, 0, 0)), value, sign * int(text))
        tokens = tokens[1:]
    return value, tokens


def clean_label(label: str) -> str:
    """A unit label with its whitespace collapsed to single blanks; "" for an empty label or UFF's "NONE"."""
    text = " ".join(str(label).split())
    return "" if text.upper() == "NONE" else text


def unit_factor(src: str, dst: str) -> float | None:
    """Factor that converts FRF values labelled ``src`` into values labelled ``dst``.

    Parameters
    ----------
    src, dst : str
        Unit labels (see :func:`parse_units`).

    Returns
    -------
    float or None
        1.0 for identical labels (also when both are empty or not understood); ``f_src / f_dst`` when both are
        understood and of the same dimension (``"mm/N"`` into ``"m/N"``: 1e-3); None otherwise.
    """
    a, b = clean_label(src), clean_label(dst)
    if a == b:
        return 1.0
    pa, pb = parse_units(a), parse_units(b)
    if pa is None or pb is None or pa[1] != pb[1]:
        return None
    return pa[0] / pb[0]
