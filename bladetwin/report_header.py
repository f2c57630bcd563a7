"""The report's header: the campaign's identity, the run's key settings and its timings, from ``summary.json``."""

from __future__ import annotations

import math
from typing import Any

from .report_cells import MISSING, UNAVAILABLE, as_float, as_list, format_column, format_number

__all__ = ["header_items", "fact_items", "timing_rows"]

_KIND_TEXT = {
    "virtual": "virtual campaign (simulated on the digital twin; the true patterns are known)",
    "lab": "laboratory campaign (measured; only the filmed joints have a reference)",
}
_TIMING_LABELS = {
    "ema": "experimental modal analysis",
    "rom": "reduced-order models",
    "dataset": "dataset (δ grid × patterns)",
    "identify": "identification (k-NN)",
    "validation": "validation",
    "report": "report",
    "total": "total",
}
def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return MISSING
    s = round(seconds)
    if s < 60:
        return f"{seconds:.1f} s"
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h} h {m:02d} min" if h else f"{m} min {s:02d} s"


def timing_rows(summary: dict) -> list[tuple[str, str, str, bool]]:
    """Each stage group's time: (label, seconds, as read by a person, whether it is the total)."""
    raw = summary.get("timings_s") if isinstance(summary.get("timings_s"), dict) else {}
    items = [(k, v) for k, v in raw.items() if k != "total"] + ([("total", raw["total"])] if "total" in raw else [])
    seconds = format_column([as_float(v) for _, v in items])
    out = []
    for (key, v), secs in zip(items, seconds, strict=True):
        x = as_float(v)
        label = _TIMING_LABELS.get(key, str(key))
        out.append((label, MISSING if x is None else secs, MISSING if x is None else _duration(x), key == "total"))
    return out


def _joined(values: Any, sep: str = ", ") -> str | None:
    seq = as_list(values)
    return sep.join(format_number(v) for v in seq) if seq else None


def fact_items(summary: dict) -> list[tuple[str, str]]:
    """The identification's settings a reader needs first: feature modes, step-1 grid error, bias correction."""
    facts = []
    if summary.get("feature_modes"):
        facts.append(("Feature modes (disk–one-blade)", _joined(summary["feature_modes"])))
    step1 = summary.get("step1")
    if isinstance(step1, dict) and "max_abs_eps_pct" in step1:
        v = step1["max_abs_eps_pct"]
        text = UNAVAILABLE if v is None else \
            f"{format_number(v, percent=True)} % (target ≤ 50 %: the nearest δ grid value)"
        facts.append(("Largest step-1 grid error |ε|", text))
    bias = summary.get("bias")
    if isinstance(bias, dict):
        if not bias.get("enabled", False):
            facts.append(("Bias correction", "off"))
        else:
            joints = _joined(bias.get("joints"))
            facts.append(("Bias correction", "on" + (f", estimated on filmed joints {joints}" if joints else "")))
    return facts


def header_items(summary: dict) -> list[tuple[str, str]]:
    """The campaign's identity: kind, blades, grid, filmed joints, folder, when and by which version."""
    items = []
    kind = summary.get("kind")
    if kind is not None:
        items.append(("Kind", _KIND_TEXT.get(str(kind), str(kind))))
    if summary.get("n_blades") is not None:
        items.append(("Blades", format_number(summary["n_blades"])))
    grid = as_list(summary.get("grid"))
    if grid:
        items.append(("Contact grid per flank", " × ".join(format_number(g) for g in grid)))
    if "known_joints" in summary:
        items.append(("Known (filmed) joints", _joined(summary.get("known_joints")) or "none"))
    if summary.get("campaign_dir"):
        items.append(("Campaign folder", str(summary["campaign_dir"])))
    if summary.get("generated"):
        items.append(("Generated", str(summary["generated"])))
    if summary.get("bladetwin_version"):
        items.append(("bladetwin version", str(summary["bladetwin_version"])))
    return items
