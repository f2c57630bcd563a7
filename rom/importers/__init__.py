"""FE importers: a lab's own disk and blade models as :class:`rom.component.Component` objects (issue 13).

Formats (:mod:`~rom.importers.readers`): ANSYS ``.full`` (+ ``.cdb``) through the optional
``ansys-mapdl-reader``, Matrix Market pairs, Nastran OP4 (in-house reader and writer, :mod:`~rom.importers.op4`
and :mod:`~rom.importers.op4_writer`), the last two with CSV side files for the DOF map, coordinates and node
sets (:mod:`~rom.importers.csvio`). Units are converted to SI (:mod:`~rom.importers.units`), constrained DOFs
kept as decoupled rows (:mod:`~rom.importers.build`). Interface grids come from node sets and coordinates or
from a CSV (:mod:`~rom.importers.grids`); :mod:`~rom.importers.model` turns disk + blade into a bladed disk the
ROM back end accepts, from Python or from a ``[model]`` TOML table; :mod:`~rom.importers.export` writes a model
in the importable formats. The user-facing guide is ``docs/importers.md``.
"""

from .errors import GridError, MissingDependencyError, ModelImportError, UnitsWarning
from .export import EXPORT_FORMATS, ExportedModel, export_bladed_disk
from .grids import (
    FlankAxes,
    InterfaceGrids,
    check_conformity,
    grid_from_points,
    grids_from_ids,
    grids_from_node_sets,
    principal_axes,
)
from .model import ImportedBladedDisk, ImportedParams, bladed_disk_from_components, load_bladed_disk, read_model_toml
from .op4 import Op4Matrix, read_op4
from .op4_writer import write_op4
from .placement import BladePlacement, axis_rotation
from .readers import FORMATS, guess_format, import_component, read_matrix_market_component, read_op4_component
from .units import UNIT_SYSTEMS, UnitSystem, unit_system

__all__ = [
    "ModelImportError", "MissingDependencyError", "GridError", "UnitsWarning",
    "FORMATS", "guess_format", "import_component", "read_matrix_market_component", "read_op4_component",
    "read_op4", "write_op4", "Op4Matrix",
    "UnitSystem", "UNIT_SYSTEMS", "unit_system",
    "BladePlacement", "axis_rotation",
    "FlankAxes", "InterfaceGrids", "principal_axes", "grid_from_points", "grids_from_node_sets", "grids_from_ids",
    "check_conformity",
    "ImportedParams", "ImportedBladedDisk", "bladed_disk_from_components", "load_bladed_disk", "read_model_toml",
    "EXPORT_FORMATS", "ExportedModel", "export_bladed_disk",
]
