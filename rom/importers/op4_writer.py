"""Nastran OUTPUT4 (``.op4``) writer: real double precision, text or binary, dense or sparse (BIGMAT) columns.

The format, and why bladetwin reads and writes it itself, are in :mod:`rom.importers.op4`.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..fileio import atomic_path

__all__ = ["write_op4"]


def _strings(rows: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) positions of the runs of consecutive row numbers in a sorted column."""
    if rows.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(rows) != 1) + 1
    starts = np.r_[0, cuts]
    stops = np.r_[cuts, rows.size]
    return list(zip(starts.tolist(), stops.tolist(), strict=True))


def _form_of(A: sp.csc_matrix) -> int:
    if A.shape[0] != A.shape[1]:
        return 2
    D = A - A.T
    return 6 if D.nnz == 0 or np.abs(D.data).max() == 0 else 1


def write_op4(
    path: str | os.PathLike,
    matrices: Mapping[str, sp.spmatrix | np.ndarray],
    *,
    binary: bool = True,
    sparse: bool = True,
    endian: str = "<",
) -> Path:
    """Write matrices to an OP4 file, atomically, in real double precision.

    Parameters
    ----------
    path : path-like
    matrices : mapping name → matrix, shape (n_rows, n_cols)
        Names of at most 8 ASCII characters; values are written as float64. The form is 6 (symmetric) for an
        exactly symmetric matrix, 1 for another square one, 2 for a rectangular one.
    binary : bool
        Fortran unformatted binary (default) or text (``1P,3E23.16``, 17 significant digits: exact).
    sparse : bool
        Sparse BIGMAT column storage (default) or dense columns (first to last non-zero of each column).
    endian : {"<", ">"}
        Byte order of binary files.
    """
    if endian not in ("<", ">"):
        raise ValueError(f"endian must be '<' or '>', got {endian!r}")
    prepared = []
    for name, A in matrices.items():
        if not (isinstance(name, str) and 0 < len(name) <= 8 and name.isascii() and " " not in name):
            raise ValueError(f"OP4 matrix names have 1..8 ASCII characters without spaces, got {name!r}")
        A = sp.csc_matrix(A, dtype=np.float64)
        A.sum_duplicates()  # explicit zeros stay: sparse storage writes them, so the structure reads back
        A.sort_indices()
        if not np.isfinite(A.data).all():
            raise ValueError(f"matrix {name!r} has non-finite values")
        mag = np.abs(A.data[A.data != 0])
        if not binary and mag.size and (mag.max() >= 1e100 or mag.min() < 1e-99):
            raise ValueError(f"matrix {name!r} has values beyond 1e±99, which E23.16 cannot hold: write binary")
        prepared.append((name, A))
    with atomic_path(path) as tmp:
        if binary:
            with open(tmp, "wb") as fh:
                for name, A in prepared:
                    _write_binary(fh, name, A, sparse, endian)
        else:
            with open(tmp, "w", encoding="ascii", newline="\n") as fh:
                for name, A in prepared:
                    _write_text(fh, name, A, sparse)
    return Path(path)


def _dense_segment(rows: np.ndarray, vals: np.ndarray) -> tuple[int, np.ndarray]:
    """A dense column's one stored segment: its first row (0-based) and the values from there to its last
    nonzero, zeros between (a dense OP4 column is written from its first to its last nonzero)."""
    first, last = int(rows[0]), int(rows[-1])
    col = np.zeros(last - first + 1)
    col[rows - first] = vals
    return first, col


def _nonempty_columns(A: sp.csc_matrix):
    """``(j, rows, values)`` of every column of ``A`` that holds entries (OP4 writes no record for the others)."""
    for j in range(A.shape[1]):
        lo, hi = A.indptr[j], A.indptr[j + 1]
        if lo < hi:
            yield j, A.indices[lo:hi], A.data[lo:hi]


def _write_binary(fh, name: str, A: sp.csc_matrix, sparse: bool, e: str) -> None:
    n_rows, n_cols = A.shape
    i4, f8 = e + "i4", e + "f8"
    head = struct.pack(e + "5i", 24, n_cols, -n_rows if sparse else n_rows, _form_of(A), 2)
    fh.write(head + name.ljust(8).encode("ascii") + struct.pack(e + "i", 24))
    for j, rows, vals in _nonempty_columns(A):
        if not sparse:
            first, col = _dense_segment(rows, vals)
            n = 12 + 8 * col.size
            fh.write(struct.pack(e + "4i", n, j + 1, first + 1, 2 * col.size))
            fh.write(col.astype(f8).tobytes())
            fh.write(struct.pack(e + "i", n))
            continue
        parts = []
        nw = 0
        for s, t in _strings(rows):
            k = t - s
            parts.append(np.array([2 * k + 1, rows[s] + 1], dtype=i4).tobytes())
            parts.append(vals[s:t].astype(f8).tobytes())
            nw += 2 + 2 * k
        n = 12 + 4 * nw
        fh.write(struct.pack(e + "4i", n, j + 1, 0, nw))
        fh.write(b"".join(parts))
        fh.write(struct.pack(e + "i", n))
    fh.write(struct.pack(e + "4i", 20, n_cols + 1, 1, 2) + struct.pack(e + "d", 1.0) + struct.pack(e + "i", 20))


def _value_lines(vals: np.ndarray) -> str:
    text = [f"{v:23.16E}" for v in vals.tolist()]
    return "".join("".join(text[k:k + 3]) + "\n" for k in range(0, len(text), 3))


def _write_text(fh, name: str, A: sp.csc_matrix, sparse: bool) -> None:
    n_rows, n_cols = A.shape
    fh.write(f"{n_cols:8d}{-n_rows if sparse else n_rows:8d}{_form_of(A):8d}{2:8d}{name:<8s}1P,3E23.16\n")
    for j, rows, vals in _nonempty_columns(A):
        if not sparse:
            first, col = _dense_segment(rows, vals)
            fh.write(f"{j + 1:8d}{first + 1:8d}{col.size:8d}\n")
            fh.write(_value_lines(col))
            continue
        runs = _strings(rows)
        nw = sum(2 + 2 * (t - s) for s, t in runs)
        fh.write(f"{j + 1:8d}{0:8d}{nw:8d}\n")
        for s, t in runs:
            fh.write(f"{2 * (t - s) + 1:8d}{int(rows[s]) + 1:8d}\n")
            fh.write(_value_lines(vals[s:t]))
    fh.write(f"{n_cols + 1:8d}{1:8d}{1:8d}\n")
    fh.write(_value_lines(np.array([1.0])))
