"""The calibration's outputs: ``summary.json:calibration`` and the report's section (paper §5, Figs. 9–13)."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from .output_files import save_figure, write_csv
from .stages import RunResult

__all__ = ["calibration_summary", "calibration_section"]

_COMPONENTS = ("disk", "blade")


def calibration_summary(res: RunResult) -> dict:
    """``summary.json:calibration``: per component the target, E and ρ before and after, ρ's source; the modes."""
    cal = res.calibration
    if cal is None:
        return {"enabled": False, "disk": None, "blade": None, "notes": ["not run (--no-calibrate)"], "modes": []}
    return {"enabled": True, **cal.to_dict(), "modes": cal.mode_rows()}


def _plot(rows: list[dict]):
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4), constrained_layout=True)
    for ax, name in zip(axes, _COMPONENTS, strict=True):
        mine = [r for r in rows if r["component"] == name]
        x = np.arange(1, len(mine) + 1)
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.plot(x, [r["before_pct"] for r in mine], "o--", color="C3", label="model before calibration")
        ax.plot(x, [r["after_pct"] for r in mine], "s-", color="C0", label="after calibration")
        ax.set_xlabel(f"{name} mode (test order)")
        ax.set_ylabel("(f model − f test) / f test (%)")
        ax.set_title(f"free {name}")
        ax.set_xticks(x)
    axes[0].legend(fontsize=8)
    return fig


def calibration_section(res: RunResult, out: Path) -> dict | None:
    """The report's calibration section (None when the run did not calibrate); writes its CSV files and figure."""
    s = calibration_summary(res)
    if not s["enabled"]:
        return None
    head = ["component", "target (Hz)", "model before (Hz)", "E before (GPa)", "E after (GPa)", "E change (%)",
            "ρ before (kg/m³)", "ρ after (kg/m³)", "ρ from"]
    rows = []
    for name in _COMPONENTS:
        c = s[name]
        if c is not None:
            rows.append([name, c["target_hz"], c["model_hz"], c["E_before_pa"] / 1e9, c["E_after_pa"] / 1e9,
                         c["E_change_pct"], c["rho_before_kg_m3"], c["rho_after_kg_m3"],
                         "weighed mass" if c["rho_source"] == "masses" else "model (not weighed)"])
    modes = s["modes"]
    mode_rows = [[r["component"], r["mode"], r["test_hz"], r["before_hz"], r["before_pct"], r["after_hz"],
                  r["after_pct"]] for r in modes]
    tables = [{"file": write_csv(out / "calibration.csv", head, rows),
               "caption": "Material calibration (paper §5, Table 4): the disk's E on its first measured frequency, "
                          "the blades' E on the mean of their squared first frequencies, ρ from the weighed masses."},
              {"file": write_csv(out / "calibration_modes.csv", ["component", "mode", "test (Hz)", "model before (Hz)",
                                                                  "before (%)", "model after (Hz)", "after (%)"],
                                  mode_rows),
               "caption": "Each free-blade (√ of the blades' mean f²) and free-disk mode against the model, before "
                          "and after calibration (paired by nearest frequency)."}]
    figs = []
    drawn = save_figure(lambda: _plot(modes), out / "calibration.png") if modes else None
    if drawn:
        figs.append({"file": drawn, "caption": "The model's frequency error on the free components before and "
                                               "after calibration (paper Figs. 9–13)."})
    text = ["bladetwin calibrates E and ρ of the disk and the blades before any reduction, as the paper's §5 does; "
            "every ROM of the run is the calibrated one (on by default; `--no-calibrate` keeps the handbook "
            "materials)."]
    text += [f"Note: {n}." for n in s["notes"]]
    return {"id": "calibration", "title": "Material calibration (paper §5, Table 4)", "text": text,
            "figures": figs, "tables": tables}
