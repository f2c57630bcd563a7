"""Contact-pattern figures: one pattern, and the synthetic patterns beside the known ones (paper Fig. 14)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import ArrayLike

from ..errors import IdentifyError
from ..synthetic import SyntheticPatterns
from .draw import FLANKS, cell_edges, checked_array, draw_pattern, figure_axes, map_stack, tick_labels

__all__ = ["plot_pattern", "plot_synthetic_patterns"]


def plot_pattern(grid: ArrayLike, *, coordinates=None, title: str | None = None, ax: Axes | None = None) -> Figure:
    """One contact pattern (or gray map) in the orientation of :mod:`identify.plots` (its docstring).

    Parameters
    ----------
    grid : array_like of bool or float, shape (rows, cols)
        A contact grid (True = contact, drawn black) or a gray map (darkness in [0, 1]).
    coordinates : (u, v) or rom.academic.BladedDisk, optional
        Node coordinates in m, arrays of shape (rows, cols) (e.g. :func:`rom.academic.flank_coordinates`):
        draw in mm instead of grid indices.
    title : str, optional
    ax : Axes, optional

    Returns
    -------
    Figure
    """
    g = checked_array("grid", grid, 2)
    if coordinates is not None:  # size the figure on the flank's physical aspect, not on its node counts
        u_edges, v_edges = cell_edges(coordinates, g.shape)
        aspect = (u_edges[-1] - u_edges[0]) / (v_edges[-1] - v_edges[0])
    else:
        aspect = g.shape[0] / g.shape[1]
    width = 6.0 if aspect < 1 else max(3.0, 6.0 / aspect)
    fig, ax = figure_axes(ax, (width, min(8.0, width * aspect + 1.2)))
    draw_pattern(ax, g, coordinates)
    if title:
        ax.set_title(title)
    return fig


def plot_synthetic_patterns(patterns: SyntheticPatterns, known_L=None, known_R=None, *,
                            known_labels: Sequence[str] | None = None, gray: bool = False,
                            fig: Figure | None = None) -> Figure:
    """Synthetic contact patterns of both flank sides beside the known ones (paper Fig. 14).

    Columns, left to right: known L (if given), synthetic L, known R (if given), synthetic R; one pattern per
    row. Unused panels are removed, so the figure holds one axes per pattern drawn (plus a colour bar when
    ``gray``).

    Parameters
    ----------
    patterns : SyntheticPatterns
        From :func:`identify.synthetic.sample_patterns`: ``L`` (n_L, rows, cols), ``R`` (n_R, rows, cols),
        ``gray_L``, ``gray_R`` and ``labels_L``, ``labels_R``.
    known_L, known_R : array_like of shape (n_known, rows, cols), or sequence of FilmMap, optional
        The known (measured) joints' maps of each side: contact grids, or gray maps when ``gray``.
    known_labels : sequence of str, optional
        One label per known joint (e.g. "BR-3"), shared by both sides; default "known 1", "known 2", …
    gray : bool
        Draw the grayscale maps (Eq. 32; darkness, 1 = black) instead of the thresholded contact grids.
    fig : Figure, optional

    Returns
    -------
    Figure
    """
    for attr in ("L", "R", "labels_L", "labels_R") + (("gray_L", "gray_R") if gray else ()):
        if not hasattr(patterns, attr):
            raise IdentifyError(f"patterns: expected a SyntheticPatterns (fields L, R, gray_L, gray_R, labels_L, "
                                f"labels_R), got {type(patterns).__name__} without {attr!r}")
    syn = {s: checked_array(f"patterns.{'gray_' if gray else ''}{s}", getattr(patterns, f"gray_{s}" if gray else s), 3)
           for s in FLANKS}
    shape = syn["L"].shape[1:]
    if syn["R"].shape[1:] != shape:
        raise IdentifyError(f"patterns: L grids {shape} and R grids {syn['R'].shape[1:]} differ in shape")
    columns: list[tuple[str, np.ndarray, list[str]]] = []
    for side, known in (("L", known_L), ("R", known_R)):
        if known is not None:
            k = map_stack(f"known_{side}", known, shape, gray=gray)
            labels = tick_labels("known_labels", known_labels, k.shape[0], "known {}")
            columns.append((side, k, [f"{side} · {lab} (known)" for lab in labels]))
        n_syn = syn[side].shape[0]
        syn_labels = tick_labels(f"patterns.labels_{side}", getattr(patterns, f"labels_{side}"), n_syn, "SP-{}")
        columns.append((side, syn[side], [f"{side} · {lab}" for lab in syn_labels]))
    n_rows = max(c[1].shape[0] for c in columns)
    rows, cols = shape
    panel_w = 3.2
    fig = fig or Figure(figsize=(panel_w * len(columns), n_rows * (panel_w * rows / cols + 0.65) + 0.6),
                        layout="constrained")
    axs = fig.subplots(n_rows, len(columns), squeeze=False)
    art = None
    for c, (_, maps, labels) in enumerate(columns):
        for r in range(n_rows):
            ax = axs[r, c]
            if r >= maps.shape[0]:
                ax.remove()  # this column holds fewer patterns
                continue
            art = draw_pattern(ax, maps[r])
            ax.set_title(labels[r], fontsize="small")
            # Axis names only on each column's last panel and on the first column, to keep small panels readable.
            if r != maps.shape[0] - 1:
                ax.set_xlabel("")
            if c != 0:
                ax.set_ylabel("")
    if gray and art is not None:
        fig.colorbar(art, ax=[a for a in axs.ravel() if a in fig.axes], shrink=0.5,
                     label="darkness (1 = black = high pressure)")
    what = "gray maps, dark = high pressure" if gray else "contact grids, black = contact"
    fig.suptitle(f"synthetic patterns, {syn['L'].shape[0]} L × {syn['R'].shape[0]} R: {what}")
    return fig
