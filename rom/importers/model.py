"""A bladed disk from imported disk and blade components, for the ROM back end; the ``[model]`` table.

:func:`bladed_disk_from_components` returns an :class:`ImportedBladedDisk`: a
:class:`rom.academic.BladedDisk` whose slots follow a :class:`~rom.importers.placement.BladePlacement` and whose
``params`` is an :class:`ImportedParams` (the number of slots, the grid shape and ``level = "imported"``: there
is no geometry to parametrize). Everything that takes a ``BladedDisk`` by its protocol — ``disk``, ``blade``,
``n_slots``, ``params.grid``, ``slot_rotation``, ``placed_blade_coords``, ``interface_gap``, ``check_slot`` and
the node-set conventions (disk ``"slot{s}_L"``, ``"slot{s}_R"`` grids and ``"meas"``; blade ``"L"``, ``"R"``,
``"meas"``; ``meta["meas_direction"]``) — works on it: :func:`rom.craig_bampton.reduce_disk`,
:func:`rom.rubin.reduce_blade`, :mod:`rom.rom_assembly`, :func:`rom.fe_assembly.assemble_fe` and the cache.

The ``[model]`` table (written by ``bladetwin fe export`` as ``model.toml``, read by :func:`load_bladed_disk`)::

    [model]
    # family = "imported"       # optional here; a campaign's [model] says it (docs/campaign.md)
    format = "mtx"              # mtx | op4 | full (a component table may override it)
    units = "SI"                # SI | mm-t-s | mm-kg-ms | cm-g-s | in-lbf-s (likewise)

    [model.disk]                # and [model.blade], same keys
    K = "disk_K.mtx"            # mtx: the two matrix files
    M = "disk_M.mtx"
    # file = "disk.op4"         # op4 / full: the one file
    # matrices = ["KAA", "MAA"] # op4: K and M names (default: the K* and M* matrix)
    # archive = "disk.cdb"      # full: coordinates and node components
    dofmap = "disk_dofmap.csv"  # mtx / op4: row,node,dir
    coords = "disk_coords.csv"  # mtx / op4: node,x,y,z
    node_sets = "disk_node_sets.csv"  # set,node
    meas = "meas"               # node set of the measurement nodes (disk: one per sector, in sector order)
    meas_direction = 3          # measured direction (1, 2, 3 = x, y, z; the blade's in its own frame)

    [model.placement]
    n_slots = 18
    axis = [0.0, 0.0, -1.0]     # disk axis through the origin
    angles_deg = [0.0, 20.0]    # one per slot, right-handed about axis (default: evenly spaced)
    # rotation0 = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]  # blade frame → slot at angle 0
    # origin0 = [0.0, 0.0, 0.0] # and the translation, in the model's length unit
    cyclic = true               # the disk is cyclically symmetric (default false)

    [model.grids]
    file = "grids.csv"          # explicit grids (slot,flank,row,col,node; slot 0 = blade); or, without it,
    disk_set = "slot{slot}_{flank}"   # grids built from these node sets and the coordinates
    blade_set = "{flank}"
    row_axis = [0.0, 0.0, 1.0]  # blade frame; default: the flank's principal axes
    col_axis = [0.0, 1.0, 0.0]
    incomplete = "error"        # or "drop_rows" / "drop_cols" (mid-side nodes of quadratic elements)
    shape = [7, 31]             # optional check
    # tolerance = 1e-6          # largest disk/blade gap accepted (m); default 1e-3 of the grid spacing

Paths are relative to the TOML file's folder.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..academic import BladedDisk
from ..component import Component
from .csvio import read_grids_csv
from .errors import GridError, ModelImportError
from .grids import (
    DEFAULT_GAP_RTOL,
    DEFAULT_RTOL,
    FlankAxes,
    InterfaceGrids,
    check_conformity,
    grids_from_ids,
    grids_from_node_sets,
    principal_axes,
)
from .placement import BladePlacement
from .readers import FORMATS, import_component
from .units import unit_system

__all__ = ["ImportedParams", "ImportedBladedDisk", "bladed_disk_from_components", "load_bladed_disk",
           "read_model_toml"]

_FLANKS = ("L", "R")


@dataclass(frozen=True)
class ImportedParams:
    """The parameters the ROM back end reads from ``BladedDisk.params`` for an imported model."""

    n_blades: int
    grid: tuple[int, int]
    level: str = "imported"

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class ImportedBladedDisk(BladedDisk):
    """A :class:`rom.academic.BladedDisk` built from imported components (see the module notes).

    Attributes
    ----------
    placement : BladePlacement
        Blade placement per slot; it replaces the academic slot angles and rotations.
    axes : mapping flank → FlankAxes, optional
        Blade-frame grid axes (rows, columns), for :meth:`flank_coordinates`.
    max_gap : float
        Largest disk/blade grid gap found when the model was built (m).
    cyclic : bool
        Whether the disk is cyclically symmetric, so that the CB model of one slot serves every slot (the
        ``[model.placement]`` key ``cyclic``; the exported twin says true). Nothing checks it: it is the
        model author's statement, for :func:`rom.craig_bampton.reduce_disk` to honour.
    """

    placement: BladePlacement | None = None
    axes: Mapping[str, FlankAxes] | None = None
    max_gap: float = 0.0
    cyclic: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.placement, BladePlacement):
            raise ModelImportError("an ImportedBladedDisk needs a BladePlacement")
        if self.placement.n_slots != self.params.n_blades:
            raise ModelImportError(f"placement has {self.placement.n_slots} slots, params.n_blades is "
                                   f"{self.params.n_blades}")

    def slot_angle(self, slot: int) -> float:
        """Angle of ``slot`` about the placement axis (rad)."""
        return float(self.placement.angles[self.check_slot(slot) - 1])

    def slot_rotation(self, slot: int) -> np.ndarray:
        """R_s (3×3): x_global = R_s @ x_blade_local for DOFs of the blade in ``slot``."""
        return self.placement.rotation(self.check_slot(slot))

    def placed_blade_coords(self, slot: int) -> np.ndarray:
        """Blade node coordinates placed in ``slot`` (global frame), shape (n_nodes, 3)."""
        return self.placement.place(self.blade.coords, self.check_slot(slot))

    def flank_coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """In-plane coordinates (m) of the blade's flank-L grid nodes, each of shape (rows, cols).

        ``u`` is the position along the grid's row axis (it grows with the row index), ``v`` along its column
        axis: the imported counterpart of :func:`rom.academic.flank_coordinates`, which assumes the academic
        blade frame (rows axial along z, columns radial along y).
        """
        X = self.blade.coords[self.blade.node_set("L")]
        ax = (self.axes or {}).get("L") or principal_axes(X.reshape(-1, 3))
        return X @ ax.row, X @ ax.col


def bladed_disk_from_components(
    disk: Component,
    blade: Component,
    placement: BladePlacement,
    grids: InterfaceGrids,
    *,
    disk_meas: str = "meas",
    blade_meas: str = "meas",
    disk_meas_direction: int = 3,
    blade_meas_direction: int = 1,
    tolerance: float | None = None,
    gap_rtol: float = DEFAULT_GAP_RTOL,
    cyclic: bool = False,
) -> ImportedBladedDisk:
    """Assemble an :class:`ImportedBladedDisk` from imported components.

    Parameters
    ----------
    disk, blade : Component
        SI components; the blade must be free–free (no constrained DOF).
    placement : BladePlacement
        One placement per slot (its ``n_slots`` is the model's).
    grids : InterfaceGrids
        Flank grids ``"L"`` and ``"R"`` of the blade and of every disk slot
        (:func:`~rom.importers.grids.grids_from_node_sets` or :func:`~rom.importers.grids.grids_from_ids`).
    disk_meas, blade_meas : str
        Node sets of the measurement nodes; the disk's has one node per slot (sector order).
    disk_meas_direction, blade_meas_direction : int
        Measured direction (1, 2, 3); the disk's in the global frame, the blade's in the blade frame.
    tolerance, gap_rtol : float
        Conformity tolerance (:func:`~rom.importers.grids.check_conformity`).
    cyclic : bool
        Whether the disk is cyclically symmetric (see :class:`ImportedBladedDisk`).

    Raises
    ------
    GridError, ModelImportError
        One line each: wrong flanks, non-conforming grids (with the gap), bad measurement sets, constrained DOFs
        on an interface or on the blade.
    """
    n = placement.n_slots
    if set(grids.blade) != set(_FLANKS):
        raise GridError(f"the ROM needs the blade flanks {list(_FLANKS)}, the grids have {sorted(grids.blade)}")
    missing = [(s, f) for s in range(1, n + 1) for f in _FLANKS if (s, f) not in grids.disk]
    if missing:
        raise GridError(f"no grid for disk slot {missing[0][0]} flank {missing[0][1]!r}")
    shape = grids.shape
    gap = check_conformity(disk, blade, grids, placement, tolerance=tolerance, gap_rtol=gap_rtol)
    blade_fixed = blade.meta.get("constrained_dofs") or []
    if blade_fixed:
        raise ModelImportError(f"{blade.meta.get('source', blade.name)}: the blade must be free–free for the Rubin "
                               f"reduction, it has {len(blade_fixed)} constrained DOF(s)")
    fixed = np.zeros(disk.n_dof, bool)
    fixed[np.asarray(disk.meta.get("constrained_dofs") or [], dtype=np.int64)] = True
    for (s, f), g in grids.disk.items():
        bad = fixed[disk.dofs_of(g.ravel())].any(axis=1)
        if bad.any():
            raise GridError(f"{disk.meta.get('source', disk.name)}: grid node {int(disk.node_ids[g.ravel()[bad][0]])} "
                            f"of slot {s} flank {f!r} has constrained DOFs; interface nodes must be free")
    for comp, key, direction, want in ((disk, disk_meas, disk_meas_direction, n), (blade, blade_meas,
                                                                                    blade_meas_direction, None)):
        if direction not in (1, 2, 3):
            raise ModelImportError(f"{comp.name}: meas_direction must be 1, 2 or 3, got {direction!r}")
        nodes = np.asarray(comp.node_set(key)).ravel()
        if want is not None and nodes.size != want:
            raise ModelImportError(f"{comp.meta.get('source', comp.name)}: measurement set {key!r} has {nodes.size} "
                                   f"node(s); the disk needs one per slot ({want}), in slot order")
    disk_sets = {k: v for k, v in disk.node_sets.items()}
    for (s, f), g in grids.disk.items():
        disk_sets[f"slot{s}_{f}"] = g
    disk_sets["meas"] = np.asarray(disk.node_set(disk_meas)).ravel()
    blade_sets = {k: v for k, v in blade.node_sets.items()}
    blade_sets.update({f: grids.blade[f] for f in _FLANKS})
    blade_sets["meas"] = np.asarray(blade.node_set(blade_meas)).ravel()
    d = Component(disk.name, disk.K, disk.M, disk.node_ids, disk.coords, disk_sets,
                  {**disk.meta, "meas_direction": int(disk_meas_direction)}, disk.elements)
    b = Component(blade.name, blade.K, blade.M, blade.node_ids, blade.coords, blade_sets,
                  {**blade.meta, "meas_direction": int(blade_meas_direction)}, blade.elements)
    params = ImportedParams(n_blades=n, grid=(int(shape[0]), int(shape[1])))
    return ImportedBladedDisk(params, d, b, placement=placement, axes=grids.axes, max_gap=gap, cyclic=bool(cyclic))


# ----------------------------------------------------------------------------------------- the [model] table
_COMPONENT_KEYS = {"format", "units", "K", "M", "file", "matrices", "archive", "dofmap", "coords", "node_sets",
                   "meas", "meas_direction"}
_PLACEMENT_KEYS = {"n_slots", "axis", "angles_deg", "rotation0", "origin0", "cyclic"}
_GRID_KEYS = {"file", "disk_set", "blade_set", "row_axis", "col_axis", "incomplete", "shape", "tolerance", "rtol"}
# `family = "imported"` lets the same table serve as a campaign's [model] (docs/campaign.md), where the family
# tells it from the academic twin's.
_MODEL_KEYS = {"family", "format", "units", "disk", "blade", "placement", "grids"}


def _table(section: Mapping, key: str, allowed: set[str], where: str, required: bool = True) -> Mapping:
    t = section.get(key)
    if t is None:
        if required:
            raise ModelImportError(f"{where}: missing table [model.{key}]")
        return {}
    if not isinstance(t, Mapping):
        raise ModelImportError(f"{where}: model.{key} must be a table")
    unknown = sorted(set(t) - allowed)
    if unknown:
        raise ModelImportError(f"{where}: unknown key(s) {unknown} in [model.{key}]; allowed: {sorted(allowed)}")
    return t


def _component(section: Mapping, key: str, base: Path, where: str):
    t = _table(section, key, _COMPONENT_KEYS, where)
    fmt = t.get("format", section.get("format"))
    if fmt not in FORMATS:
        raise ModelImportError(f"{where}: model format must be one of {list(FORMATS)}, got {fmt!r} ([model.{key}])")
    units = t.get("units", section.get("units", "SI"))

    def path(k):
        return None if t.get(k) is None else base / str(t[k])

    if fmt == "mtx":
        if "K" not in t or "M" not in t:
            raise ModelImportError(f"{where}: [model.{key}] needs K and M (the Matrix Market files)")
        main, mass = path("K"), path("M")
    else:
        if "file" not in t:
            raise ModelImportError(f"{where}: [model.{key}] needs file (the {fmt} file)")
        main, mass = path("file"), None
    matrices = tuple(t["matrices"]) if "matrices" in t else None
    comp = import_component(main, format=fmt, mass=mass, dofmap=path("dofmap"), coords=path("coords"),
                            node_sets=path("node_sets"), archive=path("archive"), matrices=matrices, units=units,
                            name=key)
    return comp, t, unit_system(units)


def load_bladed_disk(section: Mapping, base_dir: str | os.PathLike = ".", *, where: str = "[model]"
                     ) -> ImportedBladedDisk:
    """Build the :class:`ImportedBladedDisk` a ``[model]`` table describes (schema in the module notes).

    Parameters
    ----------
    section : mapping
        The ``[model]`` table (e.g. ``tomllib.load(f)["model"]``).
    base_dir : path-like
        Folder the table's paths are relative to.
    where : str
        Names the table in messages (e.g. the TOML file).
    """
    base = Path(base_dir)
    unknown = sorted(set(section) - _MODEL_KEYS)
    if unknown:
        raise ModelImportError(f"{where}: unknown key(s) {unknown} in [model]; allowed: {sorted(_MODEL_KEYS)}")
    if section.get("family", "imported") != "imported":
        raise ModelImportError(f"{where}: [model] family = {section['family']!r}; a table of files describes an "
                               "imported model (family = 'imported')")
    disk, dt, _ = _component(section, "disk", base, where)
    blade, bt, bunits = _component(section, "blade", base, where)
    pt = _table(section, "placement", _PLACEMENT_KEYS, where)
    try:
        n_slots = int(pt["n_slots"])
        axis = np.asarray(pt.get("axis", [0.0, 0.0, 1.0]), dtype=np.float64)
        if "angles_deg" in pt:
            angles = np.radians(np.asarray(pt["angles_deg"], dtype=np.float64))
            if angles.size != n_slots:
                raise ModelImportError(f"{where}: [model.placement] angles_deg has {angles.size} entries for "
                                       f"n_slots = {n_slots}")
        else:
            angles = 2 * math.pi * np.arange(n_slots) / n_slots
        kw = {}
        if "rotation0" in pt:
            kw["rotation0"] = np.asarray(pt["rotation0"], dtype=np.float64)
        if "origin0" in pt:
            kw["origin0"] = np.asarray(pt["origin0"], dtype=np.float64) * bunits.length
    except KeyError:
        raise ModelImportError(f"{where}: [model.placement] needs n_slots") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ModelImportError):
            raise
        raise ModelImportError(f"{where}: [model.placement]: {' '.join(str(exc).split())}") from None
    placement = BladePlacement(axis, angles, **kw)
    gt = _table(section, "grids", _GRID_KEYS, where, required=False)
    tolerance = gt.get("tolerance")
    axes = None
    if "row_axis" in gt or "col_axis" in gt:
        if not ("row_axis" in gt and "col_axis" in gt):
            raise ModelImportError(f"{where}: [model.grids] needs both row_axis and col_axis, or neither")
        axes = FlankAxes.of(gt["row_axis"], gt["col_axis"], where)
    if "file" in gt:
        gfile = base / str(gt["file"])
        grids = grids_from_ids(disk, blade, read_grids_csv(gfile), n_slots, where=str(gfile))
        if "shape" in gt and tuple(grids.shape) != tuple(gt["shape"]):
            raise GridError(f"{gfile}: grids are {grids.shape[0]} × {grids.shape[1]}, [model.grids] shape says "
                            f"{list(gt['shape'])}")
        if axes is not None:
            # Explicit grids need no axes to be ordered, but ImportedBladedDisk.flank_coordinates does: without
            # them it falls back on principal axes, which differ from the author's (the twin's are z, y).
            grids = replace(grids, axes={f: axes for f in grids.blade})
    else:
        grids = grids_from_node_sets(
            disk, blade, placement, disk_set=str(gt.get("disk_set", "slot{slot}_{flank}")),
            blade_set=str(gt.get("blade_set", "{flank}")), axes=axes,
            shape=tuple(gt["shape"]) if "shape" in gt else None, rtol=float(gt.get("rtol", DEFAULT_RTOL)),
            incomplete=str(gt.get("incomplete", "error")),
        )
    return bladed_disk_from_components(
        disk, blade, placement, grids, disk_meas=str(dt.get("meas", "meas")), blade_meas=str(bt.get("meas", "meas")),
        disk_meas_direction=int(dt.get("meas_direction", 3)), blade_meas_direction=int(bt.get("meas_direction", 1)),
        tolerance=None if tolerance is None else float(tolerance), cyclic=bool(pt.get("cyclic", False)),
    )


def read_model_toml(path: str | os.PathLike) -> ImportedBladedDisk:
    """:func:`load_bladed_disk` on the ``[model]`` table of a TOML file (paths relative to its folder)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ModelImportError(f"{path}: not valid TOML ({' '.join(str(exc).split())})") from None
    if "model" not in doc or not isinstance(doc["model"], Mapping):
        raise ModelImportError(f"{path}: no [model] table")
    return load_bladed_disk(doc["model"], path.parent, where=str(path))
