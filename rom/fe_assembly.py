"""FE reference assembly: disk plus blades, tied node-to-node on contacting grid nodes (paper Eqs. 21–22).

This is the full finite-element model that the reduced-order models are validated against. Blade DOFs
stay in each blade's local frame (x = out of plane, y = span, z = chord); a contacting blade node is
eliminated through ``u_blade = Rᵀ u_disk`` with ``R`` the slot rotation, so ``K = Zᵀ blkdiag(K_d, K_b, …) Z``.
Detached nodes are not tied.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .academic import BladedDisk
from .contact import FLANKS, ContactPattern
from .solver import solve_modes

__all__ = ["MeasLabel", "FEAssembly", "AssemblyModes", "assemble_fe", "solve_fe"]

#: Measurement DOF label: (component "disk" | "blade", slot/sector 1..N, point 1..3, direction 1..3 in the
#: component's own frame: disk z = 3, blade local x = 1).
MeasLabel = tuple[str, int, int, int]


@dataclass(frozen=True, eq=False)
class FEAssembly:
    """Assembled FE model.

    Attributes
    ----------
    K, M : csr_matrix, shape (n, n)
        Reduced (tied) stiffness and mass.
    Z : csr_matrix, shape (n_unreduced, n)
        Maps reduced DOFs to the stacked unreduced vector [disk, blade of slots[0], blade of slots[1], …].
    meas_rows : ndarray of int, shape (n_meas,)
        Rows of the unreduced vector that are measurement DOFs.
    meas_labels : list of MeasLabel
    slots : tuple of int
    """

    K: sp.csr_matrix
    M: sp.csr_matrix
    Z: sp.csr_matrix
    meas_rows: np.ndarray
    meas_labels: list
    slots: tuple


@dataclass(frozen=True, eq=False)
class AssemblyModes:
    """Modes of an assembly at its measurement DOFs: the one mode-set type of every assembly solve.

    The ROM's solves fill the first three fields; the virtual rig's exact (truth) solve also fills the
    last two.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_modes,)
        Elastic natural frequencies (Hz), ascending.
    meas_shapes : ndarray, shape (n_meas, n_modes)
        Mass-normalised mode shapes at the measurement DOFs (m/√kg).
    meas_labels : list of MeasLabel
    rigid_shapes : ndarray, shape (n_meas, n_rigid), optional
        Mass-normalised rigid-body modes at the measurement DOFs (they give the FRFs' mass line).
    blade_energy : ndarray, shape (n_modes,), optional
        Share of each mode's kinetic energy in the blades (1 for a blade alone): tells blade-dominated
        modes (the blade-mode families) from disk-dominated ones.
    """

    frequencies_hz: np.ndarray
    meas_shapes: np.ndarray
    meas_labels: list
    rigid_shapes: np.ndarray | None = None
    blade_energy: np.ndarray | None = None

    def select(self, kind: str) -> tuple[np.ndarray, list]:
        """Rows of ``meas_shapes`` and labels of one kind (``"blade"`` or ``"disk"``)."""
        rows = [k for k, lab in enumerate(self.meas_labels) if lab[0] == kind]
        return self.meas_shapes[rows], [self.meas_labels[k] for k in rows]


def assemble_fe(bd: BladedDisk, patterns: Mapping[int, ContactPattern]) -> FEAssembly:
    """Tie blades into the disk.

    Parameters
    ----------
    bd : BladedDisk
    patterns : mapping slot (1..N) → ContactPattern
        One entry per populated slot: ``{s: p}`` gives the disk–one-blade model of slot s, all slots give
        the full bladed disk.
    """
    if not patterns:
        raise ValueError("patterns must name at least one slot")
    slots = tuple(sorted(patterns))
    nd, nb = bd.disk.n_dof, bd.blade.n_dof
    rows, cols, vals = [np.arange(nd)], [np.arange(nd)], [np.ones(nd)]
    next_col = nd
    meas_rows = list(3 * bd.disk.node_set("meas") + bd.disk.meta["meas_direction"] - 1)
    meas_labels: list = [("disk", s + 1, 1, 3) for s in range(bd.n_slots)]
    for k, s in enumerate(slots):
        bd.check_slot(s)
        pat = patterns[s]
        pat.check_shape(bd.params.grid)
        off = nd + k * nb
        Rt = bd.slot_rotation(s).T
        tied_blade, tied_disk = [], []
        for f in FLANKS:
            mask = pat.flank(f)
            tied_blade.append(bd.blade.node_set(f)[mask])
            tied_disk.append(bd.disk.node_set(f"slot{s}_{f}")[mask])
        tb, td = np.concatenate(tied_blade), np.concatenate(tied_disk)
        # Tied blade DOFs: u_b(node, :) = Rᵀ u_d(node', :)
        r = off + 3 * tb[:, None, None] + np.arange(3)[None, :, None]
        c = 3 * td[:, None, None] + np.arange(3)[None, None, :]
        rows.append(np.broadcast_to(r, (tb.size, 3, 3)).ravel())
        cols.append(np.broadcast_to(c, (tb.size, 3, 3)).ravel())
        vals.append(np.broadcast_to(Rt[None], (tb.size, 3, 3)).ravel())
        free = np.setdiff1d(np.arange(nb), (3 * tb[:, None] + np.arange(3)).ravel())
        rows.append(off + free)
        cols.append(next_col + np.arange(free.size))
        vals.append(np.ones(free.size))
        next_col += free.size
        meas = bd.blade.node_set("meas")
        meas_rows += list(off + 3 * meas + bd.blade.meta["meas_direction"] - 1)
        meas_labels += [("blade", s, p + 1, int(bd.blade.meta["meas_direction"])) for p in range(meas.size)]
    n_un = nd + len(slots) * nb
    Z = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n_un, next_col)
    )
    Z.eliminate_zeros()
    Kfull = sp.block_diag([bd.disk.K] + [bd.blade.K] * len(slots), format="csr")
    Mfull = sp.block_diag([bd.disk.M] + [bd.blade.M] * len(slots), format="csr")
    K = (Z.T @ Kfull @ Z).tocsr()
    M = (Z.T @ Mfull @ Z).tocsr()
    return FEAssembly(K, M, Z, np.asarray(meas_rows), meas_labels, slots)


def solve_fe(asm: FEAssembly, n_modes: int, backend: str = "auto") -> AssemblyModes:
    """Lowest ``n_modes`` elastic modes of an FE assembly, at its measurement DOFs."""
    sol = solve_modes(asm.K, asm.M, n_modes, backend=backend)
    shapes = (asm.Z[asm.meas_rows] @ sol.shapes)
    return AssemblyModes(sol.frequencies_hz, np.asarray(shapes), list(asm.meas_labels))
