"""Exceptions and warnings of the FE importers.

Every refusal is a :class:`ModelImportError`: a one-line message naming the file, the field or value at fault
and what was expected. It subclasses :class:`rom.errors.ROMError` (itself a ``ValueError``), so the command
line prints it as is (exit code 2) and callers that catch ``ValueError`` keep working.
"""

from __future__ import annotations

from ..errors import ROMError

__all__ = ["ModelImportError", "MissingDependencyError", "GridError", "UnitsWarning"]


class ModelImportError(ROMError):
    """A model file (or the CSV beside it) that cannot be imported as it is: damaged, inconsistent, unsupported."""


class MissingDependencyError(ModelImportError):
    """An optional dependency needed for one format is not installed; the message says what to install."""


class GridError(ModelImportError):
    """An interface grid that cannot be built or does not conform (nodes missing, not a lattice, gap too big)."""


class UnitsWarning(UserWarning):
    """The imported model's mass does not look like a solid in the assumed unit system (wrong ``units``?)."""
