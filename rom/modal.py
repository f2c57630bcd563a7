"""Small modal tools shared by the reduced-order models: dense eigen-solves, MAC, MAC-based mode pairing.

``rom`` may not import ``ema`` (design §1), so the MAC and the Hungarian pairing used to compare ROM and FE
modes live here too. Pairing follows design §5: an assignment (Hungarian) on the MAC matrix restricted to a
frequency window, never pairing by index alone.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from scipy.optimize import linear_sum_assignment

__all__ = ["DenseModes", "dense_modes", "mac", "ModePairing", "pair_modes"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class DenseModes:
    """Lowest elastic modes of a small dense model.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_modes,)
    shapes : ndarray, shape (n, n_modes)
        Mass-normalised eigenvectors (φᵀ M φ = 1).
    n_rigid : int
        Number of rigid-body (below ``rigid_hz``) eigenvalues that were dropped.
    """

    frequencies_hz: np.ndarray
    shapes: np.ndarray
    n_rigid: int


def _dense_shift_invert(K: np.ndarray, M: np.ndarray, k: int, shift_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``k`` eigenpairs by shift-invert Lanczos on a dense Cholesky factor of K − σM, σ = −(2π shift_hz)²."""
    sigma = -((2 * math.pi * shift_hz) ** 2)
    cho = sla.cho_factor(K - sigma * M, lower=True, check_finite=False)
    n = K.shape[0]
    op = spla.LinearOperator((n, n), matvec=lambda x: sla.cho_solve(cho, x, check_finite=False), dtype=np.float64)
    vals, vecs = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=op, tol=1e-13)
    order = np.argsort(vals)
    vals, vecs = vals[order], vecs[:, order]
    vecs = vecs / np.sqrt(np.einsum("ij,ij->j", vecs, M @ vecs))
    return vals, vecs


def dense_modes(
    K: np.ndarray,
    M: np.ndarray,
    n_modes: int,
    *,
    max_rigid: int = 6,
    rigid_hz: float = 1.0,
    method: str = "auto",
    shift_hz: float = 100.0,
    overwrite: bool = False,
) -> DenseModes:
    """Lowest ``n_modes`` elastic modes of a dense symmetric pencil (K, M).

    Two solvers give the same modes: LAPACK's subset ``eigh`` (O(n³) reduction of the whole pencil) and
    shift-invert Lanczos on one dense Cholesky factor of K − σM (σ < 0 keeps it positive definite for
    free–free models; O(n³/3) plus cheap triangular solves). ``method="auto"`` takes Lanczos for larger
    models (n ≥ 2000) when few modes are wanted; below that LAPACK is faster here.

    Parameters
    ----------
    K, M : ndarray, shape (n, n)
        Symmetric stiffness (positive semi-definite) and mass (positive definite) matrices.
    n_modes : int
        Number of elastic modes wanted (fewer are returned when the model is smaller).
    max_rigid : int
        At most this many eigenvalues below ``rigid_hz`` are treated as rigid-body modes and dropped.
    rigid_hz : float
        Frequency (Hz) under which an eigenvalue counts as a rigid-body mode.
    method : {"auto", "eigh", "lanczos"}
    shift_hz : float
        Lanczos shift σ = −(2π shift_hz)².
    overwrite : bool
        Let LAPACK work in place on ``K`` and ``M`` (they are destroyed). Saves two dense copies, about
        10 % of a disk–one-blade solve; for callers that own throw-away matrices (:func:`rom.rom_assembly.solve_d1b`).
    """
    n = K.shape[0]
    if K.shape != (n, n) or M.shape != (n, n):
        raise ValueError(f"K and M must be square and of equal shape, got {K.shape} and {M.shape}")
    if n_modes < 1:
        raise ValueError(f"n_modes must be ≥ 1, got {n_modes}")
    k = min(n, n_modes + max_rigid)
    if method == "auto":
        method = "lanczos" if n >= 2000 and k < n // 10 else "eigh"
    if method == "eigh":
        if overwrite:
            # K and M are symmetric: their transposes are the same matrices in Fortran order, which LAPACK
            # can overwrite without the copy f2py makes of C-ordered input.
            K, M = K.T, M.T
        vals, vecs = sla.eigh(K, M, subset_by_index=[0, k - 1], driver="gvx", check_finite=False,
                              overwrite_a=overwrite, overwrite_b=overwrite)
    elif method == "lanczos":
        vals, vecs = _dense_shift_invert(K, M, k, shift_hz)
    else:
        raise ValueError(f"method must be 'auto', 'eigh' or 'lanczos', got {method!r}")
    lim = (2 * math.pi * rigid_hz) ** 2
    rigid = (vals < lim) & (np.arange(vals.size) < max_rigid)
    el = np.flatnonzero(~rigid)[:n_modes]
    freqs = np.sqrt(np.clip(vals[el], 0.0, None)) / (2 * math.pi)
    return DenseModes(freqs, vecs[:, el], int(rigid.sum()))


def mac(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between the columns of ``A`` (n, a) and ``B`` (n, b); shape (a, b)."""
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    if A.ndim == 1:
        A = A[:, None]
    if B.ndim == 1:
        B = B[:, None]
    if A.shape[0] != B.shape[0]:
        raise ValueError(f"MAC needs shapes on the same DOFs, got {A.shape[0]} and {B.shape[0]} rows")
    num = np.abs(A.T @ B) ** 2
    den = np.outer(np.einsum("ij,ij->j", A, A), np.einsum("ij,ij->j", B, B))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0, num / den, 0.0)
    return out


@dataclass(frozen=True, eq=False)
class ModePairing:
    """Result of :func:`pair_modes`.

    Attributes
    ----------
    ref_index, test_index : ndarray of int, shape (n_pairs,)
        Paired columns, sorted by reference index.
    mac : ndarray, shape (n_pairs,)
        MAC of each pair.
    rel_freq_error : ndarray, shape (n_pairs,)
        (f_test − f_ref) / f_ref of each pair (a fraction).
    """

    ref_index: np.ndarray
    test_index: np.ndarray
    mac: np.ndarray
    rel_freq_error: np.ndarray

    @property
    def max_abs_rel_err(self) -> float:
        return float(np.max(np.abs(self.rel_freq_error))) if self.rel_freq_error.size else float("nan")

    @property
    def min_mac(self) -> float:
        return float(np.min(self.mac)) if self.mac.size else float("nan")


def pair_modes(
    f_ref: np.ndarray,
    shapes_ref: np.ndarray,
    f_test: np.ndarray,
    shapes_test: np.ndarray,
    *,
    window: float = 0.05,
) -> ModePairing:
    """Pair test modes with reference modes by MAC (Hungarian assignment inside a frequency window).

    Every reference mode gets the test mode that maximises the total MAC of the assignment, among test
    modes whose frequency lies within ``window`` (relative) of it; pairs outside the window get MAC −1 in
    the assignment so they are used only when nothing else is left.

    Parameters
    ----------
    f_ref : ndarray, shape (n_ref,)
    shapes_ref : ndarray, shape (n_dof, n_ref)
    f_test : ndarray, shape (n_test,), n_test ≥ n_ref
    shapes_test : ndarray, shape (n_dof, n_test)
    window : float
        Relative frequency window (fraction).
    """
    f_ref, f_test = np.asarray(f_ref, float), np.asarray(f_test, float)
    if f_test.size < f_ref.size:
        raise ValueError(f"need at least as many test modes as reference modes, got {f_test.size} < {f_ref.size}")
    C = mac(shapes_ref, shapes_test)
    rel = (f_test[None, :] - f_ref[:, None]) / f_ref[:, None]
    score = np.where(np.abs(rel) <= window, C, -1.0)
    r, c = linear_sum_assignment(score, maximize=True)
    order = np.argsort(r)
    r, c = r[order], c[order]
    return ModePairing(r, c, C[r, c], rel[r, c])
