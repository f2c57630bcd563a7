"""The UFF format below pyuff: function types, the 58 record codes, and the data set blocks of a file, checked.

pyuff pairs the ``-1`` delimiter lines two by two and trusts the headers; :func:`open_uff` first checks the file's
structure (a last data set without its closing delimiter, a binary 58b payload of the wrong length) so that a
truncated file is refused instead of read as a smaller one.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pyuff

from .errors import UFFError

__all__ = ["FUNCTION_TYPES", "ORDINATE_FORM", "FORM_ORDINATE", "FORM_UNITS", "ABSCISSA_TYPES", "delimiters",
           "open_uff", "read_set", "required_field"]

#: UFF 58 record 6 field 1: function identification.
FUNCTION_TYPES: dict[int, str] = {
    0: "general or unknown",
    1: "time response",
    2: "auto spectrum",
    3: "cross spectrum",
    4: "frequency response function",
    5: "transmissibility",
    6: "coherence",
    7: "auto correlation",
    8: "cross correlation",
    9: "power spectral density",
    10: "energy spectral density",
    11: "probability density function",
    12: "spectrum",
    13: "cumulative frequency distribution",
    14: "peaks valley",
    15: "stress/cycles",
    16: "strain/cycles",
    17: "orbit",
    18: "mode indicator function",
    19: "force pattern",
    20: "partial power",
    21: "partial coherence",
    22: "eigenvalue",
    23: "eigenvector",
    24: "shock response spectrum",
    25: "finite impulse response filter",
    26: "multiple coherence",
    27: "order function",
    28: "phase compensation",
}

#: UFF specific data types (record 9/10 field 1) that fix the FRF form, and back.
ORDINATE_FORM = {8: "receptance", 11: "mobility", 12: "accelerance"}
FORM_ORDINATE = {v: k for k, v in ORDINATE_FORM.items()}
#: The unit label written for each FRF form when the set states none.
FORM_UNITS = {"receptance": "m/N", "mobility": "m/s/N", "accelerance": "m/s^2/N"}
#: UFF abscissa data types (record 8 field 1).
ABSCISSA_TYPES = {0: "unknown", 17: "time", 18: "frequency"}


# pyuff's rule for a data set delimiter: "    -1" followed by the end of the file, a line break, or 74 blanks.
_DELIMITER = b"    -1"


def delimiters(raw: bytes) -> list[int]:
    """Byte offsets of the data set delimiters, found exactly as pyuff finds them (so blocks pair the same)."""
    out = []
    n = len(raw)
    pos = raw.find(_DELIMITER)
    while pos != -1:
        end = pos + len(_DELIMITER)
        if end == n or raw[end] in (10, 13) or (end + 74 < n and raw[end : end + 74] == b" " * 74):
            out.append(pos)
        pos = raw.find(_DELIMITER, pos + 1)
    return out


def _block_type(raw: bytes, start: int) -> str:
    """The type field of the data set that starts at delimiter offset ``start`` ("58b", "2411" or "?")."""
    lines = raw[start : start + 200].splitlines()
    field = lines[1][:7].decode("ascii", errors="replace").strip() if len(lines) > 1 else ""
    return field if re.fullmatch(r"\d+b?", field) else "?"


def _line_no(raw: bytes, offset: int) -> int:
    return raw.count(b"\n", 0, offset) + 1


# Values per point (even / uneven abscissa) and bytes per value of the UFF 58 ordinate data types.
_VALUES_PER_POINT = {2: (1, 2), 4: (1, 2), 5: (2, 3), 6: (2, 3)}
_VALUE_BYTES = {2: 4, 4: 8, 5: 4, 6: 8}


def _check_58b(path: Path, raw: bytes, start: int, end: int, index: int) -> None:
    """Refuse a binary 58b data set whose payload is shorter or longer than its header announces.

    The payload must hold ``num_pts`` points of the ordinate data type (record 7); the ID line's byte count
    must not exceed it. pyuff's own writer states ``num_pts * value size`` there even for complex data (half
    the payload), so a byte count below the payload is accepted; one above it means lost bytes. A line break
    before the closing delimiter (a common exporter habit that pyuff tolerates) is allowed.
    """
    block = raw[start:end]
    lines = block.splitlines(True)
    if len(lines) < 13:
        raise UFFError(str(path), f"binary 58b data set has {len(lines) - 1} header lines, expected 12 (truncated)",
                       index)
    header = b"".join(lines[:13])
    payload = len(block) - len(header)
    id_line, rec7 = lines[1].decode("ascii", "replace"), lines[8].decode("ascii", "replace")
    try:
        n_bytes = int(id_line[31:43])
        ord_type, num_pts, spacing = int(rec7[0:10]), int(rec7[10:20]), int(rec7[20:30])
    except ValueError as exc:
        raise UFFError(str(path), f"malformed binary 58b header ({exc})", index, "num_pts") from exc
    if ord_type not in _VALUE_BYTES:
        return  # pyuff refuses it when reading, with its own message
    expected = num_pts * _VALUES_PER_POINT[ord_type][0 if spacing else 1] * _VALUE_BYTES[ord_type]
    extra = payload - expected
    if extra == 0 or (extra in (1, 2) and block[len(block) - extra :] in (b"\n", b"\r\n", b"\r")):
        if n_bytes <= expected:
            return
        raise UFFError(str(path), f"header announces {n_bytes} data bytes but the data set holds {expected}"
                       " (truncated or damaged file)", index, "n_bytes")
    raise UFFError(
        str(path), f"header announces {num_pts} points ({expected} data bytes) but the data set holds {payload} bytes"
        " (truncated or damaged file)", index, "num_pts",
    )


def _check_structure(path: Path, raw: bytes, marks: list[int]) -> None:
    """Refuse files that end inside a data set, and binary 58b data sets of the wrong length.

    pyuff pairs delimiters two by two and silently drops a last data set that has no closing delimiter (a
    truncated file, or one that lost its final ``-1`` line), so such a file would be read as a smaller,
    seemingly whole one. ``marks`` are the delimiters (:func:`delimiters`).
    """
    if len(marks) % 2:
        start = marks[-1]
        raise UFFError(
            str(path),
            f"the last data set (type {_block_type(raw, start)}, from line {_line_no(raw, start)}) has no closing"
            " '-1' line: the file is truncated or damaged",
            len(marks) // 2,
        )
    for index, (start, end) in enumerate(zip(marks[::2], marks[1::2], strict=True)):
        if _block_type(raw, start) == "58b":
            _check_58b(path, raw, start, end, index)


def open_uff(path: Path) -> tuple[Any, np.ndarray]:
    if path.is_dir():
        raise UFFError(str(path), "is a directory, expected a UFF file")
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if not path.is_file():
        raise UFFError(str(path), "not a regular file, expected a UFF file")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise UFFError(str(path), f"cannot be read ({exc.strerror or exc})") from exc
    if not raw or raw.isspace():
        raise UFFError(str(path), "empty file, expected UFF data sets")
    marks = delimiters(raw)
    if not marks:
        what = "binary data" if b"\0" in raw[:4096] else "text"
        raise UFFError(str(path), f"not a UFF file: {what} without any '-1' data set delimiter line")
    _check_structure(path, raw, marks)
    try:
        uff = pyuff.UFF(str(path))
        types = np.asarray(uff.get_set_types(), dtype=int).reshape(-1)
    except Exception as exc:  # pyuff raises bare Exception (and others) on unreadable files
        raise UFFError(str(path), f"not a readable UFF file ({type(exc).__name__}: {exc})") from exc
    if types.size == 0:
        raise UFFError(str(path), "no UFF data sets found")
    return uff, types


def read_set(uff: Any, path: Path, index: int, dtype: int) -> dict:
    try:
        dset = uff.read_sets(int(index))
    except Exception as exc:  # pyuff raises bare Exception (and others) on malformed data sets
        raise UFFError(
            str(path), f"malformed data set type {dtype} ({type(exc).__name__}: {exc})", index
        ) from exc
    if not isinstance(dset, dict):
        raise UFFError(str(path), f"pyuff returned {type(dset).__name__} for data set type {dtype}", index)
    return dset


def required_field(dset: dict, key: str, path: Path, index: int) -> Any:
    if key not in dset:
        raise UFFError(str(path), "required field missing", index, key)
    return dset[key]
