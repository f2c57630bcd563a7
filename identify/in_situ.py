"""Which in-situ corrections to trust (beyond the paper): the blades' common part and the modes a test cannot see.

The in-situ correction ε (:func:`identify.rom_update.fit_corrections`) holds what the model misses in each seated
blade. Part of it every blade of one design shares (the model's own error); the rest is the blade's. A blade's
test that lacks the tracked mode a free mode dominates cannot set that mode: it takes the blades' common part.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from rom.contact import ContactPattern

from .rom_update import BLADE_SHARE_MIN, DISAGREE_BOUND, InSituFit

__all__ = ["unobserved_modes", "population_centre", "common_correction", "held_at_common", "calibration_warnings",
           "disagrees", "consistent_pattern", "N_CANDIDATES"]

#: Posterior samples :func:`consistent_pattern` tries: evenly spaced over the kept draws, so that a region holding
#: a quarter of the posterior's mass is missed by all of them with a chance of 0.75⁸ = 10 %; each costs one blade
#: fit (about half a second on the default disk).
N_CANDIDATES = 8


def unobserved_modes(fit: InSituFit) -> dict[int, int]:
    """Free modes a test cannot see: {free mode: the blade-dominated tracked mode it lacks} (0-based).

    A free mode dominates a blade-dominated tracked mode that the test did not find, and no found one: it is
    then set only by the other tracked modes' small shares of it, which carry the model's errors too."""
    missing: dict[int, int] = {}
    blade_rows = fit.blade_share >= BLADE_SHARE_MIN
    found = set(fit.dominant_mode[blade_rows & np.isfinite(fit.measured_hz)].tolist())
    for k in np.flatnonzero(blade_rows & ~np.isfinite(fit.measured_hz)):
        if int(fit.dominant_mode[k]) not in found:  # another found mode it dominates calibrates it: nothing lost
            missing.setdefault(int(fit.dominant_mode[k]), int(k))
    return missing


def population_centre(corrections: np.ndarray, seen: np.ndarray | None = None) -> np.ndarray:
    """The blades' common in-situ correction per free mode: the median over the blades that see it, shape (m,).

    What every blade of one design shares (the model's own error in the blade as seated) is not a blade's
    disagreement with its files: :func:`calibration_warnings` measures each blade from it, and a blade whose
    test cannot see a mode takes it (``held`` of :func:`identify.rom_update.fit_corrections`). Fewer than 3
    blades give no median that one odd blade cannot move: NaN there.

    Parameters
    ----------
    corrections : ndarray, shape (n_tested, m)
    seen : ndarray of bool, shape (n_tested, m), optional
        Which blade's test sees which mode (default: all).
    """
    eps = np.asarray(corrections, float)
    seen = np.ones(eps.shape, bool) if seen is None else np.asarray(seen, bool)
    out = np.full(eps.shape[1], np.nan)
    for i in range(eps.shape[1]):
        if np.count_nonzero(seen[:, i]) >= 3:
            out[i] = np.median(eps[seen[:, i], i])
    return out


def common_correction(fits: Sequence[InSituFit], m: int) -> np.ndarray:
    """:func:`population_centre` of the blades' fits, each seeing the modes :func:`unobserved_modes` leaves,
    shape (m,) (NaN where fewer than 3 see it; all NaN without fits)."""
    if not fits:
        return np.full(m, np.nan)
    eps = np.array([f.correction for f in fits])
    seen = np.ones(eps.shape, bool)
    for row, fit in enumerate(fits):
        seen[row, list(unobserved_modes(fit))] = False
    return population_centre(eps, seen)


def held_at_common(fit: InSituFit, centre: np.ndarray) -> np.ndarray | None:
    """``held`` for a blade's refit (:func:`identify.rom_update.fit_corrections`): the common value of each mode
    its test cannot see, NaN elsewhere; None where there is nothing to hold."""
    hold = np.full(np.size(centre), np.nan)
    for i in unobserved_modes(fit):
        hold[i] = centre[i]
    return hold if np.isfinite(hold).any() else None


def calibration_warnings(blade: int, fit: InSituFit, free_hz: np.ndarray, *, bound: float = DISAGREE_BOUND,
                         filmed: bool = False, centre: np.ndarray | None = None) -> list[str]:
    """One line per problem of one blade's calibration data, naming the blade and the mode.

    * a blade-dominated tracked mode that its disk–one-blade test lacks, where no found tracked mode is dominated
      by the same free mode, and that free mode's correction passes ``bound`` (below): it is then set only by the
      other tracked modes' small shares of it, which carry the model's errors too. Within the bound a missing
      mode is no warning: the test's table shows it, and the blade agrees with the others (design §8.53);
    * a free mode whose in-situ correction lies more than ``bound`` from ``centre`` (the blades' common part,
      :func:`population_centre`; default 0): the test and the model disagree by more than a blade's free-test
      scatter explains. On a blade whose files are right, that is the joint: a pattern
      (identified, or for a ``filmed`` joint its film) that the test does not bear out, since ε absorbs
      whatever the pattern leaves unexplained. So the line names the joint first and the files second.

    Parameters
    ----------
    free_hz : ndarray, shape (m,)
        The ROM blade's free-interface frequencies (Hz), to name the modes.
    filmed : bool
        Whether the blade's joint was filmed (its pattern is the film's, not an identified one).
    centre : ndarray, shape (m,), optional
        The blades' common correction per free mode.
    """
    out, missing = [], unobserved_modes(fit)
    c = np.zeros(fit.correction.size) if centre is None else np.nan_to_num(np.asarray(centre, float))
    off = fit.correction - c

    def beyond(i: int) -> str:
        common = f", {100 * off[i]:+.1f} % from the blades' common {100 * c[i]:+.1f} %" if c[i] else ""
        return f"{100 * fit.correction[i]:+.1f} % (eigenvalue){common}, beyond ±{100 * bound:.0f} %"

    for i, k in missing.items():
        if abs(off[i]) > bound:
            out.append(f"blade {blade}: its disk–one-blade test lacks tracked mode {k + 1} "
                       f"({fit.frequencies_hz[k]:.1f} Hz, blade-dominated): free mode {i + 1} ({free_hz[i]:.1f} Hz) "
                       f"is corrected only through the other tracked modes' small shares of it, to {beyond(i)}")
    cause = (f"joint {blade}'s film (the joint seated differently in the disk–one-blade test)" if filmed
             else f"joint {blade}'s identified pattern (a contact outside the films' family)")
    for i in _disagreeing(off, missing, bound):
        out.append(f"blade {blade}, free mode {i + 1} ({free_hz[i]:.1f} Hz): in-situ correction {beyond(i)}: the "
                   f"disk–one-blade test disagrees with the model; most likely {cause}, else the files' labels")
    return out


def _disagreeing(off: np.ndarray, missing: dict, bound: float) -> list[int]:
    """The free modes the test sees (not in ``missing``) whose correction ``off`` the blades' common one lies
    beyond ``bound``, ascending (0-based)."""
    return [int(i) for i in np.flatnonzero(np.abs(off) > bound) if int(i) not in missing]


def disagrees(fit: InSituFit, centre: np.ndarray | None = None, bound: float = DISAGREE_BOUND) -> bool:
    """Whether a free mode the test sees has its correction more than ``bound`` from the blades' ``centre``: the
    disagreement of :func:`calibration_warnings`' second kind."""
    c = np.zeros(fit.correction.size) if centre is None else np.nan_to_num(np.asarray(centre, float))
    return bool(_disagreeing(fit.correction - c, unobserved_modes(fit), bound))


def consistent_pattern(fit_one: Callable[[ContactPattern], InSituFit], candidates: Sequence[ContactPattern],
                       sigma_rel: np.ndarray, centre: np.ndarray | None = None,
                       bound: float = DISAGREE_BOUND) -> tuple[ContactPattern, InSituFit] | None:
    """Among a joint's plausible patterns, the one its disk–one-blade test bears out best with a blade correction
    the blades' population explains; None where none does.

    The contact posterior sees the test through a surrogate of the rigid-tie ROM; the updated ROM (springs, ε) is
    the model the lab takes away. Where the posterior's answer leaves that ROM a blade correction beyond ``bound``
    (:func:`disagrees`), ε has absorbed what the pattern leaves unexplained. Each candidate (draws of the same
    posterior) is fitted as the answer was, and the one with the least misfit over every tracked mode the test
    found, Σ ((ln y − ln f) / σ)², among those that do not disagree, is returned: the posterior's draw that the
    more exact model and the blade population agree with best.

    Parameters
    ----------
    fit_one : callable
        A pattern → its blade's :class:`InSituFit` (with the blades' common part held where the test cannot see
        a mode, as the answer's fit).
    candidates : sequence of rom.ContactPattern
    sigma_rel : ndarray, shape (n_tracked,)
        The test's relative noise per tracked mode.
    centre : ndarray, shape (m,), optional
        The blades' common correction (:func:`common_correction`).
    """
    best, best_cost = None, np.inf
    s = np.asarray(sigma_rel, float)
    for pattern in candidates:
        fit = fit_one(pattern)
        if disagrees(fit, centre, bound):
            continue
        use = np.isfinite(fit.measured_hz) & (fit.measured_hz > 0)
        cost = float(np.sum((np.log(fit.measured_hz[use] / fit.frequencies_hz[use]) / s[use]) ** 2))
        if cost < best_cost:
            best, best_cost = (pattern, fit), cost
    return best
