"""Stage nodes on the FE model: its reductions (CB disk, Rubin blade, cyclic all-slot disk) and the blade δ."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rom.contact import slot_flank_nodes
from rom.craig_bampton import CraigBamptonModel, reduce_disk
from rom.cyclic import CyclicDiskModel, reduce_disk_cyclic
from rom.errors import ROMError
from rom.mistuning import rom_deltas
from rom.rubin import RubinModel, reduce_blade

__all__ = ["CyclicBuild", "model_key", "mounted", "reduce_disk_cb", "reduce_blade_rubin", "reduce_disk_all_slots",
           "blade_deltas"]


@dataclass(frozen=True, eq=False)
class CyclicBuild:
    """The cyclic all-slot CB disk (:mod:`rom.cyclic`), or why it was refused (``model`` None); ``hardware_kg``
    is the blades' hardware it carries on every slot (:func:`mounted`), which a fallback solve must carry too."""

    model: CyclicDiskModel | None
    refused: str = ""
    hardware_kg: float = 0.0


def model_key(bd) -> str:
    """The FE model's identity for the store: every input of its reductions (hashes K and M, about 2 s)."""
    from rom import cache

    disk = cache.disk_key(bd)
    return cache.hash_inputs("fe-model", disk, cache.blade_key(bd), cache.cyclic_disk_key(bd, base_key=disk))


def mounted(bd, slots, hardware_kg: float):
    """``bd`` with ``hardware_kg`` kg per slot (the bolts that hold a blade, ``[masses] slot_hardware_kg``)
    spread over each listed slot's flank nodes of the disk (:meth:`rom.component.Component.with_node_masses`);
    ``slots`` None: every slot."""
    if not hardware_kg:
        return bd
    groups = [slot_flank_nodes(bd.disk, s) for s in (range(1, bd.n_slots + 1) if slots is None else slots)]
    return replace(bd, disk=bd.disk.with_node_masses(groups, float(hardware_kg)))


def reduce_disk_cb(bd, hardware_kg: float = 0.0) -> CraigBamptonModel:
    """The one-slot Craig–Bampton disk of the disk–one-blade ROMs (:func:`rom.craig_bampton.reduce_disk`), with the
    one mounted blade's hardware on its slot."""
    return reduce_disk(mounted(bd, (1,), hardware_kg), (1,))


def reduce_blade_rubin(bd) -> RubinModel:
    """The free blade reduced by Rubin's method (:func:`rom.rubin.reduce_blade`)."""
    return reduce_blade(bd)


def reduce_disk_all_slots(bd, hardware_kg: float = 0.0) -> CyclicBuild:
    """The cyclic all-slot CB disk of the full-assembly solves, every slot with its blade's hardware; a disk that
    is not cyclic gives its reason."""
    try:
        return CyclicBuild(reduce_disk_cyclic(mounted(bd, None, hardware_kg)), "", hardware_kg)
    except ROMError as exc:
        return CyclicBuild(None, str(exc), hardware_kg)


def blade_deltas(blades, blade: RubinModel) -> np.ndarray:
    """Each blade's δ (relative) on the ROM blade's modes from the measured deltas, shape (n_blades, n_modes)."""
    return rom_deltas(blades.frequencies_hz, blades.deltas_pct, blade.frequencies_hz)
