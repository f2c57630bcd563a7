"""Identification plots (paper Figs. 14–16, 19, 21–28). They only read results; nothing is identified here.

Each ``plot_*`` function draws one result object of :mod:`identify` (or plain arrays) and returns the
:class:`~matplotlib.figure.Figure`. Single-panel functions take an optional ``ax``, multi-panel ones an
optional ``fig`` to fill. None of them calls ``pyplot``, so they run under any backend (Agg included).
Inputs of the wrong shape raise :class:`~identify.errors.IdentifyError` with a one-line message.

Contact-pattern orientation
---------------------------
Every contact pattern is drawn by one helper (:func:`identify.plots.draw.draw_pattern`), laid out like a film
scan (``lab.films``, docs/campaign.md "Film images"):

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

Modules: :mod:`~identify.plots.patterns` (single patterns, Fig. 14), :mod:`~identify.plots.frequencies`
(Figs. 15–16), :mod:`~identify.plots.validation` (Figs. 19, 21–28), and :mod:`~identify.plots.draw`, the
shared drawing helpers and input checks.
"""

from .frequencies import plot_frequency_maps, plot_sensitivity
from .patterns import plot_pattern, plot_synthetic_patterns
from .validation import (
    plot_area_fractions,
    plot_centroids,
    plot_d1b_validation,
    plot_grid_error,
    plot_mode_comparison,
)

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
