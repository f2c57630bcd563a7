"""summary.json's ``response`` block, its report section, and the files of ``bladetwin response`` (issue 47).

The block holds, per ROM (the exported one, then the paper's), per family and engine order, the amplification
factor ``af``, the ``worst_blade``, the AF's 90 % interval ``af_ci90`` and each blade's probability to be the
worst ``p_worst`` over the contact posterior's samples, and on a virtual campaign the truth twin's ``af_truth``
(:class:`bladetwin.stages.response.Response`); ``against_truth`` scores each ROM on it. ``bladetwin response``
reads it back (:func:`response_rows`, :func:`plot_response`) and recomputes nothing.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

from .output_files import save_figure, write_csv

__all__ = ["RESPONSE_HEADER", "WORST_HEADER", "response_summary", "response_rows", "worst_rows",
           "plot_response", "response_section"]

#: ``response.csv``'s columns (one row per ROM, family and EO) and the report's worst-EO table's.
RESPONSE_HEADER = ["rom", "family", "eo", "af", "af_ci90_low", "af_ci90_high", "af_truth", "worst_blade",
                   "p_worst_blade", "peak_hz", "tuned_peak_hz", "damping_ratio"]
WORST_HEADER = ["ROM", "family", "worst engine order", "amplification factor", "90 % interval", "truth's AF",
                "worst blade (probability)", "damping ratio"]


def _num(v: float):
    return None if not np.isfinite(v) else float(v)


def _truth_af(r, truth, i: int, e: int) -> float | None:
    """The truth's AF of the same (family, EO), where the truth's family band overlaps the ROM's (the k-th
    resonance per nodal diameter may be another family in a model with one more disk mode)."""
    if truth is None or truth.refused[i]:
        return None
    (lo, hi), (tlo, thi) = r.bands_hz[i], truth.bands_hz[i]
    return _num(truth.af[i, e]) if min(hi, thi) > max(lo, tlo) else None


def _eo_entry(r, i: int, e: int, limit: float, truth=None) -> dict:
    """One (family, EO) of a ROM: its AF, worst blade and peaks, or why it has no AF; ``beyond_whitehead`` where
    the AF exceeds Whitehead's single-family ``limit`` (the band then holds more than the family's modes); the
    AF's 90 % interval and the blades' probabilities to be the worst (largest first, zeros left out) where the
    ROM has them; the truth's AF where there is one."""
    entry = {"af": _num(r.af[i, e]), "worst_blade": int(r.worst_blade[i, e]), "peak_hz": _num(r.peak_hz[i, e]),
             "tuned_peak_hz": _num(r.tuned_peak_hz[i, e])}
    if r.af_ci90 is not None and np.all(np.isfinite(r.af_ci90[i, e])):
        entry["af_ci90"] = [float(v) for v in r.af_ci90[i, e]]
        if r.af_ci90_contact is not None and np.all(np.isfinite(r.af_ci90_contact[i, e])):
            entry["af_ci90_contact"] = [float(v) for v in r.af_ci90_contact[i, e]]
        pw = r.p_worst[i, e]
        entry["p_worst"] = {str(b + 1): float(pw[b]) for b in np.argsort(-pw, kind="stable") if pw[b] > 0}
    if truth is not None:
        entry["af_truth"] = _truth_af(r, truth, i, e)
        if entry["af_truth"] is not None:
            entry["truth_worst_blade"] = int(truth.worst_blade[i, e])
    if entry["af"] is None:
        entry["no_af"] = ("the tuned disk's peak lies at the band's edge: the family has no resonance at the "
                          "loaded point at this engine order")
    elif entry["af"] > limit:
        entry["beyond_whitehead"] = True
    return entry


def _against_truth(roms: dict) -> dict:
    """Per ROM: the (family, EO) cases with both an AF and the truth's, the share whose truth lies in the 90 %
    interval, and the median of |AF / AF_truth − 1|."""
    out = {}
    for rom, r in roms.items():
        cases = [v for f in r["families"].values() for v in f.get("eo", {}).values()
                 if v["af"] is not None and v.get("af_truth") is not None]
        inside = [v["af_ci90"][0] <= v["af_truth"] <= v["af_ci90"][1] for v in cases if "af_ci90" in v]
        contact = [v["af_ci90_contact"][0] <= v["af_truth"] <= v["af_ci90_contact"][1] for v in cases
                   if "af_ci90_contact" in v]
        err = [abs(v["af"] / v["af_truth"] - 1) for v in cases]
        out[rom] = {"n_cases": len(cases), "n_with_interval": len(inside),
                    "in_ci90": float(np.mean(inside)) if inside else None,
                    "in_ci90_contact": float(np.mean(contact)) if contact else None,
                    "median_abs_error_pct": float(100 * np.median(err)) if err else None,
                    "worst_blade_agrees": float(np.mean([v["worst_blade"] == v["truth_worst_blade"] for v in cases]))
                    if cases else None}
    return out


def _largest(families: dict) -> dict | None:
    """The (family, EO) with the largest AF of a ROM's (or the truth's) ``families`` block, or None."""
    cases = [(v["af"], int(fam), int(eo), v) for fam, f in families.items() for eo, v in f.get("eo", {}).items()
             if v.get("af") is not None]
    if not cases:
        return None
    af, fam, eo, v = max(cases, key=lambda c: c[0])
    return {"family": fam, "eo": eo, "af": af, "worst_blade": v["worst_blade"],
            **{k: v[k] for k in ("af_ci90", "af_truth") if k in v}}


def _truth_block(truth, families, eos) -> dict:
    fams = {}
    for i, fam in enumerate(families):
        if truth.refused[i]:
            fams[str(fam)] = {"refused": truth.refused[i]}
        else:
            fams[str(fam)] = {"band_hz": [_num(v) for v in truth.bands_hz[i]],
                              "eo": {str(eo): {"af": _num(truth.af[i, e]), "worst_blade": int(truth.worst_blade[i, e])}
                                     for e, eo in enumerate(eos)}}
    return {"families": fams, "largest": _largest(fams)}


def response_summary(resp) -> dict:
    """summary.json's ``response`` block of a :class:`~bladetwin.stages.response.Response` (strict JSON).

    ``roms[rom]["families"][str(family)]["eo"][str(eo)]`` holds ``af``, ``worst_blade`` (1-based),
    ``peak_hz`` and ``tuned_peak_hz`` (Hz), with ``af`` null and ``no_af`` saying why where the tuned peak lies
    at the band's edge; ``af_ci90`` and ``p_worst`` where the posterior's samples gave them; ``af_truth`` on a
    virtual campaign. A family the solves could not cover holds ``refused`` instead, and one without an interval
    ``no_interval``. ``truth`` holds the truth twin's own AFs, ``against_truth`` each ROM's scores on them, and
    ``not_computed`` the figures this run could not give, each with why.
    """
    truth = getattr(resp, "truth", None)
    roms, whitehead = {}, 0.5 * (1 + math.sqrt(resp.n_blades))
    for r in resp.roms:
        fams = {}
        for i, fam in enumerate(resp.families):
            entry = {"band_hz": [_num(v) for v in r.bands_hz[i]], "damping_ratio": _num(r.damping_ratio[i])}
            if r.refused[i]:
                entry["refused"] = r.refused[i]
            else:
                entry["eo"] = {str(eo): _eo_entry(r, i, e, whitehead, truth) for e, eo in enumerate(resp.eos)}
                if r.interval and r.interval[i]:
                    entry["no_interval"] = r.interval[i]
                if r.discrepancy is not None and np.isfinite(r.discrepancy[i]):
                    entry["discrepancy"] = float(r.discrepancy[i])
                amp = getattr(r, "amplitude_discrepancy", None)
                if amp is not None and np.isfinite(amp[i]):
                    entry["amplitude_discrepancy"] = float(amp[i])
            fams[str(fam)] = entry
        roms[r.rom] = {"solve": r.solve, "n_samples": int(r.n_samples), "families": fams, "largest": _largest(fams)}
    missing = {}
    if not any(r.n_samples for r in resp.roms):
        missing["af_ci90"] = missing["p_worst"] = resp.interval_source or "no posterior samples"
    if truth is None:
        missing["af_truth"] = ("no truth/response_modes.npz: not a virtual campaign, or one made before it was "
                               "written (`bladetwin lab response-truth CAMPAIGN` adds it)")
    block = {"n_blades": resp.n_blades, "point": resp.point, "whitehead_limit": whitehead,
             "families": list(resp.families), "eos": list(resp.eos), "damping_source": resp.damping_source,
             "interval_source": resp.interval_source, "exported": resp.roms[0].rom, "roms": roms,
             "not_computed": missing}
    if truth is not None:
        block["truth"] = _truth_block(truth, resp.families, resp.eos)
        block["against_truth"] = _against_truth(roms)
    return block


def _top(v: dict) -> str:
    """The most probable worst blade as ``"blade:probability"`` ("" without samples)."""
    pw = v.get("p_worst") or {}
    return "" if not pw else f"{next(iter(pw))}:{next(iter(pw.values())):.2f}"


def response_rows(block: dict, eos=None, families=None) -> list[list]:
    """``response.csv``'s rows (:data:`RESPONSE_HEADER`) of a ``response`` block, for the EOs and families asked
    (default all); a refused family is left out."""
    rows = []
    for rom, r in block["roms"].items():
        for fam, f in r["families"].items():
            if (families is None or int(fam) in families) and "eo" in f:
                rows += [[rom, int(fam), int(eo), v["af"], *(v.get("af_ci90") or [None, None]), v.get("af_truth"),
                          v["worst_blade"], _top(v), v["peak_hz"], v["tuned_peak_hz"], f["damping_ratio"]]
                         for eo, v in f["eo"].items() if eos is None or int(eo) in eos]
    return rows


def worst_rows(block: dict) -> list[list]:
    """Per ROM and family, the EO with the largest AF (:data:`WORST_HEADER`)."""
    rows = []
    for rom, r in block["roms"].items():
        for fam, f in r["families"].items():
            vals = {int(eo): v for eo, v in f.get("eo", {}).items() if v["af"] is not None}
            if vals:
                eo = max(vals, key=lambda k: vals[k]["af"])
                v = vals[eo]
                ci = v.get("af_ci90")
                pw = v.get("p_worst") or {}
                worst = f"{v['worst_blade']}" + (f" ({pw.get(str(v['worst_blade']), 0.0):.0%})" if pw else "")
                truth = v.get("af_truth")
                rows.append([rom, int(fam), eo, f"{v['af']:.3f}", "" if ci is None else f"{ci[0]:.3f}–{ci[1]:.3f}",
                             "" if truth is None else f"{truth:.3f}", worst, f"{f['damping_ratio']:.4g}"])
    return rows


def plot_response(block: dict, eos=None, families=None):
    """AF against EO, one panel per family: each ROM a line of its own colour with its 90 % interval as a bar,
    the truth's AF as black crosses (virtual campaigns), Whitehead's limit (1 + √N)/2 dashed; an AF above 1.2 ×
    that limit is drawn at the top as a triangle with its value; a panel without an AF says so (the report's text
    gives each reason)."""
    fams = [int(f) for f in block["families"] if families is None or int(f) in families]
    fig, axes = plt.subplots(1, len(fams), figsize=(3.6 * len(fams) + 0.6, 3.6), squeeze=False, sharey=True)
    style = {rom: (f"C{k}", "os^"[k % 3]) for k, rom in enumerate(block["roms"])}
    n_roms = len(block["roms"])
    truth_drawn = False
    # The axis ends a little above Whitehead's limit: an AF beyond it (flagged as suspect) would squeeze every
    # other to a flat line; it is drawn at the top as a triangle with its value written beside it.
    top = 1.2 * block["whitehead_limit"]
    for ax, fam in zip(axes[0], fams, strict=True):
        drawn = False
        for k, (rom, r) in enumerate(block["roms"].items()):
            items = sorted((int(eo), v) for eo, v in r["families"][str(fam)].get("eo", {}).items()
                           if (eos is None or int(eo) in eos) and v["af"] is not None)
            if not items:
                continue
            shift = 0.12 * (k - (n_roms - 1) / 2)  # side by side, so both ROMs' intervals show
            x = np.array([eo for eo, _ in items]) + shift
            y = np.array([v["af"] for _, v in items])
            ax.plot(x, np.minimum(y, top), marker=style[rom][1], color=style[rom][0], ms=4)
            for xx, yy in zip(x[y > top], y[y > top], strict=True):
                ax.plot(xx, top, marker="^", color=style[rom][0], ms=7, clip_on=False)
                ax.annotate(f"{yy:.2f}", (xx, top), xytext=(5, -10), textcoords="offset points", fontsize=7,
                            color=style[rom][0])
            ci = [(xx, v["af_ci90"]) for xx, (_, v) in zip(x, items, strict=True) if "af_ci90" in v]
            if ci:
                ax.vlines([c[0] for c in ci], [min(c[1][0], top) for c in ci], [min(c[1][1], top) for c in ci],
                          color=style[rom][0], lw=2.5, alpha=0.45)
            drawn = True
        truth = sorted((int(eo), v["af"]) for eo, v in block.get("truth", {}).get("families", {})
                       .get(str(fam), {}).get("eo", {}).items() if (eos is None or int(eo) in eos) and v["af"])
        if truth:  # the truth's own families: a ROM may have refused this one
            ax.plot(*zip(*truth, strict=True), "kx", ms=7, mew=1.5, zorder=5)
            truth_drawn = drawn = True
        if not drawn:
            ax.text(0.5, 0.78, "no amplification factor\n(the text gives why)", transform=ax.transAxes,
                    ha="center", va="center", fontsize=8, color="0.3",
                    bbox={"facecolor": "white", "edgecolor": "0.8", "boxstyle": "round"})
        ax.axhline(block["whitehead_limit"], ls="--", color="0.4")
        ax.axhline(1.0, ls=":", color="0.6")
        ax.set_title(f"family {fam}")
        ax.set_xlabel("engine order")
        ax.set_xticks([int(e) for e in block["eos"] if eos is None or int(e) in eos])
    axes[0][0].set_ylabel("amplification factor")
    axes[0][0].set_ylim(0.9, top)
    handles = [Line2D([], [], color=c, marker=m, label=f"{rom} ROM (bar: 90 % interval)") for rom, (c, m)
               in style.items()]
    if truth_drawn:
        handles.append(Line2D([], [], ls="", marker="x", color="k", mew=1.5, label="truth"))
    handles += [Line2D([], [], ls="--", color="0.4", label="Whitehead (1+√N)/2"),
                Line2D([], [], ls=":", color="0.6", label="tuned (AF = 1)")]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 3), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.14, 1, 1))
    return fig


def _interval_text(block: dict) -> str:
    if "af_ci90" in block["not_computed"]:
        return f"No intervals: {block['not_computed']['af_ci90']}."
    sig = [f"{rom} ROM family {fam} {100 * f['discrepancy']:.2f} %" for rom, r in block["roms"].items()
           for fam, f in r["families"].items() if "discrepancy" in f]
    text = (f"The 90 % intervals propagate {block['interval_source']}: each sample changes the unfilmed joints' "
            "disk–one-blade frequencies, and the solved assembly's family modes are corrected in their own span "
            "(rom.forced.perturbation, no new assembly solve).")
    amp = [f"{rom} ROM family {fam} {100 * f['amplitude_discrepancy']:.2f} %" for rom, r in block["roms"].items()
           for fam, f in r["families"].items() if "amplitude_discrepancy" in f]
    if sig:
        text += (" The discrepancy σ is the spread of the family's frequency errors against the full-assembly test, "
                 f"its mean removed ({'; '.join(sig)}): the blade-to-blade scatter the ROM misses, which the "
                 "contact alone does not hold.")
    if amp:
        text += (" The amplitude discrepancy σ_a is the scatter of the blades' point amplitudes in their "
                 f"disk–one-blade tests ({'; '.join(amp)}): the ROM's blades share one shape, real ones do not, "
                 "and a blade whose point moves (1 + η) times as much peaks about (1 + 2η) times as high. It "
                 "holds the tests' scaling noise too, so it errs wide.")
    if sig or amp:
        text += " af_ci90_contact in summary.json is the interval with the contact's uncertainty alone."
    return text + " Not held: the error of the tuned disk the AF divides by, and of the damping."


def _truth_text(block: dict) -> list[str]:
    out = [f"The truth twin, family {fam}: {f['refused']}" for fam, f in block.get("truth", {}).get("families", {})
           .items() if "refused" in f]
    for rom, a in block.get("against_truth", {}).items():
        if not a["n_cases"]:
            out.append(f"{rom} ROM: no (family, EO) with both its AF and the truth's.")
            continue
        line = (f"Against the truth twin's own AF ({a['n_cases']} (family, EO) cases): the {rom} ROM's AF is off by "
                f"{a['median_abs_error_pct']:.1f} % (median), and it names the truth's worst blade in "
                f"{100 * a['worst_blade_agrees']:.0f} % of the cases")
        if a["in_ci90"] is not None:
            line += f"; its 90 % interval holds the truth in {100 * a['in_ci90']:.0f} % of the cases"
        if a.get("in_ci90_contact") is not None:
            line += f" ({100 * a['in_ci90_contact']:.0f} % with the contact's uncertainty alone)"
        out.append(line + ".")
    return out


def response_section(resp, out: Path) -> tuple[dict, dict]:
    """(the report's section, summary.json's ``response`` block) of a run's :class:`Response`."""
    block = response_summary(resp)
    fig = save_figure(lambda: plot_response(block), out / "response_af.png")
    table = write_csv(out / "response_worst.csv", WORST_HEADER, worst_rows(block))
    notes = [f"{rom} ROM, {f['refused']}" for rom, r in block["roms"].items()
             for f in r["families"].values() if "refused" in f]
    for rom, r in block["roms"].items():
        for fam, f in r["families"].items():
            why: dict[str, list[str]] = {}   # each reason the block gives (_eo_entry's no_af), with its EOs
            for eo, v in f.get("eo", {}).items():
                if "no_af" in v:
                    why.setdefault(v["no_af"], []).append(eo)
            notes += [f"{rom} ROM, family {fam}: no amplification factor at EO {', '.join(eos)}: {reason} (its band "
                      "likely holds a disk-dominated mode)." for reason, eos in why.items()]
    beyond = [f"{rom} ROM family {fam} EO {eo}" for rom, r in block["roms"].items()
              for fam, f in r["families"].items() for eo, v in f.get("eo", {}).items() if v.get("beyond_whitehead")]
    if beyond:
        notes.append(f"Beyond Whitehead's single-family limit, so suspect (the band holds more than the family's "
                       f"modes, or the tuned peak is weak at the loaded point): {', '.join(beyond)}.")
    for rom, r in block["roms"].items():
        notes += [f"{rom} ROM, family {fam}: no interval: {f['no_interval']}." for fam, f in r["families"].items()
                  if "no_interval" in f and "refused" not in f]
    text = [f"Forced response under engine-order excitation (a travelling wave at blade point {block['point']} of "
            f"every blade, EO 0..{max(block['eos'])}) and the mistuning amplification factor: the worst blade's peak "
            "over the tuned disk's (every joint with the films' mean pattern, every blade the mean blade), family "
            f"by family, with each family's damping from {block['damping_source']}. Whitehead's limit "
            f"(1 + √N)/2 = {block['whitehead_limit']:.3f}.",
            _interval_text(block), *_truth_text(block), *notes]
    if "af_truth" in block["not_computed"]:
        text.append(f"No truth to check the AF against: {block['not_computed']['af_truth']}.")
    section = {"id": "response", "title": "Forced response and amplification factor", "text": text,
               "figures": [{"file": fig, "caption": "Amplification factor against engine order, per family, the "
                            "exported ROM and the paper's, each with its 90 % interval over the contact posterior "
                            "(bars) where the run sampled it; the truth's as crosses on a virtual campaign; "
                            "Whitehead's limit dashed."}],
               "tables": [{"file": table, "caption": "Per family, the engine order with the largest amplification "
                           "factor, its 90 % interval, the truth's AF, and its worst blade with the share of the "
                           "posterior's samples in which that blade is the worst."}]}
    return section, block
