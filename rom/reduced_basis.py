"""Reduced-basis model of the disk–one-blade ROM on contact springs, with certified frequency bounds (issue 46).

Full model :class:`rom.spring_assembly.SpringD1B`: K(θ) = K₀ + E S(θ) Eᵀ, affine in the pattern p and the
blade mistuning δ (θ = [p; δ]), M fixed. Reductor :func:`reduce_spring_d1b`: a POD of full-order eigenvectors
at training patterns, in the bonded joint's energy norm, gives an M-orthonormal V (n × r); the offline stage
stores VᵀK₀V, Z = EᵀV and the residual's factor. Reduced model :class:`ReducedBasis`: :func:`evaluate`
assembles K_r(θ) = VᵀK₀V + Zᵀ S(θ) Z for each pattern, solves the r × r eigenproblem, certifies every Ritz
frequency and answers by a direct solve where the certificate exceeds the tolerance.

Certificate (:func:`frequency_bounds`): residuals r = K(θ)v − λ̃Mv in the A⁻¹ norm, A = K(θ) − σM, σ < 0
(as :mod:`identify.reanalysis` does for δ). The M⁻¹ norm gives the same theorem, but the stiff springs'
high-frequency content makes ‖r‖_{M⁻¹} of the order of λ̃ even where λ̃ is right to 1e-6 (coarse model, r = 130:
median bound 1.2 against a median error of 7e-6). Springs only stiffen, so A(θ) ⪰ A₀ = K₀ − σM at every pattern
(a negative δ is allowed for by a factor 1 + γ), and the A₀⁻¹ norm, whose factor is computed once, bounds
the A(θ)⁻¹ norm from above.

Reach (measured, ``benchmarks/reduced_basis.py``): over random patterns the eigenvectors span about as many
directions as the springs have (3 per flank node), because each node's spring shapes the root locally. The
3×7 grid (42 nodes, n = 411) certifies 5e-5 on every held-out pattern from r ≈ 160; the default 7×31 grid
(434 nodes, n = 2 763) needs r ≈ 1 500 for that, which costs more than a direct solve; at r = 845, 71 ms per
evaluation, 99.5 % of held-out patterns had a bound above 5e-5 (median bound 5e-5, median error 6e-6).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from scipy.ndimage import gaussian_filter

from .contact import ContactPattern
from .fe_assembly import AssemblyModes
from .modal import dense_modes, single_thread_blas
from .spring_assembly import TWO_PI, SpringD1B, solve_spring_d1b

__all__ = ["ReducedBasis", "RBModes", "plausible_patterns", "reduce_spring_d1b", "evaluate", "frequency_bounds"]

log = logging.getLogger(__name__)



def plausible_patterns(grid: tuple[int, int], n: int, *, seed: int = 0,
                       fraction: tuple[float, float] = (0.2, 0.9)) -> list[ContactPattern]:
    """``n`` random contact patterns made of patches, as a joint's pressure field gives (deterministic).

    Each flank's map is a smooth random field (correlation length 10–40 % of the flank), a misalignment
    tilt and a node-scale roughness that rags the patches' edges (as ``lab.patterns`` models the rig's truth);
    contact is where the map exceeds the level that gives a contact area fraction drawn from ``fraction``
    over both flanks. Draws that :class:`~rom.contact.ContactPattern` refuses (a hinge) are drawn again.
    """
    rows, cols = int(grid[0]), int(grid[1])
    if not 0.0 < fraction[0] <= fraction[1] <= 1.0:
        raise ValueError(f"fraction must be a range inside (0, 1], got {fraction}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"n must be a non-negative integer, got {n!r}")
    rng = np.random.default_rng(seed)
    xi, eta = np.meshgrid(np.linspace(-0.5, 0.5, rows), np.linspace(-0.5, 0.5, cols), indexing="ij")
    out: list[ContactPattern] = []
    while len(out) < n:
        ell = rng.uniform(0.1, 0.4)
        z = gaussian_filter(rng.standard_normal((2, rows, cols)), (0, ell * rows, ell * cols), mode="reflect")
        z /= z.std(axis=(1, 2), keepdims=True) + 1e-300
        tilt = rng.normal(0.0, 1.0, (2, 2, 1, 1))  # per flank: axial and radial pressure gradients
        z += tilt[:, 0] * xi + tilt[:, 1] * eta + rng.normal(0.0, 0.5, (2, 1, 1)) + 0.3 * rng.standard_normal(z.shape)
        level = np.quantile(z, 1.0 - rng.uniform(*fraction))
        try:
            out.append(ContactPattern(z[0] > level, z[1] > level))
        except ValueError:
            continue
    return out


@dataclass(frozen=True, eq=False)
class ReducedBasis:
    """The reduced model of a :class:`SpringD1B` on an M-orthonormal basis V (n × r), with its offline blocks.

    Attributes
    ----------
    model : SpringD1B
        The full model (fallbacks, reconstruction ``V @ y``).
    V : ndarray, shape (n, r)
        VᵀMV = I, M-orthogonal to the rigid-body modes.
    K0r, KFr : ndarray, shape (r, r)
        VᵀK₀V and Vᵀ(K₀ + Σ_all K_i)V (N/m).
    Z : ndarray, shape (3 n_nodes + m, r)
        EᵀV: spring elongations and blade modal amplitudes of the basis vectors.
    R : ndarray, shape (≤ n, 2r + 3 n_nodes + m)
        Triangular factor of L⁻¹[A₀V, MV, E] (A₀ = K₀ − σM = LLᵀ): a Ritz pair's residual
        r = A₀Vy − νMVy + Eu has ‖r‖_{A₀⁻¹} = ‖R [y; −νy; u]‖, free of the cancellation of Gram matrices.
    G_delta : ndarray, shape (m, m)
        The δ block of EᵀA₀⁻¹E (for negative δ).
    out_V : ndarray, shape (n_meas, r)
    sigma : float
        σ < 0 (rad²/s²).
    n_guard : int
        Ritz pairs computed above the wanted ones (their intervals give the top wanted mode its gap).
    meta : dict
        Training record.
    """

    model: SpringD1B
    V: np.ndarray
    K0r: np.ndarray
    KFr: np.ndarray
    Z: np.ndarray
    R: np.ndarray
    G_delta: np.ndarray
    out_V: np.ndarray
    sigma: float
    n_guard: int
    meta: dict = field(default_factory=dict)

    @property
    def r(self) -> int:
        return int(self.V.shape[1])


@dataclass(frozen=True, eq=False)
class RBModes:
    """Modes of a batch of patterns from :func:`evaluate`.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_patterns, n_modes)
        Elastic frequencies (Hz): Ritz values, or the direct solve's where ``fallback``.
    bound : ndarray, shape (n_patterns, n_modes)
        Certified bound on |f̃ − f| / f of each Ritz frequency against the full model's mode of the same rank
        (:func:`frequency_bounds`; ``inf`` where none holds). Kept on fallback rows: it says why.
    kb_bound : ndarray, shape (n_patterns, n_modes)
        The unconditional bound: the full model has *some* eigenfrequency this close (relative).
    fallback : ndarray of bool, shape (n_patterns,)
        Rows answered by a direct full-order solve because a bound exceeded ``tol``.
    meas_shapes : ndarray, shape (n_patterns, n_meas, n_modes), or None
        Mass-normalised shapes at the measurement DOFs (Ritz vectors, or the direct solve's).
    meas_labels : list
    """

    frequencies_hz: np.ndarray
    bound: np.ndarray
    kb_bound: np.ndarray
    fallback: np.ndarray
    meas_shapes: np.ndarray | None
    meas_labels: list


def reduce_spring_d1b(
    model: SpringD1B,
    patterns: Iterable[ContactPattern] | Callable[..., Iterable[ContactPattern]] | None = None,
    *,
    n_modes: int = 10,
    rank: int | None = None,
    pod_tol: float = 1e-9,
    n_train: int = 60,
    n_guard: int = 2,
    seed: int = 0,
    shift_hz: float = 100.0,
) -> ReducedBasis:
    """Reduced basis from full-order eigenvectors at training patterns (POD in the bonded energy norm).

    Parameters
    ----------
    model : SpringD1B
    patterns : iterable of ContactPattern, or callable ``(grid, n, seed) -> iterable``, optional
        Training patterns (default :func:`plausible_patterns` with ``n_train`` and ``seed``).
    n_modes : int
        Elastic modes the basis serves; each snapshot holds ``n_modes + n_guard + 2`` of them.
    rank : int, optional
        Basis size r; default: the POD modes until the share of the snapshots' energy left out is ≤ ``pod_tol``.
    shift_hz : float
        σ = −(2π shift_hz)² of the certificate's norm and of the POD's (K − σM) energy norm.

    Returns
    -------
    ReducedBasis
    """
    if not (isinstance(n_modes, (int, np.integer)) and n_modes >= 1):
        raise ValueError(f"n_modes must be a positive integer, got {n_modes!r}")
    if patterns is None:
        patterns = plausible_patterns(model.grid, n_train, seed=seed)
    elif callable(patterns):
        patterns = patterns(model.grid, n_train, seed)
    pats = list(patterns)
    if not pats:
        raise ValueError("reduce_spring_d1b needs at least one training pattern")
    sigma = -((TWO_PI * shift_hz) ** 2)
    n_snap = n_modes + n_guard + 2
    with single_thread_blas():
        snaps = [_full_modes(model, model.parameters(p), n_snap)[1] for p in pats]
    X = np.hstack(snaps)
    X -= model.rigid @ (model.rigid.T @ (model.M @ X))
    # POD in the energy norm of the bonded joint: eigenvalue errors are energy-norm errors squared.
    bonded = np.r_[np.ones(model.n_nodes), np.zeros(model.m)]
    L = sla.cholesky(model.K(bonded) - sigma * model.M, lower=True)
    Y = L.T @ X
    Y /= np.linalg.norm(Y, axis=0)
    U, s, _ = np.linalg.svd(Y, full_matrices=False)
    if rank is None:
        tail = np.cumsum((s**2)[::-1])[::-1] / np.sum(s**2)
        rank = int(np.count_nonzero(tail > pod_tol))
    if not (isinstance(rank, (int, np.integer)) and n_modes + n_guard <= rank <= U.shape[1]):
        raise ValueError(f"rank must be an integer in {n_modes + n_guard}..{U.shape[1]} (the snapshots), got {rank!r}")
    V = sla.solve_triangular(L.T, U[:, :rank], lower=False)
    meta = {"n_train": len(pats), "n_snapshots": X.shape[1], "pod_singular_values": s[: rank + 1] / s[0]}
    return _offline(model, _m_orthonormal(model, V), sigma, n_guard, meta)


def _full_modes(model: SpringD1B, theta: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``k`` elastic eigenpairs (ω² in rad²/s², M-normalised vectors (n, k)) of the full model."""
    dm = dense_modes(model.K(theta), model.M.copy(), k, overwrite=True)
    return (TWO_PI * dm.frequencies_hz) ** 2, dm.shapes


def _m_orthonormal(model: SpringD1B, V: np.ndarray) -> np.ndarray:
    """V M-orthonormalised and M-orthogonal to the rigid modes, to round-off (the bound assumes VᵀMV = I)."""
    V = V - model.rigid @ (model.rigid.T @ (model.M @ V))
    lam, Q = np.linalg.eigh(V.T @ model.M @ V)  # first pass by eigenvectors: VᵀMV may be ill-conditioned
    V = V @ (Q / np.sqrt(lam))
    V = V - model.rigid @ (model.rigid.T @ (model.M @ V))
    W = V.T @ model.M @ V
    return sla.solve_triangular(sla.cholesky(0.5 * (W + W.T), lower=True), V.T, lower=True).T


def _offline(model: SpringD1B, V: np.ndarray, sigma: float, n_guard: int, meta: dict) -> ReducedBasis:
    """The affine blocks of K_r and the residual's triangular factor for basis V (module notes)."""
    E = model.operator()
    L = sla.cholesky(model.K0 - sigma * model.M, lower=True)
    LE = sla.solve_triangular(L, E.toarray(), lower=True)
    # L⁻¹A₀V = LᵀV. The QR is backward stable, so the residual norm keeps its relative accuracy however small.
    R = sla.qr(np.hstack([L.T @ V, sla.solve_triangular(L, model.M @ V, lower=True), LE]), mode="r")[0]
    Z = np.asarray(E.T @ V)
    K0r = V.T @ model.K0 @ V
    n3 = 3 * model.n_nodes
    Z3 = Z[:n3].reshape(model.n_nodes, 3, -1)
    KFr = K0r + np.einsum("nir,nij,njs->rs", Z3, model.springs, Z3, optimize=True)
    defect = float(np.abs(V.T @ model.M @ V - np.eye(V.shape[1])).max())
    return ReducedBasis(model, V, 0.5 * (K0r + K0r.T), 0.5 * (KFr + KFr.T), Z, np.triu(R), LE[:, n3:].T @ LE[:, n3:],
                        model.out @ V, float(sigma), int(n_guard), {**meta, "orthonormality_defect": defect})


def frequency_bounds(lam: np.ndarray, res2: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Certified relative frequency bounds of Ritz pairs from their residuals (module notes).

    With ν = λ̃ − σ, μ̃ = 1/ν and d = ‖r‖_{A⁻¹} / ν^{3/2} (the residual of T = A⁻¹M, self-adjoint in the
    A = K − σM inner product, for the A-normalised Ritz vector):

    * unconditional (Krylov–Bogoliubov): T has an eigenvalue in [μ̃ − d, μ̃ + d], i.e. the full model an
      eigenvalue ν* ∈ [ν / (1 + ρ), ν / (1 − ρ)], ρ = μ̃⁻¹ d (``kb``);
    * matched by rank: the Ritz value of rank k bounds the exact one of rank k from above (Rayleigh–Ritz),
      and from below by Kato–Temple, μ_k ≤ μ̃_k + d_k² / (μ̃_k − α_k) with α_k = μ̃_{k+1} + d_{k+1}, where
      the intervals are disjoint; a cluster of overlapping intervals gets √(Σ d²) over the cluster (Kahan).
      This needs the basis to have missed no mode: the full model has exactly k elastic eigenvalues below
      the (k+1)-th interval. Residuals cannot certify that (a mode M-orthogonal to V leaves no residual);
      the tests check it against the full model's complete spectrum.

    Parameters
    ----------
    lam : ndarray, shape (..., k)
        Ritz values λ̃ (rad²/s²), ascending, of M-normalised Ritz vectors.
    res2 : ndarray, shape (..., k)
        ‖r‖² in the A⁻¹ norm, r = K v − λ̃ M v (rad⁴/s⁴ · kg, with K in N/m and M in kg).
    sigma : float
        σ < 0 (rad²/s²).

    Returns
    -------
    bound, kb : ndarray, shape (..., k)
        Bounds on |f̃ − f| / f: matched by rank, and unconditional; ``inf`` where none holds.
    """
    lam = np.asarray(lam, np.float64)
    nu = lam - sigma
    mu = 1.0 / nu
    d = np.sqrt(np.clip(res2, 0.0, None)) / nu**1.5
    hi = mu + d
    # α_k: the top of the next interval; the last pair has none (gap 0: Kato–Temple gives nothing there).
    alpha = np.concatenate([hi[..., 1:], mu[..., -1:]], axis=-1)
    gap = mu - alpha
    sep = np.concatenate([hi[..., 1:] < mu[..., :-1] - d[..., :-1], np.ones(mu.shape[:-1] + (1,), bool)], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.minimum(d, np.where(gap > 0, d**2 / gap, np.inf))
    # Clusters: runs of overlapping intervals get Kahan's √(Σ d²) over the run, each of its members.
    for idx in np.ndindex(mu.shape[:-1]):
        start = np.r_[0, np.flatnonzero(sep[idx][:-1]) + 1]
        for a, b in zip(start, np.r_[start[1:], mu.shape[-1]], strict=True):
            if b - a > 1:
                delta[idx][a:b] = np.sqrt(np.sum(d[idx][a:b] ** 2))
    rho = d * nu
    with np.errstate(divide="ignore", invalid="ignore"):
        lam_lo = 1.0 / (mu + delta) + sigma
        bound = np.where(lam_lo > 0, np.sqrt(lam / lam_lo) - 1.0, np.inf)
        kb_lo = nu / (1.0 + rho) + sigma
        kb_hi = np.where(rho < 1, nu / (1.0 - rho) + sigma, np.inf)
        kb = np.where(kb_lo > 0, np.maximum(np.sqrt(lam / kb_lo) - 1.0, 1.0 - np.sqrt(lam / kb_hi)), np.inf)
    return bound, kb


def evaluate(
    rb: ReducedBasis,
    patterns: Iterable[ContactPattern],
    n_modes: int = 10,
    tol: float = 5e-5,
    *,
    deltas: Iterable | None = None,
    shapes: bool = False,
    solver: Callable[[ContactPattern, object, int], AssemblyModes] | None = None,
) -> RBModes:
    """Frequencies of many patterns from the reduced basis, certified; direct solves where a bound exceeds ``tol``.

    Parameters
    ----------
    rb : ReducedBasis
    patterns : iterable of ContactPattern
    n_modes : int
        Elastic modes wanted (≤ r − n_guard).
    tol : float
        Largest accepted bound on the relative *frequency* error (default 5e-5, i.e. 0.005 %).
    deltas : None, or one δ (as for :meth:`rom.rubin.RubinModel.with_delta`) per pattern
        Blade mistuning (Eq. 19), affine in K; None: the blade's own.
    shapes : bool
        Also return the shapes at the measurement DOFs.
    solver : callable ``(pattern, delta, n_modes) -> AssemblyModes``, optional
        The fallback (default :func:`rom.spring_assembly.solve_spring_d1b` on ``rb.model``; ``solve_d1b`` of the
        blade ``with_contact_stiffness`` gives the same frequencies to ~1e-8 in a quarter of the time).

    Returns
    -------
    RBModes
    """
    pats = list(patterns)
    if not pats:
        raise ValueError("evaluate needs at least one contact pattern")
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes <= rb.r - rb.n_guard):
        raise ValueError(f"n_modes must be an integer in 1..{rb.r - rb.n_guard} (basis size minus guard), "
                         f"got {n_modes!r}")
    if not (isinstance(tol, (int, float)) and tol > 0):
        raise ValueError(f"tol must be a positive relative frequency error, got {tol!r}")
    dl = [None] * len(pats) if deltas is None else list(deltas)
    if len(dl) != len(pats):
        raise ValueError(f"deltas must give one δ per pattern ({len(pats)}), got {len(dl)}")
    theta = np.array([rb.model.parameters(p, d) for p, d in zip(pats, dl, strict=True)]).reshape(len(pats), -1)
    k = n_modes + rb.n_guard
    with single_thread_blas():  # batches of 64 bound the memory of the residual product (r · 64 · k doubles)
        parts = [_ritz(rb, theta[i : i + 64], k) for i in range(0, len(pats), 64)]
    lam, Y, res2, lam_err = (np.concatenate(x) for x in zip(*parts, strict=True))
    # VᵀMV = I + e, |e| ≤ r·defect: ‖v‖²_M and the Rayleigh quotient move by that share; the eigen-solver's λ̃
    # differs from the quotient by lam_err. √(1 ± x) moves by at most x for x ≤ ½, hence the additive slack.
    e = rb.r * rb.meta["orthonormality_defect"]
    bound, kb = frequency_bounds(lam, res2 / (_delta_factor(rb, theta)[:, None] * (1 - e)), rb.sigma)
    slack = lam_err[:, None] / lam[:, :n_modes] + e
    bound, kb = bound[:, :n_modes] + slack, kb[:, :n_modes] + slack
    f = np.sqrt(lam[:, :n_modes]) / TWO_PI
    meas = np.einsum("mr,brk->bmk", rb.out_V, Y[:, :, :n_modes]) if shapes else None
    fallback = ~np.all(bound <= tol, axis=1)
    solve = solver or (lambda p, d, n: solve_spring_d1b(rb.model, p, n, delta=d))
    for b in np.flatnonzero(fallback):
        direct = solve(pats[b], dl[b], n_modes)
        f[b] = direct.frequencies_hz
        if meas is not None:
            meas[b] = direct.meas_shapes
    log.info("evaluate: %d patterns, %d direct solves (bound > %g)", len(pats), int(fallback.sum()), tol)
    return RBModes(f, bound, kb, fallback, meas, list(rb.model.meas_labels))


def _delta_factor(rb: ReducedBasis, theta: np.ndarray) -> np.ndarray:
    """1 + γ ≤ 1 per pattern with A(θ) ⪰ (1 + γ) A₀: springs only stiffen, a negative δ softens (shape (B,)).

    γ = −λ_max(D^½ G_ff D^½), D = diag(max(−δ, 0) ω²), G_ff the δ block of EᵀA₀⁻¹E; ‖r‖²_{A(θ)⁻¹} ≤ ‖r‖²_{A₀⁻¹}/(1+γ).
    """
    out = np.ones(theta.shape[0])
    for b, t in enumerate(theta):
        dneg = np.sqrt(np.clip(-t[rb.model.n_nodes :], 0.0, None) * rb.model.omega2)
        if np.any(dneg > 0):
            out[b] = max(1.0 - np.linalg.eigvalsh(dneg[:, None] * rb.G_delta * dneg[None, :])[-1], 0.0)
    return out


def _ritz(rb: ReducedBasis, theta: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Lowest ``k`` Ritz pairs, squared A₀⁻¹-norm residuals and eigen-solver error for each θ.

    Shapes (B, k), (B, r, k), (B, k), (B,).

    A(θ)v = A₀v + Eu with u = S(θ)Zy, so r = A₀Vy − νMVy + Eu (ν = λ̃ − σ) and ‖r‖_{A₀⁻¹} = ‖R c‖,
    c = [y; −νy; u]. A margin of (length of c) · eps · Σ_j ‖R_:j‖ |c_j| ≥ the round-off of the product is added.
    """
    mod, B, r = rb.model, theta.shape[0], rb.r
    N, n3 = mod.n_nodes, 3 * mod.n_nodes
    Z3 = rb.Z[:n3].reshape(N, 3, r)
    lam, Y, lam_err = np.empty((B, k)), np.empty((B, r, k)), np.empty(B)
    C = np.empty((B, rb.R.shape[1], k))
    for b, t in enumerate(theta):
        on = t[:N] > 0.5
        # Add the attached nodes' springs to K₀, or remove the detached ones' from the bonded K_F: the fewer.
        sel, base, sign = (on, rb.K0r, 1.0) if on.sum() <= N // 2 else (~on, rb.KFr, -1.0)
        Zs = Z3[sel]
        Kr = base + sign * (Zs.reshape(-1, r).T @ np.einsum("nij,njr->nir", mod.springs[sel], Zs).reshape(-1, r))
        dw = t[N:] * mod.omega2
        if np.any(dw != 0):
            Kr = Kr + rb.Z[n3:].T @ (dw[:, None] * rb.Z[n3:])
        lam[b], Y[b] = sla.eigh(0.5 * (Kr + Kr.T), subset_by_index=[0, k - 1], driver="evr", check_finite=False)
        # |λ̃ − yᵀK_r y| ≤ ‖K_r y − λ̃ y‖ (y unit), plus the round-off of that product.
        KY = Kr @ Y[b]
        lam_err[b] = np.max(np.linalg.norm(KY - lam[b] * Y[b], axis=0)
                            + r * np.finfo(float).eps * np.linalg.norm(np.abs(Kr) @ np.abs(Y[b]), axis=0))
        ZY = rb.Z @ Y[b]
        u = np.zeros_like(ZY)
        u[:n3][np.repeat(on, 3)] = np.einsum("nij,njk->nik", mod.springs[on], ZY[:n3].reshape(N, 3, k)[on]).reshape(
            -1, k)
        u[n3:] = dw[:, None] * ZY[n3:]
        C[b] = np.vstack([Y[b], -(lam[b] - rb.sigma) * Y[b], u])
    W = rb.R @ C.transpose(1, 0, 2).reshape(C.shape[1], -1)  # one product for the whole batch
    res = np.linalg.norm(W, axis=0).reshape(B, k)
    margin = C.shape[1] * np.finfo(float).eps * np.einsum("j,bjk->bk", np.linalg.norm(rb.R, axis=0), np.abs(C))
    return lam, Y, (res + margin) ** 2, lam_err
