"""Interface grids from a real mesh: the (rows × cols) node grid of every slot flank, and their conformity.

A lab's model names the nodes of each contact flank (a node component per flank, on the disk for every slot
and on the blade root), in no useful order. :func:`grid_from_points` orders one such set by position:

1. **Axes.** Rows and columns follow two in-plane directions of the flank: given (``row_axis``, ``col_axis``,
   e.g. the blade's axial and radial directions) or, by default, the flank's principal axes from an SVD of its
   centred coordinates: columns along the longest extent, rows along the second one, each signed so that its
   largest component is positive (:func:`principal_axes`).
2. **Positions → rows and columns.** The coordinates along each axis are sorted and cut wherever two
   successive values differ by more than ``rtol`` times the node spacing ``h`` (the smallest in-plane distance
   between two nodes of the set). Nodes of one row share their row coordinate up to mesh noise (≪ h), and
   distinct rows are at least h apart, so the cut needs no tolerance tuned to a mesh.
3. **Lattice check.** Every (row, col) position must hold exactly one node. Flanks meshed with quadratic
   elements also carry mid-side nodes between corner rows: ``incomplete="drop_rows"`` (or ``"drop_cols"``)
   keeps the complete rows (columns) only, which is how the academic grid is built.

The disk's flank of slot s is ordered in the frame of the blade placed in that slot, with the blade flank's
axes, so that disk and blade grid node (i, j) are the same physical point; :func:`check_conformity` measures
how far apart they are and refuses a gap beyond a tolerance (default: 1e-3 of the node spacing).
Explicit grids from a CSV (``slot,flank,row,col,node``) skip the ordering but not the conformity check.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..component import Component
from .build import node_indices
from .errors import GridError
from .placement import BladePlacement

__all__ = [
    "FlankAxes", "InterfaceGrids", "principal_axes", "grid_from_points", "grids_from_node_sets", "grids_from_ids",
    "check_conformity", "DEFAULT_RTOL", "DEFAULT_GAP_RTOL",
]

log = logging.getLogger(__name__)

#: Successive coordinates further apart than this fraction of the node spacing start a new row (column).
DEFAULT_RTOL = 0.25
#: Default conformity tolerance: this fraction of the smallest grid node spacing.
DEFAULT_GAP_RTOL = 1e-3

_INCOMPLETE = ("error", "drop_rows", "drop_cols")


@dataclass(frozen=True)
class FlankAxes:
    """In-plane directions of a flank (unit vectors, blade frame): the row index grows along ``row``, the column
    index along ``col``."""

    row: np.ndarray
    col: np.ndarray

    @classmethod
    def of(cls, row, col, where: str = "grid axes") -> FlankAxes:
        r = np.asarray(row, dtype=np.float64).reshape(-1)
        c = np.asarray(col, dtype=np.float64).reshape(-1)
        if r.shape != (3,) or c.shape != (3,) or not (np.isfinite(r).all() and np.isfinite(c).all()):
            raise GridError(f"{where}: row_axis and col_axis must be finite 3-vectors")
        nr, nc = np.linalg.norm(r), np.linalg.norm(c)
        if nr == 0 or nc == 0 or abs(r @ c) > 1e-6 * nr * nc:
            raise GridError(f"{where}: row_axis {r.tolist()} and col_axis {c.tolist()} must be non-zero and "
                            "orthogonal")
        return cls(r / nr, c / nc)


def principal_axes(X: np.ndarray) -> FlankAxes:
    """Default flank axes of points ``X`` (n, 3): columns along the largest principal extent, rows along the
    second; each axis signed so that its largest component is positive."""
    Y = np.asarray(X, dtype=np.float64)
    _, _, Vt = np.linalg.svd(Y - Y.mean(axis=0), full_matrices=False)
    axes = []
    for v in Vt[:2]:
        axes.append(v if v[np.argmax(np.abs(v))] > 0 else -v)
    return FlankAxes(row=axes[1], col=axes[0])


def _clusters(t: np.ndarray, gap: float) -> np.ndarray:
    """Labels 0..k−1 of 1-D values: a new label wherever sorted neighbours differ by more than ``gap``."""
    order = np.argsort(t, kind="stable")
    cut = np.r_[False, np.diff(t[order]) > gap]
    labels = np.empty(t.size, dtype=np.int64)
    labels[order] = np.cumsum(cut)
    return labels


def grid_from_points(
    X: np.ndarray,
    axes: FlankAxes,
    *,
    rtol: float = DEFAULT_RTOL,
    incomplete: str = "error",
    shape: tuple[int, int] | None = None,
    where: str = "node set",
) -> tuple[np.ndarray, float]:
    """Order flank points into a (rows × cols) grid by position.

    Parameters
    ----------
    X : ndarray, shape (n, 3)
        Point coordinates (m), in the frame of ``axes``.
    axes : FlankAxes
    rtol : float
        Row/column cut as a fraction of the node spacing (0 < rtol < 0.5).
    incomplete : {"error", "drop_rows", "drop_cols"}
        What to do when positions of the lattice are empty (see the module notes).
    shape : (int, int), optional
        Expected grid shape; a different one is an error.
    where : str
        Names the set in messages.

    Returns
    -------
    grid : ndarray of int64, shape (rows, cols)
        Positions into ``X``: ``X[grid[i, j]]`` is grid node (i, j).
    spacing : float
        The node spacing h (m).
    """
    if incomplete not in _INCOMPLETE:
        raise ValueError(f"incomplete must be one of {_INCOMPLETE}, got {incomplete!r}")
    if not 0 < rtol < 0.5:
        raise ValueError(f"rtol must lie in (0, 0.5), got {rtol}")
    X = np.asarray(X, dtype=np.float64)
    if X.shape[0] < 4:
        raise GridError(f"{where}: {X.shape[0]} node(s); a grid needs at least 2 × 2")
    if not np.isfinite(X).all():
        raise GridError(f"{where}: node coordinates are missing (NaN); give the coordinates of the mesh")
    uv = np.column_stack([X @ axes.row, X @ axes.col])
    h = _node_spacing(uv, where)
    rows, cols = _rows_and_columns(uv, h, rtol, where)
    R, C = int(rows.max()) + 1, int(cols.max()) + 1
    grid = np.full((R, C), -1, dtype=np.int64)
    flat = rows * C + cols
    if np.unique(flat).size != flat.size:
        raise GridError(f"{where}: two nodes fall on the same grid position; the set does not form a "
                        f"{R} × {C} lattice")
    grid.ravel()[flat] = np.arange(X.shape[0])
    grid = _complete_part(grid, incomplete, where, X.shape[0])
    if shape is not None and tuple(grid.shape) != tuple(shape):
        raise GridError(f"{where}: grid is {grid.shape[0]} × {grid.shape[1]}, expected {shape[0]} × {shape[1]}")
    return grid, h


def _node_spacing(uv: np.ndarray, where: str) -> float:
    """The node spacing h: the smallest in-plane distance between two of the points ``uv`` (n, 2)."""
    dist, nearest = cKDTree(uv).query(uv, k=2)
    h = float(dist[:, 1].min())
    if h <= 0:
        k = int(np.argmin(dist[:, 1]))
        raise GridError(f"{where}: two nodes (positions {k} and {int(nearest[k, 1])}) lie at the same point of the "
                        "flank plane; is the set a flank surface?")
    return h


def _rows_and_columns(uv: np.ndarray, h: float, rtol: float, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Row and column labels of the points ``uv`` (n, 2) (module notes, step 2), checked to be straight."""
    rows = _clusters(uv[:, 0], rtol * h)
    cols = _clusters(uv[:, 1], rtol * h)
    for lab, t, what in ((rows, uv[:, 0], "row"), (cols, uv[:, 1], "column")):
        spread = np.bincount(lab, weights=t) / np.bincount(lab)
        worst = float(np.max(np.abs(t - spread[lab])))
        if worst > 0.5 * h:
            raise GridError(f"{where}: nodes of one {what} spread over {worst:.3g} m along its axis (node spacing "
                            f"{h:.3g} m): the flank's nodes do not lie in straight rows and columns along these axes")
    return rows, cols


def _complete_part(grid: np.ndarray, incomplete: str, where: str, n_points: int) -> np.ndarray:
    """The lattice ``grid`` (−1 at empty positions) itself when complete, else its complete rows or columns as
    ``incomplete`` asks (module notes, step 3)."""
    full = grid >= 0
    if full.all():
        return grid
    keep_r, keep_c = full.all(axis=1), full.all(axis=0)
    if incomplete == "drop_rows" and keep_r.sum() >= 2:
        log.info("%s: dropped %d incomplete rows (%d nodes)", where, int((~keep_r).sum()), int(full[~keep_r].sum()))
        return grid[keep_r]
    if incomplete == "drop_cols" and keep_c.sum() >= 2:
        log.info("%s: dropped %d incomplete columns (%d nodes)", where, int((~keep_c).sum()),
                 int(full[:, ~keep_c].sum()))
        return grid[:, keep_c]
    hint = ("" if incomplete != "error" else
            "; with mid-side nodes of quadratic elements, incomplete='drop_rows' or 'drop_cols' keeps "
            "the complete rows or columns")
    R, C = grid.shape
    raise GridError(f"{where}: the {n_points} nodes fill {int(full.sum())} of the {R} × {C} positions of "
                    f"their rows and columns: not a complete grid{hint}")


@dataclass(frozen=True, eq=False)
class InterfaceGrids:
    """Contact grids of a bladed disk, as node *indices* of the components.

    Attributes
    ----------
    blade : mapping flank → ndarray of int64, shape (rows, cols)
        Blade root grids (node indices of the blade component).
    disk : mapping (slot, flank) → ndarray of int64, shape (rows, cols)
        Slot grids (node indices of the disk component), slots 1..n_slots.
    axes : mapping flank → FlankAxes, optional
        The blade-frame axes the grids were ordered along (``None`` for explicit grids).
    """

    blade: Mapping[str, np.ndarray]
    disk: Mapping[tuple[int, str], np.ndarray]
    axes: Mapping[str, FlankAxes] | None = None

    @property
    def flanks(self) -> tuple[str, ...]:
        return tuple(self.blade)

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(next(iter(self.blade.values())).shape)


def grids_from_node_sets(
    disk: Component,
    blade: Component,
    placement: BladePlacement,
    *,
    flanks: Sequence[str] = ("L", "R"),
    disk_set: str = "slot{slot}_{flank}",
    blade_set: str = "{flank}",
    axes: Mapping[str, FlankAxes] | FlankAxes | None = None,
    shape: tuple[int, int] | None = None,
    rtol: float = DEFAULT_RTOL,
    incomplete: str = "error",
) -> InterfaceGrids:
    """Build every flank grid from named node sets and coordinates.

    Parameters
    ----------
    disk, blade : Component
        With node sets named by ``disk_set`` (``{slot}``, ``{flank}`` substituted) and ``blade_set``.
    placement : BladePlacement
        Slots and blade placement; disk flanks are ordered in the placed blade's frame.
    flanks : sequence of str
        Flank names (``"L"``, ``"R"``).
    axes : FlankAxes or mapping flank → FlankAxes, optional
        Grid axes in the blade frame (default: :func:`principal_axes` of each blade flank).
    shape : (int, int), optional
        Expected grid shape (default: the blade's first flank's).
    rtol, incomplete
        See :func:`grid_from_points`.

    Returns
    -------
    InterfaceGrids
    """
    blade_grids: dict[str, np.ndarray] = {}
    used_axes: dict[str, FlankAxes] = {}
    disk_grids: dict[tuple[int, str], np.ndarray] = {}
    for f in flanks:
        nodes = np.asarray(blade.node_set(blade_set.format(flank=f)), dtype=np.int64).ravel()
        X = blade.coords[nodes]
        ax = axes.get(f) if isinstance(axes, Mapping) else axes
        ax = ax if ax is not None else principal_axes(X)
        where = f"blade ({blade.meta.get('source', blade.name)}) node set {blade_set.format(flank=f)!r}"
        g, _ = grid_from_points(X, ax, rtol=rtol, incomplete=incomplete, shape=shape, where=where)
        shape = tuple(g.shape)
        blade_grids[f] = nodes[g]
        used_axes[f] = ax
        for s in range(1, placement.n_slots + 1):
            key = disk_set.format(slot=s, flank=f)
            dn = np.asarray(disk.node_set(key), dtype=np.int64).ravel()
            Xd = placement.to_blade_frame(disk.coords[dn], s)
            where = f"disk ({disk.meta.get('source', disk.name)}) node set {key!r}"
            gd, _ = grid_from_points(Xd, ax, rtol=rtol, incomplete=incomplete, shape=shape, where=where)
            disk_grids[(s, f)] = dn[gd]
    return InterfaceGrids(blade_grids, disk_grids, used_axes)


def grids_from_ids(
    disk: Component,
    blade: Component,
    grids: Mapping[tuple[int, str], np.ndarray],
    n_slots: int,
    *,
    where: str = "grids",
) -> InterfaceGrids:
    """:class:`InterfaceGrids` from explicit node-id grids (:func:`rom.importers.csvio.read_grids_csv`).

    ``grids[(0, flank)]`` are the blade's, ``grids[(s, flank)]`` disk slot s's; every slot 1..n_slots needs
    every flank of the blade, all of one shape.
    """
    flanks = sorted(f for s, f in grids if s == 0)
    if not flanks:
        raise GridError(f"{where}: no blade grid (slot 0)")
    shape = grids[(0, flanks[0])].shape
    blade_grids, disk_grids = {}, {}
    for (s, f), ids in grids.items():
        if s > n_slots:
            raise GridError(f"{where}: slot {s} but the model has {n_slots} slots")
        if f not in flanks:
            raise GridError(f"{where}: slot {s} has flank {f!r}, the blade has only {flanks}")
        if ids.shape != shape:
            raise GridError(f"{where}: grid of slot {s} flank {f!r} is {ids.shape[0]} × {ids.shape[1]}, the blade's "
                            f"is {shape[0]} × {shape[1]}")
        if s == 0:
            blade_grids[f] = node_indices(blade.node_ids, ids, where, f"the blade grid of flank {f!r}")
        else:
            disk_grids[(s, f)] = node_indices(disk.node_ids, ids, where, f"the grid of slot {s} flank {f!r}")
    missing = [(s, f) for s in range(1, n_slots + 1) for f in flanks if (s, f) not in disk_grids]
    if missing:
        raise GridError(f"{where}: no grid for slot {missing[0][0]} flank {missing[0][1]!r} ({len(missing)} missing)")
    return InterfaceGrids(blade_grids, disk_grids, None)


def _grid_spacing(X: np.ndarray) -> float:
    """Smallest distance between neighbouring grid nodes, X of shape (rows, cols, 3)."""
    d = [np.linalg.norm(np.diff(X, axis=a), axis=-1) for a in (0, 1)]
    return float(min(v.min() for v in d if v.size))


def check_conformity(
    disk: Component,
    blade: Component,
    grids: InterfaceGrids,
    placement: BladePlacement,
    *,
    tolerance: float | None = None,
    gap_rtol: float = DEFAULT_GAP_RTOL,
) -> float:
    """Largest gap between disk and placed-blade grid nodes over all slots and flanks; refuse it beyond a tolerance.

    Parameters
    ----------
    tolerance : float, optional
        Largest gap accepted (m). Default: ``gap_rtol`` times the smallest grid node spacing of the blade.

    Returns
    -------
    float
        The largest gap (m).

    Raises
    ------
    GridError
        Naming the slot, flank, grid position, both nodes and the gap.
    """
    h = min(_grid_spacing(blade.coords[g]) for g in grids.blade.values())
    tol = gap_rtol * h if tolerance is None else float(tolerance)
    worst = 0.0
    for (s, f), gd in grids.disk.items():
        gb = grids.blade[f]
        gap = np.linalg.norm(disk.coords[gd] - placement.place(blade.coords[gb], s), axis=-1)
        k = np.unravel_index(int(np.argmax(gap)), gap.shape)
        worst = max(worst, float(gap[k]))
        if gap[k] > tol:
            how = f"{gap_rtol:g} of the {h:.3g} m grid spacing" if tolerance is None else "given"
            raise GridError(
                f"disk slot {s} flank {f!r} does not conform to the blade placed in it: gap {gap[k]:.3g} m at grid row "
                f"{k[0] + 1}, col {k[1] + 1} (disk node {int(disk.node_ids[gd[k]])}, blade node "
                f"{int(blade.node_ids[gb[k]])}); tolerance {tol:.3g} m ({how})"
            )
    return worst
