"""Nastran OUTPUT4 (``.op4``) matrices: reader and writer, text and binary, real double precision.

Why in-house: pyNastran, the usual Python OP4 reader, pins ``numpy<2`` (version 1.4.1, the latest on PyPI;
``pip install --dry-run pyNastran`` here would replace numpy 2.4 by 1.26.4), which the rest of bladetwin
cannot go back to. The format is small; this module reads, and :mod:`rom.importers.op4_writer` writes, the
part of it that FE matrices use.

The format (as written by MSC/NX Nastran's OUTPUT4 module)
----------------------------------------------------------
A file holds one or more matrices. Each matrix is a header, one record per non-null column, and an
end record:

* **header** — ``NCOL, NROW, FORM, TYPE, NAME``: columns, rows (negative: sparse "BIGMAT" storage), form
  (1 square, 2 rectangular, 6 symmetric, ...), type (1 real single, 2 real double, 3/4 complex) and an
  8-character name. In text files: ``4I8, A8`` then the number format, e.g. ``1P,3E23.16`` (3 numbers of
  width 23 per line).
* **column** — ``ICOL, IROW, NW`` then NW words (a word is 4 bytes; a double takes 2):

  - dense (``IROW > 0``): the values of rows IROW, IROW+1, ... (first to last non-zero of the column);
  - sparse (``IROW = 0``): strings of consecutive non-zeros, each with a header: ``IS = IROW + 65536 (L + 1)``
    (one word) in the classic storage, or ``L + 1, IROW`` (two words) in BIGMAT storage, followed by the
    string's L words of values. BIGMAT is needed beyond 65 535 rows.

* **end** — a column record with ``ICOL = NCOL + 1`` and one dummy value.

Binary files are Fortran unformatted sequential files: every record is framed by its byte length (int32)
before and after; the byte order is detected from the header record's length (24). In text files the
integers are ``I8`` fields and the values fixed-width fields of the header's format; the counts of dense
columns are written as numbers of values (as MSC's and Al Danial's op4 tools write them), and either
numbers or words are accepted on reading.

Supported: real double precision (TYPE 2) matrices, dense and sparse (classic and BIGMAT) storage, text and
binary (either byte order), reading and writing. Refused with a one-line :class:`ModelImportError`: other
types (single precision, complex), 64-bit record words, and any record that does not add up (a damaged or
truncated file is refused, never half read).
"""

from __future__ import annotations

import mmap
import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .errors import ModelImportError
from .op4_writer import write_op4

__all__ = ["Op4Matrix", "read_op4", "write_op4", "BIGMAT_MIN_ROWS"]

#: Classic sparse storage encodes the row in 16 bits: from this many rows on, BIGMAT storage is required.
BIGMAT_MIN_ROWS = 65_536

_TYPES = {1: "real single precision", 2: "real double precision", 3: "complex single precision",
          4: "complex double precision"}


@dataclass(frozen=True, eq=False)
class Op4Matrix:
    """One matrix of an OP4 file.

    Attributes
    ----------
    name : str
        The matrix name (up to 8 characters).
    form : int
        Nastran matrix form (1 square, 2 rectangular, 6 symmetric, ...).
    matrix : scipy.sparse.csc_matrix, shape (n_rows, n_cols)
        The values, float64: zeros inside dense columns are dropped, zeros stored in sparse strings kept.
    storage : str
        ``"dense"``, ``"sparse"`` or ``"bigmat"``.
    """

    name: str
    form: int
    matrix: sp.csc_matrix
    storage: str


class _Columns:
    """Collects (row, column, value) strings of one matrix, then builds the CSC matrix."""

    def __init__(self, path: Path, name: str, n_rows: int, n_cols: int):
        self.path, self.name, self.n_rows, self.n_cols = path, name, n_rows, n_cols
        self.rows: list[np.ndarray] = []
        self.cols: list[np.ndarray] = []
        self.vals: list[np.ndarray] = []
        self.last_col = 0

    def column(self, icol: int, where: str) -> None:
        if not 1 <= icol <= self.n_cols:
            raise ModelImportError(f"{self.path}: matrix {self.name!r}: column {icol} outside 1..{self.n_cols} "
                                   f"({where}; damaged file?)")
        if icol <= self.last_col:
            raise ModelImportError(f"{self.path}: matrix {self.name!r}: column {icol} after column {self.last_col}; "
                                   f"columns must come in increasing order ({where}; damaged file?)")
        self.last_col = icol

    def add(self, icol: int, irow: int, values: np.ndarray, where: str, dense: bool) -> None:
        """One run of values from row ``irow`` (1-based) down."""
        self.add_runs(icol, [irow], [values.size], values, where, dense)

    def add_runs(self, icol: int, starts: list[int], counts: list[int], values: np.ndarray, where: str,
                 dense: bool) -> None:
        """Runs of consecutive rows of one column: run k starts at row ``starts[k]`` (1-based) and has
        ``counts[k]`` of the concatenated ``values``."""
        n = len(starts)
        self.add_all(np.full(n, icol, dtype=np.int64), starts, counts, np.full(n, dense), values,
                     f"column {icol}, {where}")

    def add_all(self, cols: np.ndarray, starts: np.ndarray, counts: np.ndarray, dense: np.ndarray,
                values: np.ndarray, where: str) -> None:
        """Every run of a matrix at once: run k is column ``cols[k]``, rows ``starts[k]`` on, ``counts[k]`` values."""
        c = np.asarray(counts, dtype=np.int64)
        r0 = np.asarray(starts, dtype=np.int64)
        bad = (r0 < 1) | (r0 - 1 + c > self.n_rows)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise ModelImportError(f"{self.path}: matrix {self.name!r} column {int(cols[k])}: rows {r0[k]}.."
                                   f"{r0[k] + c[k] - 1} outside 1..{self.n_rows} ({where}; damaged file?)")
        if not np.isfinite(values).all():
            raise ModelImportError(f"{self.path}: matrix {self.name!r}: non-finite value ({where})")
        first = np.cumsum(c) - c
        rows = np.repeat(r0 - 1 - first, c) + np.arange(values.size, dtype=np.int64)
        col = np.repeat(np.asarray(cols, dtype=np.int64) - 1, c)
        # Zeros inside dense columns are padding; zeros written in sparse strings are stored structure.
        keep = ~np.repeat(np.asarray(dense, bool), c) | (values != 0)
        self.rows.append(rows[keep])
        self.cols.append(col[keep])
        self.vals.append(values[keep])

    def matrix(self) -> sp.csc_matrix:
        if self.vals:
            r, c, v = np.concatenate(self.rows), np.concatenate(self.cols), np.concatenate(self.vals)
        else:
            r = c = np.zeros(0, np.int64)
            v = np.zeros(0)
        A = sp.csc_matrix((v, (r, c)), shape=(self.n_rows, self.n_cols))
        A.sort_indices()
        return A


def _open_matrix(path: Path, name: str, ncol: int, nrow: int, mtype: int, where: str) -> tuple[_Columns, bool]:
    """Check a matrix header (text or binary) and start its accumulator.

    Returns the accumulator and whether the columns are stored as BIGMAT (``nrow < 0``, or so many rows that
    Nastran writes BIGMAT regardless). ``where`` prefixes the messages (e.g. ``"line 12: "``).
    """
    if mtype != 2:
        what = _TYPES.get(mtype, f"unknown type {mtype}")
        raise ModelImportError(f"{path}: matrix {name!r} is {what} (TYPE {mtype}); only real double precision "
                               "(TYPE 2) is supported: export it with OUTPUT4 in double precision")
    if ncol <= 0 or nrow == 0:
        raise ModelImportError(f"{path}: {where}matrix {name!r} header has {nrow} rows and {ncol} columns")
    n_rows = abs(nrow)
    return _Columns(path, name, n_rows, ncol), nrow < 0 or n_rows >= BIGMAT_MIN_ROWS


# ------------------------------------------------------------------------------------------------ reading
def read_op4(path: str | os.PathLike, names: list[str] | None = None) -> dict[str, Op4Matrix]:
    """Read the matrices of an OP4 file (text or binary, detected).

    Parameters
    ----------
    path : path-like
    names : list of str, optional
        Keep only these matrices (all are still checked as they are read past).

    Returns
    -------
    dict name → Op4Matrix, in file order.
    """
    path = Path(path)
    with open(path, "rb") as fh:
        head = fh.read(8)
    if len(head) < 8:
        raise ModelImportError(f"{path}: too short to be an OP4 file ({len(head)} bytes)")
    first_le = struct.unpack("<i", head[:4])[0]
    first_be = struct.unpack(">i", head[:4])[0]
    if first_le in (24, 48) or first_be in (24, 48):
        if 48 in (first_le, first_be):
            raise ModelImportError(f"{path}: binary OP4 with 64-bit words is not supported; write it with 32-bit "
                                   "words (the default of OUTPUT4)")
        found = _read_binary(path, "<" if first_le == 24 else ">")
    else:
        found = _read_text(path)
    if not found:
        raise ModelImportError(f"{path}: no matrix found (empty OP4 file?)")
    out = {}
    for m in found:
        if m.name in out:
            raise ModelImportError(f"{path}: two matrices are called {m.name!r}")
        if names is None or m.name in names:
            out[m.name] = m
    if names is not None:
        missing = [n for n in names if n not in out]
        if missing:
            raise ModelImportError(f"{path}: no matrix {missing[0]!r}; the file holds {[m.name for m in found]}")
    return out


def _read_binary(path: Path, e: str) -> list[Op4Matrix]:
    i4 = np.dtype(e + "i4")
    f8 = np.dtype(e + "f8")
    one, two = struct.Struct(e + "i"), struct.Struct(e + "2i")
    out: list[Op4Matrix] = []
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        size = len(buf)

        def record(pos: int) -> tuple[int, int]:
            """Start and length of the record at ``pos``; checks both length markers."""
            if pos + 4 > size:
                raise ModelImportError(f"{path}: truncated at byte {pos} (a record was expected)")
            n = int(np.frombuffer(buf, i4, 1, pos)[0])
            end = pos + 4 + n
            if n < 0 or end + 4 > size or int(np.frombuffer(buf, i4, 1, end)[0]) != n:
                raise ModelImportError(f"{path}: damaged or truncated record at byte {pos} (length {n} does not match "
                                       "its end marker)")
            return pos + 4, n

        pos = 0
        while pos < size:
            start, n = record(pos)
            if n != 24:
                raise ModelImportError(f"{path}: expected a matrix header record (24 bytes) at byte {pos}, got {n}")
            ncol, nrow, form, mtype = (int(v) for v in np.frombuffer(buf, i4, 4, start))
            name = bytes(buf[start + 16:start + 24]).decode("ascii", "replace").strip()
            acc, bigmat = _open_matrix(path, name, ncol, nrow, mtype, "")
            storage = "dense"
            pos = start + n + 4
            while True:
                start, n = record(pos)
                where = f"record at byte {pos}"
                if n < 12:
                    raise ModelImportError(f"{path}: matrix {name!r}: column record too short at byte {pos}")
                icol, irow, nw = (int(v) for v in np.frombuffer(buf, i4, 3, start))
                pos = start + n + 4
                if icol > ncol:  # end record
                    break
                if nw * 4 != n - 12 or nw < 0:
                    raise ModelImportError(f"{path}: matrix {name!r} column {icol}: {nw} words announced, the record "
                                           f"holds {(n - 12) / 4:g} ({where})")
                acc.column(icol, where)
                if irow > 0:
                    if nw % 2:
                        raise ModelImportError(f"{path}: matrix {name!r} column {icol}: odd word count {nw} for "
                                               f"doubles ({where})")
                    acc.add(icol, irow, np.frombuffer(buf, f8, nw // 2, start + 12).astype(np.float64), where, True)
                    continue
                if irow < 0:
                    raise ModelImportError(f"{path}: matrix {name!r} column {icol}: row {irow} ({where})")
                storage = "bigmat" if bigmat else "sparse"
                starts, counts, chunks = [], [], []
                w = 0
                while w < nw:
                    off = start + 12 + 4 * w
                    if bigmat:
                        if w + 2 > nw:
                            raise ModelImportError(f"{path}: matrix {name!r} column {icol}: string header cut "
                                                   f"({where})")
                        lp1, r0 = two.unpack_from(buf, off)
                        length, w = lp1 - 1, w + 2
                    else:
                        (word,) = one.unpack_from(buf, off)
                        length = word // 65536 - 1
                        r0, w = word - 65536 * (length + 1), w + 1
                    if length <= 0 or length % 2 or w + length > nw:
                        raise ModelImportError(f"{path}: matrix {name!r} column {icol}: string of {length} words does "
                                               f"not fit the record ({where}; damaged file?)")
                    vstart = start + 12 + 4 * w
                    chunks.append(buf[vstart:vstart + 4 * length])
                    starts.append(r0)
                    counts.append(length // 2)
                    w += length
                vals = np.frombuffer(b"".join(chunks), f8).astype(np.float64)
                acc.add_runs(icol, starts, counts, vals, where, False)
            out.append(Op4Matrix(name, form, acc.matrix(), storage))
    return out


_INT_LINE = re.compile(r"^[\s+\-0-9]+$")
_FMT = re.compile(r"(\d+)\s*[EDed]\s*(\d+)\s*\.\s*(\d+)")


def _ints(line: str, n: int) -> list[int] | None:
    """``n`` I8 fields (or whitespace-separated integers when the fields do not parse)."""
    try:
        fields = [int(line[8 * i:8 * i + 8]) for i in range(n)]
        if len(line.rstrip()) <= 8 * n:
            return fields
    except ValueError:
        pass
    parts = line.split()
    if len(parts) == n and all(p.lstrip("+-").isdigit() for p in parts):
        return [int(p) for p in parts]
    return None


class _Text:
    """The non-blank lines of a text OP4 file, classified once into integer lines (headers of matrices, columns
    and strings) and value lines."""

    def __init__(self, path: Path):
        self.path = path
        with open(path, encoding="ascii", errors="replace") as fh:
            numbered = [(k, line.rstrip("\r\n")) for k, line in enumerate(fh, start=1)]
        numbered = [(k, line) for k, line in numbered if line.strip()]
        self.lno = [k for k, _ in numbered]
        self.lines = [line for _, line in numbered]
        is_int = np.fromiter((_INT_LINE.match(line) is not None for line in self.lines), bool, len(self.lines))
        # next_int[i]: index of the first integer line at or after i (len(lines) if none).
        ints = np.r_[np.flatnonzero(is_int), len(self.lines)]
        self.next_int = ints[np.searchsorted(ints, np.arange(len(self.lines) + 1))]
        self._width = 0
        self._cum = np.zeros(1, np.int64)

    def fields_between(self, a: int, b: int, width: int) -> int:
        """Number of value fields on lines a..b−1 (a field per ``width`` characters, the last one may be short)."""
        if width != self._width:
            nf = np.fromiter(((len(t) + width - 1) // width for t in self.lines), np.int64, len(self.lines))
            self._cum, self._width = np.r_[0, np.cumsum(nf)], width
        return int(self._cum[b] - self._cum[a])

    def parse(self, blocks: list[tuple[int, int]], per_line: int, width: int) -> np.ndarray:
        """The numbers on the value lines of ``blocks`` (ranges of line indices), in order, in one conversion."""
        lines, fields = self.lines, []
        for a, b in blocks:
            for i in range(a, b):
                text = lines[i]
                if len(text) > per_line * width:
                    raise ModelImportError(f"{self.path}: line {self.lno[i]}: longer than {per_line} numbers of "
                                           f"width {width}")
                fields.extend(text[f:f + width] for f in range(0, len(text), width))
        try:
            return np.array(fields, dtype=str).astype(np.float64)
        except ValueError:
            pass
        out = []  # slow path: accept Fortran's D exponents, or name the first field that is not a number
        for a, b in blocks:
            for i in range(a, b):
                text = lines[i]
                for f in range(0, len(text), width):
                    field = text[f:f + width].strip()
                    try:
                        out.append(float(field.replace("D", "E").replace("d", "e")))
                    except ValueError:
                        raise ModelImportError(f"{self.path}: line {self.lno[i]}: {field!r} is not a number (fields "
                                               f"of width {width})") from None
        return np.asarray(out, dtype=np.float64)


def _read_text(path: Path) -> list[Op4Matrix]:
    src = _Text(path)
    out: list[Op4Matrix] = []
    i = 0
    while i < len(src.lines):
        matrix, i = _text_matrix(src, i)
        out.append(matrix)
    return out


def _text_header(src: _Text, i: int) -> tuple[str, int, int, int, int, int, int]:
    """The matrix header on non-blank line ``i``: name, NCOL, NROW, FORM, TYPE, and the numbers per line and the
    field width of its number format."""
    path, lno, line = src.path, src.lno[i], src.lines[i]
    try:
        ncol, nrow, form, mtype = (int(line[8 * c:8 * c + 8]) for c in range(4))
    except ValueError:
        raise ModelImportError(f"{path}: line {lno}: expected a matrix header (NCOL, NROW, FORM, TYPE as I8, "
                               f"name, format), got {line[:60]!r}") from None
    name = line[32:40].strip()
    fmt = _FMT.search(line[40:])
    if fmt is None:
        raise ModelImportError(f"{path}: line {lno}: matrix {name!r} header has no number format such as "
                               f"'1P,3E23.16' (got {line[40:].strip()!r})")
    return name, ncol, nrow, form, mtype, int(fmt.group(1)), int(fmt.group(2))


def _text_matrix(src: _Text, i: int) -> tuple[Op4Matrix, int]:
    """The matrix whose header is non-blank line ``i``, and the index of the line after its end record."""
    path, lines, n = src.path, src.lines, len(src.lines)
    name, ncol, nrow, form, mtype, per_line, width = _text_header(src, i)
    acc, bigmat = _open_matrix(path, name, ncol, nrow, mtype, f"line {src.lno[i]}: ")
    storage = "dense"
    # Walk the integer lines; value lines are only counted here and parsed at the end, all at once.
    blocks: list[tuple[int, int]] = []
    runs: list[tuple[int, int, int, bool]] = []  # (column, first row, count, dense)
    i += 1
    while True:
        if i >= n:
            raise ModelImportError(f"{path}: matrix {name!r} ends without its end record (truncated file?)")
        lno, line = src.lno[i], lines[i]
        head = _ints(line, 3)
        if head is None:
            raise ModelImportError(f"{path}: line {lno}: expected a column header ICOL, IROW, NW in matrix "
                                   f"{name!r}, got {line[:60]!r}")
        icol, irow, nw = head
        where = f"line {lno}"
        stop = int(src.next_int[i + 1])
        if icol > ncol:  # end record and the line of its dummy value
            i = min(i + 2, stop)
            break
        acc.column(icol, where)
        if irow > 0:
            count = src.fields_between(i + 1, stop, width)
            if nw not in (count, 2 * count):
                raise ModelImportError(f"{path}: {where}: matrix {name!r} column {icol} announces {nw} numbers "
                                       f"(or words), {count} follow (damaged file?)")
            blocks.append((i + 1, stop))
            runs.append((icol, irow, count, True))
            i = stop
            continue
        if irow < 0:
            raise ModelImportError(f"{path}: {where}: matrix {name!r} column {icol} has row {irow}")
        storage = "bigmat" if bigmat else "sparse"
        i, used = _text_strings(src, i + 1, (name, icol, nw), bigmat, width, blocks, runs)
        if used != nw:
            raise ModelImportError(f"{path}: {where}: matrix {name!r} column {icol} announces {nw} words, its "
                                   f"strings hold {used} (damaged file?)")
    if runs:
        vals = src.parse(blocks, per_line, width)
        cols, r0, counts, dense = (np.array(v) for v in zip(*runs, strict=True))
        acc.add_all(cols, r0, counts, dense, vals, f"matrix ending at line {lno}")
    return Op4Matrix(name, form, acc.matrix(), storage), i


def _text_strings(src: _Text, i: int, column: tuple[str, int, int], bigmat: bool, width: int,
                  blocks: list[tuple[int, int]], runs: list[tuple[int, int, int, bool]]) -> tuple[int, int]:
    """Read the strings of a sparse column from non-blank line ``i`` on, appending their value lines to
    ``blocks`` and their runs to ``runs``.

    ``column`` is (matrix name, ICOL, NW): strings are read until NW words are used. Returns the index of the
    line after the last string and the words used.
    """
    path, lines, n = src.path, src.lines, len(src.lines)
    name, icol, nw = column
    used = 0
    while used < nw:
        if i >= n:
            raise ModelImportError(f"{path}: matrix {name!r} column {icol} is cut short (truncated file?)")
        k, text = src.lno[i], lines[i]
        got = _ints(text, 2 if bigmat else 1)
        if got is None:
            raise ModelImportError(f"{path}: line {k}: expected a {'BIGMAT ' if bigmat else ''}string header "
                                   f"in matrix {name!r} column {icol}, got {text[:60]!r}")
        if bigmat:
            length, r0 = got[0] - 1, got[1]
            used += 2
        else:
            length = got[0] // 65536 - 1
            r0 = got[0] - 65536 * (length + 1)
            used += 1
        if length <= 0 or length % 2:
            raise ModelImportError(f"{path}: line {k}: string of {length} words in matrix {name!r} column "
                                   f"{icol} (expected an even, positive count)")
        stop = int(src.next_int[i + 1])
        count = src.fields_between(i + 1, stop, width)
        if count != length // 2:
            raise ModelImportError(f"{path}: line {k}: string announces {length // 2} values, {count} follow "
                                   f"(matrix {name!r} column {icol}; damaged file?)")
        blocks.append((i + 1, stop))
        runs.append((icol, r0, count, False))
        used += length
        i = stop
    return i, used
