"""Atomic file output: write to a temporary file in the target's folder, then rename over the target.

``ema`` has the same helper (``ema.fileio``): the two floor-1 packages may not import each other
(docs/design.md §1), and the floor-3 ``bladetwin`` uses this one.
"""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path"]


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it atomically replaces ``path``.

    The folder is created if needed. On an exception the temporary file is removed and ``path`` is left
    as it was. The result gets the permissions a plain ``open()`` would give (``mkstemp`` creates 0600).
    """
    path = Path(path)
    if path.is_dir():
        # Checked first: os.replace onto a folder fails only after the whole output was written.
        raise IsADirectoryError(errno.EISDIR, "is a directory; expected a file name", str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)
