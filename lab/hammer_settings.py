"""How a virtual hammer test is done (:func:`lab.hammer.hammer_test`): the hammer, the analyser, the noise."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["HammerSettings"]


@dataclass(frozen=True)
class HammerSettings:
    """How the hammer test is done. SI units.

    Attributes
    ----------
    contact_time_s : float
        Duration T_c of the half-sine force pulse. A steel tip on steel gives about 0.1–0.3 ms (Ewins, *Modal
        Testing*, 2000; Avitabile, *Modal Testing: A Practitioner's Guide*, 2017). A half-sine's
        spectrum is |F(f)| ∝ |cos(π f T_c)| / |1 - (2 f T_c)²|, first zero at 1.5/T_c; the usual rule is to
        use it only where it has fallen by less than 10–20 dB. The default 0.2 ms falls by 2.1 dB at 2.5 kHz
        and 9.5 dB at 5 kHz (f T_c = 1), so it serves every band up to 5 kHz.
    peak_force_n : float
        Nominal peak force (N); a modal hammer on a small blade gives tens to hundreds of newtons.
    amplitude_scatter : float
        Each hit's peak is the nominal one times a factor uniform in [1 - s, 1 + s] (hand-held: ±10 %).
    double_hit_share : float
        Probability that a hit bounces back for a second one (about 1 in 10 on light, lively structures).
    double_hit_delay_s : (float, float)
        Range (uniform) of the second pulse's start after the first's; at least the contact time.
    double_hit_amplitude : (float, float)
        Range (uniform) of the second pulse's peak relative to the first.
    force_noise : float
        Force-channel noise: Gaussian, white at the analyser's rate, standard deviation this fraction of the
        nominal peak force (the channel's range is set to the peak).
    response_noise : float
        Response-channel (laser) noise: Gaussian, white at the analyser's rate, standard deviation this
        fraction of the RMS of the channel's elastic response over the record, taken on the first hit of each
        reference (as an analyser's range is set on a trial hit, after AC coupling removed the rigid-body drift).
    n_averages : int
        Hits averaged per reference (about 5 is common practice for impact tests; Avitabile 2017).
    force_window : float or None
        Length of the rectangular force window, as a multiple of ``contact_time_s`` from the trigger (the
        pulse's start): it keeps the pulse and drops the noise after it (Brandt, *Noise and Vibration
        Analysis*, 2011). A second hit outside it spoils the FRF, as in a lab. None: no force window.
    exp_window_end : float or None
        The exponential window w(t) = exp(-t/τ) falls to this value at the end of the record: 1 % is standard
        practice (Brandt 2011; Avitabile 2017). It makes lightly damped responses decay within
        the record (no leakage) and adds the damping Δζ_r = 1/(τ ω_r). None: no exponential window.
    oversampling : float
        fs / f_max. Analysers sample at 2.56 f_max (Brandt 2011): f_max at 78 % of Nyquist leaves room for
        the anti-aliasing filter's transition band.
    simulation_factor : int
        The structure's responses are computed on a grid at least this many times finer than the analyser's
        (refined further so that the pulse spans at least 8 samples): it keeps the response's aliases small.
    tip_rule : float or None
        A lab picks the hammer's tip for the band: :meth:`for_band` shortens the contact time to at most
        ``tip_rule / f_max``, so that the force spectrum is down by at most 9.5 dB at the band's top (f T_c = 1;
        harder tips and lighter hammers give contact times down to a few tens of µs). None: the contact
        time as set, whatever the band.

    Notes
    -----
    The band and the line spacing (hence the record length T = 1/df) come from :class:`lab.rig.RigSetup`.
    """

    contact_time_s: float = 2.0e-4
    peak_force_n: float = 100.0
    amplitude_scatter: float = 0.1
    double_hit_share: float = 0.1
    double_hit_delay_s: tuple[float, float] = (0.5e-3, 2.0e-3)
    double_hit_amplitude: tuple[float, float] = (0.1, 0.5)
    force_noise: float = 1.0e-3
    response_noise: float = 5.0e-3
    n_averages: int = 5
    force_window: float | None = 4.0
    exp_window_end: float | None = 0.01
    oversampling: float = 2.56
    simulation_factor: int = 8
    tip_rule: float | None = 1.0

    def for_band(self, f_max_hz: float) -> HammerSettings:
        """These settings with the tip a lab would take for a band up to ``f_max_hz`` (see ``tip_rule``)."""
        if self.tip_rule is None or self.contact_time_s * f_max_hz <= self.tip_rule:
            return self
        t_c = self.tip_rule / f_max_hz
        lo, hi = self.double_hit_delay_s
        return replace(self, contact_time_s=t_c, double_hit_delay_s=(max(lo, t_c), max(hi, t_c)))

    def validate(self) -> None:
        """Raise ValueError, with a one-line message naming the field and what was expected, on a bad setting."""

        def need(ok: bool, name: str, expected: str) -> None:
            if not ok:
                raise ValueError(f"HammerSettings.{name} = {getattr(self, name)!r}: expected {expected}")

        def real(x: object) -> bool:
            return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) \
                and math.isfinite(x)

        def pair(x: object) -> bool:
            return isinstance(x, (tuple, list)) and len(x) == 2 and all(real(v) for v in x) and x[0] <= x[1]

        need(real(self.contact_time_s) and self.contact_time_s > 0, "contact_time_s", "a positive duration (s)")
        need(real(self.peak_force_n) and self.peak_force_n > 0, "peak_force_n", "a positive force (N)")
        need(real(self.amplitude_scatter) and 0 <= self.amplitude_scatter < 1, "amplitude_scatter",
             "a fraction in [0, 1)")
        need(real(self.double_hit_share) and 0 <= self.double_hit_share <= 1, "double_hit_share",
             "a probability in [0, 1]")
        need(pair(self.double_hit_delay_s) and self.double_hit_delay_s[0] >= self.contact_time_s,
             "double_hit_delay_s", "(min, max) in s with contact_time_s <= min <= max (pulses may not overlap)")
        need(pair(self.double_hit_amplitude) and 0 < self.double_hit_amplitude[0] and self.double_hit_amplitude[1]
             <= 1, "double_hit_amplitude", "(min, max) with 0 < min <= max <= 1")
        need(real(self.force_noise) and self.force_noise >= 0, "force_noise", "a fraction >= 0")
        need(real(self.response_noise) and self.response_noise >= 0, "response_noise", "a fraction >= 0")
        need(isinstance(self.n_averages, (int, np.integer)) and not isinstance(self.n_averages, bool)
             and self.n_averages >= 1, "n_averages", "an integer >= 1")
        need(self.force_window is None or (real(self.force_window) and self.force_window >= 1), "force_window",
             "None or a multiple >= 1 of contact_time_s (the window must hold the pulse)")
        need(self.exp_window_end is None or (real(self.exp_window_end) and 0 < self.exp_window_end < 1),
             "exp_window_end", "None or a fraction in (0, 1)")
        need(real(self.oversampling) and self.oversampling >= 2, "oversampling",
             "fs / f_max >= 2 (Nyquist; analysers use 2.56)")
        need(isinstance(self.simulation_factor, (int, np.integer)) and not isinstance(self.simulation_factor, bool)
             and self.simulation_factor >= 4, "simulation_factor", "an integer >= 4")
        need(self.tip_rule is None or (real(self.tip_rule) and self.tip_rule > 0), "tip_rule",
             "None or a positive f_max · T_c")
