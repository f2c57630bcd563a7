"""A pickle-free codec for stage results: frozen dataclasses, arrays, sparse matrices and plain values ↔ ``.npz``.

Every stage result is a tree of plain values (``None``, bool, int, float, str, :class:`pathlib.Path`), containers
(list, tuple, dict), NumPy arrays, SciPy sparse matrices and frozen dataclasses of the project's packages. The tree
becomes a JSON skeleton whose leaves point to the arrays, both kept in one ``.npz`` (``allow_pickle=False`` on
read). A dataclass is rebuilt only when its type lives in one of :data:`PACKAGES`, so a store entry can never
instantiate anything else.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import os
import zipfile
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from rom.fileio import atomic_path

__all__ = ["PACKAGES", "FORMAT", "CodecError", "encode", "save", "load", "load_warnings"]

#: The packages whose dataclasses a store entry may name.
PACKAGES = ("ema", "rom", "identify", "bladetwin")
#: Version of the stored types' fields, part of every node's key: raise it when a stored dataclass renames
#: or drops a field, or moves to another module, so old entries are never decoded into the new types
#: (2: ``frequencies_hz`` in ema; 3: each entry holds the warnings its computation raised, so a stored stage still
#: reports them; 4: ``SyntheticPatterns`` and other stored types moved with the packages' split modules).
FORMAT = 4


class CodecError(ValueError):
    """A value that cannot be encoded, or an entry that does not decode."""


def _encode(obj, arrays: dict[str, np.ndarray]):
    if obj is None or isinstance(obj, bool | str):
        return {"v": obj}
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, int | float | complex) and not isinstance(obj, bool):
        return {"c": [obj.real, obj.imag]} if isinstance(obj, complex) else {"v": obj}
    if isinstance(obj, Path):
        return {"p": str(obj)}
    if isinstance(obj, np.ndarray):
        if obj.dtype == object:
            raise CodecError("object arrays cannot be stored")
        name = f"a{len(arrays)}"
        arrays[name] = obj
        return {"a": name}
    if sp.issparse(obj):
        A = sp.csr_matrix(obj)
        return {"sp": type(obj).__name__, "shape": list(A.shape),
                "parts": [_encode(x, arrays) for x in (A.data, A.indices, A.indptr)]}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        cls = type(obj)
        if cls.__module__.split(".")[0] not in PACKAGES:
            raise CodecError(f"{cls.__module__}.{cls.__qualname__}: not a type of {PACKAGES}")
        return {"dc": f"{cls.__module__}:{cls.__qualname__}",
                "f": {f.name: _encode(getattr(obj, f.name), arrays) for f in dataclasses.fields(obj)}}
    if isinstance(obj, dict):
        return {"d": [[_encode(k, arrays), _encode(v, arrays)] for k, v in obj.items()]}
    if isinstance(obj, list | tuple):
        return {"l" if isinstance(obj, list) else "t": [_encode(x, arrays) for x in obj]}
    raise CodecError(f"a {type(obj).__name__} cannot be stored")


def _dataclass(spec: str):
    module, _, qualname = spec.partition(":")
    if module.split(".")[0] not in PACKAGES:
        raise CodecError(f"{spec}: not a type of {PACKAGES}")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    if not (isinstance(obj, type) and dataclasses.is_dataclass(obj)):
        raise CodecError(f"{spec}: not a dataclass")
    return obj


def _decode(node: dict, z):
    tag = next(t for t in ("v", "c", "p", "a", "sp", "dc", "d", "l", "t") if t in node)
    val = node[tag]
    if tag == "v":
        return val
    if tag == "c":
        return complex(*val)
    if tag == "p":
        return Path(val)
    if tag == "a":
        return z[val]
    if tag == "sp":
        data, indices, indptr = (_decode(p, z) for p in node["parts"])
        A = sp.csr_matrix((data, indices, indptr), shape=tuple(node["shape"]))
        return A if val == "csr_matrix" else getattr(sp, val)(A)
    if tag == "dc":
        cls = _dataclass(val)
        values = {k: _decode(v, z) for k, v in node["f"].items()}
        init = {f.name for f in dataclasses.fields(cls) if f.init}
        obj = cls(**{k: v for k, v in values.items() if k in init})
        for k, v in values.items():
            if k not in init:
                object.__setattr__(obj, k, v)
        return obj
    if tag == "d":
        return {_hashable(_decode(k, z)): _decode(v, z) for k, v in val}
    if tag in ("l", "t"):
        items = [_decode(x, z) for x in val]
        return items if tag == "l" else tuple(items)
    raise CodecError(f"unknown tag {tag!r}")


def _hashable(k):
    return tuple(_hashable(x) for x in k) if isinstance(k, list) else k


def encode(value) -> tuple[dict, dict[str, np.ndarray]]:
    """The JSON skeleton of ``value`` and the arrays it points to (what :func:`save` writes)."""
    arrays: dict[str, np.ndarray] = {}
    return _encode(value, arrays), arrays


def save(path: str | os.PathLike, value, warnings: tuple[str, ...] | list[str] = ()) -> Path:
    """Write ``value`` to ``path`` (``.npz``, atomic), with the user ``warnings`` its computation raised.

    Raises :class:`CodecError` for a value it cannot hold.
    """
    skeleton, arrays = encode(value)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, __skeleton__=np.array(json.dumps(skeleton)), __warnings__=np.array(json.dumps(list(warnings))),
                 **arrays)
    return path


def load_warnings(path: str | os.PathLike) -> list[str]:
    """The warnings :func:`save` stored with an entry (``[]`` if it holds none); the value itself is not read."""
    with np.load(path, allow_pickle=False) as z:
        return [str(w) for w in json.loads(str(z["__warnings__"]))] if "__warnings__" in z.files else []


def load(path: str | os.PathLike):
    """Read :func:`save`'s file. Raises :class:`CodecError` (naming the file) for a damaged or foreign one."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return _decode(json.loads(str(z["__skeleton__"])), z)
    except CodecError as exc:
        raise CodecError(f"{path}: {exc}") from None
    except (OSError, ValueError, KeyError, EOFError, TypeError, AttributeError, ImportError,
            zipfile.BadZipFile) as exc:
        raise CodecError(f"{path}: unreadable store entry ({type(exc).__name__}: {exc})") from None
