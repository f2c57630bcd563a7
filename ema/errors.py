"""Exceptions raised by the EMA front end."""

from __future__ import annotations

__all__ = ["EMAError", "UFFError"]


class EMAError(ValueError):
    """An input the EMA front end refuses, with a one-line message written for the user.

    The command line prints the message as is (exit code 2). It subclasses ``ValueError`` so that callers
    that already catch ``ValueError`` keep working.
    """


class UFFError(EMAError):
    """A UFF file that cannot be read as requested.

    The message is always one line and names the file, the data set index (0-based, in file order) and
    the offending field, so that a command line can print it as is.

    Parameters
    ----------
    path : str
        File name.
    reason : str
        What is wrong, e.g. ``"not an FRF (function type 9 = power spectral density)"``.
    dataset : int or None
        0-based index of the data set in the file, or ``None`` for file-level problems.
    field : str or None
        Name of the UFF field (pyuff key) at fault, or ``None``.
    """

    def __init__(self, path: str, reason: str, dataset: int | None = None, field: str | None = None):
        self.path = str(path)
        self.reason = " ".join(str(reason).split())
        self.dataset = dataset
        self.field = field
        where = self.path
        if dataset is not None:
            where += f", data set {dataset}"
        if field is not None:
            where += f", field {field!r}"
        super().__init__(f"{where}: {self.reason}")
