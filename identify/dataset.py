"""The identification dataset (paper §6.3, Fig. 17): the record and its Parquet storage.

A :class:`Dataset` holds, for every sample (a δ row × a pattern pair), the frequencies of the ``n_modes``
tracked disk–one-blade modes; :mod:`identify.dataset_build` builds it, :mod:`identify.dataset_parts` in
resumable parts.

Storage: Parquet (pyarrow), one row per sample (columns ``delta_1..k``, ``i_L``, ``i_R``, ``f_1..n``,
``error_bound``, ``fallback``, ``mac_min``), and the rest in the schema metadata under
``b"bladetwin.identify.dataset"`` as JSON (format version, model key, grid, pattern grids as 0/1 strings,
feature modes, weights, δ grid). :func:`save_dataset` writes atomically; :func:`load_dataset` validates
everything and refuses a dataset made with another ROM (:func:`identify.tracking.model_key`).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rom.fileio import atomic_path

from .delta_grid import off_grid
from .errors import IdentifyError
from .sensitivity import check_features, check_patterns, check_weights

__all__ = [
    "Dataset",
    "save_dataset",
    "load_dataset",
    "FORMAT_VERSION",
]

#: Parquet layout version (bump on incompatible changes).
FORMAT_VERSION = 1
_META_KEY = b"bladetwin.identify.dataset"
_FORMAT = "bladetwin.identify.dataset"
#: Rows per Parquet batch read by :func:`load_dataset`.
_READ_BATCH = 262_144


@dataclass(frozen=True, eq=False)
class Dataset:
    """Tracked disk–one-blade frequencies over a δ grid and all pattern pairs (paper §6.3).

    Attributes
    ----------
    deltas : ndarray of float64, shape (n_samples, n_delta_modes)
        Blade mistuning of each sample, relative (0.01 = 1 %), values of ``delta_grid``.
    pair : ndarray of int64, shape (n_samples, 2)
        Pattern pair ``(i_L, i_R)``, 0-based rows of ``patterns_L`` and ``patterns_R``.
    frequencies_hz : ndarray of float64, shape (n_samples, n_modes)
        Frequency of tracked mode ``m`` (the reference pair's m-th mode, paper Eq. 34), Hz.
    patterns_L, patterns_R : ndarray of bool, shape (n_L, rows, cols), (n_R, rows, cols)
    feature_modes : tuple of int
        0-based columns of ``frequencies_hz`` used as k-NN features.
    weights : ndarray of float64, shape (n_features,)
        Weights of Eq. 33 for the features.
    delta_grid : ndarray of float64, shape (n_values,)
        Grid values (relative), shared by every δ mode.
    model_key : str
        :func:`identify.tracking.model_key` of the ROM that made the dataset.
    error_bound : ndarray of float64, shape (n_samples,)
        Largest bound on the relative frequency error of the sample's tracked modes; NaN for fallbacks
        (solved directly).
    fallback : ndarray of bool, shape (n_samples,)
        Samples solved by a direct dense solve.
    mac_min : ndarray of float64, shape (n_samples,)
        Smallest MAC of the sample's tracked modes with its pair's δ = 0 modes.
    meta : dict
        Provenance: reference pair, n_fallbacks, tolerances, formulation, build time.
    """

    deltas: np.ndarray
    pair: np.ndarray
    frequencies_hz: np.ndarray
    patterns_L: np.ndarray
    patterns_R: np.ndarray
    feature_modes: tuple[int, ...]
    weights: np.ndarray
    delta_grid: np.ndarray
    model_key: str
    error_bound: np.ndarray | None = None
    fallback: np.ndarray | None = None
    mac_min: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        D = _readonly(self.deltas, np.float64, "deltas", 2)
        P = _readonly(self.pair, np.int64, "pair", 2)
        F = _readonly(self.frequencies_hz, np.float64, "frequencies_hz", 2)
        n = D.shape[0]
        if P.shape != (n, 2) or F.shape[0] != n:
            raise IdentifyError(f"dataset fields disagree: deltas {D.shape}, pair {P.shape}, frequencies_hz {F.shape}; "
                                "expected (n_samples, k), (n_samples, 2), (n_samples, n_modes)")
        PL = check_patterns(self.patterns_L, "patterns_L")
        PR = check_patterns(self.patterns_R, "patterns_R", PL.shape[1:])
        if n and ((P.min(axis=0) < 0).any() or (P.max(axis=0) >= (len(PL), len(PR))).any()):
            raise IdentifyError(f"dataset.pair holds indices outside 0..{len(PL) - 1} (L) / 0..{len(PR) - 1} (R)")
        modes = check_features(self.feature_modes, F.shape[1])
        w = check_weights(self.weights, len(modes))
        w.flags.writeable = False
        g = _readonly(self.delta_grid, np.float64, "delta_grid", 1)
        if not isinstance(self.model_key, str) or not self.model_key:
            raise IdentifyError(f"dataset.model_key must be a non-empty string, got {self.model_key!r}")
        for name, dtype in (("error_bound", np.float64), ("fallback", bool), ("mac_min", np.float64)):
            v = getattr(self, name)
            if v is not None:
                v = _readonly(v, dtype, name, 1)
                if v.shape != (n,):
                    raise IdentifyError(f"dataset.{name} has shape {v.shape}, expected ({n},)")
                object.__setattr__(self, name, v)
        for name, v in (("deltas", D), ("pair", P), ("frequencies_hz", F), ("patterns_L", PL), ("patterns_R", PR),
                        ("feature_modes", modes), ("weights", w), ("delta_grid", g)):
            object.__setattr__(self, name, v)
        object.__setattr__(self, "meta", dict(self.meta))

    @property
    def n_samples(self) -> int:
        return int(self.deltas.shape[0])

    @property
    def features_hz(self) -> np.ndarray:
        """``frequencies_hz[:, feature_modes]``, shape (n_samples, n_features)."""
        return self.frequencies_hz[:, list(self.feature_modes)]

    def check_model(self, key: str) -> None:
        """Raise IdentifyError unless the dataset was built with the ROM whose model key is ``key``."""
        if key != self.model_key:
            raise IdentifyError(f"dataset model key {self.model_key[:16]}… does not match the ROM in use "
                                f"({key[:16]}…): the dataset was built with another model; rebuild it")


def _readonly(a, dtype, name: str, ndim: int) -> np.ndarray:
    # A read-only array of the right dtype that owns its memory is taken as it is (load_dataset hands over
    # its own arrays, and a million-row table would otherwise be copied again); anything else, a view
    # included, is copied, so the caller cannot change the dataset afterwards through an array it holds.
    owned = isinstance(a, np.ndarray) and a.dtype == dtype and not a.flags.writeable and a.base is None
    try:
        out = a if owned else np.array(a, dtype=dtype)
    except (TypeError, ValueError):
        raise IdentifyError(f"dataset.{name} cannot be read as {np.dtype(dtype).name}") from None
    if out.ndim != ndim:
        raise IdentifyError(f"dataset.{name} has shape {out.shape}, expected a {ndim}-D array")
    # error_bound is NaN for direct solves, mac_min for datasets saved without it.
    if out.dtype.kind == "f" and not np.all(np.isfinite(out)) and name not in ("error_bound", "mac_min"):
        raise IdentifyError(f"dataset.{name} holds NaN or infinite values")
    out.flags.writeable = False
    return out


def _bits(P: np.ndarray) -> list[str]:
    return ["".join("1" if v else "0" for v in p.ravel()) for p in P]


def _unbits(strings, grid, name: str, path) -> np.ndarray:
    rows, cols = grid
    if not isinstance(strings, list) or not strings:
        raise IdentifyError(f"{path}: metadata field {name!r} must be a non-empty list of 0/1 strings")
    out = np.zeros((len(strings), rows, cols), bool)
    for k, s in enumerate(strings):
        if not isinstance(s, str) or len(s) != rows * cols or set(s) - {"0", "1"}:
            raise IdentifyError(f"{path}: metadata {name}[{k}] must be a string of {rows * cols} '0'/'1' characters "
                                f"(grid {rows}×{cols})")
        out[k] = np.frombuffer(s.encode(), np.uint8).reshape(rows, cols) == ord("1")
    return out


def save_dataset(dataset: Dataset, path: str | os.PathLike) -> Path:
    """Write ``dataset`` to a Parquet file (atomic: temporary file + rename).

    Parameters
    ----------
    dataset : Dataset
    path : str or PathLike

    Returns
    -------
    pathlib.Path
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    if not isinstance(dataset, Dataset):
        raise IdentifyError(f"save_dataset needs a Dataset, got {type(dataset).__name__}")
    n = dataset.n_samples
    cols: dict[str, object] = {}
    for k in range(dataset.deltas.shape[1]):
        cols[f"delta_{k + 1}"] = pa.array(dataset.deltas[:, k], pa.float64())
    cols["i_L"] = pa.array(dataset.pair[:, 0], pa.int32())
    cols["i_R"] = pa.array(dataset.pair[:, 1], pa.int32())
    for m in range(dataset.frequencies_hz.shape[1]):
        cols[f"f_{m + 1}"] = pa.array(dataset.frequencies_hz[:, m], pa.float64())
    cols["error_bound"] = pa.array(np.full(n, np.nan) if dataset.error_bound is None else dataset.error_bound,
                                   pa.float64())
    cols["fallback"] = pa.array(np.zeros(n, bool) if dataset.fallback is None else dataset.fallback, pa.bool_())
    cols["mac_min"] = pa.array(np.full(n, np.nan) if dataset.mac_min is None else dataset.mac_min, pa.float64())
    meta = {
        "format": _FORMAT,
        "version": FORMAT_VERSION,
        "model_key": dataset.model_key,
        "grid": list(dataset.patterns_L.shape[1:]),
        "patterns_L": _bits(dataset.patterns_L),
        "patterns_R": _bits(dataset.patterns_R),
        "feature_modes": list(dataset.feature_modes),
        "weights": dataset.weights.tolist(),
        "delta_grid": dataset.delta_grid.tolist(),
        "n_delta_modes": int(dataset.deltas.shape[1]),
        "n_modes": int(dataset.frequencies_hz.shape[1]),
        "meta": dataset.meta,
    }
    table = pa.table(cols).replace_schema_metadata({_META_KEY: json.dumps(meta, default=_json_default).encode()})
    path = Path(path)
    # Dictionary encoding only where values repeat (δ grid values, pattern indices, flags). Arrow tries it
    # on every column by default, and the frequency columns' dictionary pages cost read time for nothing:
    # without them the 1.76 M-sample file is 122 MB instead of 129 and loads in 0.47 s instead of 0.70
    # (medians of 8 fresh processes).
    repeated = [c for c in cols if c.startswith("delta_") or c in ("i_L", "i_R", "fallback")]
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, use_dictionary=repeated)
    return path


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"dataset meta value of type {type(o).__name__} is not JSON-serialisable")


def _first_line(exc: BaseException) -> str:
    """The first line of an exception's message, or its type name when the message is empty."""
    return (str(exc).splitlines() or [type(exc).__name__])[0]


_REQUIRED = ("format", "version", "model_key", "grid", "patterns_L", "patterns_R", "feature_modes", "weights",
             "delta_grid", "n_delta_modes", "n_modes")


def load_dataset(path: str | os.PathLike, *, model_key: str | None = None) -> Dataset:
    """Read and validate a dataset written by :func:`save_dataset`.

    Parameters
    ----------
    path : str or PathLike
    model_key : str, optional
        Key of the ROM in use (:func:`identify.tracking.model_key`); a dataset made with another model
        is refused.

    Returns
    -------
    Dataset

    Raises
    ------
    IdentifyError
        Not a Parquet file, missing or malformed metadata or columns, values off the δ grid, pair indices
        out of range, or a model key other than ``model_key``.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        pf = pq.ParquetFile(path)
    except (pa.ArrowException, OSError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise IdentifyError(f"{path}: not a readable Parquet dataset ({_first_line(exc)})") from None
    meta = _read_meta(pf, path)
    grid = meta["grid"]
    PL = _unbits(meta["patterns_L"], grid, "patterns_L", path)
    PR = _unbits(meta["patterns_R"], grid, "patterns_R", path)
    D, pair, F, extra = _read_rows(pf, meta["n_delta_modes"], meta["n_modes"], path)
    g = _checked_grid(meta, D, path)
    if model_key is not None and meta["model_key"] != model_key:
        raise IdentifyError(f"{path}: dataset model key {str(meta['model_key'])[:16]}… does not match the ROM in use "
                            f"({model_key[:16]}…): the dataset was built with another model; rebuild it")
    try:
        return Dataset(deltas=D, pair=pair, frequencies_hz=F, patterns_L=PL, patterns_R=PR,
                       feature_modes=tuple(meta["feature_modes"]), weights=meta["weights"], delta_grid=g,
                       model_key=meta["model_key"], error_bound=extra.get("error_bound"),
                       fallback=extra.get("fallback"), mac_min=extra.get("mac_min"),
                       meta=meta.get("meta") or {})
    except IdentifyError as exc:
        raise IdentifyError(f"{path}: {exc}") from None


def _read_meta(pf, path: Path) -> dict:
    """The dataset's metadata from the Parquet schema, checked (format, version, fields, grid, mode counts)."""
    raw = (pf.schema_arrow.metadata or {}).get(_META_KEY)
    if raw is None:
        raise IdentifyError(f"{path}: no bladetwin dataset metadata (schema key {_META_KEY.decode()!r}); "
                            "expected a file written by identify.dataset.save_dataset")
    try:
        meta = json.loads(raw)
    except ValueError:
        raise IdentifyError(f"{path}: dataset metadata is not valid JSON") from None
    if not isinstance(meta, dict):
        raise IdentifyError(f"{path}: dataset metadata must be a JSON object")
    missing = [k for k in _REQUIRED if k not in meta]
    if missing:
        raise IdentifyError(f"{path}: dataset metadata lacks field(s) {missing}")
    if meta["format"] != _FORMAT or meta["version"] != FORMAT_VERSION:
        raise IdentifyError(f"{path}: dataset format {meta['format']!r} version {meta['version']!r}; expected "
                            f"{_FORMAT!r} version {FORMAT_VERSION}")
    grid = meta["grid"]
    if not (isinstance(grid, list) and len(grid) == 2 and all(isinstance(x, int) and x > 0 for x in grid)):
        raise IdentifyError(f"{path}: metadata field 'grid' = {grid!r}, expected [rows, cols]")
    nd, nm = meta["n_delta_modes"], meta["n_modes"]
    if not (isinstance(nd, int) and nd >= 1 and isinstance(nm, int) and nm >= 1):
        raise IdentifyError(f"{path}: n_delta_modes={nd!r}, n_modes={nm!r}: expected integers ≥ 1")
    return meta


def _read_rows(pf, nd: int, nm: int, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """δ (n, nd), pairs (n, 2), frequencies (n, nm) and the optional columns, read-only."""
    import pyarrow as pa

    schema = pf.schema_arrow
    names = [f"delta_{k + 1}" for k in range(nd)] + ["i_L", "i_R"] + [f"f_{m + 1}" for m in range(nm)]
    absent = [c for c in names if c not in schema.names]
    if absent:
        raise IdentifyError(f"{path}: dataset lacks column(s) {absent}")
    # Batch by batch straight into the final arrays: Arrow then reuses one batch's buffers instead of holding
    # the whole table beside its NumPy copy, and a million-row table makes every extra copy count (a fresh
    # page costs more than the copy on these machines: 1.76 M samples load in 0.5 s instead of 0.7–1.1 s).
    n = pf.metadata.num_rows
    D, pair, F = np.empty((n, nd)), np.empty((n, 2), np.int64), np.empty((n, nm))
    extra = {name: np.empty(n, dtype) for name, dtype in
             (("error_bound", np.float64), ("fallback", bool), ("mac_min", np.float64)) if name in schema.names}
    targets = [(D, k) for k in range(nd)] + [(pair, 0), (pair, 1)] + [(F, m) for m in range(nm)]
    targets += [(a, None) for a in extra.values()]
    wanted = names + list(extra)
    pos = 0
    try:
        for batch in pf.iter_batches(batch_size=_READ_BATCH, columns=wanted):
            rows = slice(pos, pos + batch.num_rows)
            for (out, k), name in zip(targets, wanted, strict=True):
                values = batch.column(name).to_numpy(zero_copy_only=False)  # by name: any column order
                if k is None:
                    out[rows] = values
                else:
                    out[rows, k] = values
            pos += batch.num_rows
    except (pa.ArrowException, OSError, ValueError, TypeError) as exc:  # any Arrow fault: refused
        raise IdentifyError(f"{path}: dataset rows cannot be read ({_first_line(exc)})") from None
    if pos != n:
        raise IdentifyError(f"{path}: the file declares {n} rows but holds {pos}")
    for a in (D, pair, F, *extra.values()):
        a.flags.writeable = False  # Dataset takes read-only arrays as they are
    return D, pair, F, extra


def _checked_grid(meta: dict, D: np.ndarray, path: Path) -> np.ndarray:
    """The metadata's δ grid, with every row's δ checked to lie on it."""
    try:
        g = np.asarray(meta["delta_grid"], dtype=np.float64)
    except (TypeError, ValueError):
        raise IdentifyError(f"{path}: metadata field 'delta_grid' must be a list of numbers") from None
    if g.ndim != 1 or g.size == 0:
        raise IdentifyError(f"{path}: metadata field 'delta_grid' must be a non-empty list of numbers")
    off = off_grid(D, g)
    if off.any():
        r, k = np.argwhere(off)[0]
        raise IdentifyError(f"{path}: row {r}, delta_{k + 1} = {D[r, k]:.6g} is not a value of the δ grid {g.tolist()}")
    return g
