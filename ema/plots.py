"""EMA plots. They only read results (FRF sets, diagrams, models); no fitting happens here."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .frf import FRFSet
from .lsfd import synthesize
from .modal import ModalModel
from .stabilization import CLASS_NAMES, StabilizationDiagram

__all__ = ["plot_stabilization", "plot_mac", "plot_frf_fit", "plot_families"]

_STYLE = {0: ("o", "0.7", 3), 1: ("x", "tab:orange", 4), 2: ("d", "tab:blue", 4), 3: ("+", "tab:green", 7)}


def _axes(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=figsize)
    return fig, fig.add_subplot(1, 1, 1)


def plot_stabilization(
    diagram: StabilizationDiagram,
    frf: FRFSet | None = None,
    indicator: str = "mean",
    selected_hz: np.ndarray | None = None,
    ax: Axes | None = None,
) -> Figure:
    """Stabilization diagram: poles per order with stability symbols over the mean |FRF| or the CMIF.

    Parameters
    ----------
    diagram : StabilizationDiagram
    frf : FRFSet, optional
        Drawn (log scale, right axis) over the band when given.
    indicator : {"mean", "cmif"}
    selected_hz : array_like, optional
        Frequencies of selected modes, drawn as vertical lines.
    ax : Axes, optional

    Returns
    -------
    Figure
    """
    fig, ax = _axes(ax, (10, 5))
    for cls, (marker, color, size) in _STYLE.items():
        sel = diagram.stability == cls
        ax.plot(diagram.frequencies_hz[sel], diagram.order[sel], linestyle="none", marker=marker, color=color,
                markersize=size, label=CLASS_NAMES[cls])
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("model order")
    ax.set_xlim(*diagram.band_hz)
    if frf is not None:
        ax2 = ax.twinx()
        mask = (frf.freq_hz >= diagram.band_hz[0]) & (frf.freq_hz <= diagram.band_hz[1])
        if indicator == "cmif":
            y = frf.cmif()[:, mask].T
            label = "CMIF"
        elif indicator == "mean":
            y = frf.mean_abs()[mask]
            label = "mean |FRF|"
        else:
            raise ValueError(f"indicator {indicator!r} not one of 'mean', 'cmif'")
        ax2.semilogy(frf.freq_hz[mask], y, color="k", linewidth=0.8)
        ax2.set_ylabel(label)
    if selected_hz is not None:
        for f in np.atleast_1d(selected_hz):
            ax.axvline(float(f), color="tab:red", linewidth=0.6, alpha=0.6)
    ax.legend(loc="upper left", fontsize="small")
    ax.set_title(f"stabilization ({diagram.method})")
    return fig


def plot_mac(mac_matrix: np.ndarray, labels_a: list[str] | None = None, labels_b: list[str] | None = None,
             ax: Axes | None = None) -> Figure:
    """MAC matrix as an image with values, shape (n_a, n_b)."""
    M = np.asarray(mac_matrix, dtype=float)
    fig, ax = _axes(ax, (6, 5))
    im = ax.imshow(M, vmin=0, vmax=1, cmap="viridis", origin="upper")
    fig.colorbar(im, ax=ax, label="MAC")
    if M.size <= 400:
        for (i, j), v in np.ndenumerate(M):
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=6, color="w" if v < 0.6 else "k")
    ax.set_xticks(range(M.shape[1]), labels_b or [str(k + 1) for k in range(M.shape[1])])
    ax.set_yticks(range(M.shape[0]), labels_a or [str(k + 1) for k in range(M.shape[0])])
    ax.set_xlabel("model B mode")
    ax.set_ylabel("model A mode")
    return fig


def plot_frf_fit(frf: FRFSet, model: ModalModel, output: int = 0, input: int = 0, ax: Axes | None = None) -> Figure:
    """Measured against synthesised FRF (magnitude) for one output / input pair over the model's band."""
    fig, ax = _axes(ax, (9, 4))
    data = frf.with_form(model.form) if frf.form != model.form else frf
    band = model.band_hz or (float(data.freq_hz[0]), float(data.freq_hz[-1]))
    mask = (data.freq_hz >= band[0]) & (data.freq_hz <= band[1])
    f = data.freq_hz[mask]
    syn = synthesize(model, f).H[output, input]
    ax.semilogy(f, np.abs(data.H[output, input, mask]), color="k", linewidth=0.8, label="measured")
    ax.semilogy(f, np.abs(syn), color="tab:red", linewidth=0.8, linestyle="--", label="synthesised")
    for fr in model.frequencies_hz:
        ax.axvline(fr, color="0.8", linewidth=0.5)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"|H| ({model.form})")
    ax.set_title(f"output {frf.outputs[output]} / input {frf.inputs[input]}")
    ax.legend(fontsize="small")
    return fig


def plot_families(frf: FRFSet, model: ModalModel, windows: list[tuple[float, float]]) -> Figure:
    """One panel per dense window: the measurement and the model's synthesis, with a line at each mode (the zoom a
    whole-band stabilization diagram cannot show).

    Each FRF is divided by its own median magnitude in the window before the RMS over all FRFs is taken. Why: a
    plain RMS is the strongest FRFs' curve, and modes that only a few response points see (disk modes at blade
    tips, found by :func:`ema.unexplained.fill_unexplained`) vanish under the tails of strong ones; relative to
    each FRF's own level, they stand out as they do in the FRFs that see them. The model is divided by the same medians.

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        With residues (e.g. from ``ema.fit(families=True)``).
    windows : list of (f_lo, f_hi)
        Hz, e.g. the windows of :func:`ema.family.family_windows` holding several modes.
    """
    n = max(len(windows), 1)
    fig = Figure(figsize=(4.5 * n, 3.6))
    data = frf.with_form(model.form) if frf.form != model.form else frf
    for k, (lo, hi) in enumerate(windows):
        ax = fig.add_subplot(1, n, k + 1)
        mask = (data.freq_hz >= lo) & (data.freq_hz <= hi)
        f = data.freq_hz[mask]
        H = data.H[:, :, mask]
        level = np.maximum(np.median(np.abs(H), axis=2, keepdims=True), np.finfo(float).tiny)
        rms = np.sqrt(np.mean(np.abs(H / level) ** 2, axis=(0, 1)))
        syn = np.sqrt(np.mean(np.abs(synthesize(model, f).H / level) ** 2, axis=(0, 1)))
        ax.semilogy(f, rms, color="k", linewidth=0.9, label="measured")
        ax.semilogy(f, syn, color="tab:red", linewidth=0.9, linestyle="--", label="model")
        inside = model.frequencies_hz[(model.frequencies_hz >= lo) & (model.frequencies_hz <= hi)]
        for fr in inside:
            ax.axvline(fr, color="tab:blue", linewidth=0.4, alpha=0.7)
        ax.set_title(f"{lo:.5g}–{hi:.5g} Hz: {inside.size} modes", fontsize="small")
        ax.set_xlabel("frequency [Hz]")
        if k == 0:
            ax.set_ylabel("RMS over FRFs of |H| / its median here")
            ax.legend(fontsize="small")
    fig.tight_layout()
    return fig
