"""ema: experimental modal analysis front end (floor 1; imports neither rom, identify, lab nor bladetwin).

UFF I/O, FRF sets, pole estimation (LSCF, LSRF, local fitting), stabilization diagrams, pole selection,
mode shapes and residues (LSFD), MAC and mode pairing, campaign tables. Plots live in ``ema.plots``.
"""

from .campaign import (
    blade_deltas,
    disk_modes,
    joint_frequencies,
    nodal_diameter_purity,
    nodal_diameters,
    track_modes,
    write_table,
)
from .errors import EMAError, UFFError
from .fit import EMAResult, estimate_poles, fit, local_poles, mode_dominance
from .frf import FRFSet, Nodes, UnitSystem, convert_form, merge_frfsets
from .lscf import lscf
from .lsfd import dominance, fit_quality, lsfd, modal_model, refine_poles, synthesize
from .lsrf import lsrf
from .mac import ModePairing, automac, distinct_mac, mac, mac_paired, pair_by_frequency, pair_modes
from .modal import ModalModel
from .picks import Picks, fit_with_picks, load_picks, save_picks
from .poles import PoleSet
from .selection import PoleSelection, select_auto, select_near, select_picks
from .stabilization import StabilityCriteria, StabilizationDiagram, stabilize
from .uff import read_frfs, read_modes, read_nodes, read_uff, read_units, write_frfs, write_modes

__all__ = [
    "EMAError",
    "EMAResult",
    "FRFSet",
    "ModalModel",
    "ModePairing",
    "Nodes",
    "Picks",
    "PoleSelection",
    "PoleSet",
    "StabilityCriteria",
    "StabilizationDiagram",
    "UFFError",
    "UnitSystem",
    "automac",
    "blade_deltas",
    "convert_form",
    "disk_modes",
    "distinct_mac",
    "dominance",
    "estimate_poles",
    "fit",
    "fit_quality",
    "fit_with_picks",
    "joint_frequencies",
    "load_picks",
    "local_poles",
    "lscf",
    "lsfd",
    "lsrf",
    "mac",
    "mac_paired",
    "merge_frfsets",
    "modal_model",
    "mode_dominance",
    "nodal_diameter_purity",
    "nodal_diameters",
    "pair_by_frequency",
    "pair_modes",
    "read_frfs",
    "read_modes",
    "read_nodes",
    "read_uff",
    "read_units",
    "refine_poles",
    "save_picks",
    "select_auto",
    "select_near",
    "select_picks",
    "stabilize",
    "synthesize",
    "track_modes",
    "write_frfs",
    "write_modes",
    "write_table",
]
