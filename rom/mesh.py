"""Structured 20-node hexahedral meshes on a mapped lattice.

A block of ``(a, b, c)`` cells is described on the *quadratic lattice* of half-cell indices
``(I, J, K)`` with ``0 ≤ I ≤ 2a`` etc.: even indices are cell corners, odd ones mid-sides.
A mapping function gives the physical position of every lattice point, so mid-side nodes follow curved
geometry (arcs, fillets) exactly where the mapping does. Cells can be switched off (slots), and the first
direction can be periodic (closed rings).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .hex20 import REF_NODES

__all__ = ["StructuredMesh", "structured_hex20"]

_OFFSETS = (1 + REF_NODES).astype(np.int64)  # lattice offsets of the 20 nodes inside a cell, (20, 3)


@dataclass(frozen=True, eq=False)
class StructuredMesh:
    """A hex20 mesh with its lattice bookkeeping.

    Attributes
    ----------
    coords : ndarray, shape (n_nodes, 3)
        Node coordinates (m).
    conn : ndarray of int64, shape (n_elements, 20)
        Element node indices.
    lattice : ndarray of int64, shape (nI, nJ, nK)
        Node index at each lattice point, −1 where no node exists (face/cell centres, inactive cells).
    """

    coords: np.ndarray
    conn: np.ndarray
    lattice: np.ndarray

    def node_at(self, I, J, K) -> np.ndarray:
        """Node indices at lattice points; raises if any point has no node."""
        idx = self.lattice[I, J, K]
        if np.any(idx < 0):
            raise ValueError("requested lattice point carries no hex20 node (face centre or inactive cell)")
        return idx


def structured_hex20(
    cells: tuple[int, int, int],
    position: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
    active: np.ndarray | None = None,
    periodic_first: bool = False,
) -> StructuredMesh:
    """Mesh a mapped block of hex20 cells.

    Parameters
    ----------
    cells : (a, b, c)
        Cell counts along the three lattice directions.
    position : callable
        ``position(I, J, K) -> X`` with integer lattice arrays of shape (n,) and ``X`` of shape (n, 3) in m.
        With ``periodic_first``, ``I`` is reduced modulo ``2a``.
    active : ndarray of bool, shape (a, b, c), optional
        Cells to keep (default: all).
    periodic_first : bool
        Close the first direction into a ring (lattice point ``2a`` is point ``0``).
    """
    a, b, c = cells
    if min(cells) < 1:
        raise ValueError(f"cell counts must be ≥ 1, got {cells}")
    if active is None:
        active = np.ones(cells, dtype=bool)
    nI = 2 * a if periodic_first else 2 * a + 1
    ii, jj, kk = np.nonzero(active)
    lat = np.stack([2 * ii, 2 * jj, 2 * kk], axis=1)[:, None, :] + _OFFSETS[None, :, :]  # (E, 20, 3)
    if periodic_first:
        lat[..., 0] %= nI
    flat = np.ravel_multi_index((lat[..., 0], lat[..., 1], lat[..., 2]), (nI, 2 * b + 1, 2 * c + 1))
    used, conn = np.unique(flat, return_inverse=True)
    conn = conn.reshape(flat.shape).astype(np.int64)
    I, J, K = np.unravel_index(used, (nI, 2 * b + 1, 2 * c + 1))
    coords = np.asarray(position(I, J, K), dtype=float)
    lattice = -np.ones((nI, 2 * b + 1, 2 * c + 1), dtype=np.int64)
    lattice[I, J, K] = np.arange(used.size)
    return StructuredMesh(coords, conn, lattice)
