"""PCA pattern sampler: synthetic contact patterns from a few measured ones (paper §3.1, Eqs. 25–32; §6.1).

The known joints' grayscale maps of one flank side (L or R), sampled on the grid (:mod:`identify.film`), are
the rows of X (Eq. 25). scikit-learn's :class:`~sklearn.decomposition.PCA` centres them (Eqs. 26–27) and
finds the principal directions V by SVD (Eq. 28); the coefficients are Z = X_cent V (Eq. 29). Each
component's coefficients get a sample mean μ_z and standard deviation σ_z (Eq. 30, ``ddof=1``). A synthetic
coefficient vector is

    κ_z = μ_z + σ_z · scale · r_z,   r_z ~ N(0, 1) independent per component z and per pattern,   (Eq. 31)

its map X_syn = μ + V κ (Eq. 32), and its contact grid ``X_syn > threshold``.

Eq. 31's r: per component, not one scalar per pattern. The paper calls r "a scalar random variable". One r
shared by all components would put every synthetic map on the line μ + t · Σ_z σ_z v_z: a one-parameter family
that cannot show the independent variations of the components. The model of §3.1 is a Gaussian per component
(Eq. 30 gives each its own μ_z, σ_z), and PCA coefficients are uncorrelated over the known set. Independent
r_z give coefficients with exactly those per-component means and (at scale 1) standard deviations, and no
correlation. Each κ_z is still built from a scalar r, so Eq. 31 holds as written, component by component.

Staying in the measured family
------------------------------
A synthetic grid is accepted only if

* it is neither empty nor full, and its contacting nodes are not all on one line (so every left × right
  pair is a valid :class:`rom.contact.ContactPattern`), and
* its contact area fraction a (share of nodes in contact) lies in the **known range widened by scale**:
  [a_min − w, a_max + w] ∩ [0, 1], where a_min and a_max are the extreme area fractions of the known maps
  thresholded the same way (``X > threshold``), and w = max(scale · s_a, 1 / n_nodes), with s_a the known
  fractions' sample standard deviation (``ddof=1``). Scale widens the spread of the coefficients by its
  factor (Eq. 31) and the accepted range by as many standard deviations of the known areas. The floor of one
  node keeps the range open when every known map has the same area.

A rejected draw is replaced by a new one (the next draws of the same generator). After ``max_draws`` draws per
requested pattern without enough accepted ones, the sampler gives up with an :class:`IdentifyError`.

Both flank sides at once, and their left × right pairs: :func:`identify.synthetic.sample_patterns`.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.decomposition import PCA
from sklearn.utils.validation import check_is_fitted

from .errors import IdentifyError
from .film_image import otsu_threshold

__all__ = [
    "PatternSampler",
    "SideSample",
    "draw_coefficients",
    "non_collinear",
    "non_collinear_batch",
    "N_PATTERNS",
]

#: Defaults of paper §6.1: 10 synthetic patterns per flank side, so 10 × 10 = 100 left × right pairs.
N_PATTERNS = 10


def draw_coefficients(
    mean: np.ndarray, std: np.ndarray, scale: float, n: int, rng: np.random.Generator
) -> np.ndarray:
    """Synthetic PCA coefficient vectors, Eq. 31: κ_z = μ_z + σ_z · scale · r_z with r_z ~ N(0, 1).

    Parameters
    ----------
    mean, std : ndarray of float64, shape (k,)
        μ_z and σ_z of Eq. 30.
    scale : float
        The paper's Scale (≥ 0).
    n : int
        Number of vectors.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of float64, shape (n, k)
        Row p is pattern p's κ; r is drawn row by row (n × k standard normals, independent per component).
    """
    r = rng.standard_normal((n, np.size(mean)))
    return np.asarray(mean, np.float64) + np.asarray(std, np.float64) * scale * r


def non_collinear(grid: np.ndarray) -> bool:
    """At least 3 contacting nodes, not all on one line."""
    return bool(non_collinear_batch(np.asarray(grid, bool)[None])[0])


def non_collinear_batch(grids: np.ndarray) -> np.ndarray:
    """:func:`non_collinear` of each grid of ``grids`` (n, rows, cols), shape (n,), in exact integer arithmetic.

    The contacting nodes are all on one line exactly when each one's cross product with the line through the first
    and the last of them (row-major order) is 0. Vectorised because the contact posterior asks it of every
    proposal: one rank computation per grid took 70 % of a joint's sampling.
    """
    g = np.asarray(grids, bool)
    n, rows, cols = g.shape
    flat = g.reshape(n, -1)
    first = np.argmax(flat, axis=1)
    last = rows * cols - 1 - np.argmax(flat[:, ::-1], axis=1)
    r, c = np.divmod(np.arange(rows * cols), cols)
    r0, c0, r1, c1 = (a[:, None] for a in (first // cols, first % cols, last // cols, last % cols))
    cross = (r[None] - r0) * (c1 - c0) - (c[None] - c0) * (r1 - r0)
    return (flat.sum(axis=1) >= 3) & np.any(flat & (cross != 0), axis=1)


def _check_maps(X, grid) -> tuple[np.ndarray, tuple[int, int]]:
    """X as (n, rows·cols) float64 and the grid shape; IdentifyError for shapes, values or sizes refused."""
    if isinstance(X, np.ndarray):
        arr = X
    else:
        items = [np.asarray(x.gray if hasattr(x, "gray") else x) for x in X]
        shapes = sorted({x.shape for x in items})
        if len(shapes) > 1:
            raise IdentifyError(f"known maps must all have one grid shape, got shapes {', '.join(map(str, shapes))}")
        arr = np.stack(items) if items else np.empty((0, 0))
    if arr.dtype.kind not in "biuf":
        raise IdentifyError(f"known maps must be numeric, got dtype {arr.dtype}")
    if arr.ndim == 3:
        g = tuple(arr.shape[1:])
        if grid is not None and tuple(grid) != g:
            raise IdentifyError(f"known maps have grid shape {g}, but grid={tuple(grid)} was given")
    elif arr.ndim == 2:
        if grid is None:
            raise IdentifyError(f"known maps of shape {arr.shape} (n, rows·cols) need grid=(rows, cols)")
        g = tuple(int(x) for x in grid)
        if len(g) != 2 or g[0] * g[1] != arr.shape[1]:
            raise IdentifyError(f"grid={tuple(grid)} does not match {arr.shape[1]} values per map")
    else:
        raise IdentifyError(f"known maps must have shape (n, rows, cols) or (n, rows·cols), got {arr.shape}")
    if arr.shape[0] < 2:
        raise IdentifyError(f"PCA needs at least 2 known maps, got {arr.shape[0]}")
    if min(g) < 1 or g[0] * g[1] < 2:
        raise IdentifyError(f"grid shape {g} has fewer than 2 nodes")
    X2 = arr.reshape(arr.shape[0], -1).astype(np.float64)
    if not np.isfinite(X2).all():
        raise IdentifyError("known maps hold non-finite values (NaN or inf)")
    return X2, g


@dataclass(frozen=True, eq=False)
class SideSample:
    """Synthetic patterns of one flank side, from :meth:`PatternSampler.sample`.

    Attributes
    ----------
    kappa : ndarray of float64, shape (n, k)
        Accepted coefficient vectors (Eq. 31).
    gray : ndarray of float64, shape (n, rows, cols)
        Reconstructed maps μ + V κ (Eq. 32).
    contact : ndarray of bool, shape (n, rows, cols)
        ``gray > threshold``.
    n_draws : int
        Coefficient vectors drawn in all, accepted or not.
    """

    kappa: np.ndarray
    gray: np.ndarray
    contact: np.ndarray
    n_draws: int


class PatternSampler(BaseEstimator):
    """PCA of one flank side's known grayscale maps and Gaussian sampling of synthetic patterns (Eqs. 25–32).

    Parameters
    ----------
    n_components : int or None
        Principal components kept, 1..n_known − 1. None keeps n_known − 1, the rank of the centred data (a
        further component has zero variance and could not vary a pattern).
    n_patterns : int
        Patterns :meth:`sample` returns by default. Default 10 (paper §6.1).
    scale : float
        Eq. 31's Scale, ≥ 0: the spread of the coefficients in units of their known standard deviations.
        Default 1.
    threshold : float or None
        Contact threshold on the maps' scale: contact where the map exceeds it. For maps from
        :mod:`identify.film` (darkness, 1 = black), the known films' ``FilmMap.level`` are the natural choice
        (e.g. their mean). None: Otsu's threshold (:func:`identify.film_image.otsu_threshold`) on all values of the
        known maps.
    max_draws : int
        Draws allowed per requested pattern before :meth:`sample` gives up. Default 100.
    grid : (int, int) or None
        Grid shape, needed only when X comes flat, (n, rows·cols).
    random_state : int, numpy.random.Generator or None
        Seed of :meth:`sample`. An int (or None) starts a fresh generator on every call, so the same seed gives
        the same patterns; a Generator is used as is and advances.

    Attributes
    ----------
    pca_ : sklearn.decomposition.PCA
        The fitted PCA (``svd_solver="full"``).
    mean_ : ndarray, shape (d,)
        μ, the mean map (Eq. 26), d = rows · cols.
    components_ : ndarray, shape (k, d)
        Vᵀ: the principal directions as rows (Eq. 28), sklearn's sign convention.
    scores_ : ndarray, shape (n_known, k)
        Z = X_cent V (Eq. 29).
    score_mean_, score_std_ : ndarray, shape (k,)
        μ_z and σ_z (Eq. 30; σ with n − 1). μ_z is zero up to rounding (the data are centred), kept as in Eq. 30.
    threshold_ : float
    known_fractions_ : ndarray, shape (n_known,)
        Area fraction of each known map at ``threshold_``.
    fraction_range_ : (float, float)
        Accepted synthetic area fractions (module docstring).
    grid_shape_ : (int, int)
    n_features_in_ : int
        d.
    """

    def __init__(
        self,
        n_components: int | None = None,
        n_patterns: int = N_PATTERNS,
        scale: float = 1.0,
        threshold: float | None = None,
        max_draws: int = 100,
        grid: tuple[int, int] | None = None,
        random_state: int | np.random.Generator | None = None,
    ) -> None:
        self.n_components = n_components
        self.n_patterns = n_patterns
        self.scale = scale
        self.threshold = threshold
        self.max_draws = max_draws
        self.grid = grid
        self.random_state = random_state

    def _check_params(self, n_known: int) -> None:
        def is_int(x) -> bool:
            return isinstance(x, numbers.Integral) and not isinstance(x, bool)

        k = self.n_components
        if k is not None and not (is_int(k) and 1 <= k <= n_known - 1):
            raise IdentifyError(f"n_components must be an integer in 1..{n_known - 1} (n_known − 1) or None, "
                                f"got {k!r}")
        if not (is_int(self.n_patterns) and self.n_patterns >= 1):
            raise IdentifyError(f"n_patterns must be a positive integer, got {self.n_patterns!r}")
        if not (isinstance(self.scale, numbers.Real) and math.isfinite(self.scale) and self.scale >= 0):
            raise IdentifyError(f"scale must be a finite number ≥ 0, got {self.scale!r}")
        t = self.threshold
        if t is not None and not (isinstance(t, numbers.Real) and math.isfinite(t)):
            raise IdentifyError(f"threshold must be a finite number or None, got {t!r}")
        if not (is_int(self.max_draws) and self.max_draws >= 1):
            raise IdentifyError(f"max_draws must be a positive integer, got {self.max_draws!r}")

    def fit(self, X, y=None) -> PatternSampler:
        """Fit the PCA and the coefficient statistics on the known maps of one flank side.

        Parameters
        ----------
        X : array_like, shape (n_known, rows, cols) or (n_known, rows·cols); or a sequence of FilmMap
            Known grayscale maps (``FilmMap.gray``), n_known ≥ 2, all on one grid.
        y : ignored

        Returns
        -------
        self

        Raises
        ------
        IdentifyError
            Fewer than 2 maps, maps of different grid shapes, non-finite values, or a bad hyper-parameter.
        """
        X2, g = _check_maps(X, self.grid)
        n = X2.shape[0]
        self._check_params(n)
        k = self.n_components if self.n_components is not None else n - 1
        pca = PCA(n_components=k, svd_solver="full").fit(X2)
        Z = pca.transform(X2)  # Eq. 29 (sklearn centres with the mean of Eq. 26 first, Eq. 27)
        thr = float(self.threshold) if self.threshold is not None else _otsu_or_error(X2)
        fractions = (X2 > thr).mean(axis=1)
        w = max(self.scale * float(np.std(fractions, ddof=1)), 1.0 / X2.shape[1])
        self.pca_ = pca
        self.mean_ = pca.mean_
        self.components_ = pca.components_
        self.scores_ = Z
        self.score_mean_ = Z.mean(axis=0)
        self.score_std_ = Z.std(axis=0, ddof=1)
        self.threshold_ = thr
        self.known_fractions_ = fractions
        self.fraction_range_ = (max(0.0, float(fractions.min()) - w), min(1.0, float(fractions.max()) + w))
        self.grid_shape_ = g
        self.n_features_in_ = X2.shape[1]
        return self

    def _flat(self, X) -> np.ndarray:
        check_is_fitted(self)
        a = np.asarray(X, dtype=np.float64)
        if a.ndim == 3:
            a = a.reshape(a.shape[0], -1)
        if a.ndim != 2 or a.shape[1] != self.n_features_in_:
            raise IdentifyError(f"maps must have shape (n, {self.grid_shape_[0]}, {self.grid_shape_[1]}) or "
                                f"(n, {self.n_features_in_}), got {np.shape(X)}")
        return a

    def transform(self, X) -> np.ndarray:
        """PCA coefficients Z = (X − μ) V (Eqs. 27, 29) of maps, shape (n, k)."""
        return self.pca_.transform(self._flat(X))

    def inverse_transform(self, kappa) -> np.ndarray:
        """Maps μ + V κ (Eq. 32) of coefficient vectors ``kappa`` (n, k), shape (n, rows, cols)."""
        check_is_fitted(self)
        kappa = np.atleast_2d(np.asarray(kappa, dtype=np.float64))
        if kappa.shape[1] != self.components_.shape[0]:
            raise IdentifyError(f"coefficient vectors must have {self.components_.shape[0]} entries, got "
                                f"{kappa.shape[1]}")
        return (self.mean_ + kappa @ self.components_).reshape(-1, *self.grid_shape_)

    def accepts(self, contact: np.ndarray) -> np.ndarray:
        """Whether synthetic grids stay in the measured family (module docstring), shape (n,).

        Parameters
        ----------
        contact : ndarray of bool, shape (n, rows, cols)
        """
        check_is_fitted(self)
        c = np.asarray(contact, dtype=bool).reshape(-1, *self.grid_shape_)
        a = c.mean(axis=(1, 2))
        lo, hi = self.fraction_range_
        ok = (a >= lo) & (a <= hi) & c.any(axis=(1, 2)) & ~c.all(axis=(1, 2))
        return ok & non_collinear_batch(c)

    def sample(self, n_patterns: int | None = None) -> SideSample:
        """Draw synthetic patterns (Eqs. 31–32), redrawing those outside the measured family.

        Parameters
        ----------
        n_patterns : int, optional
            How many; default ``self.n_patterns``.

        Returns
        -------
        SideSample

        Raises
        ------
        IdentifyError
            If fewer than ``n_patterns`` are accepted within ``max_draws · n_patterns`` draws.
        """
        check_is_fitted(self)
        n = self.n_patterns if n_patterns is None else n_patterns
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1:
            raise IdentifyError(f"n_patterns must be a positive integer, got {n!r}")
        rng = np.random.default_rng(self.random_state)
        limit = self.max_draws * n
        kept: list[np.ndarray] = []
        drawn = 0
        # Draw in batches of the missing count: the stream of r vectors, and so the result, depends on the seed
        # only (candidates are accepted in draw order).
        while len(kept) < n and drawn < limit:
            m = min(n - len(kept), limit - drawn)
            kappa = draw_coefficients(self.score_mean_, self.score_std_, self.scale, m, rng)
            drawn += m
            gray = self.inverse_transform(kappa)
            kept.extend(kappa[self.accepts(gray > self.threshold_)])
        if len(kept) < n:
            lo, hi = self.fraction_range_
            raise IdentifyError(
                f"only {len(kept)} of {n} synthetic patterns stayed in the measured family (area fraction in "
                f"[{lo:.3f}, {hi:.3f}], not empty or full, not on a line) after {drawn} draws; lower scale "
                f"(now {self.scale}) or check the threshold ({self.threshold_:.4g})"
            )
        kappa = np.array(kept[:n])
        gray = self.inverse_transform(kappa)
        return SideSample(kappa=kappa, gray=gray, contact=gray > self.threshold_, n_draws=drawn)


def _otsu_or_error(X2: np.ndarray) -> float:
    try:
        return otsu_threshold(X2)
    except IdentifyError:
        raise IdentifyError("known maps are uniform (every value equal): no automatic threshold; "
                            "pass threshold=") from None
