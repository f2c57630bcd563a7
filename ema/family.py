"""Dense mode families resolved by a structured fit of rank-one residues (issue 31, item 1).

A mistuned bladed disk's blade family holds as many modes as blades within about 1 % (0.02–0.06 % apart,
with half-power bandwidths of 0.1–1 %). The pole estimators' free residues (one complex number per mode and
FRF) cannot separate them: with the true poles given, the linearised covariance of the free-residue fit on
the bundled full-assembly test leaves the family's frequencies at 0.2–0.5 % standard deviation, or singular.
The physics has fewer unknowns. Each mode's residue matrix is rank one, ``A_r = ψ_r l_rᵀ`` (the shape at the
outputs times the participation at the references), and with it the Cramér–Rao bound of the same family's
frequencies is below 0.0005 % (docs/ema.md, "Dense families").

This module fits that model window by window:

- **Model** (mobility shown; receptance and accelerance by the power of jω)::

      H_oi(ω) = jω Σ_r [ψ_or l_ir / (jω − λ_r) + conj(ψ_or l_ir) / (jω − conj λ_r)] + jω (L_oi / (jω)² + U_oi)

  Variable projection: for given poles and participations the shapes ψ and the real residual terms are one
  linear least-squares solve shared by every output; the natural frequencies, log damping ratios and
  participations (each normalised to 1 at its largest reference) are refined by Levenberg–Marquardt with
  Kaufman's Jacobian. The Jacobian of each parameter is rank two over the outputs, and each of its columns
  is a few kernels of the frequency times a coefficient per reference, so its Gram matrix is assembled from
  the kernels' Gram over the lines without forming the Jacobian (:mod:`ema.gram`).
- **Growth.** Starting from the modes an ordinary fit selected, the line and output where the residual holds
  most energy get a new pole, its participation that output's residual at that line, and the whole window is
  refined again. The new mode is kept when it explains at least as much of the data in its own half-power band
  as the noise left there (:func:`_explains`), that band lies in the window and its damping is not at a bound
  (:func:`_kept`); otherwise the next (line, output) is tried, and growth stops after :data:`RETRIES` + 1
  refusals in a row that ended in different places (:func:`_repeats`). Per output, because a mistuned family's
  modes are localised: at one line different blades' outputs see different modes (design §8.60). Not an
  information criterion: a test's noise is a share of |H|, and a pole fitted to it beat BIC on the bundled test
  (design §8.33). Each trial is refined to :data:`TRIAL_TOL`, the modes kept to :data:`TOL` once growth ends.

The result replaces the window's modes; their shapes come from ``ψ_r l_rᵀ`` and their standard deviations
from the larger of two sandwich covariances of the structured fit: White's (the lines as clusters, as
:func:`ema.uncertainty.pole_std`) and one whose meat comes from residuals drawn from the window's noise model,
correlated over the lines as the residual is (:func:`_result`, :mod:`ema.line_correlation`).
:func:`ema.families.resolve_families` runs it on every window of several modes;
:func:`ema.unexplained.unexplained_lines` finds where a model leaves modes out, with
:func:`ema.fit_noise.noise_model`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .family_shapes import reweighted_residues
from .family_window import FamilyWindow
from .family_windows import damping_outlier_bound, family_windows
from .fit_noise import noise_draws, rank_one_scale
from .frf import FRFSet
from .line_correlation import scores_variance
from .lsfd import lsfd
from .modal import modal_from_pole, pole_from_modal

__all__ = ["FamilyFit", "FamilyWindow", "damping_outlier_bound", "family_windows", "fit_family", "fit_weighted",
           "normalised_participations", "step_parameters", "ZETA_BOUNDS"]

#: Damping ratio bounds of the refinement (a pole driven to the lower bound is fitting a noise spike).
ZETA_BOUNDS = (1e-5, 0.05)
#: Levenberg–Marquardt iterations per refinement, and the relative cost decrease that ends it.
MAX_ITER, TOL = 150, 1e-9
#: The relative cost decrease that ends a growth trial's refinement. Looser than :data:`TOL`: a trial only decides
#: whether its new mode is kept, and the tail of its refinement (gains of 1e-6 to 1e-9 per iteration, up to 100
#: iterations of 150) was most of the growth's time. A seed-7 36-blade campaign's 1192-1279 Hz window kept the same
#: 37 modes (37 paired) in 99 s instead of 138 s (design §8.67).
TRIAL_TOL = 1e-6
#: A participation is scaled anew when an entry exceeds its pivot this many times (:func:`_refine`; above 1, so
#: that two entries of nearly equal size do not swap the pivot back and forth).
REPIVOT = 2.0
#: Growth tries this many more candidates after one is refused before it stops (:func:`fit_family`); refusals that
#: end where an earlier one did are not counted (:func:`_repeats`).
RETRIES = 3


@dataclass(frozen=True)
class FamilyFit:
    """The structured fit of one window.

    Attributes
    ----------
    window_hz : (f_lo, f_hi)
        The lines fitted (Hz).
    poles : ndarray of complex128, shape (n_modes,)
        Continuous-time poles (rad/s), ascending frequency.
    residues : ndarray of complex128, shape (n_modes, n_outputs, n_inputs)
        ``ψ_r l_rᵀ`` in the receptance convention of :func:`ema.lsfd.lsfd`.
    frequency_std_hz, damping_std : ndarray of float64, shape (n_modes,)
        Sandwich standard deviations (White's estimator with the spectral lines as clusters).
    n_start : int
        Modes the window started with.
    """

    window_hz: tuple[float, float]
    poles: np.ndarray
    residues: np.ndarray
    frequency_std_hz: np.ndarray
    damping_std: np.ndarray
    n_start: int

    @property
    def n_modes(self) -> int:
        return int(self.poles.size)


def step_parameters(f, logz, part, pivot, delta):
    """The window's parameters moved by a step ``delta`` in :meth:`FamilyWindow.gauss_newton`'s order (f Hz, log ζ,
    Re/Im of each non-pivot participation, mode by mode), log ζ clipped to :data:`ZETA_BOUNDS`."""
    f, logz, part = f.copy(), logz.copy(), part.copy()
    k = 0
    for r in range(f.size):
        f[r] += delta[k]
        logz[r] += delta[k + 1]
        k += 2
        for i in range(part.shape[0]):
            if i != pivot[r]:
                part[i, r] += delta[k] + 1j * delta[k + 1]
                k += 2
    return f, np.clip(logz, *np.log(ZETA_BOUNDS)), part


def _participations(frf: FRFSet, window: tuple[float, float], lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each mode's participation from the free-residue LSFD at the poles: the rank-one part of its residues."""
    A = lsfd(frf, lam, window)[0]                              # (n, n_out, n_in)
    part = np.array([np.linalg.svd(A[r])[2][0] for r in range(lam.size)]).T.reshape(A.shape[2], lam.size)
    return normalised_participations(part)


def normalised_participations(part: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Participations (n_in, n_modes) scaled to 1 at each mode's largest reference, and those references (pivots)."""
    pivot = np.argmax(np.abs(part), axis=0)
    return part / part[pivot, np.arange(part.shape[1])], pivot


def _mode_offsets(n_modes: int, n_in: int) -> np.ndarray:
    """Where each mode's parameters start in :meth:`FamilyWindow.gauss_newton`'s order: f, log ζ, then Re and Im
    of its n_in − 1 non-pivot participations, 2 n_in in all."""
    return np.arange(n_modes) * 2 * n_in


def _held(f, logz, grad, lo: float, hi: float, n_in: int) -> np.ndarray:
    """Which parameters (in :meth:`FamilyWindow.gauss_newton`'s order) sit at a bound that the descent direction
    ``−grad`` pushes them past: a frequency at the window's edge, a log ζ at the upper bound of :data:`ZETA_BOUNDS`.

    Projected Levenberg–Marquardt holds them fixed for the step. Why: a step clipped back to the bound leaves the
    other parameters' move too small, and the refinement crawled to MAX_ITER, each iteration lowering the cost by
    1e-8 to 1e-5, wherever a mode's damping ran to 5 % (24-blade campaign: 53 of 143 s in one such refinement).
    Not at the lower bound: a pole fitting a noise spike is to reach it, where :func:`fit_family` drops it (held
    there, a 6-blade campaign's 647 Hz spike stopped at ζ 0.0004 and was kept, 3.6 % from every true mode).
    """
    held = np.zeros(grad.size, bool)
    at = _mode_offsets(f.size, n_in)                      # each mode's f; its log ζ follows
    held[at] = ((f <= lo) & (grad[at] > 0)) | ((f >= hi) & (grad[at] < 0))
    held[at + 1] = (logz >= np.log(ZETA_BOUNDS[1])) & (grad[at + 1] < 0)
    return held


def _refine(win: FamilyWindow, f, zeta, part, pivot, watch: int | None = None, tol: float = TOL):
    """Projected Levenberg–Marquardt on the variable-projection cost (:func:`_held`); returns (f, ζ, part, pivot).
    ``watch``: a mode; stop once it is held at a bound, where :func:`_kept` refuses it (:func:`_given_up`).

    A participation whose largest entry grows past :data:`REPIVOT` times its pivot is scaled anew to 1 at that
    entry (the cost does not change: ψ takes the scale). Why: with the pivot held at 1, a mode whose pivot entry
    should be small is reached only by its other entries running off (to 1e5 on a 36-blade window), where the
    steps stall; from the true poles of that window, the refinement ended at 3.0 times the cost it reaches with
    re-pivoting (design §8.60)."""
    f, logz = np.asarray(f, float).copy(), np.log(np.clip(zeta, *ZETA_BOUNDS))
    lo, hi = win.freq[0], win.freq[-1]
    cost, JJ, grad = win.gauss_newton(pole_from_modal(f, np.exp(logz)), part, pivot)
    mu = 1e-3
    for _ in range(MAX_ITER):
        free = ~_held(f, logz, grad, lo, hi, win.n_in)
        if watch is not None and _given_up(f, free, win.n_in, watch):
            break
        JJf, gf = JJ[np.ix_(free, free)], grad[free]
        scale = np.where(np.diag(JJf) > 0, np.diag(JJf), 1.0)
        while True:
            delta = np.zeros(grad.size)
            delta[free] = -np.linalg.solve(JJf + mu * np.diag(scale), gf)
            f2, logz2, part2 = step_parameters(f, logz, part, pivot, delta)
            f2 = np.clip(f2, lo, hi)
            solved = win.solve(pole_from_modal(f2, np.exp(logz2)), part2)
            cost2 = solved[0]
            if cost2 < cost:
                mu = max(mu / 3, 1e-12)
                break
            mu *= 4
            if mu > 1e10:
                return f, np.exp(logz), part, pivot
        gain = (cost - cost2) / cost
        f, logz, part = f2, logz2, part2
        if np.max(np.abs(part), initial=0.0) > REPIVOT:
            part, pivot, solved = *normalised_participations(part), None
        cost, JJ, grad = win.gauss_newton(pole_from_modal(f, np.exp(logz)), part, pivot, solved)
        if gain < tol:
            break
    return f, np.exp(logz), part, pivot


def _given_up(f, free, n_in: int, r: int) -> bool:
    """Is mode r held (not ``free``) at the upper damping bound or at the window's edge?

    A growth trial whose new mode is there is refused (:func:`_kept`), and :func:`_refine` stops it: a 24-blade
    campaign's trials at a window's edge otherwise ran 150 iterations (7.7 s each) with the new mode held at the
    edge at 5 % damping. Held, not merely near: a mode near a bound can come back (a trial at 4.5 % damping
    ended at 1.9 %: ``tests/ema/test_family.py``)."""
    at = _mode_offsets(f.size, n_in)[r]
    return bool(not free[at] or not free[at + 1])


def _band_energy(win: FamilyWindow, res: np.ndarray, f: float, zeta: float) -> float:
    """Residual energy in a mode's half-power band (at least ± one line)."""
    half = max(zeta * f, np.median(np.diff(win.freq)) if win.n_lines > 1 else 0.0)
    lines = np.abs(win.freq - f) <= half
    return float(np.sum(res.reshape(2, win.n_in, win.n_lines, win.n_out)[:, :, lines] ** 2))


def _explains(win: FamilyWindow, f, zeta, part, r: int) -> bool:
    """Does mode r explain at least the noise of its own half-power band?

    The cost rises by Δ when the mode is removed (the others' shapes re-solved); that Δ is compared with the
    residual energy left in the mode's band with it. A pole that fits noise cannot remove more than the noise
    there; a mode of the data removes its own resonance, many times the noise at any visible peak.
    """
    return _explained(win, f, zeta, part, r) >= 1.0


def _explained(win: FamilyWindow, f, zeta, part, r: int, solved: tuple | None = None) -> float:
    """Mode r's Δ (the cost's rise without it) over half the residual energy left in its half-power band
    (:func:`_explains`; cost is ½‖r‖²). ``solved``: the window's (cost, residual) at these modes, if known."""
    lam = pole_from_modal(f, zeta)
    cost, res = solved if solved is not None else win.solve(lam, part)[:2]
    left = _band_energy(win, res, f[r], zeta[r])
    keep = np.arange(f.size) != r
    without = win.solve(lam[keep], part[:, keep])[0] if keep.any() else 0.5 * float(np.sum(win.Y**2))
    return (without - cost) / max(0.5 * left, np.finfo(float).tiny)


def _at_bound(zeta):
    """Is a damping ratio (or each of an array) at a bound of :data:`ZETA_BOUNDS`: a pole fitting a noise spike
    (lower) or the window's background (upper)?"""
    return (zeta <= 1.5 * ZETA_BOUNDS[0]) | (zeta >= ZETA_BOUNDS[1] / 1.5)


def fit_family(frf: FRFSet, poles: np.ndarray, window: tuple[float, float], core: tuple[float, float],
               max_added: int | None = None, zeta0: float | None = None, complex_residuals: bool = False,
               skip_repeats: bool = True) -> FamilyFit:
    """Structured fit of one window, grown from ``poles`` (see the module docstring).

    Parameters
    ----------
    frf : FRFSet
    poles : ndarray of complex, shape (n,)
        Starting poles (rad/s) inside the window (may be empty).
    window : (f_lo, f_hi)
        Lines fitted (Hz).
    core : (f_lo, f_hi)
        Where new modes may be added (Hz): the window less its edges, where the residual terms act.
    max_added : int, optional
        Cap on added modes (default: the window's lines / 4, less the starting modes).
    zeta0 : float, optional
        Damping ratio a new mode starts from (default: the median of the window's modes, else 0.002).
    complex_residuals : bool
        Each FRF's residual terms with complex coefficients (a background of any phase), not only the real
        mass and stiffness lines: for data from which other modes were subtracted (:mod:`ema.unexplained`).
    skip_repeats : bool
        Refusals that end where an earlier one did do not count towards :data:`RETRIES` (:func:`_repeats`).
    """
    win = FamilyWindow(frf, window, complex_residuals)
    f, zeta = modal_from_pole(np.asarray(poles, np.complex128).reshape(-1))
    n_start = f.size
    # per output, 2 n_in n_lines equations against 2 unknowns per mode and 2 (or 4) n_in residual terms
    cap = max(0, win.n_in * win.n_lines // 4 - n_start) if max_added is None else max_added
    part, pivot = (_participations(frf, window, pole_from_modal(f, zeta)) if f.size
                   else (np.zeros((win.n_in, 0), complex), np.zeros(0, int)))
    if f.size:
        f, zeta, part, pivot = _refine(win, f, zeta, part, pivot)
    # every starting mode at a damping bound: the rank-one model does not describe the window (a 6-blade campaign's
    # 417-716 Hz window, stretched by one pole at 2.6 % damping, sent all six to 5 %). Growth and the restart only
    # repeated it (two more refinements, each to MAX_ITER: 6 of the fit's 16 s); every mode is dropped below.
    hopeless = f.size > 0 and bool(np.all(_at_bound(zeta)))
    in_core = (win.freq >= core[0]) & (win.freq <= core[1])
    lo, hi = win.freq[0], win.freq[-1]
    tried = np.zeros((win.n_lines, win.n_out), bool)    # (line, output) refused since the last mode
    refused: list[tuple[float, float]] = []             # where those trials' new modes ended (Hz, ζ)
    for _ in range(0 if hopeless else cap):
        lam = pole_from_modal(f, zeta)
        res = win.solve(lam, part)[1] if f.size else win.Y
        rc = res.reshape(2, win.n_in, win.n_lines, win.n_out)
        energy = np.where(in_core[:, None] & ~tried, np.sum(rc**2, axis=(0, 1)), -1.0)   # (n_lines, n_out)
        k, o = np.unravel_index(int(np.argmax(energy)), energy.shape)
        if energy[k, o] <= 0:
            break
        z0 = zeta0 if zeta0 is not None else float(np.median(zeta)) if zeta.size else 0.002
        new, new_pivot = normalised_participations((rc[0][:, k, o] + 1j * rc[1][:, k, o]).reshape(-1, 1))
        trial = _refine(win, np.r_[f, win.freq[k]], np.r_[zeta, z0], np.c_[part, new], np.r_[pivot, new_pivot],
                        watch=f.size, tol=TRIAL_TOL)
        if not (_kept(trial, f.size, (lo, hi)) and _explains(win, trial[0], trial[1], trial[2], f.size)):
            if _refusal_ends_growth(win, trial[0][f.size], trial[1][f.size], (k, o), tried, refused, skip_repeats):
                break
            continue
        f, zeta, part, pivot = trial
        tried[:], refused = False, []
    if f.size and not hopeless:
        f, zeta, part, pivot = _restart_participations(frf, win, window, f, zeta, part, pivot)
    # Dropped, the rest refined again, until none is left: each mode the refinements drove to a damping bound,
    # which fits the window's background (upper; a 6-blade campaign kept one at 1116.5 Hz, 1 % from every true
    # mode) or a noise spike (lower; 647.1 Hz, 3.8 % off), as _explains refuses them when grown; else the mode
    # that least explains its band's noise, if it explains less (_unexplained_modes); else the worst
    # mode whose frequency the window leaves undetermined (σ wider than the window): a pole fitted twice (a 24-blade
    # campaign's 1257.2 Hz, twice, σ 1.7e6 Hz each, 1.35 % from every true mode; design §8.58). Not σ against the
    # half-power width fζ: a dense family's real modes reach it (the synthetic family's 498.1 Hz: σ 0.44 Hz).
    while True:
        bad = _unexplained_modes(win, f, zeta, part)
        if not bad.any():
            fit = _result(win, window, f, zeta, part, pivot, n_start)
            ratio = fit.frequency_std_hz / (window[1] - window[0])
            if not np.nanmax(ratio, initial=0) > 1:
                return fit
            bad = np.arange(f.size) == np.argsort(f)[int(np.nanargmax(ratio))]
        n_start -= int(np.count_nonzero(bad[:n_start]))
        f, zeta, part, pivot = f[~bad], zeta[~bad], part[:, ~bad], pivot[~bad]
        if f.size:
            f, zeta, part, pivot = _refine(win, f, zeta, part, pivot)


def fit_weighted(frf: FRFSet, floor: np.ndarray, *args, complex_residuals: bool = False, **kwargs) -> FamilyFit:
    """:func:`fit_family` (same arguments after ``floor``) on the FRFs divided by the rank-one part of their noise
    ``floor`` (n_outputs, n_inputs; :func:`ema.fit_noise.band_floor`, :func:`ema.fit_noise.rank_one_scale`), which
    leaves the rank-one model unchanged and makes each FRF count by its noise; the shapes then again, output by
    output, with each FRF weighted by its own noise (:func:`ema.family_shapes.reweighted_residues`)."""
    weights = rank_one_scale(floor)
    fit = fit_family(replace(frf, H=frf.H / weights[:, :, None]), *args, complex_residuals=complex_residuals,
                     **kwargs)
    residues = reweighted_residues(frf, fit.window_hz, fit.poles, fit.residues * weights[None], floor,
                                   complex_residuals)
    return replace(fit, residues=residues)


def _kept(modes, r: int, span: tuple[float, float]) -> bool:
    """Does mode r of ``modes`` (f, ζ, ...) have its half-power band f(1 ± ζ) inside ``span`` (the window's lines,
    Hz), and its damping off the bounds of :data:`ZETA_BOUNDS` (seed 11's campaign grew one at 5 %, 1.9 % from
    every true mode: a pole fitting the window's background)?

    The half-power band, as the window's data must hold the peak to determine f and ζ: a 6-blade campaign's grown
    1279.6 Hz (ζ 0.85 %, 1 % off) sat 0.4 Hz from the edge, where the residual terms stand for the modes outside.
    Not the core (where trials start): the bundled campaign's 618.3 and 624.5 Hz lie between two windows' cores,
    and their trials, which converge on them (ζ 0.13 % and 0.11 %, 16 and 2 Hz inside their windows), were
    refused (§8.62)."""
    f, zeta = modes[0][r], modes[1][r]
    return bool(span[0] <= f * (1 - zeta) and f * (1 + zeta) <= span[1] and not _at_bound(zeta))


def _refusal_ends_growth(win: FamilyWindow, f: float, zeta: float, start: tuple[int, int], tried: np.ndarray,
                         refused: list[tuple[float, float]], skip_repeats: bool) -> bool:
    """Book a refused trial, started at ``start`` (line, output), whose new mode ended at (f Hz, ζ): its start goes
    into ``tried`` and, unless it repeats an earlier refusal (:func:`_repeats`, with ``skip_repeats``), the place into
    ``refused`` (both updated in place). Returns whether growth stops: more than :data:`RETRIES` places refused.
    A repeat sets aside the lines within a half-power band of its start for every output: they lead there too."""
    k, o = start
    tried[k, o] = True
    if skip_repeats and _repeats(f, zeta, refused):
        tried[np.abs(win.freq - win.freq[k]) <= f * zeta] = True
        return False
    refused.append((f, zeta))
    return len(refused) > RETRIES


def _repeats(f: float, zeta: float, refused: list[tuple[float, float]]) -> bool:
    """Did a refused trial's new mode (f Hz, ζ) end in the half-power band of an earlier refused one, both off the
    damping bounds? Then it is the same local minimum reached from a neighbouring line, and says nothing new about
    whether the window holds more modes; :func:`fit_family` does not count it towards :data:`RETRIES`.

    Why: a seed-7 36-blade campaign's 1192-1279 Hz window holds 38 true modes. Four trials in a row, from
    1218.0-1219.1 Hz, each ended at 1224.48 Hz (ζ 0.37 %) explaining less than its band's noise, and growth stopped
    at 14 modes; a later one, from 1228.9 Hz, was kept, and growth went on to 37 (design §8.67). Trials that run
    to a damping bound (the window's background) are each counted: such a refusal says the residual left there is
    not a mode."""
    return not _at_bound(zeta) and any(abs(f - g) <= g * z and not _at_bound(z) for g, z in refused)


def _unexplained_modes(win: FamilyWindow, f, zeta, part) -> np.ndarray:
    """Which modes to drop (mask): those at a damping bound or at the window's edge; else the one that least
    explains the noise of its band, if it explains less (:func:`_explains`). At the edge, the refinement's bound
    holds the frequency, not the data (a 24-blade campaign's 1257.2 Hz, 1 % from every true mode; §8.62). Why
    the last: growth tests only the new mode; a later refinement can leave an older one on a neighbour's peak
    noise (tests/ema/test_family.py: ζ 0.017 %; §8.61)."""
    bad = _at_bound(zeta) | (f <= win.freq[0]) | (f >= win.freq[-1])
    if bad.any() or not f.size:
        return bad
    solved = win.solve(pole_from_modal(f, zeta), part)[:2]
    share = np.array([_explained(win, f, zeta, part, r, solved) for r in range(f.size)])
    return (np.arange(f.size) == np.argmin(share)) & (share < 1.0)


def _restart_participations(frf: FRFSet, win: FamilyWindow, window: tuple[float, float], f: np.ndarray,
                            zeta: np.ndarray, part: np.ndarray, pivot: np.ndarray
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each mode's participation replaced by the free residues' rank-one part where that lowers the cost; then
    every parameter refined once more.

    Why: the participations of the first modes were set before the window grew, and refinement can leave
    them in a local minimum once neighbours are added (seed 11's 190.05 Hz mode: shape MAC 0.10, while the
    free residues at the same poles are rank one with MAC 0.998). One mode at a time, so that a refinement
    from scratch (about 10 s more on the bundled test) is not needed.
    """
    lam = pole_from_modal(f, zeta)
    alt, alt_pivot = _participations(frf, window, lam)
    cost = win.solve(lam, part)[0]
    part, pivot = part.copy(), pivot.copy()
    for r in range(f.size):
        trial = part.copy()
        trial[:, r] = alt[:, r]
        c = win.solve(lam, trial)[0]
        if c < cost:
            part, cost = trial, c
            pivot[r] = alt_pivot[r]
    # always: a fresh refinement moves on where the last stopped (a 6-blade campaign's noise pole, 646.9 Hz, ζ 4e-4,
    # 3.6 % off, was kept; refined again it runs to the lower bound and is dropped: design §8.52)
    return _refine(win, f, zeta, part, pivot)


def _result(win, window, f, zeta, part, pivot, n_start) -> FamilyFit:
    lam = pole_from_modal(f, zeta)
    n = f.size
    _, res, coef = win.solve(lam, part)[:3] if n else (0, None, np.zeros((0, win.n_out)))
    psi = coef[:n] + 1j * coef[n:2 * n]                   # (n, n_out)
    residues = psi[:, :, None] * part.T[:, None, :]
    # nonlinear parameters, shapes, residual terms
    n_par = n * (2 * win.n_in + 2 * win.n_out) + win.residual_cols.shape[1] * win.n_out
    f_std = np.full(n, np.nan)
    z_std = np.full(n, np.nan)
    if n:
        try:
            # The larger of two sandwich covariances, per parameter. White's, with the lines as clusters (as
            # ema.uncertainty.pole_std), sees the misfit; but a lightly damped mode's frequency rests on its one
            # or two peak lines, too few clusters for their residuals to measure the noise (seed 11: truths at
            # 2-4 σ). The second takes the meat from residuals drawn from a noise model fitted to the window.
            # Plain Gauss-Newton, one variance for all lines, held only 39-60 % of the truths within ± 2 σ.
            # Where the noise is correlated over the lines (a windowed hammer test's is: ema.line_correlation)
            # the draws are made as correlated, and their meat sums each line's score with its neighbours' over
            # the correlation's lags (nothing lies beyond them). Not Newey-West's on the residual's own scores:
            # they sum to zero at the minimum, and over a peak's few lines that bias took most of the lags' share.
            draws, rho = noise_draws(win, res)
            JJ, per = win.scores(lam, part, pivot, draws)
            u = per @ np.linalg.inv(JJ)                   # each line's score times the (symmetric) bread
            var_white = scores_variance(u[0], np.ones(1)) * win.Y.size / max(win.Y.size - n_par, 1)
            var_model = scores_variance(u[1:], np.ones_like(rho)).mean(axis=0)
            var = np.maximum(var_white, var_model)
            idx = _mode_offsets(n, win.n_in)
            # a variance that round-off left at or below 0 (a near-singular bread) is unknown, not exact
            var = np.where(var > 0, var, np.nan)
            f_std = np.sqrt(var[idx])
            z_std = np.sqrt(var[idx + 1]) * zeta   # d ζ = ζ d log ζ
        except np.linalg.LinAlgError:
            pass
    order = np.argsort(f)
    return FamilyFit(window_hz=(float(window[0]), float(window[1])), poles=lam[order], residues=residues[order],
                     frequency_std_hz=f_std[order], damping_std=z_std[order], n_start=n_start)
