"""The run's EMA section: every test's stabilization diagram, the blade, disk, d1b and assembly tables, and
summary.json's ``ema``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import ema

from .output_files import blank, save_figure, write_csv
from .run_figures import plot_blade_deltas
from .stages import RunResult
from .stages.bias import MATCH_WINDOW
from .util import drawing_figures

__all__ = ["ema_section", "ema_modes", "assembly_table"]


def _stabilization(name: str, test, fit, frf, out: Path) -> dict:
    """One test's stabilization diagram, drawn from its stored diagram over its FRFs."""
    from ema.plots import plot_stabilization

    def draw():
        fig = plot_stabilization(fit.diagram, frf, selected_hz=fit.model.frequencies_hz)
        fig.axes[0].set_title(f"{test.file.name}: {_method_label(fit)}, "
                              f"{'picked by hand' if fit.picked else 'automatic selection'}, "
                              f"{fit.model.n_modes} modes")
        return fig

    families = " The dense mode families were then resolved by the rank-one residue fit (docs/ema.md): the " \
               "modes it added need not sit on a stable column." if "+families" in (fit.model.method or "") else ""
    return {"file": save_figure(draw, out / f"stabilization_{name}.png"),
            "caption": f"Stabilization diagram of {test.file.name} ({test.type} test), "
                       f"{'hand-picked poles' if fit.picked else 'automatic selection'}.{families}"}


def _families_figure(name: str, test, fit, frf, out: Path) -> list[dict]:
    """The zoom on a test's dense windows (four modes or more) after the family fit, beside its diagram."""
    from ema.family_windows import family_windows
    from ema.plots import plot_families

    f = fit.model.frequencies_hz
    windows = [w for w, _ in family_windows(fit.model.poles, frf, fit.model.band_hz or (f.min(), f.max()))
               if np.count_nonzero((f >= w[0]) & (f <= w[1])) >= 4]
    if not windows:
        return []
    return [{"file": save_figure(lambda: plot_families(frf, fit.model, windows), out / f"families_{name}.png"),
             "caption": f"Dense mode families of {test.file.name}: the RMS over all its FRFs, each divided by its "
                        "own median in the window (so that modes seen by a few points show), measured (black) "
                        "against the identified modal model (red, dashed), each mode a blue line."}]


def _method_label(fit) -> str:
    """The pole estimator, with "+FAMILIES" where the dense families were resolved (ema.fit(families=True))."""
    return (fit.model.method or fit.method).upper()


def _ema_tables(res: RunResult, out: Path, notes: list[str]) -> list[dict]:
    bf, bd_ = res.blades.frequencies_hz, res.blades.deltas_pct
    t_bf = write_csv(out / "blade_frequencies.csv", ["blade"] + [f"mode {m + 1} (Hz)" for m in range(bf.shape[1])],
                [[b + 1, *map(float, bf[b])] for b in range(bf.shape[0])])
    t_bd = write_csv(out / "blade_deltas.csv", ["blade"] + [f"δ mode {m + 1} (%)" for m in range(bd_.shape[1])],
                [[b + 1, *map(float, bd_[b])] for b in range(bd_.shape[0])])
    tables = [{"file": t_bd, "caption": "Blade mistuning δ (%), Eq. 37 (paper Table 2).", "heatmap": True},
              {"file": t_bf, "caption": "Blade natural frequencies (Hz), modes tracked by MAC."}]
    disk = [fit for t, fit in res.ema.values() if t.type == "disk"]
    if disk:
        try:
            dm = ema.disk_modes(disk[0].model)
        except ValueError as exc:  # e.g. disk points that are not one per sector: the run's answer stands
            notes.append(f"Disk modes: nodal diameters not assigned ({exc}).")
        else:
            ema.write_table(dm.assign(**disk[0].model.mode_quality().columns()), out / "disk_modes.csv")
            tables.append({"file": "disk_modes.csv", "caption": "Disk modes with their nodal diameters. "
                           + _COMPLEXITY})
    # Table 3: each joint's EMA frequencies matched one-to-one to the modes the dataset tracks (its blade
    # points are numbered per joint, so the tests share only the disk points and cannot be paired by MAC).
    mh = res.features.measured_hz
    write_csv(out / "d1b_frequencies.csv", ["joint"] + [f"mode {m + 1} (Hz)" for m in range(mh.shape[1])],
              [[int(j), *map(blank, mh[k])] for k, j in enumerate(res.joints)])
    tables.append({"file": "d1b_frequencies.csv", "caption": "Disk–one-blade natural frequencies (Hz) per joint "
                   "(paper Table 3): each joint's EMA modes matched to the tracked ROM modes within "
                   f"{100 * MATCH_WINDOW:.0f} % of the ROM's frequency moved by the joints' median offset, the "
                   "ROM's untracked modes taking their own (empty: not found)."})
    asm = [fit for t, fit in res.ema.values() if t.type == "assembly"]
    if asm:
        tables.append(assembly_table(asm[0].model, out))
    return tables


#: The caption's sentence on the complexity columns of every mode table.
_COMPLEXITY = ("MPC (modal phase collinearity, 1 for a real mode), MPD (mean phase deviation from the shape's "
               "best-fit line, 0° for a real mode) and MCF (mode complexity factor, 0 for a real mode, 1 for a "
               "travelling one) judge whether a mode is physical (docs/ema.md).")


def assembly_table(m: ema.ModalModel, out: Path) -> dict:
    """``assembly_modes.csv``: the full-assembly modes with their standard deviations and complexity indicators.

    Returns the report's table entry (file and caption).
    """
    f_std = m.frequency_std_hz if m.frequency_std_hz is not None else np.full(m.n_modes, np.nan)
    z_std = m.damping_std if m.damping_std is not None else np.full(m.n_modes, np.nan)
    mq = m.mode_quality()
    head = ["mode", "frequency (Hz)", "σ frequency (Hz)", "damping (%)", "σ damping (%)", "MPC", "MPD (°)", "MCF"]
    write_csv(out / "assembly_modes.csv", head,
              [[k + 1, float(m.frequencies_hz[k]), blank(f_std[k]), float(100 * m.damping_ratio[k]),
                blank(100 * z_std[k]), blank(mq.mpc[k]), blank(mq.mpd_deg[k]), blank(mq.mcf[k])]
               for k in range(m.n_modes)])
    return {"file": "assembly_modes.csv", "caption": "Full-assembly modes found by the EMA, each with its standard "
            "deviation σ (the fit's linearised covariance, docs/ema.md; empty: its window is too short to tell). "
            + _COMPLEXITY}


def ema_modes(res: RunResult) -> dict:
    """summary.json's ``ema``: per test, ``n_modes`` and its ``modes`` (Hz, damping ratio, standard deviations,
    MPC, MPD in degrees and MCF).

    The full-assembly test of a virtual campaign adds its scores against the truth
    (:func:`lab.judge.assembly_scores`: ``n_visible``, ``one_to_one_within_0p05pct``, ``mean_shape_mac``, …).
    """
    from lab.judge import assembly_scores, load_assembly_truth

    out = {}
    for name, (t, fit) in res.ema.items():
        out[name] = {"n_modes": int(fit.model.n_modes), "modes": fit.model.as_records()}
        if t.type == "assembly":
            truth = load_assembly_truth(res.campaign.truth_dir)
            if truth is not None:
                out[name] |= assembly_scores(fit.model, truth)
    return out


def ema_section(res: RunResult, out: Path, notes: list[str]) -> dict:
    rows, figs, drawn = [], [], set()
    for name, (t, fit) in res.ema.items():
        q = fit.fit_quality
        rows.append([name, t.type, t.file.name, _method_label(fit),
                     "picks file " + t.picks.name if fit.picked else "automatic", fit.model.n_modes,
                     float(np.min(q)) if q.size else float("nan"), float(np.mean(q)) if q.size else float("nan")])
        # one diagram per test type, and every hand-picked one; the UFF file is read only to draw them
        diagram = drawing_figures() and (t.type not in drawn or fit.picked)
        families = drawing_figures() and "+families" in (fit.model.method or "")
        frf = ema.read_uff(t.file) if diagram or families else None   # read once for both figures
        if diagram:
            drawn.add(t.type)
            figs.append(_stabilization(name, t, fit, frf, out))
        if families:
            figs += _families_figure(name, t, fit, frf, out)
    t_quality = write_csv(out / "ema_quality.csv", ["test", "type", "file", "method", "selection", "modes",
                                               "fit quality min", "fit quality mean"], rows)
    figs.append({"file": save_figure(lambda: plot_blade_deltas(res.blades.deltas_pct), out / "blade_deltas.png"),
                 "caption": "Blade mistuning δ of every blade and tracked mode (Eq. 37, paper Table 2)."})
    tables = [{"file": t_quality, "caption": "EMA of every test: pole estimator, selection, modes found and fit "
               "quality (1 − relative squared error of the synthesis)."}] + _ema_tables(res, out, notes)
    return {"id": "ema", "title": "Experimental modal analysis",
            "text": [f"{len(res.ema)} UFF files, fitted with LSRF and automatic pole selection unless a picks file "
                     "is named for the test in campaign.toml. One stabilization diagram per test type is shown."],
            "figures": figs, "tables": tables}
