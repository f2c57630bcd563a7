"""Write a bladed disk in the importable formats, with a ready ``[model]`` table (``model.toml``).

``bladetwin fe export`` uses it on the academic twin: it gives users a worked example of every file an
import needs, and the tests a round trip (export → :func:`rom.importers.model.read_model_toml` → the same ROM).

Files in the output folder (every one written atomically; ``model.toml`` last, so that its presence means the
export is complete):

==============================  ===========================================================================
``{disk,blade}_K.mtx``, ``_M``  Matrix Market, ``coordinate real symmetric`` (``format="mtx"``)
``{disk,blade}.op4``            OP4 with ``KAA`` and ``MAA``, binary or text (``format="op4"``)
``{disk,blade}_dofmap.csv``     ``row,node,dir`` (constrained DOFs left out, as FE codes do)
``{disk,blade}_coords.csv``     ``node,x,y,z`` (m)
``{disk,blade}_node_sets.csv``  ``set,node``: flank grids (row-major), measurement nodes, any other set
``grids.csv``                   ``slot,flank,row,col,node`` (slot 0: the blade root)
``model.toml``                  the ``[model]`` table describing all of the above
==============================  ===========================================================================
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..academic import BladedDisk
from ..component import Component
from ..fileio import atomic_path
from .csvio import write_coords_csv, write_dofmap_csv, write_grids_csv, write_node_sets_csv
from .matrix_market import write_matrix_market
from .op4_writer import write_op4
from .placement import BladePlacement

__all__ = ["ExportedModel", "export_bladed_disk", "EXPORT_FORMATS"]

#: Formats :func:`export_bladed_disk` writes.
EXPORT_FORMATS = ("mtx", "op4")

#: The academic twin's grid axes in the blade frame: rows axial (z), columns radial (y).
_ACADEMIC_AXES = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0))


@dataclass(frozen=True)
class ExportedModel:
    """What :func:`export_bladed_disk` wrote: the ``model.toml`` and every file it names."""

    model_toml: Path
    files: tuple[Path, ...]


def _placement(bd: BladedDisk) -> BladePlacement:
    p = getattr(bd, "placement", None)
    if p is not None:
        return p
    # The academic twin: slot s at 2π (s − 1)/N from +y towards +x, i.e. right-handed about −z.
    return BladePlacement.uniform(bd.n_slots, axis=(0.0, 0.0, -1.0))


def _free_rows(comp: Component) -> np.ndarray:
    fixed = np.zeros(comp.n_dof, bool)
    fixed[np.asarray(comp.meta.get("constrained_dofs") or [], dtype=np.int64)] = True
    return np.flatnonzero(~fixed)


def _vec(v) -> str:
    return "[" + ", ".join(f"{float(x):.17g}" for x in np.asarray(v).ravel()) + "]"


def export_bladed_disk(
    bd: BladedDisk,
    out_dir: str | os.PathLike,
    *,
    format: str = "mtx",
    binary: bool = True,
) -> ExportedModel:
    """Write the disk and blade of ``bd`` and a ``model.toml`` describing them.

    Parameters
    ----------
    bd : BladedDisk
        The academic twin (or an :class:`~rom.importers.model.ImportedBladedDisk`).
    out_dir : path-like
        Output folder (created).
    format : {"mtx", "op4"}
    binary : bool
        OP4 only: binary (default) or text.

    Returns
    -------
    ExportedModel
    """
    if format not in EXPORT_FORMATS:
        raise ValueError(f"format must be one of {list(EXPORT_FORMATS)}, got {format!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    tables = {}
    for key in ("disk", "blade"):
        paths, tables[key] = _write_component(out, key, getattr(bd, key), format, binary)
        written += paths
    written.append(_write_grids(out, bd))
    toml = out / "model.toml"
    with atomic_path(toml) as tmp:
        Path(tmp).write_text(_model_toml(bd, format, tables), encoding="utf-8")
    return ExportedModel(toml, tuple(written) + (toml,))


def _write_component(out: Path, key: str, comp: Component, format: str, binary: bool) -> tuple[list[Path], str]:
    """Write one component's K, M and side files into ``out``: their paths and the ``[model.<key>]`` table's lines."""
    written: list[Path] = []
    rows = _free_rows(comp)
    K = comp.K[rows][:, rows].tocsr()
    M = comp.M[rows][:, rows].tocsr()
    if format == "mtx":
        written.append(write_matrix_market(out / f"{key}_K.mtx", K, comment=f"bladetwin {key} stiffness (N/m)"))
        written.append(write_matrix_market(out / f"{key}_M.mtx", M, comment=f"bladetwin {key} mass (kg)"))
        files = f'K = "{key}_K.mtx"\nM = "{key}_M.mtx"\n'
    else:
        written.append(write_op4(out / f"{key}.op4", {"KAA": K, "MAA": M}, binary=binary))
        files = f'file = "{key}.op4"\nmatrices = ["KAA", "MAA"]\n'
    written.append(write_dofmap_csv(out / f"{key}_dofmap.csv", comp.node_ids[rows // 3], rows % 3 + 1))
    written.append(write_coords_csv(out / f"{key}_coords.csv", comp.node_ids, comp.coords))
    sets = {name: comp.node_ids[np.asarray(idx)] for name, idx in comp.node_sets.items()}
    written.append(write_node_sets_csv(out / f"{key}_node_sets.csv", sets))
    return written, (files + f'dofmap = "{key}_dofmap.csv"\ncoords = "{key}_coords.csv"\n'
                     f'node_sets = "{key}_node_sets.csv"\nmeas = "meas"\n'
                     f'meas_direction = {int(comp.meta["meas_direction"])}\n')


def _write_grids(out: Path, bd: BladedDisk) -> Path:
    """``grids.csv``: the blade's flank grids (slot 0) and every slot's, by node id."""
    grids = {(0, f): bd.blade.node_ids[bd.blade.node_set(f)] for f in ("L", "R")}
    for s in range(1, bd.n_slots + 1):
        for f in ("L", "R"):
            grids[(s, f)] = bd.disk.node_ids[bd.disk.node_set(f"slot{s}_{f}")]
    return write_grids_csv(out / "grids.csv", grids)


def _model_toml(bd: BladedDisk, format: str, tables: dict[str, str]) -> str:
    """The text of ``model.toml``: the ``[model]`` table with the components' tables, placement and grids."""
    placement = _placement(bd)
    axes = getattr(bd, "axes", None)
    row_axis, col_axis = (axes["L"].row, axes["L"].col) if axes else _ACADEMIC_AXES
    level = getattr(bd.params, "level", "")
    return (
        f"# bladetwin model: exported by `bladetwin fe export` ({level} twin, grid {bd.params.grid[0]}x"
        f"{bd.params.grid[1]}).\n"
        "# Paths are relative to this file. Units: SI (m, kg, s; K in N/m, M in kg).\n"
        "[model]\n"
        f'format = "{format}"\n'
        'units = "SI"\n\n'
        "[model.disk]\n" + tables["disk"] + "\n"
        "[model.blade]\n" + tables["blade"] + "\n"
        "[model.placement]\n"
        "# Slot s receives the blade rotated by angles_deg[s - 1] about axis (right-handed, through the origin),\n"
        "# after the base placement rotation0 / origin0 (blade frame -> slot at angle 0).\n"
        f"n_slots = {placement.n_slots}\n"
        f"axis = {_vec(placement.axis)}\n"
        # Rounded to 1e-12 degree (~2e-14 rad): 60 rather than 59.999999999999993 in the file.
        f"angles_deg = {_vec(np.round(np.degrees(placement.angles), 12))}\n"
        "rotation0 = [" + ", ".join(_vec(r) for r in placement.rotation0) + "]\n"
        f"origin0 = {_vec(placement.origin0)}\n"
        "# Cyclic: the CB model of one slot serves every slot (true for the twin; say false when unsure).\n"
        f"cyclic = {'true' if getattr(bd, 'cyclic', True) else 'false'}\n\n"
        "[model.grids]\n"
        "# Explicit grids. Without `file`, they are built from the node sets slot{slot}_{flank} (disk) and\n"
        "# {flank} (blade) and the coordinates, ordered along row_axis / col_axis (blade frame).\n"
        'file = "grids.csv"\n'
        f"shape = [{bd.params.grid[0]}, {bd.params.grid[1]}]\n"
        'disk_set = "slot{slot}_{flank}"\n'
        'blade_set = "{flank}"\n'
        f"row_axis = {_vec(row_axis)}\n"
        f"col_axis = {_vec(col_axis)}\n"
    )
