"""Resumable dataset builds in Parquet parts, in process or on Dask (issue 12, items 1–2).

A build is split into its pattern pairs (:func:`identify.dataset_build.plan_dataset`, :func:`solve_pair`). Each
finished pair is written atomically as one Parquet part in the build folder, beside ``manifest.json``, which
holds the hash of every input (the cache key). Re-running the same build after an interruption (even
SIGKILL) reads the finished parts and computes only the missing pairs; a folder holding parts of another
build is refused. The table does not depend on where the pairs ran: each pair runs with one BLAS thread, so
its numbers are the same in any process, and the parts are assembled in the serial build's order.

Executors:

* default: in this process, no cluster;
* ``workers=N``: a ``dask.distributed.LocalCluster`` of N single-threaded worker processes;
* ``scheduler="tcp://host:8786"``: an existing Dask cluster.

With Dask the plan (the reduced models and patterns) is scattered to the workers once, and the workers send
each pair's arrays back: the folder, the parts and the final table stay on the client.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rom.cache import hash_inputs
from rom.fileio import atomic_path

from .dataset import Dataset
from .dataset_build import (
    DEFAULT_TOL,
    DatasetPlan,
    PairResult,
    assemble_dataset,
    plan_dataset,
    solve_pair,
)
from .errors import IdentifyError
from .sensitivity import Sensitivity

__all__ = ["build_dataset_parts", "build_key", "MANIFEST"]

MANIFEST = "manifest.json"
_FORMAT = "bladetwin.identify.dataset-parts"
_VERSION = 1


def build_key(plan: DatasetPlan) -> str:
    """SHA-256 of every input of a build: model key, patterns, δ grid, counts, tolerance, method, reference."""
    return hash_inputs(_FORMAT, _VERSION, plan.key, plan.PL, plan.PR, plan.grid, plan.n_delta_modes, plan.n_modes,
                       plan.n_extra, plan.formulation, plan.tol, plan.method, list(plan.reference))


def _part_path(folder: Path, i: int, j: int) -> Path:
    return folder / f"part-L{i:04d}-R{j:04d}.parquet"


def _write_part(folder: Path, r: PairResult, key: str) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    n_modes = r.frequencies_hz.shape[1]
    cols = {f"f{m}": r.frequencies_hz[:, m] for m in range(n_modes)}
    cols.update(bound=r.bound, mac_min=r.mac_min, fallback=r.fallback)
    meta = {"key": key, "i": r.i, "j": r.j, "freq0": r.freq0.tolist(), "mac_ref": r.mac_ref.tolist(),
            "rank_ref": r.rank_ref.tolist()}
    table = pa.table(cols).replace_schema_metadata({b"bladetwin.part": json.dumps(meta).encode()})
    with atomic_path(_part_path(folder, r.i, r.j)) as tmp:
        pq.write_table(table, tmp)


def _read_part(path: Path, key: str, plan: DatasetPlan) -> PairResult | None:
    """The part at ``path``; None where there is none: not yet written, or gone (a concurrent build of the same
    dataset finished and cleared the folder: two campaigns of one disk, their dataset nodes on two workers)."""
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
        meta = json.loads(table.schema.metadata[b"bladetwin.part"])
    except FileNotFoundError:
        return None
    except Exception as exc:  # noqa: BLE001 - any unreadable part is reported the same way
        raise IdentifyError(f"{path}: not a readable dataset part ({exc}); delete it and re-run") from None
    if meta.get("key") != key:
        raise IdentifyError(f"{path}: a part of another build (key {str(meta.get('key'))[:12]}…); delete it")
    n = plan.n_rows
    freq = np.column_stack([table[f"f{m}"].to_numpy() for m in range(plan.n_modes)]) if n else np.empty((0, 0))
    if freq.shape != (n, plan.n_modes):
        raise IdentifyError(f"{path}: {freq.shape} samples × modes, expected {(n, plan.n_modes)}; delete it")
    return PairResult(int(meta["i"]), int(meta["j"]), freq, table["bound"].to_numpy(zero_copy_only=False),
                      table["mac_min"].to_numpy(), table["fallback"].to_numpy(zero_copy_only=False).astype(bool),
                      np.asarray(meta["freq0"], float), np.asarray(meta["mac_ref"], float),
                      np.asarray(meta["rank_ref"], np.int64))


def _open_folder(folder: Path, key: str, plan: DatasetPlan) -> None:
    """Create the build folder with its manifest, or check that an existing one belongs to this build."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / MANIFEST
    if path.is_file():
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise IdentifyError(f"{path}: unreadable manifest ({exc})") from None
        if doc.get("format") != _FORMAT or doc.get("key") != key:
            raise IdentifyError(f"{folder}: holds the parts of another dataset build (key "
                                f"{str(doc.get('key'))[:12]}…, this build's {key[:12]}…); use another folder or "
                                "delete it")
        return
    doc = {"format": _FORMAT, "version": _VERSION, "key": key, "n_pairs": len(plan.pairs), "n_rows": plan.n_rows,
           "n_modes": plan.n_modes, "model_key": plan.key}
    with atomic_path(path) as tmp:
        Path(tmp).write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")


def build_dataset_parts(
    disk, blade, patterns_L, patterns_R, delta_grid, folder: str | Path, *,
    n_delta_modes: int = 3, n_modes: int = 10, sensitivity: Sensitivity | None = None, n_features: int = 3,
    reference: tuple[int, int] | None = None, n_extra: int = 4, formulation: str = "exact",
    tol: float | None = None, method: str = "auto", workers: int | None = None, scheduler: str | None = None,
    say: Callable[[str], None] = lambda m: None,
) -> Dataset:
    """:func:`identify.dataset_build.build_dataset`, resumable, one Parquet part per pattern pair in ``folder``.

    Parameters
    ----------
    folder : path
        Build folder (created): ``manifest.json`` and ``part-L<i>-R<j>.parquet``.
    workers : int, optional
        Run the pairs on a local Dask cluster of this many single-threaded worker processes.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``); overrides ``workers``.
    say : callable
        Progress messages.
    Other parameters as :func:`identify.dataset_build.build_dataset`.

    Returns
    -------
    Dataset
        The same table as :func:`build_dataset` with the same inputs, whichever executor ran it.

    Raises
    ------
    IdentifyError
        Bad inputs (as ``build_dataset``); a folder or part of another build; Dask missing for ``workers`` or
        ``scheduler``.
    """
    plan = plan_dataset(disk, blade, patterns_L, patterns_R, delta_grid, n_delta_modes=n_delta_modes,
                        n_modes=n_modes, sensitivity=sensitivity, reference=reference, n_extra=n_extra,
                        formulation=formulation, tol=DEFAULT_TOL if tol is None else tol, method=method)
    folder = Path(folder)
    key = build_key(plan)
    _open_folder(folder, key, plan)
    results = {}
    for i, j in plan.pairs:
        p = _part_path(folder, i, j)
        if (part := _read_part(p, key, plan)) is not None:  # None: not written, or cleared by a concurrent build
            results[i, j] = part
    todo = [pair for pair in plan.pairs if pair not in results]
    say(f"dataset: {len(plan.pairs)} pattern pairs × {plan.n_rows} δ rows; {len(results)} pairs already in "
        f"{folder}, {len(todo)} to compute")

    every = max(1, len(todo) // 10)  # about ten progress lines per build

    def done(r: PairResult) -> None:
        _write_part(folder, r, key)
        results[r.i, r.j] = r
        k = len(results) - (len(plan.pairs) - len(todo))
        if k % every == 0 or k == len(todo):
            say(f"  {k} of {len(todo)} pattern pairs done")

    if todo and (workers is not None or scheduler is not None):
        _run_dask(plan, todo, done, workers, scheduler)
    else:
        for i, j in todo:
            done(solve_pair(plan, i, j))
    return assemble_dataset(plan, results, sensitivity=sensitivity, n_features=n_features)


def _run_dask(plan: DatasetPlan, todo: list, done: Callable[[PairResult], None], workers: int | None,
              scheduler: str | None) -> None:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise IdentifyError("Dask executors need dask.distributed: pip install 'bladetwin[scale]' "
                            "(or pip install 'dask[distributed]')") from None
    import logging

    if logging.getLogger("distributed").getEffectiveLevel() <= logging.INFO and not logging.getLogger().isEnabledFor(
            logging.INFO):
        # distributed logs each worker's start and stop at INFO; the build reports its own progress, so keep
        # that chatter for callers who asked for INFO (``bladetwin -v``)
        logging.getLogger("distributed").setLevel(logging.WARNING)
    if scheduler is not None:
        cluster, client = None, Client(scheduler)
    else:
        if not isinstance(workers, int) or workers < 1:
            raise IdentifyError(f"workers={workers!r}: expected a positive integer")
        # Processes, one thread each: the pairs are BLAS-bound and numpy holds the GIL in between.
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        remote_plan = client.scatter(plan, broadcast=True)  # once per worker, not once per task
        futures = [client.submit(solve_pair, remote_plan, i, j, pure=False) for i, j in todo]
        for fut in as_completed(futures):
            done(fut.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
