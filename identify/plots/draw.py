"""Shared helpers of the identification plots: checked inputs, tick labels, and the one pattern orientation.

:func:`draw_pattern` is the only function that draws a contact pattern (orientation: :mod:`identify.plots`).
The ``checked_*`` helpers turn inputs of the wrong shape into one-line :class:`~identify.errors.IdentifyError`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import QuadMesh
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.ticker import MaxNLocator
from numpy.typing import ArrayLike

from rom.academic import flank_coordinates

from ..errors import IdentifyError

__all__ = [
    "PATTERN_CMAP",
    "REF_COLOR",
    "PRED_COLOR",
    "FLANKS",
    "figure_axes",
    "checked_array",
    "tick_labels",
    "checked_indices",
    "cell_edges",
    "draw_pattern",
    "map_stack",
    "joint_patterns",
    "joint_axis",
]

PATTERN_CMAP = "Greys"  # 0 white, 1 black: dark = contact, as on the film
#: Reference (actual, measured) in red and predicted in blue, as in the paper's centroid figures.
REF_COLOR, PRED_COLOR = "tab:red", "tab:blue"
FLANKS = ("L", "R")
_AXIAL_LABEL, _RADIAL_LABEL = "axial row", "radial column → rim"


def figure_axes(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    """``ax`` and its figure, or a new constrained-layout figure of ``figsize`` (inches) with one axes."""
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.add_subplot(1, 1, 1)


def checked_array(name: str, a, ndim: int, shape: tuple[int | None, ...] | None = None) -> np.ndarray:
    """``a`` as float64 with ``ndim`` dimensions (and ``shape``, None = any size); IdentifyError otherwise."""
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise IdentifyError(f"{name}: expected a numeric array, got {type(a).__name__}") from None
    want = shape if shape is not None else (None,) * ndim
    if arr.ndim != ndim or any(w is not None and w != s for w, s in zip(want, arr.shape, strict=False)):
        text = "(" + ", ".join("n" if w is None else str(w) for w in want) + ")"
        raise IdentifyError(f"{name} has shape {arr.shape}: expected {text}")
    return arr


def tick_labels(name: str, labels: Sequence[str] | None, n: int, default: str) -> list[str]:
    """Tick labels: the given ones (exactly n), or ``default.format(k)`` for k = 1..n."""
    if labels is None:
        return [default.format(k) for k in range(1, n + 1)]
    out = [str(x) for x in labels]
    if len(out) != n:
        raise IdentifyError(f"{name} holds {len(out)} labels: expected {n}")
    return out


def checked_indices(name: str, idx, n: int, what: str = "mode") -> list[int]:
    """0-based indices in 0..n − 1 (IdentifyError names the first bad one)."""
    try:
        a = np.asarray(idx if idx is not None else [], dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise IdentifyError(f"{name}: expected 0-based {what} indices, got {idx!r}") from None
    for k in a:
        if not np.isfinite(k) or k != int(k) or not 0 <= k < n:
            raise IdentifyError(f"{name}: {what} index {k:g} outside 0..{n - 1} (0-based)")
    return [int(k) for k in a]


def cell_edges(coordinates, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Cell edges (mm) along the rows (axial u) and the columns (radial v), shapes (rows + 1,), (cols + 1,).

    The grid's nodes are cell centres, as on the film; the outer cells are as wide as their neighbours.
    """
    if hasattr(coordinates, "blade"):  # a rom.academic.BladedDisk
        coordinates = flank_coordinates(coordinates)
    try:
        u, v = coordinates
    except (TypeError, ValueError):
        raise IdentifyError("coordinates: expected (u, v) arrays of the grid shape or a BladedDisk") from None
    u = checked_array("coordinates u", u, 2, shape)
    v = checked_array("coordinates v", v, 2, shape)
    # A flank grid is axis-aligned in (u, v): u is constant along a row, v along a column.
    u_row, v_col = u.mean(axis=1) * 1e3, v.mean(axis=0) * 1e3
    for axis, c, what in (("u", u_row, "row"), ("v", v_col, "column")):
        if c.size > 1 and not np.all(np.diff(c) > 0):
            raise IdentifyError(f"coordinates {axis} must grow with the grid {what} (film orientation), got "
                                f"{np.array2string(c, precision=3, max_line_width=10_000)} mm")

    def edges(c: np.ndarray) -> np.ndarray:
        if c.size == 1:
            return np.array([c[0] - 0.5, c[0] + 0.5])
        mid = 0.5 * (c[1:] + c[:-1])
        return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])

    return edges(u_row), edges(v_col)


def draw_pattern(ax: Axes, grid: ArrayLike, coordinates=None, *, vmin: float = 0.0, vmax: float = 1.0
                  ) -> AxesImage | QuadMesh:
    """Draw one contact pattern (or gray map) in the one orientation of :mod:`identify.plots`; the only place that does.

    Parameters
    ----------
    ax : Axes
    grid : array_like of bool or float, shape (rows, cols)
        ``grid[i, j]`` lands on image row i (axial, downwards), column j (radial, rim to the right).
    coordinates : (u, v) or BladedDisk, optional
        Node coordinates (m), each of shape (rows, cols): the pattern is then drawn in mm with cell edges
        half-way between nodes. Without them, in grid indices.
    vmin, vmax : float
        Colour range (``Greys``: vmin white, vmax black).

    Returns
    -------
    AxesImage (grid indices) or QuadMesh (physical coordinates)
    """
    g = checked_array("pattern", grid, 2)
    if coordinates is None:
        art = ax.imshow(g, cmap=PATTERN_CMAP, vmin=vmin, vmax=vmax, origin="upper", interpolation="nearest",
                        aspect="equal")
        # Few integer ticks: a 7-row pattern is a thin strip, and every row labelled would overlap.
        ax.xaxis.set_major_locator(MaxNLocator(nbins=8, integer=True))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=3, integer=True))
        ax.set_xlabel(_RADIAL_LABEL)
        ax.set_ylabel(_AXIAL_LABEL)
        return art
    u_edges, v_edges = cell_edges(coordinates, g.shape)
    art = ax.pcolormesh(v_edges, u_edges, g, cmap=PATTERN_CMAP, vmin=vmin, vmax=vmax, shading="flat")
    ax.set_xlim(v_edges[0], v_edges[-1])
    ax.set_ylim(u_edges[-1], u_edges[0])  # inverted: u (and the row index) grows downwards, as on the film
    ax.set_aspect("equal")
    ax.set_xlabel("radial v [mm] → rim")
    ax.set_ylabel("axial u [mm]")
    return art


def map_stack(name: str, maps, shape: tuple[int, int] | None = None, *, gray: bool = False) -> np.ndarray:
    """(n, rows, cols) float maps from an array, or from a sequence of FilmMap (``.gray`` or ``.contact``)."""
    if isinstance(maps, Sequence) and len(maps) and hasattr(maps[0], "contact"):
        maps = [m.gray if gray else m.contact for m in maps]
    return checked_array(name, maps, 3, (None, *shape) if shape is not None else None)


def joint_patterns(name: str, patterns, n_joints: int) -> np.ndarray:
    """(n_joints, 2, rows, cols) from such an array or a sequence of objects with ``.L`` and ``.R``."""
    if isinstance(patterns, Sequence) and len(patterns) and hasattr(patterns[0], "L"):
        patterns = [[p.L, p.R] for p in patterns]
    return checked_array(name, patterns, 4, (n_joints, 2, None, None))


def joint_axis(ax: Axes, labels: list[str]) -> np.ndarray:
    """One x tick per joint at 1..n, labelled (vertical when long); returns the tick positions."""
    x = np.arange(1, len(labels) + 1)
    ax.set_xticks(x, labels, rotation=90 if max(map(len, labels)) > 3 else 0)
    ax.set_xlim(0.3, len(labels) + 0.7)
    return x
