"""The noise of FRFs: a two-part model of a fit's residual, and each FRF's noise floor from the data alone.

:func:`noise_model` estimates an additive floor per FRF and a share of the response from residual and model
powers (used by :mod:`ema.unexplained` to find lines that noise alone does not explain); :func:`noise_draws` draws
residuals from it for the sandwich standard deviations of a family window (:mod:`ema.family`);
:func:`difference_floor` estimates each FRF's noise level from its fourth differences over the lines, with no model.
"""

from __future__ import annotations

import numpy as np

from .line_correlation import correlate_lines, line_correlation

__all__ = ["band_floor", "difference_floor", "noise_draws", "noise_model", "noise_scale", "noise_sd",
           "rank_one_scale", "N_DRAWS", "STRONG"]

#: Residual draws of the noise-model part of a family fit's standard deviations (:func:`noise_draws`).
N_DRAWS = 32
#: A model value counts as strong, for the multiplicative noise share, where its power is this many times the
#: FRF's additive floor (the floor then adds at most 1 % to the ratio).
STRONG = 100.0


def noise_model(P: np.ndarray, M: np.ndarray, axis: int) -> tuple[np.ndarray, float]:
    """The two-part FRF noise model from residual powers ``P`` and model powers ``M`` (same shape).

    Returns the additive floor per FRF, ``median |R|² / ln 2`` along the lines' ``axis`` (kept, so it broadcasts;
    the median of a complex Gaussian's power is ln 2 times its variance), and the share of the response,
    ``median |R|² / |Ĥ|² / ln 2`` over the values at least :data:`STRONG` times the floor (0 if none).
    """
    floor = np.maximum(np.median(P, axis=axis, keepdims=True) / np.log(2), np.finfo(float).tiny)
    strong = M >= STRONG * floor
    share = float(np.median(P[strong] / M[strong]) / np.log(2)) if strong.any() else 0.0
    return floor, share


def difference_floor(H: np.ndarray) -> np.ndarray:
    """Each FRF's noise standard deviation from its fourth differences over the lines, with no model.

    A difference-based variance estimator (Gasser, Sroka & Jennen-Steinmetz, Biometrika 1986), of fourth order:
    for white noise of variance σ² on a response smooth at the line spacing, the fourth difference
    ``H[l−2] − 4 H[l−1] + 6 H[l] − 4 H[l+1] + H[l+2]`` has variance 70 σ², and its median power is ln 2 times
    that (complex Gaussian); the median leaves out the resonance peaks, where the response itself bends within
    a few lines. Fourth, not second, differences: off resonance the second difference of the response itself
    lifted the estimate by 1.3-1.8 times at noise 1e-5 to 1e-6 of the peak (five modes at 0.3 % damping, 0.25 Hz
    lines); the fourth, by 1.05-1.09 (``tests/ema/test_fit_noise.py``). Why not the residual of a modal fit
    (:func:`noise_model`): that floor holds whatever the fit misses as well; on a 24-blade test its rank-one form
    was 10^0.83 times this one's on average, spread 10^0.56 over the FRFs, and weighted by it, the families fit
    found none of a group of weak modes that only the quiet FRFs see (design §8.61).

    Parameters
    ----------
    H : ndarray of complex, shape (n_outputs, n_inputs, n_lines)
        Evenly spaced lines.

    Returns
    -------
    ndarray of float64, shape (n_outputs, n_inputs)
        σ per FRF (FRF units), at least the smallest positive float; ones (no weighting) under five lines.
    """
    if H.shape[2] < 5:
        return np.ones(H.shape[:2])
    d = H[:, :, :-4] - 4.0 * H[:, :, 1:-3] + 6.0 * H[:, :, 2:-2] - 4.0 * H[:, :, 3:-1] + H[:, :, 4:]
    power = np.median(d.real**2 + d.imag**2, axis=2) / (70.0 * np.log(2))
    return np.sqrt(np.maximum(power, np.finfo(float).tiny))


def band_floor(frf, band: tuple[float, float]) -> np.ndarray:
    """Each FRF's noise σ (FRF units) from :func:`difference_floor` over the valid lines of ``band`` (Hz); shape
    (n_outputs, n_inputs). Over a whole band, not a window: the median then falls off the resonances, which in a
    dense family's window fill most lines and lift the fourth differences of the strong FRFs."""
    sel = frf.valid_lines() & (frf.freq_hz >= band[0]) & (frf.freq_hz <= band[1]) & (frf.freq_hz > 0)
    return difference_floor(frf.H[:, :, sel])


def rank_one_scale(floor: np.ndarray) -> np.ndarray:
    """The nearest ``a_o b_i`` to a per-FRF noise ``floor`` (n_outputs, n_inputs) in log scale: each FRF's weight
    in a structured fit.

    Dividing the FRFs by it makes their noise about equal, so that a mode only a few quiet FRFs see (a disk mode
    at the blade tips, 10^4 times under the strong FRFs' noise) counts by its own noise. The rank-one residues
    ``ψ l^T`` absorb a rank-one weighting exactly (ψ_o scales by a_o, l_i by b_i), so the fit's model is unchanged.
    """
    lg = np.log(floor)
    return np.exp(lg.mean(axis=1, keepdims=True) + lg.mean(axis=0, keepdims=True) - lg.mean())


def noise_scale(frf, band: tuple[float, float]) -> np.ndarray:
    """:func:`rank_one_scale` of :func:`band_floor`; shape (n_outputs, n_inputs)."""
    return rank_one_scale(band_floor(frf, band))


def noise_sd(r: np.ndarray, fitted: np.ndarray, axis: int) -> np.ndarray:
    """σ of each real and of each imaginary value under :func:`noise_model`, fitted to the residual ``r``.

    ``r``, ``fitted``: residual and model, each shaped (2, ...) with the real parts first; ``axis``: the lines' axis
    of one part. Returns shape ``r.shape[1:]``."""
    M = fitted[0] ** 2 + fitted[1] ** 2
    floor, share = noise_model(r[0] ** 2 + r[1] ** 2, M, axis=axis)
    return np.sqrt((floor + share * M) / 2)


def noise_draws(win, res: np.ndarray, n_draws: int = N_DRAWS) -> tuple[np.ndarray, np.ndarray]:
    """Residuals drawn from the window's noise model, shape (n_draws, rows, n_out), from a fixed seed, and the
    correlation over the lines they were drawn with (:func:`ema.line_correlation.line_correlation`'s ``rho``).

    The model of :func:`ema.unexplained.unexplained_lines`, fitted to the window's own residual ``res`` (rows,
    n_out; from :meth:`ema.family_window.FamilyWindow.solve`): an additive floor per FRF (the median residual power)
    and a share of the fitted response (from the strong values); correlated over the lines as the residual, each
    value divided by its σ, is (white noise: independent lines). ``win``: the
    :class:`ema.family_window.FamilyWindow`.
    """
    shape = (2, win.n_in, win.n_lines, win.n_out)
    r = res.reshape(shape)
    sd = noise_sd(r, (win.Y - res).reshape(shape), axis=1)             # (n_in, n_lines, n_out)
    rho, _ = line_correlation(r / sd, axis=2)
    rng = np.random.default_rng(0)
    white = rng.standard_normal((n_draws, *shape))
    white = np.moveaxis(correlate_lines(np.moveaxis(white, 3, -1), rho), -1, 3)
    return (sd * white).reshape(n_draws, -1, win.n_out), rho
