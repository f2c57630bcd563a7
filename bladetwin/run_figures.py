"""Figures of the run report that no library module draws (plotting only: every input is computed)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

__all__ = ["plot_blade_deltas", "plot_joint_patterns", "plot_contact_probability", "plot_d1b_features", "plot_bias",
           "plot_rom_update", "plot_posterior_frequencies"]


def plot_blade_deltas(deltas_pct: np.ndarray) -> Figure:
    """Blade mistuning deltas (Eq. 37, paper Table 2) as a heat map.

    Parameters
    ----------
    deltas_pct : ndarray, shape (n_blades, n_modes)
        δ of each blade and mode, %.
    """
    d = np.asarray(deltas_pct, float)
    fig = Figure(figsize=(min(2 + 0.7 * d.shape[1], 12), 1.2 + 0.28 * d.shape[0]), layout="constrained")
    ax = fig.add_subplot()
    lim = float(np.nanmax(np.abs(d))) or 1.0
    im = ax.imshow(d, cmap="RdBu_r", norm=TwoSlopeNorm(0.0, -lim, lim), aspect="auto")
    ax.set_xticks(range(d.shape[1]), [f"mode {m + 1}" for m in range(d.shape[1])], rotation=45, ha="right")
    ax.set_yticks(range(d.shape[0]), [f"blade {b + 1}" for b in range(d.shape[0])])
    if d.size <= 400:
        for (i, j), v in np.ndenumerate(d):
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=7)
    fig.colorbar(im, ax=ax, label="δ (%)")
    ax.set_title("Blade mistuning δ (Eq. 37)")
    return fig


def plot_joint_patterns(patterns: Sequence, labels: Sequence[str], reference: Sequence | None = None) -> Figure:
    """Each joint's pattern, flanks L and R side by side, with its reference pattern beside where known.

    Parameters
    ----------
    patterns : sequence of rom.ContactPattern, length n_joints
    labels : sequence of str, length n_joints
        Row titles (e.g. "joint 4: SP-3 / SP-7").
    reference : sequence of ContactPattern, optional
    """
    n = len(patterns)
    cols = 2 if reference is None else 4
    shape = np.asarray(patterns[0].L).shape
    w = 1.2 + cols * max(1.6, 0.09 * shape[1])
    fig = Figure(figsize=(min(w, 14), 0.4 + 0.75 * n), layout="constrained")
    axes = fig.subplots(n, cols, squeeze=False)
    heads = ["identified L", "identified R"] + ([] if reference is None else ["reference L", "reference R"])
    for r in range(n):
        grids = [patterns[r].L, patterns[r].R] + ([] if reference is None else [reference[r].L, reference[r].R])
        for c, g in enumerate(grids):
            ax = axes[r, c]
            ax.imshow(np.asarray(g, float), cmap="Greys", vmin=0, vmax=1, aspect="auto", interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(heads[c], fontsize=9)
        axes[r, 0].set_ylabel(labels[r], rotation=0, ha="right", va="center", fontsize=8)
    return fig


def plot_contact_probability(probability: Sequence, labels: Sequence[str], columns: dict[str, Sequence]) -> Figure:
    """Each unfilmed joint's posterior contact probability per flank, beside other answers (k-NN, reference).

    Parameters
    ----------
    probability : sequence of ndarray, shape (2, rows, cols) each
        P(contact) per node, flanks L and R (:attr:`identify.JointPosterior.probability`).
    labels : sequence of str
        Row titles, e.g. "joint 4 · L 45–71 %".
    columns : dict name → sequence of rom.ContactPattern
        Patterns drawn beside (both flanks each), e.g. ``{"k-NN": ..., "reference": ...}``.
    """
    n = len(probability)
    cols = 2 + 2 * len(columns)
    shape = np.asarray(probability[0][0]).shape
    fig = Figure(figsize=(min(1.6 + cols * max(1.4, 0.08 * shape[1]), 15), 0.6 + 0.7 * n), layout="constrained")
    axes = fig.subplots(n, cols, squeeze=False)
    heads = ["P(contact) L", "P(contact) R"] + [f"{name} {f}" for name in columns for f in "LR"]
    im = None
    for r in range(n):
        grids = [probability[r][0], probability[r][1]]
        for pats in columns.values():
            grids += [pats[r].L, pats[r].R]
        for c, g in enumerate(grids):
            ax = axes[r, c]
            img = ax.imshow(np.asarray(g, float), cmap="Greys" if c > 1 else "viridis", vmin=0, vmax=1,
                            aspect="auto", interpolation="nearest")
            im = img if c < 2 else im
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(heads[c], fontsize=9)
        axes[r, 0].set_ylabel(labels[r], rotation=0, ha="right", va="center", fontsize=8)
    if im is not None:
        fig.colorbar(im, ax=axes[:, :2], shrink=0.6, label="posterior probability of contact")
    return fig


def plot_d1b_features(joints: Sequence[int], measured_hz: np.ndarray, predicted_hz: np.ndarray,
                      feature_modes: Sequence[int], *, reference_hz: np.ndarray | None = None,
                      title: str = "") -> Figure:
    """Disk–one-blade feature frequencies per joint: relative error of the prediction (paper Figs. 23, 27).

    Parameters
    ----------
    joints : sequence of int, length n_joints
    measured_hz, predicted_hz : ndarray, shape (n_joints, n_features)
        The comparison's reference (measured, or the ROM with the reference pattern) and the prediction.
    feature_modes : sequence of int
        1-based mode numbers, for the legend.
    reference_hz : ndarray, optional
        A second prediction drawn as hollow markers (e.g. the ROM with the reference pattern).
    """
    fig = Figure(figsize=(8, 3.2), layout="constrained")
    ax = fig.add_subplot()
    x = np.asarray(joints)
    for k, m in enumerate(feature_modes):
        err = 100 * (predicted_hz[:, k] / measured_hz[:, k] - 1)
        (line,) = ax.plot(x, err, "o-", ms=4, label=f"mode {m}: identified")
        if reference_hz is not None:
            ax.plot(x, 100 * (reference_hz[:, k] / measured_hz[:, k] - 1), "s", mfc="none",
                    color=line.get_color(), label=f"mode {m}: reference pattern")
    ax.axhline(0, color="0.5", lw=0.8)
    ax.set_xlabel("joint")
    ax.set_ylabel("Δf (%)")
    ax.set_xticks(x)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(title)
    return fig


def plot_bias(bias_pct: np.ndarray, spread_pct: np.ndarray, feature_modes: Sequence[int]) -> Figure:
    """The ROM's per-mode frequency bias on the filmed joints (median, with the spread between joints).

    Parameters
    ----------
    bias_pct, spread_pct : ndarray, shape (n_modes,)
    feature_modes : sequence of int
        0-based feature modes (highlighted).
    """
    fig = Figure(figsize=(7, 2.8), layout="constrained")
    ax = fig.add_subplot()
    m = np.arange(1, len(bias_pct) + 1)
    colors = ["C3" if k in set(feature_modes) else "C0" for k in range(len(bias_pct))]
    ax.bar(m, bias_pct, yerr=spread_pct, color=colors, capsize=3)
    ax.axhline(0, color="0.5", lw=0.8)
    ax.set_xticks(m)
    ax.set_xlabel("tracked disk–one-blade mode (red: feature modes)")
    ax.set_ylabel("f_measured / f_ROM − 1 (%)")
    ax.set_title("ROM bias on the filmed joints (median ± spread)")
    return fig


def plot_rom_update(corrections_pct: np.ndarray, mode_labels: Sequence[str], families: dict) -> Figure:
    """The updated ROM: each blade's in-situ corrections, and each family's subspace correlation, both ROMs.

    Parameters
    ----------
    corrections_pct : ndarray, shape (n_blades, n_modes)
        In-situ frequency correction of each blade's calibrated free modes (%).
    mode_labels : sequence of str, length n_modes
    families : dict name → list of :class:`identify.families.FamilyRow`
        ``paper_B``, ``updated_B`` (and ``_C``): the family-wise view of Case B (and C).
    """
    c = np.asarray(corrections_pct, float)
    fig = Figure(figsize=(12, 4.2), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    n_b, n_m = c.shape
    width = 0.8 / max(n_m, 1)
    for i in range(n_m):
        ax1.bar(np.arange(1, n_b + 1) + (i - (n_m - 1) / 2) * width, c[:, i], width, label=mode_labels[i])
    ax1.axhline(0, color="k", lw=0.6)
    ax1.set_xlabel("blade")
    ax1.set_ylabel("in-situ correction (% of frequency)")
    ax1.set_title("In-situ corrections beyond Eq. 19 (from the disk–one-blade tests)")
    if n_m:
        ax1.legend(fontsize=7, ncol=2)
    # Families are categories, not a curve: one group of bars per measured family (Case B), Case C as markers.
    ref = families.get("paper_B") or families.get("updated_B") or []
    x = np.arange(len(ref))
    for k, kind in enumerate(("paper", "updated")):
        for case, draw in (("B", "bar"), ("C", "marker")):
            rows = families.get(f"{kind}_{case}")
            if not rows or len(rows) != len(ref):
                continue
            y = [r.subspace_mean_cos2 for r in rows]
            label = f"{kind} ROM, Case {case}"
            if draw == "bar":
                ax2.bar(x + (k - 0.5) * 0.4, y, 0.4, color=f"C{k}", label=label)
            else:
                ax2.plot(x + (k - 0.5) * 0.4, y, "k" + ("o" if k == 0 else "s"), mfc="none", ms=5, label=label)
    ax2.set_xticks(x, [f"{0.5 * (r.f_low_hz + r.f_high_hz):.0f} Hz\n({r.n_measured})" for r in ref], fontsize=7)
    ax1.xaxis.get_major_locator().set_params(integer=True)
    # Headroom above 1 holds the legend, which would otherwise cover bars near 1 (most families).
    ax2.set_ylim(0, 1.25)
    ax2.set_yticks(np.linspace(0.0, 1.0, 6))
    ax2.set_xlabel("measured mode family: centre (number of measured modes)")
    ax2.set_ylabel("subspace correlation (mean cos²)")
    ax2.set_title("Full assembly, family by family: ROM vs measured")
    ax2.legend(fontsize=7, ncol=2, loc="upper center")
    return fig


def plot_posterior_frequencies(rows: np.ndarray) -> Figure:
    """Each unfilmed joint's tracked disk–one-blade frequencies against its test: the posterior's answer and its
    90 % interval, one panel per tracked mode (the figure of :data:`bladetwin.methods.FREQUENCY_HEADER`'s table).

    Parameters
    ----------
    rows : ndarray, shape (n_rows, 7)
        Joint, tracked mode (1-based), the test's frequency (bias removed; NaN where the test did not find the
        mode), the answer's, the interval's 5 % and 95 % bounds (Hz), and the answer's offset from the test (%).
    """
    r = np.asarray(rows, float)
    modes = np.unique(r[:, 1]).astype(int) if r.size else np.array([], int)
    ncol = min(5, max(len(modes), 1))
    nrow = max(1, -(-len(modes) // ncol))
    fig = Figure(figsize=(2.5 * ncol + 0.6, 2.1 * nrow + 0.5), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrow, ncol, sharex=True, squeeze=False)).ravel()
    joints = np.unique(r[:, 0]).astype(int) if r.size else np.array([], int)
    x_of = {j: k for k, j in enumerate(joints)}
    for ax, m in zip(axes, modes, strict=False):
        sel = r[(r[:, 1] == m) & np.isfinite(r[:, 2])]
        x = np.array([x_of[int(j)] for j in sel[:, 0]])
        y = 100 * (sel[:, 3] / sel[:, 2] - 1)
        lo, hi = 100 * (sel[:, 4] / sel[:, 2] - 1), 100 * (sel[:, 5] / sel[:, 2] - 1)
        ax.axhline(0, color="0.3", lw=0.8)
        # the interval as a bar and the answer as a dot, drawn apart: the answer (the posterior's pattern) may lie
        # outside the interval of the frequencies over its samples, which an error bar around it cannot show
        ax.vlines(x, lo, hi, color="C0", lw=1.2)
        ax.plot(x, y, "o", ms=3, color="C0")
        ax.set_title(f"mode {m}", fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in axes[len(modes):]:
        ax.set_visible(False)
    for ax in axes[-ncol:]:
        ax.set_xticks(range(len(joints)), [str(j) for j in joints], fontsize=6)
        ax.set_xlabel("joint", fontsize=8)
    for ax in axes[::ncol]:
        ax.set_ylabel("vs the test (%)", fontsize=8)
    fig.suptitle("Disk–one-blade frequencies: the posterior's answer (dot) and its 90 % interval (bar) against "
                 "the test (0)", fontsize=10)
    return fig
