"""The ROM updated beyond Eq. 19 on the disk–one-blade tests: in-situ blade corrections and contact stiffness.

The paper's ROM carries each blade's *free* eigenvalue deviations into the assembly (Eq. 19) and ties the
contacting nodes rigidly (Eq. 21). Two things a real specimen does are outside it (docs/design.md §8.24):
a blade feature that the disk clamps (a root fillet) moves the blade's in-situ modes by other amounts than
its free modes; and a joint is a finite stiffness, which puts the disk-dominated modes below the ties'.

The updated ROM adds, per blade ``j``, an in-situ correction ``ε_j`` of its free-interface eigenvalues,
``Ω_f² = diag((1 + δ_j,i + ε_j,i) ω_i²)`` (Eq. 19 with δ → δ + ε), and one contact stiffness for every joint
(:mod:`rom.contact_stiffness`: ``k_n``, ``k_t`` in N/m³). Each disk–one-blade test (blade ``j`` in its own slot)
measures 10 tracked modes, which fix that blade's ε on the modes the blade dominates. The filmed joints,
whose patterns are known, also fix the contact stiffness through the disk-dominated modes.

* :func:`tracked_sensitivity` (from :mod:`identify.d1b_solve`, which also holds the fits' reduced-basis solve) —
  the tracked frequencies and ``∂ ln f_k / ∂ δ_i`` (analytic: an eigenvalue's derivative with respect to a
  diagonal stiffness entry is ``φ_k,i²`` for mass-normalised modes);
* :func:`fit_corrections` — one blade's ε by regularised Gauss–Newton (prior: Eq. 19, ε = 0);
* :func:`fit_contact_stiffness` — ``k_n``, ``k_t`` with the filmed blades' ε, jointly (Levenberg–Marquardt);
* :mod:`identify.in_situ` — which corrections to trust, and the one-line warnings on data the calibration
  cannot use.

The full-assembly test never enters: every function here takes disk–one-blade data only.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rom.contact import ContactPattern
from rom.contact_stiffness import ContactStiffness, interface_compliance, with_contact_stiffness

from .d1b_solve import eps_model, tracked_sensitivity, tuned_pencil
from .errors import IdentifyError
from .tracking import ModeTracker

__all__ = ["ROM_ERROR", "PRIOR_STD", "LOG_PRIOR_STD", "STOP_SHARE", "STOP_CHI2", "DISAGREE_BOUND", "BLADE_SHARE_MIN",
           "InSituFit", "StiffnessFit", "UpdatedROM", "tracked_sensitivity", "calibrated_modes", "fit_corrections",
           "fit_contact_stiffness", "start_stiffness", "noise_floor"]

#: Prior standard deviation of an in-situ correction ε (relative eigenvalue). Wide on purpose: a blade mode
#: that a disk–one-blade test sees is set by the test; one that no tracked mode sees stays at Eq. 19.
PRIOR_STD = 0.05
#: |ε − the blades' median| beyond which free and in-situ data of a blade's mode are said to disagree (relative
#: eigenvalue, about 5 % in frequency): more than twice the largest free-blade deviation a specimen of one design
#: shows (about 2 %). Not the blade, then: a joint the model's pattern misrepresents (ε absorbs it), or a
#: mislabelled or damaged test (identify.in_situ).
DISAGREE_BOUND = 0.10
#: A tracked mode is blade-dominated when the blade's free modes hold at least this share of its stiffness.
BLADE_SHARE_MIN = 0.5
#: The reduced model's own frequency error against its FE model (relative): Craig–Bampton + Rubin reach
#: about 0.01 % on the academic disk (docs/rom.md). No update should fit the data closer than this.
ROM_ERROR = 1e-4
_LOG_K_STEP = 0.05  # finite-difference step on ln k (5 %)
#: Std of the stiffness fit's Gaussian prior on ln k around its start: a factor 1000, wide on purpose.
LOG_PRIOR_STD = float(np.log(1e3))
#: The stiffness fit stops when a step moves ln k by less than this share of its standard deviation.
STOP_SHARE = 0.01
#: ... or when the undamped Gauss–Newton step from where it stands would lower its cost (χ²: the squared
#: normalised residuals and prior terms) by less than this: the optimum is then within a posterior density 5 %
#: higher, far below the Δχ² = 1 of one standard deviation. On a shallow valley where k and the blades' ε trade,
#: the steps after it only creep along the valley (docs/design.md §8.89). Taken from the normal equations, not
#: from the last step's gain, which a heavily damped step keeps small far from the optimum.
STOP_CHI2 = 0.1


@dataclass(frozen=True, eq=False)
class InSituFit:
    """One blade's in-situ correction (Eq. 19 with δ → δ + ε) fitted on its disk–one-blade test.

    Attributes
    ----------
    correction : ndarray, shape (m,)
        ε, relative eigenvalue correction of each free-interface mode (0: Eq. 19 unchanged).
    frequencies_hz : ndarray, shape (n_tracked,)
        The updated ROM's tracked frequencies after the fit.
    measured_hz : ndarray, shape (n_tracked,)
        The test's frequencies on the tracked modes (NaN: not found).
    blade_share : ndarray, shape (n_tracked,)
        Share of each tracked mode's stiffness held by the blade's free modes (0–1).
    dominant_mode : ndarray of int, shape (n_tracked,)
        0-based free-interface mode with the largest sensitivity for each tracked mode.
    """

    correction: np.ndarray
    frequencies_hz: np.ndarray
    measured_hz: np.ndarray
    blade_share: np.ndarray
    dominant_mode: np.ndarray

    @property
    def residual_pct(self) -> np.ndarray:
        """Measured over fitted frequency − 1 (%), shape (n_tracked,), NaN where not measured."""
        return (self.measured_hz / self.frequencies_hz - 1.0) * 100.0


@dataclass(frozen=True, eq=False)
class StiffnessFit:
    """The joints' contact stiffness fitted on the filmed joints' disk–one-blade tests.

    Attributes
    ----------
    stiffness : ContactStiffness
    joints : ndarray of int, shape (n_filmed,)
        The filmed joints fitted.
    corrections : ndarray, shape (n_filmed, m)
        Their blades' ε, fitted jointly with the stiffness.
    log_std : ndarray, shape (2,)
        Linearised standard deviation of ln k_n and ln k_t.
    n_iter : int
    rms_residual_pct : float
        RMS of the tracked modes' residuals over the filmed joints at the optimum (%).
    settled : bool
        Whether the fit stopped by its own rule (steps below the data's resolution, or no step that lowers the
        cost), not at ``max_iter``: on a valley where k_n and the blades' ε trade, where it stops depends on
        ``max_iter`` (docs/design.md §8.42, §8.77).
    """

    stiffness: ContactStiffness
    joints: np.ndarray
    corrections: np.ndarray
    log_std: np.ndarray
    n_iter: int
    rms_residual_pct: float
    settled: bool = True


@dataclass(frozen=True, eq=False)
class UpdatedROM:
    """The ROM beyond Eq. 19: every blade's in-situ correction and the joints' contact stiffness.

    Attributes
    ----------
    stiffness : ContactStiffness or None
        ``None``: rigid ties (Eq. 21), as when no filmed joint has a disk–one-blade test.
    corrections : ndarray, shape (n_blades, m)
        ε of each blade's free-interface modes (relative eigenvalue; zeros: Eq. 19 unchanged).
    calibrated : ndarray of bool, shape (n_blades,)
        Blades whose disk–one-blade test was fitted.
    residual_pct : ndarray, shape (n_blades, n_tracked)
        Measured over updated-ROM tracked frequency − 1 (%) after the fit (NaN: no test or mode not found).
    residual_paper_pct : ndarray, shape (n_blades, n_tracked)
        The same for the paper's ROM (rigid ties, Eq. 19), for comparison.
    free_hz : ndarray, shape (m,)
        The tuned ROM blade's free-interface frequencies (Hz), naming the modes.
    replaced : tuple of (int, ContactPattern)
        (joint, pattern) for each joint whose given pattern its disk–one-blade test did not bear out, with the
        plausible pattern the update took instead (:func:`identify.in_situ.consistent_pattern`); empty: every
        joint as given.
    """

    stiffness: ContactStiffness | None
    corrections: np.ndarray
    calibrated: np.ndarray
    residual_pct: np.ndarray
    residual_paper_pct: np.ndarray
    free_hz: np.ndarray
    replaced: tuple = ()

    def patterns_for(self, patterns) -> list[ContactPattern]:
        """``patterns`` (one per slot) with :attr:`replaced`'s patterns at their joints."""
        out = list(patterns)
        for joint, pattern in self.replaced:
            out[int(joint) - 1] = pattern
        return out

    def frequency_correction_pct(self, delta_all: np.ndarray) -> np.ndarray:
        """The corrections as in-situ frequency changes (%) of each free mode, shape (n_blades, m)."""
        return (np.sqrt((1 + delta_all + self.corrections) / (1 + delta_all)) - 1) * 100


def noise_floor(ema_std_rel: np.ndarray) -> np.ndarray:
    """Relative noise per tracked mode (shape as given): the EMA's std (its median where a mode has none) and
    the ROM's own error :data:`ROM_ERROR`, in quadrature."""
    s = np.asarray(ema_std_rel, np.float64).copy()
    ok = np.isfinite(s) & (s > 0)
    s[~ok] = np.median(s[ok]) if ok.any() else 0.0
    return np.sqrt(s**2 + ROM_ERROR**2)


def _gn_step(r: np.ndarray, jac: np.ndarray, sigma: np.ndarray, eps: np.ndarray, prior_std: float) -> np.ndarray:
    """The regularised Gauss–Newton step on ε: min ‖(r − J Δ)/σ‖² + ‖(ε + Δ)/τ‖²."""
    Jw = jac / sigma[:, None]
    A = Jw.T @ Jw + np.eye(eps.size) / prior_std**2
    b = Jw.T @ (r / sigma) - eps / prior_std**2
    return np.linalg.solve(A, b)


def _blade_share(jacobian: np.ndarray) -> np.ndarray:
    """Share of each tracked mode's stiffness the blade's free modes hold (0–1), shape (n_tracked,): twice the sum
    of ∂ ln f/∂δ over the free modes, since Eq. 19's δ scales the blade's modal stiffness and f ∝ √λ."""
    return 2 * jacobian.sum(axis=1)


def calibrated_modes(jacobian: np.ndarray) -> np.ndarray:
    """The free-interface modes an in-situ fit corrects: the one that dominates each blade-dominated tracked mode.

    One correction per blade and mode family, as the Fundamental Mistuning Model has one deviation per blade and
    family (Feiner & Griffin). Modes no tracked mode is dominated by stay at Eq. 19: the test cannot tell
    them apart from the disk's or the joint's errors.

    Parameters
    ----------
    jacobian : ndarray, shape (n_tracked, m)
        From :func:`tracked_sensitivity`.

    Returns
    -------
    ndarray of int, sorted, 0-based
    """
    return np.unique(np.argmax(jacobian[_blade_share(jacobian) >= BLADE_SHARE_MIN], axis=1))


def fit_corrections(tracker: ModeTracker, pattern: ContactPattern, delta: np.ndarray, measured_hz: np.ndarray,
                    sigma_rel: np.ndarray, *, prior_std: float = PRIOR_STD, n_iter: int = 3,
                    held: np.ndarray | None = None) -> InSituFit:
    """One blade's in-situ correction ε from its disk–one-blade test (regularised Gauss–Newton in ln f).

    Only :func:`calibrated_modes` are corrected, on the blade-dominated tracked modes alone (a blade share ≥
    :data:`BLADE_SHARE_MIN` at ε = 0); the other modes keep ε = 0. The first solve is direct; the steps
    after it solve a Ritz model over the corrected modes (:func:`identify.d1b_solve.eps_model`), directly where
    its bound on a tracked frequency exceeds :data:`identify.d1b_solve.RITZ_TOL`.

    Parameters
    ----------
    tracker : ModeTracker
        With the model to update (``tracker.blade``: rigid ties, or on springs).
    pattern : ContactPattern
        The joint's pattern (film, identified or reference).
    delta : ndarray, shape (m,)
        The blade's free deltas (Eq. 19, relative).
    measured_hz : ndarray, shape (n_tracked,)
        The test's frequencies on the tracked modes (NaN: not found).
    sigma_rel : ndarray, shape (n_tracked,)
        Relative noise of each (:func:`noise_floor`).
    held : ndarray, shape (m,), optional
        ε held at these values, not fitted (NaN: fitted as usual): the blades' common correction for a mode
        that this test cannot see (:mod:`identify.in_situ`).
    """
    delta = np.asarray(delta, np.float64)
    y = np.asarray(measured_hz, np.float64)
    use = np.isfinite(y) & (y > 0)
    fixed = np.zeros(delta.size, bool) if held is None else np.isfinite(held)
    eps = np.where(fixed, held if held is not None else 0.0, 0.0)
    pencil = tuned_pencil(tracker, pattern)
    f, jac = tracked_sensitivity(tracker, pattern, delta + eps, pencil=pencil)
    # Only the blade-dominated tracked modes set ε: a disk-dominated one carries the contact stiffness and the
    # disk's own error, which it cannot tell from ε (design §8.79).
    use &= _blade_share(jac) >= BLADE_SHARE_MIN
    free = calibrated_modes(jac)
    free = free[~fixed[free]]
    n_steps = n_iter if use.any() and free.size else 0
    # The steps move ε on ``free`` only: one Ritz model serves them all (identify.d1b_solve).
    model = eps_model(tracker, pencil, delta + eps, free) if n_steps else None
    for _ in range(n_steps):
        step = _gn_step(np.log(y[use] / f[use]), jac[np.ix_(use, free)], np.asarray(sigma_rel)[use], eps[free],
                        prior_std)
        eps[free] = np.maximum(eps[free] + step, -0.5 - delta[free])  # keeps (1 + δ + ε) ω² positive
        got = None if model is None else model.sensitivity(tracker, delta + eps)
        f, jac = got if got is not None else tracked_sensitivity(tracker, pattern, delta + eps, pencil=pencil)
    return InSituFit(eps, f, y, _blade_share(jac), np.argmax(jac, axis=1))


def start_stiffness(tracker: ModeTracker, compliance_unit: np.ndarray) -> float:
    """A scale-free starting stiffness (N/m³): where the springs are as compliant as the blade's own root.

    ``compliance_unit`` is the springs' compliance at 1 N/m³ normal and tangential (shape (n_nodes, 3, 3)).
    """
    blade = tracker.blade
    g = np.median(np.diag(blade.G_bb)[: blade.n_interface])
    c = np.median(np.einsum("nii->ni", compliance_unit))
    return float(c / g)


def fit_contact_stiffness(tracker: ModeTracker, compliance_unit: np.ndarray, joints: dict, *,
                          prior_std: float = PRIOR_STD, max_iter: int = 12, log_prior_std: float = LOG_PRIOR_STD,
                          progress=None) -> StiffnessFit:
    """Contact stiffness (k_n, k_t) and the filmed blades' ε, jointly, by Levenberg–Marquardt.

    The disk-dominated tracked modes carry the stiffness; each blade's ε takes its :func:`calibrated_modes`.
    Stops when an iteration moves ln k by less than :data:`STOP_SHARE` of its standard deviation (from the
    normal equations): finer steps are below what the data resolve, and below the round-off of the ROM's
    eigen-solves, which makes the cost flat to about 1e-5 near the optimum (a model rebuilt on other BLAS
    threads moves k by about 5e-5 relative); or when the Gauss–Newton step would lower the cost by less than
    :data:`STOP_CHI2` (χ² units), a gain the data do not resolve. A stiffness that the data inform less than its
    prior does is held where it is (:func:`_prior_dominated`): on a joint nearly rigid in one direction its
    steps would only swing back and forth. On a specimen whose model error is far above the tests' noise, k_n
    and the blades' ε trade along a shallow valley, and ``max_iter`` ends the fit before it settles
    (docs/design.md §8.42).

    Parameters
    ----------
    tracker : ModeTracker
        With the paper's (rigid-tie) blade.
    compliance_unit : ndarray, shape (2, n_nodes, 3, 3)
        The springs' compliance at 1 N/m³, normal part then tangential part
        (:func:`rom.contact_stiffness.blade_compliance_parts`).
    joints : dict joint → (pattern, delta (m,), measured_hz (n_tracked,), sigma_rel (n_tracked,))
        The filmed joints with their known patterns.
    log_prior_std : float
        Std of the Gaussian prior on ln k around the start (:func:`start_stiffness`); wide (a factor 1000).

    Returns
    -------
    StiffnessFit
    """
    if not joints:
        raise IdentifyError("the contact stiffness needs at least one filmed joint with a disk–one-blade test")
    problem = _StiffnessProblem(tracker, compliance_unit, joints, prior_std, log_prior_std)
    log_k = problem.log_k0.copy()
    eps = {j: np.zeros(tracker.blade.m) for j in problem.keys}
    cost, parts = problem.evaluate(log_k, eps)
    problem.free = {j: calibrated_modes(parts[j][1]) for j in problem.keys}
    lm, it, settled = 1e-2, 0, False
    held = np.zeros(2, bool)
    current = None  # the normal equations at the answer, when the loop ends with them (a held k zeroes a column)
    for it in range(1, max_iter + 1):
        A, b = problem.normal_equations(log_k, eps, parts, held)
        newly_held = _prior_dominated(A, log_prior_std) & ~held
        held |= newly_held
        current = None if newly_held.any() else A
        if b @ _held_solve(A, b, held) < STOP_CHI2:  # Gauss–Newton's predicted gain, whatever the damping
            it, settled = it - 1, True
            break
        while True:
            step = _held_solve(A + lm * np.diag(np.diag(A)), b, held)
            step[:2] = np.clip(step[:2], -1.0, 1.0)  # at most a factor e per iteration on k
            new_k, new_eps = log_k + step[:2], problem.add(eps, step[2:])
            new_cost, new_parts = problem.evaluate(new_k, new_eps)
            if new_cost <= cost or lm > 1e6:
                break
            lm *= 10
        if new_cost > cost:
            settled = True
            break
        log_k, eps, cost, parts, lm = new_k, new_eps, new_cost, new_parts, max(lm / 10, 1e-6)
        current = None
        if progress is not None:
            progress(f"contact stiffness, iteration {it}: k_n = {np.exp(log_k[0]):.3g}, "
                     f"k_t = {np.exp(log_k[1]):.3g} N/m³")
        if np.all(held | (np.abs(step[:2]) < STOP_SHARE * np.sqrt(np.diag(np.linalg.inv(A))[:2]))):
            settled = True
            break
    A = problem.normal_equations(log_k, eps, parts, held)[0] if current is None else current
    cov = np.linalg.inv(A)
    res = np.concatenate([p[3] for p in parts.values()]) * 100
    return StiffnessFit(ContactStiffness(float(np.exp(log_k[0])), float(np.exp(log_k[1]))),
                        np.array(problem.keys, np.int64), np.array([eps[j] for j in problem.keys]),
                        np.sqrt(np.diag(cov)[:2]), it, float(np.sqrt(np.mean(res**2))), settled)


def _prior_dominated(A: np.ndarray, log_prior_std: float) -> np.ndarray:
    """Which of ln k_n, ln k_t the data inform less than their prior does (shape (2,), bool).

    Such a stiffness is past the point where the tests see it (a joint nearly rigid in that direction): its
    Gauss–Newton curvature is the prior's alone, so the steps it gets are set by the residuals' curvature
    that Gauss–Newton leaves out, and swing by the clip's factor e either way without lowering the cost.
    The fit holds it where it is.
    """
    return np.diag(A)[:2] - 1 / log_prior_std**2 < 1 / log_prior_std**2


def _held_solve(A: np.ndarray, b: np.ndarray, held: np.ndarray) -> np.ndarray:
    """The solution of ``A x = b`` with the stiffness entries marked ``held`` (shape (2,)) kept at 0."""
    free = np.r_[~held, np.ones(b.size - 2, bool)]
    x = np.zeros(b.size)
    x[free] = np.linalg.solve(A[np.ix_(free, free)], b[free])
    return x


class _StiffnessProblem:
    """The least-squares problem of :func:`fit_contact_stiffness` over [ln k_n, ln k_t, each blade's ε(free)]."""

    def __init__(self, tracker, compliance_unit, joints, prior_std, log_prior_std):
        self.tracker, self.unit, self.joints = tracker, compliance_unit, joints
        self.prior_std, self.log_prior_std = prior_std, log_prior_std
        self.keys = sorted(joints)
        self.log_k0 = np.full(2, np.log(start_stiffness(tracker, compliance_unit[0] + compliance_unit[1])))
        self.free: dict = {}
        self._blades: dict = {}

    def blade(self, log_k):
        """The blade on springs of stiffness exp(``log_k``), one object per stiffness, shared by the joints:
        :mod:`rom.rubin` memoises the boundary inverse by the object's flexibility, so it is factored once."""
        key = tuple(float(x) for x in log_k)
        if key not in self._blades:
            while len(self._blades) >= 3:  # the current point, its trial step and a finite-difference point
                self._blades.pop(next(iter(self._blades)))
            k = np.exp(log_k)
            self._blades[key] = with_contact_stiffness(
                self.tracker.blade, interface_compliance(self.unit, ContactStiffness(float(k[0]), float(k[1]))))
        return self._blades[key]

    def solve(self, log_k, j, eps):
        pat, delta, _, _ = self.joints[j]
        return tracked_sensitivity(replace(self.tracker, blade=self.blade(log_k)), pat, delta + eps)

    def evaluate(self, log_k, eps):
        """(cost, {joint: (f, jac, use, r)}) at ln k and ε."""
        parts, cost = {}, float(np.sum(((log_k - self.log_k0) / self.log_prior_std) ** 2))
        for j in self.keys:
            _, _, y, s = self.joints[j]
            f, jac = self.solve(log_k, j, eps[j])
            use = np.isfinite(y) & (y > 0)
            r = np.log(y[use] / f[use])
            parts[j] = (f, jac, use, r)
            cost += float(np.sum((r / s[use]) ** 2) + np.sum((eps[j] / self.prior_std) ** 2))
        return cost, parts

    def _offsets(self):
        sizes = [self.free[j].size for j in self.keys]
        return 2 + np.r_[0, np.cumsum(sizes)].astype(int)

    def add(self, eps, step):
        out, off = {}, self._offsets() - 2
        for q, j in enumerate(self.keys):
            e = eps[j].copy()
            fr = self.free[j]
            e[fr] = np.maximum(e[fr] + step[off[q]:off[q + 1]], -0.5 - self.joints[j][1][fr])
            out[j] = e
        return out

    def normal_equations(self, log_k, eps, parts, held=(False, False)):
        """Gauss–Newton normal equations (ln k by finite differences of :data:`_LOG_K_STEP`, ε analytic).

        A ``held`` stiffness gets no finite difference: its data columns are zero."""
        off = self._offsets()
        A = np.zeros((off[-1], off[-1]))
        b = np.zeros(off[-1])
        A[:2, :2] += np.eye(2) / self.log_prior_std**2
        b[:2] -= (log_k - self.log_k0) / self.log_prior_std**2
        for q, j in enumerate(self.keys):
            _, _, _, s = self.joints[j]
            f, jac, use, r = parts[j]
            jk = np.zeros((int(use.sum()), 2))
            for p in np.flatnonzero(~np.asarray(held, bool)):
                lk = log_k.copy()
                lk[p] += _LOG_K_STEP
                jk[:, p] = np.log(self.solve(lk, j, eps[j])[0][use] / f[use]) / _LOG_K_STEP
            fr = self.free[j]
            J = np.hstack([jk, jac[np.ix_(use, fr)]]) / s[use][:, None]
            idx = np.r_[0, 1, np.arange(off[q], off[q + 1])]
            A[np.ix_(idx, idx)] += J.T @ J
            b[idx] += J.T @ (r / s[use])
            blk = np.arange(off[q], off[q + 1])
            A[blk, blk] += 1 / self.prior_std**2
            b[blk] -= eps[j][fr] / self.prior_std**2
        return A, b
