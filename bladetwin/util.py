"""Floor-3 helpers: atomic file output, readable tables, step progress (policy lives here, not in the libraries)."""

from __future__ import annotations

import json
import sys
import time
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from rom.fileio import atomic_path

__all__ = ["atomic_write_text", "atomic_savefig", "format_table", "step", "print_json", "drawing_figures",
           "figures_drawn"]

#: Whether the run's outputs draw their figures (``bladetwin run --no-figures``: not).
_DRAW: ContextVar[bool] = ContextVar("bladetwin_draw_figures", default=True)


def drawing_figures() -> bool:
    """Whether figures are drawn here (False inside ``figures_drawn(False)``)."""
    return _DRAW.get()


@contextmanager
def figures_drawn(draw: bool):
    """Draw the outputs' figures, or skip them, inside the block (they take most of a small run's writing time)."""
    token = _DRAW.set(bool(draw))
    try:
        yield
    finally:
        _DRAW.reset(token)


def _atomic(path: Path, write) -> Path:
    with atomic_path(path) as tmp:
        write(tmp)
    return Path(path)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write text via a temporary file in the same folder and an atomic rename."""
    return _atomic(Path(path), lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def atomic_savefig(fig, path: str | Path, dpi: int = 150) -> Path:
    """Save a matplotlib figure atomically; the format follows the file suffix."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    return _atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))


def format_table(headers: list[str], rows: list[list], floatfmt: str = "{:.1f}") -> str:
    """A plain-text table with right-aligned columns."""
    cells = [[floatfmt.format(v) if isinstance(v, float) else str(v) for v in r] for r in rows]
    widths = [max(len(h), *(len(r[k]) for r in cells)) if cells else len(h) for k, h in enumerate(headers)]
    line = "  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in cells]
    return "\n".join(out)


@contextmanager
def step(message: str, enabled: bool = True):
    """Announce a long step on stderr and report its duration (keeps stdout clean for --json)."""
    t0 = time.perf_counter()
    if enabled:
        print(f"… {message}", file=sys.stderr, flush=True)
    yield
    if enabled:
        print(f"  done in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)


def print_json(obj) -> None:
    json.dump(obj, sys.stdout, indent=2)
    sys.stdout.write("\n")
