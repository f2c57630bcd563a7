"""The order from the data inside :func:`ema.fit` (``grow=True``; issue 44): double the order while the diagram asks.

After the estimate at ``max_order`` the order doubles, at most :data:`MAX_DOUBLINGS` times, while both hold:

- **no headroom**: the automatic selection in the band fills more than 1/:data:`HEADROOM` of the modes the highest
  order holds (LSCF: p·n_inputs/2 at order p; complex LSRF: n at order n);
- **not saturated**: the diagram's upper orders still add modes, i.e. the selection from the orders up to
  :data:`SATURATION` of the highest holds fewer modes in the band than the selection from all of them. A diagram
  whose last quarter of orders adds no mode has found what its estimator finds at this order; a higher order
  then only adds noise poles (on ``benchmarks/ema.py`` the complex LSRF selects 33 modes from orders to 45 and
  to 60 alike, all 30 true ones among them; LSCF selects 10 → 14 at order 60 and 26 → 27 at 120, and grows on).

**The diagram keeps about ``max_order`` orders**: the grown estimate computes every ``s``-th order, ``s`` the
factor by which the order has grown (orders 2, 4, …, 120, then 4, 8, …, 240). The cost of a diagram (the
eigenvalue problems of all its orders, the stabilization, the clustering) grows with its orders times its poles,
so a diagram of every order to 240 cost about four times one with every fourth (LSCF on the benchmark: the
estimate and selections at 240 took 9.2 s with every order, the whole fit now about 6 s); the modes stable
over the upper orders are stable at every fourth order as well.

The diagram and selection of the last estimate are returned with it, so that :func:`ema.fit` does not compute
them again.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from .errors import EMAError
from .frf import FRFSet
from .poles import PoleSet
from .selection import PoleSelection, select_auto
from .stabilization import StabilityCriteria, StabilizationDiagram, stabilize

__all__ = ["Grown", "grow_order", "HEADROOM", "MAX_DOUBLINGS", "SATURATION"]

log = logging.getLogger(__name__)

#: The order grows only while the selection fills more than 1/HEADROOM of the modes its highest order holds. LSCF
#: at order 40 (20 modes) missed modes of the 10-mode close-modes truth on four seeds of six, at 60 on none
#: (tests/ema/test_auto_order.py); the complex LSRF found the 29 modes of tests/ema/test_band_fitting.py at 60.
HEADROOM = {"lscf": 3.0, "lsrf": 2.0}
#: The order grows at most this many doublings above ``max_order``.
MAX_DOUBLINGS = 3
#: The saturation test compares the selection from the orders up to this share of the highest with the whole
#: diagram's: the last quarter of the orders.
SATURATION = 0.75


class Grown(NamedTuple):
    """The poles at the chosen order, their diagram and its automatic selection."""

    poles: PoleSet
    diagram: StabilizationDiagram
    selection: PoleSelection


def grow_order(estimate: Callable[[int, Sequence[int]], PoleSet], frf: FRFSet, poles: PoleSet, method: str,
               band: tuple[float, float], max_order: int, criteria: StabilityCriteria | None,
               min_quality: float) -> Grown:
    """The poles at ``max_order``, or at a doubled order where the diagram asks for one (module notes).

    Parameters
    ----------
    estimate : callable
        ``estimate(order, orders)``: the estimator's poles over the fit band at those orders (highest ``order``).
    frf : FRFSet
    poles : PoleSet
        The estimate at ``max_order``.
    method : {"lscf", "lsrf"}
    band : (f_lo, f_hi)
        Hz, the band whose modes are counted.
    max_order : int
    criteria : StabilityCriteria, optional
    min_quality : float
        Automatic selection threshold.

    Returns
    -------
    Grown
    """
    order = max_order
    per_order = frf.n_inputs / 2 if method == "lscf" else 1.0
    for doubling in range(MAX_DOUBLINGS + 1):
        diagram = stabilize(poles, criteria)
        selection = select_auto(diagram, min_quality=min_quality)
        n = _count(selection, band)
        if doubling == MAX_DOUBLINGS or n * HEADROOM[method] <= order * per_order:
            break
        early = select_auto(_up_to(diagram, SATURATION * max(diagram.orders)), min_quality=min_quality)
        if _count(early, band) >= n:
            log.info("%s: %d modes selected at order %d, none added by its upper orders", method, n, order)
            break
        step = 2 * order // max_order
        try:
            grown = estimate(2 * order, range(step, 2 * order + 1, step))
        except EMAError:  # more unknowns than the lines support: the order stays
            break
        poles, order = grown, 2 * order
        log.info("%s: %d modes selected, the order grows to %d (every %d)", method, n, order, step)
    return Grown(poles, diagram, selection)


def _count(selection: PoleSelection, band: tuple[float, float]) -> int:
    f = selection.frequencies_hz
    return int(np.count_nonzero((f >= band[0]) & (f <= band[1])))


def _up_to(diagram: StabilizationDiagram, top: float) -> StabilizationDiagram:
    """The diagram of the orders up to ``top`` (the stability classes compare each order with the one before)."""
    return diagram.take(diagram.order <= top, orders=tuple(o for o in diagram.orders if o <= top))
