"""The model order from the data (issue 31, item 2): grow it until the automatic selection stops gaining modes.

A fixed highest order suits the data sets it was chosen on: on the close-modes truth of the tests (10 modes,
4 outputs, pairs 0.2–0.3 % apart), LSCF finds all 10 at order 60 and only 6–9 at order 40 on four seeds of six.
:func:`fit_auto_order` fits at ``start``, then at ``factor`` times the order, and so on, and stops at the first
order whose next step selects no more modes in the band: the lowest order on this ladder that resolves every
mode the data support. The ladder ends where the estimator refuses the order (too few lines for its unknowns).
"""

from __future__ import annotations

import numbers
from dataclasses import replace

from .errors import EMAError
from .fit import EMAResult, fit
from .settings import FitSettings, refuse_settings_keywords

__all__ = ["fit_auto_order", "AUTO_START", "AUTO_FACTOR"]

#: First order of the ladder, and its growth factor (doubling keeps the extra fits below the last one's cost).
AUTO_START, AUTO_FACTOR = 20, 2


@refuse_settings_keywords
def fit_auto_order(frf, band: tuple[float, float] | None = None, settings: FitSettings | None = None, *,
                   start: int = AUTO_START, factor: int = AUTO_FACTOR, limit: int = 640,
                   **fit_kwargs) -> tuple[EMAResult, int]:
    """:func:`ema.fit` at the model order chosen from the data (module docstring).

    Parameters
    ----------
    frf : FRFSet
    band : (f_lo, f_hi) in Hz, optional
    settings : FitSettings, optional
        As for :func:`ema.fit`, without ``orders``; each rung is fitted at its own order, without growth
        (``grow`` is set False).
    start, factor : int
        The ladder ``start · factor**k`` (start ≥ 2, factor ≥ 2).
    limit : int
        Highest order tried.
    **fit_kwargs
        Passed to :func:`ema.fit` (``frequencies_hz``, ``families``, …), except ``max_order``.

    Returns
    -------
    (EMAResult, int)
        The fit at the chosen order, and that order.

    Raises
    ------
    EMAError
        Bad ladder settings, an order given as well, or a data set that refuses even ``start``.
    TypeError
        A field of :class:`FitSettings` given as a keyword.
    """
    for name, v, lo in (("start", start, 2), ("factor", factor, 2), ("limit", limit, 2)):
        if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < lo:
            raise EMAError(f"{name} must be an integer ≥ {lo}, got {v!r}")
    if "max_order" in fit_kwargs or (settings is not None and settings.orders is not None):
        raise EMAError("the order is chosen from the data: give no max_order or orders")
    # the ladder chooses the order: no growth inside a rung
    settings = replace(settings if settings is not None else FitSettings(), grow=False)
    order = min(int(start), int(limit))
    best = fit(frf, band, settings, max_order=order, **fit_kwargs)
    while order * factor <= limit:
        try:
            nxt = fit(frf, band, settings, max_order=order * factor, **fit_kwargs)
        except EMAError:  # more unknowns than the lines support: the ladder ends here
            break
        if nxt.model.n_modes <= best.model.n_modes:
            break
        best, order = nxt, order * factor
    return best, order
