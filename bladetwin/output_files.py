"""The run's files, written atomically: CSV tables and figures (skipped under ``bladetwin run --no-figures``)."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from .util import atomic_savefig, atomic_write_text, drawing_figures

__all__ = ["NO_FIGURES_NOTE", "write_csv", "save_figure", "blank"]


def write_csv(path: Path, header: list[str], rows: list[list]) -> str:
    """``rows`` under ``header`` as CSV at ``path`` (floats with 6 significant digits); returns the file's name."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow([f"{v:.6g}" if isinstance(v, float | np.floating) else v for v in r])
    atomic_write_text(path, buf.getvalue())
    return path.name


#: The report's note on a run without figures.
NO_FIGURES_NOTE = "Figures were not drawn (bladetwin run --no-figures); rerun without it to draw them."


def save_figure(make: Callable[[], Figure], path: Path) -> str | None:
    """``make()``'s figure saved to ``path`` (its name returned); nothing drawn and None under ``--no-figures``."""
    if not drawing_figures():
        return None
    fig = make()
    atomic_savefig(fig, path, dpi=110)
    plt.close(fig)
    return path.name


def blank(v: float):
    """A table cell: empty where ``v`` is not finite."""
    return "" if not np.isfinite(v) else float(v)
