"""Each unfilmed joint's contact as a posterior from its disk–one-blade test (beyond the paper).

The seed paper's answer is one of n × n pre-drawn patterns with no measure of confidence. Here a joint's pattern
is a point θ of the continuous prior of :mod:`identify.contact_prior` (PCA coefficients and contact level per
flank), and the data are every tracked mode its d1b test found:

    log p(θ | y) = −½ ‖θ‖² − ½ Σ_m [(log y_m − log(r_m · f_m(θ))) / σ_m]²   (+ const)

with f the surrogate of :mod:`identify.contact_surrogate` (δ = 0), r_m the joint's δ factor, and σ_m the
relative noise of mode m: the model error measured on the filmed joints, the EMA's standard deviation and the
surrogate's held-out error, added in quadrature (:func:`noise_model`). Patterns that are empty, full or on a line
have zero prior mass.

The posterior is sampled by the ensemble sampler of ``emcee`` (Goodman & Weare 2010) with differential-evolution
moves (ter Braak 2006; ter Braak & Vrugt 2008), seeded, until its chains converge (:mod:`identify.chains`: R̂ and
ESS, checked after every ``n_steps``), on the hard-thresholded grids: the sampler needs no gradient, so the
likelihood's steps at each node's threshold do not hurt it. What the user gets (:class:`JointPosterior`): the MAP
pattern (the best sample), the probability that each node is in contact, and 90 % intervals of each flank's area
fraction and centroid and of the predicted frequencies.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from rom.contact import ContactPattern

from .chains import ChainDiagnostics, diagnose
from .contact_prior import ContactPrior
from .contact_surrogate import ContactSurrogate
from .errors import IdentifyError
from .validation import contact_area_fraction, contact_centroid

__all__ = ["JointPosterior", "joint_posterior", "noise_model", "predictive_spread", "median_area_answer",
           "evenly_spaced", "prior_intervals", "width_ratio", "N_THIN", "MAX_EXTENSIONS"]

#: Every how many draws the areas' R̂ is taken (:func:`_diagnostics`).
AREA_THIN = 5

#: How many more times its steps a posterior's walkers may run before it is reported as not converged. Only a
#: joint short of convergence pays for it; 2 left 9 of 56 posteriors unconverged on five small coarse campaigns,
#: 5 leaves 3, each still R̂ > 1.05 after 9000 steps (design §8.55).
MAX_EXTENSIONS = 5

#: Samples each joint keeps for what comes after it (the forced response's intervals: 200 samples give a 90 %
#: interval's ends to about ±2 percentiles).
N_THIN = 200


@dataclass(frozen=True, eq=False)
class JointPosterior:
    """One joint's posterior (module docstring).

    Attributes
    ----------
    pattern : rom.ContactPattern
        The MAP pattern (hard threshold).
    theta_map : ndarray, shape (n_dim,)
    probability : ndarray, shape (2, rows, cols)
        Posterior probability that each node of each flank (L, R) is in contact.
    area_pct_map : ndarray, shape (2,)
        Area fraction of the MAP pattern per flank, % (Eq. 41).
    area_pct_ci90 : ndarray, shape (2, 2)
        5 % and 95 % posterior quantiles of each flank's area fraction, %.
    centroid_map : ndarray, shape (2, 2)
        (ū, v̄) of the MAP pattern per flank (Eq. 42), in the coordinates' unit (m).
    centroid_ci90 : ndarray, shape (2, 2, 2)
        Flank × (u, v) × (5 %, 95 %) quantiles of the centroid.
    frequencies_hz : ndarray, shape (n_modes,)
        Predicted tracked frequencies of the MAP pattern at the joint's δ (Hz).
    frequencies_hz_ci90 : ndarray, shape (n_modes, 2)
        Their 5 % and 95 % posterior quantiles.
    n_samples : int
        Posterior samples kept.
    acceptance : float
        Mean acceptance fraction of the ensemble's moves.
    samples_hz : ndarray, shape (n_thin, n_modes)
        Predicted tracked frequencies of :data:`N_THIN` (or all, if fewer) kept samples, evenly thinned from the
        flattened chain (Hz): what the forced response's intervals propagate (:mod:`rom.forced.perturbation`).
    answer_grids : ndarray of bool, shape (2, rows, cols)
        The answer (:func:`median_area_answer`): on each flank the nodes most probably in contact, as many as
        the samples' median count.
    samples_grids : ndarray of bool, shape (n_thin, 2, rows, cols)
        The contact grids (flanks L, R) of the same kept samples as ``samples_hz``: the patterns the posterior
        finds plausible, for what must choose among them (the ROM update's consistency check).
    answer_hz : ndarray, shape (n_modes,)
        Predicted tracked frequencies of the answer (:attr:`answer_grids`), Hz: the samples' centre, the pattern
        the full solves take.
    diagnostics : identify.chains.ChainDiagnostics
        The chains' R̂ (over θ and each flank's area), ESS (over θ) and the steps run: where the first
        ``n_steps`` leave R̂ above :data:`identify.chains.RHAT_MAX` or the ESS below
        :data:`identify.chains.ESS_MIN`, the walkers run on, ``n_steps`` at a time, up to ``max_extensions``
        times; ``diagnostics.converged`` says whether that sufficed.
    """

    pattern: ContactPattern
    theta_map: np.ndarray
    probability: np.ndarray
    area_pct_map: np.ndarray
    area_pct_ci90: np.ndarray
    centroid_map: np.ndarray
    centroid_ci90: np.ndarray
    frequencies_hz: np.ndarray
    frequencies_hz_ci90: np.ndarray
    n_samples: int
    acceptance: float
    samples_hz: np.ndarray
    answer_hz: np.ndarray
    diagnostics: ChainDiagnostics | None = None
    samples_grids: np.ndarray | None = None
    answer_grids: np.ndarray | None = None


def noise_model(model_spread, surrogate_error_pct, ema_std_rel=None, representation_rel=None) -> np.ndarray:
    """Relative noise per mode, shape (n_modes,): model, surrogate, EMA and family errors in quadrature.

    Parameters
    ----------
    model_spread : array_like, shape (n_modes,)
        Scatter of f_measured / f_ROM − 1 over the filmed joints (relative; 0 for the numerical input).
    surrogate_error_pct : array_like, shape (n_modes,)
        :attr:`ContactSurrogate.error_pct`.
    ema_std_rel : array_like, shape (n_modes,), optional
        The EMA's frequency standard deviation over its frequency (NaN: unknown, taken as 0).
    representation_rel : array_like, shape (n_modes,), optional
        How far the prior's family misses a real joint in frequency: the RMS relative error of the films'
        held-out projections (:func:`identify.contact_prior.held_out_projections`). Without it the numerical
        input, which has no model error, trusts the family as if it held the truth.
    """
    s = np.asarray(model_spread, np.float64) ** 2 + (np.asarray(surrogate_error_pct, np.float64) / 100) ** 2
    for extra in (ema_std_rel, representation_rel):
        if extra is not None:
            s = s + np.nan_to_num(np.asarray(extra, np.float64)) ** 2
    return np.sqrt(s)


def evenly_spaced(n: int, k: int) -> np.ndarray:
    """``min(k, n)`` distinct indices into ``n`` draws, evenly spaced from the first to the last, ascending."""
    return np.unique(np.linspace(0, n - 1, min(k, n)).round().astype(int))


def median_area_answer(probability, grids) -> np.ndarray:
    """One pattern for a joint's posterior: on each flank, the nodes most probably in contact, as many as the
    samples' median count, shape (2, rows, cols) (bool).

    The contact area is what the answer is judged by first (paper Eq. 41), and under absolute error its Bayes
    estimate is the posterior median. Among patterns of one count, the most probable nodes maximise the expected
    node agreement, Σ P(node as chosen). So this is the node-agreement estimate at the median area; the nodes
    with P > ½ maximise node agreement alone, at an area that can sit far from the posterior's (on the bundled
    campaign's joint 4: 9/8 % against a median of 16/12 %; design §8.88). Ties go to the first node in row order.

    Parameters
    ----------
    probability : array_like, shape (2, rows, cols)
        Each node's posterior probability of contact.
    grids : array_like of bool, shape (n, 2, rows, cols)
        The posterior's samples.
    """
    prob = np.asarray(probability, np.float64)
    g = np.asarray(grids, bool)
    out = np.zeros(prob.shape, bool)
    for f in range(prob.shape[0]):
        n = int(np.round(np.median(g[:, f].reshape(len(g), -1).sum(axis=1))))
        top = np.argsort(-prob[f].ravel(), kind="stable")[:n]
        out[f].flat[top] = True
    return out


def predictive_spread(spread, n_joints) -> np.ndarray:
    """The scatter a new joint's f_measured / f_ROM − 1 has about the filmed joints' bias, shape (n_modes,).

    The filmed joints' population std (``spread``: ddof 0 over ``n_joints`` per mode), turned into the sample
    std (ddof 1) and widened by √(1 + 1/n) for the bias's own error: the prediction interval of a new
    observation, √((n + 1) / (n − 1)) in all. With two or three filmed joints the plain spread is about half of
    it, and the posterior's intervals were too narrow (design §8.80). NaN where ``n_joints`` < 2: no scatter
    measured.

    Parameters
    ----------
    spread : array_like, shape (n_modes,)
        :attr:`bladetwin.stages.bias.Features.spread` (relative).
    n_joints : array_like of int, shape (n_modes,)
        How many filmed joints found each mode.
    """
    s, n = np.asarray(spread, np.float64), np.asarray(n_joints, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n >= 2, s * np.sqrt((n + 1) / (n - 1)), np.nan)


def _check(prior, surrogate, target_hz, sigma_rel, factor, n_walkers, n_steps) -> tuple:
    if not isinstance(prior, ContactPrior) or not isinstance(surrogate, ContactSurrogate):
        raise IdentifyError("joint_posterior needs an identify.ContactPrior and an identify.ContactSurrogate")
    n_modes = surrogate.intercept.size
    y = np.asarray(target_hz, np.float64).ravel()
    s = np.asarray(sigma_rel, np.float64).ravel()
    r = np.ones(n_modes) if factor is None else np.asarray(factor, np.float64).ravel()
    if y.shape != (n_modes,) or s.shape != (n_modes,) or r.shape != (n_modes,):
        raise IdentifyError(f"target_hz, sigma_rel and factor must each hold {n_modes} values (one per tracked mode)")
    use = np.isfinite(y) & (y > 0)
    if not use.any():
        raise IdentifyError("target_hz holds no finite, positive frequency")
    if np.any(~np.isfinite(s[use])) or np.any(s[use] <= 0):
        raise IdentifyError(f"sigma_rel must be positive and finite where a target is given, got {s.tolist()}")
    for name, v, lo in (("n_walkers", n_walkers, 2 * prior.n_dim), ("n_steps", n_steps, 10)):
        if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < lo:
            raise IdentifyError(f"{name} must be an integer ≥ {lo}, got {v!r}")
    return y, s, r, use


def joint_posterior(prior: ContactPrior, surrogate: ContactSurrogate, target_hz, sigma_rel, coordinates, *,
                    factor=None, n_walkers: int = 32, n_steps: int = 1500, seed: int = 0,
                    max_extensions: int = MAX_EXTENSIONS) -> JointPosterior:
    """Sample one joint's contact posterior (module docstring).

    Parameters
    ----------
    prior : ContactPrior
    surrogate : ContactSurrogate
    target_hz : array_like, shape (n_modes,)
        The joint's frequencies of the tracked modes (Hz; NaN where its test did not find the mode).
    sigma_rel : array_like, shape (n_modes,)
        Relative noise per mode (:func:`noise_model`).
    coordinates : (u, v)
        Node coordinates of a flank (m), arrays of shape (rows, cols).
    factor : array_like, shape (n_modes,), optional
        The joint's δ factor f(pattern, δ) / f(pattern, 0) (default 1).
    n_walkers, n_steps : int
        Ensemble size (≥ 2 n_dim) and steps; the first third of the steps are discarded as burn-in.
    max_extensions : int
        How many more times ``n_steps`` the walkers may run while the chains have not converged
        (:class:`JointPosterior` ``diagnostics``).
    seed : int
        Seeds the start positions and the sampler: the same inputs give the same answer.
    """
    import emcee

    y, s, r, use = _check(prior, surrogate, target_hz, sigma_rel, factor, n_walkers, n_steps)
    logy = np.log(np.where(use, y, 1.0))
    logr = np.log(r)

    def log_prob(theta: np.ndarray) -> np.ndarray:
        g = prior.grids(theta)
        ok = prior.valid(g)
        out = np.full(len(theta), -np.inf)
        if ok.any():
            logf = np.log(surrogate.predict_hz(g[ok])) + logr
            res = ((logy - logf) / s)[:, use]
            out[ok] = -0.5 * np.sum(theta[ok] ** 2, axis=1) - 0.5 * np.sum(res ** 2, axis=1)
        return out

    rng = np.random.default_rng(seed)
    start = prior.draw(n_walkers, rng)
    # differential-evolution moves, not emcee's default stretch: on the thresholded likelihood the stretch
    # move's walkers mixed so slowly that R̂ over them was still 1.05–1.10 after 4500 steps on the bundled
    # campaign (τ ≈ 60–130 steps); with the DE mixture (emcee's documented choice for rugged, multimodal
    # targets) every bundled joint reached R̂ ≤ 1.05 within 4500 steps, most within 3000 (docs/design.md §8.51)
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(n_walkers, prior.n_dim, log_prob, moves=moves, vectorize=True)
    sampler.random_state = np.random.RandomState(seed).get_state()  # emcee's own stream, seeded
    sampler.run_mcmc(start, n_steps, progress=False)
    total = n_steps
    diagnostics = _diagnostics(sampler, prior, total)
    for _ in range(max_extensions):
        if diagnostics.converged:
            break
        sampler.run_mcmc(None, n_steps, progress=False)  # on from the walkers' last state
        total += n_steps
        diagnostics = _diagnostics(sampler, prior, total)
    burn = total // 3
    chain = sampler.get_chain(discard=burn, flat=True)
    logp = sampler.get_log_prob(discard=burn, flat=True)
    return _summarise(prior, surrogate, chain, logp, coordinates, logr, float(np.mean(sampler.acceptance_fraction)),
                      diagnostics)


def _diagnostics(sampler, prior: ContactPrior, total: int) -> ChainDiagnostics:
    """R̂ over θ and each flank's area, ESS over θ, of the kept draws (the last two thirds of ``total`` steps).

    The areas' R̂ is taken on every k-th draw (k = 5: about 200 draws a walker at 1500 steps); the grids of every
    draw took a sixth of a joint's sampling time, and draws a few steps apart are nearly the same (τ ≈ 30–130
    steps on the bundled campaign).
    """
    chain = sampler.get_chain(discard=total // 3)
    thin = chain[::AREA_THIN]
    area = contact_area_fraction(prior.grids(thin.reshape(-1, thin.shape[2]))).reshape(*thin.shape[:2], -1)
    return diagnose(chain, area, total)


def _area_centroid(grids: np.ndarray, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area fraction (%, shape (n, 2)) and centroid (m, shape (n, 2, 2)) of each grid pair (n, 2, rows, cols)."""
    area = contact_area_fraction(grids)
    with np.errstate(invalid="ignore"):
        return area, contact_centroid(grids, u, v)


def _ci90(area: np.ndarray, cen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """5 % and 95 % quantiles: of the areas, shape (2, 2), and of the centroids, shape (2, 2, 2)."""
    q = (5, 95)
    return np.percentile(area, q, axis=0).T, np.moveaxis(np.nanpercentile(cen, q, axis=0), 0, -1)


def _summarise(prior, surrogate, chain, logp, coordinates, logr, acceptance,
               diagnostics: ChainDiagnostics | None = None) -> JointPosterior:
    """Every figure of :class:`JointPosterior` from the kept samples."""
    u, v = (np.asarray(a, np.float64) for a in coordinates)
    best = int(np.argmax(logp))
    grids = prior.grids(chain)
    area, cen = _area_centroid(grids, u, v)
    area_ci90, centroid_ci90 = _ci90(area, cen)
    freq = surrogate.predict_hz(grids) * np.exp(logr)
    thin = evenly_spaced(len(chain), N_THIN)
    probability = grids.mean(axis=0)
    answer_grids = median_area_answer(probability, grids)
    answer = surrogate.predict_hz(answer_grids[None])[0] * np.exp(logr)
    return JointPosterior(
        pattern=ContactPattern(grids[best, 0], grids[best, 1]), theta_map=chain[best].copy(),
        probability=probability, area_pct_map=area[best], area_pct_ci90=area_ci90,
        centroid_map=cen[best], centroid_ci90=centroid_ci90,
        frequencies_hz=freq[best], frequencies_hz_ci90=np.percentile(freq, (5, 95), axis=0).T,
        n_samples=len(chain), acceptance=acceptance, samples_hz=freq[thin], answer_hz=answer,
        diagnostics=diagnostics, samples_grids=grids[thin], answer_grids=answer_grids)


def _widths(area_ci90: np.ndarray, centroid_ci90: np.ndarray) -> np.ndarray:
    """Interval widths in the order of :data:`WIDTH_NAMES`, shape (6,)."""
    return np.r_[np.diff(area_ci90, axis=1).ravel(), np.diff(centroid_ci90, axis=2).ravel()]


#: The quantities :func:`width_ratio` compares, in its order (area in %, centroid coordinates in m).
WIDTH_NAMES = ("area L", "area R", "centroid u L", "centroid v L", "centroid u R", "centroid v R")


def prior_intervals(prior: ContactPrior, coordinates, *, n: int = 4000, seed: int = 0) -> np.ndarray:
    """90 % interval widths of each flank's area fraction (%) and centroid (m) under the prior, shape (6,) in the
    order of :data:`WIDTH_NAMES`, from ``n`` seeded prior draws."""
    u, v = (np.asarray(a, np.float64) for a in coordinates)
    return _widths(*_ci90(*_area_centroid(prior.grids(prior.draw(n, np.random.default_rng(seed))), u, v)))


def width_ratio(post: JointPosterior, prior_widths: np.ndarray) -> np.ndarray:
    """Posterior over prior 90 % width of each quantity of :data:`WIDTH_NAMES`, shape (6,): 1 where the data say
    nothing about it, near 0 where they pin it down (the identifiability study of docs/identify.md)."""
    return _widths(post.area_pct_ci90, post.centroid_ci90) / np.asarray(prior_widths, np.float64)
