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
_DN_T = np.ascontiguousarray(_DN.transpose(0, 2, 1))  # (q, 3, 20)


def _geometry(Xe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Physical shape-function gradients (E, q, 20, 3) and |J|·w (E, q) for element coordinates (E, 20, 3)."""
    # J = ∂x/∂ξ (E, q, 3, 3) by batched matmuls (einsum is ~5× slower). The derivatives of the shape
    # functions sum to zero, so J only sees coordinates relative to the element: centring them first keeps
    # the element's size from cancelling against its distance to the origin (ulps of J, not hundreds).
    Xe = Xe - Xe.mean(axis=1, keepdims=True)
    J = np.matmul(_DN_T[None], Xe[:, None])
    det = np.linalg.det(J)
    if np.any(det <= 0.0):
        bad = int(np.argwhere((det <= 0.0).any(axis=1))[0, 0])
        raise ValueError(f"hex20 element {bad} of this chunk is inverted or degenerate (Jacobian ≤ 0)")
    invJ = np.linalg.inv(J)
    dNdx = np.matmul(_DN[None], np.swapaxes(invJ, -1, -2))
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
    conn = np.asarray(conn, dtype=np.int64)
    n_nodes, n_el = coords.shape[0], conn.shape[0]
    # Assemble at node level: every element couples 20 × 20 node pairs, each a 3×3 stiffness block and a
    # scalar mass (the mass only couples equal directions). Summing 400 blocks per element, not 3 600 scalars,
    # and building K as a block (BSR) matrix takes a third of the time of a scalar COO assembly.
    pairs = (conn[:, :, None] * n_nodes + conn[:, None, :]).ravel()  # (n_el·400,) node-pair keys
    keys, slot = np.unique(pairs, return_inverse=True)
    del pairs
    n_pairs = keys.size
    k_blocks = np.zeros((n_pairs, 9))
    m_pairs = np.zeros(n_pairs)
    nn = (_N[:, :, None] * _N[:, None, :]).reshape(_N.shape[0], 400)  # (q, 400): N_n N_m at each Gauss point
    for start in range(0, n_el, chunk):
        c = conn[start : start + chunk]
        e = c.shape[0]
        where = slot[400 * start : 400 * (start + e)]
        dNdx, wdet = _geometry(coords[c])
        G = (dNdx * np.sqrt(wdet)[:, :, None, None]).reshape(e, -1, 60)
        # A[(n, i), (m, j)] = ∫ ∂N_n/∂x_i ∂N_m/∂x_j: one batched GEMM over the Gauss points.
        A = np.matmul(G.transpose(0, 2, 1), G).reshape(e, 20, 3, 20, 3)
        S = A[:, :, 0, :, 0] + A[:, :, 1, :, 1] + A[:, :, 2, :, 2]  # ∫ ∇N_n · ∇N_m, (e, 20, 20)
        # Block entry (i, j) of node pair (n, m): λ A[n,i,m,j] + μ A[n,j,m,i] + μ δ_ij S[n,m].
        for i in range(3):
            for j in range(3):
                kij = lam * A[:, :, i, :, j] + mu * A[:, :, j, :, i]
                if i == j:
                    kij += mu * S
                k_blocks[:, 3 * i + j] += np.bincount(where, weights=kij.ravel(), minlength=n_pairs)
        m_pairs += np.bincount(where, weights=(rho * (wdet @ nn)).ravel(), minlength=n_pairs)
    rows, cols = np.divmod(keys, n_nodes)
    indptr = np.zeros(n_nodes + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n_nodes), out=indptr[1:])
    # Keys are sorted, so the pairs come row by row with sorted columns: both matrices are canonical CSR.
    K = sp.bsr_matrix((k_blocks.reshape(-1, 3, 3), cols, indptr), shape=(3 * n_nodes, 3 * n_nodes)).tocsr()
    # M = M_nodes ⊗ I₃ written out: DOF row 3a + d holds node row a's pairs at columns 3b + d.
    dof_ptr = np.zeros(3 * n_nodes + 1, dtype=np.int64)
    np.cumsum(np.repeat(np.diff(indptr), 3), out=dof_ptr[1:])
    offset = np.arange(n_pairs) - indptr[rows]
    m_cols = np.empty(3 * n_pairs, dtype=K.indices.dtype)
    m_data = np.empty(3 * n_pairs)
    for d in range(3):
        at = dof_ptr[3 * rows + d] + offset
        m_cols[at] = 3 * cols + d
        m_data[at] = m_pairs
    M = sp.csr_matrix((m_data, m_cols, dof_ptr.astype(K.indptr.dtype)), shape=(3 * n_nodes, 3 * n_nodes))
    K.sort_indices()
    M.sort_indices()
    return K, M
