"""bladetwin: command line and batch pipeline (floor 3 of the house, docs/design.md §1)."""

__all__: list[str] = []
__version__ = "0.1.0"
