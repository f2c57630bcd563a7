"""summary.json's ``rom`` block and the ROM update's tables: the paper's ROM beside the updated one.

Cases A, B and C of both ROMs, and the control B_baseline, come from the validation node; the updated ROM's
parameters (contact stiffness, each blade's in-situ corrections) from :mod:`bladetwin.stages.rom_update`.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

__all__ = ["CASES", "CONTROL_TEXT", "rom_summary", "correction_rows", "CORRECTION_HEADER", "family_rows",
           "FAMILY_HEADER", "case_rows", "CASE_HEADER"]

CORRECTION_HEADER = ["blade", "free mode", "free frequency (Hz)", "δ free (%)", "in-situ correction (% frequency)",
                     "d1b RMS residual, paper ROM (%)", "d1b RMS residual, updated ROM (%)"]
FAMILY_HEADER = ["case", "ROM", "band low (Hz)", "band high (Hz)", "measured modes", "paired", "mean |Δf| (%)",
                 "mean MAC", "subspace cos (largest angle)", "subspace mean cos²"]
CASE_HEADER = ["case", "paper |Δf| (%)", "paper MAC", "paper modes", "updated |Δf| (%)", "updated MAC",
               "updated modes"]


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _parameters(res) -> dict:
    """The updated ROM's fitted parameters (JSON-ready)."""
    upd = res.rom_update["answer"]
    fit = res.rom_update.get("stiffness")
    stiff = None
    if fit is not None:
        stiff = {"normal_n_per_m3": fit.stiffness.normal_n_per_m3,
                 "tangential_n_per_m3": fit.stiffness.tangential_n_per_m3,
                 "log_std": [float(v) for v in fit.log_std], "fitted_on_joints": [int(j) for j in fit.joints],
                 "iterations": int(fit.n_iter), "settled": bool(fit.settled)}
    freq = upd.frequency_correction_pct(res.delta_all)
    blades = []
    for b in range(upd.corrections.shape[0]):
        modes = np.flatnonzero(upd.corrections[b])
        blades.append({"blade": b + 1, "calibrated": bool(upd.calibrated[b]),
                       "free_modes": [int(i) + 1 for i in modes],
                       "eigenvalue_correction_pct": [float(100 * upd.corrections[b, i]) for i in modes],
                       "frequency_correction_pct": [float(freq[b, i]) for i in modes]})
    # joints whose answer the updated ROM replaced by a posterior draw its test bears out (design §8.84)
    replaced = [{"joint": int(j), "area_pct": [float(100 * pat.L.mean()), float(100 * pat.R.mean())]}
                for j, pat in upd.replaced]
    return {"contact_stiffness": stiff, "rigid_ties": fit is None, "blades": blades, "replaced_joints": replaced,
            "d1b_rms_residual_pct": {"paper": _rms(upd.residual_paper_pct), "updated": _rms(upd.residual_pct)}}


def rom_summary(res) -> dict | None:
    """summary.json's ``rom``: ``paper.cases``, ``updated.cases`` (A, B, B_baseline, C: :data:`CASES`),
    ``updated.parameters`` and the family-wise view; ``None`` when the update did not run."""
    rom = res.cases.get("rom")
    if rom is None or "answer" not in res.rom_update:
        return None
    fam = res.validation.families
    return {"paper": {"cases": rom["paper"], "families": {k: [asdict(r) for r in fam.get(f"paper_{k}", [])]
                                                          for k in ("B", "C")}},
            "updated": {"cases": rom["updated"], "parameters": _parameters(res),
                        "families": {k: [asdict(r) for r in fam.get(f"updated_{k}", [])] for k in ("B", "C")}}}


#: The rows of the cases' table: B (the run's answer) between the control and C (the true patterns).
CASES = ("A", "B", "B_baseline", "C")

#: What the control ``B_baseline`` means, in one line (the report prints it beside the table).
CONTROL_TEXT = ("B_baseline is the control: Case B with the baseline pattern (the films' majority) at every "
                "unfilmed joint, each blade's in-situ correction re-fitted for it, against the same full-assembly "
                "test; where B_baseline ≤ B, the identified contact does not improve the ROM's match with the test.")


def case_rows(rom: dict) -> list[list]:
    """Cases A, B, the control B_baseline and C of both ROMs side by side (rows of :data:`CASE_HEADER`)."""
    rows = []
    for k in CASES:
        row: list = [k]
        for kind in ("paper", "updated"):
            c = rom[kind]["cases"].get(k)
            row += [None, None, None] if c is None else [c["mean_abs_df_pct"], c["mean_mac"], c["n_modes"]]
        rows.append(row)
    return rows


def correction_rows(res) -> list[list]:
    """Each blade's in-situ corrections (rows of :data:`CORRECTION_HEADER`); uncalibrated blades get one row."""
    upd = res.rom_update["answer"]
    freq = upd.frequency_correction_pct(res.delta_all)
    rows = []
    for b in range(upd.corrections.shape[0]):
        r_paper, r_upd = _rms(upd.residual_paper_pct[b]), _rms(upd.residual_pct[b])
        modes = np.flatnonzero(upd.corrections[b])
        for i in modes if modes.size else [None]:
            rows.append([b + 1, None if i is None else int(i) + 1,
                         None if i is None else float(upd.free_hz[i]),
                         None if i is None else float(100 * res.delta_all[b, i]),
                         None if i is None else float(freq[b, i]), r_paper, r_upd])
    return rows


def family_rows(families: dict) -> list[list]:
    """The family-wise view of Cases B and C for both ROMs (rows of :data:`FAMILY_HEADER`)."""
    rows = []
    for name, fams in families.items():
        kind, case = name.split("_")
        for f in fams:
            rows.append([case, kind, f.f_low_hz, f.f_high_hz, f.n_measured, f.n_paired, f.mean_abs_df_pct,
                         f.mean_mac, f.subspace_cos_min, f.subspace_mean_cos2])
    return rows
