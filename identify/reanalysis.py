"""Reanalysis of the disk–one-blade ROM for many blade-mistuning vectors δ (paper §6.3, Eqs. 19, 38).

Blade mistuning (Eq. 19) changes only the blade's free-interface eigenvalues, ``ω_i² → (1 + δ_i) ω_i²``. In the
assembled disk–one-blade pencil (Eq. 22) these are ``k`` diagonal entries of K (the stiffness of the modal
coordinates η_f,1..k), so for one contact pattern pair

    K(δ) = K₀ + E diag(d) Eᵀ,   d_i = δ_i ω_i²,   E = the k unit columns of those coordinates,   M fixed:

a rank-k update. One factorisation per pattern pair then serves every δ of the grid:

1. **Krylov basis.** One Cholesky factor of A₀ = K₀ − σM (σ = −(2π · shift_hz)² < 0, so A₀ is positive
   definite for the free–free assembly) and a block shift-invert Lanczos run whose first block holds
   ``A₀⁻¹ E`` beside random columns. By the Woodbury identity ``(K(δ) − σM)⁻¹ = A₀⁻¹ − A₀⁻¹ E W Eᵀ A₀⁻¹``, so the
   Krylov space of the mistuned operator from any start block lies inside this one: a single basis serves
   every δ as well as a Lanczos run on that δ would. (Small models, where a basis of a few blocks would fill
   half the space, take all modes from one dense ``eigh`` instead.)
2. **Small parametric model.** Rayleigh–Ritz at δ = 0 gives Ritz pairs (θ, y), M-orthonormal. The eigenvectors
   of K(δ) satisfy ``(K₀ − λM) x = −E diag(d) Eᵀ x``: besides the low modes, x holds the *far* Ritz vectors
   only through ``(Θ_F − λ)⁻¹ U_F g`` (U = Eᵀ Y, g a k-vector). That function of λ is smooth over the wanted
   band, so a few poles τ_q, blocks ``(Θ_F − τ_q)⁻¹ U_F``, capture it. The basis Z = [low Ritz vectors,
   orthonormalised pole blocks] has s ≈ n_low + n_poles · k columns (≈ 35), M-orthonormal, and in it
   ``H(δ) = H₀ + U_z diag(d) U_zᵀ`` is a standard symmetric s × s eigenproblem: a batch of them costs one
   ``numpy.linalg.eigh`` call.
3. **Error bound in the full ROM space.** For each Ritz pair (λ, x) of H(δ) the residual
   ``r = K(δ) x − λ M x`` is a combination of the columns of [K₀ Y_z, M Y_z, E], whose A₀⁻¹-weighted R factor is
   computed once per pair; so ‖r‖ in the A₀⁻¹ norm costs an s-sized product per mode. Writing the pencil as
   the standard problem of A_δ^(−1/2) M A_δ^(−1/2) (A_δ = K(δ) − σM) gives a rigorous bound (Rayleigh-quotient
   residual theorem, no gap assumption): some eigenvalue λ* satisfies
   ``|λ* − λ| ≤ (λ − σ) ρ / (1 − ρ)`` with ``ρ = ‖r‖_{A_δ⁻¹} / sqrt(λ − σ)``, and
   ``‖r‖²_{A_δ⁻¹} ≤ ‖r‖²_{A₀⁻¹} / (1 + γ)``, γ the least eigenvalue of ``S^½ diag(d) S^½``, S = Eᵀ A₀⁻¹ E.
   :func:`solve_ritz` returns that bound on the relative *frequency* error of every mode; callers fall back
   to a direct solve where it exceeds their tolerance. The bound assumes the Ritz value's nearest
   eigenvalue is the one of the same rank. A mode missing from the basis would break that, which would
   need a mode from above the basis' buffer to drop below the wanted band. δ of a few per cent moves
   eigenvalues far less than that (the basis keeps ``n_buffer`` spare modes above the wanted ones).

Everything is float64 and deterministic (fixed-seed start block). All functions are pure; no ``rom`` model
objects appear here, only the assembled matrices.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.linalg.lapack import dpotrf, dpotrs

from rom.modal import append_block, single_thread_blas

__all__ = ["RitzModel", "RitzSolution", "ritz_model", "solve_ritz", "frequency_error_bound"]

log = logging.getLogger(__name__)

#: Models smaller than this take all modes from one dense ``eigh`` (rom.modal uses the same crossover).
_KRYLOV_MIN_N = 500


@dataclass(frozen=True, eq=False)
class RitzModel:
    """δ-parametric reduced model of one disk–one-blade pencil (one contact pattern pair).

    Coordinates ``z`` (length s) are M-orthonormal: the first ``n_low`` are the Ritz vectors at δ = 0 in
    ascending order (rigid-body ones first), the rest span the pole blocks of the far Ritz vectors.

    Attributes
    ----------
    H0 : ndarray, shape (s, s)
        Projected stiffness at δ = 0 (rad²/s²); the projected mass is the identity.
    U : ndarray, shape (s, k)
        Projected update columns Z ᵀ Yᵀ E: ``H(δ) = H0 + U diag(δ ω²) Uᵀ``.
    omega2 : ndarray, shape (k,)
        Tuned blade eigenvalues ω_i² (rad²/s²) of the updated coordinates (Eq. 19).
    R : ndarray, shape (2s + k, 2s + k)
        R factor of A₀^(−½)[K₀ Y_z, M Y_z, E] (residual norms in the A₀⁻¹ norm).
    S_half : ndarray, shape (k, k)
        Symmetric square root of S = Eᵀ A₀⁻¹ E.
    sigma : float
        Shift σ (rad²/s², negative).
    n_rigid : int
        Rigid-body Ritz values (dropped; δ does not move them).
    n_low : int
        Leading z coordinates that are δ = 0 Ritz vectors.
    n_cand : int
        Elastic modes returned per δ (the candidates for tracking).
    shapes0 : ndarray, shape (n, n_cand)
        Elastic Ritz vectors at δ = 0 in the full ROM space, M-normalised (the pair's δ = 0 modes).
    mass_shapes0 : ndarray, shape (n, n_cand)
        ``M @ shapes0`` (MAC of a direct solve against the δ = 0 modes).
    bound0 : ndarray, shape (n_cand,)
        Frequency error bound of the δ = 0 modes (relative).
    method : str
        ``"krylov"`` or ``"eigh"``: how the Ritz basis was made.
    n_basis : int
        Size of that Ritz basis.
    basis_rows : ndarray, shape (n_rows, s), or None
        The rows ``rows`` of :func:`ritz_model` of the M-orthonormal basis Z: a mode's entries there are
        ``basis_rows @ w`` for its coordinates w (:attr:`RitzSolution.coords`).
    """

    H0: np.ndarray
    U: np.ndarray
    omega2: np.ndarray
    R: np.ndarray
    S_half: np.ndarray
    sigma: float
    n_rigid: int
    n_low: int
    n_cand: int
    shapes0: np.ndarray
    mass_shapes0: np.ndarray
    bound0: np.ndarray
    method: str
    n_basis: int
    basis_rows: np.ndarray | None = None

    @property
    def s(self) -> int:
        return int(self.H0.shape[0])

    @property
    def frequencies0_hz(self) -> np.ndarray:
        """Elastic frequencies (Hz) at δ = 0, shape (n_cand,)."""
        lam = np.diag(self.H0)[self.n_rigid : self.n_rigid + self.n_cand]
        return np.sqrt(np.clip(lam, 0.0, None)) / (2 * math.pi)


@dataclass(frozen=True, eq=False)
class RitzSolution:
    """Elastic modes of a :class:`RitzModel` for a batch of δ.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_samples, n_cand)
        Ascending per sample.
    mac0 : ndarray, shape (n_samples, n_cand, n_cand)
        ``mac0[t, a, b]``: MAC (mass-weighted) between the pair's δ = 0 mode ``a`` and the sample's mode ``b``.
    bound : ndarray, shape (n_samples, n_cand)
        Upper bound on each frequency's relative error against the exact ROM eigenvalue (``inf`` where the
        shifted stiffness of that δ is not positive definite).
    coords : ndarray, shape (n_samples, s, n_cand), or None
        Each mode's coordinates w in the model's basis (unit norm: the mode is M-normalised), with
        ``coords=True`` of :func:`solve_ritz`.
    """

    frequencies_hz: np.ndarray
    mac0: np.ndarray
    bound: np.ndarray
    coords: np.ndarray | None = None


def frequency_error_bound(res_norm: np.ndarray, lam: np.ndarray, sigma: float, gamma: np.ndarray) -> np.ndarray:
    """Bound on the relative frequency error of Ritz pairs from their A₀⁻¹-norm residuals (module docstring).

    Parameters
    ----------
    res_norm : ndarray, shape (..., m)
        ‖K(δ) x − λ M x‖ in the A₀⁻¹ norm, x M-normalised.
    lam : ndarray, shape (..., m)
        Ritz values λ (rad²/s²), > 0.
    sigma : float
        Shift (rad²/s², negative).
    gamma : ndarray, shape (...)
        Least eigenvalue of S^½ diag(d) S^½ per sample (0 for δ = 0).

    Returns
    -------
    ndarray, shape (..., m)
        |f* − f| / f ≤ this, for the eigenvalue λ* nearest λ; ``inf`` where it cannot be bounded.
    """
    lam = np.asarray(lam, dtype=np.float64)
    g = 1.0 + np.minimum(np.asarray(gamma, dtype=np.float64), 0.0)[..., None]
    nu = lam - sigma
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(g > 0, res_norm / np.sqrt(np.clip(g, 1e-300, None) * nu), np.inf)
        rel_lam = np.where(rho < 1, nu * rho / (1 - rho) / lam, np.inf)
        # |sqrt(1 + e) − 1| ≤ e / (1 + sqrt(1 − e)) for |e| < 1 (the worse of the two signs).
        out = np.where(rel_lam < 1, rel_lam / (1 + np.sqrt(np.clip(1 - rel_lam, 0, None))), np.inf)
    return np.where(lam > 0, out, np.inf)


def _cholesky_shifted(K: np.ndarray, M: np.ndarray, sigma: float) -> np.ndarray:
    """Upper Cholesky factor of K − σM (Fortran-ordered for LAPACK)."""
    A = np.multiply(M, -sigma)
    A += K
    U, info = dpotrf(A.T, lower=0, overwrite_a=1, clean=1)
    if info != 0:
        raise ValueError(f"K − σM is not positive definite at σ = {sigma:.4g} rad²/s² (potrf info {info})")
    return U


def _krylov_basis(K, M, Uf, E, block, n_wanted, min_blocks, max_blocks, sigma, tol, rigid_lam, max_rigid, seed):
    """Block shift-invert Lanczos with ``A₀⁻¹E`` in its first block; Ritz pairs of the whole basis.

    Stops after the first block count ≥ ``min_blocks`` at which the ``n_wanted`` lowest elastic Ritz pairs have
    frequency bounds ≤ ``tol`` (or at ``max_blocks``). Returns (θ, Y, KY, MY), Y = V C the Ritz vectors.
    """
    n = K.shape[0]
    k = E.shape[1]
    rng = np.random.default_rng(seed)
    X = dpotrs(Uf, np.hstack([E, M @ rng.standard_normal((n, block - k))]), lower=0)[0]
    V = np.empty((n, max_blocks * block), order="F")
    MV = np.empty_like(V)
    KV = np.empty_like(V)
    used = n_kv = 0
    for j in range(max_blocks):
        used = append_block(V, MV, used, X, M)
        if j + 1 >= min_blocks:
            KV[:, n_kv:used] = K @ V[:, n_kv:used]
            n_kv = used
            Vu, KVu, MVu = V[:, :used], KV[:, :used], MV[:, :used]
            Kr, Mr = Vu.T @ KVu, Vu.T @ MVu
            theta, C = sla.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T), check_finite=False)
            n_rig = int(((theta < rigid_lam) & (np.arange(theta.size) < max_rigid)).sum())
            w = slice(n_rig, n_rig + n_wanted)
            Rw = KVu @ C[:, w] - (MVu @ C[:, w]) * theta[w]
            res = np.linalg.norm(sla.solve_triangular(Uf, Rw, trans="T", check_finite=False), axis=0)
            bound = frequency_error_bound(res, theta[w], sigma, np.zeros(()))
            if j + 1 == max_blocks or bound.max() <= tol:
                log.debug("krylov basis: %d blocks of %d, max δ=0 bound %.2e", j + 1, block, bound.max())
                return theta, Vu @ C, KVu @ C, MVu @ C
        X = dpotrs(Uf, MV[:, used - block : used], lower=0)[0]
    raise AssertionError("unreachable")  # pragma: no cover


def _check_ritz_inputs(K, M, update_index, omega2, method: str, block: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`ritz_model`'s checks; returns the update coordinates (int64) and their tuned ω² (float64)."""
    n = K.shape[0]
    if K.shape != (n, n) or M.shape != (n, n):
        raise ValueError(f"K and M must be square and of equal shape, got {K.shape} and {M.shape}")
    idx = np.asarray(update_index, dtype=np.int64).ravel()
    w2 = np.asarray(omega2, dtype=np.float64).ravel()
    k = idx.size
    if w2.size != k or k == 0 or idx.min() < 0 or idx.max() >= n or np.unique(idx).size != k:
        raise ValueError(f"update_index must be {w2.size} distinct coordinates in 0..{n - 1}, got {idx.tolist()}")
    if method not in ("auto", "krylov", "eigh"):
        raise ValueError(f"method must be 'auto', 'krylov' or 'eigh', got {method!r}")
    if block <= k:
        raise ValueError(f"block must exceed the update rank {k}, got {block}")
    return idx, w2


def _eigh_basis(K: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, ...]:
    """Every mode of the pencil by dense ``eigh``: (θ, Y, K Y, M Y)."""
    theta, Y = sla.eigh(K, M, check_finite=False)
    return theta, Y, K @ Y, M @ Y


def _project(Uf, E, idx, theta, Y, KY, MY, n_low: int, n_top: int, n_poles: int, rows):
    """Steps 2–3 of the module docstring: the low Ritz vectors kept, the far ones compressed to pole blocks.

    ``n_top`` is the number of Ritz values up to the last wanted mode (rigid ones included). Returns the
    projected stiffness ``H0`` (s, s), the update rows ``U`` (s, k), the residual factor ``R``, ``S½`` and
    the basis' ``rows`` (None when not asked).
    """
    Ur = Y[idx, :].T  # (r, k)
    # Pole blocks of the far Ritz vectors, poles spread over [0, 1.1 λ_max] of the wanted band.
    F = np.arange(n_low, theta.size)
    lam_top = 1.1 * theta[n_top - 1]
    taus = np.linspace(0.0, lam_top, n_poles) if n_poles > 1 else np.array([0.5 * lam_top])
    blocks = np.hstack([Ur[F] / (theta[F] - t)[:, None] for t in taus])
    QF, RF = np.linalg.qr(blocks)
    # Drop directions the far space cannot hold (a far set narrower than the pole blocks).
    keep = np.abs(np.diag(RF)) > 1e-12 * max(np.abs(np.diag(RF)).max(initial=0.0), 1e-300)
    QF = QF[:, keep]
    s = n_low + QF.shape[1]
    H0 = np.zeros((s, s))
    H0[np.arange(n_low), np.arange(n_low)] = theta[:n_low]
    Hf = (QF.T * theta[F]) @ QF
    H0[n_low:, n_low:] = 0.5 * (Hf + Hf.T)
    Uz = np.vstack([Ur[:n_low], QF.T @ Ur[F]])
    KYz = np.hstack([KY[:, :n_low], KY[:, F] @ QF])
    MYz = np.hstack([MY[:, :n_low], MY[:, F] @ QF])
    G = sla.solve_triangular(Uf, np.hstack([KYz, MYz, E]), trans="T", check_finite=False)
    R = np.linalg.qr(G, mode="r")
    CE = dpotrs(Uf, E, lower=0)[0]
    S = CE[idx]
    ev, evec = np.linalg.eigh(0.5 * (S + S.T))
    S_half = (evec * np.sqrt(np.clip(ev, 0.0, None))) @ evec.T
    Zr = None if rows is None else np.hstack([Y[rows, :n_low], Y[rows][:, F] @ QF])
    return H0, Uz, R, S_half, Zr


def ritz_model(K: np.ndarray, M: np.ndarray, update_index, omega2, n_cand: int, *, method: str = "auto",
               shift_hz: float = 100.0, block: int = 24, min_blocks: int = 4, max_blocks: int = 10,
               basis_tol: float = 1e-6, n_check: int | None = None, n_buffer: int = 6, n_poles: int = 3,
               max_rigid: int = 6, rigid_hz: float = 1.0, seed: int = 0, rows=None) -> RitzModel:
    """Build the δ-parametric reduced model of one pencil (module docstring, steps 1–3).

    Parameters
    ----------
    K, M : ndarray, shape (n, n)
        The tuned (δ = 0) disk–one-blade stiffness and mass (Eq. 22), symmetric; not modified.
    update_index : array_like of int, shape (k,)
        Coordinates whose diagonal stiffness is ``(1 + δ_i) ω_i²`` (the blade modal coordinates η_f,1..k).
    omega2 : array_like, shape (k,)
        Tuned ω_i² (rad²/s²) of those coordinates.
    n_cand : int
        Elastic modes wanted per δ.
    method : {"auto", "krylov", "eigh"}
        Ritz basis: block Krylov (from 500 DOFs with ``"auto"``) or all modes by dense ``eigh``.
    shift_hz : float
        σ = −(2π shift_hz)².
    block, min_blocks, max_blocks : int
        Krylov block width (≥ k + 1) and block counts.
    basis_tol : float
        Frequency bound the first ``n_check`` δ = 0 modes must meet before the Krylov run stops. At the
        default level 4 blocks of 24 gave 8e-6 and 5 blocks 6e-8, for δ = 0 and for a 6³ δ grid alike.
    n_check : int, optional
        Elastic modes held to ``basis_tol`` (default ``n_cand``; the extra candidates only serve tracking).
    n_buffer : int
        Spare Ritz vectors kept in the low set above the wanted ones.
    n_poles : int
        Pole blocks for the far Ritz vectors (module docstring, step 2).
    max_rigid, rigid_hz : int, float
        At most ``max_rigid`` Ritz values below ``rigid_hz`` (Hz) are rigid-body modes (as
        :func:`rom.modal.dense_modes`).
    seed : int
        Seed of the random start columns.
    rows : array_like of int, optional
        ROM coordinates whose entries of every mode the caller needs (:attr:`RitzModel.basis_rows`).

    Returns
    -------
    RitzModel
    """
    n, (idx, w2) = K.shape[0], _check_ritz_inputs(K, M, update_index, omega2, method, block)
    sigma, rigid_lam = -((2 * math.pi * shift_hz) ** 2), (2 * math.pi * rigid_hz) ** 2
    n_low = max_rigid + n_cand + n_buffer
    if method == "auto":
        method = "krylov" if n >= _KRYLOV_MIN_N and max_blocks * block <= n // 2 else "eigh"
    E = np.zeros((n, idx.size))
    E[idx, np.arange(idx.size)] = 1.0
    with single_thread_blas():
        Uf = _cholesky_shifted(K, M, sigma)
        n_check = n_cand if n_check is None else min(int(n_check), n_cand)
        theta, Y, KY, MY = (_krylov_basis(K, M, Uf, E, block, n_check, min_blocks, max_blocks, sigma, basis_tol,
                                          rigid_lam, max_rigid, seed) if method == "krylov" else _eigh_basis(K, M))
        r = theta.size
        if n_low + 1 > r:
            raise ValueError(f"the Ritz basis ({r} vectors) is too small for {n_cand} modes and {n_buffer} spare")
        n_rigid = int(((theta < rigid_lam) & (np.arange(r) < max_rigid)).sum())
        rows = None if rows is None else np.asarray(rows, np.int64).ravel()
        H0, Uz, R, S_half, Zr = _project(Uf, E, idx, theta, Y, KY, MY, n_low, n_rigid + n_cand, n_poles, rows)
    s, cand = H0.shape[0], slice(n_rigid, n_rigid + n_cand)
    res0 = np.linalg.norm(R[:, :s][:, cand] - R[:, s : 2 * s][:, cand] * theta[cand], axis=0)
    bound0 = frequency_error_bound(res0, theta[cand], sigma, np.zeros(()))
    return RitzModel(H0=H0, U=Uz, omega2=w2, R=R, S_half=S_half, sigma=sigma, n_rigid=n_rigid, n_low=n_low,
                     n_cand=n_cand, shapes0=np.ascontiguousarray(Y[:, cand]),
                     mass_shapes0=np.ascontiguousarray(MY[:, cand]), bound0=bound0, method=method, n_basis=r,
                     basis_rows=Zr)


def solve_ritz(model: RitzModel, deltas, *, coords: bool = False) -> RitzSolution:
    """Elastic modes of ``model`` for each δ row (one batched ``eigh`` of s × s matrices).

    Parameters
    ----------
    model : RitzModel
    deltas : array_like, shape (n_samples, k)
        Relative blade mistuning of the updated modes (Eq. 19; 0.01 = 1 %).
    coords : bool
        Also return each mode's coordinates (:attr:`RitzSolution.coords`).

    Returns
    -------
    RitzSolution
    """
    D = np.atleast_2d(np.asarray(deltas, dtype=np.float64))
    k = model.omega2.size
    if D.ndim != 2 or D.shape[1] != k:
        raise ValueError(f"deltas must have shape (n_samples, {k}), got {D.shape}")
    d = D * model.omega2  # (t, k)
    s, nr, nc = model.s, model.n_rigid, model.n_cand
    with single_thread_blas():
        H = model.H0 + np.einsum("ik,tk,jk->tij", model.U, d, model.U, optimize=True)
        lam, W = np.linalg.eigh(H)
        lam, W = lam[:, nr : nr + nc], W[:, :, nr : nr + nc]
        # Residual coefficients on [K₀Y_z, MY_z, E]: r = K₀x − λMx + E diag(d) Eᵀx, Eᵀx = Uᵀw.
        xe = np.einsum("ik,til->tkl", model.U, W, optimize=True)
        C = np.concatenate([W, -lam[:, None, :] * W, d[:, :, None] * xe], axis=1)  # (t, 2s + k, nc)
        res = np.linalg.norm(np.einsum("ij,tjl->til", model.R, C, optimize=True), axis=1)
        Sd = np.einsum("ij,tj,jl->til", model.S_half, d, model.S_half, optimize=True)
        gamma = np.linalg.eigvalsh(Sd)[:, 0]
    bound = frequency_error_bound(res, lam, model.sigma, gamma)
    mac0 = W[:, nr : nr + nc, :] ** 2  # the δ = 0 modes are unit z coordinates nr..nr+nc−1
    if s < nr + nc:  # pragma: no cover - ritz_model keeps n_low ≥ nr + nc
        raise AssertionError("Ritz model smaller than its candidates")
    return RitzSolution(np.sqrt(np.clip(lam, 0.0, None)) / (2 * math.pi), mac0, bound, W if coords else None)
