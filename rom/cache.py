"""On-disk cache of reduced components (``.npz``, no pickle), keyed by a SHA-256 of every input.

The key hashes the full FE matrices (CSR data, indices, indptr, shape), the boundary/output DOF sets and
frames, the number of modes, the reductor's name and options, and :data:`FORMAT_VERSION` (bumped whenever
the reduction code changes its results). Any changed input therefore gives a new key: a stale entry is
never reused, it just stays on disk until removed.

Files are ``<cache_dir>/<kind>-<key[:32]>.npz`` holding every array field of the model, ``__kind__``, ``__key__``
and the JSON-encoded ``meta`` as 0-d unicode arrays; optional fields that are ``None`` are simply absent.
Loading uses ``allow_pickle=False``. Writes are atomic (temporary file in the same folder + ``os.replace``).

Policy (whether to cache, where) belongs to the caller (design §1, floor 3); the default folder is
``$BLADETWIN_CACHE`` or ``.cache/bladetwin/`` at the repository root.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .craig_bampton import DEFAULT_N_CB_MODES, CraigBamptonModel, disk_boundary_dofs, reduce_disk
from .cyclic import DEFAULT_N_CC, DEFAULT_N_CYCLIC_MODES, CyclicDiskModel, reduce_disk_cyclic
from .fileio import atomic_path
from .rubin import DEFAULT_N_FREE_MODES, RubinModel, blade_boundary_dofs, reduce_blade

__all__ = [
    "FORMAT_VERSION",
    "default_cache_dir",
    "hash_inputs",
    "save_model",
    "load_model",
    "cached",
    "cache_file",
    "disk_key",
    "blade_key",
    "cached_reduce_disk",
    "cached_reduce_blade",
    "cyclic_disk_key",
    "cached_reduce_disk_cyclic",
]

log = logging.getLogger(__name__)

#: Bump when a reductor's output changes for the same inputs.
FORMAT_VERSION = 1

_MODEL_TYPES = {"CraigBamptonModel": CraigBamptonModel, "RubinModel": RubinModel, "CyclicDiskModel": CyclicDiskModel}
#: The reduced models the cache holds.
_Model = CraigBamptonModel | RubinModel | CyclicDiskModel


def default_cache_dir() -> Path:
    """``$BLADETWIN_CACHE`` if set, else ``<repository>/.cache/bladetwin``."""
    env = os.environ.get("BLADETWIN_CACHE")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1] / ".cache" / "bladetwin"


def _update(h, obj) -> None:
    """Feed a canonical encoding of ``obj`` into the hash ``h``."""
    if sp.issparse(obj):
        A = sp.csr_matrix(obj, dtype=np.float64, copy=True)
        A.sum_duplicates()
        A.sort_indices()
        h.update(f"csr{A.shape}".encode())
        for part in (A.data, A.indices.astype(np.int64), A.indptr.astype(np.int64)):
            h.update(np.ascontiguousarray(part).tobytes())
    elif isinstance(obj, np.ndarray):
        a = np.ascontiguousarray(obj)
        h.update(f"nd{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    elif isinstance(obj, (list, tuple)):
        h.update(f"seq{len(obj)}".encode())
        for o in obj:
            _update(h, o)
    elif isinstance(obj, dict):
        h.update(f"map{len(obj)}".encode())
        for k in sorted(obj):
            _update(h, str(k))
            _update(h, obj[k])
    else:
        h.update(json.dumps(obj, sort_keys=True, default=str).encode())
        h.update(b"|")


def hash_inputs(*inputs) -> str:
    """SHA-256 hex digest of a canonical encoding of ``inputs`` (sparse matrices, arrays, JSON-able values)."""
    h = hashlib.sha256()
    _update(h, ("bladetwin-rom-cache", FORMAT_VERSION))
    for obj in inputs:
        _update(h, obj)
    return h.hexdigest()


def save_model(path: str | os.PathLike, model: _Model, key: str = "") -> Path:
    """Write a reduced model to ``path`` (.npz, atomic)."""
    kind = type(model).__name__
    if kind not in _MODEL_TYPES:
        raise ValueError(f"can only cache {sorted(_MODEL_TYPES)}, got {kind}")
    arrays: dict[str, np.ndarray] = {"__kind__": np.array(kind), "__key__": np.array(key)}
    for f in dataclasses.fields(model):
        v = getattr(model, f.name)
        if v is None:
            continue
        if f.name == "meta":
            arrays["meta"] = np.array(json.dumps(v, sort_keys=True))
        else:
            arrays[f.name] = np.asarray(v)
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
        fh.flush()
        os.fsync(fh.fileno())
    return path


def load_model(path: str | os.PathLike, key: str | None = None) -> _Model:
    """Read a model written by :func:`save_model` (``allow_pickle=False``); check ``key`` when given."""
    with np.load(path, allow_pickle=False) as z:
        kind = str(z["__kind__"])
        if kind not in _MODEL_TYPES:
            raise ValueError(f"{path}: unknown cached model kind {kind!r}")
        if key is not None and str(z["__key__"]) != key:
            raise ValueError(f"{path}: cache key mismatch")
        cls = _MODEL_TYPES[kind]
        kw = {}
        for f in dataclasses.fields(cls):
            if f.name not in z.files:
                continue
            if f.name == "meta":
                kw["meta"] = json.loads(str(z["meta"]))
            else:
                a = z[f.name]
                kw[f.name] = a.item() if a.ndim == 0 else a
    return cls(**kw)


def cached(
    kind: str,
    key: str,
    build: Callable[[], _Model],
    cache_dir: str | os.PathLike | None = None,
) -> _Model:
    """Load ``<cache_dir>/<kind>-<key>.npz`` if present, otherwise ``build()`` and store it."""
    path = cache_file(kind, key, cache_dir)
    if path.exists():
        try:
            model = load_model(path, key)
            log.info("cache hit: %s", path)
            return model
        except (ValueError, OSError, KeyError) as exc:  # corrupt or colliding entry: rebuild
            log.warning("ignoring unreadable cache entry %s (%s)", path, exc)
    model = build()
    save_model(path, model, key)
    log.info("cache store: %s", path)
    return model


def cache_file(kind: str, key: str, cache_dir: str | os.PathLike | None = None) -> Path:
    """Where :func:`cached` keeps the model of ``kind`` with ``key``: ``<cache_dir>/<kind>-<key[:32]>.npz``."""
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    return folder / f"{kind}-{key[:32]}.npz"


def disk_key(bd, slots: Sequence[int] = (1,), n_modes: int = DEFAULT_N_CB_MODES) -> str:
    """Cache key of :func:`cached_reduce_disk`'s model (kind ``"disk-cb"``): every input of the reduction."""
    dofs, rots = disk_boundary_dofs(bd, slots)
    meas = 3 * bd.disk.node_set("meas") + int(bd.disk.meta["meas_direction"]) - 1
    return hash_inputs("craig_bampton", bd.disk.K, bd.disk.M, dofs, rots, meas, int(n_modes), list(slots),
                       bd.n_slots, list(bd.params.grid))


def cached_reduce_disk(
    bd,
    slots: Sequence[int] = (1,),
    n_modes: int = DEFAULT_N_CB_MODES,
    *,
    cache_dir: str | os.PathLike | None = None,
    backend: str = "auto",
    key: str | None = None,
) -> CraigBamptonModel:
    """:func:`rom.craig_bampton.reduce_disk` through the cache (no full basis is cached).

    ``key``: a precomputed :func:`disk_key` for these arguments (it hashes K and M, about 2 s by default).
    """
    key = disk_key(bd, slots, n_modes) if key is None else key
    return cached("disk-cb", key, lambda: reduce_disk(bd, slots, n_modes, backend=backend), cache_dir)


def cached_reduce_blade(
    bd,
    n_modes: int = DEFAULT_N_FREE_MODES,
    *,
    cache_dir: str | os.PathLike | None = None,
    backend: str = "auto",
) -> RubinModel:
    """:func:`rom.rubin.reduce_blade` through the cache (no full basis is cached)."""
    return cached("blade-rubin", blade_key(bd, n_modes), lambda: reduce_blade(bd, n_modes, backend=backend),
                  cache_dir)


def blade_key(bd, n_modes: int = DEFAULT_N_FREE_MODES) -> str:
    """Cache key of :func:`cached_reduce_blade`'s model (kind ``"blade-rubin"``): every input of the reduction."""
    dofs, n_i = blade_boundary_dofs(bd.blade)
    return hash_inputs("rubin", bd.blade.K, bd.blade.M, dofs, n_i, int(n_modes), list(bd.params.grid))


def cyclic_disk_key(bd, n_modes: int = DEFAULT_N_CYCLIC_MODES, n_cc: int = DEFAULT_N_CC, *,
                    base_key: str | None = None) -> str:
    """Cache key of :func:`cached_reduce_disk_cyclic`'s model (kind ``"disk-cyclic"``): every input.

    ``base_key``: the disk's :func:`disk_key` (slot 1, default modes) if already computed; it holds the
    hash of K and M (about 2 s on the default disk), which this key then reuses.
    """
    base = disk_key(bd) if base_key is None else base_key
    dofs, rots = disk_boundary_dofs(bd, range(1, bd.n_slots + 1))
    # The reductor's name changes with its algorithm (the sector harmonics since 2026-11-24), so models built
    # by the whole-disk algorithm before are not read: they agree to 1e-10, but not bit for bit.
    return hash_inputs("cyclic_craig_bampton/sector_harmonics", base, dofs, rots, int(n_modes), int(n_cc))


def cached_reduce_disk_cyclic(
    bd,
    n_modes: int = DEFAULT_N_CYCLIC_MODES,
    n_cc: int = DEFAULT_N_CC,
    *,
    cache_dir: str | os.PathLike | None = None,
    key: str | None = None,
) -> CyclicDiskModel:
    """:func:`rom.cyclic.reduce_disk_cyclic` through the cache (``key``: a precomputed :func:`cyclic_disk_key`)."""
    key = cyclic_disk_key(bd, n_modes, n_cc) if key is None else key
    return cached("disk-cyclic", key, lambda: reduce_disk_cyclic(bd, n_modes, n_cc=n_cc), cache_dir)
