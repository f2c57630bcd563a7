"""rom: finite-element substructures and reduced-order models of bladed disks (floor 1; never imports ema).

Public API (see each module for details):

- :mod:`rom.component`: :class:`Component` (sparse K, M with labelled DOFs and node sets)
- :mod:`rom.academic`: the academic bladed-disk twin (:class:`AcademicParams`, :func:`build_bladed_disk`)
- :mod:`rom.solver`: shift-invert Lanczos modal solver, nodal-diameter labels
- :mod:`rom.contact`: :class:`ContactPattern`
- :mod:`rom.fe_assembly`: the FE reference assembly
- :mod:`rom.calibration`: Young's-modulus calibration
- :mod:`rom.craig_bampton`, :mod:`rom.rubin`: Craig–Bampton disk and Rubin blade reductions (Eqs. 2–17)
- :mod:`rom.rom_assembly`: disk–one-blade and full bladed-disk ROMs with mistuning and contact (Eqs. 18–22)
- :mod:`rom.cyclic`: the cyclic all-slot CB disk (built once) and the full bladed-disk solve on it in seconds
- :mod:`rom.modal`, :mod:`rom.validation`, :mod:`rom.cache`, :mod:`rom.pattern_io`: dense eigen-solver, ROM-vs-FE
  checks (MAC-paired), the reduced-model cache, contact-pattern files
- :mod:`rom.errors`: :class:`ROMError`, the one-line errors written for users
"""

from .academic import AcademicParams, BladedDisk, Material, build_bladed_disk
from .calibration import Calibration, calibrate_bladed_disk, calibrate_modulus
from .component import Component
from .contact import ContactPattern
from .craig_bampton import CraigBamptonModel, reduce_disk
from .cyclic import CyclicDiskModel, reduce_disk_cyclic, solve_full_cyclic
from .errors import ROMError
from .fe_assembly import AssemblyModes, FEAssembly, assemble_fe, solve_fe
from .forced import AmplificationFactor, BladeModes, ForcedResponse, amplification_factors, forced_response
from .rom_assembly import ReducedAssembly, assemble_d1b, assemble_full, solve_d1b, solve_full
from .rubin import RubinModel, reduce_blade
from .solver import ModalSolution, nodal_diameters, solve_modes

__all__ = [
    "AcademicParams", "BladedDisk", "Material", "build_bladed_disk",
    "Calibration", "calibrate_bladed_disk", "calibrate_modulus",
    "Component", "ContactPattern", "ROMError",
    "AssemblyModes", "FEAssembly", "assemble_fe", "solve_fe",
    "ModalSolution", "nodal_diameters", "solve_modes",
    # The reductors craig_bampton() and rubin() stay in their modules (same names as the modules).
    "CraigBamptonModel", "reduce_disk", "RubinModel", "reduce_blade",
    "ReducedAssembly", "assemble_d1b", "assemble_full", "solve_d1b", "solve_full",
    "CyclicDiskModel", "reduce_disk_cyclic", "solve_full_cyclic",
    "AmplificationFactor", "BladeModes", "ForcedResponse", "amplification_factors", "forced_response",
]
