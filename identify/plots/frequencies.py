"""Frequency figures of the pattern pairs: each mode's sensitivity (Fig. 15) and its maps (Fig. 16)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ..errors import IdentifyError
from .draw import checked_array, checked_indices, figure_axes, tick_labels

__all__ = ["plot_sensitivity", "plot_frequency_maps"]

_FEATURE, _OTHER = "tab:orange", "0.65"
#: Fields of a sensitivity result per unit, first found wins (identify.sensitivity.Sensitivity: std_rel_pct, std_hz).
_STD_FIELDS = {"pct": ("std_rel_pct", "std_pct"), "hz": ("std_hz",)}


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
        std, other = checked_array("sensitivity", sensitivity, 1), None
    else:
        name, o_name = field(unit), field(other_unit)
        if name is None:
            raise IdentifyError(f"sensitivity: {type(sensitivity).__name__} has no {' or '.join(_STD_FIELDS[unit])}"
                                f"; pass unit={other_unit!r} or the standard deviations as an array")
        std = checked_array(f"sensitivity.{name}", getattr(sensitivity, name), 1)
        other = checked_array(f"sensitivity.{o_name}", getattr(sensitivity, o_name), 1, (std.size,)) if o_name else None
        if feature_modes is None:
            feature_modes = getattr(sensitivity, "feature_modes", None)
    n = std.size
    feat = checked_indices("feature_modes", feature_modes, n)
    fig, ax = figure_axes(ax, (max(5.0, 0.55 * n + 2), 4))
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
    F = checked_array("frequencies_hz", getattr(frequencies_hz, "frequencies_hz", frequencies_hz), 3)
    n_L, n_R, n_modes = F.shape
    chosen = checked_indices("modes", modes, n_modes) if modes is not None else list(range(n_modes))
    if not chosen:
        raise IdentifyError("modes: expected at least one mode index")
    tl = tick_labels("labels_L", labels_L, n_L, "{}")
    tr = tick_labels("labels_R", labels_R, n_R, "{}")
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
