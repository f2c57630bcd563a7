"""The campaign's DOF numbering (docs/campaign.md): how a ROM's measurement labels map to UFF nodes.

A disk point of sector ``s`` is UFF node ``s``; point ``p`` of the blade in slot ``s`` is node
``BLADE_NODE_STRIDE · s + p``. Virtual campaigns are written this way, and a lab's files are read this way, so
a ROM's modes can be compared with an EMA's on their common DOFs. It lives in ``ema`` (floor 1) because the
rig (``lab``), the identification and the pipeline all need it, and ``ema`` may import none of them: the ROM's
modes are taken duck-typed.
"""

from __future__ import annotations

import numpy as np

from .modal import ModalModel

__all__ = ["BLADE_NODE_STRIDE", "dof_label", "rom_modal_model"]

#: Blade point ``p`` of slot ``s`` is UFF node ``BLADE_NODE_STRIDE * s + p``.
BLADE_NODE_STRIDE = 1000


def dof_label(meas_label: tuple) -> tuple[int, int]:
    """UFF ``(node, direction)`` of a ROM measurement label ``("disk", sector, 1, d)`` / ``("blade", s, p, d)``."""
    kind, index, point, direction = meas_label
    if kind == "disk":
        return int(index), int(direction)
    if kind == "blade":
        return BLADE_NODE_STRIDE * int(index) + int(point), int(direction)
    raise ValueError(f"unknown measurement label kind {kind!r}")


def rom_modal_model(modes) -> ModalModel:
    """ROM modes as an undamped ``ema.ModalModel`` on the campaign's UFF DOF labels (real shapes as complex).

    ``modes`` is anything with ``frequencies_hz`` (n,), ``meas_shapes`` (n_meas, n) and ``meas_labels``
    (``rom.AssemblyModes``): the form a ROM takes to be compared with an EMA.
    """
    f = np.asarray(modes.frequencies_hz, np.float64)
    dofs = tuple(dof_label(tuple(lab)) for lab in modes.meas_labels)
    return ModalModel(f, np.zeros(f.size), np.asarray(modes.meas_shapes).astype(complex), dofs)
