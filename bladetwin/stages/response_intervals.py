"""The AF's intervals over the contact posterior's samples (issue 47; :mod:`bladetwin.stages.response` uses them).

Each posterior sample of the unfilmed joints changes their disk–one-blade frequencies
(:class:`ContactSamples`); :func:`family_changes` turns that into each blade's eigenvalue change for one family,
:func:`with_discrepancy` adds every blade's frequency discrepancy against the full-assembly test
(:func:`family_discrepancy`), :func:`amplitude_draws` scales every blade's point by the scatter of the
disk–one-blade tests' blade-point amplitudes (:func:`amplitude_discrepancy`), and :func:`sample_afs` gives every
sample's AF and worst blade through :func:`rom.forced.perturbed_family`, without a new assembly solve.
:func:`family_interval` puts them together for one family.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ema.numbering import dof_label
from rom.forced import BladeModes, amplification_factor, perturbed_family, sample_model

__all__ = ["POINT", "ContactSamples", "contact_samples", "family_changes", "family_discrepancy", "with_discrepancy",
           "amplitude_discrepancy", "amplitude_draws",
           "FamilyInterval", "family_interval", "sample_afs", "interval_quantiles"]

#: The blade point loaded and read on every blade (the response node's).
POINT = 1


@dataclass(frozen=True, eq=False)
class ContactSamples:
    """The contact posterior's samples at the unfilmed joints, as changes of their tracked d1b frequencies.

    Attributes
    ----------
    rel : ndarray, shape (n_samples, n_blades, n_modes)
        f_sample / f_answer − 1 of each joint's tracked modes (0 at joints without a posterior: the filmed ones).
    answer_hz : ndarray, shape (n_blades, n_modes)
        The answer's predicted tracked frequencies (Hz); NaN at joints without a posterior.
    """

    rel: np.ndarray
    answer_hz: np.ndarray

    @property
    def n_samples(self) -> int:
        return int(self.rel.shape[0])


def contact_samples(n_blades: int, posts: dict) -> ContactSamples | None:
    """:class:`ContactSamples` of the joints' posteriors (``{joint: JointPosterior or None}``); None without any.

    Sample k of every joint makes sample k of the disk: the joints' posteriors are independent, so any pairing
    of their samples is a draw from the product.
    """
    posts = {j: p for j, p in posts.items() if p is not None and len(p.samples_hz)}
    if not posts:
        return None
    n_s = min(len(p.samples_hz) for p in posts.values())
    n_m = next(iter(posts.values())).answer_hz.size
    rel, answer = np.zeros((n_s, n_blades, n_m)), np.full((n_blades, n_m), np.nan)
    for j, p in posts.items():
        answer[j - 1] = p.answer_hz
        rel[:, j - 1] = p.samples_hz[:n_s] / p.answer_hz - 1.0
    return ContactSamples(rel, answer)


def _point_rows(d1b) -> list[int]:
    """Rows of blade point :data:`POINT` in a ROM's disk–one-blade labels (one, where the solve measures it)."""
    return [k for k, lab in enumerate(d1b.meas_labels) if lab[0] == "blade" and int(lab[2]) == POINT]


def _point_value(d1b, band) -> tuple[float, float] | None:
    """(frequency Hz, value at the blade point) of the disk–one-blade mode of the family in ``band``: the one
    moving the blade point most (the blade-dominated one); None where no d1b mode lies in the band."""
    rows = _point_rows(d1b)
    if len(rows) != 1:
        return None
    f = np.asarray(d1b.frequencies_hz)
    inside = np.flatnonzero((f >= band[0]) & (f <= band[1]))
    if not inside.size:
        return None
    values = np.asarray(d1b.meas_shapes)[rows[0], inside]
    k = int(np.argmax(np.abs(values)))
    return float(f[inside[k]]), float(values[k])


def family_changes(samples: ContactSamples, band, d1b) -> tuple[np.ndarray | None, float, str]:
    """(Δλ of every sample and blade, shape (n_samples, n_blades); ψ at the blade point; "") of one family, or
    (None, nan, why) where the family has no d1b mode or no tracked mode in its band.

    Δλ_j = ω_j² ((1 + r_j)² − 1), r_j the sample's relative change of the joint's tracked mode nearest the
    family's d1b mode (:mod:`rom.forced.perturbation`).
    """
    mode = _point_value(d1b, band)
    if mode is None:
        return None, float("nan"), "no disk–one-blade mode of the ROM in the family's band"
    f_d1b, psi = mode
    f_tracked = np.nanmedian(samples.answer_hz, axis=0)
    k = int(np.nanargmin(np.abs(np.log(f_tracked / f_d1b))))
    if not band[0] <= f_tracked[k] <= band[1]:
        return None, float("nan"), (f"no tracked disk–one-blade mode in the family's band (nearest: "
                                    f"{f_tracked[k]:.6g} Hz)")
    w2 = (2 * np.pi * np.nan_to_num(samples.answer_hz[:, k])) ** 2
    return w2 * ((1.0 + samples.rel[:, :, k]) ** 2 - 1.0), psi, ""


def sample_afs(mis, tuned, band, eos, refs: dict, delta_lambda: np.ndarray, psi: float,
               scale: np.ndarray | None = None) -> tuple:
    """AF and worst blade of every sample and EO, shapes (n_samples, n_eo) (NaN / 0 where ``refs`` has no EO).

    ``mis``, ``tuned``: :class:`rom.forced.BladeModes` with the family's damping; ``refs``: EO index → the tuned
    sweep. The samples' family modes come from :func:`rom.forced.perturbed_family`; ``scale``, shape
    (n_samples, n_blades), multiplies each blade's row of every mode (:func:`amplitude_draws`): a blade whose
    point moves (1 + η) times as much is loaded and read (1 + η) times as much.
    """
    f, phi = perturbed_family(mis, band, delta_lambda, psi)
    af, worst = np.full((len(f), len(eos)), np.nan), np.zeros((len(f), len(eos)), int)
    for s in range(len(f)):
        m = sample_model(mis, band, f[s], phi[s])
        if scale is not None:
            m = BladeModes(m.frequencies_hz, m.damping_ratio, m.shapes * scale[s][:, None])
        for e, ref in refs.items():
            a = amplification_factor(m, tuned, eos[e], tuple(band), tuned_response=ref)
            af[s, e], worst[s, e] = a.af, a.worst_blade
    return af, worst


def interval_quantiles(af: np.ndarray, worst: np.ndarray, n_blades: int) -> tuple[np.ndarray, np.ndarray]:
    """(5 %/95 % quantiles, shape (n_eo, 2); each blade's share of being the worst, shape (n_eo, n_blades))."""
    ci, pw = np.full((af.shape[1], 2), np.nan), np.full((af.shape[1], n_blades), np.nan)
    for e in range(af.shape[1]):
        ok = np.isfinite(af[:, e])
        if ok.any():
            ci[e] = np.percentile(af[ok, e], (5, 95))
            pw[e] = np.bincount(worst[ok, e] - 1, minlength=n_blades) / ok.sum()
    return ci, pw


def family_discrepancy(model_hz: np.ndarray, test_hz: np.ndarray, band) -> float:
    """The spread σ of d = f_test / f_model − 1 over a family's modes paired one-to-one within 2 % in ``band``:
    1.4826 × the median absolute deviation of d from its median (a common offset, the test day's temperature or
    the material, removed); NaN with fewer than 3 pairs.

    It measures how far the ROM's blade-to-blade frequency scatter misses the full-assembly test's, the scatter
    the AF follows: a mistuned family's modes sit where its blades' frequencies put them. The median, not the
    standard deviation: a disk-coupled mode of the band (the bundled updated ROM's nodal diameter 0, 1.9 % off
    while the blade cluster's 17 modes spread by 0.006 %) is a coupling error, not blade scatter; counted as
    blade scatter it inflated σ 70× and made every blade about as likely to be the worst. Pairing by frequency
    alone matches a dense family's sorted lists: where the scatter exceeds the modes' spacing, σ is that of the
    sorted frequencies, a lower bound of the blades'.
    """
    from ema.mac import pair_by_frequency

    fm = np.sort(model_hz[(model_hz >= band[0]) & (model_hz <= band[1])])
    ft = np.sort(test_hz[(test_hz >= band[0]) & (test_hz <= band[1])])
    if fm.size < 3 or ft.size < 3:
        return float("nan")
    rows, cols = pair_by_frequency(fm, ft, 0.02)
    if rows.size < 3:
        return float("nan")
    d = ft[cols] / fm[rows] - 1.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))))


def with_discrepancy(dl: np.ndarray, mis, band, sigma: float, seed: int) -> np.ndarray:
    """``dl`` plus every blade's random eigenvalue change for a relative frequency error of σ (seeded)."""
    lam = float(np.mean(mis.omega[(mis.frequencies_hz >= band[0]) & (mis.frequencies_hz <= band[1])] ** 2))
    xi = sigma * np.random.default_rng(seed).standard_normal(dl.shape)
    return dl + lam * ((1.0 + xi) ** 2 - 1.0)


def amplitude_discrepancy(fits: dict, d1b, band) -> tuple[float, int]:
    """(σ_a, tests used): the scatter of the blades' point amplitudes in their disk–one-blade tests.

    Each blade's mass-normalised shape value at its blade point :data:`POINT`, in its test's mode nearest the
    ROM's disk–one-blade mode of the family (:func:`_point_value`), relative to the tests' median; σ_a is
    1.4826 × the median absolute deviation of those ratios from 1 (the ROM's common scale, which the AF
    cancels, removed).

    Why: the ROM's blades share one shape and differ in stiffness only, so in every ROM each blade's point moves
    alike in the family's blade mode. Real blades differ in geometry as well, and a blade whose point moves
    (1 + η) times as much is loaded and read (1 + η) times as much: its peak under engine-order excitation
    changes by about 2η, which no frequency shows. The tests' scatter holds that and their own scaling noise:
    σ_a bounds the first from above.

    Parameters
    ----------
    fits : dict
        Joint (1-based) → the disk–one-blade test's fit (with ``.model``, an :class:`ema.ModalModel`). Tests
        without mass-normalised shapes (no driving point), without the blade point or without a mode inside
        ``band`` within 5 % of the ROM's frequency are skipped.
    d1b : rom.fe_assembly.AssemblyModes
        The ROM's disk–one-blade modes (:func:`bladetwin.stages.response.d1b_node`): the family's blade mode
        and the blade point's measured direction.
    band : (float, float)
        The family's band (Hz).

    Returns
    -------
    sigma_a : float
        NaN with fewer than 3 usable tests, or where the ROM has no blade point or no mode in the band.
    n_used : int
    """
    mode = _point_value(d1b, band)
    if mode is None:  # also None where the ROM's labels hold the blade point not exactly once
        return float("nan"), 0
    direction = int(d1b.meas_labels[_point_rows(d1b)[0]][3])
    values = [v for joint, fit in sorted(fits.items())
              if (v := _test_amplitude(fit.model, joint, direction, mode[0], band)) is not None]
    if len(values) < 3:
        return float("nan"), len(values)
    rel = np.asarray(values) / np.median(values)
    return float(1.4826 * np.median(np.abs(rel - 1.0))), len(values)


def _test_amplitude(m, joint: int, direction: int, f_hz: float, band) -> float | None:
    """|φ| at joint ``joint``'s blade point in the test's mode nearest ``f_hz`` in ``band`` (within 5 %), from
    mass-normalised shapes; None where the test cannot give it."""
    if m.scaling != "mass":
        return None
    node, d = dof_label(("blade", joint, POINT, direction))
    rows = [k for k, (n, dd) in enumerate(m.dofs) if n == node and abs(dd) == d]
    f = np.asarray(m.frequencies_hz, float)
    inside = np.flatnonzero((f >= band[0]) & (f <= band[1]))
    if len(rows) != 1 or not inside.size:
        return None
    k = inside[np.argmin(np.abs(np.log(f[inside] / f_hz)))]
    v = abs(complex(m.shapes[rows[0], k]))
    return v if abs(np.log(f[k] / f_hz)) <= 0.05 and np.isfinite(v) and v > 0 else None


def amplitude_draws(n_samples: int, n_blades: int, sigma_a: float, seed: int) -> np.ndarray:
    """Every sample's blade-point scales 1 + σ_a ξ, ξ standard normal, shape (n_samples, n_blades); the stream
    (``seed``, 2) is independent of :func:`with_discrepancy`'s (``seed``)."""
    return 1.0 + sigma_a * np.random.default_rng([seed, 2]).standard_normal((n_samples, n_blades))


@dataclass(frozen=True, eq=False)
class FamilyInterval:
    """One family's intervals over the samples (:func:`family_interval`).

    Attributes
    ----------
    ci90, ci90_contact : ndarray, shape (n_eo, 2)
        5 %/95 % quantiles of the AF with every term, and with the contact's uncertainty alone.
    p_worst : ndarray, shape (n_eo, n_blades)
        Each blade's share of being the worst, with every term.
    sigma, sigma_a : float
        The frequency discrepancy (:func:`family_discrepancy`) and the amplitude discrepancy
        (:func:`amplitude_discrepancy`); NaN where not given.
    """

    ci90: np.ndarray
    ci90_contact: np.ndarray
    p_worst: np.ndarray
    sigma: float
    sigma_a: float


def family_interval(mis, tuned, band, eos, refs: dict, delta_lambda: np.ndarray, psi: float, family: int,
                    test_hz=None, d1b=None, d1b_fits=None) -> FamilyInterval:
    """A family's intervals: the contact's samples alone, then with each blade's frequency discrepancy against
    the full-assembly test's frequencies ``test_hz`` and its point amplitude's scatter over the disk–one-blade
    tests ``d1b_fits`` (joint → fit; with the ROM's d1b modes ``d1b``) where given. Arguments as
    :func:`sample_afs`; ``family`` seeds the draws.

    Raises
    ------
    rom.errors.ROMError
        A sample beyond the perturbation's reach (:func:`rom.forced.perturbed_family`).
    """
    n_b = mis.n_blades
    s_af, s_worst = sample_afs(mis, tuned, band, eos, refs, delta_lambda, psi)
    ci_c, pw = interval_quantiles(s_af, s_worst, n_b)
    sigma = family_discrepancy(mis.frequencies_hz, test_hz, band) if test_hz is not None else float("nan")
    sigma_a = amplitude_discrepancy(d1b_fits, d1b, band)[0] if d1b_fits and d1b is not None else float("nan")
    ci = ci_c
    if np.isfinite(sigma) or np.isfinite(sigma_a):
        dl = with_discrepancy(delta_lambda, mis, band, sigma, seed=family) if np.isfinite(sigma) else delta_lambda
        scale = amplitude_draws(*dl.shape, sigma_a, seed=family) if np.isfinite(sigma_a) else None
        s_af, s_worst = sample_afs(mis, tuned, band, eos, refs, dl, psi, scale)
        ci, pw = interval_quantiles(s_af, s_worst, n_b)
    return FamilyInterval(ci, ci_c, pw, sigma, sigma_a)
