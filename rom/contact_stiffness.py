"""Finite contact stiffness of the blade-root joints (beyond the paper's rigid ties, Eq. 21).

The paper ties each contacting blade-root node to its disk-slot node (Eq. 21). A real joint is a pair of
rough surfaces: each contacting node pair is joined by a spring of normal stiffness ``k_n · A`` and
tangential stiffness ``k_t · A`` (``k_n``, ``k_t`` in N/m³, ``A`` the node's tributary area on the flank, m²).

In Rubin's formulation such a spring is exact and costs nothing. A massless spring in series with the blade's
boundary adds its compliance to the blade's residual flexibility (Eq. 13): the interface force ``g`` that
moves the disk-side node by ``x_b`` satisfies ``x_b = Φ_b η + (G_bb + C) g`` with ``C`` the springs'
compliance, and the strain energy of blade and spring together is ``½ gᵀ (G_bb + C) g``. So the super-element
of Eqs. 15–17 with ``G_bb + C`` in place of ``G_bb`` *is* the blade on springs, with the same coordinates:
the disk-side node keeps its index in the assembly (Eq. 22), every assembly and solver works unchanged, and
``k → ∞`` gives back the rigid ties. Detached nodes carry no force, so their compliance never acts.

* :func:`tributary_areas` — each grid node's share of its flank's area;
* :func:`flank_normal` — the unit normal of a flank's plane, from its nodes;
* :func:`compliance_parts`, :func:`interface_compliance` — the block-diagonal ``C`` over the root-interface DOFs;
* :func:`with_contact_stiffness` — the Rubin blade on springs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .contact import FLANKS
from .rubin import RubinModel

__all__ = ["ContactStiffness", "tributary_areas", "flank_normal", "compliance_parts", "blade_compliance_parts",
           "interface_compliance", "with_contact_stiffness"]


@dataclass(frozen=True)
class ContactStiffness:
    """Stiffness per unit area of every blade-root joint (N/m³), normal and tangential to the flank."""

    normal_n_per_m3: float
    tangential_n_per_m3: float

    def __post_init__(self) -> None:
        for name in ("normal_n_per_m3", "tangential_n_per_m3"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and np.isfinite(v) and v > 0):
                raise ValueError(f"contact stiffness {name} must be a positive number in N/m³, got {v!r}")


def _spacing_weights(x: np.ndarray) -> np.ndarray:
    """Half the distance to each neighbour along a line of nodes (m), shape (n,)."""
    d = np.diff(x)
    w = np.zeros(x.size)
    w[:-1] += d / 2
    w[1:] += d / 2
    return w


def tributary_areas(coords: np.ndarray) -> np.ndarray:
    """Area (m²) each grid node stands for on its flank, shape (rows, cols), from the node spacings.

    Parameters
    ----------
    coords : ndarray, shape (rows, cols, 3)
        The flank's grid nodes (m); rows run axially (local z), columns along the flank's wall.
    """
    c = np.asarray(coords, np.float64)
    if c.ndim != 3 or c.shape[2] != 3 or min(c.shape[:2]) < 2:
        raise ValueError(f"flank coordinates must have shape (rows ≥ 2, cols ≥ 2, 3), got {c.shape}")
    axial = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(c[:, 0], axis=0), axis=1))]
    along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(c[0], axis=0), axis=1))]
    return np.outer(_spacing_weights(axial), _spacing_weights(along))


def flank_normal(coords: np.ndarray) -> np.ndarray:
    """Unit normal (shape (3,)) of the plane through a flank's grid nodes (least squares, sign arbitrary)."""
    p = np.asarray(coords, np.float64).reshape(-1, 3)
    _, s, vt = np.linalg.svd(p - p.mean(axis=0), full_matrices=False)
    if s[1] <= 1e-9 * max(s[0], 1e-300):
        raise ValueError("the flank's grid nodes are collinear: no plane, no normal")
    return vt[2]


def compliance_parts(areas: list[np.ndarray], normals: list[np.ndarray]) -> np.ndarray:
    """The springs' compliance at 1 N/m³, split into its normal and tangential parts (m³/N per node).

    ``C_node = P_n / k_n + P_t / k_t`` with ``P_n = n nᵀ / A`` and ``P_t = (I − n nᵀ) / A`` in the blade's frame.

    Parameters
    ----------
    areas : list of ndarray, shape (rows, cols) each
        Tributary areas (m²) of each flank, in interface order (L then R).
    normals : list of ndarray, shape (3,) each
        Each flank's unit normal in the blade's frame.

    Returns
    -------
    ndarray, shape (2, n_nodes, 3, 3)
        ``[P_n, P_t]``, node by node in interface order (flank by flank, row-major).
    """
    parts = []
    for a, n in zip(areas, normals, strict=True):
        n = np.asarray(n, np.float64) / np.linalg.norm(n)
        nn = np.outer(n, n)
        a = np.asarray(a, np.float64).ravel()
        if np.any(a <= 0):
            raise ValueError("every contact grid node needs a positive tributary area")
        parts.append(np.stack([nn[None] / a[:, None, None], (np.eye(3) - nn)[None] / a[:, None, None]]))
    return np.concatenate(parts, axis=1)


def blade_compliance_parts(blade_component) -> np.ndarray:
    """:func:`compliance_parts` of a blade component with ``L`` and ``R`` grid node sets (academic, imported)."""
    grids = [blade_component.coords[blade_component.node_set(f)] for f in FLANKS]
    return compliance_parts([tributary_areas(g) for g in grids], [flank_normal(g) for g in grids])


def interface_compliance(parts: np.ndarray, stiffness: ContactStiffness) -> np.ndarray:
    """Compliance blocks (m/N, shape (n_nodes, 3, 3)) of the springs at ``stiffness`` from :func:`compliance_parts`."""
    return parts[0] / stiffness.normal_n_per_m3 + parts[1] / stiffness.tangential_n_per_m3


def with_contact_stiffness(blade: RubinModel, compliance: np.ndarray) -> RubinModel:
    """The Rubin blade joined to the disk by springs of ``compliance`` (see the module notes).

    Parameters
    ----------
    blade : RubinModel
    compliance : ndarray, shape (n_interface / 3, 3, 3)
        From :func:`interface_compliance` (m/N).

    Returns
    -------
    RubinModel
        The same blade with ``G_bb + C`` on the interface block; δ (Eq. 19) and every basis are kept.
    """
    c = np.asarray(compliance, np.float64)
    if c.shape != (blade.n_interface // 3, 3, 3):
        raise ValueError(f"compliance must have shape ({blade.n_interface // 3}, 3, 3) (one block per root node), "
                         f"got {c.shape}")
    G = blade.G_bb.copy()
    idx = np.arange(blade.n_interface).reshape(-1, 3)
    G[idx[:, :, None], idx[:, None, :]] += 0.5 * (c + c.transpose(0, 2, 1))
    return replace(blade, G_bb=G, meta=dict(blade.meta, contact_compliance=True))
