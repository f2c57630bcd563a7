"""Modes a model misses, found where the residual stands above the noise, and fitted by a grown structured window.

:func:`unexplained_lines` scales the residual of every FRF by a two-part noise model
(:func:`ema.fit_noise.noise_model`) and sets a threshold that noise alone exceeds with probability
:data:`FALSE_ALARM`; :func:`fill_unexplained` opens a window at the line highest above it, grows a structured fit
there (:func:`ema.family.fit_family`) and merges it in (:func:`ema.families.merge_families`), until no line stands
above the threshold.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from .families import merge_families
from .family import FamilyFit, fit_weighted
from .family_windows import damping_outlier_bound
from .fit_noise import band_floor, noise_model
from .frf import FRFSet
from .lsfd import half_widths, synthesize
from .modal import ModalModel, modal_from_pole, pole_from_modal
from .refine import without_modes

__all__ = ["FALSE_ALARM", "unexplained_lines", "fill_unexplained", "with_margins"]

log = logging.getLogger(__name__)

#: Chance that noise alone puts one line of a whole test above :func:`unexplained_lines`' threshold.
FALSE_ALARM = 0.01


def unexplained_lines(frf: FRFSet, model: ModalModel, band: tuple[float, float]
                      ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Where the data hold more than a modal model and noise explain: the lines of modes the fit missed.

    The residual ``R = H − Ĥ`` of every FRF is scaled by a noise model with the two kinds of FRF noise: an
    additive floor per FRF, ``σ²_oi = median_f |R_oi|² / ln 2`` (the median of a complex Gaussian's power),
    and a share of the response, ``s² = median |R|² / |Ĥ|² / ln 2`` over the strong values (|Ĥ|² ≥
    :data:`ema.fit_noise.STRONG` σ²_oi). Under that model ``z = |R|² / (σ²_oi + s² |Ĥ_oi|²)`` is exponential
    with mean 1 in every FRF, so the largest of ``n_frf × n_lines`` values stays below
    ``ln(n_frf n_lines / FALSE_ALARM)`` with probability ``1 − FALSE_ALARM``.
    Why the largest over the FRFs, not their sum: a mode seen by a few
    response points only (a disk mode at blade tips) stands far above the floor in those FRFs and vanishes
    in a sum over all of them (on the bundled full-assembly test the sum missed four disk modes that the
    largest shows at 10⁴ times the floor).

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        With residues (:func:`ema.lsfd.modal_model`).
    band : (f_lo, f_hi)
        Hz.

    Returns
    -------
    freq_hz : ndarray, shape (n_lines,)
    z : ndarray, shape (n_lines,)
        The largest scaled residual power over the FRFs at each line.
    threshold : float
    floor : ndarray, shape (n_outputs, n_inputs)
        The additive noise floor ``σ_oi`` (FRF units).
    """
    sel = frf.valid_lines() & (frf.freq_hz >= band[0]) & (frf.freq_hz <= band[1]) & (frf.freq_hz > 0)
    freq = frf.freq_hz[sel]
    fitted = synthesize(model, freq, form=frf.form).H
    P = np.abs(frf.H[:, :, sel] - fitted) ** 2
    M = np.abs(fitted) ** 2
    floor, share = noise_model(P, M, axis=2)
    z = np.max((P / (floor + share * M)).reshape(-1, freq.size), axis=0)
    threshold = float(np.log(P.shape[0] * P.shape[1] * max(freq.size, 1) / FALSE_ALARM))
    return freq, z, threshold, np.sqrt(floor[:, :, 0])


def with_margins(window: tuple[float, float], model: ModalModel, band: tuple[float, float]) -> tuple[float, float]:
    """``window`` (Hz) widened, within ``band``, to take in every mode of ``model`` whose half-power band
    f(1 ± ζ) reaches into it, with that band.

    Why: the window is fitted on the data less the model's modes outside it, and what such a mode leaves (its errors
    of frequency, damping and residue) is steep within its half-power band, where the residual terms cannot follow
    it. Cut there, the window's growth trials ran to that edge instead of to the modes its core misses: a seed-7
    36-blade campaign's 186.6-200.6 Hz window, beside the model's 200.94 and 201.11 Hz (ζ 0.24-0.30 %), ended growth
    on four trials at 200.2 Hz and found 15 of the 19 true modes in its core; with them in, 19 of 19 (design §8.73).
    Once: the modes whose bands reach into the margins leave their errors there, not in the window, and following
    them on took a 48-blade window 22 Hz into a family (78 s instead of 10 s, the same modes found).
    """
    f, zeta = model.frequencies_hz, model.damping_ratio
    lo, hi = window
    up = (f > hi) & (f <= band[1]) & (f * (1 - zeta) < hi)
    down = (f < lo) & (f >= band[0]) & (f * (1 + zeta) > lo)
    return (max(band[0], min(lo, float(np.min(f[down] * (1 - zeta[down]), initial=lo)))),
            min(band[1], max(hi, float(np.max(f[up] * (1 + zeta[up]), initial=hi)))))


def missed_beside(window: tuple[float, float], freq: np.ndarray, z: np.ndarray, threshold: float) -> np.ndarray:
    """Frequencies (Hz) of modes the model misses just outside ``window``: beyond each edge whose line stands above
    ``threshold``, the highest peak of the scaled residual ``z`` above it within the window's half-width (the local
    window rule that sized it), higher than the edge's line.

    Why: such a mode's tail fills the window's data, and growth patched it with poles of its own (a seed-7
    48-blade campaign: the window opened at 570.85 Hz before the scan reached 593.96 and 596.79 Hz grew 578.0,
    580.15 and 583.86 Hz, 0.7-1.7 % from every true mode; design §8.94). As a margin's starting mode, it stands for
    that tail and is merged only if it ends inside the window."""
    half = (window[1] - window[0]) / 2
    out = []
    for edge, reach in ((window[1], (window[1], window[1] + half)), (window[0], (window[0] - half, window[0]))):
        e = int(np.argmin(np.abs(freq - edge)))
        if z[e] <= threshold:
            continue
        inner = np.flatnonzero((freq > reach[0]) & (freq < reach[1]))
        inner = inner[(inner > 0) & (inner < freq.size - 1)]
        peaks = inner[(z[inner] > z[inner - 1]) & (z[inner] >= z[inner + 1]) & (z[inner] > z[e])]
        if peaks.size:
            out.append(freq[peaks[np.argmax(z[peaks])]])
    return np.array(out, dtype=np.float64)


def _within(fit: FamilyFit, window: tuple[float, float], n_margins: int) -> FamilyFit:
    """``fit`` cut to its modes inside ``window`` (Hz), less the ``n_margins`` starting modes it had outside it.

    ``n_start`` stays what :func:`ema.family.fit_family` counts (the starting modes that it kept) for a window
    without margins; with them, the margins' starting modes are taken as kept."""
    if fit.window_hz == (float(window[0]), float(window[1])):
        return fit
    f = modal_from_pole(fit.poles)[0]
    sel = (f >= window[0]) & (f <= window[1])
    return FamilyFit(window_hz=(float(window[0]), float(window[1])), poles=fit.poles[sel], residues=fit.residues[sel],
                     frequency_std_hz=fit.frequency_std_hz[sel], damping_std=fit.damping_std[sel],
                     n_start=max(0, fit.n_start - n_margins))


def _scan_window(frf: FRFSet, model: ModalModel, band: tuple[float, float], scan: tuple, line: float,
                 zeta: float) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float], np.ndarray]:
    """The window a scan opens at ``line`` (Hz), of the local half-width at damping ``zeta``: (the window opened,
    the window fitted, with its margins, the core where growth may add modes, the missed modes beside it in Hz).
    ``scan``: :func:`unexplained_lines`' result."""
    freq, z, threshold, _ = scan
    _, half, _ = half_widths(pole_from_modal(np.array([line]), np.array([zeta])), frf, band)
    opened = (max(band[0], line - half[0]), min(band[1], line + half[0]))
    core = (max(opened[0], line - half[0] / 2), min(opened[1], line + half[0] / 2))
    window = with_margins(opened, model, band)
    extra = missed_beside(opened, freq, z, threshold)
    if extra.size:
        window = (max(band[0], min(window[0], float(np.min(extra)) * (1 - zeta))),
                  min(band[1], max(window[1], float(np.max(extra)) * (1 + zeta))))
    return opened, window, core, extra


def fill_unexplained(frf: FRFSet, model: ModalModel, band: tuple[float, float],
                     tried: Sequence[tuple[float, float]] = ()) -> ModalModel:
    """Open a structured fit wherever the data hold modes that ``model`` misses (the order from the data).

    A fit at a fixed model order finds nothing of a family whose stable poles need a higher order, and a window
    grown from the found modes never reaches it. Here the line that :func:`unexplained_lines` ranks
    highest above its noise threshold gets a window (the local half-width rule of :func:`ema.lsfd.local_windows`
    at the model's median damping). :func:`ema.family.fit_family` grows it from the model's modes inside it, on
    the data less the model's other modes (so that a strong neighbour's tail does not draw the new pole away);
    a grown window is merged in (:func:`ema.families.merge_families`) when one of its modes sits on the line that
    opened it, no more damped than the model's :func:`ema.family.damping_outlier_bound`, and new (growth added a
    mode, or that one matches none of the model's: a starting pole moved onto the line), and the residual is
    scanned again. Each try uses up its window's core, so the loop ends; it ends early when no line stands above
    the threshold.

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        With residues and ``frequency_std_hz`` (at least one mode: its damping sets the windows' width).
    band : (f_lo, f_hi)
        Hz.
    tried : sequence of (f_lo, f_hi)
        Hz ranges already grown (the windows of :func:`ema.families.resolve_families`): not tried again.
    """
    tried = list(tried)
    zeta_max = damping_outlier_bound(model.damping_ratio)
    scan = unexplained_lines(frf, model, band) if model.n_modes else None
    # weighted by each FRF's noise, as resolve_families; from the data's differences, not this scan's floor: that
    # one holds the modes the model misses as well (design §8.61)
    floor = band_floor(frf, band)
    while scan is not None:
        freq, z, threshold, _ = scan
        z = z.copy()
        for lo, hi in tried:
            z[(freq >= lo) & (freq <= hi)] = 0.0
        k = int(np.argmax(z))
        if z[k] <= threshold:
            break
        zeta = float(np.median(model.damping_ratio))
        opened, window, core, extra = _scan_window(frf, model, band, scan, float(freq[k]), zeta)
        tried.append(core)
        f = model.frequencies_hz
        inside = (f >= window[0]) & (f <= window[1])
        data = without_modes(frf, model, ~inside)
        # complex residual terms: what the subtracted modes leave (their errors of damping and residue phase) is a
        # background of any phase, which the real mass and stiffness lines cannot follow; once weighted, it stands
        # far above the strong FRFs' noise, and a pole at the damping bound took it (24-blade campaign: 0 of the
        # 7 modes of a 634-672 Hz window with real terms, 7 of 7 with complex ones; design §8.61)
        # every refusal counts: what the subtracted modes leave draws trial after trial to one place (a 24-blade
        # campaign's 658.9 Hz, 13 times), and growing on past it cost a mode and added one 1 % off (design §8.67)
        start = np.r_[model.poles[inside], pole_from_modal(extra, np.full(extra.size, zeta))]
        fit = fit_weighted(data, floor, start, window, core, zeta0=zeta, complex_residuals=True, skip_repeats=False)
        # the margins give the fit its neighbours as modes; it answers for the window the scan opened (design §8.73)
        fit = _within(fit, opened, int(np.count_nonzero(inside & ((f < opened[0]) | (f > opened[1])))) + extra.size)
        log.info("unexplained %.6g Hz (z %.3g > %.3g; %.6g-%.6g Hz, %d missed beside): %d modes -> %d", freq[k], z[k],
                 threshold, *window, extra.size, fit.n_start, fit.n_modes)
        f_new, z_new = modal_from_pole(fit.poles)
        # kept only if a mode of it sits on the line that opened the window: within max(2 ζ f, 2 lines), as
        # merge_families matches, with ζ its own but at most the model's median. A pole that wandered off to
        # fit something else in the window is noise; so is a narrow one beside the line (a 6-blade campaign:
        # ζ 0.025 %, 1.35 Hz away, 2.8 % from every true mode) and a broad one whose band merely covers it
        # (seed 12: ζ 2.5 %, 6 Hz away, 1.2 % from every true mode); and one more damped than the model's outliers
        # (a 24-blade campaign: three at ζ 1.0-1.2 %, 1.5-5 % from every true mode, between the family windows)
        spacing = float(np.median(np.diff(freq))) if freq.size > 1 else 0.0
        reach = np.maximum(2 * np.minimum(z_new, zeta) * f_new, 2 * spacing)
        on_line = (np.abs(f_new - freq[k]) <= reach) & (z_new <= zeta_max)
        # a mode on the line that matches none of the model's is new even where the fit kept its count: a starting
        # mode can move onto the line, and merge_families keeps the model's mode it left (a 36-blade campaign: the
        # model's 596.4 Hz moved to the unexplained 608.5 Hz, true 608.48 Hz, and the trial that would have put it
        # back was refused at the window's edge, so "2 modes -> 2" threw the new mode away). Not so in
        # resolve_families' windows, where no line vouches for such a mode (merge_families' seed 12)
        matched = np.any(np.abs(f_new[:, None] - model.frequencies_hz[None, :]) <= reach[:, None], axis=1)
        if np.any(on_line) and (fit.n_modes > fit.n_start or np.any(on_line & ~matched)):
            model = merge_families(frf, model, [fit], found=[on_line & ~matched])
            scan = unexplained_lines(frf, model, band)
    return model
