"""The forced response under engine-order excitation and the mistuning amplification factor (issue 47).

One node, ``response``: for the ROM the run exports (the updated one where it ran, else the paper's) and for
the paper's beside it, the AF (:func:`rom.forced.amplification_factor`) of each of the lowest families and each
engine order 0..⌊N/2⌋, with the worst blade. It takes the full-assembly solves the run already made (the
mistuned disks) and solves only what no node holds: each ROM's *tuned* disk, every joint with the films' mean
pattern (the baseline's) and every blade the blades' mean (δ, and ε for the updated ROM). Each family gets the
damping the EMA measured in its band (the full-assembly test, else the disk–one-blade tests); every mode of the
model takes its family's ratio (:func:`rom.forced.family_damping`), the tuned disk's and the mistuned one's alike.

A family is refused, with its reason, where the solves may miss a mode of its band: the AF needs every one.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from rom.errors import ROMError
from rom.forced import amplification_factor, blade_modes, family_band, family_damping

from . import names
from .full import FullSolve, solve_assembly
from .graph import Node
from .rom_update import updated_blade

__all__ = ["N_FAMILIES", "POINT", "ROMResponse", "Response", "refuse_overlapping", "tuned_node", "response_node",
           "add_response_node"]

#: Families the run computes by default (the lowest), and the blade point loaded and read on every blade.
N_FAMILIES, POINT = 3, 1


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
    """

    n_blades: int
    point: int
    families: tuple
    eos: tuple
    damping_source: str
    roms: tuple


def _measured_damping(fits: dict) -> tuple[np.ndarray, np.ndarray, str]:
    """(frequencies Hz, damping ratios, source): the full-assembly EMA's modes, else the d1b tests' together."""
    use = ["assembly"] if "assembly" in fits else sorted(fits)
    f = np.concatenate([np.asarray(fits[k].model.frequencies_hz, float) for k in use] or [np.zeros(0)])
    z = np.concatenate([np.asarray(fits[k].model.damping_ratio, float) for k in use] or [np.zeros(0)])
    ok = np.isfinite(f) & np.isfinite(z) & (z > 0) & (z < 1)
    if not ok.any():
        raise ROMError(f"no EMA mode with a damping ratio in (0, 1) among the tests {use}: the forced response "
                       "needs each family's measured damping")
    return f[ok], z[ok], ("the full-assembly test's EMA" if use == ["assembly"] else "the disk–one-blade tests' EMA")


def _band_damping(band, f: np.ndarray, z: np.ndarray) -> float:
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


def _rom_response(rom: str, solve: str, mistuned, tuned, families, eos, measured) -> ROMResponse:
    """One ROM's AFs: ``mistuned`` and ``tuned`` are :class:`rom.fe_assembly.AssemblyModes`."""
    mis0, tun0 = blade_modes(mistuned, 0.01, POINT), blade_modes(tuned, 0.01, POINT)
    shape = (len(families), len(eos))
    af, worst = np.full(shape, np.nan), np.zeros(shape, int)
    peak, tpeak = np.full(shape, np.nan), np.full(shape, np.nan)
    bands, zeta, refused = np.full((len(families), 2), np.nan), np.full(len(families), np.nan), []
    for i, fam in enumerate(families):
        band, why = _family(tun0, mis0, fam, solve)
        refused.append(why)
        if band is not None:
            bands[i] = band
    refused = refuse_overlapping(bands, families, refused)
    if not measured[0].size:
        refused = [r or f"family {fam}: {measured[2]}" for fam, r in zip(families, refused, strict=True)]
    for i in np.flatnonzero([not r for r in refused]):
        zeta[i] = _band_damping(bands[i], *measured[:2])
    ok = np.isfinite(zeta)
    if ok.any():
        mis = blade_modes(mistuned, family_damping(mis0.frequencies_hz, bands[ok], zeta[ok]), POINT)
        tun = blade_modes(tuned, family_damping(tun0.frequencies_hz, bands[ok], zeta[ok]), POINT)
        for i in np.flatnonzero(ok):
            for e, eo in enumerate(eos):
                a = amplification_factor(mis, tun, eo, tuple(bands[i]), family=families[i])
                tpeak[i, e] = a.tuned_peak_hz
                if _at_edge(a.tuned_peak_hz, bands[i]):
                    continue  # no resonance of the family in the band: a ratio of two flanks is no AF
                af[i, e], worst[i, e] = a.af, a.worst_blade
                peak[i, e] = a.mistuned.peak_hz[a.worst_blade - 1]
    bands[[bool(r) for r in refused]] = np.nan
    return ROMResponse(rom, solve, bands, zeta, af, worst, peak, tpeak, tuple(refused))


def tuned_node(cyclic, bd, blade, baseline, delta_all: np.ndarray, n_modes: int, update=None):
    """The node: a ROM's tuned disk, every joint with the pattern ``baseline`` and every blade the blades' mean
    (δ, and ε of ``update`` on its contact springs where the ROM was updated); its
    :class:`rom.fe_assembly.AssemblyModes`."""
    if update is not None:
        blade, delta_all = updated_blade(blade, bd, update.stiffness), delta_all + update.corrections
    mean = np.broadcast_to(np.mean(delta_all, axis=0), delta_all.shape).copy()
    return solve_assembly(cyclic, bd, blade, [baseline] * delta_all.shape[0], mean, n_modes).modes


def response_node(delta_all: np.ndarray, paper: FullSolve, tuned_paper, exported: FullSolve | None = None,
                  tuned_exported=None, *, paper_solve: str,
                  exported_solve: str | None = None, n_families: int = N_FAMILIES, **fits) -> Response:
    """The node: AF per family 1..``n_families`` and EO 0..⌊N/2⌋ of the exported ROM and of the paper's.

    Parameters
    ----------
    delta_all : ndarray, shape (n_blades, n_delta)
        The blades' δ (its rows count the blades).
    paper : FullSolve
        The paper's ROM with the run's answer (``full/identified`` or ``full/posterior``).
    tuned_paper, tuned_exported : rom.fe_assembly.AssemblyModes
        The tuned disks (:func:`tuned_node`) of the paper's ROM and of the updated one.
    exported : FullSolve, optional
        The updated ROM's solve (``full/updated``), where the run updated the ROM.
    paper_solve, exported_solve : str
        The solves' names (members of ``full/``).
    **fits : TestFit
        The EMA of the full-assembly test (``assembly``) or of the disk–one-blade tests: the families' damping.
    """
    try:
        measured = _measured_damping(fits)
    except ROMError as exc:  # no damping to give the families: each is refused with the reason, the run goes on
        measured = (np.zeros(0), np.zeros(0), str(exc))
    n = int(delta_all.shape[0])
    families, eos = tuple(range(1, n_families + 1)), tuple(range(n // 2 + 1))
    roms = []
    if exported is not None:
        roms.append(_rom_response("updated", exported_solve, exported.modes, tuned_exported, families, eos,
                                  measured))
    roms.append(_rom_response("paper", paper_solve, paper.modes, tuned_paper, families, eos, measured))
    return Response(n, POINT, families, eos, measured[2], tuple(roms))


def add_response_node(p, campaign, opts) -> None:
    """Add the ``response`` node and its tuned disks to a campaign's pipeline ``p``."""
    paper = "posterior" if opts.posterior else "identified"
    solve = {"cyclic": names.DISK_CYCLIC, "bd": names.FE_MODEL, "blade": names.BLADE_RUBIN,
             "baseline": names.BASELINE, "delta_all": names.DELTA_ALL, "n_modes": names.N_FULL_MODES}
    p.add(Node(names.RESPONSE_TUNED_PAPER, tuned_node, solve, {}, label="tuned disk (paper's ROM)"))
    inputs = {"delta_all": names.DELTA_ALL, "paper": names.full(paper), "tuned_paper": names.RESPONSE_TUNED_PAPER}
    params = {"paper_solve": paper, "n_families": N_FAMILIES}
    if opts.updated:
        p.add(Node(names.RESPONSE_TUNED_UPDATED, tuned_node, {**solve, "update": names.rom_update("answer")}, {},
                   label="tuned disk (updated ROM)"))
        inputs.update(exported=names.full("updated"), tuned_exported=names.RESPONSE_TUNED_UPDATED)
        params["exported_solve"] = "updated"
    kind = "assembly" if campaign.of_type("assembly") else "d1b"
    inputs.update({names.test_name(t): names.ema(names.test_name(t)) for t in campaign.of_type(kind)})
    p.add(Node(names.RESPONSE, response_node, inputs, params, label="forced response and amplification factors"))
