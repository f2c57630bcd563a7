"""From matrices in a file's DOF order to a valid :class:`rom.component.Component`.

A :class:`~rom.component.Component` has three DOFs per node, node-major (DOF ``3 n + d − 1`` for node index
``n`` and direction ``d``). FE files order their rows as they like and leave constrained DOFs out, so the
importers go through three steps:

1. :func:`dof_layout` — the component's node list (the DOF map's node ids, sorted) and, for every matrix
   row, its component DOF.
2. The matrices in component numbering, as symmetric CSR: the Matrix Market reader writes the entries
   straight into their CSR slots (:mod:`rom.importers.matrix_market`); matrices already in memory (OP4,
   ANSYS) go through :func:`matrix_to_csr` / :func:`triplets_to_csr`, which never make a dense copy and free
   their inputs as they go (peak about twice the final matrix).
3. :func:`finish_component` — coordinates, node sets, unit conversion, constrained DOFs, mass check.

Constrained (absent) DOFs
-------------------------
A DOF of a component node that no matrix entry touches (left out of the DOF map, or a row the file stores
as zeros, as ANSYS does for constrained DOFs) is *constrained*. It is kept in the component so that every
node still has three DOFs, with ``K_cc = k_ref`` (the mean stiffness diagonal) and ``M_cc = 0`` and no
coupling: the pencil is block diagonal, the constrained block has only infinite eigenvalues, and every finite
eigenpair of the component is exactly the file's eigenpair padded with zeros there. The shift-invert solver
(:func:`rom.solver.solve_modes`) factorizes ``K − σ M``, which stays positive definite. The list is in
``meta["constrained_dofs"]`` (component DOF indices); a reduction must not put them on a boundary.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..component import Component
from .errors import GridError, ModelImportError
from .units import UnitSystem, check_mass

__all__ = ["DofLayout", "dof_layout", "triplets_to_csr", "finish_component", "node_indices", "matrix_to_csr",
           "symmetrized", "SYMMETRY_RTOL", "ROUNDOFF_RTOL"]

log = logging.getLogger(__name__)

#: A matrix stored in full is accepted as symmetric when max |A − Aᵀ| ≤ SYMMETRY_RTOL · max |A|; anything near
#: 1e-8 is a modelling error (an unsymmetric element, a damping or gyroscopic term).
SYMMETRY_RTOL = 1e-8
#: Below this (relative) asymmetry the matrix is kept bit for bit: it is the round-off of FE assembly (~1e-16),
#: which the solvers ignore, and a full-storage export then reads back exactly. Between the two it is
#: replaced by (A + Aᵀ)/2.
ROUNDOFF_RTOL = 1e-12


@dataclass(frozen=True)
class DofLayout:
    """Where each matrix row of a file goes in the component.

    Attributes
    ----------
    node_ids : ndarray of int64, shape (n_nodes,)
        Component node ids, ascending.
    index : ndarray of int64, shape (n_rows,)
        Component DOF (``3 n + d − 1``) of each matrix row of the file.
    """

    node_ids: np.ndarray
    index: np.ndarray

    @property
    def n_dof(self) -> int:
        return 3 * int(self.node_ids.size)

    @property
    def is_identity(self) -> bool:
        """True when the file's rows already are the component's DOFs in order (no remapping needed)."""
        return self.index.size == self.n_dof and bool((self.index == np.arange(self.n_dof)).all())


def dof_layout(nodes: np.ndarray, dirs: np.ndarray, where: str, extra_nodes: np.ndarray | None = None) -> DofLayout:
    """The component layout of a DOF map.

    Parameters
    ----------
    nodes, dirs : ndarray of int, shape (n_rows,)
        Node id and direction (1..3) of each matrix row.
    where : str
        The DOF map's file, for messages.
    extra_nodes : ndarray of int, optional
        Further node ids of the component (the coordinates file's): a node with no row at all — every DOF
        constrained, as FE codes leave them out — is kept, with three constrained DOFs.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    dirs = np.asarray(dirs, dtype=np.int64)
    if nodes.shape != dirs.shape or nodes.ndim != 1:
        raise ModelImportError(f"{where}: node and direction columns differ in length")
    if ((dirs < 1) | (dirs > 3)).any():
        bad = int(dirs[(dirs < 1) | (dirs > 3)][0])
        raise ModelImportError(f"{where}: directions must be 1, 2, 3 (x, y, z), got {bad}")
    node_ids = np.unique(nodes if extra_nodes is None else np.concatenate([nodes, np.asarray(extra_nodes)]))
    index = 3 * np.searchsorted(node_ids, nodes).astype(np.int64) + dirs - 1
    counts = np.bincount(index, minlength=3 * node_ids.size)
    if (counts > 1).any():
        g = int(np.flatnonzero(counts > 1)[0])
        raise ModelImportError(f"{where}: node {int(node_ids[g // 3])} direction {g % 3 + 1} is mapped to "
                               f"{int(counts[g])} matrix rows; each DOF must have one row")
    return DofLayout(node_ids, index)


def _remap(rows: np.ndarray, index: np.ndarray | None, chunk: int = 1 << 22) -> np.ndarray:
    """``index[rows]`` in place, chunk by chunk (no second full-length array)."""
    if index is None:
        return rows
    for s in range(0, rows.size, chunk):
        rows[s:s + chunk] = index[rows[s:s + chunk]]
    return rows


def triplets_to_csr(parts: list, n: int, *, half: bool, index: np.ndarray | None, where: str, label: str
                    ) -> sp.csr_matrix:
    """Symmetric CSR matrix from stored entries.

    Parameters
    ----------
    parts : list [rows, cols, data]
        0-based file row and column (int32 or int64) and value (float64) of each stored entry, shape (nnz,).
        The list is emptied: its arrays are modified in place and released as soon as they are used, so that
        the caller does not hold them while the CSR matrix is built.
    n : int
        Size of the result (the component's DOF count).
    half : bool
        True when one triangle is stored (either one: off-diagonal entries are mirrored); False for the whole
        matrix, which must then be symmetric to :data:`SYMMETRY_RTOL` (it is symmetrized unless its
        asymmetry is round-off, :data:`ROUNDOFF_RTOL`).
    index : ndarray of int64, shape (n_rows,), optional
        Component DOF of each file row (:attr:`DofLayout.index`); ``None`` when they coincide.
    where, label : str
        File and matrix name (``"K"``, ``"M"``) for messages.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n, n), float64, sorted indices, no duplicates
    """
    rows, cols, data = parts
    parts.clear()
    if not np.isfinite(data).all():
        k = int(np.flatnonzero(~np.isfinite(data))[0])
        raise ModelImportError(f"{where}: {label} has a non-finite value {data[k]!r} at row {int(rows[k]) + 1}, "
                               f"column {int(cols[k]) + 1}")
    rows = _remap(rows, index)
    cols = _remap(cols, index)
    idx_dtype = np.int32 if n < 2**31 - 1 else np.int64
    A = sp.csr_matrix((data, (rows.astype(idx_dtype, copy=False), cols.astype(idx_dtype, copy=False))),
                      shape=(n, n))
    del rows, cols, data
    A.sum_duplicates()
    if half:
        # A holds one triangle (in file numbering): A + Aᵀ with the diagonal counted once. The diagonal of
        # Aᵀ is zeroed in place (no structural change), and the sum drops the zeros it produces.
        T = A.T.tocsr()
        row_of = np.repeat(np.arange(n, dtype=T.indices.dtype), np.diff(T.indptr))
        T.data[T.indices == row_of] = 0.0
        del row_of
        A = A + T
        del T
    else:
        A = symmetrized(A, where, label)
    A.sort_indices()
    return A


def symmetrized(A: sp.csr_matrix, where: str, label: str) -> sp.csr_matrix:
    """A checked symmetric to :data:`SYMMETRY_RTOL`: kept as is within round-off, else (A + Aᵀ)/2 (in place when
    the patterns agree)."""
    A.sort_indices()
    T = A.T.tocsr()
    T.sort_indices()
    scale = float(np.abs(A.data).max()) if A.nnz else 0.0
    if np.array_equal(A.indptr, T.indptr) and np.array_equal(A.indices, T.indices):
        diff = np.abs(A.data - T.data)
        k = int(np.argmax(diff)) if diff.size else 0
        worst = float(diff[k]) if diff.size else 0.0
        if worst > SYMMETRY_RTOL * scale:
            i = int(np.searchsorted(A.indptr, k, side="right") - 1)
            _not_symmetric(where, label, worst, scale, i, int(A.indices[k]))
        del diff
        if worst <= ROUNDOFF_RTOL * scale:
            return A
        A.data += T.data
        A.data *= 0.5
        return A
    D = (A - T).tocoo()
    k = int(np.argmax(np.abs(D.data))) if D.nnz else 0
    worst = float(abs(D.data[k])) if D.nnz else 0.0
    if worst > SYMMETRY_RTOL * scale:
        _not_symmetric(where, label, worst, scale, int(D.row[k]), int(D.col[k]))
    if worst <= ROUNDOFF_RTOL * scale:
        return A
    S = (A + T) * 0.5
    return S.tocsr()


def _not_symmetric(where: str, label: str, worst: float, scale: float, i: int, j: int):
    raise ModelImportError(
        f"{where}: {label} is not symmetric: max |{label} − {label}ᵀ| = {worst:.3g} at component DOF {i}, {j} "
        f"({worst / scale:.2g} of max |{label}|; at most {SYMMETRY_RTOL:g} allowed)"
    )


def node_indices(node_ids: np.ndarray, ids: np.ndarray, where: str, what: str) -> np.ndarray:
    """Indices (into sorted ``node_ids``) of the node ids ``ids`` (any shape); :class:`GridError` if one is missing."""
    ids = np.asarray(ids, dtype=np.int64)
    pos = np.searchsorted(node_ids, ids)
    pos_c = np.clip(pos, 0, node_ids.size - 1)
    bad = node_ids[pos_c] != ids
    if bad.any():
        missing = np.unique(ids[bad])
        raise GridError(f"{where}: {what} names {missing.size} node(s) that are not in the mesh "
                        f"(first: node {int(missing[0])})")
    return pos_c


def finish_component(
    name: str,
    K: sp.csr_matrix,
    M: sp.csr_matrix,
    node_ids: np.ndarray,
    *,
    coords: tuple[np.ndarray, np.ndarray] | None,
    node_sets: Mapping[str, np.ndarray] | None,
    units: UnitSystem,
    source: str,
    meta: Mapping[str, object] | None = None,
) -> Component:
    """Assemble the :class:`~rom.component.Component`: coordinates, node sets, SI units, constrained DOFs.

    Parameters
    ----------
    name : str
    K, M : csr_matrix, shape (3 n_nodes, 3 n_nodes)
        Symmetric matrices in component numbering, in the file's units (converted here, in place).
    node_ids : ndarray of int64, shape (n_nodes,)
        Ascending node ids (:attr:`DofLayout.node_ids`).
    coords : (ids (m,), xyz (m, 3)) or None
        Node coordinates in the file's length unit; they must cover every component node (others are
        ignored). ``None`` leaves the coordinates NaN (grids and the mass check then cannot be done).
    node_sets : mapping name → node ids, optional
        Named sets (any shape), mapped to node indices.
    units : UnitSystem
        The system the file is in.
    source : str
        The file, for messages and ``meta["source"]``.
    meta : mapping, optional
        Extra metadata (format, matrix names, ...).
    """
    n_nodes = int(node_ids.size)
    if K.shape != (3 * n_nodes,) * 2 or M.shape != K.shape:
        raise ModelImportError(f"{source}: K {K.shape} and M {M.shape} must both be ({3 * n_nodes}, {3 * n_nodes})")
    X = np.full((n_nodes, 3), np.nan)
    if coords is not None:
        ids, xyz = coords
        order = np.argsort(ids, kind="stable")
        sid = np.asarray(ids)[order]
        pos = np.searchsorted(sid, node_ids)
        pos_c = np.clip(pos, 0, max(sid.size - 1, 0))
        bad = sid[pos_c] != node_ids if sid.size else np.ones(n_nodes, bool)
        if bad.any():
            raise ModelImportError(f"{source}: the coordinates lack {int(bad.sum())} of the {n_nodes} nodes of the "
                                   f"DOF map (first: node {int(node_ids[bad][0])})")
        X = np.asarray(xyz, dtype=np.float64)[order[pos_c]] * units.length
    # SI, in place on the CSR data: no second copy of a large matrix.
    if not units.is_si:
        K.data *= units.stiffness
        M.data *= units.mass
    # Constrained DOFs: no entry in K nor M (see the module notes).
    touched = (np.diff(K.indptr) > 0) | (np.diff(M.indptr) > 0)
    constrained = np.flatnonzero(~touched)
    if constrained.size:
        if constrained.size == K.shape[0]:
            raise ModelImportError(f"{source}: K and M have no entries")
        k_ref = float(np.abs(K.diagonal()[touched]).mean())
        dk = np.zeros(K.shape[0])
        dk[constrained] = k_ref
        K = (K + sp.diags(dk, format="csr")).tocsr()
        K.sort_indices()
        log.info("%s: %d constrained DOFs kept as decoupled rows (K = %.3g, M = 0)", source, constrained.size, k_ref)
    sets = {}
    for key, ids in (node_sets or {}).items():
        sets[key] = node_indices(node_ids, ids, source, f"node set {key!r}")
    info = {"source": source, "units": units.name, "units_conversion": units.describe(),
            "constrained_dofs": constrained.tolist(), **dict(meta or {})}
    comp = Component(name, K, M, np.asarray(node_ids, dtype=np.int64), X, sets, info)
    check_mass(comp.mass(), X, source, units)
    return comp


def matrix_to_csr(A: sp.spmatrix, n: int, *, index: np.ndarray | None, where: str, label: str
                  ) -> tuple[sp.csr_matrix, str]:
    """:func:`triplets_to_csr` for a matrix already in memory (OP4, ANSYS): detects one-triangle storage.

    Returns the symmetric CSR matrix in component numbering and a word on the storage found.
    """
    if A.shape[0] != A.shape[1]:
        raise ModelImportError(f"{where}: {label} must be square, got {A.shape[0]} × {A.shape[1]}")
    if index is not None and index.size != A.shape[0]:
        raise ModelImportError(f"{where}: {label} has {A.shape[0]} rows, the DOF map has {index.size}")
    C = sp.coo_matrix(A)
    lower = bool((C.row > C.col).any())
    upper = bool((C.row < C.col).any())
    half = lower != upper
    storage = f"{'upper' if upper else 'lower'} triangle" if half else "full matrix"
    idx_dtype = np.int32 if A.shape[0] < 2**31 - 1 else np.int64
    parts = [C.row.astype(idx_dtype, copy=True), C.col.astype(idx_dtype, copy=True),
             np.array(C.data, dtype=np.float64, copy=True)]
    del C
    return triplets_to_csr(parts, n, half=half, index=index, where=where, label=label), storage
