"""Validation nodes: the disk–one-blade feature table and the full assembly's Cases A/B/C (paper Table 8)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import ema
from ema.numbering import rom_modal_model
from identify.dataset import Dataset
from identify.validation import ModeComparison, compare_modes
from rom.fe_assembly import AssemblyModes

from .bias import Features, tracker_for
from .full import FullSolve

__all__ = ["MEASURED_WINDOW", "MEASURED_MAC_MIN", "FullValidation", "d1b_rows", "vs_measured", "case_figures",
           "families_vs_measured", "full_validation"]

#: Pairing of a ROM's modes with measured ones (Cases B, C): MAC-maximizing, within ±5 %, MAC ≥ 0.3, as the
#: rig's own Case C check (``lab.model_error``). Measured shapes in dense families can be poor; a mode without
#: a credible partner stays unpaired (counted in ``n_reference_modes``) rather than forced onto a distant one.
MEASURED_WINDOW, MEASURED_MAC_MIN = 0.05, 0.3


@dataclass(frozen=True, eq=False)
class FullValidation:
    """The full assembly's comparisons by name (``A``, ``B``, ``B_no_bias``, ``C``, ``baseline_A``,
    ``baseline_B``…), Table 8's figures (:func:`case_figures`), the notes on what was not compared, and the
    family-wise view of Cases B and C (``families``: name → list of :class:`identify.families.FamilyRow`)."""

    comparisons: dict
    cases: dict
    notes: list
    families: dict = field(default_factory=dict)


def d1b_rows(disk, blade, dataset: Dataset, features: Features, delta_all: np.ndarray, known: dict,
             identified: list, reference, numerical, *, source: str) -> list[dict]:
    """The node: each joint's feature frequencies (Hz), measured and by the ROM with its identified pattern
    (bias added back), and with the reference and numerical-input patterns where there are references."""
    tracker = tracker_for(disk, blade, dataset)
    feat = list(dataset.feature_modes)
    bias = features.bias
    rows = []
    for k, j in enumerate(int(j) for j in features.joints):
        # a filmed joint's identified pattern is its film: its ROM frequencies were tracked for the bias already
        f_id = (features.rom_known_hz[j] if j in features.rom_known_hz
                else tracker.track(identified[j - 1], delta_all[j - 1]).frequencies_hz)
        row = {"joint": j, "source": "film" if j in known else source, "measured_hz": features.measured_hz[k, feat],
               "identified_hz": f_id[feat] * (1 + bias[feat])}
        if reference is not None:
            row["reference_hz"] = tracker.track(reference[j - 1], delta_all[j - 1]).frequencies_hz[feat]
            row["numerical_hz"] = tracker.track(numerical[j - 1], delta_all[j - 1]).frequencies_hz[feat]
        rows.append(row)
    return rows


def _common(measured: ema.ModalModel, rom: AssemblyModes):
    from ema.mac import common_dofs

    from ..campaign import CampaignError

    model = rom_modal_model(rom)
    pa, pb, _ = common_dofs(measured, model)
    if pa.shape[0] < 2:
        raise CampaignError("the full-assembly test and the ROM share fewer than 2 measurement DOFs: the node "
                            "numbering of the UFF file does not follow the rig's convention (docs/campaign.md)")
    return model, pa, pb


def vs_measured(measured: ema.ModalModel, rom: AssemblyModes) -> ModeComparison:
    """A ROM's modes against the measured ones, on their common DOFs (shapes sign-aware through the MAC)."""
    model, pa, pb = _common(measured, rom)
    return compare_modes((measured.frequencies_hz, pa), (model.frequencies_hz, pb), freq_window=MEASURED_WINDOW,
                         mac_min=MEASURED_MAC_MIN)


def families_vs_measured(measured: ema.ModalModel, rom: AssemblyModes, comparison: ModeComparison) -> list:
    """The family-wise view (:func:`identify.families.family_view`) of one ROM against the measured modes."""
    from identify.families import family_view

    model, pa, pb = _common(measured, rom)
    return family_view(comparison, measured.frequencies_hz, pa, model.frequencies_hz, pb)


def case_figures(c: ModeComparison | None) -> dict | None:
    """Table 8's figures of one comparison: mean |Δf| (%), mean MAC, pairs, and the reference modes offered."""
    if c is None or not c.pairs.size:
        return None
    return {"mean_abs_df_pct": c.mean_abs_freq_error_pct, "mean_mac": c.mean_mac, "n_modes": int(len(c.pairs)),
            "n_reference_modes": int(c.mac_matrix.shape[0])}


def _in_band(m: AssemblyModes, f_max: float) -> AssemblyModes:
    keep = m.frequencies_hz <= f_max
    return AssemblyModes(m.frequencies_hz[keep], m.meas_shapes[:, keep], m.meas_labels)


def _measured_in_band(measured: ema.ModalModel, full: dict, notes: list) -> tuple[ema.ModalModel, float]:
    f_max = float(measured.frequencies_hz.max())
    top = float(min(m.frequencies_hz.max() for m in full.values()))
    if top < f_max:
        notes.append(f"The ROM's {len(next(iter(full.values())).frequencies_hz)} modes reach {top:.1f} Hz, below "
                     f"the highest measured mode ({f_max:.1f} Hz): the measured modes above are not compared.")
        keep = measured.frequencies_hz <= top
        measured = ema.ModalModel(measured.frequencies_hz[keep], measured.damping_ratio[keep],
                                  measured.shapes[:, keep], measured.dofs)
        f_max = top
    return measured, f_max


def full_validation(assembly=None, *, bias: bool, answer: str = "knn", **solves: FullSolve) -> FullValidation:
    """The node: Cases A, B, C and the baseline's, from the full solves by name and the assembly's EMA.

    With the updated ROM's solves (``updated``, ``updated_reference``, ``updated_numerical``), ``cases["rom"]``
    holds Cases A, B and C of the paper's ROM (with the run's ``answer``: ``"knn"`` or ``"posterior"``) and of
    the updated ROM, side by side, and the control ``B_baseline`` of each: Case B with the baseline pattern
    (the films' majority) at every unfilmed joint, for the updated ROM from its solve ``updated_baseline``
    (each blade's in-situ correction re-fitted for those patterns; its figures only, not in ``comparisons``).
    Where ``B_baseline`` ≤ ``B``, the identified contact does not improve the match with the test.
    """
    full = {name: s.modes for name, s in solves.items()}
    comps: dict[str, ModeComparison] = {}
    control: ModeComparison | None = None
    notes: list[str] = []
    measured = assembly.model if assembly is not None and assembly.model.n_modes else None
    f_max = None
    if measured is not None:
        measured, f_max = _measured_in_band(measured, full, notes)
        comps["B"] = vs_measured(measured, full["identified"])
        comps["baseline_B"] = vs_measured(measured, full["baseline"])
        if bias:
            comps["B_no_bias"] = vs_measured(measured, full["identified_no_bias"])
        if "reference" in full:
            comps["C"] = vs_measured(measured, full["reference"])
        if "posterior" in full:
            comps["posterior_B"] = vs_measured(measured, full["posterior"])
        for name, solve in (("updated_B", "updated"), ("updated_C", "updated_reference")):
            if solve in full:
                comps[name] = vs_measured(measured, full[solve])
        if "updated_baseline" in full:  # the control: its figures only (no comparison figure of its own)
            control = vs_measured(measured, full["updated_baseline"])
    else:
        notes.append("No full-assembly test: Cases B and C are unavailable.")
    if "reference" in full:
        ref = full["reference"] if f_max is None else _in_band(full["reference"], f_max)
        for name, other in (("A", "numerical"), ("baseline_A", "baseline"), ("posterior_A", "posterior_numerical")):
            if other not in full:
                continue
            comps[name] = compare_modes((ref.frequencies_hz, ref.meas_shapes),
                                        (full[other].frequencies_hz, full[other].meas_shapes))
        if "updated_numerical" in full:
            upd = full["updated_reference"] if f_max is None else _in_band(full["updated_reference"], f_max)
            comps["updated_A"] = compare_modes((upd.frequencies_hz, upd.meas_shapes),
                                               (full["updated_numerical"].frequencies_hz,
                                                full["updated_numerical"].meas_shapes))
    else:
        notes.append("Cases A and C need a reference pattern for every joint (truth/ of a virtual campaign, or "
                     "a film of every joint); this campaign has none, so they are unavailable.")
    cases = {k: case_figures(comps.get(k)) for k in ("A", "B", "B_no_bias", "C")}
    # The paper's ROM with the run's answer: the posterior's comparisons where it answered, else the k-NN's.
    paper, paper_solve = ("posterior_", "posterior") if answer == "posterior" else ("", "identified")
    families = {}
    if measured is not None and "updated" in full:
        by_case = {"paper_B": (paper + "B", paper_solve), "paper_C": ("C", "reference"),
                   "updated_B": ("updated_B", "updated"), "updated_C": ("updated_C", "updated_reference")}
        families = {name: families_vs_measured(measured, full[solve], comps[c])
                    for name, (c, solve) in by_case.items() if c in comps}
    cases["baseline"] = {"A": case_figures(comps.get("baseline_A")), "B": case_figures(comps.get("baseline_B"))}
    if "posterior" in full:
        cases["posterior"] = {k: case_figures(comps.get(f"posterior_{k}")) for k in ("A", "B")}
    if "updated" in full:
        updated = {k: case_figures(comps.get(f"updated_{k}")) for k in ("A", "B", "C")}
        cases["rom"] = {"paper": {"A": case_figures(comps.get(paper + "A")), "B": case_figures(comps.get(paper + "B")),
                                  "C": cases["C"], "B_baseline": cases["baseline"]["B"]},
                        "updated": {**updated, "B_baseline": case_figures(control)}}
    return FullValidation(comps, cases, notes, families)
