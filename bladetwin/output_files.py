"""The run's files, written atomically: CSV tables and figures (skipped under ``bladetwin run --no-figures``)."""

from __future__ import annotations

import csv
import io
import multiprocessing
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from .user_warnings import recording
from .util import atomic_savefig, atomic_write_text, drawing_figures

__all__ = ["NO_FIGURES_NOTE", "write_csv", "save_figure", "figures_deferred", "blank"]

#: The figures asked for inside :func:`figures_deferred`, as (make, path); None outside it.
_PENDING: ContextVar[list | None] = ContextVar("bladetwin_pending_figures", default=None)
#: The figures a forked drawing process reads (inherited through the fork: closures cannot be pickled).
_JOBS: list = []


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
    """``make()``'s figure saved to ``path`` (its name returned); nothing drawn and None under ``--no-figures``.

    Inside :func:`figures_deferred` the figure is drawn when the block ends.
    """
    if not drawing_figures():
        return None
    pending = _PENDING.get()
    if pending is None:
        _draw(make, path)
    else:
        pending.append((make, Path(path)))
    return Path(path).name


def _draw(make: Callable[[], Figure], path: Path) -> None:
    fig = make()
    atomic_savefig(fig, path, dpi=110)
    plt.close(fig)


def _draw_job(index: int) -> list[str]:
    """Draw :data:`_JOBS` [index] in a forked process; return its user warnings for the parent to record."""
    with recording() as texts:
        _draw(*_JOBS[index])
    return texts


@contextmanager
def figures_deferred(workers: int) -> Iterator[None]:
    """Draw the figures asked for inside the block when it ends, on up to ``workers`` forked processes.

    Drawing is most of a run's writing time (about 14 s of a default run on one core), and the figures are
    independent. Their files are complete when the block ends; a figure's user warnings are raised again here,
    in figure order, so that a caller's :func:`bladetwin.user_warnings.recording` gets them. Where processes
    cannot be forked, or for one worker, the figures are drawn here, one after the other. A block that raises
    draws nothing.
    """
    pending: list = []
    token = _PENDING.set(pending)
    try:
        yield
    finally:
        _PENDING.reset(token)
    n = min(int(workers), len(pending))
    if n < 2 or "fork" not in multiprocessing.get_all_start_methods():
        for make, path in pending:
            _draw(make, path)
        return
    _JOBS[:] = pending
    try:
        with multiprocessing.get_context("fork").Pool(n) as pool:
            texts = pool.map(_draw_job, range(len(pending)), chunksize=1)
    finally:
        _JOBS.clear()
    for t in (t for job in texts for t in job):
        warnings.warn(t, UserWarning, stacklevel=2)


def blank(v: float):
    """A table cell: empty where ``v`` is not finite."""
    return "" if not np.isfinite(v) else float(v)
