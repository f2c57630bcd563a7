"""The content-addressed store: each node's output under the hash of its inputs (a generalised ``rom.cache``).

An entry is ``<root>/nodes/<function>/<key[:32]>.npz`` written by :mod:`bladetwin.stages.codec` (atomic, no
pickle). The key hashes the node's function, version and parameters and the keys of its inputs
(:func:`node_key`), so a changed input (a picks file, a setting) gives new keys to exactly the nodes that depend
on it, and two campaigns of the same disk find the same reduced models. An entry that cannot be read is
removed and recomputed, with a warning (:meth:`Store.check`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rom.cache import default_cache_dir, hash_inputs
from rom.fileio import atomic_path

from . import codec

__all__ = ["Store", "node_key", "content_key", "FolderMemo"]


def node_key(func_id: str, version: int, params: dict, input_keys: dict[str, str]) -> str:
    """Key of a node's output: SHA-256 of the store's format, its function, version, parameters and its inputs'
    keys."""
    return hash_inputs("node", codec.FORMAT, func_id, int(version), dict(params), dict(input_keys))


def content_key(value) -> str:
    """Key of a value by its content: the hash of its codec encoding (arrays by bytes)."""
    skeleton, arrays = codec.encode(value)
    return hash_inputs("content", skeleton, [arrays[k] for k in sorted(arrays)])


class FolderMemo:
    """A mapping of small arrays on disk, one ``.npy`` per key, shared by worker processes.

    Writes are atomic; an entry that cannot be read reads as absent (so it is computed again).
    """

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)

    def get(self, key: str, default=None):
        try:
            return np.load(self.folder / f"{key}.npy", allow_pickle=False)
        except (OSError, ValueError, EOFError):
            return default

    def __setitem__(self, key: str, value) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.folder / f"{key}.npy") as tmp, open(tmp, "wb") as fh:
            np.save(fh, np.asarray(value, np.float64), allow_pickle=False)


class Store:
    """Stage results on disk, by node function and key.

    Parameters
    ----------
    root : path-like or None
        The store's folder; default ``$BLADETWIN_CACHE`` or ``.cache/bladetwin`` (``rom.cache``'s).
    """

    def __init__(self, root: str | os.PathLike | None = None) -> None:
        self.root = Path(root) if root is not None else default_cache_dir()

    def path(self, func_id: str, key: str) -> Path:
        return self.root / "nodes" / func_id.rsplit(".", 1)[-1] / f"{key[:32]}.npz"

    def has(self, func_id: str, key: str) -> bool:
        return self.path(func_id, key).is_file()

    def check(self, func_id: str, key: str) -> str | None:
        """``None`` if the entry opens; else why not, and the entry is removed (it will be recomputed)."""
        path = self.path(func_id, key)
        try:
            with np.load(path, allow_pickle=False) as z:
                str(z["__skeleton__"]), str(z["__warnings__"])
            return None
        except Exception as exc:  # noqa: BLE001 - any unreadable entry is recomputed, whatever broke it
            path.unlink(missing_ok=True)
            return f"{path}: unreadable store entry ({type(exc).__name__}), recomputed"

    def save(self, func_id: str, key: str, value, warnings: tuple[str, ...] | list[str] = ()) -> Path:
        return codec.save(self.path(func_id, key), value, warnings)

    def warnings(self, func_id: str, key: str) -> list[str]:
        """The user warnings stored with an entry (raised when it was computed)."""
        return codec.load_warnings(self.path(func_id, key))

    def load(self, func_id: str, key: str):
        return codec.load(self.path(func_id, key))

    def memo(self, name: str) -> FolderMemo:
        """A :class:`FolderMemo` under ``<root>/memo/<name>`` (e.g. the refinement's d1b solves)."""
        return FolderMemo(self.root / "memo" / name)
