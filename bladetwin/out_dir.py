"""A run's output folder: checked before any computation, and cleared of what an earlier run wrote and this one
did not (a reused ``--out`` must not show figures this run did not make)."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from .campaign import CampaignError

__all__ = ["check_out_dir", "listed_files", "previous_summary", "remove_stale"]


def check_out_dir(out: Path, flag: str = "--out") -> None:
    """Refuse, in one line, an output folder that cannot be written: a file in its place, or no write access.

    Creates the folder (and its parents) when it does not exist, and probes it with a temporary file, so a run
    fails in seconds instead of after its computation.
    """
    out = Path(out)
    for parent in (out, *out.parents):
        if parent.exists() and not parent.is_dir():
            raise CampaignError(f"{flag} {out}: {parent} is a file, expected a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".probe-", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise CampaignError(f"{flag} {out}: cannot write there ({exc.strerror or exc})") from None


def listed_files(summary: dict) -> set[str]:
    """The files a run's ``summary.json`` says it wrote: its report sections' figures and tables, and its files."""
    names = {"summary.json", "report.html"}
    for section in summary.get("sections") or []:
        for item in (section.get("figures") or []) + (section.get("tables") or []):
            if isinstance(item, dict) and isinstance(item.get("file"), str):
                names.add(item["file"])
    names.update(v for v in (summary.get("files") or {}).values() if isinstance(v, str))
    return {n for n in names if Path(n).name == n}  # plain names in the folder, nothing elsewhere


def previous_summary(out: Path) -> dict:
    """The ``summary.json`` an earlier run left in ``out`` ({} if none, or unreadable)."""
    try:
        return json.loads((Path(out) / "summary.json").read_text())
    except (OSError, ValueError):
        return {}


def remove_stale(out: Path, before: dict, after: dict) -> list[str]:
    """Remove the files the earlier run listed (``before``) that this run (``after``) did not write; their names."""
    stale = sorted(listed_files(before) - listed_files(after))
    for name in stale:
        (Path(out) / name).unlink(missing_ok=True)
    return stale
