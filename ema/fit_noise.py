"""The two-part noise model of an FRF fit's residual: an additive floor per FRF and a share of the response.

:func:`noise_model` estimates it from residual and model powers (used by :mod:`ema.unexplained` to find lines that
noise alone does not explain); :func:`noise_draws` draws residuals from it for the sandwich standard deviations of
a family window (:mod:`ema.family`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["noise_draws", "noise_model", "N_DRAWS", "STRONG"]

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


def noise_draws(win, res: np.ndarray, n_draws: int = N_DRAWS) -> np.ndarray:
    """Residuals drawn from the window's noise model, shape (n_draws, rows, n_out), from a fixed seed.

    The model of :func:`ema.unexplained.unexplained_lines`, fitted to the window's own residual ``res`` (rows,
    n_out; from :meth:`ema.family.FamilyWindow.solve`): an additive floor per FRF (the median residual power)
    and a share of the fitted response (from the strong values). ``win``: the :class:`ema.family.FamilyWindow`.
    """
    shape = (2, win.n_in, win.n_lines, win.n_out)
    r, fitted = res.reshape(shape), (win.Y - res).reshape(shape)
    P = r[0] ** 2 + r[1] ** 2
    M = fitted[0] ** 2 + fitted[1] ** 2
    floor, share = noise_model(P, M, axis=1)
    sd = np.sqrt((floor + share * M) / 2)[None]                       # each of the real and imaginary parts
    rng = np.random.default_rng(0)
    return (sd * rng.standard_normal((n_draws, *shape))).reshape(n_draws, -1, win.n_out)
