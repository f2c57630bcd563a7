"""20-node serendipity hexahedron (quadratic, isoparametric) for 3-D linear elasticity.

Node order (reference coordinates ξ, η, ζ ∈ [-1, 1]): corners 0–7 as in ANSYS SOLID186 / Abaqus C3D20,
then the mid-side nodes of the bottom face (8–11), top face (12–15) and vertical edges (16–19).
Element matrices use full 3×3×3 Gauss integration, so the mass matrix of an undistorted element and the
stiffness matrix are integrated exactly; matrices are assembled vectorised, in chunks of elements, to
keep memory bounded.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["REF_NODES", "shape_functions", "assemble", "element_volumes"]

_CORNERS = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1], [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=float,
)
_MIDS = np.array(
    [
        [0, -1, -1], [1, 0, -1], [0, 1, -1], [-1, 0, -1],
        [0, -1, 1], [1, 0, 1], [0, 1, 1], [-1, 0, 1],
        [-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],
    ],
    dtype=float,
)
#: Reference coordinates of the 20 nodes, shape (20, 3).
REF_NODES = np.vstack([_CORNERS, _MIDS])


def shape_functions(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions and their reference derivatives.

    Parameters
    ----------
    xi : ndarray, shape (n_points, 3)
        Reference coordinates.

    Returns
    -------
    N : ndarray, shape (n_points, 20)
    dN : ndarray, shape (n_points, 20, 3)
        ∂N/∂(ξ, η, ζ).
    """
    xi = np.atleast_2d(np.asarray(xi, dtype=float))
    p = xi[:, None, :]  # (q, 1, 3)
    r = REF_NODES[None, :, :]  # (1, 20, 3)
    N = np.empty((xi.shape[0], 20))
    dN = np.empty((xi.shape[0], 20, 3))
    # Corners: N = 1/8 Π(1 + ξ ξ_i) (Σ ξ ξ_i − 2)
    pc, rc = p, r[:, :8, :]
    lin = 1.0 + pc * rc  # (q, 8, 3)
    s = (pc * rc).sum(axis=2) - 2.0  # (q, 8)
    prod = lin.prod(axis=2)
    N[:, :8] = prod * s / 8.0
    for a in range(3):
        others = np.prod(np.delete(lin, a, axis=2), axis=2)
        dN[:, :8, a] = (rc[..., a] * others * s + prod * rc[..., a]) / 8.0
    # Mid-sides: the zero reference coordinate takes the bubble (1 − ξ²), the others the linear factors.
    rm = r[:, 8:, :]
    zero = rm == 0.0  # (1, 12, 3)
    f = np.where(zero, 1.0 - pc**2, 1.0 + pc * rm)  # (q, 12, 3)
    df = np.where(zero, -2.0 * pc, rm) * np.ones_like(f)
    N[:, 8:] = f.prod(axis=2) / 4.0
    for a in range(3):
        dN[:, 8:, a] = df[..., a] * np.prod(np.delete(f, a, axis=2), axis=2) / 4.0
    return N, dN


def _gauss(n: int = 3) -> tuple[np.ndarray, np.ndarray]:
    g, w = np.polynomial.legendre.leggauss(n)
    X = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    W = np.einsum("i,j,k->ijk", w, w, w).reshape(-1)
    return X, W


_GP, _GW = _gauss(3)
_N, _DN = shape_functions(_GP)


def _geometry(Xe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Physical shape-function gradients (E, q, 20, 3) and |J|·w (E, q) for element coordinates (E, 20, 3)."""
    J = np.einsum("qna,enb->eqab", _DN, Xe)
    det = np.linalg.det(J)
    if np.any(det <= 0.0):
        bad = int(np.argwhere((det <= 0.0).any(axis=1))[0, 0])
        raise ValueError(f"hex20 element {bad} of this chunk is inverted or degenerate (Jacobian ≤ 0)")
    invJ = np.linalg.inv(J)
    dNdx = np.einsum("qna,eqba->eqnb", _DN, invJ)
    return dNdx, det * _GW[None, :]


def element_volumes(coords: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """Volume of each element in m³, shape (n_elements,)."""
    return _geometry(coords[conn])[1].sum(axis=1)


def assemble(
    coords: np.ndarray,
    conn: np.ndarray,
    E: float,
    nu: float,
    rho: float,
    chunk: int = 2000,
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Assemble the global stiffness and consistent mass matrices.

    Parameters
    ----------
    coords : ndarray, shape (n_nodes, 3)
        Node coordinates (m).
    conn : ndarray of int, shape (n_elements, 20)
        Node indices of each element in :data:`REF_NODES` order.
    E, nu, rho : float
        Young's modulus (Pa), Poisson's ratio, density (kg/m³); isotropic.
    chunk : int
        Elements per vectorised batch (bounds the temporary memory).

    Returns
    -------
    K, M : csr_matrix, shape (3 n_nodes, 3 n_nodes)
        Node-major DOF ordering (DOF = 3 node + direction − 1).
    """
    if not (E > 0 and rho > 0 and -1.0 < nu < 0.5):
        raise ValueError(f"material must have E > 0, rho > 0 and -1 < nu < 0.5; got E={E}, rho={rho}, nu={nu}")
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    n_dof = 3 * coords.shape[0]
    eye3 = np.eye(3)
    k_parts, m_parts, idx_parts = [], [], []
    for start in range(0, conn.shape[0], chunk):
        c = conn[start : start + chunk]
        dNdx, wdet = _geometry(coords[c])
        G = dNdx * np.sqrt(wdet)[:, :, None, None]
        A = np.einsum("eqni,eqmj->enimj", G, G)  # ∫ ∂N_n/∂x_i ∂N_m/∂x_j
        S = np.einsum("enimi->enm", A)  # ∫ ∇N_n · ∇N_m
        Ke = lam * A + mu * A.transpose(0, 1, 4, 3, 2) + mu * S[:, :, None, :, None] * eye3[None, None, :, None, :]
        # The mass only couples equal directions: store the 20×20 scalar block once per direction.
        m_parts.append(rho * np.einsum("qn,qm,eq->enm", _N, _N, wdet).reshape(c.shape[0], -1))
        k_parts.append(Ke.reshape(c.shape[0], -1))
        idx_parts.append(c)
    nodes = np.concatenate(idx_parts).astype(np.int64)
    dofs = (3 * nodes[:, :, None] + np.arange(3)[None, None, :]).reshape(nodes.shape[0], 60)
    rows = np.repeat(dofs, 60, axis=1).ravel()
    cols = np.tile(dofs, (1, 60)).ravel()
    K = sp.csr_matrix((np.concatenate(k_parts).ravel(), (rows, cols)), shape=(n_dof, n_dof))
    del rows, cols
    mvals = np.concatenate(m_parts).ravel()
    m_rows = np.concatenate([np.repeat(3 * nodes + d, 20, axis=1).ravel() for d in range(3)])
    m_cols = np.concatenate([np.tile(3 * nodes + d, (1, 20)).ravel() for d in range(3)])
    M = sp.csr_matrix((np.tile(mvals, 3), (m_rows, m_cols)), shape=(n_dof, n_dof))
    K.sum_duplicates()
    M.sum_duplicates()
    return K, M
