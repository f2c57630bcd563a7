"""The writer of ``bladetwin run``: tables (CSV), figures (PNG), patterns, the ROM's modes (UFF 55), summary.json.

The one place a run's results become files (no stage draws or writes). Everything is written atomically into the
output folder; :func:`bladetwin.report.render_report` then turns
``summary.json`` and the files it names into ``report.html``.
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from identify.plots import (
    plot_area_fractions,
    plot_centroids,
    plot_frequency_maps,
    plot_grid_error,
    plot_sensitivity,
    plot_synthetic_patterns,
)
from identify.validation import contact_area_fraction, geometric_validation
from rom.pattern_io import save_patterns

from .methods import FREQUENCY_HEADER, POSTERIOR_HEADER, methods_summary, posterior_frequency_rows, posterior_rows
from .output_files import NO_FIGURES_NOTE, blank, figures_deferred, save_figure, write_csv
from .outputs_calibration import calibration_section, calibration_summary
from .outputs_ema import ema_modes, ema_section
from .outputs_response import response_section
from .outputs_rom import full_section, rom_section
from .rom_summary import (
    rom_summary,
)
from .run_figures import (
    plot_bias,
    plot_contact_probability,
    plot_d1b_features,
    plot_joint_patterns,
    plot_posterior_frequencies,
)
from .stages import PAPER_TABLE8, RunResult
from .user_warnings import emit, recording, unique
from .util import atomic_write_text, figures_drawn

__all__ = ["write_outputs", "write_sensitivity", "summary_of"]

def _label(i: int) -> str:
    return f"SP-{i + 1}"


def write_sensitivity(sens, out: Path, *, plot: bool = True) -> list[str]:
    """The sensitivity table and its figures (paper Figs. 15–16) in ``out``; returns the files' names."""
    rows = [[m + 1, float(sens.mean_hz[m]), float(sens.std_hz[m]), float(sens.std_rel_pct[m]),
             int(m in sens.feature_modes)] for m in range(sens.n_modes)]
    files = [write_csv(out / "sensitivity.csv", ["mode", "mean_hz", "std_hz", "std_pct", "feature"], rows)]
    if plot:
        files += [save_figure(lambda: plot_sensitivity(sens), out / "sensitivity.png"),
                  save_figure(lambda: plot_frequency_maps(sens), out / "frequency_maps.png")]
    return files


def _patterns_section(res: RunResult, out: Path) -> dict:
    films = res.films
    table, sens_png, maps_png = write_sensitivity(res.sensitivity, out)
    figs = [{"file": save_figure(lambda: plot_synthetic_patterns(res.synthetic, [a for a, _ in films.values()],
                                                  [b for _, b in films.values()],
                                                  known_labels=[f"joint {j}" for j in films]), out / "patterns.png"),
             "caption": "Film maps of the known joints and the synthetic patterns SP-1… drawn by the PCA sampler "
                        "(paper Fig. 14)."},
            {"file": sens_png,
             "caption": "Spread of the disk–one-blade frequencies over all pattern pairs; feature modes marked "
                        "(paper Fig. 15)."},
            {"file": maps_png,
             "caption": "Frequency maps of the feature modes over the pattern pairs (paper Fig. 16)."}]
    tables = [{"file": table,
               "caption": "Sensitivity per tracked mode (std over the pattern pairs)."}]
    return {"id": "patterns", "title": "Film maps, synthetic patterns and sensitivity",
            "text": [f"Known joints {list(res.campaign.known_joints)}; {len(res.synthetic.L)} synthetic patterns per "
                     f"flank (Scale {res.options.scale:g}, seed {res.options.seed}). Feature modes "
                     f"{[m + 1 for m in res.dataset.feature_modes]}; dataset of {res.dataset.n_samples} samples."],
            "figures": figs, "tables": tables}


def _joint_row(res: RunResult, j: int) -> tuple[dict, list]:
    """summary.json's entry and the CSV row of joint ``j``."""
    p, known, ref = res.final_patterns[j - 1], res.known, res.reference
    aL, aR = (float(a) for a in contact_area_fraction(np.stack([p.L, p.R])))
    lab = res.predictions.labels["experimental"].get(j)
    post = j in res.posterior.get("experimental", {})
    src = "film" if j in known else (("k-NN + refinement" if res.options.refine else "k-NN") if lab else "baseline")
    tag = " (refined)" if res.options.refine else ""  # a refined pattern starts from this pair and leaves it
    pl = "film" if j in known else (_label(lab[0]) + tag if lab else "mean known")
    pr = "film" if j in known else (_label(lab[1]) + tag if lab else "mean known")
    if post and j not in known:  # the posterior answered: its majority pattern, not a synthetic pair
        src, pl, pr = "posterior", "posterior", "posterior"
    rL = rR = None
    if ref is not None:
        rL, rR = (float(a) for a in contact_area_fraction(np.stack([ref[j - 1].L, ref[j - 1].R])))
    # Largest |relative distance| of a feature outside what the synthetic pairs reach (0: inside), %.
    beyond = float(100 * np.max(np.abs(lab[3]))) if lab and j not in known else None
    flag = bool(lab[4]) if lab and j not in known else None
    entry = {"joint": j, "source": src, "pattern_L": pl, "pattern_R": pr, "area_fraction_L_pct": aL,
             "area_fraction_R_pct": aR, "reference_area_L_pct": rL, "reference_area_R_pct": rR,
             "beyond_family_pct": beyond, "outside_family": flag}
    row = [j, src, pl, pr, float(lab[2]) if lab else "", "" if beyond is None else beyond,
           "" if flag is None else ("yes" if flag else "no"), aL, aR, "" if rL is None else rL,
           "" if rR is None else rR]
    return entry, row


def _geometric(res: RunResult, out: Path, figs: list, tables: list, text: list) -> dict | None:
    ref, known, c = res.reference, res.known, res.campaign
    unknown = [j for j in range(1, c.n_blades + 1) if j not in known] if ref is not None else []
    if not unknown:
        return None
    geo = geometric_validation([res.final_patterns[j - 1] for j in unknown], [ref[j - 1] for j in unknown], res.bd)
    geo_b = geometric_validation([res.baseline_pattern for _ in unknown], [ref[j - 1] for j in unknown], res.bd)
    summary = {"joints": unknown,
               "area_error_pp": {"identified": float(np.mean(np.abs(geo.area_error_pct))),
                                 "baseline": float(np.mean(np.abs(geo_b.area_error_pct)))},
               "centroid_distance_mm": {"identified": float(1e3 * np.nanmean(geo.centroid_distance)),
                                        "baseline": float(1e3 * np.nanmean(geo_b.centroid_distance))}}
    jl = [f"joint {j}" for j in unknown]
    figs.append({"file": save_figure(lambda: plot_area_fractions(geo, joint_labels=jl), out / "area_fractions.png"),
                 "caption": "Contact area fraction of the identified and reference patterns at the unfilmed joints "
                            "(Eq. 41, paper Figs. 21, 25)."})
    figs.append({"file": save_figure(lambda: plot_centroids(geo, [ref[j - 1] for j in unknown], res.bd,
                                             [res.final_patterns[j - 1] for j in unknown], joint_labels=jl),
                              out / "centroids.png"),
                 "caption": "Contact centroids, identified (blue) and reference (red), best and worst joint "
                            "(Eq. 42, paper Figs. 22, 26)."})
    write_csv(out / "geometric_validation.csv", ["joint", "area error L (pp)", "area error R (pp)",
                                             "centroid distance L (mm)", "centroid distance R (mm)"],
         [[j, *map(float, geo.area_error_pct[k]), *map(float, 1e3 * geo.centroid_distance[k])]
          for k, j in enumerate(unknown)])
    tables.append({"file": "geometric_validation.csv",
                   "caption": "Geometric validation at the unfilmed joints (identified vs reference)."})
    a, d = summary["area_error_pp"], summary["centroid_distance_mm"]
    text.append(f"Geometric validation on the unfilmed joints: mean |area error| {a['identified']:.1f} pp "
                f"(baseline {a['baseline']:.1f} pp), mean centroid distance {d['identified']:.2f} mm (baseline "
                f"{d['baseline']:.2f} mm).")
    return summary


def _identification_section(res: RunResult, out: Path) -> tuple[dict, list, dict | None]:
    c, feat = res.campaign, list(res.dataset.feature_modes)
    bias_pct, spread_pct = 100 * res.features.bias, 100 * res.features.spread
    t_bias = write_csv(out / "bias.csv", ["mode", "bias (%)", "spread (%)", "feature"],
                  [[m + 1, float(bias_pct[m]), float(spread_pct[m]), int(m in feat)] for m in range(len(bias_pct))])
    eps = res.step1.epsilon_pct
    t_eps = write_csv(out / "step1_epsilon.csv", ["joint"] + [f"ε δ{m + 1} (%)" for m in range(eps.shape[1])],
                 [[int(j), *map(float, eps[k])] for k, j in enumerate(res.joints)])
    joints, rows = zip(*(_joint_row(res, j) for j in range(1, c.n_blades + 1)), strict=True)
    t_pred = write_csv(out / "identified_patterns.csv", ["joint", "source", "pattern L", "pattern R", "k-NN distance",
                                                     "outside the synthetic family (%)", "beyond 2x the ROM scatter",
                                                     "area L (%)", "area R (%)", "reference area L (%)",
                                                     "reference area R (%)"], list(rows))
    save_patterns(out / "identified_patterns.npz", res.final_patterns)
    names = [f"{s['joint']}: {'film' if s['joint'] in res.known else s['pattern_L'] + '/' + s['pattern_R']}"
             for s in joints]
    figs = [{"file": save_figure(lambda: plot_bias(bias_pct, spread_pct, feat), out / "bias.png"),
             "caption": "Per-mode ROM bias estimated on the filmed joints; removed from every joint's measured "
                        "features before the k-NN."},
            {"file": save_figure(lambda: plot_grid_error(res.step1, blade_labels=[f"joint {j}" for j in res.joints]),
                          out / "step1_epsilon.png"),
             "caption": "Step 1 of the k-NN: normalized δ grid error ε (Eq. 40, paper Fig. 19); |ε| ≤ 50 % means "
                        "the nearest grid row was chosen."},
            {"file": save_figure(lambda: plot_joint_patterns(res.final_patterns, names, res.reference),
                          out / "identified_patterns_map.png"),
             "caption": "Identified pattern of every joint (films at the known joints)"
                        + (", beside the reference pattern (paper Tables 6–7)." if res.reference is not None else ".")}]
    text = [f"ROM bias per tracked mode (%): {np.round(bias_pct, 3).tolist()} "
            f"({'removed' if res.options.bias else 'not removed: --no-bias'}).",
            f"Step 1: max |ε| = {float(np.max(np.abs(eps))):.1f} %."]
    tables = [{"file": t_pred, "caption": "Identified pattern of every joint (paper Tables 6–7) and its contact "
               "area fraction; 'outside the synthetic family': how far (largest feature, % of its frequency) the "
               "joint's measured features lie beyond what the synthetic pairs reach at its δ (0: within reach)."},
              {"file": t_bias, "caption": "ROM bias per tracked mode."},
              {"file": t_eps, "caption": "Step-1 grid error ε per joint and δ mode (Eq. 40)."}]
    geo = _geometric(res, out, figs, tables, text)
    return ({"id": "identification", "title": "Bias correction and identification", "text": text, "figures": figs,
             "tables": tables}, list(joints), geo)


def _d1b_section(res: RunResult, out: Path) -> tuple[dict, dict]:
    rows_d, fm = res.d1b_rows, [m + 1 for m in res.dataset.feature_modes]
    meas = np.array([r["measured_hz"] for r in rows_d])
    ident = np.array([r["identified_hz"] for r in rows_d])
    jj = [r["joint"] for r in rows_d]
    header = ["joint", "source"] + [f"measured mode {m} (Hz)" for m in fm] + [f"identified mode {m} (Hz)" for m in fm]
    body = [[r["joint"], r["source"], *map(float, r["measured_hz"]), *map(float, r["identified_hz"])] for r in rows_d]
    title = "identified ROM (bias added back) vs measured"
    figs = [{"file": save_figure(lambda: plot_d1b_features(jj, meas, ident, fm, title=title),
                          out / "d1b_experimental.png"),
             "caption": "Disk–one-blade feature modes: the ROM with each joint's identified pattern (its bias added "
                        "back) against the measured frequencies (paper Fig. 27)."}]
    summary = {"experimental_mean_abs_df_pct": float(np.nanmean(np.abs(ident / meas - 1)) * 100)}
    if res.reference is not None:
        refh = np.array([r["reference_hz"] for r in rows_d])
        num = np.array([r["numerical_hz"] for r in rows_d])
        header += [f"reference-pattern ROM mode {m} (Hz)" for m in fm] + [f"numerical-input ROM mode {m} (Hz)"
                                                                         for m in fm]
        body = [b + [*map(float, r["reference_hz"]), *map(float, r["numerical_hz"])]
                for b, r in zip(body, rows_d, strict=True)]
        title = "numerical input: identified vs reference pattern (ROM)"
        figs.append({"file": save_figure(lambda: plot_d1b_features(jj, refh, num, fm, title=title),
                                         out / "d1b_numerical.png"),
                     "caption": "Disk–one-blade feature modes on the numerical input: ROM with the identified pattern "
                                "against the ROM with the reference pattern (paper Fig. 23)."})
        unknown = [k for k, r in enumerate(rows_d) if r["source"] != "film"]
        if unknown:
            summary["numerical_mean_abs_df_pct"] = float(np.mean(np.abs(num[unknown] / refh[unknown] - 1)) * 100)
    write_csv(out / "d1b_validation.csv", header, body)
    return {"id": "d1b", "title": "Disk–one-blade validation",
            "text": [f"Feature modes {fm}. Mean |Δf| of the identified ROM against the measurement: "
                     f"{summary['experimental_mean_abs_df_pct']:.3f} %."],
            "figures": figs, "tables": [{"file": "d1b_validation.csv", "caption": "Feature frequencies per joint."}]}, \
        summary


def _posterior_section(res: RunResult, out: Path, methods: dict) -> list[dict]:
    """The contact posterior's answer per unfilmed joint: probability maps, intervals (empty if it did not run)."""
    posts = res.posterior.get("experimental", {})
    if not posts:
        return []
    joints = sorted(posts)
    labels = [f"joint {j}" for j in joints]
    columns = {}
    if "knn" in res.answers:
        columns["k-NN"] = [res.answers["knn"]["experimental"][j - 1] for j in joints]
    if res.reference is not None:
        columns["reference"] = [res.reference[j - 1] for j in joints]
    fig = save_figure(lambda: plot_contact_probability([posts[j].probability for j in joints], labels, columns),
               out / "contact_probability.png")
    write_csv(out / "posterior_contact.csv", POSTERIOR_HEADER, [[blank(v) for v in r] for r in posterior_rows(res)])
    freq_rows = posterior_frequency_rows(res)
    write_csv(out / "posterior_frequencies.csv", FREQUENCY_HEADER, [[blank(v) for v in r] for r in freq_rows])
    # the frequency table runs to (joints × tracked modes) rows: a figure shows it, the report folds the table
    freq_fig = save_figure(lambda: plot_posterior_frequencies(np.array(freq_rows, float).reshape(-1, 7)),
                           out / "posterior_frequencies.png")
    s = res.posterior["surrogate"]
    m = methods.get("posterior", {})
    text = ["Each unfilmed joint's contact as a posterior over a continuous pattern family (the films' PCA and the "
            "contact level, Eq. 30's prior), given every tracked mode of its disk-one-blade test; the noise is the "
            "ROM's scatter on the filmed joints, the EMA's standard deviation, the surrogate's error and the family's "
            "error on the films (each film against its projection on the other films' PCA). The answer "
            "holds, on each flank, the nodes most probably in contact, as many as the posterior's median count; the "
            "intervals are 90 % posterior intervals. Beyond the paper (docs/identify.md).",
            f"Surrogate of the d1b ROM: held-out RMS error {', '.join(f'{e:.3f}' for e in s.error_pct)} % per mode "
            f"({s.n_test} of {s.n_train + s.n_test} direct solves held out)."]
    exp = m.get("experimental")
    if exp:
        text.append(f"Against the reference patterns (experimental input): mean |area error| {exp['area_error_pp']:.1f}"
                    f" pp, centroid distance {exp['centroid_distance_mm']:.2f} mm, node agreement "
                    f"{100 * exp['node_agreement']:.1f} %; the true area lies in the 90 % interval on "
                    f"{100 * exp.get('ci90_coverage_area', float('nan')):.0f} % of flanks (median width "
                    f"{exp.get('ci90_median_width_pp', float('nan')):.1f} pp), the true centroid on "
                    f"{100 * np.float64(exp.get('ci90_coverage_centroid', np.nan)):.0f} % of flank axes.")
    ratio = (m.get("width_ratio") or {}).get("experimental")
    if ratio:
        text.append("What the data pin down: each 90 % interval's width over the prior's (median over the joints; 1 "
                    "means the test says nothing about it): " + ", ".join(f"{k} {v:.2f}" for k, v in ratio.items())
                    + f". The test narrows {min(ratio, key=ratio.get)} most and {max(ratio, key=ratio.get)} least; "
                      "what it leaves near 1 comes from the films' family (the prior).")
    text += _chains_text((m.get("diagnostics") or {}).get("experimental") or {})
    text += _film_next_text(m.get("film_next") or [])
    return [{"id": "posterior", "title": "Contact posterior: every unfilmed joint with its confidence",
             "text": text,
             "figures": [{"file": fig, "caption": "Posterior probability of contact at each node (left pair), beside "
                          "the k-NN's answer and the reference pattern where they exist."},
                         {"file": freq_fig, "caption": "Each unfilmed joint's tracked disk–one-blade frequencies "
                          "against its test (0: the test's frequency, bias removed): the posterior's answer and the "
                          "90 % interval of the ROM's frequency over the posterior (model error not included)."}],
             "tables": [{"file": "posterior_contact.csv", "caption": "The posterior's answer per unfilmed joint: "
                         "area fractions and centroids with their 90 % intervals (experimental input)."},
                        {"file": "posterior_frequencies.csv", "figure": freq_fig,
                         "caption": "Each unfilmed joint's tracked disk–one-blade frequencies: the test's (bias "
                         "removed), the posterior's answer and the 90 % interval of the ROM's frequency over the "
                         "posterior (model error not included)."}]}]


def _film_next_text(ranked: list[dict]) -> list[str]:
    """Which joints to film next, best first (``methods.posterior.film_next``)."""
    if not ranked:
        return []

    def item(c: dict) -> str:
        where = f"{c['outside_pp']:.0f} pp outside the films' areas" if c["outside_pp"] > 0 else "inside them"
        return f"joint {c['joint']} ({where}, interval {c['width_pp']:.0f} pp wide)"

    more = (f"; the order of all {len(ranked)} is in summary.json (methods.posterior.film_next)"
            if len(ranked) > 3 else "")
    return ["Film next: " + ", ".join(item(c) for c in ranked[:3]) + more + ". First the joint whose answer lies "
            "furthest outside the films' range of contact area (pp over both flanks), then the widest interval: a film "
            "there changes the family every other joint is drawn from most. It may widen the other joints' "
            "intervals: where the films are few, they are too narrow (identify.film_next)."]


def _chains_text(diag: dict) -> list[str]:
    """The chains' convergence (experimental input): R̂ and ESS over the joints, and every joint that failed."""
    if not diag:
        return []
    from identify.chains import ESS_MIN, RHAT_MAX

    rhat, ess = [d["rhat"] for d in diag.values()], [d["ess"] for d in diag.values() if d["ess"] is not None]
    steps = sorted({d["n_steps"] for d in diag.values()})
    bad = [j for j, d in diag.items() if not d["converged"]]
    text = (f"Chains (summary.json: methods.posterior.diagnostics): R̂ over the walkers {min(rhat):.3f}–"
            f"{max(rhat):.3f}, effective samples {min(ess, default=0):.0f}–{max(ess, default=0):.0f}, after "
            f"{' or '.join(str(n) for n in steps)} steps (a joint runs on while R̂ > {RHAT_MAX} or ESS < "
            f"{ESS_MIN:.0f}). ")
    text += (f"Not converged: joint{'s' if len(bad) > 1 else ''} {', '.join(bad)}; their intervals are approximate."
             if bad else "Every joint converged.")
    return [text]


def write_outputs(res: RunResult, out: Path, *, command: str = "bladetwin run", figures: bool = True,
                  workers: int = 1) -> dict:
    """Write every output of a run into ``out`` and return the summary (also written to summary.json).

    ``figures=False`` (``bladetwin run --no-figures``) writes everything but the PNG figures, and says so.
    ``workers``: processes that draw the figures (:func:`bladetwin.output_files.figures_deferred`).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    notes: list[str] = [] if figures else [NO_FIGURES_NOTE]
    # a figure's or a table's warning: to summary.json too (the figures are drawn when the inner block ends)
    with recording() as texts, figures_drawn(figures), figures_deferred(workers):
        sections = [ema_section(res, out, notes), calibration_section(res, out), _patterns_section(res, out)]
        sections = [x for x in sections if x is not None]
        ident, joints, geo = _identification_section(res, out)
        d1b, d1b_summary = _d1b_section(res, out)
        methods = methods_summary(res)
        rom = rom_summary(res)
        sections += [ident, *_posterior_section(res, out, methods), d1b, *rom_section(res, out, rom),
                     full_section(res, out)]
        response = None
        if res.response is not None:  # below every other section
            section, response = response_section(res.response, out)
            sections.append(section)
    for sec in sections:  # a figure not drawn is not listed
        sec["figures"] = [f for f in sec.get("figures", []) if f.get("file")]
    for text in unique(texts):
        emit(text)
    summary = summary_of(res, command)
    summary["notes"] = summary["notes"] + notes
    summary["warnings"] = unique(summary["warnings"] + texts)
    summary.update(_clean({"joints": joints, "sections": sections, "geometric": geo, "d1b": d1b_summary,
                           "ema": ema_modes(res), "methods": methods,
                           "rom": rom, "response": response}))
    summary["files"] = {"patterns": "identified_patterns.npz", "rom_modes_uff": "identified_rom_modes.uff"}
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2, allow_nan=False, default=_nan) + "\n")
    return summary


def _nan(o):
    raise TypeError(f"not JSON serializable: {type(o).__name__}")


def _clean(obj):
    """NaN/inf → None, numpy scalars → Python, recursively (summary.json is strict JSON)."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def summary_of(res: RunResult, command: str) -> dict:
    """summary.json's figures (without the report sections)."""
    c = res.campaign
    return _clean({
        "campaign": c.name, "campaign_dir": str(c.root), "kind": c.kind, "n_blades": c.n_blades,
        "grid": list(c.grid), "known_joints": list(c.known_joints),
        "generated": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), "command": command,
        "report": "report.html",
        "feature_modes": [m + 1 for m in res.dataset.feature_modes],
        "step1": {"max_abs_eps_pct": float(np.max(np.abs(res.step1.epsilon_pct)))},
        "bias": {"enabled": res.options.bias, "per_mode_pct": (100 * res.features.bias).tolist(),
                 "spread_pct": (100 * res.features.spread).tolist(),
                 "joints": [j for j in c.known_joints if j in set(res.joints.tolist())]},
        "cases": res.cases, "paper_table8": PAPER_TABLE8, "notes": list(res.notes), "warnings": list(res.warnings),
        "settings": {"n_patterns": res.options.n_patterns, "scale": res.options.scale, "seed": res.options.seed,
                     "step_pct": res.options.step_pct, "n_features": res.options.n_features,
                     "refine_max_solves": res.options.refine, "method": res.options.method,
                     "n_components": res.options.n_components, "posterior_steps": res.options.posterior_steps,
                     "rom": res.options.rom,
                     "calibrate": res.options.calibrate},
        "calibration": calibration_summary(res),
        "timings_s": {k: round(v, 2) for k, v in res.timings_s.items()},
        "stages": dict(res.stage_counts),
    })
