"""The CSV side files of an imported model: DOF map, node coordinates, node sets and interface grids.

Formats (comma-separated, one header line, ``#`` starts a comment line):

* DOF map — ``row,node,dir``: matrix row (1-based) → node id and direction (1, 2, 3 = x, y, z). Every row of
  the matrices appears exactly once.
* Coordinates — ``node,x,y,z``: one line per node of the mesh, in the model's length unit. A node listed here
  that has no matrix row (all its DOFs constrained) stays in the component, with three constrained DOFs.
* Node sets — ``set,node``: one line per member; the order of the lines is the order of the set (it matters
  for measurement nodes, e.g. the disk's one node per sector in sector order).
* Interface grids — ``slot,flank,row,col,node``: one line per grid node; ``slot`` 0 is the blade root,
  1..N the disk slots; ``row`` and ``col`` are 1-based.

Readers return node *ids*; mapping them to node indices is the component builder's job
(:mod:`rom.importers.build`). Every problem is a one-line :class:`~rom.importers.errors.ModelImportError`
naming the file, the column and the first bad line.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from ..fileio import atomic_path
from .errors import ModelImportError

__all__ = [
    "read_dofmap_csv", "read_coords_csv", "read_node_sets_csv", "read_grids_csv",
    "write_dofmap_csv", "write_coords_csv", "write_node_sets_csv", "write_grids_csv",
]


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _read(path: str | os.PathLike, columns: Mapping[str, str]) -> dict[str, np.ndarray]:
    """Columns of a CSV file as arrays, checked: present, complete, of the right kind ("int", "float", "str").

    Numbers are parsed straight into int64/float64 columns (a 2 M-line DOF map stays ~50 MB); only when that
    fails is the file read again as text, to name the first bad line.
    """
    path = Path(path)
    try:
        head = pd.read_csv(path, comment="#", skipinitialspace=True, nrows=0)
    except FileNotFoundError:
        raise
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise ModelImportError(f"{path}: not a readable CSV file ({_one_line(exc)})") from None
    names = {str(c).strip().lower(): c for c in head.columns}
    missing = [c for c in columns if c not in names]
    if missing:
        raise ModelImportError(f"{path}: missing column(s) {missing}; expected header {','.join(columns)}, "
                               f"got {','.join(names)}")
    kinds = {"int": np.int64, "float": np.float64, "str": str}
    try:
        df = pd.read_csv(path, comment="#", skipinitialspace=True, usecols=[names[c] for c in columns],
                         dtype={names[c]: kinds[k] for c, k in columns.items()}, keep_default_na=False,
                         na_values={names[c]: [""] for c, k in columns.items() if k == "float"})
        out = {c: df[names[c]].to_numpy() for c in columns}
        ok = all(np.isfinite(out[c]).all() for c, k in columns.items() if k == "float")
        ok = ok and all((np.char.str_len(out[c].astype(str)) > 0).all() for c, k in columns.items() if k == "str")
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError, OverflowError):
        ok = False
    if ok and len(df) == 0:
        raise ModelImportError(f"{path}: no data lines under the header {','.join(columns)}")
    if ok:
        return {c: (np.asarray(v, dtype=np.int64) if columns[c] == "int" else v) for c, v in out.items()}
    return _read_slowly(path, columns, names)


def _read_slowly(path: Path, columns: Mapping[str, str], names: Mapping[str, str]) -> dict[str, np.ndarray]:
    """The text path of :func:`_read`: find and name the first line that is not what its column expects."""
    try:
        df = pd.read_csv(path, comment="#", skipinitialspace=True, dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        raise ModelImportError(f"{path}: not a readable CSV file ({_one_line(exc)})") from None
    if len(df) == 0:
        raise ModelImportError(f"{path}: no data lines under the header {','.join(columns)}")
    out: dict[str, np.ndarray] = {}
    for name, kind in columns.items():
        text = df[names[name]].astype(str).str.strip()
        if kind == "str":
            values = text.to_numpy()
            bad = values == ""
        else:
            values = pd.to_numeric(text, errors="coerce").to_numpy(dtype=np.float64)
            bad = ~np.isfinite(values)
            if kind == "int":
                bad |= values != np.round(values)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            expected = {"int": "an integer", "float": "a finite number", "str": "a name"}[kind]
            raise ModelImportError(f"{path}: column {name!r} must hold {expected} on every line; data line {k + 1} "
                                   f"has {text.iloc[k]!r} ({int(bad.sum())} such line(s))")
        out[name] = values.astype(np.int64) if kind == "int" else values
    return out


def read_dofmap_csv(path: str | os.PathLike, n_rows: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read a DOF map.

    Parameters
    ----------
    path : path-like
        CSV with columns ``row,node,dir``.
    n_rows : int, optional
        Matrix size the map must cover exactly (rows 1..n_rows, each once).

    Returns
    -------
    nodes : ndarray of int64, shape (n_rows,)
        Node id of matrix row ``k`` (0-based).
    dirs : ndarray of int64, shape (n_rows,)
        Direction 1..3 of matrix row ``k``.
    """
    t = _read(path, {"row": "int", "node": "int", "dir": "int"})
    rows = t["row"]
    n = int(rows.size) if n_rows is None else int(n_rows)
    in_order = rows.size == n and rows[0] == 1 and bool((np.diff(rows) == 1).all())
    bad = (rows < 1) | (rows > n)
    if bad.any():
        raise ModelImportError(f"{path}: row {int(rows[bad][0])} is outside 1..{n} (the matrix has {n} rows)")
    seen = np.ones(1) if in_order else np.bincount(rows - 1, minlength=n)  # rows 1..n in order: each once
    if (seen > 1).any():
        raise ModelImportError(f"{path}: matrix row {int(np.flatnonzero(seen > 1)[0]) + 1} is mapped "
                               f"{int(seen.max())} times; each row must appear once")
    if (seen == 0).any():
        miss = np.flatnonzero(seen == 0)
        raise ModelImportError(f"{path}: the DOF map does not cover the matrix: {miss.size} of {n} rows have no line "
                               f"(first: row {int(miss[0]) + 1})")
    dirs = t["dir"]
    bad = (dirs < 1) | (dirs > 3)
    if bad.any():
        d = int(dirs[bad][0])
        what = " (a rotation: only translational DOFs 1, 2, 3 = x, y, z are supported)" if 4 <= d <= 6 else ""
        raise ModelImportError(f"{path}: column 'dir' must be 1, 2 or 3 (x, y, z), got {d}{what}")
    if in_order:
        return t["node"], dirs
    order = np.argsort(rows, kind="stable")
    return t["node"][order], dirs[order]


def read_coords_csv(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read node coordinates: ``(node ids (n,), coordinates (n, 3))`` in the file's order and length unit."""
    t = _read(path, {"node": "int", "x": "float", "y": "float", "z": "float"})
    ids = t["node"]
    uniq, counts = np.unique(ids, return_counts=True)
    if (counts > 1).any():
        raise ModelImportError(f"{path}: node {int(uniq[counts > 1][0])} has {int(counts.max())} coordinate lines; "
                               "expected one per node")
    return ids, np.column_stack([t["x"], t["y"], t["z"]])


def read_node_sets_csv(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read named node sets: name → node ids (int64, file order)."""
    t = _read(path, {"set": "str", "node": "int"})
    names, first = np.unique(t["set"], return_index=True)
    out: dict[str, np.ndarray] = {}
    for name in names[np.argsort(first)]:
        ids = t["node"][t["set"] == name]
        if np.unique(ids).size != ids.size:
            raise ModelImportError(f"{path}: node set {name!r} lists a node twice")
        out[str(name)] = ids
    return out


def read_grids_csv(path: str | os.PathLike) -> dict[tuple[int, str], np.ndarray]:
    """Read explicit interface grids: ``(slot, flank)`` → node ids of shape (rows, cols); slot 0 is the blade."""
    t = _read(path, {"slot": "int", "flank": "str", "row": "int", "col": "int", "node": "int"})
    out: dict[tuple[int, str], np.ndarray] = {}
    keys = sorted(set(zip(t["slot"].tolist(), t["flank"].tolist(), strict=True)))
    for slot, flank in keys:
        sel = (t["slot"] == slot) & (t["flank"] == flank)
        r, c, node = t["row"][sel], t["col"][sel], t["node"][sel]
        where = f"{path}: grid of slot {slot} flank {flank!r}"
        if slot < 0:
            raise ModelImportError(f"{path}: slot must be 0 (blade) or a slot number ≥ 1, got {slot}")
        if r.min() < 1 or c.min() < 1:
            raise ModelImportError(f"{where}: row and col are 1-based, got row {int(r.min())}, col {int(c.min())}")
        shape = (int(r.max()), int(c.max()))
        grid = np.full(shape, -1, dtype=np.int64)
        flat = (r - 1) * shape[1] + (c - 1)
        if np.unique(flat).size != flat.size:
            raise ModelImportError(f"{where}: a (row, col) position is given twice")
        grid.ravel()[flat] = node
        if (grid < 0).any():
            i, j = np.argwhere(grid < 0)[0]
            raise ModelImportError(f"{where}: position row {i + 1}, col {j + 1} has no node; a {shape[0]} × "
                                   f"{shape[1]} grid needs all {shape[0] * shape[1]} positions")
        out[(int(slot), str(flank))] = grid
    return out


# ------------------------------------------------------------------------------------------------ writers
def _write(path: str | os.PathLike, columns: Mapping[str, np.ndarray]) -> Path:
    df = pd.DataFrame(dict(columns))
    with atomic_path(path) as tmp:
        # %.17g: every float64 survives the round trip through text exactly.
        df.to_csv(tmp, index=False, float_format="%.17g", lineterminator="\n")
    return Path(path)


def write_dofmap_csv(path: str | os.PathLike, nodes: np.ndarray, dirs: np.ndarray) -> Path:
    """Write a DOF map for matrix rows 1..n: ``nodes`` and ``dirs`` of shape (n,)."""
    return _write(path, {"row": np.arange(1, len(nodes) + 1), "node": np.asarray(nodes), "dir": np.asarray(dirs)})


def write_coords_csv(path: str | os.PathLike, node_ids: np.ndarray, coords: np.ndarray) -> Path:
    """Write node coordinates: ``node_ids`` (n,), ``coords`` (n, 3)."""
    X = np.asarray(coords, dtype=np.float64)
    return _write(path, {"node": np.asarray(node_ids), "x": X[:, 0], "y": X[:, 1], "z": X[:, 2]})


def write_node_sets_csv(path: str | os.PathLike, sets: Mapping[str, np.ndarray]) -> Path:
    """Write node sets: name → node ids (any shape; written flat, row-major)."""
    names = [np.full(np.asarray(ids).size, k, dtype=object) for k, ids in sets.items()]
    ids = [np.asarray(v, dtype=np.int64).ravel() for v in sets.values()]
    return _write(path, {"set": np.concatenate(names), "node": np.concatenate(ids)})


def write_grids_csv(path: str | os.PathLike, grids: Mapping[tuple[int, str], np.ndarray]) -> Path:
    """Write interface grids: ``(slot, flank)`` → node ids of shape (rows, cols); slot 0 is the blade."""
    cols: dict[str, list] = {"slot": [], "flank": [], "row": [], "col": [], "node": []}
    for (slot, flank), g in grids.items():
        g = np.asarray(g, dtype=np.int64)
        r, c = np.indices(g.shape)
        cols["slot"].append(np.full(g.size, slot))
        cols["flank"].append(np.full(g.size, flank, dtype=object))
        cols["row"].append(r.ravel() + 1)
        cols["col"].append(c.ravel() + 1)
        cols["node"].append(g.ravel())
    return _write(path, {k: np.concatenate(v) for k, v in cols.items()})
