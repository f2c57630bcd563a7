"""Matrix Market (``.mtx``) coordinate files: a streaming reader and a writer.

The reader parses the entries in chunks (pandas' C tokenizer) and reads the file twice: once to check it and
count the entries of every row of the result, once to write each entry (and its mirror image) straight into
its slot of the final CSR matrix in component numbering. No coordinate list is ever held, so the peak is the
final matrix plus one chunk; ``scipy.io.mmread`` builds a COO matrix of the whole symmetric matrix first and
its CSR conversion copies it again. ``benchmarks/import_memory.py`` compares the two on a 2 M-DOF pair.

Supported: ``matrix coordinate real|double|integer general|symmetric``. A ``symmetric`` file must store one
triangle (the standard says the lower one; the upper one is accepted too). A ``general`` file that holds
only one triangle is taken as that triangle of a symmetric matrix (ANSYS and other codes write their
upper-triangle storage that way; an FE stiffness or mass matrix is never triangular). Refused with a one-line
message: ``array`` (dense) storage, complex/pattern fields, skew-symmetric/hermitian storage, a header count
that disagrees with the entries (truncated or damaged file), indices out of range, non-finite values.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.sparse as sp

from ..fileio import atomic_path
from .build import symmetrized
from .errors import ModelImportError

__all__ = ["MatrixMarketHeader", "read_matrix_market_header", "read_matrix_market", "write_matrix_market"]

log = logging.getLogger(__name__)

_CHUNK = 1 << 18  # entries parsed per step: ~30 MB of temporaries whatever the file size


@dataclass(frozen=True)
class MatrixMarketHeader:
    """The banner and size line of a Matrix Market file.

    Attributes
    ----------
    n_rows, n_cols : int
    nnz : int
        Stored entries announced by the size line.
    field : str
        ``"real"``, ``"double"`` or ``"integer"``.
    symmetry : str
        ``"general"`` or ``"symmetric"``.
    data_offset : int
        Byte offset of the first entry line.
    """

    n_rows: int
    n_cols: int
    nnz: int
    field: str
    symmetry: str
    data_offset: int


def read_matrix_market_header(path: str | os.PathLike) -> MatrixMarketHeader:
    """Parse and check the banner and size line of a Matrix Market file."""
    path = Path(path)
    with open(path, "rb") as fh:
        banner = fh.readline().decode("ascii", "replace").strip()
        parts = banner.split()
        if len(parts) != 5 or parts[0].lower() != "%%matrixmarket":
            raise ModelImportError(f"{path}: not a Matrix Market file (first line {banner[:60]!r}; expected "
                                   "'%%MatrixMarket matrix coordinate real symmetric')")
        obj, fmt, field, symmetry = (p.lower() for p in parts[1:])
        if obj != "matrix":
            raise ModelImportError(f"{path}: Matrix Market object {obj!r} is not supported; expected 'matrix'")
        if fmt != "coordinate":
            raise ModelImportError(f"{path}: Matrix Market format {fmt!r} is not supported; expected 'coordinate' "
                                   "(sparse) storage")
        if field not in ("real", "double", "integer"):
            raise ModelImportError(f"{path}: Matrix Market field {field!r} is not supported; expected 'real'")
        if symmetry not in ("general", "symmetric"):
            raise ModelImportError(f"{path}: Matrix Market symmetry {symmetry!r} is not supported; expected "
                                   "'symmetric' or 'general'")
        while True:
            line = fh.readline()
            if not line:
                raise ModelImportError(f"{path}: no size line after the header (file truncated?)")
            text = line.decode("ascii", "replace").strip()
            if text and not text.startswith("%"):
                break
        try:
            n_rows, n_cols, nnz = (int(v) for v in text.split())
        except ValueError:
            raise ModelImportError(f"{path}: size line must be 'rows columns entries', got {text[:60]!r}") from None
        if n_rows <= 0 or n_cols <= 0 or nnz < 0:
            raise ModelImportError(f"{path}: size line {text!r} must have positive sizes")
        return MatrixMarketHeader(n_rows, n_cols, nnz, field, symmetry, fh.tell())


def _chunks(path: Path, h: MatrixMarketHeader):
    """(first entry number, i, j, v) per chunk of entries, 1-based indices, checked: count, range, finiteness."""
    got = 0
    with open(path, "rb") as fh:
        fh.seek(h.data_offset)
        try:
            reader = pd.read_csv(fh, sep=r"\s+", header=None, names=["i", "j", "v"], comment="%", engine="c",
                                 dtype={"i": np.int64, "j": np.int64, "v": np.float64}, chunksize=_CHUNK)
            for chunk in reader:
                i = chunk["i"].to_numpy()
                j = chunk["j"].to_numpy()
                v = chunk["v"].to_numpy()
                if got + i.size > h.nnz:
                    raise ModelImportError(f"{path}: more entries than the {h.nnz} the size line announces")
                bad = (i < 1) | (i > h.n_rows) | (j < 1) | (j > h.n_cols)
                if bad.any():
                    e = int(np.flatnonzero(bad)[0])
                    raise ModelImportError(f"{path}: entry {got + e + 1} ({i[e]}, {j[e]}) lies outside the "
                                           f"{h.n_rows} × {h.n_cols} matrix")
                if not np.isfinite(v).all():
                    e = int(np.flatnonzero(~np.isfinite(v))[0])
                    raise ModelImportError(f"{path}: entry {got + e + 1} ({i[e]}, {j[e]}) has no finite value")
                yield got, i, j, v
                got += i.size
        except pd.errors.EmptyDataError:  # no entry line at all: the count check below names it
            pass
        except ModelImportError:
            raise
        except (pd.errors.ParserError, ValueError, OverflowError) as exc:
            msg = " ".join(str(exc).split())
            raise ModelImportError(f"{path}: entry lines must be 'row column value' ({msg})") from None
    if got != h.nnz:
        raise ModelImportError(f"{path}: the file ends after {got} of the {h.nnz} entries its size line announces "
                               "(truncated or damaged)")


def read_matrix_market(
    path: str | os.PathLike,
    *,
    index: np.ndarray | None = None,
    n: int | None = None,
    label: str = "K",
) -> tuple[sp.csr_matrix, str]:
    """Read a symmetric matrix from a Matrix Market file, streaming, straight into CSR.

    Two passes over the file, so that no coordinate list is ever held: the first checks the entries and counts
    them per destination row, the second writes each chunk's entries (and their mirror images for one-triangle
    storage) into their final CSR slots. The peak is the final matrix plus one chunk and a few length-n arrays.

    Parameters
    ----------
    path : path-like
    index : ndarray of int64, shape (n_rows,), optional
        Destination row/column of each file row (component DOF numbering); default: the file's own.
    n : int, optional
        Size of the result (default: the file's size).
    label : str
        Matrix name for messages.

    Returns
    -------
    A : scipy.sparse.csr_matrix, shape (n, n), float64
        The full symmetric matrix (entries stored as zeros in the file are kept as stored zeros).
    storage : str
        How the file stored it, e.g. ``"symmetric, lower triangle"``.
    """
    path = Path(path)
    h = read_matrix_market_header(path)
    if h.n_rows != h.n_cols:
        raise ModelImportError(f"{path}: {label} must be square, the file is {h.n_rows} × {h.n_cols}")
    if index is not None and index.size != h.n_rows:
        raise ModelImportError(f"{path}: {label} has {h.n_rows} rows, the DOF map has {index.size}")
    n = h.n_rows if n is None else int(n)
    dest = (lambda k: k - 1) if index is None else (lambda k: index[k - 1])
    own, mirrored, lower, upper = _count_rows(path, h, dest, n)
    half, storage = _storage(path, h, lower, upper, label)
    counts = own + mirrored if half else own
    del own, mirrored
    indptr = _row_pointers(counts)
    del counts
    A = _fill_csr(path, h, dest, indptr, half)
    if not half:
        A = symmetrized(A, str(path), label)  # refused unless symmetric to round-off
    return A, storage


def _count_rows(path: Path, h: MatrixMarketHeader, dest, n: int):
    """Pass 1: check the entries and count them per destination row, as stored and as mirrored (shape (n,) each);
    whether any lies below (``lower``) or above (``upper``) the diagonal."""
    own = np.zeros(n, dtype=np.int64)
    mirrored = np.zeros(n, dtype=np.int64)
    lower = upper = False
    for _, i, j, _v in _chunks(path, h):
        lower = lower or bool((i > j).any())
        upper = upper or bool((i < j).any())
        own += np.bincount(dest(i), minlength=n)
        off = i != j
        mirrored += np.bincount(dest(j[off]), minlength=n)
    return own, mirrored, lower, upper


def _storage(path: Path, h: MatrixMarketHeader, lower: bool, upper: bool, label: str) -> tuple[bool, str]:
    """Whether the file holds one triangle of a symmetric matrix (to be mirrored), and its storage in words."""
    if h.symmetry == "symmetric":
        if lower and upper:
            raise ModelImportError(f"{path}: a 'symmetric' file must store one triangle, this one has entries "
                                   "above and below the diagonal")
        return True, f"symmetric, {'upper' if upper else 'lower'} triangle"
    if lower != upper:
        log.info("%s: general storage of one triangle only, taken as the %s triangle of a symmetric %s", path,
                 "upper" if upper else "lower", label)
        return True, f"general, {'upper' if upper else 'lower'} triangle only (taken as symmetric)"
    return False, "general (full matrix)"


def _row_pointers(counts: np.ndarray) -> np.ndarray:
    """CSR row pointers for ``counts`` entries per row, shape (n + 1,), int32 where the sizes allow."""
    n = counts.size
    nnz = int(counts.sum())
    idx_dtype = np.int32 if max(n, nnz) < 2**31 - 1 else np.int64
    indptr = np.zeros(n + 1, dtype=idx_dtype)
    np.cumsum(counts, out=indptr[1:])
    return indptr


def _fill_csr(path: Path, h: MatrixMarketHeader, dest, indptr: np.ndarray, half: bool) -> sp.csr_matrix:
    """Pass 2: place every entry (and its mirror, with ``half``) in its row's next free slots of the CSR matrix
    with row pointers ``indptr``; indices sorted, duplicates summed."""
    n = indptr.size - 1
    nnz = int(indptr[-1])
    indices = np.empty(nnz, dtype=indptr.dtype)
    data = np.empty(nnz, dtype=np.float64)
    nxt = indptr[:-1].astype(np.int64)  # next free slot of every row
    for _, i, j, v in _chunks(path, h):
        r, c = dest(i), dest(j)
        if half:
            off = i != j
            r, c, v = np.concatenate([r, c[off]]), np.concatenate([c, r[off]]), np.concatenate([v, v[off]])
        order = np.argsort(r, kind="stable")
        rs = r[order]
        new = np.r_[True, rs[1:] != rs[:-1]]
        group = np.flatnonzero(new)
        rank = np.arange(rs.size) - np.repeat(group, np.diff(np.r_[group, rs.size]))
        pos = nxt[rs] + rank
        indices[pos] = c[order]
        data[pos] = v[order]
        nxt[rs[new]] += np.diff(np.r_[group, rs.size])
    del nxt
    A = sp.csr_matrix((data, indices, indptr), shape=(n, n))
    A.sort_indices()
    A.sum_duplicates()  # duplicated entries add up, as FE assembly does
    return A


def write_matrix_market(path: str | os.PathLike, A: sp.spmatrix, *, comment: str = "",
                        symmetry: str = "auto") -> Path:
    """Write a sparse matrix as ``coordinate real``, atomically.

    Parameters
    ----------
    path : path-like
    A : sparse matrix, shape (n, n)
    comment : str
        Written as ``%`` lines after the banner.
    symmetry : {"auto", "symmetric", "general"}
        ``"symmetric"`` stores the lower triangle (A must be symmetric), ``"general"`` every entry; ``"auto"``
        takes ``"symmetric"`` when A is exactly symmetric and ``"general"`` otherwise (FE assembly leaves
        round-off asymmetry: the file then still reproduces the matrix bit for bit).

    Values are written with 17 significant digits, so they read back bit for bit.
    """
    A = sp.csr_matrix(A, dtype=np.float64)
    A.sum_duplicates()
    if symmetry == "auto":
        D = A - A.T
        D.eliminate_zeros()
        symmetry = "symmetric" if D.nnz == 0 else "general"
        del D
    if symmetry not in ("symmetric", "general"):
        raise ValueError(f"symmetry must be 'auto', 'symmetric' or 'general', got {symmetry!r}")
    C = sp.tril(A, format="coo") if symmetry == "symmetric" else A.tocoo()
    with atomic_path(path) as tmp, open(tmp, "w", encoding="ascii", newline="\n") as fh:
        fh.write(f"%%MatrixMarket matrix coordinate real {symmetry}\n")
        for line in comment.splitlines():
            fh.write(f"% {line}\n")
        fh.write(f"{A.shape[0]} {A.shape[1]} {C.nnz}\n")
        for s in range(0, C.nnz, _CHUNK):
            e = min(s + _CHUNK, C.nnz)
            pd.DataFrame({"i": C.row[s:e] + 1, "j": C.col[s:e] + 1, "v": C.data[s:e]}).to_csv(
                fh, sep=" ", header=False, index=False, float_format="%.17g", lineterminator="\n")
    return Path(path)
