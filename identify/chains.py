"""Convergence of an ensemble sampler's chains: rank-normalised split-R̂ and the effective sample size.

The contact posterior (:mod:`identify.posterior`) is sampled by emcee's ensemble; nothing told whether its walkers
had mixed. Two standard figures do:

* **R̂** (Vehtari, Gelman, Simpson, Carpenter & Bürkner, "Rank-normalization, folding, and localization: an
  improved R̂ for assessing convergence of MCMC", Bayesian Analysis 16(2), 2021): every walker's kept chain is
  split in halves, the draws are replaced by their normal scores over all chains (rank-normalised, so heavy
  tails and the steps of a thresholded quantity do not matter), and R̂ = √(var⁺ / W) compares the spread of
  the chains' means with the spread within them; the larger of the bulk R̂ and the folded one (|x − median|,
  the tails) is kept. Near 1 where the walkers agree; a walker stuck apart from the others raises it.
* **ESS**: the kept draws over the integrated autocorrelation time τ that emcee estimates from the walkers'
  mean autocorrelation function (:func:`emcee.autocorr.integrated_time`), the effective number of independent
  draws behind a posterior mean or quantile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ChainDiagnostics", "RHAT_MAX", "ESS_MIN", "split_rhat", "effective_sample_size", "diagnose"]

#: R̂ above this is not converged (issue 46; Vehtari et al. recommend 1.01 for final inference).
RHAT_MAX = 1.05
#: Fewer effective draws than this are too few for 5 %/95 % quantiles (Vehtari et al.: 100 per chain × 4 chains).
ESS_MIN = 400.0


@dataclass(frozen=True)
class ChainDiagnostics:
    """One posterior's convergence figures.

    Attributes
    ----------
    rhat : float
        The largest R̂ over the sampled parameters and the derived quantities given to :func:`diagnose`.
    ess : float
        The smallest ESS over the sampled parameters.
    n_steps : int
        Steps each walker ran, burn-in included.
    """

    rhat: float
    ess: float
    n_steps: int

    @property
    def converged(self) -> bool:
        return bool(self.rhat <= RHAT_MAX and self.ess >= ESS_MIN)


def _normal_scores(x: np.ndarray) -> np.ndarray:
    """Rank-normalised draws: Φ⁻¹((r − 3/8) / (S + 1/4)) of their pooled ranks r (ties averaged), same shape."""
    from scipy.special import ndtri
    from scipy.stats import rankdata

    r = rankdata(x, method="average").reshape(x.shape)
    return ndtri((r - 0.375) / (x.size + 0.25))


def _rhat(z: np.ndarray) -> float:
    """Classic R̂ of chains ``z``, shape (n_draws, n_chains)."""
    n = z.shape[0]
    w = float(np.mean(np.var(z, axis=0, ddof=1)))
    b_over_n = float(np.var(np.mean(z, axis=0), ddof=1))
    if w <= 0:
        return 1.0 if b_over_n <= 0 else float("inf")
    return float(np.sqrt(((n - 1) / n * w + b_over_n) / w))


def split_rhat(chains: np.ndarray) -> float:
    """Rank-normalised split-R̂ of one quantity (module notes).

    Parameters
    ----------
    chains : ndarray, shape (n_draws, n_chains)
        Kept draws of each chain (a walker), burn-in removed; n_draws ≥ 4.

    Returns
    -------
    float
        max(bulk R̂, folded R̂); 1 for a quantity that never varies.
    """
    x = np.asarray(chains, np.float64)
    if x.ndim != 2 or x.shape[0] < 4:
        raise ValueError(f"chains have shape {x.shape}, expected (n_draws ≥ 4, n_chains)")
    half = x.shape[0] // 2
    split = np.concatenate([x[:half], x[-half:]], axis=1)
    if np.ptp(split) == 0:
        return 1.0
    folded = np.abs(split - np.median(split))
    return max(_rhat(_normal_scores(split)), _rhat(_normal_scores(folded)) if np.ptp(folded) > 0 else 1.0)


def effective_sample_size(chains: np.ndarray) -> np.ndarray:
    """ESS of each parameter: draws × chains / τ, τ from :func:`emcee.autocorr.integrated_time`.

    Parameters
    ----------
    chains : ndarray, shape (n_draws, n_chains, n_dim)

    Returns
    -------
    ndarray, shape (n_dim,)
        0 for a parameter that some chain never moves (a stuck walker), NaN for one that no chain moves.
    """
    from emcee.autocorr import integrated_time

    x = np.asarray(chains, np.float64)
    if x.ndim != 3:
        raise ValueError(f"chains have shape {x.shape}, expected (n_draws, n_chains, n_dim)")
    spread = np.ptp(x, axis=0)  # (n_chains, n_dim)
    moving = np.all(spread > 0, axis=0)
    out = np.where(np.any(spread > 0, axis=0), 0.0, np.nan)
    if moving.any():
        tau = np.atleast_1d(integrated_time(x[..., moving], tol=0))  # tol 0: the estimate, no length check
        out[moving] = x.shape[0] * x.shape[1] / np.maximum(tau, 1.0)
    return out


def diagnose(chains: np.ndarray, derived: np.ndarray | None = None, n_steps: int | None = None
             ) -> ChainDiagnostics:
    """R̂ over the parameters and the ``derived`` quantities, ESS over the parameters.

    Parameters
    ----------
    chains : ndarray, shape (n_draws, n_chains, n_dim)
        Kept draws (burn-in removed).
    derived : ndarray, shape (n_draws', n_chains, n_q), optional
        Quantities computed from the draws whose convergence matters too (each flank's contact area), from all
        of them or from every k-th (n_draws' ≤ n_draws).
    n_steps : int, optional
        Steps each walker ran, burn-in included (default: n_draws).
    """
    x = np.asarray(chains, np.float64)
    q = [x] if derived is None else [x, np.asarray(derived, np.float64)]
    rhat = max(split_rhat(a[..., k]) for a in q for k in range(a.shape[2]))
    ess = effective_sample_size(x)
    return ChainDiagnostics(float(rhat), float(np.nanmin(ess)) if np.isfinite(ess).any() else float("nan"),
                            int(x.shape[0] if n_steps is None else n_steps))
