"""Small modal tools shared by the reduced-order models: dense eigen-solves, MAC, MAC-based mode pairing.

``rom`` may not import ``ema`` (design §1), so the MAC and the Hungarian pairing used to compare ROM and FE
modes live here too. Pairing follows design §5: an assignment (Hungarian) on the MAC matrix restricted to a
frequency window, never pairing by index alone.

Dense eigen-solves (:func:`dense_modes`) have two solvers: LAPACK's subset ``eigh`` and a block
shift-invert Lanczos with full re-orthogonalisation and a Rayleigh–Ritz step (docs/rom.md §4). The
Lanczos solver is the faster one from ~500 DOFs when a few tens of eigenpairs are wanted (2.4× at the
1 461-DOF disk–one-blade). It is also the more accurate there: ``eigh`` reduces the pencil with a Cholesky
factor of M, and the reduced mass matrices are ill-conditioned (cond(M) ≈ 2e8 for the default
disk–one-blade), so its relative residuals are 3e-8–1e-7. The Lanczos solver only factors K − σM and
reaches ~4e-9.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.linalg.lapack import dpotrf, dpotrs

__all__ = [
    "append_block",
    "DenseModes",
    "dense_modes",
    "relative_residuals",
    "single_thread_blas",
]

log = logging.getLogger(__name__)

#: Block Lanczos settings (docs/rom.md §4): the first Rayleigh–Ritz step comes after ``_MIN_BLOCKS`` blocks,
#: the last after ``_MAX_BLOCKS + 1``; blocks have at least ``_BLOCK`` columns.
_MIN_BLOCKS = 7
_MAX_BLOCKS = 14
_BLOCK = 16
#: Smallest model for which ``method="auto"`` takes the Lanczos solver (measured crossover, docs/rom.md §4).
_LANCZOS_MIN_N = 500
#: Relative residual at which the elastic Lanczos pairs are accepted.
_LANCZOS_TOL = 1e-7


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
    method : str
        The solver that produced the modes (``"eigh"`` or ``"lanczos"``).
    """

    frequencies_hz: np.ndarray
    shapes: np.ndarray
    n_rigid: int
    method: str = "eigh"


def relative_residuals(
    K: np.ndarray, M: np.ndarray, lam: np.ndarray, X: np.ndarray, sigma: float = 0.0
) -> np.ndarray:
    """Relative residuals ‖K x − λ M x‖ / (‖K x‖ + (|λ| + |σ|) ‖M x‖) of eigenpairs, shape (k,).

    The |σ| term measures rigid-body modes (λ ≈ 0, K x ≈ 0) against the scale of the shifted pencil
    K − σM instead of against round-off; it changes nothing for λ ≫ |σ|.

    Parameters
    ----------
    K, M : ndarray, shape (n, n)
    lam : ndarray, shape (k,)
        Eigenvalues (rad²/s²).
    X : ndarray, shape (n, k)
        Eigenvectors.
    sigma : float
        Shift (rad²/s²), e.g. −(2π · 100 Hz)².
    """
    return _residuals(K @ X, M @ X, lam, sigma)


def _residuals(KX: np.ndarray, MX: np.ndarray, lam: np.ndarray, sigma: float) -> np.ndarray:
    num = np.linalg.norm(KX - MX * lam, axis=0)
    den = np.linalg.norm(KX, axis=0) + (np.abs(lam) + abs(sigma)) * np.linalg.norm(MX, axis=0)
    return num / np.where(den > 0, den, 1.0)


def _rigid(lam: np.ndarray, rigid_lam: float, max_rigid: int) -> np.ndarray:
    """Mask of the rigid-body eigenvalues: at most the first ``max_rigid`` of ascending ``lam`` below ``rigid_lam``."""
    return (lam < rigid_lam) & (np.arange(lam.size) < max_rigid)


@functools.cache
def _blas_controller():
    """One threadpoolctl controller (building one scans the loaded libraries: ~0.4 ms each time)."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - a declared dependency
        return None
    return ThreadpoolController()


def single_thread_blas() -> contextlib.AbstractContextManager:
    """Context that limits BLAS/LAPACK to one thread (threadpoolctl).

    ``ema.poles.single_thread_blas`` is its floor-1 twin: ``rom`` and ``ema`` may not import each other
    (docs/design.md §1, as for ``fileio.atomic_path``).

    Dense reduced models of a few thousand DOFs are memory-bound. On the 2-core reference machine, one
    disk–one-blade solve took 0.12 s steadily with one BLAS thread against 0.17–0.21 s (medians of 15,
    noisy) with two, which spend their time synchronising (docs/rom.md §4). Many solves are better spread
    over processes, one BLAS thread each.
    """
    ctl = _blas_controller()
    if ctl is None:  # pragma: no cover
        return contextlib.nullcontext()
    return ctl.limit(limits=1, user_api="blas")


def append_block(V: np.ndarray, MV: np.ndarray, used: int, X: np.ndarray, M) -> int:
    """Orthonormalise the block ``X`` against ``V[:, :used]`` and append it to V (and M·block to MV), in place.

    Block classical Gram–Schmidt done twice (CGS2: the second pass restores the orthogonality the first loses
    in floating point), then a thin QR. Shared by the block Lanczos solvers (here and ``identify.reanalysis``).

    Parameters
    ----------
    V, MV : ndarray, shape (n, capacity)
        Basis and its mass products; columns ``[:used]`` are filled.
    used : int
    X : ndarray, shape (n, b)
        The new block; overwritten.
    M : ndarray or sparse matrix, shape (n, n)

    Returns
    -------
    int
        ``used + b``.
    """
    b = X.shape[1]
    Vp = V[:, :used]
    for _ in range(2):
        if used:
            X -= Vp @ (Vp.T @ X)
    Q, _ = np.linalg.qr(X)
    V[:, used : used + b] = Q
    MV[:, used : used + b] = M @ Q
    return used + b


def _block_lanczos(
    K: np.ndarray, M: np.ndarray, k: int, shift_hz: float, rigid_lam: float, max_rigid: int, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Lowest ``k`` eigenpairs by block shift-invert Lanczos on one dense Cholesky factor of K − σM.

    σ = −(2π shift_hz)² < 0 keeps K − σM positive definite for free–free models. The Krylov space of
    (K − σM)⁻¹M is built block by block (block size b = max(k, 16), random start with a fixed seed) and
    orthonormalised by block classical Gram–Schmidt done twice, then a Rayleigh–Ritz step on (K, M)
    projected onto it. Every block costs one M·Q product and one pair of triangular solves, both BLAS-3.

    Returns ``(λ, X, max relative residual)`` once every wanted elastic pair (not one of the first
    ``max_rigid`` with λ < ``rigid_lam``) has a residual ≤ ``_LANCZOS_TOL``. Returns ``None`` when K − σM is
    not positive definite, when that does not happen by the last block, or when the model is too small for
    a basis of ``_MIN_BLOCKS`` blocks within n/2 columns; the caller then uses ``eigh``.
    """
    n = K.shape[0]
    b = max(k, _BLOCK)
    # Keep the Krylov basis well below n: a basis that nearly fills the space brings no saving over eigh.
    max_blocks = min(_MAX_BLOCKS, n // (2 * b) - 1)
    if max_blocks < _MIN_BLOCKS:
        return None
    sigma = -((2 * math.pi * shift_hz) ** 2)
    A = np.multiply(M, -sigma)
    A += K
    # A is symmetric: its transpose is the same matrix in Fortran order, so LAPACK factors it in place.
    L, info = dpotrf(A.T, lower=0, overwrite_a=1, clean=0)
    if info != 0:
        log.info("block Lanczos: K − σM is not positive definite (info %d); using eigh", info)
        return None
    rng = np.random.default_rng(seed)
    V = np.empty((n, (max_blocks + 1) * b), order="F")
    MV = np.empty_like(V)
    KV = np.empty_like(V)
    X = rng.standard_normal((n, b))
    used = n_kv = 0
    # Thin products with a ~1 500² matrix are memory-bound: one BLAS thread is as fast and far steadier.
    with single_thread_blas():
        for j in range(max_blocks + 1):
            used = append_block(V, MV, used, X, M)
            if j >= _MIN_BLOCKS - 1:
                KV[:, n_kv:used] = K @ V[:, n_kv:used]
                n_kv = used
                Vu, KVu, MVu = V[:, :used], KV[:, :used], MV[:, :used]
                Kr = Vu.T @ KVu
                Mr = Vu.T @ MVu
                # Symmetrise away round-off; eigh then M-normalises Y against Mr, hence X = V Y against M.
                try:
                    lam, Y = sla.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T), subset_by_index=[0, k - 1],
                                      check_finite=False)
                except np.linalg.LinAlgError:  # a Krylov space that broke down (nearly dependent basis)
                    log.info("block Lanczos: singular projected mass after %d blocks; using eigh", j + 1)
                    return None
                # Only the elastic pairs are judged (and returned by the caller). Rigid-body eigenvalues come
                # out as ±(0.1–0.5) rad²/s² from round-off, which puts a floor of ~3e-7 under their residual
                # on the reduced blade and disk models.
                elastic = ~_rigid(lam, rigid_lam, max_rigid)
                res = float(np.max(_residuals(KVu @ Y[:, elastic], MVu @ Y[:, elastic], lam[elastic], sigma),
                                   initial=0.0))
                if res <= _LANCZOS_TOL:
                    return lam, Vu @ Y, res
            if j < max_blocks:
                X = dpotrs(L, MV[:, used - b : used], lower=0)[0]
    log.info("block Lanczos: residual %.1e after %d blocks; using eigh", res, max_blocks + 1)
    return None


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
    block shift-invert Lanczos on one dense Cholesky factor of K − σM (σ < 0 keeps it positive definite
    for free–free models; n³/3 plus BLAS-3 triangular solves; see the module docstring).
    ``method="auto"`` takes Lanczos from ``_LANCZOS_MIN_N`` DOFs when few modes are wanted, where it is
    faster (docs/rom.md §4); ``eigh`` below. Lanczos falls back to ``eigh`` if it does not converge.

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
        Let ``eigh`` work in place on ``K`` and ``M`` (they may be destroyed; the Lanczos solver leaves them
        alone). Saves two dense copies; for callers that own throw-away matrices
        (:func:`rom.rom_assembly.solve_d1b`).
    """
    n = K.shape[0]
    if K.shape != (n, n) or M.shape != (n, n):
        raise ValueError(f"K and M must be square and of equal shape, got {K.shape} and {M.shape}")
    if n_modes < 1:
        raise ValueError(f"n_modes must be ≥ 1, got {n_modes}")
    k = min(n, n_modes + max_rigid)
    if method not in ("auto", "eigh", "lanczos"):
        raise ValueError(f"method must be 'auto', 'eigh' or 'lanczos', got {method!r}")
    if method == "auto":
        method = "lanczos" if n >= _LANCZOS_MIN_N and k <= n // 30 else "eigh"
    lim = (2 * math.pi * rigid_hz) ** 2
    if method == "lanczos":
        got = _block_lanczos(K, M, k, shift_hz, lim, max_rigid)
        if got is None:
            method = "eigh"
        else:
            vals, vecs, _ = got
    if method == "eigh":
        if overwrite:
            # K and M are symmetric: their transposes are the same matrices in Fortran order, which LAPACK
            # can overwrite without the copy f2py makes of C-ordered input.
            K, M = K.T, M.T
        vals, vecs = sla.eigh(K, M, subset_by_index=[0, k - 1], driver="gvx", check_finite=False,
                              overwrite_a=overwrite, overwrite_b=overwrite)
    rigid = _rigid(vals, lim, max_rigid)
    el = np.flatnonzero(~rigid)[:n_modes]
    freqs = np.sqrt(np.clip(vals[el], 0.0, None)) / (2 * math.pi)
    return DenseModes(freqs, vecs[:, el], int(rigid.sum()), method)
