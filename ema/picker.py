"""Interactive pole picking on a stabilization diagram (Jupyter with ``%matplotlib widget``, or any
interactive matplotlib backend).

Left-click near a pole to pick it: the click snaps to the nearest pole within ``snap_px`` pixels,
preferring the most stable class there. Left-click a picked pole again, or right-click near it, to drop it.
The picker never changes the diagram. It only holds a list of ``(order, frequency_hz)`` picks, which
:meth:`PolePicker.selection` turns into a :class:`~ema.selection.PoleSelection` through
:func:`ema.selection.select_picks`, the same path as ``fit(picks=...)``.

Install the optional extra for notebooks: ``pip install bladetwin[notebook]`` (ipympl).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from .frf import FRFSet
from .plots import plot_stabilization
from .selection import PoleSelection, select_picks
from .stabilization import StabilizationDiagram

__all__ = ["PolePicker"]


class PolePicker:
    """Pick physical poles by clicking on a stabilization diagram.

    Parameters
    ----------
    diagram : StabilizationDiagram
    frf : FRFSet, optional
        Drawn under the poles (mean |FRF|) as a guide.
    initial : sequence of (order, frequency_hz), optional
        Start from these picks (e.g. an automatic selection to correct by hand).
    fig : Figure, optional
        Figure to draw into; by default ``matplotlib.pyplot.figure`` when pyplot is interactive, else a
        plain :class:`~matplotlib.figure.Figure`.
    snap_px : float
        Largest distance in pixels between a click and the pole it picks.
    """

    def __init__(
        self,
        diagram: StabilizationDiagram,
        frf: FRFSet | None = None,
        initial: Sequence[tuple[int, float]] = (),
        fig: Figure | None = None,
        snap_px: float = 12.0,
    ) -> None:
        if diagram.order.size == 0:
            raise ValueError("the stabilization diagram holds no pole to pick")
        if not snap_px > 0:
            raise ValueError(f"snap_px must be > 0, got {snap_px}")
        self._diagram = diagram
        self._snap_px = float(snap_px)
        self._picked: list[int] = []
        for order, f in initial:
            self._toggle(self._nearest_of_order(int(order), float(f)))
        if fig is None:
            import matplotlib.pyplot as plt

            fig = plt.figure(figsize=(10, 5)) if plt.isinteractive() else Figure(figsize=(10, 5))
        self.fig = fig
        self.ax = fig.add_subplot(1, 1, 1) if not fig.axes else fig.axes[0]
        plot_stabilization(diagram, frf, ax=self.ax)
        (self._marks,) = self.ax.plot([], [], "o", mfc="none", mec="red", ms=11, mew=1.8, label="picked")
        self._cid = fig.canvas.mpl_connect("button_press_event", self.on_click)
        self._redraw()

    # -------------------------------------------------------------------- state
    @property
    def picks(self) -> tuple[tuple[int, float], ...]:
        """Picked poles as ``(order, frequency_hz)``, sorted by frequency."""
        d = self._diagram
        idx = sorted(self._picked, key=lambda k: d.frequencies_hz[k])
        return tuple((int(d.order[k]), float(d.frequencies_hz[k])) for k in idx)

    def selection(self) -> PoleSelection:
        """The picks as a :class:`PoleSelection` (via :func:`select_picks`)."""
        return select_picks(self._diagram, self.picks)

    def disconnect(self) -> None:
        """Stop listening to clicks (the figure stays)."""
        self.fig.canvas.mpl_disconnect(self._cid)

    # -------------------------------------------------------------------- events
    def on_click(self, event) -> None:
        """Matplotlib ``button_press_event`` handler: left click toggles, right click drops."""
        # The |FRF| guide is a twin axes on top of the diagram: accept clicks on either (snapping is in pixels).
        ax = event.inaxes
        if ax is None or event.x is None or not (ax is self.ax or self.ax.get_shared_x_axes().joined(self.ax, ax)):
            return
        k = self._nearest_pole(event.x, event.y)
        if k is None:
            return
        if event.button == 3:
            if k in self._picked:
                self._picked.remove(k)
        elif event.button == 1:
            self._toggle(k)
        self._redraw()

    # -------------------------------------------------------------------- helpers
    def _toggle(self, k: int) -> None:
        if k in self._picked:
            self._picked.remove(k)
        else:
            self._picked.append(k)

    def _nearest_of_order(self, order: int, f: float) -> int:
        cand = np.flatnonzero(self._diagram.order == order)
        if cand.size == 0:
            raise ValueError(f"initial pick ({order}, {f} Hz): order {order} has no pole in the diagram")
        return int(cand[np.argmin(np.abs(self._diagram.frequencies_hz[cand] - f))])

    def _nearest_pole(self, x_px: float, y_px: float) -> int | None:
        d = self._diagram
        xy = self.ax.transData.transform(np.column_stack([d.frequencies_hz, d.order]))
        dist = np.hypot(xy[:, 0] - x_px, xy[:, 1] - y_px)
        near = np.flatnonzero(dist <= self._snap_px)
        if near.size == 0:
            return None
        # Most stable class first, then the closest.
        best = near[np.lexsort((dist[near], -d.stability[near]))]
        return int(best[0])

    def _redraw(self) -> None:
        d = self._diagram
        idx = np.asarray(self._picked, dtype=int)
        self._marks.set_data(d.frequencies_hz[idx], d.order[idx])
        freqs = ", ".join(f"{f:.4g}" for _, f in self.picks) or "none"
        self.ax.set_title(f"{len(idx)} picked (Hz): {freqs}\nleft click: pick / unpick, right click: drop", fontsize=9)
        self.fig.canvas.draw_idle()
