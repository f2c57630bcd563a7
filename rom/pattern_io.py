"""Contact-pattern files (docs/rom.md, "Pattern files").

Two formats:

``.npz``
    Boolean (or 0/1 integer) arrays ``L`` and ``R``: shape ``(rows, cols)`` for one joint, or
    ``(n, rows, cols)`` for ``n`` joints (slot 1..n in order). Loaded with ``allow_pickle=False``.
``.txt`` / ``.csv``
    One joint: the L grid as ``rows`` lines of 0/1 values (separated by commas and/or spaces), an empty
    line, then the R grid. Lines starting with ``#`` are comments. Row i, column j is grid node (i, j)
    (rows axial, columns radially outward, as in :mod:`rom.academic`).
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .contact import ContactPattern
from .errors import ROMError
from .fileio import atomic_path

__all__ = ["load_patterns", "save_patterns"]


def _parse_text(text: str, path) -> list[ContactPattern]:
    blocks: list[list[list[int]]] = [[]]
    for raw in text.splitlines():
        line = raw.strip()
        if line.startswith("#"):
            continue
        if not line:
            if blocks[-1]:
                blocks.append([])
            continue
        try:
            blocks[-1].append([int(v) for v in line.replace(",", " ").split()])
        except ValueError:
            raise ROMError(f"{path}: grid lines must hold 0/1 values, got {raw.strip()[:60]!r}") from None
    blocks = [b for b in blocks if b]
    if len(blocks) != 2:
        raise ROMError(f"{path}: expected two grids (L, then R) separated by an empty line, found {len(blocks)}")
    grids = []
    for name, b in zip("LR", blocks, strict=True):
        if len({len(r) for r in b}) != 1:
            raise ROMError(f"{path}: rows of grid {name} have different lengths")
        grids.append(np.array(b))
    return [_pattern(path, grids[0], grids[1])]


def _pattern(path: Path, L: np.ndarray, R: np.ndarray, joint: int | None = None) -> ContactPattern:
    """A :class:`ContactPattern`, its complaints prefixed with the file (and joint) they come from."""
    try:
        return ContactPattern(L, R)
    except ValueError as exc:
        where = f"{path}" + (f", joint {joint}" if joint is not None else "")
        raise ROMError(f"{where}: {exc}") from None


def _load_npz(path: Path) -> tuple[np.ndarray, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = {"L", "R"} - set(z.files)
            if missing:
                raise ROMError(f"{path}: a pattern .npz needs arrays 'L' and 'R'; missing {sorted(missing)}")
            return z["L"], z["R"]
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        if isinstance(exc, ROMError):
            raise
        # A truncated or foreign file: numpy raises any of these; one line for the user instead.
        raise ROMError(f"{path}: not a readable .npz pattern file ({type(exc).__name__}: {exc})") from None


def load_patterns(path: str | os.PathLike) -> list[ContactPattern]:
    """Read one or more contact patterns from a ``.npz`` or text file (see module notes)."""
    path = Path(path)
    if path.is_dir():
        raise ROMError(f"{path}: is a directory, expected a pattern file (.npz, .txt or .csv)")
    if not path.exists():
        raise FileNotFoundError(f"pattern file not found: {path}")
    if path.suffix.lower() == ".npz":
        L, R = _load_npz(path)
        if L.shape != R.shape or L.ndim not in (2, 3):
            raise ROMError(
                f"{path}: L and R must share a shape (rows, cols) or (n, rows, cols); got {L.shape}, {R.shape}"
            )
        if L.ndim == 2:
            return [_pattern(path, L, R)]
        return [_pattern(path, a, b, joint=k + 1) for k, (a, b) in enumerate(zip(L, R, strict=True))]
    if path.suffix.lower() in (".txt", ".csv"):
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ROMError(f"{path}: not a text pattern file (not UTF-8 text); expected 0/1 grids") from None
        return _parse_text(text, path)
    raise ROMError(f"{path}: pattern files must be .npz, .txt or .csv, got {path.suffix!r}")


def save_patterns(path: str | os.PathLike, patterns: Sequence[ContactPattern]) -> Path:
    """Write patterns to ``.npz`` (arrays L, R of shape (n, rows, cols)); atomic."""
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise ValueError(f"save_patterns writes .npz files, got {path.suffix!r}")
    L = np.stack([p.L for p in patterns])
    R = np.stack([p.R for p in patterns])
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, L=L, R=R)
    return path
