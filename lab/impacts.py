"""The hammer's force in a virtual hammer test: each hit's peak, double hits, and the half-sine pulses.

:func:`lab.hammer.hammer_test` draws one :class:`Impacts` per reference DOF (one hit per average) and records
the force :func:`impact_force` gives on its simulation grid (docs/twin.md, "The hammer test").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hammer_settings import HammerSettings

__all__ = ["Impacts", "draw_impacts", "impact_force"]

@dataclass(frozen=True)
class Impacts:
    """Random draws of a series of hits (one per average).

    Attributes
    ----------
    amplitude_n : ndarray, shape (n_hits,)
        Peak force of the first pulse (N).
    double : ndarray of bool, shape (n_hits,)
        Whether a second pulse follows.
    delay_s : ndarray, shape (n_hits,)
        Start of the second pulse after the first's (drawn for every hit; used where ``double``).
    ratio : ndarray, shape (n_hits,)
        Second pulse's peak over the first's (0 where not ``double``).
    """

    amplitude_n: np.ndarray
    double: np.ndarray
    delay_s: np.ndarray
    ratio: np.ndarray


def draw_impacts(settings: HammerSettings, rng: np.random.Generator, n_hits: int) -> Impacts:
    """Draw the amplitude and any double hit of ``n_hits`` hits (uniform scatter, Bernoulli double hits)."""
    s = settings
    amplitude = s.peak_force_n * (1.0 + s.amplitude_scatter * rng.uniform(-1.0, 1.0, n_hits))
    double = rng.random(n_hits) < s.double_hit_share
    delay = rng.uniform(*s.double_hit_delay_s, n_hits)
    ratio = np.where(double, rng.uniform(*s.double_hit_amplitude, n_hits), 0.0)
    return Impacts(amplitude, double, delay, ratio)


def impact_force(t: np.ndarray, contact_time_s: float, impacts: Impacts) -> np.ndarray:
    """Samples of the force of each hit (N): half-sine pulses starting at t = 0 (and at ``delay_s``).

    Parameters
    ----------
    t : ndarray, shape (n_t,)
        Sampling instants (s) from the trigger.
    contact_time_s : float
    impacts : Impacts
        ``n_hits`` hits.

    Returns
    -------
    ndarray, shape (n_hits, n_t)
    """

    def half_sine(x: np.ndarray) -> np.ndarray:
        inside = (x >= 0) & (x <= contact_time_s)
        return np.where(inside, np.sin(np.pi * np.clip(x / contact_time_s, 0.0, 1.0)), 0.0)

    second = half_sine(t[None, :] - impacts.delay_s[:, None]) * impacts.ratio[:, None]
    return impacts.amplitude_n[:, None] * (half_sine(t)[None, :] + second)
