"""Validation figures: step-1 grid error (Fig. 19), geometric (Figs. 21–22, 25–26) and dynamic (23–24, 27–28)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..errors import IdentifyError
from ..validation import D1BValidation, GeometricValidation, GridError, ModeComparison
from .draw import (
    FLANKS,
    PRED_COLOR,
    REF_COLOR,
    cell_edges,
    checked_array,
    checked_indices,
    draw_pattern,
    figure_axes,
    joint_axis,
    joint_patterns,
    tick_labels,
)

__all__ = [
    "plot_grid_error",
    "plot_area_fractions",
    "plot_centroids",
    "plot_d1b_validation",
    "plot_mode_comparison",
]


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
    eps = checked_array("error.epsilon_pct", getattr(error, "epsilon_pct", error), 2)
    n_blades, n_modes = eps.shape
    ml = tick_labels("mode_labels", mode_labels, n_modes, "mode {}")
    bl = tick_labels("blade_labels", blade_labels, n_blades, "{}")
    fig, ax = figure_axes(ax, (max(6.0, 0.45 * n_blades * max(1, n_modes) / 2 + 2), 4))
    ax.axhspan(-50, 50, color="tab:green", alpha=0.12, lw=0)
    for y in (-50, 50):
        ax.axhline(y, color="tab:green", linestyle="--", linewidth=0.8)
    ax.axhline(0, color="k", linewidth=0.5)
    x = joint_axis(ax, bl)
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
    a_p = checked_array("validation.area_pct_pred", validation.area_pct_pred, 2, (None, 2))
    n = a_p.shape[0]
    a_r = checked_array("validation.area_pct_ref", validation.area_pct_ref, 2, (n, 2))
    c_p = checked_array("validation.centroid_pred", validation.centroid_pred, 3, (n, 2, 2))
    c_r = checked_array("validation.centroid_ref", validation.centroid_ref, 3, (n, 2, 2))
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
    labels = tick_labels("joint_labels", joint_labels, a_p.shape[0], "{}")
    fig = fig or Figure(figsize=(max(6.0, 0.45 * len(labels) + 2), 6), layout="constrained")
    axs = fig.subplots(2, 1, sharex=True)
    for f, ax in enumerate(axs):
        x = joint_axis(ax, labels)
        ax.bar(x - 0.2, a_r[:, f], width=0.4, color=REF_COLOR, label="reference")
        ax.bar(x + 0.2, a_p[:, f], width=0.4, color=PRED_COLOR, label="predicted")
        ax.set_ylim(0, 100)
        ax.set_ylabel(f"A_c, flank {FLANKS[f]} [%]")
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
    ref = joint_patterns("reference", reference, n)
    pred = joint_patterns("predicted", predicted, n) if predicted is not None else None
    if pred is not None and pred.shape != ref.shape:
        raise IdentifyError(f"predicted {pred.shape} and reference {ref.shape} patterns: expected the same shape")
    labels = tick_labels("joint_labels", joint_labels, n, "joint {}")
    d = checked_array("validation.centroid_distance", validation.centroid_distance, 2, (n, 2)) * 1e3  # mm
    if joints is None:
        # Ranking only, on the result's own distances: the best and the worst joint, as in the paper.
        score = np.array([np.nanmean(r) if np.isfinite(r).any() else np.inf for r in d])
        joints = [int(np.argmin(score))] + ([int(np.argmax(np.where(np.isfinite(score), score, -np.inf)))]
                                            if n > 1 else [])
        joints = list(dict.fromkeys(joints))
    sel = checked_indices("joints", joints, n, "joint")
    if not sel:
        raise IdentifyError("joints: expected at least one joint index")
    kinds = [("reference", ref)] + ([("predicted", pred)] if pred is not None else [])
    panels = [(f, kind, pats) for f in range(2) for kind, pats in kinds]
    rows, cols = ref.shape[2:]
    u_edges, v_edges = cell_edges(coordinates, (rows, cols))
    aspect = (u_edges[-1] - u_edges[0]) / (v_edges[-1] - v_edges[0])
    panel_w = 3.4
    fig = fig or Figure(figsize=(panel_w * len(panels), len(sel) * (panel_w * aspect + 1.0) + 0.4),
                        layout="constrained")
    axs = fig.subplots(len(sel), len(panels), squeeze=False)
    for r, j in enumerate(sel):
        for c, (f, kind, pats) in enumerate(panels):
            ax = axs[r, c]
            draw_pattern(ax, pats[j, f], coordinates)
            for cen, color, marker, name in ((c_r, REF_COLOR, "o", "reference centroid"),
                                             (c_p, PRED_COLOR, "D", "predicted centroid")):
                u_c, v_c = cen[j, f] * 1e3
                if np.isfinite(u_c) and np.isfinite(v_c):  # NaN: a flank without contact has no centroid
                    ax.plot(v_c, u_c, marker=marker, color=color, markeredgecolor="w", markersize=8,
                            linestyle="none", label=name)
            ax.set_title(f"{labels[j]}, flank {FLANKS[f]}, {kind} (Δ = {d[j, f]:.2f} mm)", fontsize="small")
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
    f_r = checked_array("validation.freq_ref_hz", validation.freq_ref_hz, 2, (None, len(fm)))
    n = f_r.shape[0]
    f_p = checked_array("validation.freq_pred_hz", validation.freq_pred_hz, 2, (n, len(fm)))
    err = checked_array("validation.freq_error_pct", validation.freq_error_pct, 2, (n, len(fm)))
    mac = checked_array("validation.mac", validation.mac, 2, (n, len(fm)))
    if not fm:
        raise IdentifyError("validation.feature_modes is empty: nothing to draw")
    labels = tick_labels("joint_labels", joint_labels, n, "{}")
    fig = fig or Figure(figsize=(max(4.5, 0.28 * n + 1.5) * len(fm), 7.5), layout="constrained")
    axs = fig.subplots(3, len(fm), squeeze=False, sharex=True)
    for c, k in enumerate(fm):
        a_f, a_e, a_m = axs[:, c]
        x = joint_axis(a_m, labels)
        a_f.plot(x, f_r[:, c], "o", color=REF_COLOR, label="reference")
        a_f.plot(x, f_p[:, c], "x", color=PRED_COLOR, markersize=8, label="predicted")
        a_f.set_title(f"mode {k + 1}")
        a_e.bar(x, err[:, c], color=PRED_COLOR)
        a_e.axhline(0, color="k", linewidth=0.5)
        a_m.bar(x, mac[:, c], color=PRED_COLOR)
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
    pairs = checked_array("comparison.pairs", comparison.pairs, 2, (None, 2))
    n = pairs.shape[0]
    f_r = checked_array("comparison.freq_ref_hz", comparison.freq_ref_hz, 1, (n,))
    f_p = checked_array("comparison.freq_pred_hz", comparison.freq_pred_hz, 1, (n,))
    err = checked_array("comparison.freq_error_pct", comparison.freq_error_pct, 1, (n,))
    mac = checked_array("comparison.mac", comparison.mac, 1, (n,))
    M = checked_array("comparison.mac_matrix", comparison.mac_matrix, 2)
    if n and not (np.all(pairs >= 0) and pairs[:, 0].max() < M.shape[0] and pairs[:, 1].max() < M.shape[1]):
        raise IdentifyError(f"comparison.pairs hold indices outside the {M.shape[0]} × {M.shape[1]} MAC matrix")
    x = pairs[:, 0] + 1
    fig = fig or Figure(figsize=(14, 7.5), layout="constrained")
    ax = fig.subplot_mosaic([["f", "M"], ["e", "M"], ["m", "M"]], width_ratios=[1.6, 1])
    a_f, a_e, a_m, a_M = ax["f"], ax["e"], ax["m"], ax["M"]
    a_e.sharex(a_f)
    a_m.sharex(a_f)
    a_f.plot(x, f_r, "o", color=REF_COLOR, markersize=4, label="reference")
    a_f.plot(x, f_p, "x", color=PRED_COLOR, markersize=5, label="predicted")
    a_f.set_ylabel("frequency [Hz]")
    a_f.legend(fontsize="small")
    a_e.bar(x, err, color=PRED_COLOR)
    a_e.axhline(0, color="k", linewidth=0.5)
    a_e.set_ylabel("Δf [%]")
    a_m.bar(x, mac, color=PRED_COLOR)
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
        a_M.plot(pairs[:, 1] + 1, pairs[:, 0] + 1, "s", markerfacecolor="none", markeredgecolor=REF_COLOR,
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
