"""ema: experimental modal analysis front end (floor 1; imports neither rom, identify, lab nor bladetwin).

UFF I/O, FRF sets, pole estimation (LSCF, LSRF, local fitting), stabilization diagrams, pole selection,
mode shapes and residues (LSFD), MAC and mode pairing, mode complexity (MPC, MPD, MCF), campaign tables.
Plots live in ``ema.plots``.
"""

from .campaign import blade_deltas, disk_modes, joint_frequencies, nodal_diameters, write_table
from .errors import EMAError, UFFError
from .fit import EMAResult, fit
from .frf import FRFSet, Nodes, UnitSystem, merge_frfsets
from .lsfd import synthesize
from .mac import ModePairing, mac, pair_by_frequency, pair_modes
from .modal import ModalModel
from .mode_quality import ModeQuality, mode_quality
from .order import fit_auto_order
from .picks import Picks, fit_with_picks, load_picks, save_picks
from .settings import FitSettings
from .stabilization import StabilityCriteria
from .uff import read_coherence, read_frfs, read_modes, read_nodes, read_uff, read_units, write_frfs, write_modes

# What a user calls. The estimators' internals (lscf, lsrf, lsfd, stabilize, select_*, dominance, …) are
# importable from their own modules (ema.lscf, ema.stabilization, ema.selection, ema.lsfd, ema.mac).
__all__ = [
    "EMAError",
    "EMAResult",
    "FRFSet",
    "FitSettings",
    "ModalModel",
    "ModePairing",
    "ModeQuality",
    "Nodes",
    "Picks",
    "StabilityCriteria",
    "UFFError",
    "UnitSystem",
    "blade_deltas",
    "disk_modes",
    "fit",
    "fit_auto_order",
    "fit_with_picks",
    "joint_frequencies",
    "load_picks",
    "mac",
    "merge_frfsets",
    "mode_quality",
    "nodal_diameters",
    "pair_by_frequency",
    "pair_modes",
    "read_coherence",
    "read_frfs",
    "read_modes",
    "read_nodes",
    "read_uff",
    "read_units",
    "save_picks",
    "synthesize",
    "write_frfs",
    "write_modes",
    "write_table",
]
