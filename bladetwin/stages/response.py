"""The forced response under engine-order excitation and the mistuning amplification factor (issue 47).

For the ROM the run exports (the updated one where it ran, else the paper's) and for the paper's beside it, a
node each (``response_af_*``, :func:`rom_response_node`) gives the AF (:func:`rom.forced.amplification_factor`)
of each of the lowest families and each engine order 0..⌊N/2⌋, with the worst blade; ``response`` gathers them
with the truth's. They take the full-assembly solves the run already made (the mistuned disks) and solve only
what no node holds: each ROM's *tuned* disk, every joint with the films' mean pattern (the baseline's) and every
blade the blades' mean (δ, and ε for the updated ROM). Each family gets the damping the EMA measured in its band
(the full-assembly test, else the disk–one-blade tests); every mode of the model takes its family's ratio
(:func:`rom.forced.family_damping`), the tuned disk's and the mistuned one's alike.

A family is refused, with its reason, where the solves may miss a mode of its band: the AF needs every one.

**Intervals.** Where the contact posterior ran, each of its samples (sample k of every unfilmed joint) changes
the joints' disk–one-blade frequencies; the solved assembly's family modes are corrected for it in their own
span (:mod:`rom.forced.perturbation`, scaled by the ROM's disk–one-blade mode at the blade point, node
``response_d1b_*``), and the AF and worst blade of every sample give ``af_ci90`` and ``p_worst``. Where the
campaign has a full-assembly test, every blade's frequency is also drawn off by the family's discrepancy
against it (:func:`family_discrepancy`: the robust spread of the paired modes' errors, their mean removed).
Where the disk–one-blade tests give mass-normalised shapes at the blade point, every blade's point is also
scaled by the scatter of those amplitudes (:func:`amplitude_discrepancy`): the ROM's blades share one shape.

**Truth.** On a virtual campaign with ``truth/response_modes.npz`` (:mod:`lab.truth_response`) the truth twin's
own mistuned and tuned modes go through the same rules: ``truth`` holds its AF.
"""

from __future__ import annotations

import hashlib
import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rom.errors import ROMError
from rom.forced import amplification_factor, blade_modes, family_band, family_damping

from . import names
from .full import FullSolve
from .graph import Node
from .response_intervals import POINT, contact_samples, family_changes, family_interval
from .response_solves import TRUTH_FILE, d1b_node, truth_node, tuned_node

__all__ = ["N_FAMILIES", "POINT", "ROMResponse", "Response", "measured_damping", "band_damping",
           "refuse_overlapping", "rom_response_node", "response_node", "add_response_node"]

#: Families the run computes by default (the lowest); the blade point loaded and read on every blade is POINT.
N_FAMILIES = 3


@dataclass(frozen=True, eq=False)
class ROMResponse:
    """One ROM's amplification factors.

    Attributes
    ----------
    rom : str
        ``"updated"`` or ``"paper"``.
    solve : str
        The full solve it reuses (the member of ``full/``, e.g. ``"updated"``).
    bands_hz : ndarray, shape (n_families, 2)
        Each family's sweep band (Hz) on this ROM's tuned disk; NaN where refused.
    damping_ratio : ndarray, shape (n_families,)
        Each family's damping ratio (the EMA's); NaN where refused.
    af : ndarray, shape (n_families, n_eo)
        Amplification factor (largest mistuned blade peak over the tuned peak, 1); NaN where refused, and where
        the tuned disk's peak lies at the band's edge (no resonance of the family at that EO: :func:`_at_edge`).
    worst_blade : ndarray of int, shape (n_families, n_eo)
        The mistuned disk's blade (1-based) with the largest peak; 0 where refused.
    peak_hz, tuned_peak_hz : ndarray, shape (n_families, n_eo)
        Where the worst blade's peak and the tuned disk's peak occur (Hz).
    refused : tuple of str, one per family
        Why a family was not computed ("" where it was).
    af_ci90 : ndarray, shape (n_families, n_eo, 2)
        5 % and 95 % quantiles of the AF over the posterior's samples (:func:`sample_afs`); NaN where not
        computed.
    p_worst : ndarray, shape (n_families, n_eo, n_blades)
        Share of the samples in which each blade is the worst; NaN where not computed.
    interval : tuple of str, one per family
        Why a family has no interval ("" where it has one).
    n_samples : int
        Posterior samples behind the intervals (0: none).
    af_ci90_contact : ndarray, shape (n_families, n_eo, 2)
        The same interval with the contact's uncertainty alone (no blade-frequency discrepancy).
    discrepancy : ndarray, shape (n_families,)
        The family's relative blade-frequency discrepancy σ against the full-assembly test
        (:func:`family_discrepancy`); NaN where there is no such test or too few paired modes.
    amplitude_discrepancy : ndarray, shape (n_families,)
        The relative scatter σ_a of the blades' point amplitudes in their disk–one-blade tests
        (:func:`amplitude_discrepancy`); NaN where fewer than 3 tests give it.
    """

    rom: str
    solve: str
    bands_hz: np.ndarray
    damping_ratio: np.ndarray
    af: np.ndarray
    worst_blade: np.ndarray
    peak_hz: np.ndarray
    tuned_peak_hz: np.ndarray
    refused: tuple
    af_ci90: np.ndarray | None = None
    p_worst: np.ndarray | None = None
    interval: tuple = ()
    n_samples: int = 0
    af_ci90_contact: np.ndarray | None = None
    discrepancy: np.ndarray | None = None
    amplitude_discrepancy: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Response:
    """The node's result: every ROM's AF per family (1-based) and engine order.

    Attributes
    ----------
    n_blades, point : int
        Blades N, and the blade point (1-based) loaded and read on each.
    families, eos : tuple of int
    damping_source : str
        The tests whose EMA gave the families' damping.
    roms : tuple of ROMResponse
        The exported ROM first, then the paper's (once where they are the same).
    truth : ROMResponse or None
        The truth twin's own AF (``rom="truth"``), same force, bands rule and damping: a virtual campaign with
        ``truth/response_modes.npz`` only.
    interval_source : str
        What the intervals sample, or why there are none.
    """

    n_blades: int
    point: int
    families: tuple
    eos: tuple
    damping_source: str
    roms: tuple
    truth: ROMResponse | None = None
    interval_source: str = ""


def measured_damping(fits: dict) -> tuple[np.ndarray, np.ndarray, str]:
    """(frequencies Hz, damping ratios, source): the full-assembly EMA's modes, else the d1b tests' together."""
    use = ["assembly"] if "assembly" in fits else sorted(fits)
    f = np.concatenate([np.asarray(fits[k].model.frequencies_hz, float) for k in use] or [np.zeros(0)])
    z = np.concatenate([np.asarray(fits[k].model.damping_ratio, float) for k in use] or [np.zeros(0)])
    ok = np.isfinite(f) & np.isfinite(z) & (z > 0) & (z < 1)
    if not ok.any():
        raise ROMError(f"no EMA mode with a damping ratio in (0, 1) among the tests {use}: the forced response "
                       "needs each family's measured damping")
    return f[ok], z[ok], ("the full-assembly test's EMA" if use == ["assembly"] else "the disk–one-blade tests' EMA")


def band_damping(band, f: np.ndarray, z: np.ndarray) -> float:
    """The mean damping of the measured modes inside ``band`` (Hz), else of the one nearest in relative frequency."""
    inside = (f >= band[0]) & (f <= band[1])
    if inside.any():
        return float(np.mean(z[inside]))
    return float(z[np.argmin(np.abs(np.log(f / np.sqrt(band[0] * band[1]))))])


def _family(tuned, mistuned, fam: int, solve: str) -> tuple[tuple[float, float] | None, str]:
    """(band, "") of a family whose every mode both solves hold, else (None, why)."""
    try:
        band = family_band(tuned, fam)
    except ROMError as exc:
        return None, f"family {fam}: {exc}"
    for what, m in (("the tuned disk's solve", tuned), (f"the full solve '{solve}'", mistuned)):
        top = float(m.frequencies_hz.max())
        if top <= band[1]:
            return None, (f"family {fam}: {what} holds {m.n_modes} modes up to {top:.6g} Hz, not above the family's "
                          f"band {band[0]:.6g}–{band[1]:.6g} Hz: modes of the band may be missing (solve more modes)")
    return band, ""


def _at_edge(f_hz: float, band) -> bool:
    """Does the tuned disk's peak lie at an edge of the band (within 0.1 % of its width)?

    Then the family's mode of this engine order barely moves the loaded point (a disk-dominated mode: the
    solves carry no blade energy to tell it apart) and the sweep's largest value is the flank of a neighbouring
    family's resonance; the ratio of two such flanks is not an amplification factor.
    """
    lo, hi = band
    return min(f_hz - lo, hi - f_hz) <= 1e-3 * (hi - lo)


def refuse_overlapping(bands: np.ndarray, families, refused: list) -> list:
    """``refused`` with every family whose band overlaps another's refused too.

    Families are the k-th resonance per nodal diameter (:func:`rom.forced.family_band`); where a disk-dominated
    mode interleaves at some diameters, that ordering mixes two families and their bands overlap (the updated
    ROM of the bundled campaign: family 2 spanned 468–1234 Hz, family 3 631–1282 Hz). A mode of both bands then
    belongs to neither family alone: no AF of either is attributable.
    """
    out = list(refused)
    for i, j in itertools.combinations(range(len(families)), 2):
        if refused[i] or refused[j]:
            continue
        lo, hi = max(bands[i][0], bands[j][0]), min(bands[i][1], bands[j][1])
        if lo < hi:
            why = (f"the bands of families {families[i]} and {families[j]} overlap ({lo:.6g}–{hi:.6g} Hz): ordering "
                   "the resonances per nodal diameter mixed them (the solves carry no blade energy to tell blade "
                   "and disk families apart)")
            out[i] = out[i] or f"family {families[i]}: {why}"
            out[j] = out[j] or f"family {families[j]}: {why}"
    return out


def _rom_response(rom: str, solve: str, mistuned, tuned, families, eos, measured, samples=None,
                  d1b=None, test_hz=None, d1b_fits=None) -> ROMResponse:
    """One ROM's AFs: ``mistuned`` and ``tuned`` are :class:`rom.fe_assembly.AssemblyModes`; with ``samples``
    (:class:`ContactSamples`) and the ROM's disk–one-blade modes ``d1b``, their intervals too, widened by the
    blade-frequency discrepancy against the full-assembly test's frequencies ``test_hz`` and by the blade-point
    amplitude scatter of the disk–one-blade tests ``d1b_fits`` (joint → fit) where given."""
    mis0, tun0 = blade_modes(mistuned, 0.01, POINT), blade_modes(tuned, 0.01, POINT)
    n_f, n_e, n_b = len(families), len(eos), mis0.n_blades
    af, worst = np.full((n_f, n_e), np.nan), np.zeros((n_f, n_e), int)
    peak, tpeak = np.full((n_f, n_e), np.nan), np.full((n_f, n_e), np.nan)
    ci, ci_c, pw = np.full((n_f, n_e, 2), np.nan), np.full((n_f, n_e, 2), np.nan), np.full((n_f, n_e, n_b), np.nan)
    bands, zeta, sigma, refused = np.full((n_f, 2), np.nan), np.full(n_f, np.nan), np.full(n_f, np.nan), []
    sigma_a = np.full(n_f, np.nan)
    for i, fam in enumerate(families):
        band, why = _family(tun0, mis0, fam, solve)
        refused.append(why)
        if band is not None:
            bands[i] = band
    refused = refuse_overlapping(bands, families, refused)
    if not measured[0].size:
        refused = [r or f"family {fam}: {measured[2]}" for fam, r in zip(families, refused, strict=True)]
    for i in np.flatnonzero([not r for r in refused]):
        zeta[i] = band_damping(bands[i], *measured[:2])
    interval = ["" if samples is not None else "no posterior samples"] * n_f
    ok = np.isfinite(zeta)
    if ok.any():
        mis = blade_modes(mistuned, family_damping(mis0.frequencies_hz, bands[ok], zeta[ok]), POINT)
        tun = blade_modes(tuned, family_damping(tun0.frequencies_hz, bands[ok], zeta[ok]), POINT)
        for i in np.flatnonzero(ok):
            refs = {}
            for e, eo in enumerate(eos):
                a = amplification_factor(mis, tun, eo, tuple(bands[i]), family=families[i])
                tpeak[i, e] = a.tuned_peak_hz
                if _at_edge(a.tuned_peak_hz, bands[i]):
                    continue  # no resonance of the family in the band: a ratio of two flanks is no AF
                af[i, e], worst[i, e] = a.af, a.worst_blade
                peak[i, e] = a.mistuned.peak_hz[a.worst_blade - 1]
                refs[e] = a.tuned
            if samples is None or d1b is None:
                continue
            dl, psi, interval[i] = family_changes(samples, bands[i], d1b)
            if dl is None or not refs:
                continue
            try:
                fi = family_interval(mis, tun, bands[i], eos, refs, dl, psi, families[i], test_hz, d1b, d1b_fits)
                ci[i], ci_c[i], pw[i], sigma[i], sigma_a[i] = fi.ci90, fi.ci90_contact, fi.p_worst, fi.sigma, fi.sigma_a
            except ROMError as exc:  # a sample beyond the perturbation's reach: no interval, the AF stands
                ci[i], ci_c[i], pw[i] = np.nan, np.nan, np.nan
                interval[i] = f"family {families[i]}: {exc}"
    bands[[bool(r) for r in refused]] = np.nan
    interval = [r or why for r, why in zip(refused, interval, strict=True)]
    return ROMResponse(rom, solve, bands, zeta, af, worst, peak, tpeak, tuple(refused), ci, pw, tuple(interval),
                       0 if samples is None else samples.n_samples, ci_c, sigma, sigma_a)


def _measured(fits: dict) -> tuple:
    """:func:`measured_damping`, or no damping with the reason: each family is then refused, the run goes on."""
    try:
        return measured_damping(fits)
    except ROMError as exc:
        return np.zeros(0), np.zeros(0), str(exc)


def _axes(delta_all: np.ndarray, n_families: int) -> tuple[int, tuple, tuple]:
    """Blades N (``delta_all``'s rows), the families 1..``n_families`` and the engine orders 0..⌊N/2⌋."""
    n = int(delta_all.shape[0])
    return n, tuple(range(1, n_families + 1)), tuple(range(n // 2 + 1))


def rom_response_node(delta_all: np.ndarray, mistuned: FullSolve, tuned, d1b=None, *, rom: str, solve: str,
                      n_families: int = N_FAMILIES, **fits_and_posts) -> ROMResponse:
    """The node of one ROM (``rom``: ``"updated"`` or ``"paper"``): its AF per family 1..``n_families`` and EO
    0..⌊N/2⌋, and their intervals over the contact posterior's samples. One node per ROM, so that the paper's
    ROM's (about half of the work) runs while the updated ROM is still being fitted.

    Parameters
    ----------
    delta_all : ndarray, shape (n_blades, n_delta)
        The blades' δ (its rows count the blades).
    mistuned : FullSolve
        The ROM's full-assembly solve with the run's answer (``full/<solve>``).
    tuned : rom.fe_assembly.AssemblyModes
        The ROM's tuned disk (:func:`tuned_node`).
    d1b : rom.fe_assembly.AssemblyModes, optional
        The ROM's disk–one-blade modes (:func:`d1b_node`), for the intervals.
    **fits_and_posts
        ``TestFit`` of the full-assembly test (``assembly``) or of the disk–one-blade tests: the families'
        damping; ``post_NN``: the experimental input's :class:`identify.posterior.JointPosterior` of joint NN,
        the intervals' samples; ``d1bfit_NN``: joint NN's disk–one-blade fit, the blade-point amplitudes.
    """
    posts = {int(k[5:]): v for k, v in fits_and_posts.items() if k.startswith("post_")}
    d1b_fits = {int(k[7:]): v for k, v in fits_and_posts.items() if k.startswith("d1bfit_")}
    fits = {k: v for k, v in fits_and_posts.items() if not k.startswith(("post_", "d1bfit_"))}
    n, families, eos = _axes(delta_all, n_families)
    test = fits.get("assembly")
    test_hz = None if test is None else np.asarray(test.model.frequencies_hz, float)
    return _rom_response(rom, solve, mistuned.modes, tuned, families, eos, _measured(fits),
                         contact_samples(n, posts), d1b, test_hz, d1b_fits)


def response_node(delta_all: np.ndarray, paper: ROMResponse, exported: ROMResponse | None = None,
                  truth: tuple | None = None, *, n_joints: int = 0, n_families: int = N_FAMILIES,
                  **fits) -> Response:
    """The node: the ROMs' AFs (:func:`rom_response_node`, the exported ROM's first) with the truth's AF.

    ``truth`` is the truth twin's (mistuned, tuned) modes (:func:`truth_node`); ``n_joints`` the unfilmed joints
    whose posteriors the intervals sample; ``fits`` the tests' fits that give the families' damping.
    """
    measured = _measured(fits)
    n, families, eos = _axes(delta_all, n_families)
    roms = (paper,) if exported is None else (exported, paper)
    true = None if truth is None else _rom_response("truth", "truth", truth[0], truth[1], families, eos, measured)
    n_samples = roms[0].n_samples
    source = (f"{n_samples} samples of the contact posterior at {n_joints} unfilmed joints"
              + (", each with every blade's frequency off by the family's discrepancy against the full-assembly test"
                 if "assembly" in fits else " (no full-assembly test: no blade-frequency discrepancy)")
              + (" and every blade's point amplitude off by the scatter of the disk–one-blade tests' amplitudes"
                 if any(np.isfinite(r.amplitude_discrepancy).any() for r in roms)
                 else " (no disk–one-blade test gives a mass-normalised blade-point amplitude: no amplitude "
                      "discrepancy)")
              if n_samples else "no contact posterior in this run (--method knn)")
    return Response(n, POINT, families, eos, measured[2], roms, true, source)


def add_response_node(p, campaign, opts) -> None:
    """Add the ``response`` node, each ROM's AF node, their tuned disks, disk–one-blade modes and the truth's
    modes to a campaign's pipeline ``p``."""
    solve = {"cyclic": names.DISK_CYCLIC, "bd": names.FE_MODEL, "blade": names.BLADE_RUBIN,
             "baseline": names.BASELINE, "delta_all": names.DELTA_ALL, "n_modes": names.N_FULL_MODES}
    d1b = {"disk": names.DISK_CB, "bd": names.FE_MODEL, "blade": names.BLADE_RUBIN, "baseline": names.BASELINE,
           "delta_all": names.DELTA_ALL}
    kind = "assembly" if campaign.of_type("assembly") else "d1b"
    tests = {names.test_name(t): names.ema(names.test_name(t)) for t in campaign.of_type(kind)}
    unfilmed = [t.index for t in campaign.of_type("d1b") if t.index not in campaign.known_joints]
    samples = ({**{f"post_{j:02d}": names.posterior_joint("experimental", j) for j in unfilmed},
                **{f"d1bfit_{t.index:02d}": names.ema(names.test_name(t)) for t in campaign.of_type("d1b")}}
               if opts.posterior else {})
    # per ROM: its full solve, its update, its words, and its nodes (tuned disk, d1b modes, AF)
    roms = {"paper": ("posterior" if opts.posterior else "identified", None, "paper's ROM",
                      (names.RESPONSE_TUNED_PAPER, names.RESPONSE_D1B_PAPER, names.RESPONSE_AF_PAPER))}
    if opts.updated:
        roms["updated"] = ("updated", names.rom_update("answer"), "updated ROM",
                           (names.RESPONSE_TUNED_UPDATED, names.RESPONSE_D1B_UPDATED, names.RESPONSE_AF_UPDATED))
    af = {}
    for rom, (solved, update, what, (tuned, d1b_modes, af_name)) in roms.items():
        upd = {} if update is None else {"update": update}
        p.add(Node(tuned, tuned_node, {**solve, **upd}, {}, label=f"tuned disk ({what})"))
        inputs = {"delta_all": names.DELTA_ALL, "mistuned": names.full(solved), "tuned": tuned, **samples, **tests}
        if opts.posterior:
            p.add(Node(d1b_modes, d1b_node, {**d1b, **upd}, {}, label=f"disk–one-blade modes ({what})"))
            inputs["d1b"] = d1b_modes
        # version 2: the peaks refined by Newton's method (peak frequencies move by 1e-10; design §8.75)
        af[rom] = p.add(Node(af_name, rom_response_node, inputs,
                             {"rom": rom, "solve": solved, "n_families": N_FAMILIES}, version=2,
                             label=f"amplification factors ({what})")).name
    inputs = {"delta_all": names.DELTA_ALL, "paper": af["paper"], **tests}
    if "updated" in af:
        inputs["exported"] = af["updated"]
    truth = campaign.truth_dir
    if truth is not None and (Path(truth) / TRUTH_FILE).is_file():
        digest = hashlib.sha256((Path(truth) / TRUTH_FILE).read_bytes()).hexdigest()
        p.add(Node(names.RESPONSE_TRUTH, truth_node, {}, {"truth_dir": str(truth), "sha256": digest},
                   where="parent", stored=False, content_key=True, label="the truth's modes"))
        inputs["truth"] = names.RESPONSE_TRUTH
    p.add(Node(names.RESPONSE, response_node, inputs,
               {"n_joints": len(unfilmed) if opts.posterior else 0, "n_families": N_FAMILIES}, version=9,
               label="forced response and amplification factors"))
