"""rom: finite-element substructures and reduced-order models of bladed disks (floor 1; never imports ema).

Public API (see each module for details):

- :mod:`rom.component`: :class:`Component` (sparse K, M with labelled DOFs and node sets)
- :mod:`rom.academic`: the academic bladed-disk twin (:class:`AcademicParams`, :func:`build_bladed_disk`)
- :mod:`rom.solver`: shift-invert Lanczos modal solver, nodal-diameter labels
- :mod:`rom.contact`: :class:`ContactPattern`
- :mod:`rom.fe_assembly`: the FE reference assembly
- :mod:`rom.calibration`: Young's-modulus calibration
"""

from .academic import AcademicParams, BladedDisk, Material, build_bladed_disk
from .calibration import Calibration, calibrate_bladed_disk, calibrate_modulus
from .component import Component
from .contact import ContactPattern
from .fe_assembly import AssemblyModes, FEAssembly, assemble_fe, solve_fe
from .solver import ModalSolution, nodal_diameters, solve_modes

__all__ = [
    "AcademicParams", "BladedDisk", "Material", "build_bladed_disk",
    "Calibration", "calibrate_bladed_disk", "calibrate_modulus",
    "Component", "ContactPattern",
    "AssemblyModes", "FEAssembly", "assemble_fe", "solve_fe",
    "ModalSolution", "nodal_diameters", "solve_modes",
]
