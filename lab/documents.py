"""The documents a virtual campaign writes besides its files: the weighed masses of the manifest and the truth's
plain values (what :mod:`lab.campaign` puts into ``campaign.toml`` and ``truth/truth.json``)."""

from __future__ import annotations

import numpy as np

from rom.calibration import component_mass

__all__ = ["weighed", "specimen_truth", "blade_deltas_pct", "jsonable"]


def weighed(twin) -> dict:
    """What a lab's balance says (manifest ``[masses]``): the disk to 0.1 g, each blade to 1 mg, and the bolts
    that hold one blade (``slot_hardware_kg``, where the twin has bolts) to 1 mg (kg)."""
    out = {"disk_kg": round(component_mass(twin.truth_disk), 4),
           "blade_kg": [round(component_mass(b), 6) for b in twin.blades]}
    hardware = twin.params.bolt_mass_kg * twin.params.bolts_per_slot
    if hardware > 0:
        out["slot_hardware_kg"] = round(hardware, 6)
    return out


def specimen_truth(twin) -> dict:
    """The specimen's own effects for ``truth.json``: material offsets, sector moduli, test-day factors."""
    return {"material_offsets": dict(twin.materials), "day_factors": dict(twin.day_factors),
            "disk_sector_moduli": None if twin.sector_moduli is None else twin.sector_moduli.tolist(),
            "truth_mesh_level": twin.bd.params.level}


def blade_deltas_pct(freqs: list[list[float]]) -> list[list[float]]:
    """Paper Eq. 37 on the exact frequencies: (ω²_b − mean_b ω²) / mean_b ω² · 100, blade × mode."""
    n = min(len(f) for f in freqs)
    lam = np.array([f[:n] for f in freqs]) ** 2
    return (100 * (lam - lam.mean(axis=0)) / lam.mean(axis=0)).tolist()


def jsonable(obj) -> dict:
    """A dataclass or dict with numpy scalars and tuples made plain JSON/TOML values."""
    from dataclasses import asdict, is_dataclass

    d = asdict(obj) if is_dataclass(obj) else dict(obj)

    def plain(x):
        if isinstance(x, dict):
            return {k: plain(v) for k, v in x.items() if v is not None}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        if isinstance(x, np.generic):
            return x.item()
        return x

    return plain(d)
