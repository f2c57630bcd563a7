"""Reduced bladed-disk assemblies (paper §2.3.2–2.4, Eqs. 20–22): disk–one-blade and full bladed disk.

Contact (Eq. 20): the boundary DOFs of each joint split into contacting (c) and detached (d) node triplets
by a :class:`~rom.contact.ContactPattern`. Compatibility (Eq. 21) ties each contacting blade-root DOF to
the disk-slot DOF of the same grid node (node-to-node, all three directions); the Boolean assembly
(Eq. 22) is done by index scatter. Two blade formulations:

``"paper"``
    The paper's: the blade super-element keeps every root DOF; detached DOFs stay as free coordinates.
``"exact"``
    Rubin's force-free condition (design §5): detached DOFs carry no interface force, so their residual
    attachment modes are dropped exactly and Eq. 13 uses the contacting sub-block of the boundary residual
    flexibility. Smaller and better conditioned. See docs/rom.md for the measured difference and the default.

Assemblies:

* :func:`assemble_d1b` — Craig–Bampton disk (one slot) + one Rubin blade, dense (Eq. 22).
* :func:`assemble_full` — all slots populated, each blade with its δ (Eq. 19) and its pattern.
  ``method="hybrid"`` (default, scalable) keeps the disk as its sparse FE model and attaches the Rubin
  blades' dense super-elements to the disk's slot DOFs; ``method="cb"`` is the paper's dense CB+Rubin
  assembly (a CB disk reduced on all slots; only for small models: the boundary block alone is
  (N · n_i)² doubles).

Results come as :class:`rom.fe_assembly.AssemblyModes`, with the FE reference's measurement labels
(``("disk", sector, 1, 3)`` then ``("blade", slot, point, 1)``), so ROM and FE compare directly by MAC.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .academic import BladedDisk, check_slot
from .contact import ContactPattern, slot_flank_nodes
from .craig_bampton import CraigBamptonModel
from .errors import ROMError
from .fe_assembly import AssemblyModes
from .mistuning import as_delta
from .modal import dense_modes, single_thread_blas
from .rubin import RubinModel
from .solver import solve_modes

__all__ = [
    "FORMULATIONS",
    "DEFAULT_FORMULATION",
    "ReducedAssembly",
    "assemble_d1b",
    "d1b_slot",
    "assemble_full",
    "solve_assembly",
    "solve_d1b",
    "solve_full",
]

log = logging.getLogger(__name__)

FORMULATIONS = ("paper", "exact")
#: Default contact formulation (docs/rom.md: same accuracy, smaller and faster models).
DEFAULT_FORMULATION = "exact"


@dataclass(frozen=True, eq=False)
class ReducedAssembly:
    """An assembled reduced model (Eq. 22).

    Attributes
    ----------
    K, M : ndarray or scipy.sparse.csr_matrix, shape (n, n)
        Dense for CB+Rubin assemblies, sparse for the hybrid full assembly.
    out : ndarray or csr_matrix, shape (n_meas, n)
        Maps assembled coordinates to the measurement DOFs.
    meas_labels : list of (kind, slot/sector, point, direction)
    meta : dict
    """

    K: np.ndarray | sp.csr_matrix
    M: np.ndarray | sp.csr_matrix
    out: np.ndarray | sp.csr_matrix
    meas_labels: list
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(self.K.shape[0])


# ----------------------------------------------------------------------------------------- helpers
def _check_formulation(formulation: str) -> None:
    if formulation not in FORMULATIONS:
        raise ValueError(f"formulation must be one of {FORMULATIONS}, got {formulation!r}")


def grid_shape(blade: RubinModel) -> tuple[int, int]:
    """The contact grid (rows, cols) the Rubin blade was reduced for."""
    g = blade.meta.get("grid")
    if g is None:
        raise ValueError("the blade model carries no contact-grid shape (meta['grid']); use reduce_blade()")
    return int(g[0]), int(g[1])


def check_pattern(pattern: ContactPattern, grid: tuple[int, int], slot: int) -> ContactPattern:
    """``pattern`` if it is a ContactPattern on ``grid``; else a one-line error naming ``slot``."""
    if not isinstance(pattern, ContactPattern):
        raise ValueError(f"pattern of slot {slot} must be a ContactPattern, got {type(pattern).__name__}")
    if pattern.shape != grid:
        raise ValueError(f"contact pattern of slot {slot} has grid shape {pattern.shape}, the model expects {grid}")
    return pattern


def _contact_dofs(pattern: ContactPattern) -> np.ndarray:
    """Boolean mask over the root-interface DOFs (L grid, R grid, row-major, 3 DOFs per node)."""
    return np.repeat(np.concatenate([pattern.L.ravel(), pattern.R.ravel()]), 3)


def blade_part(blade: RubinModel, pattern: ContactPattern, delta, formulation: str):
    """Super-element of one blade for a pattern (Eqs. 15–20) and the roles of its coordinates.

    Returns
    -------
    se : Superelement
    iface_pos : ndarray of int
        For each kept boundary coordinate, its position in the root-interface DOF list, or −1 (accessory).
    contact : ndarray of bool
        Whether each kept boundary coordinate is tied (contacting interface DOF).
    """
    c = _contact_dofs(pattern)
    if c.size != blade.n_interface:
        raise ValueError(f"pattern has {c.size // 6} grid nodes per flank, the blade root has {blade.n_interface // 6}")
    if formulation == "paper":
        keep = np.ones(blade.n_b, bool)
    else:
        keep = np.concatenate([c, np.ones(blade.n_b - blade.n_interface, bool)])
    model = blade if delta is None else blade.with_delta(delta)
    se = model.superelement(keep)
    S = se.boundary_index
    iface_pos = np.where(S < blade.n_interface, S, -1)
    contact = (iface_pos >= 0) & c[np.clip(iface_pos, 0, None)]
    return se, iface_pos, contact


def _rotate_triplets(A: np.ndarray, rows: np.ndarray, R: np.ndarray) -> np.ndarray:
    """B = Qᵀ A Q where Q = Rᵀ on each consecutive row triplet listed in ``rows`` (identity elsewhere).

    Used to express a blade's local root coordinates in the global frame (x_loc = Rᵀ x_glob).
    """
    B = A.copy()
    idx = rows.reshape(-1, 3)
    # rows: B[t] = R @ A[t] for each triplet t
    B[idx] = np.einsum("ij,tjk->tik", R, B[idx])
    B[:, idx] = np.einsum("ij,ktj->kti", R, B[:, idx])
    return B


def measurement_labels(n_sectors: int, slots, n_meas: int, meas_dir: int = 1) -> list:
    """Measurement labels of an assembly: one disk point per sector, then each slot's blade points."""
    labels: list = [("disk", k + 1, 1, 3) for k in range(n_sectors)]
    for s in slots:
        labels += [("blade", int(s), p + 1, meas_dir) for p in range(n_meas)]
    return labels


def _cb_assembly(
    disk: CraigBamptonModel,
    blade: RubinModel,
    patterns: Mapping[int, ContactPattern],
    deltas: Mapping[int, object],
    formulation: str,
    slot_block: Mapping[int, int],
    sector_shift: int,
) -> ReducedAssembly:
    """Dense CB disk + Rubin blades (Eq. 22); ``slot_block[s]`` = index of the disk boundary block of slot s."""
    n_sectors = int(disk.meta.get("n_sectors", disk.output_basis.shape[0]))
    grid = grid_shape(blade)
    n_i = blade.n_interface
    if disk.n_b != n_i * len(disk.meta.get("slots", [None])):
        raise ValueError(f"disk boundary ({disk.n_b} DOFs) does not match the blade root ({n_i} DOFs per slot)")
    parts = []
    n = disk.n
    n_acc = blade.n_b - n_i
    blade_out = []
    for s in sorted(patterns):
        pat = check_pattern(patterns[s], grid, s)
        se, iface_pos, contact = blade_part(blade, pat, deltas.get(s), formulation)
        idx = np.empty(se.n, np.int64)
        nm = se.n_modal
        idx[:nm] = n + np.arange(nm)
        n += nm
        bidx = idx[nm:]
        bidx[contact] = disk.n_k + slot_block[s] * n_i + iface_pos[contact]
        n_new = int((~contact).sum())
        bidx[~contact] = n + np.arange(n_new)
        n += n_new
        parts.append((se.K, se.M, idx))
        acc = bidx[iface_pos < 0]
        if acc.size != n_acc:
            raise AssertionError("accessory DOFs lost in the super-element")  # pragma: no cover
        blade_out.append(acc)
    K = disk.K(out=np.zeros((n, n)))
    M = disk.M(out=np.zeros((n, n)))
    Kf, Mf = K.reshape(-1), M.reshape(-1)  # views: a flat fancy add is ~2x faster than one through np.ix_
    for Kp, Mp, idx in parts:
        flat = (idx[:, None] * n + idx).ravel()
        Kf[flat] += Kp.reshape(-1)
        Mf[flat] += Mp.reshape(-1)
    n_meas = n_sectors + n_acc * len(parts)
    out = np.zeros((n_meas, n))
    rows = (np.arange(n_sectors) - sector_shift) % n_sectors
    out[:n_sectors, : disk.n] = disk.output_basis[rows]
    for k, acc in enumerate(blade_out):
        out[n_sectors + k * n_acc + np.arange(n_acc), acc] = 1.0
    labels = measurement_labels(n_sectors, sorted(patterns), n_acc)
    return ReducedAssembly(K, M, out, labels, {"formulation": formulation, "slots": sorted(patterns)})


# ----------------------------------------------------------------------------------------- public
def assemble_d1b(
    disk: CraigBamptonModel,
    blade: RubinModel,
    pattern: ContactPattern,
    slot: int | None = None,
    *,
    delta=None,
    formulation: str = DEFAULT_FORMULATION,
) -> ReducedAssembly:
    """Disk–one-blade ROM (Eqs. 20–22): a CB disk reduced on one slot plus one Rubin blade.

    Parameters
    ----------
    disk : CraigBamptonModel
        From :func:`rom.craig_bampton.reduce_disk` with one slot. For a cyclic disk (``meta["cyclic"]``)
        the model of one slot serves every slot: the slot's interface is identical in the slot frame and
        only the disk's measurement sectors rotate.
    blade : RubinModel
        From :func:`rom.rubin.reduce_blade`.
    pattern : ContactPattern
    slot : int, optional
        Slot 1..N (default: the disk model's own slot).
    delta : float or array_like of shape (k ≤ m,), optional
        Blade mistuning δ (Eq. 19).
    formulation : {"exact", "paper"}
    """
    _check_formulation(formulation)
    ref, slot, _ = d1b_slot(disk, slot)
    if delta is not None:
        delta = as_delta(delta, blade.m)
    asm = _cb_assembly(disk, blade, {slot: pattern}, {slot: delta}, formulation, {slot: 0}, slot - ref)
    return ReducedAssembly(asm.K, asm.M, asm.out, asm.meas_labels, {**asm.meta, "assembly": "d1b"})


def d1b_slot(disk: CraigBamptonModel, slot: int | None) -> tuple[int, int, int]:
    """(the disk model's own slot, the slot asked for, the number of sectors) of a disk–one-blade model.

    Raises
    ------
    ValueError
        If the disk is not reduced on exactly one slot, or ``slot`` is another slot of a disk not marked cyclic.
    """
    slots = list(disk.meta.get("slots", []))
    n_sectors = int(disk.meta.get("n_sectors", disk.output_basis.shape[0]))
    if len(slots) != 1:
        raise ValueError(f"a disk–one-blade model needs a disk reduced on exactly one slot, got slots {slots}")
    ref = int(slots[0])
    slot = ref if slot is None else check_slot(slot, n_sectors)
    if slot != ref and not disk.meta.get("cyclic", False):
        raise ValueError(f"the disk model was reduced for slot {ref} and is not marked cyclic; cannot use slot {slot}")
    return ref, slot, n_sectors


def assemble_full(
    disk: BladedDisk | CraigBamptonModel,
    blade: RubinModel,
    patterns: Mapping[int, ContactPattern] | ContactPattern,
    deltas=None,
    *,
    formulation: str = DEFAULT_FORMULATION,
) -> ReducedAssembly:
    """Full bladed disk (Eqs. 19–22) with one δ vector per blade and one pattern per slot.

    Parameters
    ----------
    disk : BladedDisk or CraigBamptonModel
        A ``BladedDisk`` gives the scalable sparse hybrid (disk kept as sparse FE, Rubin blades attached
        to its slot DOFs); a ``CraigBamptonModel`` reduced on *all* slots gives the paper's dense CB
        assembly (small models only).
    blade : RubinModel
    patterns : mapping slot → ContactPattern, or one ContactPattern for every slot
        Every slot 1..N must be populated.
    deltas : None, array_like of shape (N, k), or sequence of N per-blade δ (each as for ``with_delta``)
    formulation : {"exact", "paper"}
    """
    _check_formulation(formulation)
    if isinstance(disk, BladedDisk):
        n_slots = disk.n_slots
    elif isinstance(disk, CraigBamptonModel):
        n_slots = int(disk.meta.get("n_sectors", 0))
    else:
        raise ValueError(f"disk must be a BladedDisk or a CraigBamptonModel, got {type(disk).__name__}")
    pats = every_slot(patterns, n_slots)
    dl = slot_deltas(deltas, n_slots, blade.m)
    if isinstance(disk, CraigBamptonModel):
        slots = [int(s) for s in disk.meta.get("slots", [])]
        if sorted(slots) != list(range(1, n_slots + 1)):
            raise ValueError(f"a CB disk for the full assembly must be reduced on all slots 1..{n_slots}, got {slots}")
        block = {s: k for k, s in enumerate(slots)}
        asm = _cb_assembly(disk, blade, pats, dl, formulation, block, 0)
        return ReducedAssembly(asm.K, asm.M, asm.out, asm.meas_labels, {**asm.meta, "assembly": "full", "method": "cb"})
    return _hybrid_assembly(disk, blade, pats, dl, formulation)


def every_slot(patterns: Mapping[int, ContactPattern] | ContactPattern, n_slots: int) -> dict[int, ContactPattern]:
    """Slot → pattern for every slot 1..N (one pattern given: the same in every slot); other slots refused."""
    if isinstance(patterns, ContactPattern):
        return {s: patterns for s in range(1, n_slots + 1)}
    pats = dict(patterns)
    for s in pats:
        check_slot(s, n_slots)
    missing = sorted(set(range(1, n_slots + 1)) - set(pats))
    if missing:
        raise ROMError(f"patterns must give every slot 1..{n_slots}; missing {missing}")
    return pats


def slot_deltas(deltas, n_slots: int, m: int) -> dict:
    """Slot → the blade's δ (relative, first ``m`` modes), from one row per blade; None gives {}."""
    if deltas is None:
        return {}
    if isinstance(deltas, Mapping):
        raise ValueError("deltas must be an array (N, k) or a sequence with one entry per blade, not a mapping")
    rows = list(np.atleast_2d(deltas)) if isinstance(deltas, np.ndarray) else list(deltas)
    if len(rows) != n_slots:
        raise ValueError(f"deltas must have one row per blade ({n_slots}), got {len(rows)}")
    return {s + 1: as_delta(rows[s], m) for s in range(n_slots)}


def _hybrid_assembly(
    bd: BladedDisk, blade: RubinModel, patterns: Mapping[int, ContactPattern], deltas: Mapping[int, object],
    formulation: str,
) -> ReducedAssembly:
    """Sparse hybrid: disk FE (global frame) + Rubin super-elements on its slot DOFs (design §5)."""
    grid = grid_shape(blade)
    if tuple(bd.params.grid) != grid:
        raise ValueError(f"blade model grid {grid} differs from the bladed disk's {tuple(bd.params.grid)}")
    nd = bd.disk.n_dof
    n = nd
    n_acc = blade.n_b - blade.n_interface
    rows_k, cols_k, vk, vm = [], [], [], []
    blade_out = []
    for s in sorted(patterns):
        pat = check_pattern(patterns[s], grid, s)
        se, iface_pos, contact = blade_part(blade, pat, deltas.get(s), formulation)
        nm = se.n_modal
        # Root coordinates to the global frame: x_loc = R_sᵀ x_glob on every kept interface triplet.
        iface_rows = nm + np.flatnonzero(iface_pos >= 0)
        R = bd.slot_rotation(s)
        Kp = _rotate_triplets(se.K, iface_rows, R)
        Mp = _rotate_triplets(se.M, iface_rows, R)
        nodes = slot_flank_nodes(bd.disk, s)
        disk_dofs = bd.disk.dofs_of(nodes).ravel()  # same order as the blade's root DOFs
        idx = np.empty(se.n, np.int64)
        idx[:nm] = n + np.arange(nm)
        n += nm
        bidx = idx[nm:]
        bidx[contact] = disk_dofs[iface_pos[contact]]
        n_new = int((~contact).sum())
        bidx[~contact] = n + np.arange(n_new)
        n += n_new
        rows_k.append(np.repeat(idx, idx.size))
        cols_k.append(np.tile(idx, idx.size))
        vk.append(Kp.ravel())
        vm.append(Mp.ravel())
        blade_out.append(bidx[iface_pos < 0])
    r = np.concatenate(rows_k)
    c = np.concatenate(cols_k)
    K = sp.csr_matrix((np.concatenate(vk), (r, c)), shape=(n, n))
    M = sp.csr_matrix((np.concatenate(vm), (r, c)), shape=(n, n))
    pad = sp.csr_matrix((n - nd, n - nd))
    K = (K + sp.block_diag([bd.disk.K, pad], format="csr")).tocsr()
    M = (M + sp.block_diag([bd.disk.M, pad], format="csr")).tocsr()
    n_sectors = bd.n_slots
    meas_disk = 3 * bd.disk.node_set("meas").ravel() + int(bd.disk.meta["meas_direction"]) - 1
    out_cols = np.concatenate([meas_disk] + blade_out)
    out = sp.csr_matrix((np.ones(out_cols.size), (np.arange(out_cols.size), out_cols)), shape=(out_cols.size, n))
    labels = measurement_labels(n_sectors, sorted(patterns), n_acc)
    log.info("hybrid assembly: %d DOF (%d disk FE + %d blade ROM), nnz(K)=%d", n, nd, n - nd, K.nnz)
    meta = {"formulation": formulation, "slots": sorted(patterns), "assembly": "full", "method": "hybrid"}
    return ReducedAssembly(K, M, out, labels, meta)


def solve_assembly(
    asm: ReducedAssembly, n_modes: int, *, backend: str = "auto", overwrite: bool = False
) -> AssemblyModes:
    """Lowest ``n_modes`` elastic modes of a reduced assembly at its measurement DOFs (rigid modes dropped).

    ``overwrite=True`` lets a dense eigen-solve destroy ``asm.K`` and ``asm.M`` (one-shot solves only).
    """
    if sp.issparse(asm.K):
        sol = solve_modes(asm.K, asm.M, n_modes, backend=backend)
        f, shapes = sol.frequencies_hz, sol.shapes
    else:
        dm = dense_modes(asm.K, asm.M, n_modes, overwrite=overwrite)
        f, shapes = dm.frequencies_hz, dm.shapes
    meas = np.asarray(asm.out @ shapes)
    return AssemblyModes(f, meas, list(asm.meas_labels))


def solve_d1b(
    disk: CraigBamptonModel,
    blade: RubinModel,
    pattern: ContactPattern,
    slot: int | None = None,
    *,
    n_modes: int = 10,
    delta=None,
    formulation: str = DEFAULT_FORMULATION,
) -> AssemblyModes:
    """Modes of the disk–one-blade ROM (:func:`assemble_d1b` then a dense eigen-solve).

    The assembled matrices are private to this call, so the eigen-solver may work on them in place. The
    whole solve runs with one BLAS thread (:func:`rom.modal.single_thread_blas`): it is memory-bound, and
    one thread was faster and steadier than two (docs/rom.md §4). Spread many solves over processes.
    """
    with single_thread_blas():
        asm = assemble_d1b(disk, blade, pattern, slot, delta=delta, formulation=formulation)
        return solve_assembly(asm, n_modes, overwrite=True)


def solve_full(
    disk: BladedDisk | CraigBamptonModel,
    blade: RubinModel,
    patterns,
    deltas=None,
    *,
    n_modes: int | None = None,
    formulation: str = DEFAULT_FORMULATION,
    backend: str = "auto",
) -> AssemblyModes:
    """Modes of the full bladed-disk ROM (:func:`assemble_full`); default ``n_modes`` = 3 N (three families)."""
    asm = assemble_full(disk, blade, patterns, deltas, formulation=formulation)
    n_slots = len(asm.meta["slots"])
    return solve_assembly(asm, 3 * n_slots if n_modes is None else n_modes, backend=backend)
