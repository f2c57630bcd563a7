"""The tuning of :func:`ema.fit` as one frozen object, and the refusal of the keywords it replaced."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import TypeVar

from .errors import EMAError
from .stabilization import StabilityCriteria

__all__ = ["FitSettings", "SETTING_NAMES", "refuse_settings_keywords"]

F = TypeVar("F", bound=Callable)


@dataclass(frozen=True)
class FitSettings:
    """How :func:`ema.fit` estimates, selects and refines the modes; the defaults suit every bundled test.

    Attributes
    ----------
    method : {"lsrf", "lscf"}
        Pole estimator (:func:`ema.global_fit.estimate_poles`; LSRF with complex coefficients). LSRF is the
        default: on close pairs it separates the two modes at every order, where LSCF often returns a single pole
        for both (tests/ema/test_close_modes.py).
    orders : sequence of int, optional
        Explicit model orders (see :func:`ema.lscf.lscf`, :func:`ema.lsrf.lsrf`); default ``1 .. max_order``.
    criteria : StabilityCriteria, optional
        Stability criteria of the diagram; default :class:`ema.stabilization.StabilityCriteria`'s.
    min_quality : float
        Automatic selection threshold (:func:`ema.selection.select_auto`).
    min_dominance : float
        Drop modes whose :func:`ema.dominance.mode_dominance` is below this (poles that only patch the fit of a
        neighbour), then refit; again after the refinement. Applies to automatically selected modes and to the
        modes of the padding, never to modes chosen by ``frequencies_hz`` or ``picks``. 0 keeps everything.
    n_bands : int
        > 1 fits band by band (:func:`ema.global_fit.local_poles`) over the band itself (no padding):
        ``max_order`` / ``orders`` then apply to every sub-band.
    refine : bool
        Refine the selected poles by nonlinear least squares on the LSFD model (:func:`ema.refine.refine_band`).
    pad : float
        Widening of the band on each side, as a fraction of its width (single-band fits); 0 fits the band alone.
    split : bool
        Refit the window of every automatically selected mode with the complex LSRF and take its modes where it
        finds more (:func:`ema.resolve.split_merged`: two modes that the estimator merged at its order), then
        refit, refine and judge the dominance of the whole model again. Not with ``frequencies_hz``, ``picks`` or
        ``families`` (whose growth resolves its windows itself; the check moved a family's starting modes and left
        one mode of tests/ema/test_family.py's family at shape MAC 0.02).
    grow : bool
        The order from the data (single-band fits, no ``orders``, no ``picks``): double ``max_order`` while the
        automatic selection fills more than 1/:data:`ema.growth.HEADROOM` of the modes the estimator's highest
        order holds and the diagram's upper orders still add modes (:func:`ema.growth.grow_order`).

    Raises
    ------
    EMAError
        A negative ``pad``.
    """

    method: str = "lsrf"
    orders: Sequence[int] | None = None
    criteria: StabilityCriteria | None = None
    min_quality: float = 0.15
    min_dominance: float = 0.7
    n_bands: int = 1
    refine: bool = True
    pad: float = 0.25
    split: bool = True
    grow: bool = True

    def __post_init__(self) -> None:
        if not self.pad >= 0:
            raise EMAError(f"pad {self.pad}: expected >= 0")


#: The keywords of :func:`ema.fit` that :class:`FitSettings` holds.
SETTING_NAMES = frozenset(f.name for f in fields(FitSettings))


def refuse_settings_keywords(func: F) -> F:
    """``func`` (whose settings come as ``settings=FitSettings(...)``) refusing the keywords that moved into them.

    A keyword of :data:`SETTING_NAMES`, or a method name where the band goes (``fit(frf, "lscf")``), is refused
    with one line that names the setting to use; Python's own message would only say that the keyword is
    unexpected.
    """
    name = f"ema.{func.__name__}"

    @functools.wraps(func)
    def checked(*args, **kwargs):
        moved = [key for key in kwargs if key in SETTING_NAMES]
        if moved:
            raise TypeError(f"{name}: {moved[0]!r} is a setting now: pass settings=FitSettings({moved[0]}=...)")
        if len(args) > 1 and isinstance(args[1], str):
            raise TypeError(f"{name}: the method is a setting now: pass settings=FitSettings(method={args[1]!r})")
        return func(*args, **kwargs)

    return checked  # type: ignore[return-value]
