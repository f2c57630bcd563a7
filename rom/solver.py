"""Modal solver: lowest modes of K φ = ω² M φ by shift-invert Lanczos on a sparse direct factorization.

The factorization backend is chosen by measurement (``benchmarks/fe_modes.py``, docs/design.md §5): MKL
Pardiso (through ``pypardiso``, symmetric positive-definite mode on the upper triangle) for models of at
least :data:`PARDISO_MIN_DOF` DOFs when it is installed, SciPy's SuperLU otherwise (it wins on small models,
where Pardiso's fixed start-up cost dominates). Both sit behind :func:`factorize`, which returns an object
with a ``solve(b)`` method.

The shift is placed *below* zero, σ = −(2π f_shift)², so that ``K − σ M`` is positive definite even for a
free–free component whose ``K`` is singular, and rigid-body modes come out as the lowest eigenvalues.
"""

from __future__ import annotations

import ctypes
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.linalg import eigh as sla_eigh

from .block_krylov import block_krylov_modes

__all__ = [
    "ModalSolution",
    "factorize",
    "available_backends",
    "solve_modes",
    "solve_modes_factored",
    "block_krylov_modes",
    "PARDISO_BLOCK",
    "nodal_diameters",
    "PARDISO_MIN_DOF",
]

log = logging.getLogger(__name__)

# MKL's conditional numerical reproducibility: without it, Pardiso's threaded factorization gives results
# that differ from run to run by ~3e-9 relative (measured on CB-reduced disk–one-blade frequencies, with
# and without iterative refinement); with it they are bit for bit the same. It must be set before MKL
# loads (pypardiso is imported lazily, after this module); a value the user set is kept. Cost: single
# right-hand-side solves take 0.12 s instead of 0.06 s on the 171 k-DOF disk, blocks of 64 the same.
os.environ.setdefault("MKL_CBWR", "AUTO")

#: Vectors per block of :func:`block_krylov_modes` on a Pardiso factor: a solve of 16 right-hand sides costs
#: about 2.5 single ones on the 171 k-DOF disk (docs/rom.md §4.4).
PARDISO_BLOCK = 16

#: Below this size SuperLU is faster than Pardiso here (measured: 8.4k-DOF blade 0.4 s vs 2.4 s, 11.5k-DOF
#: coarse disk 0.6 s vs 1.9 s; the 171k-DOF default disk 57 s / 3.9 GB vs 36 s / 2.7 GB).
PARDISO_MIN_DOF = 30_000


def _name_mkl_runtime() -> None:
    """Tell pypardiso where MKL's runtime library is, from the ``mkl`` package's file list, unless the user did.

    When the loader cannot name ``mkl_rt`` (a pip-installed MKL: its library sits in the environment's ``lib``),
    pypardiso finds it by a recursive glob over the environment, at import and again for every new solver:
    0.9 s each, 1.9 s of a 19 s ``bladetwin run`` of a 4-blade campaign. The package's own record names it at
    once; without one, pypardiso searches as before.
    """
    if "PYPARDISO_MKL_RT" in os.environ:
        return
    from importlib import metadata

    try:
        files = metadata.files("mkl") or []
    except metadata.PackageNotFoundError:
        return
    for f in sorted((f for f in files if f.name.startswith("libmkl_rt")), key=lambda f: len(str(f))):
        path = Path(f.locate()).resolve()
        try:
            ctypes.CDLL(str(path))   # pypardiso loads a named library unguarded: name only one that loads
        except OSError:
            continue
        os.environ["PYPARDISO_MKL_RT"] = str(path)
        return


def available_backends() -> list[str]:
    """Factorization backends usable here, fastest first."""
    out = []
    try:
        _name_mkl_runtime()
        import pypardiso  # noqa: F401

        out.append("pardiso")
    except ImportError:  # pragma: no cover - depends on the platform
        pass
    out.append("superlu")
    return out


class _PardisoFactor:
    """MKL Pardiso Cholesky-type factorization of a symmetric positive-definite matrix (mtype 2).

    Two settings make its solves 4–5× faster than pypardiso's defaults (docs/rom.md §4, measured on the
    171 k-DOF disk: one right-hand side 0.25 s → 0.06 s, a block of 64 3.7 s → 0.73 s):

    * No iterative refinement (``iparm(8) = 0``). pypardiso asks for two steps, and each step is another
      forward/backward solve plus a product with A. For a positive-definite matrix Pardiso perturbs no
      pivots, and the unrefined solution agrees with the refined one to 6e-10 relative.
    * Solves call Pardiso's phase 33 directly with the 1-based index arrays prepared once. pypardiso's
      ``solve`` compares the whole matrix with the factorized one and rebuilds those arrays on every call,
      which costs as much as an unrefined single solve. If pypardiso's internals ever differ, its public
      ``solve`` is used instead.
    """

    def __init__(self, A: sp.spmatrix):
        _name_mkl_runtime()
        import pypardiso

        self._A = sp.triu(A, format="csr").astype(np.float64)
        self._A.sort_indices()
        # size_limit_storage=0: pypardiso keeps a hash, not a copy, for its "same matrix?" check; our solves
        # bypass that check (see the class notes), so a copy of A would only cost memory.
        self._solver = pypardiso.PyPardisoSolver(mtype=2, size_limit_storage=0)
        # pypardiso looks for MKL's runtime library on every new solver, by a recursive glob over the
        # environment when the loader cannot name it (0.9 s here, more than factorizing a 16 k-DOF sector
        # harmonic). Where _name_mkl_runtime found no record of it, name the library this solver found for
        # the solvers that follow.
        path = getattr(self._solver.libmkl, "_name", None)
        if path and "PYPARDISO_MKL_RT" not in os.environ:
            os.environ["PYPARDISO_MKL_RT"] = path
        self._solver.factorize(self._A)
        # After the factorization: with iparm(1) = 0 its first call fills in Pardiso's defaults (iparm(8) = 2).
        self._solver.set_iparm(8, 0)
        self._ia = self._A.indptr.astype(np.int32) + 1
        self._ja = self._A.indices.astype(np.int32) + 1

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=np.float64)
        try:
            return self._solve_phase33(b)
        except AttributeError:  # pragma: no cover - another pypardiso layout
            return self._solver.solve(self._A, b)

    def _solve_phase33(self, b: np.ndarray) -> np.ndarray:
        import ctypes

        s = self._solver
        if b.shape[0] != self._A.shape[0]:
            raise ValueError(f"right-hand side has {b.shape[0]} rows, the matrix {self._A.shape[0]}")
        bf = np.asfortranarray(b)  # Pardiso reads each right-hand side as one column (a no-op for F-order blocks)
        x = np.empty_like(bf)  # written whole by phase 33 (iparm(6) = 0: the solution goes to x, b is kept)
        err = ctypes.c_int32(0)
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        s._mkl_pardiso(
            s.pt.ctypes.data_as(ctypes.POINTER(s._pt_type[0])), ctypes.byref(ctypes.c_int32(1)),
            ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(s.mtype)), ctypes.byref(ctypes.c_int32(33)),
            ctypes.byref(ctypes.c_int32(self._A.shape[0])), self._A.data.ctypes.data_as(f64),
            self._ia.ctypes.data_as(i32), self._ja.ctypes.data_as(i32), s.perm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(1 if bf.ndim == 1 else bf.shape[1])), s.iparm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(0)), bf.ctypes.data_as(f64), x.ctypes.data_as(f64), ctypes.byref(err),
        )
        if err.value != 0:
            raise RuntimeError(f"Pardiso solve failed with error {err.value}")
        return np.ascontiguousarray(x)

    def free(self) -> None:
        self._solver.free_memory(everything=True)


class _SuperLUFactor:
    def __init__(self, A: sp.spmatrix):
        # A is symmetric positive definite (factorize's contract): symmetric mode keeps the minimum-degree
        # ordering of A + Aᵀ on the diagonal, and no pivoting is needed. Partial pivoting broke that ordering
        # and tripled the fill (6-blade coarse assembly, 25 866 DOF: 33.3 → 10.8 M entries, 4.4 → 1.2 s).
        self._lu = sla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                            options={"SymmetricMode": True})

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=np.float64))

    def free(self) -> None:
        self._lu = None


def factorize(A: sp.spmatrix, backend: str = "auto"):
    """Factorize a symmetric positive-definite sparse matrix.

    Parameters
    ----------
    A : sparse matrix, shape (n, n)
    backend : {"auto", "pardiso", "superlu"}

    Returns
    -------
    object with ``solve(b)`` (b of shape (n,) or (n, k)) and ``free()``.
    """
    if backend == "auto":
        backend = "pardiso" if A.shape[0] >= PARDISO_MIN_DOF and "pardiso" in available_backends() else "superlu"
    if backend == "pardiso":
        if "pardiso" not in available_backends():
            raise ValueError("backend 'pardiso' requested but pypardiso is not installed; use 'superlu'")
        return _PardisoFactor(A)
    if backend == "superlu":
        return _SuperLUFactor(A)
    raise ValueError(f"backend must be 'auto', 'pardiso' or 'superlu', got {backend!r}")


@dataclass(frozen=True, eq=False)
class ModalSolution:
    """Lowest modes of an undamped FE model.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_modes,)
        Elastic natural frequencies in Hz, ascending.
    shapes : ndarray, shape (n_dof, n_modes)
        Mass-normalised elastic mode shapes (φᵀ M φ = 1).
    rigid_shapes : ndarray, shape (n_dof, n_rigid)
        Mass-normalised rigid-body modes (zero-frequency eigenvectors).
    """

    frequencies_hz: np.ndarray
    shapes: np.ndarray
    rigid_shapes: np.ndarray

    @property
    def n_rigid(self) -> int:
        return int(self.rigid_shapes.shape[1])

    @property
    def omega2(self) -> np.ndarray:
        """Eigenvalues ω² in (rad/s)², shape (n_modes,)."""
        return (2 * np.pi * self.frequencies_hz) ** 2


def _start_vector(n: int, seed: int = 0) -> np.ndarray:
    """Deterministic Lanczos start vector: the same model always gives the same modes (design §3)."""
    return np.random.default_rng(seed).standard_normal(n)


def solve_modes(
    K: sp.spmatrix,
    M: sp.spmatrix,
    n_modes: int,
    *,
    backend: str = "auto",
    shift_hz: float = 200.0,
    max_rigid: int = 6,
    rigid_ratio: float = 1e-6,
    v0: np.ndarray | None = None,
) -> ModalSolution:
    """Lowest ``n_modes`` elastic modes of (K, M), rigid-body modes reported apart.

    Lanczos (ARPACK) finds one vector per eigenspace in exact arithmetic, so from an unlucky start vector it
    can miss one copy of a repeated eigenvalue: a free body's six-fold rigid-body eigenvalue, or a cyclic
    disk's double nodal-diameter pairs. After the first solve, a cheap block test on the M-orthogonal
    complement of the modes found looks for anything left below the highest mode kept; only if it finds
    something does a deflated Lanczos run add the missed modes, and the check repeats. The result is
    therefore complete whatever the start vector (docs/design.md §8.11). On a Pardiso factorization the first
    solve is the block Krylov run of :func:`block_krylov_modes` (``v0`` its first start vector), whose blocked
    solves are cheaper; the same check follows.

    Parameters
    ----------
    K, M : sparse matrices, shape (n, n)
        Symmetric stiffness (positive semi-definite) and mass (positive definite).
    n_modes : int
        Number of elastic modes wanted.
    backend : str
        Factorization backend, see :func:`factorize`.
    shift_hz : float
        The shift is σ = −(2π shift_hz)², in (rad/s)².
    max_rigid : int
        Most rigid-body modes expected (6 for a free 3-D body); that many extra modes are computed.
    rigid_ratio : float
        A mode is rigid when ω² < rigid_ratio · |σ|. The floor is tied to the shift, not to the highest mode
        computed, so the rigid count does not depend on ``n_modes`` (with the default 1e-6 and shift 200 Hz:
        below 0.2 Hz; round-off leaves rigid eigenvalues near eps · |σ| · cond).
    v0 : ndarray, shape (n,), optional
        Lanczos start vector; default a fixed pseudo-random vector (seed 0).
    """
    n = K.shape[0]
    if K.shape != M.shape or K.shape[0] != K.shape[1]:
        raise ValueError(f"K and M must be square and of equal shape, got {K.shape} and {M.shape}")
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes):
        raise ValueError(f"n_modes must be a positive integer, got {n_modes!r}")
    k = min(n_modes + max_rigid, n - 1)
    sigma = -((2 * math.pi * shift_hz) ** 2)
    fac = factorize((K - sigma * M).tocsr(), backend)
    try:
        start = _start_vector(n) if v0 is None else np.asarray(v0, dtype=np.float64)
        first = _block_first(M, sigma, fac, k, _block_for(fac), v0=start)
        vals, vecs = _complete_modes(K, M, sigma, fac, k, start, max_rigid, first=first)
    finally:
        fac.free()
    rigid = (vals < rigid_ratio * abs(sigma)) & (np.arange(vals.size) < max_rigid)
    elastic = np.flatnonzero(~rigid)[:n_modes]
    freqs = np.sqrt(np.clip(vals[elastic], 0.0, None)) / (2 * np.pi)
    log.info("solve_modes: %d DOF, %d rigid, %d elastic (%.1f–%.1f Hz)", n, rigid.sum(), elastic.size,
             freqs[0] if freqs.size else 0, freqs[-1] if freqs.size else 0)
    return ModalSolution(freqs, vecs[:, elastic], vecs[:, rigid])


def solve_modes_factored(K, M, n_modes: int, fac, *, sigma: float = 0.0, block: int | None = None) -> ModalSolution:
    """Lowest ``n_modes`` modes of a pencil with no rigid-body modes, on a factorization the caller owns.

    For a component with a clamped boundary (K positive definite) the factorization of K itself (σ = 0)
    serves both the shift-invert Lanczos and later static solves: the Craig–Bampton reduction factors its
    171 k-DOF interior once instead of twice.

    Parameters
    ----------
    K, M : sparse matrices, shape (n, n)
        Positive-definite stiffness (N/m) and mass (kg).
    n_modes : int
    fac : object with ``solve(b)``
        A factorization of K − σM (:func:`factorize`); not freed here.
    sigma : float
        The shift of ``fac`` in (rad/s)².
    block : int, optional
        0: ARPACK's single-vector Lanczos. Otherwise the block Krylov method of :func:`block_krylov_modes` with
        this many vectors per block, for a factorization whose blocked solves cost much less per vector than
        single ones (Pardiso: 16 vectors cost 0.35 s against 0.14 s for one on the 170 k-DOF disk interior).
        Default: :data:`PARDISO_BLOCK` on a Pardiso factorization, 0 on any other.
    """
    n = K.shape[0]
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes < n):
        raise ValueError(f"n_modes must be an integer in 1..{n - 1}, got {n_modes!r}")
    block = _block_for(fac) if block is None else block
    if not (isinstance(block, (int, np.integer)) and block >= 0):
        raise ValueError(f"block must be a non-negative integer, got {block!r}")
    first = _block_first(M, sigma, fac, int(n_modes), int(block))
    vals, vecs = _complete_modes(K, M, sigma, fac, int(n_modes), _start_vector(n), 0, first=first)
    freqs = np.sqrt(np.clip(vals, 0.0, None)) / (2 * np.pi)
    return ModalSolution(freqs, vecs, np.zeros((n, 0)))


def _complete_modes(K, M, sigma: float, fac, k: int, v0: np.ndarray, max_rigid_hint: int = 6, max_rounds: int = 4,
                    first: tuple[np.ndarray, np.ndarray] | None = None):
    """The ``k`` lowest eigenpairs by shift-invert Lanczos, checked for missed copies of repeated eigenvalues.

    ``first``: eigenpairs (ω², shapes) already found by another method (:func:`block_krylov_modes`), which
    then only go through the check; None runs ARPACK from ``v0``.

    Returns
    -------
    vals : ndarray, shape (k,)
        Eigenvalues ω² in (rad/s)², ascending.
    vecs : ndarray, shape (n, k)
        Mass-normalised eigenvectors.
    """
    n = K.shape[0]
    if first is None:
        op = sla.LinearOperator((n, n), matvec=fac.solve, dtype=np.float64)
        first = sla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=op, tol=1e-12, v0=v0)
    vals, vecs = _sorted_normalised(*first, M)
    # A few vectors suffice: Lanczos rarely misses more than one copy per cluster, and each round re-checks.
    k_check = min(k, max(max_rigid_hint, 2), n - k - 1)
    for _ in range(max_rounds):
        if k_check < 1 or not anything_missed(K, M, fac, vals, vecs, k_check):
            break
        # Something was missed: find it accurately with Lanczos on the deflated operator, (K − σM)⁻¹ followed
        # by the M-orthogonal projection away from the modes found (its spectrum is the pencil's minus them).
        MV = M @ vecs

        def deflated(b, V=vecs, MV=MV):
            y = fac.solve(b)
            return y - V @ (MV.T @ y)

        dop = sla.LinearOperator((n, n), matvec=deflated, dtype=np.float64)
        start = v0 - vecs @ (MV.T @ v0)
        more, more_vecs = sla.eigsh(K, k=k_check, M=M, sigma=sigma, which="LM", OPinv=dop, tol=1e-12, v0=start)
        missed = more < vals[-1] * (1 - 1e-9) + 1e-9 * abs(sigma)
        if not missed.any():
            break
        log.info("solve_modes: the deflated check found %d missed mode(s) (repeated eigenvalues)", missed.sum())
        vals, vecs = _sorted_normalised(np.r_[vals, more[missed]], np.c_[vecs, more_vecs[:, missed]], M)
        vals, vecs = vals[:k], vecs[:, :k]
    return vals, vecs


def _block_for(fac) -> int:
    """Vectors per block where blocked solves pay (a Pardiso factorization), else 0: ARPACK's single vectors."""
    return PARDISO_BLOCK if isinstance(fac, _PardisoFactor) else 0


def _block_first(M, sigma: float, fac, k: int, block: int, v0: np.ndarray | None = None):
    """:func:`block_krylov_modes`' eigenpairs where ``block`` > 0, for :func:`_complete_modes` to check; None
    (ARPACK then runs) where ``block`` is 0 or the block run did not converge (logged)."""
    if not block:
        return None
    first = block_krylov_modes(M, sigma, fac, k, block, v0=v0)
    if first is None:
        log.info("block Krylov run did not converge (%d modes, blocks of %d); ARPACK instead", k, block)
    return first


def anything_missed(K, M, fac, vals: np.ndarray, vecs: np.ndarray, b: int, iterations: int = 4) -> bool:
    """Whether an eigenvalue below ``vals[-1]`` lies outside ``span(vecs)``: a cheap block test.

    A few steps of deflated subspace iteration with ``b`` deterministic vectors, then Rayleigh–Ritz. Ritz
    values bound the complement's eigenvalues from above, and a missed mode below ``vals[-1]`` is amplified by
    at least (λ_next − σ)/(λ_missed − σ) per step (≈ 40 per step for a missed rigid mode with the default
    shift), so ``iterations · b`` solves replace a second Lanczos run, which needs hundreds in a dense cluster.
    Complex Hermitian pencils (a cyclic disk's harmonics, :mod:`rom.cyclic_sector`) work the same way.
    """
    MVh = (M @ vecs).conj().T if np.iscomplexobj(vecs) else (M @ vecs).T
    X = np.random.default_rng(1).standard_normal((K.shape[0], b))
    for _ in range(iterations):
        X = X - vecs @ (MVh @ X)
        X = np.asarray(fac.solve(M @ X)).reshape(X.shape)
        X = X - vecs @ (MVh @ X)
        X, _ = np.linalg.qr(X)
    Xh = X.conj().T if np.iscomplexobj(X) else X.T
    theta = sla_eigh((Xh @ (K @ X)), (Xh @ (M @ X)), eigvals_only=True)
    return bool(theta[0] < vals[-1] * (1 - 1e-6))


def _sorted_normalised(vals: np.ndarray, vecs: np.ndarray, M) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(vals)
    vals, vecs = vals[order], vecs[:, order]
    # Mass-normalise explicitly (eigsh returns M-orthonormal vectors, but make it exact).
    return vals, vecs / np.sqrt(np.einsum("ij,ij->j", vecs, M @ vecs))


def nodal_diameters(values: np.ndarray) -> np.ndarray:
    """Nodal diameter of each mode from one response per sector.

    Parameters
    ----------
    values : ndarray, shape (n_sectors, n_modes)
        The response of each mode at one equivalent point per sector, sectors in angular order.

    Returns
    -------
    ndarray of int, shape (n_modes,)
        The harmonic index 0..n_sectors//2 with the largest circumferential Fourier amplitude.
    """
    values = np.asarray(values)
    if values.ndim != 2:
        raise ValueError(f"values must have shape (n_sectors, n_modes), got {values.shape}")
    spec = np.abs(np.fft.rfft(values, axis=0))
    return np.argmax(spec, axis=0).astype(int)
