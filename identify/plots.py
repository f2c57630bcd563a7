"""Identification plots (paper Figs. 14–16, 19, 21–28). They only read results; nothing is identified here.

Each ``plot_*`` function draws one result object of :mod:`identify` (or plain arrays) and returns the
:class:`~matplotlib.figure.Figure`. Single-panel functions take an optional ``ax``, multi-panel ones an
optional ``fig`` to fill. None of them calls ``pyplot``, so they run under any backend (Agg included).
Inputs of the wrong shape raise :class:`~identify.errors.IdentifyError` with a one-line message.

Contact-pattern orientation
---------------------------
Every contact pattern is drawn by one helper (``_draw_pattern``), laid out like a film scan (``lab.films``,
docs/campaign.md "Film images"):

* ``grid[i, j]`` is image row i, column j. Rows run along the **axial** direction, **downwards** (u grows
  from the top); columns run **radially outwards** to the right, with the slot bottom at the left edge and
  the rim at the right. The aspect ratio is equal.
* Dark means contact, as dark means high pressure on the film (``Greys`` colour map, 0 white, 1 black). Gray
  maps (darkness, 1 = black) use the same map.
* In physical coordinates (``u, v`` of :func:`rom.academic.flank_coordinates`, drawn in mm) the layout is
  the same: v (radial) to the right, u (axial) growing downwards. Coordinates whose u does not grow with the
  row, or whose v does not grow with the column, are refused, so a pattern can never come out flipped.

Colours: reference (actual, measured) is red and predicted is blue, as in the paper's centroid figures.
Mode numbers on the axes are 1-based ("mode 5"). Mode indices passed as arguments (``feature_modes``,
``modes``) are 0-based, as in the result objects.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import QuadMesh
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from numpy.typing import ArrayLike

from rom.academic import flank_coordinates

from .errors import IdentifyError
from .sampler import SyntheticPatterns
from .validation import D1BValidation, GeometricValidation, GridError, ModeComparison

__all__ = [
    "plot_pattern",
    "plot_synthetic_patterns",
    "plot_sensitivity",
    "plot_frequency_maps",
    "plot_grid_error",
    "plot_area_fractions",
    "plot_centroids",
    "plot_d1b_validation",
    "plot_mode_comparison",
]

_PATTERN_CMAP = "Greys"  # 0 white, 1 black: dark = contact, as on the film
_REF, _PRED = "tab:red", "tab:blue"
_FEATURE, _OTHER = "tab:orange", "0.65"
_FLANKS = ("L", "R")
_AXIAL_LABEL, _RADIAL_LABEL = "axial row", "radial column → rim"
#: Fields of a sensitivity result per unit, first found wins (identify.sensitivity.Sensitivity: std_rel_pct, std_hz).
_STD_FIELDS = {"pct": ("std_rel_pct", "std_pct"), "hz": ("std_hz",)}


# ------------------------------------------------------------------------------------------ helpers
def _axes(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.add_subplot(1, 1, 1)


def _array(name: str, a, ndim: int, shape: tuple[int | None, ...] | None = None) -> np.ndarray:
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


def _labels(name: str, labels: Sequence[str] | None, n: int, default: str) -> list[str]:
    """Tick labels: the given ones (exactly n), or ``default.format(k)`` for k = 1..n."""
    if labels is None:
        return [default.format(k) for k in range(1, n + 1)]
    out = [str(x) for x in labels]
    if len(out) != n:
        raise IdentifyError(f"{name} holds {len(out)} labels: expected {n}")
    return out


def _indices(name: str, idx, n: int, what: str = "mode") -> list[int]:
    """0-based indices in 0..n − 1 (IdentifyError names the first bad one)."""
    try:
        a = np.asarray(idx if idx is not None else [], dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise IdentifyError(f"{name}: expected 0-based {what} indices, got {idx!r}") from None
    for k in a:
        if not np.isfinite(k) or k != int(k) or not 0 <= k < n:
            raise IdentifyError(f"{name}: {what} index {k:g} outside 0..{n - 1} (0-based)")
    return [int(k) for k in a]


def _cell_edges(coordinates, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Cell edges (mm) along the rows (axial u) and the columns (radial v), shapes (rows + 1,), (cols + 1,).

    The grid's nodes are cell centres, as on the film; the outer cells are as wide as their neighbours.
    """
    if hasattr(coordinates, "blade"):  # a rom.academic.BladedDisk
        coordinates = flank_coordinates(coordinates)
    try:
        u, v = coordinates
    except (TypeError, ValueError):
        raise IdentifyError("coordinates: expected (u, v) arrays of the grid shape or a BladedDisk") from None
    u = _array("coordinates u", u, 2, shape)
    v = _array("coordinates v", v, 2, shape)
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


def _draw_pattern(ax: Axes, grid: ArrayLike, coordinates=None, *, vmin: float = 0.0, vmax: float = 1.0
                  ) -> AxesImage | QuadMesh:
    """Draw one contact pattern (or gray map) in the module's one orientation; the only place that does.

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
    g = _array("pattern", grid, 2)
    if coordinates is None:
        art = ax.imshow(g, cmap=_PATTERN_CMAP, vmin=vmin, vmax=vmax, origin="upper", interpolation="nearest",
                        aspect="equal")
        # Few integer ticks: a 7-row pattern is a thin strip, and every row labelled would overlap.
        ax.xaxis.set_major_locator(MaxNLocator(nbins=8, integer=True))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=3, integer=True))
        ax.set_xlabel(_RADIAL_LABEL)
        ax.set_ylabel(_AXIAL_LABEL)
        return art
    u_edges, v_edges = _cell_edges(coordinates, g.shape)
    art = ax.pcolormesh(v_edges, u_edges, g, cmap=_PATTERN_CMAP, vmin=vmin, vmax=vmax, shading="flat")
    ax.set_xlim(v_edges[0], v_edges[-1])
    ax.set_ylim(u_edges[-1], u_edges[0])  # inverted: u (and the row index) grows downwards, as on the film
    ax.set_aspect("equal")
    ax.set_xlabel("radial v [mm] → rim")
    ax.set_ylabel("axial u [mm]")
    return art


def _stack(name: str, maps, shape: tuple[int, int] | None = None, *, gray: bool = False) -> np.ndarray:
    """(n, rows, cols) float maps from an array, or from a sequence of FilmMap (``.gray`` or ``.contact``)."""
    if isinstance(maps, Sequence) and len(maps) and hasattr(maps[0], "contact"):
        maps = [m.gray if gray else m.contact for m in maps]
    return _array(name, maps, 3, (None, *shape) if shape is not None else None)


def _joint_patterns(name: str, patterns, n_joints: int) -> np.ndarray:
    """(n_joints, 2, rows, cols) from such an array or a sequence of objects with ``.L`` and ``.R``."""
    if isinstance(patterns, Sequence) and len(patterns) and hasattr(patterns[0], "L"):
        patterns = [[p.L, p.R] for p in patterns]
    return _array(name, patterns, 4, (n_joints, 2, None, None))


def _joint_axis(ax: Axes, labels: list[str]) -> np.ndarray:
    x = np.arange(1, len(labels) + 1)
    ax.set_xticks(x, labels, rotation=90 if max(map(len, labels)) > 3 else 0)
    ax.set_xlim(0.3, len(labels) + 0.7)
    return x


# ---------------------------------------------------------------------------------------- patterns
def plot_pattern(grid: ArrayLike, *, coordinates=None, title: str | None = None, ax: Axes | None = None) -> Figure:
    """One contact pattern (or gray map) in the module's orientation (module docstring).

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
    g = _array("grid", grid, 2)
    if coordinates is not None:  # size the figure on the flank's physical aspect, not on its node counts
        u_edges, v_edges = _cell_edges(coordinates, g.shape)
        aspect = (u_edges[-1] - u_edges[0]) / (v_edges[-1] - v_edges[0])
    else:
        aspect = g.shape[0] / g.shape[1]
    width = 6.0 if aspect < 1 else max(3.0, 6.0 / aspect)
    fig, ax = _axes(ax, (width, min(8.0, width * aspect + 1.2)))
    _draw_pattern(ax, g, coordinates)
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
        From :func:`identify.sampler.sample_patterns`: ``L`` (n_L, rows, cols), ``R`` (n_R, rows, cols),
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
    syn = {s: _array(f"patterns.{'gray_' if gray else ''}{s}", getattr(patterns, f"gray_{s}" if gray else s), 3)
           for s in _FLANKS}
    shape = syn["L"].shape[1:]
    if syn["R"].shape[1:] != shape:
        raise IdentifyError(f"patterns: L grids {shape} and R grids {syn['R'].shape[1:]} differ in shape")
    columns: list[tuple[str, np.ndarray, list[str]]] = []
    for side, known in (("L", known_L), ("R", known_R)):
        if known is not None:
            k = _stack(f"known_{side}", known, shape, gray=gray)
            labels = _labels("known_labels", known_labels, k.shape[0], "known {}")
            columns.append((side, k, [f"{side} · {lab} (known)" for lab in labels]))
        n_syn = syn[side].shape[0]
        syn_labels = _labels(f"patterns.labels_{side}", getattr(patterns, f"labels_{side}"), n_syn, "SP-{}")
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
            art = _draw_pattern(ax, maps[r])
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


# ---------------------------------------------------------------------------------------- sensitivity
def plot_sensitivity(sensitivity, feature_modes: Sequence[int] | None = None, *, unit: str = "pct",
                     ax: Axes | None = None) -> Figure:
    """Standard deviation of each disk–one-blade mode's frequency over the pattern pairs (paper Fig. 15).

    Parameters
    ----------
    sensitivity : Sensitivity, object or array_like of shape (n_modes,)
        :class:`identify.sensitivity.Sensitivity` (or any object with ``std_rel_pct`` and/or ``std_hz``, shape
        (n_modes,), and ``feature_modes``), or the standard deviations themselves, in ``unit``.
    feature_modes : sequence of int, optional
        0-based indices of the chosen feature modes, highlighted; default ``sensitivity.feature_modes``.
    unit : {"pct", "hz"}
        Bar height: standard deviation relative to the mode's mean frequency (%), or in Hz. When the object
        holds the other unit too, each bar is annotated with it.
    ax : Axes, optional

    Returns
    -------
    Figure
    """
    if unit not in ("pct", "hz"):
        raise IdentifyError(f"unit={unit!r}: expected 'pct' or 'hz'")
    other_unit = "hz" if unit == "pct" else "pct"

    def field(u: str) -> str | None:
        return next((f for f in _STD_FIELDS[u] if getattr(sensitivity, f, None) is not None), None)

    if isinstance(sensitivity, np.ndarray | list | tuple):
        std, other = _array("sensitivity", sensitivity, 1), None
    else:
        name, o_name = field(unit), field(other_unit)
        if name is None:
            raise IdentifyError(f"sensitivity: {type(sensitivity).__name__} has no {' or '.join(_STD_FIELDS[unit])}"
                                f"; pass unit={other_unit!r} or the standard deviations as an array")
        std = _array(f"sensitivity.{name}", getattr(sensitivity, name), 1)
        other = _array(f"sensitivity.{o_name}", getattr(sensitivity, o_name), 1, (std.size,)) if o_name else None
        if feature_modes is None:
            feature_modes = getattr(sensitivity, "feature_modes", None)
    n = std.size
    feat = _indices("feature_modes", feature_modes, n)
    fig, ax = _axes(ax, (max(5.0, 0.55 * n + 2), 4))
    x = np.arange(1, n + 1)
    colors = [_FEATURE if k in feat else _OTHER for k in range(n)]
    bars = ax.bar(x, std, color=colors, edgecolor="k", linewidth=0.5)
    if other is not None:
        fmt = "{:.2f} Hz" if other_unit == "hz" else "{:.2f} %"
        ax.bar_label(bars, [fmt.format(v) for v in other], fontsize="x-small", padding=2)
    ax.set_xticks(x, [str(k) for k in x])
    ax.set_xlabel("disk–one-blade mode")
    ax.set_ylabel("std of frequency [%]" if unit == "pct" else "std of frequency [Hz]")
    ax.set_ylim(0, 1.15 * float(np.nanmax(std)) if n and np.nanmax(std) > 0 else 1)
    # "best" keeps the legend off the bars and their value labels, wherever the tall bars are
    ax.legend(handles=[Patch(color=_FEATURE, label="feature mode"), Patch(color=_OTHER, label="other")],
              fontsize="small", loc="best")
    chosen = ", ".join(str(k + 1) for k in feat) or "none"
    ax.set_title(f"frequency sensitivity to the contact pattern (feature modes {chosen})")
    return fig


def plot_frequency_maps(frequencies_hz, modes: Sequence[int] | None = None, *, labels_L: Sequence[str] | None = None,
                        labels_R: Sequence[str] | None = None, fig: Figure | None = None) -> Figure:
    """Frequency of chosen modes over the pattern pairs: left pattern → x, right pattern → y (paper Fig. 16).

    Parameters
    ----------
    frequencies_hz : object or array_like of shape (n_L, n_R, n_modes)
        Frequencies (Hz) of the disk–one-blade modes for each pair (i_L, i_R), or an object holding them as
        ``frequencies_hz`` (with ``feature_modes``, the default ``modes``).
    modes : sequence of int, optional
        0-based mode indices, one panel each; default the object's ``feature_modes``, else every mode.
    labels_L, labels_R : sequence of str, optional
        Tick labels of the patterns (e.g. ``SyntheticPatterns.labels_L``); default 1..n.
    fig : Figure, optional

    Returns
    -------
    Figure
        One image (with its colour bar) per mode; pair (i_L, i_R) is the cell at column i_L, row i_R, with
        pattern 1 at the bottom left.
    """
    if modes is None:
        modes = getattr(frequencies_hz, "feature_modes", None)
    F = _array("frequencies_hz", getattr(frequencies_hz, "frequencies_hz", frequencies_hz), 3)
    n_L, n_R, n_modes = F.shape
    chosen = _indices("modes", modes, n_modes) if modes is not None else list(range(n_modes))
    if not chosen:
        raise IdentifyError("modes: expected at least one mode index")
    tl = _labels("labels_L", labels_L, n_L, "{}")
    tr = _labels("labels_R", labels_R, n_R, "{}")
    n_cols = min(3, len(chosen))
    n_rows = -(-len(chosen) // n_cols)
    fig = fig or Figure(figsize=(4.6 * n_cols, 4.0 * n_rows), layout="constrained")
    axs = fig.subplots(n_rows, n_cols, squeeze=False).ravel()
    for ax in axs[len(chosen):]:
        ax.remove()
    for ax, k in zip(axs, chosen, strict=False):
        # Transposed so that the left pattern runs along x and the right one along y, as in the paper.
        im = ax.imshow(F[:, :, k].T, origin="lower", cmap="viridis", interpolation="nearest",
                       extent=(0.5, n_L + 0.5, 0.5, n_R + 0.5))
        fig.colorbar(im, ax=ax, label="frequency [Hz]", shrink=0.85)
        ax.set_xticks(np.arange(1, n_L + 1), tl, rotation=90 if max(map(len, tl)) > 3 else 0)
        ax.set_yticks(np.arange(1, n_R + 1), tr)
        ax.set_xlabel("L-side pattern")
        ax.set_ylabel("R-side pattern")
        ax.set_title(f"mode {k + 1}")
    return fig


# ------------------------------------------------------------------------------------------ validation
def plot_grid_error(error: GridError, *, mode_labels: Sequence[str] | None = None,
                    blade_labels: Sequence[str] | None = None, ax: Axes | None = None) -> Figure:
    """Step-1 grid error ε of each blade and δ mode, with the ±50 % band of the nearest grid value (Fig. 19).

    Parameters
    ----------
    error : GridError
        ``epsilon_pct`` of shape (n_blades, n_modes) (Eq. 40), from :func:`identify.validation.grid_error`.
    mode_labels : sequence of str, optional
        One per δ mode; default "mode 1", "mode 2", …
    blade_labels : sequence of str, optional
        One per blade; default 1..n_blades.
    ax : Axes, optional

    Returns
    -------
    Figure
        One bar group per blade, one bar per mode; the band |ε| ≤ 50 % is shaded.
    """
    eps = _array("error.epsilon_pct", getattr(error, "epsilon_pct", error), 2)
    n_blades, n_modes = eps.shape
    ml = _labels("mode_labels", mode_labels, n_modes, "mode {}")
    bl = _labels("blade_labels", blade_labels, n_blades, "{}")
    fig, ax = _axes(ax, (max(6.0, 0.45 * n_blades * max(1, n_modes) / 2 + 2), 4))
    ax.axhspan(-50, 50, color="tab:green", alpha=0.12, lw=0)
    for y in (-50, 50):
        ax.axhline(y, color="tab:green", linestyle="--", linewidth=0.8)
    ax.axhline(0, color="k", linewidth=0.5)
    x = _joint_axis(ax, bl)
    w = 0.8 / max(1, n_modes)
    for m in range(n_modes):
        ax.bar(x - 0.4 + (m + 0.5) * w, eps[:, m], width=w, label=ml[m], color=f"C{m}")
    nearest = getattr(error, "nearest", None)  # the result's own |ε| ≤ 50 % test; plain arrays: the same rule
    inside = int(np.count_nonzero(nearest if nearest is not None else np.abs(eps) <= 50.0))
    lim = max(60.0, 1.1 * float(np.nanmax(np.abs(eps))) if eps.size else 60.0)
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("blade")
    ax.set_ylabel("grid error ε [%]")
    ax.set_title(f"step-1 grid error: {inside} of {eps.size} within ±50 %")
    ax.legend(fontsize="small", ncols=min(n_modes, 4), loc="upper right")
    return fig


def _check_geometric(validation: GeometricValidation) -> tuple[np.ndarray, ...]:
    a_p = _array("validation.area_pct_pred", validation.area_pct_pred, 2, (None, 2))
    n = a_p.shape[0]
    a_r = _array("validation.area_pct_ref", validation.area_pct_ref, 2, (n, 2))
    c_p = _array("validation.centroid_pred", validation.centroid_pred, 3, (n, 2, 2))
    c_r = _array("validation.centroid_ref", validation.centroid_ref, 3, (n, 2, 2))
    return a_p, a_r, c_p, c_r


def plot_area_fractions(validation: GeometricValidation, *, joint_labels: Sequence[str] | None = None,
                        fig: Figure | None = None) -> Figure:
    """Predicted against reference contact area fraction A_c per joint, flank L above R (Figs. 21, 25).

    Parameters
    ----------
    validation : GeometricValidation
        ``area_pct_pred``, ``area_pct_ref`` of shape (n_joints, 2) (flanks L, R), Eq. 41.
    joint_labels : sequence of str, optional
        One per joint; default 1..n_joints.
    fig : Figure, optional

    Returns
    -------
    Figure
        Two axes (L, R), each with a reference and a predicted bar per joint.
    """
    a_p, a_r, _, _ = _check_geometric(validation)
    labels = _labels("joint_labels", joint_labels, a_p.shape[0], "{}")
    fig = fig or Figure(figsize=(max(6.0, 0.45 * len(labels) + 2), 6), layout="constrained")
    axs = fig.subplots(2, 1, sharex=True)
    for f, ax in enumerate(axs):
        x = _joint_axis(ax, labels)
        ax.bar(x - 0.2, a_r[:, f], width=0.4, color=_REF, label="reference")
        ax.bar(x + 0.2, a_p[:, f], width=0.4, color=_PRED, label="predicted")
        ax.set_ylim(0, 100)
        ax.set_ylabel(f"A_c, flank {_FLANKS[f]} [%]")
        ax.grid(axis="y", linewidth=0.4, alpha=0.5)
    axs[0].legend(fontsize="small", ncols=2, loc="upper right")
    axs[1].set_xlabel("joint")
    axs[0].set_title("contact area fraction, predicted vs reference")
    return fig


def plot_centroids(validation: GeometricValidation, reference, coordinates, predicted=None, *,
                   joints: Sequence[int] | None = None, joint_labels: Sequence[str] | None = None,
                   fig: Figure | None = None) -> Figure:
    """Reference (red) and predicted (blue) contact centroids over the patterns, in mm (Figs. 22, 26).

    Parameters
    ----------
    validation : GeometricValidation
        ``centroid_pred``, ``centroid_ref`` of shape (n_joints, 2, 2): per flank, ``(ū, v̄)`` in m (Eq. 42).
    reference : array_like of bool, shape (n_joints, 2, rows, cols), or sequence of ContactPattern
        Reference patterns, flank axis (L, R): drawn under the centroids.
    coordinates : (u, v) or rom.academic.BladedDisk
        Node coordinates (m), arrays of shape (rows, cols), as given to
        :func:`identify.validation.geometric_validation`.
    predicted : same as ``reference``, optional
        Predicted patterns; each is then drawn beside its reference.
    joints : sequence of int, optional
        0-based joints (rows of ``validation``) to draw, one row of panels each. Default: the best and the
        worst joint by the reference-to-predicted centroid distance averaged over both flanks, as the paper
        shows.
    joint_labels : sequence of str, optional
        One per joint (all n_joints); default "joint 1", "joint 2", …
    fig : Figure, optional

    Returns
    -------
    Figure
        Per joint, panels L reference, [L predicted,] R reference, [R predicted]; both centroids on each.
    """
    _, _, c_p, c_r = _check_geometric(validation)
    n = c_p.shape[0]
    ref = _joint_patterns("reference", reference, n)
    pred = _joint_patterns("predicted", predicted, n) if predicted is not None else None
    if pred is not None and pred.shape != ref.shape:
        raise IdentifyError(f"predicted {pred.shape} and reference {ref.shape} patterns: expected the same shape")
    labels = _labels("joint_labels", joint_labels, n, "joint {}")
    d = _array("validation.centroid_distance", validation.centroid_distance, 2, (n, 2)) * 1e3  # mm
    if joints is None:
        # Ranking only, on the result's own distances: the best and the worst joint, as in the paper.
        score = np.array([np.nanmean(r) if np.isfinite(r).any() else np.inf for r in d])
        joints = [int(np.argmin(score))] + ([int(np.argmax(np.where(np.isfinite(score), score, -np.inf)))]
                                            if n > 1 else [])
        joints = list(dict.fromkeys(joints))
    sel = _indices("joints", joints, n, "joint")
    if not sel:
        raise IdentifyError("joints: expected at least one joint index")
    kinds = [("reference", ref)] + ([("predicted", pred)] if pred is not None else [])
    panels = [(f, kind, pats) for f in range(2) for kind, pats in kinds]
    rows, cols = ref.shape[2:]
    u_edges, v_edges = _cell_edges(coordinates, (rows, cols))
    aspect = (u_edges[-1] - u_edges[0]) / (v_edges[-1] - v_edges[0])
    panel_w = 3.4
    fig = fig or Figure(figsize=(panel_w * len(panels), len(sel) * (panel_w * aspect + 1.0) + 0.4),
                        layout="constrained")
    axs = fig.subplots(len(sel), len(panels), squeeze=False)
    for r, j in enumerate(sel):
        for c, (f, kind, pats) in enumerate(panels):
            ax = axs[r, c]
            _draw_pattern(ax, pats[j, f], coordinates)
            for cen, color, marker, name in ((c_r, _REF, "o", "reference centroid"),
                                             (c_p, _PRED, "D", "predicted centroid")):
                u_c, v_c = cen[j, f] * 1e3
                if np.isfinite(u_c) and np.isfinite(v_c):  # NaN: a flank without contact has no centroid
                    ax.plot(v_c, u_c, marker=marker, color=color, markeredgecolor="w", markersize=8,
                            linestyle="none", label=name)
            ax.set_title(f"{labels[j]}, flank {_FLANKS[f]}, {kind} (Δ = {d[j, f]:.2f} mm)", fontsize="small")
            if r != len(sel) - 1:
                ax.set_xlabel("")
            if c != 0:
                ax.set_ylabel("")
    handles, names = axs[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, names, loc="outside lower center", ncols=2, fontsize="small")
    fig.suptitle("contact centroids (black = contact)")
    return fig


def plot_d1b_validation(validation: D1BValidation, *, joint_labels: Sequence[str] | None = None,
                        fig: Figure | None = None) -> Figure:
    """Disk–one-blade feature modes per joint: frequencies, errors and MAC (paper Figs. 23, 27).

    Parameters
    ----------
    validation : D1BValidation
        ``feature_modes`` (0-based, n_features), and ``freq_ref_hz``, ``freq_pred_hz``, ``freq_error_pct``,
        ``mac`` of shape (n_joints, n_features). NaN entries (no admissible partner) are left blank.
    joint_labels : sequence of str, optional
        One per joint; default 1..n_joints.
    fig : Figure, optional

    Returns
    -------
    Figure
        A 3 × n_features grid: frequencies (top), relative difference (middle), MAC (bottom), one column per
        feature mode.
    """
    fm = [int(k) for k in np.asarray(validation.feature_modes).reshape(-1)]
    f_r = _array("validation.freq_ref_hz", validation.freq_ref_hz, 2, (None, len(fm)))
    n = f_r.shape[0]
    f_p = _array("validation.freq_pred_hz", validation.freq_pred_hz, 2, (n, len(fm)))
    err = _array("validation.freq_error_pct", validation.freq_error_pct, 2, (n, len(fm)))
    mac = _array("validation.mac", validation.mac, 2, (n, len(fm)))
    if not fm:
        raise IdentifyError("validation.feature_modes is empty: nothing to draw")
    labels = _labels("joint_labels", joint_labels, n, "{}")
    fig = fig or Figure(figsize=(max(4.5, 0.28 * n + 1.5) * len(fm), 7.5), layout="constrained")
    axs = fig.subplots(3, len(fm), squeeze=False, sharex=True)
    for c, k in enumerate(fm):
        a_f, a_e, a_m = axs[:, c]
        x = _joint_axis(a_m, labels)
        a_f.plot(x, f_r[:, c], "o", color=_REF, label="reference")
        a_f.plot(x, f_p[:, c], "x", color=_PRED, markersize=8, label="predicted")
        a_f.set_title(f"mode {k + 1}")
        a_e.bar(x, err[:, c], color=_PRED)
        a_e.axhline(0, color="k", linewidth=0.5)
        a_m.bar(x, mac[:, c], color=_PRED)
        a_m.set_ylim(0, 1.05)
        a_m.set_xlabel("joint")
        for ax in (a_f, a_e, a_m):
            ax.grid(axis="y", linewidth=0.4, alpha=0.5)
    axs[0, 0].set_ylabel("frequency [Hz]")
    axs[1, 0].set_ylabel("Δf [%]")
    axs[2, 0].set_ylabel("MAC")
    axs[0, 0].legend(fontsize="small")
    fig.suptitle("disk–one-blade feature modes, predicted vs reference")
    return fig


def plot_mode_comparison(comparison: ModeComparison, *, title: str | None = None, fig: Figure | None = None
                         ) -> Figure:
    """Full-assembly modes, predicted against reference: frequencies, errors, paired MAC and the MAC matrix.

    Paper Figs. 24, 28 (left column), plus the whole MAC matrix (right) with the pairs marked.

    Parameters
    ----------
    comparison : ModeComparison
        From :func:`identify.validation.compare_modes`: ``pairs`` (n_pairs, 2), ``freq_ref_hz``,
        ``freq_pred_hz``, ``freq_error_pct``, ``mac`` (n_pairs,), ``mac_matrix`` (n_ref, n_pred).
    title : str, optional
        E.g. "Case B: predicted vs measured".
    fig : Figure, optional

    Returns
    -------
    Figure
        Four axes (frequency, Δf, MAC, MAC matrix) and the matrix's colour bar. The left panels' x axis is
        the 1-based reference mode number of each pair.
    """
    pairs = _array("comparison.pairs", comparison.pairs, 2, (None, 2))
    n = pairs.shape[0]
    f_r = _array("comparison.freq_ref_hz", comparison.freq_ref_hz, 1, (n,))
    f_p = _array("comparison.freq_pred_hz", comparison.freq_pred_hz, 1, (n,))
    err = _array("comparison.freq_error_pct", comparison.freq_error_pct, 1, (n,))
    mac = _array("comparison.mac", comparison.mac, 1, (n,))
    M = _array("comparison.mac_matrix", comparison.mac_matrix, 2)
    if n and not (np.all(pairs >= 0) and pairs[:, 0].max() < M.shape[0] and pairs[:, 1].max() < M.shape[1]):
        raise IdentifyError(f"comparison.pairs hold indices outside the {M.shape[0]} × {M.shape[1]} MAC matrix")
    x = pairs[:, 0] + 1
    fig = fig or Figure(figsize=(14, 7.5), layout="constrained")
    ax = fig.subplot_mosaic([["f", "M"], ["e", "M"], ["m", "M"]], width_ratios=[1.6, 1])
    a_f, a_e, a_m, a_M = ax["f"], ax["e"], ax["m"], ax["M"]
    a_e.sharex(a_f)
    a_m.sharex(a_f)
    a_f.plot(x, f_r, "o", color=_REF, markersize=4, label="reference")
    a_f.plot(x, f_p, "x", color=_PRED, markersize=5, label="predicted")
    a_f.set_ylabel("frequency [Hz]")
    a_f.legend(fontsize="small")
    a_e.bar(x, err, color=_PRED)
    a_e.axhline(0, color="k", linewidth=0.5)
    a_e.set_ylabel("Δf [%]")
    a_m.bar(x, mac, color=_PRED)
    a_m.set_ylim(0, 1.05)
    a_m.set_ylabel("MAC (pairs)")
    a_m.set_xlabel("reference mode")
    for a in (a_f, a_e, a_m):
        a.grid(axis="y", linewidth=0.4, alpha=0.5)
        a.xaxis.set_major_locator(MaxNLocator(integer=True))
    n_ref, n_pred = M.shape
    im = a_M.imshow(M, vmin=0, vmax=1, cmap="viridis", origin="upper", interpolation="nearest",
                    extent=(0.5, n_pred + 0.5, n_ref + 0.5, 0.5))
    if n:
        a_M.plot(pairs[:, 1] + 1, pairs[:, 0] + 1, "s", markerfacecolor="none", markeredgecolor=_REF,
                 markeredgewidth=1.0, markersize=max(3.0, min(8.0, 300.0 / max(n_ref, n_pred))), linestyle="none",
                 label="pair")
    fig.colorbar(im, ax=a_M, label="MAC", shrink=0.8)
    a_M.set_xlabel("predicted mode")
    a_M.set_ylabel("reference mode")
    a_M.xaxis.set_major_locator(MaxNLocator(integer=True))
    a_M.yaxis.set_major_locator(MaxNLocator(integer=True))
    mean_err, mean_mac = comparison.mean_abs_freq_error_pct, comparison.mean_mac  # Table 8's figures
    a_M.set_title(f"MAC matrix ({n} pairs)")
    head = f"{title}: " if title else ""
    fig.suptitle(f"{head}mean |Δf| = {mean_err:.2f} %, mean MAC = {mean_mac:.2f}")
    return fig
