"""Re-assemblies compared where they differ (issue 48): what the index page of several campaigns of one disk shows
beside their Table 8.

Labs re-test one disk after each re-assembly. For every pair of campaigns (:func:`campaign_pairs`) the page marks
the joints whose contact changed (:func:`changed_quantities`, the rule below), shows each campaign's contact maps
and films side by side (:func:`contact_maps`, :func:`film_views`) and Table 8 with the updated ROM
(:func:`updated_table8`). Like :mod:`bladetwin.index_page` it only reads what the runs wrote and computes no
result: each campaign's ``summary.json``, the posterior's table it lists, the figures it lists and the film scans
its campaign's manifest names.

Where the intervals come from
-----------------------------
``summary.json``'s joint rows give each joint's area fraction per flank (``area_fraction_L_pct``,
``area_fraction_R_pct``) and its ``source`` ("film" for a filmed joint), but no interval. The contact posterior's
table, which ``summary.json`` lists in its ``posterior`` section (``posterior_contact.csv``), holds every
unfilmed joint's answer with its 90 % interval: the area of each flank and the centroid (u, v) of each flank, a
column ``X`` followed by ``… 5 %`` and ``… 95 %``. Both area and centroid are compared. A run of the k-NN alone
(``--method knn``) writes no posterior, hence no interval: its unfilmed joints are "unavailable", never marked.
A film gives no centroid in ``summary.json``: a filmed joint is compared on its areas only.

The rule
--------
A joint is **changed** between campaigns *a* and *b* when, on some flank, one of its quantities (area, centroid
u or v) moved beyond what the runs can tell apart:

* posterior against posterior: the two 90 % intervals do not overlap;
* film against film: a film is exact (read node by node), so its area is compared directly: changed when the two
  areas differ by more than :data:`FILM_CHANGE_PP` percentage points of the flank;
* film against posterior (a joint filmed in one campaign only): the film's area as an interval of zero width,
  so changed when it lies outside the posterior's 90 % interval.
"""

from __future__ import annotations

import os
from itertools import combinations
from pathlib import Path

from .campaign import CampaignError, read_campaign
from .report_cells import MISSING, UNAVAILABLE, ReportError, as_float, format_column, read_csv_table

__all__ = ["CHANGED", "FILM_CHANGE_PP", "ALL_PAIRS_UP_TO", "joint_contact", "read_contact", "changed_quantities",
           "campaign_pairs", "change_marks", "contact_maps", "film_views", "updated_table8", "UPDATED_CASES",
           "POSTERIOR_SECTION", "IDENTIFICATION_SECTION", "KNN_MAP"]

#: The mark of a changed joint (and its legend line's symbol).
CHANGED = "●"
#: Two films of one joint differ when their areas differ by more than this (percentage points of the flank): a
#: film is exact, but reading it onto the grid may move its edge by a node (one node of a 3×7 flank is 4.8 pp;
#: 5 pp is about 11 nodes of the academic disk's 7×31).
FILM_CHANGE_PP = 5.0
#: Up to this many campaigns every pair is compared; beyond, each campaign with the one before (its re-assembly).
ALL_PAIRS_UP_TO = 3
#: summary.json's sections the page reads: the posterior's (its table and maps), the identification's (maps of
#: a k-NN run).
POSTERIOR_SECTION, IDENTIFICATION_SECTION = "posterior", "identification"
#: The k-NN's map of every joint, the contact figure where the posterior did not run (as the report leads with).
KNN_MAP = "identified_patterns_map.png"
_UNITS = {" (%)": "%", " (mm)": "mm"}


# ------------------------------------------------------------------------------------------- the contact


def joint_contact(summary: dict, header: list[str] | None = None, rows: list[list[str]] = ()) -> dict[int, dict]:
    """Every joint's contact as the page compares it: ``{joint: {"film": bool, "values": {name: (v, lo, hi)}}}``.

    Parameters
    ----------
    summary : dict
        A campaign's ``summary.json``; its ``joints`` rows give the films' areas (``area_fraction_L_pct``,
        ``area_fraction_R_pct``) and which joints are filmed (``source`` "film").
    header, rows : optional
        The posterior's table (``posterior_contact.csv``): a column ``X (%)`` or ``X (mm)`` followed by
        ``… 5 %`` and ``… 95 %`` is a quantity ``X`` with its 90 % interval. None: no posterior ran.

    Returns
    -------
    dict
        A film's areas as intervals of zero width ``(a, a, a)`` under ``"area L"`` and ``"area R"``; an unfilmed
        joint's quantities from the posterior's table (none without it). Names carry their unit in
        ``"units"``.
    """
    out: dict[int, dict] = {}
    for r in summary.get("joints", []):
        film = r.get("source") == "film"
        values = {}
        if film:
            for side in ("L", "R"):
                a = as_float(r.get(f"area_fraction_{side}_pct"))
                if a is not None:
                    values[f"area {side}"] = (a, a, a)
        out[int(r["joint"])] = {"film": film, "values": values, "units": {}}
    header = header or []
    for k, name in enumerate(header[:-2]):
        suffix = next((x for x in _UNITS if name.endswith(x)), None)
        if suffix is None or not (header[k + 1].endswith(" 5 %") and header[k + 2].endswith(" 95 %")):
            continue
        quantity = name[: -len(suffix)]
        for row in rows:
            joint = as_float(row[0])
            v, lo, hi = (as_float(x) for x in row[k:k + 3])
            entry = out.get(int(joint)) if joint is not None else None
            if entry is None or entry["film"] or None in (v, lo, hi):
                continue
            entry["values"][quantity] = (v, lo, hi)
            entry["units"][quantity] = _UNITS[suffix]
    return out


def read_contact(summary: dict, folder: str | os.PathLike) -> dict[int, dict]:
    """:func:`joint_contact` of the campaign whose output folder is ``folder`` (its posterior's table where
    ``summary.json`` lists one with intervals)."""
    for section in summary.get("sections", []):
        if section.get("id") != POSTERIOR_SECTION:
            continue
        for table in section.get("tables", []):
            try:
                header, rows = read_csv_table(Path(folder) / str(table.get("file")))
            except ReportError:
                continue
            if any(h.endswith(" 5 %") for h in header):
                return joint_contact(summary, header, rows)
    return joint_contact(summary)


def changed_quantities(a: dict, b: dict, film_pp: float = FILM_CHANGE_PP) -> list[str] | None:
    """The quantities of one joint that changed from campaign ``a`` to ``b`` (entries of :func:`joint_contact`).

    Two films: an area that moved by more than ``film_pp`` percentage points. Otherwise (a posterior on either
    side): a quantity whose two 90 % intervals do not overlap, a film's area being an interval of zero width.
    Non-overlap rather than "one's estimate outside the other's interval": it is symmetric (a → b reads as
    b → a), and the posterior's estimate, its majority pattern, may sit on its own interval's edge, where the
    other rule would mark a joint that only the noise moved.

    Returns
    -------
    list of str or None
        The changed quantities (empty: unchanged); None where the two share no quantity to compare (a k-NN run
        gives no interval).
    """
    common = [q for q in a["values"] if q in b["values"]]
    if not common:
        return None
    if a["film"] and b["film"]:
        return [q for q in common if abs(a["values"][q][0] - b["values"][q][0]) > film_pp]
    return [q for q in common if a["values"][q][2] < b["values"][q][1] or b["values"][q][2] < a["values"][q][1]]


def campaign_pairs(n: int) -> list[tuple[int, int]]:
    """The pairs of campaigns compared (indices): every pair up to :data:`ALL_PAIRS_UP_TO` campaigns, else each
    with the one before (a re-assembly with the previous one)."""
    return list(combinations(range(n), 2)) if n <= ALL_PAIRS_UP_TO else [(k, k + 1) for k in range(n - 1)]


def _explain(q: str, a: dict, b: dict) -> str:
    """A tooltip line: the quantity in both campaigns, each value with its interval (the one formatting rule)."""
    va, vb = a["values"][q], b["values"][q]
    unit = a["units"].get(q) or b["units"].get(q) or "%"
    t = format_column([*va, *vb], percent=unit == "%")

    def shown(entry: dict, texts: list[str]) -> str:
        return f"{texts[0]} (film)" if entry["film"] else f"{texts[0]} [{texts[1]}, {texts[2]}]"

    return f"{q}: {shown(a, t[:3])} → {shown(b, t[3:])} {unit}"


def change_marks(summaries: list[dict], contacts: list[dict[int, dict]], n_joints: int) -> dict:
    """The pairs' columns of the joint table and the page's list of changed joints per pair.

    Returns
    -------
    dict
        ``heads`` (one "a → b" per pair), ``marks`` (per joint 1..``n_joints``, one ``{"text", "title"}`` per
        pair: :data:`CHANGED` with the values compared in ``title``, "" unchanged, "unavailable" without an
        interval, "—" where a campaign lacks the joint) and ``changed`` (per pair ``{"pair", "joints"}``, the
        joints marked, each ``{"joint", "quantities"}``).
    """
    pairs = campaign_pairs(len(summaries))
    names = [s.get("campaign", f"campaign {k + 1}") for k, s in enumerate(summaries)]
    marks: list[list[dict]] = [[] for _ in range(n_joints)]
    changed = []
    for i, k in pairs:
        found = []
        for j in range(1, n_joints + 1):
            a, b = contacts[i].get(j), contacts[k].get(j)
            qs = None if a is None or b is None else changed_quantities(a, b)
            if a is None or b is None:
                cell = {"text": MISSING, "title": "the joint is not in both campaigns"}
            elif qs is None:
                cell = {"text": UNAVAILABLE, "title": "no 90 % interval to compare (the k-NN gives none)"}
            elif qs:
                cell = {"text": CHANGED, "title": "; ".join(_explain(q, a, b) for q in qs)}
                found.append({"joint": j, "quantities": ", ".join(qs)})
            else:
                cell = {"text": "", "title": "unchanged"}
            marks[j - 1].append(cell)
        changed.append({"pair": f"{names[i]} → {names[k]}", "joints": found})
    return {"heads": [f"{names[i]} → {names[k]}" for i, k in pairs], "marks": marks, "changed": changed}


# --------------------------------------------------------------------------------------- figures and films


def _figure(summary: dict, section_id: str, file: str | None) -> dict | None:
    for section in summary.get("sections", []):
        if section.get("id") == section_id:
            for f in section.get("figures", []):
                if f.get("file") and (file is None or f["file"] == file):
                    return f
    return None


def contact_maps(summaries: list[dict], outs: list[Path], root: Path) -> list[dict]:
    """Each campaign's map of its unfilmed joints' contact, as its report leads with: the posterior's
    probability maps, else the k-NN's identified patterns. ``{"name", "src", "caption"}``, ``src`` relative to
    ``root`` (None where the run drew no figure, under ``--no-figures``)."""
    out = []
    for s, o in zip(summaries, outs, strict=True):
        fig = _figure(s, POSTERIOR_SECTION, None) or _figure(s, IDENTIFICATION_SECTION, KNN_MAP)
        path = Path(o) / fig["file"] if fig else None
        ok = path is not None and path.is_file()
        out.append({"name": s.get("campaign", ""), "src": os.path.relpath(path, root) if ok else None,
                    "caption": fig.get("caption", "") if ok else "no contact map drawn (bladetwin run "
                                                                      "--no-figures draws none)"})
    return out


def film_views(summaries: list[dict], root: Path) -> dict:
    """The filmed joints' film scans, campaign by campaign: the files each campaign's manifest names (those the
    run read; ``summary.json`` keeps the campaign's folder), relative to ``root``.

    Returns
    -------
    dict
        ``joints`` (every joint filmed in some campaign), ``rows`` (per joint, per campaign ``{"L", "R"}`` paths,
        or None where that campaign did not film it) and ``missing`` (the campaigns whose manifest could not be
        read, with why).
    """
    films: list[dict] = []
    missing = []
    for s in summaries:
        try:
            c = read_campaign(s["campaign_dir"], allow_outside=True)
        except (CampaignError, KeyError, OSError) as exc:
            films.append({})
            missing.append(f"{s.get('campaign', '')}: {exc}")
            continue
        films.append({(f.joint, f.flank): os.path.relpath(f.file, root) for f in c.films})
    joints = sorted({j for f in films for j, _ in f})
    rows = [[{"L": f.get((j, "L")), "R": f.get((j, "R"))} if (j, "L") in f or (j, "R") in f else None
             for f in films] for j in joints]
    return {"joints": joints, "rows": rows, "missing": missing}


# ------------------------------------------------------------------------------------------ the updated ROM


#: Table 8 of the updated ROM: ``summary["rom"]["updated"]["cases"]``'s rows.
UPDATED_CASES = (("A", "Case A"), ("B", "Case B"), ("C", "Case C"), ("B_baseline", "control (as Case B)"))


def updated_table8(summaries: list[dict]) -> list[list[str]]:
    """Table 8 of each campaign's updated ROM (``summary["rom"]["updated"]["cases"]``): per case, |Δf| (%) and
    MAC per campaign, by the one formatting rule down each column; "unavailable" where the ROM update did not
    run (``--rom paper``) or a case was not computed."""
    columns = []
    for s in summaries:
        rom = s.get("rom") if isinstance(s.get("rom"), dict) else {}
        cases = (rom.get("updated") or {}).get("cases") or {}
        found = [cases.get(key) if isinstance(cases.get(key), dict) else None for key, _ in UPDATED_CASES]
        for metric, percent in (("mean_abs_df_pct", True), ("mean_mac", False)):
            values = [None if c is None else c.get(metric) for c in found]
            texts = format_column(values, percent=percent)
            columns.append([UNAVAILABLE if v is None else t for v, t in zip(values, texts, strict=True)])
    return [[label, *(col[i] for col in columns)] for i, (_, label) in enumerate(UPDATED_CASES)]
