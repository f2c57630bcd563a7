"""Exceptions raised by the identification back end for inputs a user gave (images, grids, datasets)."""

from __future__ import annotations

__all__ = ["IdentifyError"]


class IdentifyError(ValueError):
    """An input ``identify`` refuses, with a one-line message written for the user.

    The message names the file, field or value at fault and what was expected; the command line prints it
    as is (exit code 2). It subclasses ``ValueError`` so that callers catching ``ValueError`` keep working.
    """
