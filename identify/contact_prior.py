"""A continuous prior over a joint's contact pattern, from the known films (beyond the paper; Eqs. 30–32).

Per flank side the pattern is ``map > level`` with ``map = μ + Σ_z κ_z v_z`` (Eq. 32). The parameters are
standard normal under the prior:

* ``κ_z = μ_z + scale · σ_z · θ_z`` for the first ``k`` PCA components (Eq. 30's Gaussian, widened by the
  paper's Scale as in Eq. 31); ``k`` defaults to enough components for 95 % of the films' variance;
* ``level = ℓ̄ + s_ℓ · θ_ℓ``: ℓ̄ the films' mean contact level, and s_ℓ (times ``scale``) the spread a joint's
  level may have. Each film was read at its own level (how the lab calibrated it), so their scatter is one
  part. The other is the level that would give each film's own contact area on the mean map: joints seated
  deeper or clamped harder have larger areas for the same pressure shape, and the level is how a map shows
  that. s_ℓ² is the sum of both variances, pooled over the two flanks (their degrees of freedom as weights).

θ is laid out ``[θ_L (k_L), θ_R (k_R), θ_ℓL, θ_ℓR]``.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .errors import IdentifyError
from .sampler import PatternSampler, non_collinear_batch

__all__ = ["ContactPrior", "contact_prior", "held_out_projections"]

#: Default share of the films' variance the prior's components keep (issue 32: "enough for 95 %").
DEFAULT_VARIANCE = 0.95

#: Parameter vectors mapped to grids at a time (:meth:`ContactPrior.grids`).
_GRID_BLOCK = 2048


@dataclass(frozen=True, eq=False)
class ContactPrior:
    """The prior of :func:`contact_prior` and the map from its parameters θ to contact grids.

    Attributes
    ----------
    mean : ndarray, shape (2, n_nodes)
        Mean map per side (L, R) on the darkness scale of :class:`identify.FilmMap`.
    basis : ndarray, shape (2, k_max, n_nodes)
        Components times their prior standard deviation (``scale · σ_z · v_z``); rows past a side's ``k`` are 0.
    n_components : tuple of int
        k_L, k_R.
    level, level_std : ndarray, shape (2,)
        Prior mean and standard deviation of each side's contact level.
    grid_shape : tuple of int
        (rows, cols).
    scale : float
    """

    mean: np.ndarray
    basis: np.ndarray
    n_components: tuple[int, int]
    level: np.ndarray
    level_std: np.ndarray
    grid_shape: tuple[int, int]
    scale: float

    @property
    def n_dim(self) -> int:
        """Number of parameters: k_L + k_R + 2 levels."""
        return int(sum(self.n_components)) + 2

    def excess(self, theta) -> np.ndarray:
        """Map minus level per node, shape (n, 2, n_nodes), for parameters ``theta`` of shape (n, n_dim)."""
        t = np.atleast_2d(np.asarray(theta, np.float64))
        if t.shape[1] != self.n_dim:
            raise IdentifyError(f"theta must have {self.n_dim} columns, got shape {t.shape}")
        kL, kR = self.n_components
        out = np.empty((t.shape[0], 2, self.mean.shape[1]))
        for side, cols in ((0, slice(0, kL)), (1, slice(kL, kL + kR))):
            coef = t[:, cols]
            out[:, side] = self.mean[side] + coef @ self.basis[side, : coef.shape[1]]
            out[:, side] -= (self.level[side] + self.level_std[side] * t[:, kL + kR + side])[:, None]
        return out

    def grids(self, theta) -> np.ndarray:
        """Contact grids ``map > level``, shape (n, 2, rows, cols) (bool)."""
        t = np.atleast_2d(np.asarray(theta, np.float64))
        if t.shape[1] != self.n_dim:
            raise IdentifyError(f"theta must have {self.n_dim} columns, got shape {t.shape}")
        out = np.empty((t.shape[0], 2, self.mean.shape[1]), bool)
        # In blocks: a posterior's kept samples (~1e5) would need a float map 8× the grids' size at once, and
        # filling it took a fifth of a joint's sampling time (memory-bound); the grids are the same.
        for a in range(0, t.shape[0], _GRID_BLOCK):
            np.greater(self.excess(t[a:a + _GRID_BLOCK]), 0, out=out[a:a + _GRID_BLOCK])
        return out.reshape(-1, 2, *self.grid_shape)

    def valid(self, grids: np.ndarray) -> np.ndarray:
        """Whether each pair is a usable contact pattern (every side neither empty, full nor on a line), (n,)."""
        g = np.asarray(grids, bool).reshape(-1, 2, *self.grid_shape)
        n_on = g.sum(axis=(2, 3))
        ok = np.all((n_on > 0) & (n_on < np.prod(self.grid_shape)), axis=1)
        # both flanks in one call: the posterior asks this of every proposal, and each call has a fixed cost
        return ok & non_collinear_batch(g.reshape(-1, *self.grid_shape)).reshape(-1, 2).all(axis=1)

    def draw(self, n: int, rng: np.random.Generator, widen: float = 1.0) -> np.ndarray:
        """``n`` parameter vectors drawn from the prior (widened by ``widen``) that give valid grids, (n, n_dim)."""
        out: list[np.ndarray] = []
        tries = 0
        while len(out) < n:
            t = widen * rng.standard_normal((n, self.n_dim))
            out.extend(t[self.valid(self.grids(t))])
            tries += 1
            if tries > 50 and not out:
                raise IdentifyError("the contact prior gives no valid pattern (every draw empty, full or on a line)")
        return np.array(out[:n])


def _n_components(sampler: PatternSampler, n_components, variance: float, side: str) -> int:
    k_max = int(np.size(sampler.score_std_))
    if n_components is None:
        evr = np.cumsum(sampler.pca_.explained_variance_ratio_)
        return int(min(k_max, np.searchsorted(evr, variance - 1e-12) + 1))
    if isinstance(n_components, bool) or not isinstance(n_components, numbers.Integral) or n_components < 1:
        raise IdentifyError(f"n_components must be a positive integer, got {n_components!r}")
    if n_components > k_max:
        raise IdentifyError(f"n_components = {n_components}, but the {side} films support at most {k_max} "
                            f"(one fewer than the filmed joints)")
    return int(n_components)


def _level_spread(sampler: PatternSampler, levels: np.ndarray, areas: np.ndarray) -> float:
    """Standard deviation of a joint's contact level (module docstring): films' levels and area-equivalent levels."""
    mu = np.sort(sampler.mean_)[::-1]
    # the level at which the mean map covers the same share of nodes as each film does
    idx = np.clip(np.round(np.asarray(areas) * mu.size).astype(int) - 1, 0, mu.size - 1)
    equivalent = mu[idx]
    return float(np.sqrt(np.var(levels, ddof=1) + np.var(equivalent, ddof=1)))


def contact_prior(sampler_L: PatternSampler, sampler_R: PatternSampler, films_L: Sequence, films_R: Sequence, *,
                  scale: float = 1.0, n_components: int | None = None,
                  variance: float = DEFAULT_VARIANCE) -> ContactPrior:
    """The prior over one joint's contact pattern, from the fitted samplers and the films they were fitted on.

    Parameters
    ----------
    sampler_L, sampler_R : PatternSampler
        Fitted on the known films' maps (:func:`bladetwin.stages.patterns.family_samplers`).
    films_L, films_R : sequence of identify.FilmMap
        Those films (their ``level`` and ``contact`` set the level prior).
    scale : float
        Widens every prior standard deviation (Eq. 31's Scale), > 0.
    n_components : int, optional
        PCA components per side (1 … n_known − 1); default: enough for ``variance`` of the films' variance.
    variance : float
        Share of variance the default keeps, in (0, 1].

    Raises
    ------
    IdentifyError
        Bad ``scale``, ``n_components`` or ``variance``, unfitted samplers, or fewer than 2 films.
    """
    if isinstance(scale, bool) or not isinstance(scale, numbers.Real) or not np.isfinite(scale) or scale <= 0:
        raise IdentifyError(f"scale must be a positive number, got {scale!r}")
    if not (isinstance(variance, numbers.Real) and 0 < variance <= 1):
        raise IdentifyError(f"variance must lie in (0, 1], got {variance!r}")
    samplers, films = (sampler_L, sampler_R), (list(films_L), list(films_R))
    for side, s, f in zip("LR", samplers, films, strict=True):
        if not hasattr(s, "components_"):
            raise IdentifyError(f"sampler_{side} must be a fitted identify.PatternSampler")
        if len(f) < 2:
            raise IdentifyError(f"the {side} flank has {len(f)} films: a contact prior needs at least 2")
    ks = tuple(_n_components(s, n_components, variance, side) for side, s in zip("LR", samplers, strict=True))
    n_nodes = samplers[0].components_.shape[1]
    basis = np.zeros((2, max(ks), n_nodes))
    mean = np.empty((2, n_nodes))
    level, level_var, dof = np.empty(2), np.empty(2), np.empty(2)
    for i, (s, f, k) in enumerate(zip(samplers, films, ks, strict=True)):
        mean[i] = s.mean_ + s.score_mean_ @ s.components_
        basis[i, :k] = scale * s.score_std_[:k, None] * s.components_[:k]
        levels = np.array([m.level for m in f], np.float64)
        level[i] = levels.mean()
        level_var[i], dof[i] = _level_spread(s, levels, [float(np.mean(m.contact)) for m in f]) ** 2, len(f) - 1
    # One scatter for both flanks: a joint's seating sets both, and two films that happen to agree on one flank
    # would otherwise pin its level (design §8.81).
    level_std = np.full(2, scale * np.sqrt(dof @ level_var / dof.sum()))
    return ContactPrior(mean, basis, ks, level, level_std, tuple(samplers[0].grid_shape_), float(scale))


def held_out_projections(films_L: Sequence, films_R: Sequence, n_components: tuple[int, int]) -> np.ndarray:
    """Each film's map as the prior's family would draw it without that film: its contact grid, leave-one-out.

    For film i the PCA of Eqs. 26–29 is fitted on the other films, film i's map is projected on its first
    ``n_components`` components (capped at the n − 2 the others support) and thresholded at film i's own level.
    What this grid misses of film i's contact is what a joint's true pattern can lack in the prior's family; the
    posterior turns it into a frequency error (:func:`bladetwin.stages.posterior.representation_error`).

    Parameters
    ----------
    films_L, films_R : sequence of identify.FilmMap
        The known films, one per joint, ≥ 3 per side.
    n_components : (int, int)
        The prior's k_L, k_R.

    Returns
    -------
    ndarray of bool, shape (n_films, 2, rows, cols)
    """
    sides = (list(films_L), list(films_R))
    n = len(sides[0])
    if n < 3 or len(sides[1]) != n:
        raise IdentifyError(f"held-out projections need ≥ 3 films per side, one per joint; got {n} and "
                            f"{len(sides[1])}")
    out = []
    for i in range(n):
        grids = []
        for films, k in zip(sides, n_components, strict=True):
            rest = [f for m, f in enumerate(films) if m != i]
            s = PatternSampler(threshold=float(np.mean([f.level for f in rest]))).fit(rest)
            kappa = s.transform([films[i].gray])
            kappa[:, min(int(k), n - 2):] = 0.0  # the prior's components only
            grids.append(s.inverse_transform(kappa)[0] > films[i].level)
        out.append(grids)
    return np.array(out, bool)
