"""The one channel for warnings meant for the user (issue 30): one line each on stderr, a list in ``summary.json``
and the report's "Warnings".

The libraries (``ema``, ``rom``, ``identify``) warn with :func:`warnings.warn`, as libraries should. ``bladetwin``
records them where they arise (:func:`recording`: a stage node, the campaign checks, the tables) so that they
reach ``summary.json`` whether a stage ran now or was found in the store, and the command line prints any other
warning as one line without Python's source line (:func:`install`).
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Iterable, Iterator

__all__ = ["one_line", "recording", "unique", "install", "emit"]

PREFIX = "bladetwin: warning: "


def one_line(message) -> str:
    """A warning's text on one line (its message, whitespace collapsed; no category or source line)."""
    return " ".join(str(message).split())


@contextlib.contextmanager
def recording() -> Iterator[list[str]]:
    """Record every user warning (:class:`UserWarning`) raised inside the block, as one-line texts in order.

    Every occurrence of a user warning is recorded: Python's once-per-location rule would hide a second
    film's warning from the same line of the reader. Other categories (numpy's ``RuntimeWarning``…) speak of
    code, not of inputs: they go to stderr, once per location.
    """
    texts: list[str] = []
    others: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            # other categories keep Python's once-per-location rule: a numeric loop's RuntimeWarning, recorded
            # every time, would fill the memory
            warnings.simplefilter("default")
            warnings.simplefilter("always", UserWarning)
            try:
                yield texts
            finally:
                for w in caught:
                    if issubclass(w.category, UserWarning):
                        texts.append(one_line(w.message))
                    else:
                        others.append(w)
    finally:
        # numpy's RuntimeWarning and the like speak of code, not of inputs: stderr only, and only once the
        # recorder is gone (inside it, showwarning is the recorder itself)
        for w in others:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def unique(texts: Iterable[str]) -> list[str]:
    """``texts`` without repeats, in first-seen order."""
    return list(dict.fromkeys(texts))


def emit(text: str) -> None:
    """Print one warning on stderr: ``bladetwin: warning: <text>``."""
    print(PREFIX + one_line(text), file=sys.stderr, flush=True)


def _format(message, category, filename, lineno, line=None) -> str:  # noqa: ARG001 - formatwarning's API
    return PREFIX + one_line(message) + "\n"


def install() -> None:
    """Print every warning not recorded elsewhere as one line (as :func:`emit`), for the command line's lifetime.

    It replaces the formatting, not ``showwarning``: a caller recording warnings (``catch_warnings(record=True)``,
    ``pytest.warns``) still gets them.
    """
    warnings.formatwarning = _format
