"""Unit systems of imported FE models and their conversion to SI (m, kg, s; N, Pa).

A consistent unit system is fixed by its length, mass and time units; force is then mass·length/time².
Matrices convert as K [force/length] → N/m by ``mass / time²`` and M [mass] → kg by ``mass``; coordinates by
``length``. FE files do not say which system they use (ANSYS ``.full``, Matrix Market and OP4 store bare
numbers), so the caller names it and the importer records it in ``Component.meta["units"]``.

Because a wrong guess scales every frequency by √(factor) and goes unnoticed otherwise,
:func:`check_mass` compares the model's mass with the volume of its bounding box: a solid part of any
engineering material has an apparent density between :data:`DENSITY_RANGE` kg/m³ (e.g. steel 7850 kg/m³
filling 1–100 % of its box). Outside that range it issues a :class:`UnitsWarning` with the computed mass.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import ModelImportError, UnitsWarning

__all__ = ["UnitSystem", "UNIT_SYSTEMS", "unit_system", "check_mass", "DENSITY_RANGE"]

log = logging.getLogger(__name__)

#: Apparent density (mass / bounding-box volume, kg/m³) accepted without a warning. The lower bound allows a
#: light alloy filling 2 % of its box (a thin blade), the upper one a solid block of tungsten.
DENSITY_RANGE = (50.0, 25_000.0)

_INCH = 0.0254
_LBF = 4.4482216152605


@dataclass(frozen=True)
class UnitSystem:
    """A consistent unit system: SI value of one length, mass and time unit.

    Attributes
    ----------
    name : str
        Canonical name (``"SI"``, ``"mm-t-s"``, ...).
    length, mass, time : float
        Metres, kilograms and seconds per unit.
    """

    name: str
    length: float
    mass: float
    time: float

    @property
    def stiffness(self) -> float:
        """N/m per stiffness unit (force/length = mass/time²)."""
        return self.mass / self.time**2

    @property
    def is_si(self) -> bool:
        return self.length == 1.0 and self.mass == 1.0 and self.time == 1.0

    def describe(self) -> str:
        """One line for logs and JSON: the system and its conversion factors to SI."""
        return (f"{self.name} (coordinates ×{self.length:g} → m, K ×{self.stiffness:g} → N/m, "
                f"M ×{self.mass:g} → kg)")


#: Supported systems by canonical name. ANSYS /UNITS calls the first ones MKS, MMNS (mm, t, s: force N, stress
#: MPa), CGS and BIN (in, lbf·s²/in, s: force lbf, stress psi); mm-kg-ms (force kN, stress GPa) is common in
#: explicit codes.
UNIT_SYSTEMS: dict[str, UnitSystem] = {
    "SI": UnitSystem("SI", 1.0, 1.0, 1.0),
    "mm-t-s": UnitSystem("mm-t-s", 1e-3, 1e3, 1.0),
    "mm-kg-ms": UnitSystem("mm-kg-ms", 1e-3, 1.0, 1e-3),
    "cm-g-s": UnitSystem("cm-g-s", 1e-2, 1e-3, 1.0),
    "in-lbf-s": UnitSystem("in-lbf-s", _INCH, _LBF / _INCH, 1.0),
}

_ALIASES = {
    "si": "SI", "m-kg-s": "SI", "mks": "SI",
    "mm-t-s": "mm-t-s", "mmns": "mm-t-s", "mm-tonne-s": "mm-t-s", "n-mm-t": "mm-t-s",
    "mm-kg-ms": "mm-kg-ms",
    "cm-g-s": "cm-g-s", "cgs": "cm-g-s",
    "in-lbf-s": "in-lbf-s", "bin": "in-lbf-s",
}


def unit_system(name: str | UnitSystem) -> UnitSystem:
    """The :class:`UnitSystem` called ``name`` (case-insensitive; ANSYS aliases MKS, MMNS, CGS, BIN accepted)."""
    if isinstance(name, UnitSystem):
        return name
    key = _ALIASES.get(str(name).strip().lower())
    if key is None:
        raise ModelImportError(f"units must be one of {sorted(UNIT_SYSTEMS)} (or MKS, MMNS, CGS, BIN), got {name!r}")
    return UNIT_SYSTEMS[key]


def check_mass(mass_kg: float, coords_m: np.ndarray, where: str, units: UnitSystem) -> float | None:
    """Warn when the mass is implausible for a solid filling part of its bounding box.

    Parameters
    ----------
    mass_kg : float
        Total mass after conversion to SI (kg).
    coords_m : ndarray, shape (n_nodes, 3)
        Node coordinates after conversion (m); NaN when unknown (then nothing is checked).
    where : str
        The file, for the message.
    units : UnitSystem
        The system that was assumed, for the message.

    Returns
    -------
    float or None
        The apparent density (kg/m³), or ``None`` when it cannot be computed (no coordinates, flat model).
    """
    X = np.asarray(coords_m, dtype=np.float64)
    if X.size == 0 or not np.isfinite(X).all():
        log.info("%s: no node coordinates, the mass/units plausibility check is skipped", where)
        return None
    ext = X.max(axis=0) - X.min(axis=0)
    volume = float(np.prod(ext))
    if not (volume > 0 and math.isfinite(mass_kg)):
        return None
    rho = mass_kg / volume
    lo, hi = DENSITY_RANGE
    if not lo <= rho <= hi:
        box = " × ".join(f"{e:.3g}" for e in ext)
        warnings.warn(
            f"{where}: total mass {mass_kg:.4g} kg in a {box} m bounding box (apparent density {rho:.3g} kg/m³, "
            f"expected {lo:g}–{hi:g} for a solid part); the units assumed were {units.name}: are they right?",
            UnitsWarning, stacklevel=4,
        )
    return rho
