"""The run's ROM sections: the full-assembly validation (paper Table 8, Figs. 24 and 28) and the updated ROM."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import ema
from ema.numbering import rom_modal_model
from identify.plots import plot_mode_comparison
from identify.rom_update import LOG_PRIOR_STD

from .output_files import save_figure, write_csv
from .rom_summary import CASE_HEADER, CORRECTION_HEADER, FAMILY_HEADER, case_rows, correction_rows, family_rows
from .run_figures import plot_rom_update
from .stages import PAPER_TABLE8, RunResult

__all__ = ["CASE_TITLES", "full_section", "rom_section"]

#: The title of each validation case's figure.
CASE_TITLES = {"A": "Case A (k-NN): ROM with patterns identified from the numerical input vs ROM with the reference "
                    "patterns",
               "B": "Case B (k-NN): ROM with the identified patterns (experimental input, bias removed) vs measured",
               "B_no_bias": "Case B without the bias correction vs measured",
               "C": "Case C: ROM with the reference patterns vs measured",
               "baseline_A": "Baseline vs the ROM with the reference patterns",
               "baseline_B": "Baseline vs measured",
               "posterior_A": "Case A with the contact posterior's answers (numerical input)",
               "posterior_B": "Case B with the contact posterior's answers (experimental input, bias removed)",
               "updated_A": "Case A, updated ROM: identified (numerical input) vs reference patterns",
               "updated_B": "Case B, updated ROM (beyond Eq. 19): identified patterns vs measured",
               "updated_C": "Case C, updated ROM: reference patterns vs measured"}


def _table8_rows(cases: dict) -> list[list]:
    rows = []
    for key, label in (("A", "Case A (k-NN)"), ("B", "Case B (k-NN)"), ("B_no_bias", "Case B (k-NN), no bias "
                                                                                   "correction"), ("C", "Case C")):
        v, p = cases[key], PAPER_TABLE8.get(key, {})
        rows.append([label, *(("unavailable",) * 3 if v is None else (v["mean_abs_df_pct"], v["mean_mac"],
                                                                       v["n_modes"])),
                     p.get("mean_abs_df_pct", ""), p.get("mean_mac", "")])
    for key, v in (cases.get("posterior") or {}).items():
        rows.append([f"Case {key} (posterior)", *(("unavailable",) * 3 if v is None else (
            v["mean_abs_df_pct"], v["mean_mac"], v["n_modes"])), "", ""])
    for key in ("A", "B"):
        v = cases["baseline"][key]
        rows.append([f"baseline (as Case {key})", *(("unavailable",) * 3 if v is None
                                                     else (v["mean_abs_df_pct"], v["mean_mac"], v["n_modes"])), "", ""])
    return rows


def full_section(res: RunResult, out: Path) -> dict:
    figs = []
    for key, comp in res.validation.comparisons.items():
        figs.append({"file": save_figure(lambda c=comp, k=key: plot_mode_comparison(c, title=CASE_TITLES[k]),
                                  out / f"full_{key}.png"),
                     "caption": CASE_TITLES[key] + " (paper Figs. 24, 28)."})
        write_csv(out / f"full_pairs_{key}.csv", ["reference mode", "predicted mode", "f reference (Hz)",
                                             "f predicted (Hz)", "Δf (%)", "MAC"],
             [[int(a) + 1, int(b) + 1, float(fa), float(fb), float(e), float(m)] for (a, b), fa, fb, e, m in
              zip(comp.pairs, comp.freq_ref_hz, comp.freq_pred_hz, comp.freq_error_pct, comp.mac, strict=True)])
    tables = [{"file": write_csv(out / "table8.csv", ["case", "mean |Δf| (%)", "mean MAC", "modes", "paper |Δf| (%)",
                                                 "paper MAC"], _table8_rows(res.cases)),
               "caption": "Paper Table 8 with the baseline rows: the mean known pattern at every unfilmed joint."}]
    exported = next(k for k in ("updated", "posterior", "identified") if k in res.full)
    answer = "the contact posterior" if res.options.posterior else "the k-NN"
    rom = "updated ROM (beyond Eq. 19)" if exported == "updated" else "paper's ROM"
    ema.write_modes(out / "identified_rom_modes.uff", rom_modal_model(res.full[exported]),
                    id1=f"bladetwin identified {rom}, {answer}, campaign {res.campaign.name}")
    return {"id": "full", "title": "Full bladed disk: Cases A, B, C (Table 8)",
            "text": ["Case A: ROM with patterns identified from the numerical input against the ROM with the "
                     "reference patterns. Case B: ROM with the patterns identified from the measurements against the "
                     "measured modes. Case C: ROM with the reference patterns against the measured modes (the model "
                     "error). The baseline gives every unfilmed joint the majority pattern of the films. The "
                     "identified ROM's modes are in identified_rom_modes.uff (UFF 55, rig DOF labels): the "
                     f"{rom} with {answer}'s answers."],
            "figures": figs, "tables": tables}


def rom_section(res: RunResult, out: Path, rom: dict | None) -> list[dict]:
    """The updated ROM beside the paper's: Cases A, B, C, its parameters, the family-wise view (empty if off)."""
    if rom is None:
        return []
    upd = res.rom_update["answer"]
    modes = np.flatnonzero(np.any(upd.corrections != 0, axis=0))
    freq = upd.frequency_correction_pct(res.delta_all)[:, modes]
    fig = save_figure(lambda: plot_rom_update(freq, [f"free mode {i + 1} ({upd.free_hz[i]:.0f} Hz)" for i in modes],
                               res.validation.families), out / "rom_update.png")
    def cells(rows):  # a figure that does not exist (None) is an empty cell
        return [["" if v is None else v for v in r] for r in rows]

    tables = [{"file": write_csv(out / "rom_cases.csv", CASE_HEADER, cells(case_rows(rom))),
               "caption": "Cases A, B and C with the paper's ROM and with the updated ROM."},
              {"file": write_csv(out / "rom_corrections.csv", CORRECTION_HEADER, cells(correction_rows(res))),
               "caption": "Each blade's in-situ corrections and its disk-one-blade residuals, both ROMs.",
               "figure": fig},  # the figure's left panel shows it, its right panel the families
              {"file": write_csv(out / "rom_families.csv", FAMILY_HEADER, family_rows(res.validation.families)),
               "caption": "Family by family: frequency error, MAC and subspace correlation (principal angles).",
               "figure": fig}]
    p = rom["updated"]["parameters"]
    k = p["contact_stiffness"]
    stiff = "rigid ties (no filmed joint with a disk-one-blade test)" if k is None else _stiffness_text(k)
    r = p["d1b_rms_residual_pct"]
    text = ["The paper's ROM carries each blade's free-test deltas into the assembly (Eq. 19) and ties contacting "
            "nodes rigidly. The updated ROM (beyond the paper, docs/equations.md) adds per-blade in-situ corrections "
            "of the free modes each disk-one-blade test sees, and a contact stiffness for every joint, both fitted on "
            "the disk-one-blade tests only: the full-assembly test is never used in the fit, it is the validation. "
            "The exported ROM (identified_rom_modes.uff) is the updated one.",
            f"Contact stiffness: {stiff}. Disk-one-blade RMS residual over the tracked modes: paper's ROM "
            f"{r['paper']:.3f} %, updated ROM {r['updated']:.3f} %."]
    for rep in p.get("replaced_joints", []):
        text.append(f"Joint {rep['joint']}: with the posterior's answer, its blade's in-situ correction lay beyond "
                    f"what the blades' scatter explains, so the updated ROM takes the posterior draw that the "
                    f"joint's disk-one-blade test bears out best (contact area L {rep['area_pct'][0]:.0f} %, "
                    f"R {rep['area_pct'][1]:.0f} %); the contact answer itself is unchanged.")
    for kind in ("paper", "updated"):
        b = rom[kind]["cases"].get("B")
        if b:
            text.append(f"Case B, {kind} ROM: mean |Δf| {b['mean_abs_df_pct']:.3f} %, mean MAC {b['mean_mac']:.3f} "
                        f"({b['n_modes']} modes).")
    return [{"id": "rom_update", "title": "The ROM updated beyond Eq. 19", "text": text,
             "figures": [{"file": fig, "caption": "Left: in-situ corrections. Right: each measured mode family's "
                                                  "subspace correlation with the ROM's modes in its band."}],
             "tables": tables}]


def _stiffness_text(k: dict) -> str:
    """The fitted contact stiffness in words: each value with what the data resolve of it, and what it is."""
    def one(name: str, value: float, log_std: float) -> str:
        seen = ("its prior's: the tests do not see it" if log_std >= 0.99 * LOG_PRIOR_STD else
                "what the data resolve")
        return f"{name} = {value:.3g} N/m³ (±{log_std:.2f} in ln k, {seen})"

    text = (f"{one('k_n', k['normal_n_per_m3'], k['log_std'][0])}, "
            f"{one('k_t', k['tangential_n_per_m3'], k['log_std'][1])}, fitted on joints "
            f"{', '.join(str(j) for j in k['fitted_on_joints'])}. It is an effective stiffness of this ROM: the "
            "model's own error is absorbed into it, so the true joints' may lie far off")
    if not k.get("settled", True):
        text += (f"; the fit stopped at its limit of {k['iterations']} iterations before it settled, on a valley "
                 "where k_n and the blades' corrections trade, so it would have moved further")
    return text
