"""The ``Component`` value type: one finite-element substructure (design §1, §3).

A component carries sparse stiffness and mass matrices together with everything needed to address
its degrees of freedom by physical meaning: node ids, node coordinates, DOF labels and named node sets.
DOF ``k`` of the matrices is node ``dof_nodes[k]``, direction ``dof_dirs[k]`` (1, 2, 3 = x, y, z).
Every node carries three translational DOFs, ordered node-major: DOF of (node index n, direction d) is
``3 * n + d - 1``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import scipy.sparse as sp

__all__ = ["Component", "dof_index"]


def dof_index(node_index: np.ndarray, direction: int | np.ndarray) -> np.ndarray:
    """Global DOF index of (node index, direction 1..3); node-major ordering, 3 DOFs per node."""
    return 3 * np.asarray(node_index, dtype=np.int64) + np.asarray(direction, dtype=np.int64) - 1


@dataclass(frozen=True, eq=False)
class Component:
    """A finite-element substructure with labelled DOFs.

    Parameters
    ----------
    name : str
        Short name (``"disk"``, ``"blade"``, ...).
    K, M : scipy.sparse.csr_matrix, shape (n_dof, n_dof)
        Stiffness (N/m) and mass (kg) matrices, float64, symmetric.
    node_ids : ndarray of int64, shape (n_nodes,)
        Node ids; node index ``n`` (row of ``coords``) has id ``node_ids[n]``.
    coords : ndarray of float64, shape (n_nodes, 3)
        Node coordinates in metres.
    node_sets : mapping of str to ndarray of int64
        Named sets of node *indices* (not ids); arrays may have any shape (the contact grids are
        ``(n_i, n_j)``), entries are indices into ``coords``.
    meta : mapping
        Free-form, JSON-serialisable metadata (material, geometry parameters).
    elements : ndarray of int64, shape (n_elements, 20), optional
        Element connectivity (node indices, hex20 order of :mod:`rom.hex20`), for plots and export.
    """

    name: str
    K: sp.csr_matrix
    M: sp.csr_matrix
    node_ids: np.ndarray
    coords: np.ndarray
    node_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    meta: Mapping[str, object] = field(default_factory=dict)
    elements: np.ndarray | None = None

    def __post_init__(self) -> None:
        n_nodes = self.coords.shape[0]
        if self.coords.ndim != 2 or self.coords.shape[1] != 3:
            raise ValueError(f"Component {self.name!r}: coords must have shape (n_nodes, 3), got {self.coords.shape}")
        if self.node_ids.shape != (n_nodes,):
            raise ValueError(
                f"Component {self.name!r}: node_ids must have shape ({n_nodes},), got {self.node_ids.shape}"
            )
        for label, A in (("K", self.K), ("M", self.M)):
            if A.shape != (3 * n_nodes, 3 * n_nodes):
                raise ValueError(
                    f"Component {self.name!r}: {label} must be ({3 * n_nodes}, {3 * n_nodes}), got {A.shape}"
                )
        for key, idx in self.node_sets.items():
            idx = np.asarray(idx)
            if idx.size and (idx.min() < 0 or idx.max() >= n_nodes):
                raise ValueError(f"Component {self.name!r}: node set {key!r} indexes outside 0..{n_nodes - 1}")
        object.__setattr__(self, "K", sp.csr_matrix(self.K, dtype=np.float64))
        object.__setattr__(self, "M", sp.csr_matrix(self.M, dtype=np.float64))
        object.__setattr__(self, "node_sets", MappingProxyType({k: np.asarray(v) for k, v in self.node_sets.items()}))
        object.__setattr__(self, "meta", MappingProxyType(dict(self.meta)))

    @property
    def n_nodes(self) -> int:
        return int(self.coords.shape[0])

    @property
    def n_dof(self) -> int:
        return 3 * self.n_nodes

    @property
    def dof_nodes(self) -> np.ndarray:
        """Node id of each DOF, shape (n_dof,)."""
        return np.repeat(self.node_ids, 3)

    @property
    def dof_dirs(self) -> np.ndarray:
        """Direction (1, 2, 3 = x, y, z) of each DOF, shape (n_dof,)."""
        return np.tile(np.arange(1, 4, dtype=np.int64), self.n_nodes)

    def dofs_of(self, node_indices: np.ndarray) -> np.ndarray:
        """All three DOF indices of the given node indices, shape (n, 3), node order kept."""
        idx = np.asarray(node_indices, dtype=np.int64).reshape(-1)
        return dof_index(idx[:, None], np.arange(1, 4)[None, :])

    def node_set(self, key: str) -> np.ndarray:
        """A named node set; raises ``KeyError`` listing the available names."""
        try:
            return self.node_sets[key]
        except KeyError:
            avail = sorted(self.node_sets)
            raise KeyError(f"Component {self.name!r} has no node set {key!r}; available: {avail}") from None

    def mass(self) -> float:
        """Total mass in kg (rigid translation in x through M)."""
        u = np.zeros(self.n_dof)
        u[0::3] = 1.0
        return float(u @ (self.M @ u))

    def node_masses(self, node_groups, kg_each: float) -> sp.csr_matrix:
        """``kg_each`` kg of lumped mass spread evenly over each group of node indices, as a diagonal mass
        matrix on this component's DOFs, shape (n_dof, n_dof).

        Translations only (a bolt's rotary inertia is left out): hardware the FE model leaves out, such as the
        bolts that hold each blade on the disk (paper §4–5 models them).
        """
        if not (np.isfinite(kg_each) and kg_each >= 0):
            raise ValueError(f"kg_each must be a mass in kg (≥ 0), got {kg_each!r}")
        d = np.zeros(self.n_dof)
        for nodes in node_groups if kg_each else ():
            nodes = np.asarray(nodes, dtype=np.int64).ravel()
            d[self.dofs_of(nodes).ravel()] += kg_each / nodes.size
        return sp.diags(d, format="csr")

    def with_node_masses(self, node_groups, kg_each: float) -> Component:
        """A copy with :meth:`node_masses` added to its mass matrix; ``kg_each`` = 0 returns ``self``."""
        masses = self.node_masses(node_groups, kg_each)
        return self if kg_each == 0 else self.with_matrices(self.K, (self.M + masses).tocsr())

    def with_matrices(self, K: sp.spmatrix, M: sp.spmatrix, name: str | None = None) -> Component:
        """A copy with other matrices (e.g. after re-calibration), same nodes and sets."""
        return Component(name or self.name, K, M, self.node_ids, self.coords, dict(self.node_sets), dict(self.meta),
                         self.elements)
