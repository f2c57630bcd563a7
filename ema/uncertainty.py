"""Standard deviations of identified poles: the linearised covariance of the least-squares fit (issue 31).

The poles are the minimiser of the variable-projection misfit of :func:`ema.varpro.refine_poles`: residues and
residual terms eliminated, natural frequencies and damping ratios free. Near that minimum the parameters' covariance is
the sandwich ``(JᵀJ)⁻¹ (Σ_l J_lᵀ r_l r_lᵀ J_l) (JᵀJ)⁻¹`` (J: the residual's Jacobian in the frequencies (Hz)
and damping ratios; r: the residual; l: the spectral lines, each a cluster of its real and imaginary parts in
every FRF; White's heteroscedasticity-consistent estimator with a degrees-of-freedom factor). It needs no
noise model: a test's noise is larger at the resonances (a share of |H|) than between them, where the plain
``σ² (JᵀJ)⁻¹`` with one σ² for all lines would understate the poles' scatter. Where the noise is correlated
over neighbouring lines (a windowed hammer test's), each variance is raised by the factor that correlation
gives a noise model's sandwich (:func:`_line_factor`, :mod:`ema.line_correlation`); 1 for white noise. Each
mode is taken on its local window (:func:`ema.lsfd.local_windows`) with the poles that share it, as the
refinement does: a dense family's neighbours enter the covariance, the far modes only through the residual
terms.

What it does not hold: bias, e.g. from a missed neighbour or a residual term that does not absorb the rest of
the band. :func:`order_spread` measures part of that, the scatter of the mode's poles over the model orders
of its stabilization diagram; :func:`with_std` adds the two in quadrature. The calibration against a known
truth is measured in docs/ema.md ("Uncertainty").
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .fit_noise import noise_sd
from .frf import FRFSet
from .line_correlation import line_correlation, scores_variance
from .lsfd import local_windows
from .modal import ModalModel
from .stabilization import StabilizationDiagram
from .varpro import VarPro

__all__ = ["pole_std", "order_spread", "with_std"]


def pole_std(frf: FRFSet, poles: np.ndarray, band: tuple[float, float], residuals: bool = True,
             max_size: float = 4e7) -> tuple[np.ndarray, np.ndarray]:
    """Standard deviation of each pole's natural frequency and damping ratio.

    Parameters
    ----------
    frf : FRFSet
        The FRFs the poles were fitted to.
    poles : ndarray of complex, shape (n_modes,)
        Continuous-time poles (rad/s), e.g. ``ModalModel.poles``.
    band : (f_lo, f_hi) in Hz
        The fitted band (the local windows are clipped to it).
    residuals : bool
        Residual terms in each window's model, as in the fit.
    max_size : float
        Leave a mode's standard deviations NaN when its window's Jacobian would exceed this many entries (as
        :func:`ema.varpro.refine_poles` skips such a refinement): a very wide window, e.g. of a heavily damped
        spurious pole, holds the whole band's modes.

    Returns
    -------
    frequency_std_hz, damping_std : ndarray of float64, shape (n_modes,)
        NaN for a mode whose window has too few lines for its poles, or whose Jacobian is singular.
    """
    poles = np.asarray(poles, dtype=np.complex128).reshape(-1)
    f_std = np.full(poles.size, np.nan)
    z_std = np.full(poles.size, np.nan)
    for r, item in enumerate(local_windows(poles, frf, band)):
        if item is None:
            continue
        window, near = item
        i = int(np.searchsorted(near, r))
        var = _variance(frf, poles[near], window, residuals, max_size)
        if var is not None:
            f_std[r], z_std[r] = np.sqrt(var[i]), np.sqrt(var[near.size + i])
    return f_std, z_std


def _variance(frf: FRFSet, lam: np.ndarray, window: tuple[float, float], residuals: bool,
              max_size: float) -> np.ndarray | None:
    """Variances of (f_1..f_n [Hz], ζ_1..ζ_n) on one window (the sandwich of the module notes), or None."""
    vp = VarPro.of(frf, window, residuals, lam.size)
    if vp.Yr.size * 2 * lam.size > max_size:
        return None
    res, c, Qa = vp.evaluate(lam)
    J = vp.jacobian(lam, c, Qa)
    n_f, k = vp.f.size, res.shape[1]
    dof = res.size - J.shape[1] - Qa.shape[1] * k
    if dof <= 0:
        return None
    # column scaling keeps the normal matrix well conditioned (frequencies in Hz, damping ratios ~1e-3)
    scale = np.linalg.norm(J, axis=0)
    if not np.all(scale > 0):
        return None
    Js = J / scale
    try:
        bread = np.linalg.inv(Js.T @ Js)
    except np.linalg.LinAlgError:
        return None
    # White's: one cluster per spectral line, its real and imaginary rows in every compressed column
    g = (Js * res.ravel()[:, None]).reshape(2, n_f, k, -1).sum(axis=(0, 2))
    var = scores_variance(g @ bread, np.ones(1)) * (res.size / dof) * _line_factor(Js, res, vp.Yr - res, bread)
    var /= scale**2
    return var if np.all(np.isfinite(var)) and np.all(var >= 0) else None


def _line_factor(Js: np.ndarray, res: np.ndarray, fitted: np.ndarray, bread: np.ndarray) -> np.ndarray:
    """How much the noise's correlation over the lines raises each parameter's variance: the sandwich with a noise
    model's meat, correlated over the lines as the residual is (:func:`ema.line_correlation.line_correlation`),
    over the same with independent lines; 1 for white noise. σ per value from :func:`ema.fit_noise.noise_sd` (a
    floor per column and a share of the fitted response), columns independent.

    White's estimator takes each line as a cluster of its own. A windowed hammer test's noise is correlated over
    the lines (lag one 0.6-0.7 on the rig), and there White's held the scatter of a mode 0.3 % from its neighbour
    at 0.42-0.61 of the Monte Carlo's (tests/ema/test_uncertainty.py). Newey-West's lags over the residual's own
    scores did little better (0.51-0.66): at the minimum those scores sum to zero, and a peak spans few lines.
    A ratio, not the model's own sandwich: its level overstated the white-noise scatter by up to 1.5 times.

    ``Js`` (2 n_f k, p): the scaled Jacobian, rows (re/im, line, column); ``res``, ``fitted``: (2 n_f, k).
    """
    n_f, k = res.shape[0] // 2, res.shape[1]
    r, y = res.reshape(2, n_f, k), fitted.reshape(2, n_f, k)
    sd = noise_sd(r, y, axis=0)                                                  # (n_f, k), each part
    rho, _ = line_correlation(r / sd, axis=1)
    if rho.size == 1:
        return np.ones(Js.shape[1])
    u = np.moveaxis(Js.reshape(2, n_f, k, -1) * sd[None, :, :, None], 2, 1) @ bread
    white = scores_variance(u, np.ones(1)).sum(axis=(0, 1))
    return scores_variance(u, rho).sum(axis=(0, 1)) / np.where(white > 0, white, np.inf)


def order_spread(frequencies_hz: np.ndarray, damping_ratio: np.ndarray, diagram) -> np.ndarray:
    """Scatter (Hz) of each mode's poles over the upper half of the model orders that hold it.

    Parameters
    ----------
    frequencies_hz, damping_ratio : ndarray, shape (n_modes,)
        The selected modes.
    diagram : ema.stabilization.StabilizationDiagram
        The poles of every model order.

    Returns
    -------
    ndarray of float64, shape (n_modes,)
        The standard deviation of the frequencies of the diagram's poles within the mode's half-power
        half-bandwidth (ζ f) and nearer to it than half the distance to its nearest selected neighbour, over
        the upper half of their orders; 0 where fewer than 3 poles qualify.
    """
    f = np.asarray(frequencies_hz, dtype=np.float64)
    out = np.zeros(f.size)
    for i, fi in enumerate(f):
        others = np.delete(f, i)
        tol = min(float(damping_ratio[i]) * fi, np.min(np.abs(others - fi)) / 2 if others.size else np.inf)
        near = np.abs(diagram.frequencies_hz - fi) < tol
        if np.count_nonzero(near) < 3:
            continue
        top = near & (diagram.order >= np.median(diagram.order[near]))
        if np.count_nonzero(top) >= 3:
            out[i] = float(np.std(diagram.frequencies_hz[top]))
    return out


def with_std(frf: FRFSet, model: ModalModel, band: tuple[float, float], diagram: StabilizationDiagram) -> ModalModel:
    """The model with each mode's standard deviations: the fit's covariance (:func:`pole_std`) and the scatter over
    the model orders (:func:`order_spread`), added in quadrature for the frequencies.

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        At least one mode.
    band : (f_lo, f_hi)
        Hz, the band of the model's fit.
    diagram : StabilizationDiagram
        The diagram the modes were selected from.
    """
    f_std, z_std = pole_std(frf, model.poles, band)
    f_std = np.hypot(f_std, order_spread(model.frequencies_hz, model.damping_ratio, diagram))
    return replace(model, frequency_std_hz=f_std, damping_std=z_std)
