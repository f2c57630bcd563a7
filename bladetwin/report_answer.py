"""The report's first screen: the ROM a lab takes away, how far to trust it and the contact, and the folded notes.

A lab opens the report with three questions: what is the contact of every joint, which ROM do I take away and
how well does it match my test, and how far can I trust both. The contact maps answer the first
(:mod:`bladetwin.report_rows` places them); this module words the other two from ``summary.json`` alone, so that
every figure on the first screen is the run's own and none is written into the template.
"""

from __future__ import annotations

import re
from typing import Any

from .report_cells import as_float, as_list, format_column, format_number

__all__ = ["rom_choice", "trust_paragraphs", "headline", "HEADLINE_CHARS"]

#: A headline longer than this is cut at a word and ends with "…" (one line of the page at 1400 px).
HEADLINE_CHARS = 110
_SENTENCE_END = re.compile(r"(?<=[.!?])\s+(?=[A-Z(])")


def _get(doc: Any, *keys: str) -> Any:
    for k in keys:
        if not isinstance(doc, dict):
            return None
        doc = doc.get(k)
    return doc


def _case(c: Any) -> dict | None:
    """A case of summary.json if it holds the two figures the first screen quotes, else None."""
    if isinstance(c, dict) and as_float(c.get("mean_abs_df_pct")) is not None and as_float(c.get("mean_mac")) \
            is not None:
        return c
    return None


def _cases(summary: dict) -> dict[str, dict | None]:
    """Case B of the ROM taken away and of the paper's ROM, its control and Case C, from what the run wrote.

    With the updated ROM (``rom.updated``) every case is the updated ROM's and the paper's ROM is beside it;
    without it (``--rom paper``) the paper's ROM is the one taken away, with the run's answer: the contact
    posterior's where it ran, else the k-NN's.
    """
    rom = summary.get("rom") if isinstance(summary.get("rom"), dict) else {}
    updated = _get(rom, "updated", "cases")
    if isinstance(updated, dict) and _case(updated.get("B")):
        paper = _get(rom, "paper", "cases") or {}
        return {"kind": "updated", "B": _case(updated.get("B")), "control": _case(updated.get("B_baseline")),
                "C": _case(updated.get("C")), "paper_B": _case(paper.get("B"))}
    cases = summary.get("cases") if isinstance(summary.get("cases"), dict) else {}
    post = _case(_get(cases, "posterior", "B"))
    return {"kind": "paper", "B": post or _case(cases.get("B")), "control": _case(_get(cases, "baseline", "B")),
            "C": _case(cases.get("C")), "paper_B": None}


def _answer(summary: dict) -> str:
    sources = {str(j.get("source")) for j in as_list(summary.get("joints")) if isinstance(j, dict)}
    return "the contact posterior's" if "posterior" in sources else "the k-NN's"


def _paired(c: dict) -> str:
    n, ref = c.get("n_modes"), c.get("n_reference_modes")
    if n is None:
        return "—"
    return f"{n} of {ref}" if ref is not None else str(n)


def rom_choice(summary: dict) -> dict | None:
    """The ROM the lab takes away and the paper's beside it: Case B rows for the first screen.

    Returns
    -------
    dict or None
        ``rows``: (label, description, [mean |Δf| %, mean MAC, paired modes], whether it is the one taken away),
        one number of decimals down each column; ``text``: which ROM, with which answer, is exported; None when
        Case B was not computed (no full-assembly test).
    """
    c = _cases(summary)
    if c["B"] is None:
        return None
    answer = _answer(summary)
    if c["kind"] == "updated":
        entries = [("updated ROM", "in-situ corrections and contact stiffness fitted on the disk–one-blade tests "
                    "(beyond the paper)", c["B"], True)]
        if c["paper_B"] is not None:
            entries.append(("paper's ROM", "Eq. 19 deltas, rigid contact ties", c["paper_B"], False))
        text = f"The updated ROM, with {answer} contact at the unfilmed joints"
        replaced = [r["joint"] for r in _get(summary, "rom", "updated", "parameters", "replaced_joints") or []]
        if replaced:  # design §8.84
            text += (f" (joint{'s' if len(replaced) > 1 else ''} {', '.join(map(str, replaced))}: the posterior "
                     "draw its disk–one-blade test bears out, where the answer left its blade's correction "
                     "implausible)")
    else:
        entries = [("paper's ROM", "Eq. 19 deltas, rigid contact ties", c["B"], True)]
        text = f"The paper's ROM (the updated one did not run), with {answer} contact at the unfilmed joints"
    dfs = format_column([e[2]["mean_abs_df_pct"] for e in entries], percent=True)
    macs = format_column([e[2]["mean_mac"] for e in entries])
    rows = [(label, desc, [df, mac, _paired(case)], taken)
            for (label, desc, case, taken), df, mac in zip(entries, dfs, macs, strict=True)]
    return {"rows": rows, "text": text}


def _pct(v: Any) -> str:
    return format_number(v, percent=True)


def _interval_sentences(post: dict) -> list[str]:
    """What the posterior's intervals say: their width, and how much the tests narrowed them from the films'."""
    exp = _get(post, "experimental") or {}
    ratio = _get(post, "width_ratio", "experimental") or {}
    width = _get(post, "area_ci90_median_width_pp", "experimental") or exp.get("ci90_median_width_pp")
    out = []
    if width is not None:
        out.append(f"The 90 % interval of an unfilmed joint's contact area is {format_number(width)} pp wide "
                   "(median over the flanks).")
    areas = [float(v) for k, v in ratio.items() if k.startswith("area") and as_float(v) is not None]
    cents = [float(v) for k, v in ratio.items() if k.startswith("centroid") and as_float(v) is not None]
    if areas and cents:
        out.append(f"The tests narrow it to {_span(areas)} of the films' prior, the centroid's only to "
                   f"{_span(cents)}: where the contact sits comes mostly from the films.")
    if exp.get("ci90_coverage_area") is not None:
        out.append(f"Against the true patterns it holds the true area on "
                   f"{format_number(100 * exp['ci90_coverage_area'], 2)} % of the flanks (90 % expected).")
    held = [(what, exp.get(key)) for what, key in _HELD if as_float(exp.get(key)) is not None]
    if held:
        out.append("Its 90 % intervals hold " + "; ".join(f"{what} on {format_number(100 * v, 2)} %"
                                                          for what, v in held) + ".")
    return out or ["The contact posterior gave no interval for this campaign."]


#: The posterior's other coverages the report states: what each interval is checked against, and its key.
_HELD = (("the true centroid (each flank's u and v)", "ci90_coverage_centroid"),
         ("the ROM's feature frequencies with the true pattern", "ci90_coverage_frequency"))


def _span(values: list[float]) -> str:
    lo, hi = format_number(min(values), 2), format_number(max(values), 2)
    return lo if lo == hi else f"{lo}–{hi}"


def _contact_paragraph(summary: dict) -> str:
    post = _get(summary, "methods", "posterior")
    if isinstance(post, dict):
        sentences = _interval_sentences(post)
        exp = _get(post, "experimental") or {}
    else:
        sentences = ["The k-NN gives each joint one synthetic pattern pair and no interval (--method posterior "
                     "gives one)."]
        exp = _get(summary, "methods", "knn", "experimental") or {}
    base = _get(summary, "methods", "baseline", "area_error_pp")
    if exp.get("area_error_pp") is not None:
        sentences.append(f"The answer's area is off the truth by {format_number(exp['area_error_pp'])} pp on average"
                         + (f" (the films' majority pattern: {format_number(base)} pp)." if base is not None else "."))
    elif str(summary.get("kind")) == "lab":
        sentences.append("A lab campaign has no truth at the unfilmed joints: the intervals are the measure.")
    outside = [str(j["joint"]) for j in as_list(summary.get("joints"))
               if isinstance(j, dict) and j.get("outside_family")]
    if len(outside) == 1:
        sentences.append(f"Joint {outside[0]} lies beyond the synthetic family: trust it less.")
    elif outside:
        sentences.append(f"Joints {', '.join(outside)} lie beyond the synthetic family: trust them less.")
    return " ".join(sentences)


def _verdict(b: dict, ctrl: dict) -> str:
    """What the control says of the identified contact, figure by figure as printed."""
    df = (_pct(b["mean_abs_df_pct"]), _pct(ctrl["mean_abs_df_pct"]))
    mac = (format_number(b["mean_mac"]), format_number(ctrl["mean_mac"]))
    better_df = b["mean_abs_df_pct"] < ctrl["mean_abs_df_pct"] and df[0] != df[1]
    better_mac = b["mean_mac"] > ctrl["mean_mac"] and mac[0] != mac[1]
    if better_df and better_mac:
        return "the identified contact improves both figures"
    if better_df or better_mac:
        return (f"the identified contact improves the {'|Δf|' if better_df else 'MAC'} only: the test barely tells "
                "the contacts apart")
    return "the identified contact does not improve the match: the match comes from the rest of the ROM"


def _rom_paragraph(summary: dict) -> str | None:
    c = _cases(summary)
    b = c["B"]
    if b is None:
        return None
    rom = "updated ROM" if c["kind"] == "updated" else "paper's ROM"
    # word joiners keep "|Δf|" on one line
    text = (f"The {rom} matches the full-assembly test to {_pct(b['mean_abs_df_pct'])} % mean |\u2060Δf\u2060|, MAC "
            f"{format_number(b['mean_mac'])} ({_paired(b)} measured modes paired, Case B).")
    ctrl = c["control"]
    if ctrl is not None:
        text += (f" The control, with the films' majority pattern at every unfilmed joint: "
                 f"{_pct(ctrl['mean_abs_df_pct'])} %, {format_number(ctrl['mean_mac'])}; {_verdict(b, ctrl)}.")
    if c["C"] is not None:
        text += (f" With the true patterns (Case C): {_pct(c['C']['mean_abs_df_pct'])} %, "
                 f"{format_number(c['C']['mean_mac'])}, the model's own error.")
    return text


def trust_paragraphs(summary: dict) -> list[tuple[str, str]]:
    """How far to trust the contact and the ROM: one short paragraph each, (title, text), from ``summary.json``."""
    out = [("Contact", _contact_paragraph(summary))]
    rom = _rom_paragraph(summary)
    if rom:
        out.append(("ROM", rom))
    return out


def headline(text: str) -> tuple[str, bool]:
    """A note's or a warning's one-line headline: its first sentence, cut at a word past
    :data:`HEADLINE_CHARS` characters; and whether the headline leaves part of the text out."""
    text = " ".join(str(text).split())
    first = _SENTENCE_END.split(text, maxsplit=1)[0]
    if len(first) > HEADLINE_CHARS:
        cut = first[:HEADLINE_CHARS].rsplit(" ", 1)[0].rstrip(",;:")
        first = cut + " …"
    return first, first != text
