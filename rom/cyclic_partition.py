"""A cyclic disk cut into its N sectors, and sector 1's couplings (:mod:`rom.cyclic_sector`, step 1).

Each node gets a sector (its angle about the disk axis, sector s spanning [(s − 1.5) α, (s − 0.5) α) around
slot s, α = 2π/N) and the node of sector 1 it is a rotated copy of. Sector s's *left face* c_s is its nodes
coupled to the half of sector s − 1 next to it; b_s its slot grid; i_s the rest. An interior or slot node is
coupled only to its own sector and to the next sector's left face (checked).

Every quantity is in sector-local frames (the frame rotated with the sector; slot grid nodes in their slot
frames). The disk is checked to be cyclic: K and M applied to two random vectors agree with the circulant
operator built from sector 1's couplings to :data:`CYCLIC_TOL` (max-norm relative).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .craig_bampton import disk_boundary_dofs
from .errors import ROMError

__all__ = ["SectorBlocks", "sector_blocks", "CYCLIC_TOL"]

#: How far (max-norm relative) K and M may differ from the block-circulant operator of sector 1's couplings.
CYCLIC_TOL = 1e-6
#: Node positions of rotated copies agree to this fraction of the disk radius: trigonometric round-off is
#: 1e-16, an imported mesh's printed coordinates ~1e-7; nodes are ~1e-3 apart, so a match is never ambiguous.
#: Whether the copies are close enough is then up to the K and M check (:data:`CYCLIC_TOL`).
_POS_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class SectorBlocks:
    """Sector 1's couplings in sector-local frames, DOFs ordered [i (interior), c (left face), b (slot grid)].

    Attributes
    ----------
    n_sectors : int
    n_int, n_face, n_i : int
        DOFs of the interior, the left face and the slot grid.
    K, M : dict d → sparse matrix, shape (n_own, n_own)
        Couplings of sector 1's DOFs with sector 1 + d's (d = 0 … N − 1; absent blocks are zero).
    meas : list of (row, sector, dof3, w)
        For each disk output DOF: its row, the 0-based sector, sector 1's DOF triplet of the node (length-3
        array of DOF indices) and w (3,) with output = w · u_local.
    asymmetry : float
        Max-norm relative difference between K (and M) and the circulant operator of these blocks.
    """

    n_sectors: int
    n_int: int
    n_face: int
    n_i: int
    K: dict
    M: dict
    meas: list
    asymmetry: float

    @property
    def n_own(self) -> int:
        return self.n_int + self.n_face + self.n_i


def _axis_angle(Q: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit axis and angle (rad) of a rotation matrix, angle in (0, π]."""
    a = np.array([Q[2, 1] - Q[1, 2], Q[0, 2] - Q[2, 0], Q[1, 0] - Q[0, 1]])
    ang = math.atan2(0.5 * np.linalg.norm(a), 0.5 * (np.trace(Q) - 1.0))
    if np.linalg.norm(a) < 1e-12:  # angle π (N = 2): the axis is the eigenvector of eigenvalue 1
        w, v = np.linalg.eigh(0.5 * (Q + Q.T))
        return v[:, np.argmax(w)], ang
    return a / np.linalg.norm(a), ang


def sector_blocks(bd) -> SectorBlocks:
    """Partition the disk of ``bd`` into its N sectors and extract sector 1's couplings (module notes).

    Raises
    ------
    ROMError
        If the mesh, the slot frames or K and M are not cyclic, naming what differs.
    """
    N = bd.n_slots
    if N < 2:
        raise ROMError(f"the cyclic reduction needs a disk of at least 2 sectors, got {N}")
    X = np.asarray(bd.disk.coords, dtype=np.float64)
    n_nodes = X.shape[0]
    Q, axis = _sector_rotations(bd, N)
    b_nodes = np.concatenate([bd.disk.node_set("slot1_L").ravel(), bd.disk.node_set("slot1_R").ravel()])
    sector, upper, size = _node_sectors(X, axis, b_nodes, N)
    own, ref = _rotated_copies(X, sector, Q, size, N)
    i_nodes, c_nodes = _sector_one_parts(bd.disk, own[0], sector, upper, b_nodes, N)
    order = np.concatenate([i_nodes, c_nodes, b_nodes])  # sector 1's nodes in block order
    pos = np.empty(n_nodes, np.int64)
    pos[order] = np.arange(order.size)
    ref = pos[own[0][ref]]  # every node → its sector-1 copy's block position
    n_own = order.size
    G = _local_frames(bd, Q, sector, ref, pos, b_nodes, n_own)
    Tg, perm = _sector_major(G, sector, ref, n_own)
    n3 = 3 * n_own
    blocks = {name: _coupling_blocks(getattr(bd.disk, name), Tg, perm, order, N, n3) for name in ("K", "M")}
    n_int, n_face = 3 * i_nodes.size, 3 * c_nodes.size
    _check_locality(blocks, N, n_int, n_face)
    asym = max(_circulant_defect(getattr(bd.disk, name), blocks[name], Tg, perm, N, n3) for name in ("K", "M"))
    if asym > CYCLIC_TOL:
        raise ROMError(f"the disk is not cyclic to {CYCLIC_TOL:g} (K or M differs from sector 1's circulant "
                       f"operator by {asym:.1e} relative); use the sparse hybrid (rom.rom_assembly.assemble_full)")
    meas = _measurement_rows(bd.disk, ref, sector, G, n_int + n_face)
    return SectorBlocks(N, n_int, n_face, 3 * b_nodes.size, blocks["K"], blocks["M"], meas, asym)


def _sector_rotations(bd, N: int) -> tuple[np.ndarray, np.ndarray]:
    """Q_s, the rotation from sector s's frame to sector 1's (shape (N, 3, 3)), and the disk axis (3,)."""
    R1 = bd.slot_rotation(1)
    Q = np.stack([bd.slot_rotation(s) @ R1.T for s in range(1, N + 1)])  # sector s → frame of sector 1
    axis, ang = _axis_angle(Q[1])
    alpha = 2 * math.pi / N
    if abs(ang - alpha) > 1e-7:
        raise ROMError(f"slot 2 is not slot 1 rotated by 2π/{N} ({ang:.6g} rad); the disk is not cyclic")
    return Q, axis


def _node_sectors(X: np.ndarray, axis: np.ndarray, b_nodes: np.ndarray, N: int):
    """Each node's 0-based sector, whether it lies in the half of its sector next to the following one, and the
    disk radius (for the position tolerance): node angles about the axis, from slot 1's centre line."""
    alpha = 2 * math.pi / N
    P = X - np.outer(X @ axis, axis)
    d0 = P[b_nodes].mean(axis=0)
    d0 /= np.linalg.norm(d0)
    e2 = np.cross(axis, d0)
    r = np.linalg.norm(P, axis=1)
    size = float(r.max())
    if r.min() <= 1e-9 * size:
        raise ROMError("a disk node lies on the rotation axis; the cyclic reduction needs a disk with a bore")
    u = np.arctan2(P @ e2, P @ d0) / alpha + 0.5
    # A node on a cut (the sector's left face, up to an imported mesh's printed digits) belongs to the sector
    # on its right.
    sector = np.floor(u + _POS_TOL).astype(np.int64)
    upper = u - sector > 0.5  # in the half of its sector next to the following sector
    sector %= N
    return sector, upper, size


def _rotated_copies(X: np.ndarray, sector: np.ndarray, Q: np.ndarray, size: float, N: int):
    """Each sector's nodes (list of N index arrays) and, for every node, the position in sector 1's nodes of the
    node it is a rotated copy of."""
    own = [np.flatnonzero(sector == s) for s in range(N)]
    tree = cKDTree(X[own[0]])
    ref = np.full(X.shape[0], -1, np.int64)
    for s in range(N):
        dist, j = tree.query(X[own[s]] @ Q[s], distance_upper_bound=_POS_TOL * size)
        if own[s].size != own[0].size or np.any(~np.isfinite(dist)) or np.unique(j).size != j.size:
            raise ROMError(f"sector {s + 1}'s nodes are not sector 1's rotated by {s} × 2π/{N}; the disk is not cyclic")
        ref[own[s]] = j  # position in own[0]
    return own, ref


def _sector_one_parts(comp, own0: np.ndarray, sector: np.ndarray, upper: np.ndarray, b_nodes: np.ndarray, N: int):
    """Sector 1's interior nodes i_1 and left-face nodes c_1 (the slot grid b_1 is ``b_nodes``)."""
    n_nodes = sector.size
    # Left face: sector-1 nodes coupled to the half of sector N next to it (for N = 2, sector 2 is also the
    # right neighbour; its other half couples to sector 1's interior through sector 2's own face).
    coupled_left = _coupled_to(comp, own0, (sector == (N - 1) % N) & upper)
    is_b = np.zeros(n_nodes, bool)
    is_b[b_nodes] = True
    if np.any(sector[b_nodes] != 0):
        raise ROMError("slot 1's contact grid is not inside sector 1; the cyclic reduction cannot use this disk")
    c_nodes = own0[coupled_left & ~is_b[own0]]
    if np.any(coupled_left & is_b[own0]):
        raise ROMError("slot 1's contact grid touches the neighbouring sector; the cyclic reduction cannot use it")
    i_nodes = own0[~coupled_left & ~is_b[own0]]
    return i_nodes, c_nodes


def _local_frames(bd, Q: np.ndarray, sector, ref, pos, b_nodes: np.ndarray, n_own: int) -> np.ndarray:
    """G (n_nodes, 3, 3) with u_global = G u_local: the identity in sector 1 except the slot grid (slot frames),
    sector s rotated by Q_s. Checks that every slot's grid and frame are slot 1's rotated."""
    N = Q.shape[0]
    dofs_b, rots_b = disk_boundary_dofs(bd, range(1, N + 1))
    n_bn = b_nodes.size
    F = np.broadcast_to(np.eye(3), (n_own, 3, 3)).copy()
    F[pos[b_nodes]] = rots_b[:n_bn]
    for s in range(1, N + 1):
        nodes_s = dofs_b[(s - 1) * 3 * n_bn : s * 3 * n_bn : 3] // 3
        if np.any(ref[nodes_s] != pos[b_nodes]) or np.any(sector[nodes_s] != s - 1):
            raise ROMError(f"slot {s}'s contact grid is not slot 1's rotated; the disk is not cyclic")
        if not np.allclose(rots_b[(s - 1) * n_bn : s * n_bn], Q[s - 1] @ rots_b[:n_bn], atol=1e-8):
            raise ROMError(f"slot {s}'s frame is not slot 1's rotated; the disk is not cyclic")
    return Q[sector] @ F[ref]


def _sector_major(G: np.ndarray, sector: np.ndarray, ref: np.ndarray, n_own: int):
    """The frame transform Tg (sparse, u_global = Tg u_local) and ``perm``: new DOF index → global DOF, with the
    DOFs in sector-major block order."""
    n_nodes = G.shape[0]
    Tg = sp.bsr_matrix((G, np.arange(n_nodes), np.arange(n_nodes + 1)), shape=(3 * n_nodes, 3 * n_nodes)).tocsr()
    newdof = (3 * (sector * n_own + ref))[:, None] + np.arange(3)  # (n_nodes, 3): sector-major block order
    perm = np.empty(3 * n_nodes, np.int64)
    perm[newdof.ravel()] = np.arange(3 * n_nodes)  # new index → global DOF
    return Tg, perm


def _coupling_blocks(A, Tg, perm: np.ndarray, order: np.ndarray, N: int, n3: int) -> dict:
    """Sector 1's rows of ``A`` in local frames, cut into the non-zero blocks d → B_d (columns of sector 1 + d)."""
    rows = 3 * order[:, None] + np.arange(3)
    A = A.tocsr()
    # Sector 1's rows in local frames, columns in sector-major order.
    R0 = (Tg[:, rows.ravel()].T @ A @ Tg).tocsc()[:, perm].tocsr()
    R0.eliminate_zeros()
    blk = {}
    for d in range(N):
        B = R0[:, d * n3 : (d + 1) * n3]
        if B.nnz:
            blk[d] = B.tocsr()
    return blk


def _measurement_rows(comp, ref: np.ndarray, sector: np.ndarray, G: np.ndarray, n_ic: int) -> list:
    """:attr:`SectorBlocks.meas` of the disk's measurement DOFs; ``n_ic`` DOFs of interior and face."""
    meas_nodes = comp.node_set("meas").ravel()
    e_dir = np.zeros(3)
    e_dir[int(comp.meta["meas_direction"]) - 1] = 1.0
    meas = []
    for k, nd in enumerate(meas_nodes):
        p = ref[nd]
        if p >= n_ic:
            raise ROMError("a disk measurement DOF lies on a slot's contact grid; the cyclic CB cannot output it")
        meas.append((k, int(sector[nd]), 3 * p + np.arange(3), G[nd].T @ e_dir))
    return meas


def _coupled_to(comp, nodes: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Which of ``nodes`` have a K or M entry with a node flagged in ``target`` (bool per node), shape (n,)."""
    dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
    hit = np.zeros(nodes.size, bool)
    for A in (comp.K, comp.M):
        C = A.tocsr()[dofs].tocoo()
        hit[C.row[target[C.col // 3] & (C.data != 0)] // 3] = True
    return hit


def _check_locality(blocks: dict, N: int, n_int: int, n_face: int) -> None:
    """Interior and slot rows couple only to sector 1 and to the next sector's left face (module notes)."""
    for name, blk in blocks.items():
        for d, B in blk.items():
            if d == 0:
                continue
            inner = B[np.r_[0:n_int, n_int + n_face : B.shape[0]]]
            bad = inner[:, np.r_[0:n_int, n_int + n_face : B.shape[1]]].nnz if d == 1 else inner.nnz
            if bad:
                raise ROMError(f"{name}: a node inside sector 1 is coupled to sector {d + 1} beyond its face; "
                               "the sectors are too thin for the cyclic reduction")


def _circulant_defect(A, blk: dict, Tg, perm, N: int, n3: int) -> float:
    """max |A x − C x| / max |A x| for two fixed random x, C the circulant operator of sector 1's blocks."""
    x = np.random.default_rng(7).standard_normal((N * n3, 2))
    z = np.empty_like(x)
    z[perm] = x  # global DOF order, local frames
    y = np.empty_like(x)
    y[:] = (Tg.T @ (A @ (Tg @ z)))[perm]
    yc = np.zeros_like(x)
    xs = x.reshape(N, n3, 2)
    for d, B in blk.items():
        # Block row s: Σ_d B_d x_(s + d).
        yc += (B @ np.roll(xs, -d, axis=0).transpose(1, 0, 2).reshape(n3, -1)).reshape(n3, N, 2).transpose(
            1, 0, 2).reshape(N * n3, 2)
    return float(np.max(np.abs(y - yc)) / np.max(np.abs(y)))
