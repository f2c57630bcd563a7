"""summary.json's ``response`` block, its report section, and the files of ``bladetwin response`` (issue 47).

The block holds, per ROM (the exported one, then the paper's), per family and engine order, the amplification
factor ``af`` and the ``worst_blade`` of :class:`bladetwin.stages.response.Response`; ``bladetwin response``
reads it back (:func:`response_rows`, :func:`plot_response`) and recomputes nothing.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

from .output_files import save_figure, write_csv

__all__ = ["RESPONSE_HEADER", "WORST_HEADER", "NOT_COMPUTED", "response_summary", "response_rows", "worst_rows",
           "plot_response", "response_section"]

#: ``response.csv``'s columns (one row per ROM, family and EO) and the report's worst-EO table's.
RESPONSE_HEADER = ["rom", "family", "eo", "af", "worst_blade", "peak_hz", "tuned_peak_hz", "damping_ratio"]
WORST_HEADER = ["ROM", "family", "worst engine order", "amplification factor", "worst blade", "damping ratio"]
#: What the block does not hold yet (the posterior's samples are not re-solved, the truth's tuned disk not solved).
NOT_COMPUTED = ("af_ci90", "p_worst", "af_truth")


def _num(v: float):
    return None if not np.isfinite(v) else float(v)


def _eo_entry(r, i: int, e: int, limit: float) -> dict:
    """One (family, EO) of a ROM: its AF, worst blade and peaks, or why it has no AF; ``beyond_whitehead`` where
    the AF exceeds Whitehead's single-family ``limit`` (the band then holds more than the family's modes)."""
    entry = {"af": _num(r.af[i, e]), "worst_blade": int(r.worst_blade[i, e]), "peak_hz": _num(r.peak_hz[i, e]),
             "tuned_peak_hz": _num(r.tuned_peak_hz[i, e])}
    if entry["af"] is None:
        entry["no_af"] = ("the tuned disk's peak lies at the band's edge: the family has no resonance at the "
                          "loaded point at this engine order")
    elif entry["af"] > limit:
        entry["beyond_whitehead"] = True
    return entry


def response_summary(resp) -> dict:
    """summary.json's ``response`` block of a :class:`~bladetwin.stages.response.Response` (strict JSON).

    ``roms[rom]["families"][str(family)]["eo"][str(eo)]`` holds ``af``, ``worst_blade`` (1-based),
    ``peak_hz`` and ``tuned_peak_hz`` (Hz), with ``af`` null and ``no_af`` saying why where the tuned peak lies
    at the band's edge; a family the solves could not cover holds ``refused`` instead.
    """
    roms, whitehead = {}, 0.5 * (1 + math.sqrt(resp.n_blades))
    for r in resp.roms:
        fams = {}
        for i, fam in enumerate(resp.families):
            entry = {"band_hz": [_num(v) for v in r.bands_hz[i]], "damping_ratio": _num(r.damping_ratio[i])}
            if r.refused[i]:
                entry["refused"] = r.refused[i]
            else:
                entry["eo"] = {str(eo): _eo_entry(r, i, e, whitehead) for e, eo in enumerate(resp.eos)}
            fams[str(fam)] = entry
        roms[r.rom] = {"solve": r.solve, "families": fams}
    return {"n_blades": resp.n_blades, "point": resp.point, "whitehead_limit": whitehead,
            "families": list(resp.families), "eos": list(resp.eos), "damping_source": resp.damping_source,
            "exported": resp.roms[0].rom, "roms": roms, "not_computed": list(NOT_COMPUTED)}


def response_rows(block: dict, eos=None, families=None) -> list[list]:
    """``response.csv``'s rows (:data:`RESPONSE_HEADER`) of a ``response`` block, for the EOs and families asked
    (default all); a refused family is left out."""
    rows = []
    for rom, r in block["roms"].items():
        for fam, f in r["families"].items():
            if (families is None or int(fam) in families) and "eo" in f:
                rows += [[rom, int(fam), int(eo), v["af"], v["worst_blade"], v["peak_hz"], v["tuned_peak_hz"],
                          f["damping_ratio"]] for eo, v in f["eo"].items() if eos is None or int(eo) in eos]
    return rows


def worst_rows(block: dict) -> list[list]:
    """Per ROM and family, the EO with the largest AF (:data:`WORST_HEADER`)."""
    rows = []
    for rom, r in block["roms"].items():
        for fam, f in r["families"].items():
            vals = {int(eo): v for eo, v in f.get("eo", {}).items() if v["af"] is not None}
            if vals:
                eo = max(vals, key=lambda k: vals[k]["af"])
                rows.append([rom, int(fam), eo, vals[eo]["af"], vals[eo]["worst_blade"], f["damping_ratio"]])
    return rows


def plot_response(block: dict, eos=None, families=None):
    """AF against EO, one panel per family, each ROM a line of its own colour in every panel, Whitehead's limit
    (1 + √N)/2 dashed; a panel without an AF says so (the report's text gives each reason)."""
    fams = [int(f) for f in block["families"] if families is None or int(f) in families]
    fig, axes = plt.subplots(1, len(fams), figsize=(3.6 * len(fams) + 0.6, 3.6), squeeze=False, sharey=True)
    style = {rom: (f"C{k}", "os^"[k % 3]) for k, rom in enumerate(block["roms"])}
    for ax, fam in zip(axes[0], fams, strict=True):
        drawn = False
        for rom, r in block["roms"].items():
            pts = sorted((int(eo), v["af"]) for eo, v in r["families"][str(fam)].get("eo", {}).items()
                         if (eos is None or int(eo) in eos) and v["af"] is not None)
            if pts:
                ax.plot(*zip(*pts, strict=True), marker=style[rom][1], color=style[rom][0])
                drawn = True
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
    handles = [Line2D([], [], color=c, marker=m, label=f"{rom} ROM") for rom, (c, m) in style.items()]
    handles += [Line2D([], [], ls="--", color="0.4", label="Whitehead (1+√N)/2"),
                Line2D([], [], ls=":", color="0.6", label="tuned (AF = 1)")]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return fig


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
    text = [f"Forced response under engine-order excitation (a travelling wave at blade point {block['point']} of "
            f"every blade, EO 0..{max(block['eos'])}) and the mistuning amplification factor: the worst blade's peak "
            "over the tuned disk's (every joint with the films' mean pattern, every blade the mean blade), family "
            f"by family, with each family's damping from {block['damping_source']}. Whitehead's limit "
            f"(1 + √N)/2 = {block['whitehead_limit']:.3f}. Not computed yet: the AF's 90 % interval and each blade's "
            "probability to be the worst over the posterior, and the truth's AF on a virtual campaign.", *notes]
    section = {"id": "response", "title": "Forced response and amplification factor", "text": text,
               "figures": [{"file": fig, "caption": "Amplification factor against engine order, per family, the "
                            "exported ROM and the paper's; Whitehead's limit dashed."}],
               "tables": [{"file": table, "caption": "Per family, the engine order with the largest amplification "
                           "factor, and its worst blade."}]}
    return section, block
