"""The sensitivity (paper §6.2) and the reanalysis dataset (§6.3) nodes."""

from __future__ import annotations

import shutil
from dataclasses import dataclass

import numpy as np

from identify.dataset import Dataset
from identify.delta_grid import grid_from_deltas
from identify.sensitivity import Sensitivity, sensitivity
from identify.synthetic import SyntheticPatterns
from rom.cache import hash_inputs

__all__ = ["DaskSettings", "sensitivity_node", "dataset_node", "parts_key"]


@dataclass(frozen=True)
class DaskSettings:
    """Where the dataset is built: in the worker (both None), a local Dask cluster, or a scheduler's address.

    How a dataset is computed never changes it, so these settings are a run source with a fixed key.
    """

    workers: int | None = None
    scheduler: str | None = None


def sensitivity_node(disk, blade, synthetic: SyntheticPatterns, *, n_features: int) -> Sensitivity:
    """The node: tuned-blade d1b frequencies over every synthetic pattern pair; the feature modes."""
    return sensitivity(disk, blade, synthetic.L, synthetic.R, n_features=n_features, progress=False)


def parts_key(disk, blade, synthetic: SyntheticPatterns, delta_all: np.ndarray, grid, n_features: int,
              n_delta_modes: int) -> str:
    """The name of a dataset build's parts folder: one per node, since each build removes its folder when done.

    Two campaigns of one run (a re-assembly) can share the model and the δ grid but not their blades' δ: their
    dataset nodes are then two nodes that run side by side, and with one folder the first to finish removed the
    parts the other was still writing. The blades' δ set the node apart (nodes of one key run once).
    """
    from identify.tracking import model_key

    return hash_inputs("dataset-parts", model_key(disk, blade), synthetic.L, synthetic.R, grid,
                       np.asarray(delta_all, np.float64), n_features, n_delta_modes)[:32]


def dataset_node(disk, blade, synthetic: SyntheticPatterns, delta_all: np.ndarray, sens: Sensitivity, store,
                 dask: DaskSettings, *, n_features: int, n_delta_modes: int, step_pct: float) -> Dataset:
    """The node: the δ grid (spanning the measured deltas) × every pattern pair, by reanalysis.

    Built in Parquet parts under the store (``memo/dataset-parts-…``), so a build that is interrupted resumes
    where it stopped; the parts are removed once the dataset is complete.
    """
    from identify.dataset_parts import build_dataset_parts

    grid = grid_from_deltas(delta_all[:, :n_delta_modes], step=step_pct / 100, n_delta_modes=n_delta_modes)
    key = parts_key(disk, blade, synthetic, delta_all, grid, n_features, n_delta_modes)
    parts = store.memo(f"dataset-parts-{key}").folder
    ds = build_dataset_parts(disk, blade, synthetic.L, synthetic.R, grid, parts, n_delta_modes=n_delta_modes,
                             sensitivity=sens, n_features=n_features, workers=dask.workers,
                             scheduler=dask.scheduler)
    shutil.rmtree(parts, ignore_errors=True)
    return ds
