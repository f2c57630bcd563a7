"""Rubin free-interface reduction of the blade (paper §2.2, Eqs. 7–17) and blade mistuning (Eq. 19).

The reductor :func:`rubin` (academic convenience: :func:`reduce_blade`) computes, for a free–free
component,

* the rigid-body modes Φ_r and ``m`` free-interface modes Φ_f with eigenvalues Ω_f² (Eq. 7, 18);
* the residual attachment modes Ψ_r (Eq. 7): the columns of the elastic (inertia-relief) flexibility at the
  boundary DOFs, minus the flexibility of the retained modes, ``Ψ_r = (Pᵀ G_c P − Φ_f Ω_f⁻² Φ_fᵀ) A ᵀ``.
  ``P = I − M Φ_r Φ_rᵀ`` makes each unit load self-equilibrated (inertia relief), ``G_c`` is the flexibility
  of the blade held by a statically determinate support (six DOFs picked by pivoted QR of Φ_rᵀ, so the
  supported stiffness is positive definite). Reactions of a self-equilibrated load on a determinate
  support vanish, so ``Pᵀ G_c P`` is the exact elastic flexibility; no singular K is ever factorized and no
  shift perturbs the result (design §5).

It returns a :class:`RubinModel` holding the blocks of Eqs. 8–13 at the boundary: A Φ_r, A Φ_f, Ω_f²,
A Ψ_r (residual flexibility at the boundary, Eq. 13), M_r,b and G_r,b (Eq. 10). The boundary is
``[interface DOFs; accessory DOFs]`` (Eq. 1): for the blade, the L and R root grids and the measurement DOFs.

:meth:`RubinModel.superelement` applies the secondary transformation T2 (Eqs. 11–17) for any subset of the
boundary, giving displacement-based matrices in coordinates ``[η_r; η_f; x_b]``:

* all boundary DOFs: the paper's super-element (detached interface DOFs remain as free coordinates);
* contacting + accessory DOFs only: the exact elimination of force-free detached DOFs (design §5). A
  detached node carries no interface force, so its residual attachment mode has zero participation
  g = 0, and dropping the column is exact for Rubin's approximation; Eq. 13 then uses the contacting
  sub-block of the boundary residual flexibility.

Blade mistuning (Eq. 19) is :meth:`RubinModel.with_delta`: Ω_f² → diag((1 + δ_i) ω_i²), no basis recomputed.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as sla
from scipy.linalg import blas, lapack

from .component import Component
from .mistuning import as_delta
from .modal import DenseModes, dense_modes, single_thread_blas
from .solver import available_backends, factorize, solve_modes

__all__ = ["RubinModel", "Superelement", "rubin", "reduce_blade", "blade_boundary_dofs", "DEFAULT_N_FREE_MODES"]

log = logging.getLogger(__name__)

#: Default number m of free-interface blade modes (the paper's value, §5).
DEFAULT_N_FREE_MODES = 50


@dataclass(frozen=True, eq=False)
class Superelement:
    """Displacement-based Rubin super-element (Eqs. 15–17) for a subset of the boundary.

    Coordinates: ``[η_r (n_r); η_f (m); x_b (n_s)]`` with ``x_b`` the kept boundary DOFs.

    Attributes
    ----------
    K, M : ndarray, shape (n_r + m + n_s, n_r + m + n_s)
    boundary_index : ndarray of int, shape (n_s,)
        Positions of the kept DOFs in the model's boundary ordering.
    n_r, n_f : int
    """

    K: np.ndarray
    M: np.ndarray
    boundary_index: np.ndarray
    n_r: int
    n_f: int

    @property
    def n(self) -> int:
        return int(self.K.shape[0])

    @property
    def n_modal(self) -> int:
        """Number of modal coordinates n_r + m (they precede the boundary coordinates)."""
        return self.n_r + self.n_f


@dataclass(frozen=True, eq=False)
class RubinModel:
    """Rubin-reduced free–free component (Eqs. 7–13, 18–19).

    Attributes
    ----------
    omega2_tuned : ndarray, shape (m,)
        Free-interface eigenvalues ω_f,i² (rad²/s²) of the FE component (Eq. 18).
    delta : ndarray, shape (m,)
        Blade mistuning δ_i (Eq. 19), zeros for the tuned blade.
    Phi_r_b : ndarray, shape (n_b, n_r)
        Rigid-body modes at the boundary, Φ_r|b = A Φ_r.
    Phi_f_b : ndarray, shape (n_b, m)
        Free-interface modes at the boundary, Φ_f|b = A Φ_f.
    G_bb : ndarray, shape (n_b, n_b)
        Residual flexibility at the boundary, A Ψ_r (Eq. 13 is its inverse).
    G_rb, M_rb : ndarray, shape (n_b, n_b)
        Interface flexibility and inertia of the residual attachment modes, Ψ_rᵀ K Ψ_r and Ψ_rᵀ M Ψ_r (Eq. 10).
    boundary_dofs : ndarray of int, shape (n_b,)
        Component DOF of each boundary coordinate: ``n_interface`` interface DOFs, then accessory DOFs.
    n_interface : int
    n_dof : int
    Phi_r, Phi_f, Psi_r : ndarray or None
        Full bases (n_dof rows), kept only with ``keep_basis=True`` (for :meth:`reconstruct`).
    meta : dict
    """

    omega2_tuned: np.ndarray
    delta: np.ndarray
    Phi_r_b: np.ndarray
    Phi_f_b: np.ndarray
    G_bb: np.ndarray
    G_rb: np.ndarray
    M_rb: np.ndarray
    boundary_dofs: np.ndarray
    n_interface: int
    n_dof: int
    Phi_r: np.ndarray | None = None
    Phi_f: np.ndarray | None = None
    Psi_r: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    # ----------------------------------------------------------------- sizes and eigenvalues
    @property
    def n_r(self) -> int:
        return int(self.Phi_r_b.shape[1])

    @property
    def m(self) -> int:
        return int(self.omega2_tuned.size)

    @property
    def n_b(self) -> int:
        return int(self.boundary_dofs.size)

    @property
    def accessory_index(self) -> np.ndarray:
        """Positions of the accessory DOFs in the boundary ordering."""
        return np.arange(self.n_interface, self.n_b)

    @property
    def omega2(self) -> np.ndarray:
        """Ω_f² of Eq. 19: (1 + δ_i) ω_f,i², shape (m,)."""
        return self.omega2_tuned * (1.0 + self.delta)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Free-interface frequencies (Hz) including mistuning, shape (m,)."""
        return np.sqrt(self.omega2) / (2 * np.pi)

    # ----------------------------------------------------------------- transforms
    def with_delta(self, delta) -> RubinModel:
        """The same blade with mistuning δ (Eq. 19); δ of length ≤ m, missing entries tuned (0).

        No basis is recomputed: only Ω_f² changes. ``delta=0`` (or all zeros) gives the tuned model exactly.
        """
        return replace(self, delta=as_delta(delta, self.m))

    # ----------------------------------------------------------------- Eqs. 8–17
    def superelement(self, keep: np.ndarray | None = None) -> Superelement:
        """Displacement-based super-element for the boundary subset ``keep`` (Eqs. 11–17).

        Parameters
        ----------
        keep : ndarray of int or bool, optional
            Boundary positions kept as coordinates (default: all, the paper's super-element). Dropping
            DOFs that carry no interface force (detached contact nodes) is the exact force-free
            elimination: their residual attachment modes are left out of Eq. 7.

        Returns
        -------
        Superelement
            ``M̃ = T2ᵀ M̄ T2``, ``K̃ = T2ᵀ K̄ T2`` (Eq. 15) with M̄, K̄ of Eqs. 8–9 and T2 of Eq. 14.
        """
        if keep is None:
            S = np.arange(self.n_b)
        else:
            keep = np.asarray(keep)
            S = np.flatnonzero(keep) if keep.dtype == bool else keep.astype(np.int64).ravel()
            if keep.dtype == bool and keep.size != self.n_b:
                raise ValueError(f"boolean keep must have {self.n_b} entries, got {keep.size}")
            if S.size == 0 or S.min() < 0 or S.max() >= self.n_b:
                raise ValueError(f"keep must select boundary positions in 0..{self.n_b - 1}")
        nr, m, ns = self.n_r, self.m, S.size
        Krb, Mhat = self._residual_blocks(S)
        # Eqs. 15–17 in closed form (T2 of Eq. 14 applied to M̄, K̄ of Eqs. 8–9), with Φ_b = [Φ_r|b, Φ_f|b]:
        #   K̃ = [[Φ_bᵀ K_rb Φ_b + diag(0, Ω_f²), −Φ_bᵀ K_rb], [−K_rb Φ_b, K_rb]]
        #   M̃ = [[I + Φ_bᵀ M̂_r Φ_b, −Φ_bᵀ M̂_r], [−M̂_r Φ_b, M̂_r]],   M̂_r = K_rbᵀ M_r,b K_rb.
        # The (3,3) block of K̃ is K_rbᵀ G_r,b K_rb = K_rb because G_r,b = A Ψ_r (Eq. 10 and the K-orthogonality
        # of the residual modes; checked by the tests to 1e-6).
        Phi_b = np.hstack([self.Phi_r_b[S], self.Phi_f_b[S]])  # (ns, nr + m)
        nm = nr + m
        KP = Krb @ Phi_b
        MP = Mhat @ Phi_b
        K = np.empty((nm + ns, nm + ns))
        M = np.empty_like(K)
        # Every block is written symmetric: K_rb and M̂_r are, the off-diagonal pairs are exact transposes,
        # and only the small modal blocks need their round-off symmetrised.
        Kmm = Phi_b.T @ KP
        Mmm = Phi_b.T @ MP
        K[:nm, :nm] = 0.5 * (Kmm + Kmm.T)
        K[nr + np.arange(m), nr + np.arange(m)] += self.omega2
        K[nm:, :nm] = -KP
        K[:nm, nm:] = -KP.T
        K[nm:, nm:] = Krb
        M[:nm, :nm] = 0.5 * (Mmm + Mmm.T)
        M[np.arange(nm), np.arange(nm)] += 1.0
        M[nm:, :nm] = -MP
        M[:nm, nm:] = -MP.T
        M[nm:, nm:] = Mhat
        return Superelement(K, M, S, nr, m)

    def _residual_blocks(self, S: np.ndarray, route: str = "auto") -> tuple[np.ndarray, np.ndarray]:
        """K_r,b = (A Ψ_r)_SS⁻¹ (Eq. 13) and M̂_r = K_r,b M_r,b,SS K_r,b (Eq. 17) on the kept subset S.

        Two exact routes; ``route="auto"`` takes the cheaper one by operation count:

        * ``"direct"``: Cholesky of the (n_s × n_s) flexibility sub-block, its inverse, and M̂_r as Uᵀ U with
          U = Rᵀ K_r,b (R the Cholesky factor of M_r,b,SS): about 3.3 n_s³ flops.
        * ``"update"``: from the inverse over the whole boundary, H = G⁻¹ and P = H M_r,b H (computed once
          per model and shared by its mistuned copies), by a Schur complement over the dropped positions D:
          (G_SS)⁻¹ = H_SS − H_SD H_DD⁻¹ H_DS. About 3 n_s² n_d + 4 n_d² n_s flops (:func:`_schur_update`),
          so contact-rich patterns cost less than sparse ones.
        """
        ns = S.size
        D = np.setdiff1d(np.arange(self.n_b), S)
        nd = D.size
        if route == "auto":
            direct_cost = 10.0 * ns**3 / 3.0
            update_cost = 3.0 * ns * ns * nd + 4.0 * nd * nd * ns + nd**3 / 3.0
            route = "update" if update_cost < direct_cost else "direct"
        if route == "update":
            H, P = _boundary_inverse(self)
            if nd == 0:
                return H, P
            got = _schur_update(H, P, S, D)
            if got is not None:
                return got
        elif route != "direct":
            raise ValueError(f"route must be 'auto', 'direct' or 'update', got {route!r}")
        return _direct_blocks(self.G_bb, self.M_rb, S)

    def free_modes(self, n_modes: int) -> DenseModes:
        """Elastic modes of the reduced free–free component (paper super-element, all boundary DOFs free)."""
        se = self.superelement()
        return dense_modes(se.K, se.M, n_modes, max_rigid=self.n_r)

    def reconstruct(self, q: np.ndarray) -> np.ndarray:
        """Physical displacements of all DOFs from super-element coordinates ``[η_r; η_f; x_b]`` (all boundary).

        ``x = Φ_r η_r + Φ_f η_f + Ψ_r g_b`` with ``g_b`` from Eq. 12. Needs ``keep_basis=True``.
        """
        if self.Psi_r is None or self.Phi_r is None or self.Phi_f is None:
            raise ValueError("this RubinModel was reduced with keep_basis=False; the full basis is not available")
        q = np.asarray(q, dtype=np.float64)
        nm = self.n_r + self.m
        if q.shape[0] != nm + self.n_b:
            raise ValueError(f"q must have {nm + self.n_b} rows (n_r + m + n_b), got {q.shape[0]}")
        eta_r, eta_f, xb = q[: self.n_r], q[self.n_r : nm], q[nm:]
        resid = xb - self.Phi_r_b @ eta_r - self.Phi_f_b @ eta_f
        g = sla.solve(self.G_bb, resid, assume_a="pos")  # Eq. 12
        return self.Phi_r @ eta_r + self.Phi_f @ eta_f + self.Psi_r @ g


# H = G_bb⁻¹ and P = H M_rb H over the whole boundary, per model. Keyed by the identity of G_bb, which
# mistuned copies (``with_delta``) share; the entry keeps G_bb alive so that the id cannot be reused.
_INVERSE_MEMO: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
_INVERSE_MEMO_SIZE = 4


def _boundary_inverse(model: RubinModel) -> tuple[np.ndarray, np.ndarray]:
    key = id(model.G_bb)
    hit = _INVERSE_MEMO.get(key)
    if hit is not None and hit[0] is model.G_bb:
        return hit[1], hit[2]
    # One BLAS thread, whatever the caller's: the entry is shared by every later solve of this model in the
    # process, and a threaded product sums in another order, so a process whose first caller ran threaded would
    # give other last bits than one whose first caller did not (a dataset part built in a worker against the
    # same part built in the parent).
    with single_thread_blas():
        try:
            cho = sla.cho_factor(model.G_bb, lower=True, check_finite=False)
        except np.linalg.LinAlgError as exc:
            raise ValueError("the residual flexibility over the whole boundary is not positive definite") from exc
        H = sla.cho_solve(cho, np.eye(model.n_b), check_finite=False)
        H = 0.5 * (H + H.T)
        P = H @ (model.M_rb @ H)
        P = 0.5 * (P + P.T)
    while len(_INVERSE_MEMO) >= _INVERSE_MEMO_SIZE:
        _INVERSE_MEMO.pop(next(iter(_INVERSE_MEMO)))
    _INVERSE_MEMO[key] = (model.G_bb, H, P)
    return H, P


def _support_dofs(Phi_r: np.ndarray) -> np.ndarray:
    """Statically determinate support: the n_r DOFs that best pin the rigid-body modes (pivoted QR of Φ_rᵀ)."""
    _, _, piv = sla.qr(Phi_r.T, mode="economic", pivoting=True)
    dofs = np.sort(piv[: Phi_r.shape[1]])
    cond = np.linalg.cond(Phi_r[dofs])
    if not np.isfinite(cond) or cond > 1e8:
        raise ValueError(f"could not find a statically determinate support (cond = {cond:.3g})")
    return dofs


def rubin(
    component: Component,
    boundary_dofs: np.ndarray,
    n_modes: int = DEFAULT_N_FREE_MODES,
    *,
    n_interface: int | None = None,
    keep_basis: bool = False,
    backend: str = "auto",
    meta: dict | None = None,
) -> RubinModel:
    """Reduce a free–free component by Rubin's method (Eqs. 7–13).

    Parameters
    ----------
    component : Component
    boundary_dofs : ndarray of int, shape (n_b,)
        Interface DOFs followed by accessory DOFs (Eq. 1).
    n_modes : int
        Free-interface modes m kept (besides the rigid-body modes).
    n_interface : int, optional
        How many leading boundary DOFs are interface DOFs (default: all).
    keep_basis : bool
        Keep Φ_r, Φ_f, Ψ_r (dense, n_dof rows) for :meth:`RubinModel.reconstruct`.

    Returns
    -------
    RubinModel
    """
    n = component.n_dof
    b = np.asarray(boundary_dofs, dtype=np.int64).ravel()
    if b.size == 0 or b.min() < 0 or b.max() >= n:
        raise ValueError(f"boundary_dofs must be a non-empty set of DOFs in 0..{n - 1}")
    if np.unique(b).size != b.size:
        raise ValueError("boundary_dofs contains duplicates")
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes <= n - 6 - b.size):
        raise ValueError(f"n_modes must be an integer in 1..{n - 6 - b.size}, got {n_modes!r}")
    n_interface = b.size if n_interface is None else int(n_interface)
    if not 0 <= n_interface <= b.size:
        raise ValueError(f"n_interface must lie in 0..{b.size}, got {n_interface}")
    K, M = component.K, component.M

    # Rigid-body and free-interface modes (Eq. 7).
    sol = solve_modes(K, M, int(n_modes), backend=backend)
    Phi_r, Phi_f, w2 = sol.rigid_shapes, sol.shapes, sol.omega2
    if Phi_r.shape[1] == 0:
        raise ValueError("rubin() expects a free–free component with rigid-body modes; none were found")

    Psi_r = _residual_attachment_modes(K, M, Phi_r, Phi_f, w2, b, backend)
    G_bb = Psi_r[b]
    G_bb = 0.5 * (G_bb + G_bb.T)
    G_rb = Psi_r.T @ (K @ Psi_r)
    M_rb = Psi_r.T @ (M @ Psi_r)
    log.info("rubin: n=%d, n_b=%d, n_r=%d, m=%d (%.1f–%.1f Hz)", n, b.size, Phi_r.shape[1], w2.size,
             sol.frequencies_hz[0], sol.frequencies_hz[-1])
    return RubinModel(
        omega2_tuned=w2,
        delta=np.zeros(w2.size),
        Phi_r_b=Phi_r[b],
        Phi_f_b=Phi_f[b],
        G_bb=G_bb,
        G_rb=0.5 * (G_rb + G_rb.T),
        M_rb=0.5 * (M_rb + M_rb.T),
        boundary_dofs=b,
        n_interface=n_interface,
        n_dof=n,
        Phi_r=Phi_r if keep_basis else None,
        Phi_f=Phi_f if keep_basis else None,
        Psi_r=Psi_r if keep_basis else None,
        meta=dict(meta or {}),
    )


def _residual_attachment_modes(K, M, Phi_r: np.ndarray, Phi_f: np.ndarray, w2: np.ndarray, b: np.ndarray,
                               backend: str) -> np.ndarray:
    """Residual attachment modes Ψ_r = (Pᵀ G_c P − Φ_f Ω_f⁻² Φ_fᵀ) Aᵀ (Eq. 7), shape (n, n_b) (module notes)."""
    n = K.shape[0]
    # Inertia-relief elastic flexibility at the boundary: X = G_c P A ᵀ on a determinate support.
    sup = _support_dofs(Phi_r)
    free = np.setdiff1d(np.arange(n), sup)
    F = -(M @ Phi_r) @ Phi_r[b].T  # P Aᵀ = Aᵀ − M Φ_r Φ_r|bᵀ, shape (n, n_b)
    F[b, np.arange(b.size)] += 1.0
    # Many right-hand sides: Pardiso's blocked solve beats SuperLU's column-by-column one even on small models
    # (default blade, 1 305 columns: 8.7 s vs 22.9 s measured).
    multi = "pardiso" if backend == "auto" and b.size >= 64 and "pardiso" in available_backends() else backend
    fac = factorize(K[free][:, free].tocsr(), multi)
    try:
        X = np.zeros((n, b.size))
        X[free] = np.asarray(fac.solve(F[free])).reshape(free.size, b.size)
    finally:
        fac.free()
    X -= Phi_r @ (Phi_r.T @ (M @ X))  # Pᵀ X: remove the rigid-body component (M-orthogonal projection)
    # Residual attachment modes: subtract the retained elastic modes' flexibility Σ φ φᵀ / ω².
    return X - Phi_f @ (Phi_f[b].T / w2[:, None])


def blade_boundary_dofs(blade: Component) -> tuple[np.ndarray, int]:
    """Boundary DOFs of the academic blade: L grid, R grid (row-major, x/y/z per node), then measurement DOFs.

    Returns
    -------
    dofs : ndarray of int, shape (2 · n_grid · 3 + n_meas,)
    n_interface : int
        Number of root-grid DOFs (the rest are accessory measurement DOFs, local direction ``meas_direction``).
    """
    nodes = np.concatenate([blade.node_set("L").ravel(), blade.node_set("R").ravel()])
    grid = blade.dofs_of(nodes).ravel()
    meas = 3 * blade.node_set("meas").ravel() + int(blade.meta["meas_direction"]) - 1
    return np.concatenate([grid, meas]), int(grid.size)


def reduce_blade(
    bd, n_modes: int = DEFAULT_N_FREE_MODES, *, keep_basis: bool = False, backend: str = "auto"
) -> RubinModel:
    """Rubin model of the academic blade: root grids as interface DOFs, measurement DOFs as accessory DOFs."""
    dofs, n_i = blade_boundary_dofs(bd.blade)
    return rubin(
        bd.blade, dofs, n_modes, n_interface=n_i, keep_basis=keep_basis, backend=backend,
        meta={"grid": list(bd.params.grid), "n_meas": int(dofs.size - n_i)},
    )


def _sym_from_upper(C: np.ndarray) -> np.ndarray:
    """Full symmetric matrix from the upper triangle that BLAS syrk/syr2k/potri fill."""
    return np.triu(C) + np.triu(C, 1).T


def _schur_update(
    H: np.ndarray, P: np.ndarray, S: np.ndarray, D: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """K_r,b and M̂_r on S from the whole-boundary H = G⁻¹ and P = H M_r,b H (see ``_residual_blocks``).

    With H_DD = L Lᵀ, Z = L⁻¹ H_DS and Y = L⁻ᵀ Z = H_DD⁻¹ H_DS:

    * K_r,b = H_SS − Zᵀ Z (one syrk);
    * M̂_r = P_SS − Yᵀ P_DS − P_SD Y + Yᵀ P_DD Y = P_SS + Yᵀ F + Fᵀ Y with F = ½ P_DD Y − P_DS (one syr2k).

    Returns ``None`` when H_DD is not numerically positive definite (the caller takes the direct route).
    """
    try:
        L = sla.cholesky(H[np.ix_(D, D)], lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return None
    Z = sla.solve_triangular(L, H[np.ix_(D, S)], lower=True, check_finite=False)
    Krb = blas.dsyrk(-1.0, Z, beta=1.0, c=np.asfortranarray(H[np.ix_(S, S)]), trans=1, overwrite_c=1)
    Y = sla.solve_triangular(L, Z, lower=True, trans="T", check_finite=False, overwrite_b=True)
    F = P[np.ix_(D, D)] @ Y
    F *= 0.5
    F -= P[np.ix_(D, S)]
    Mhat = blas.dsyr2k(1.0, Y, F, beta=1.0, c=np.asfortranarray(P[np.ix_(S, S)]), trans=1, overwrite_c=1)
    return _sym_from_upper(Krb), _sym_from_upper(Mhat)


def _direct_blocks(G: np.ndarray, Mrb: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K_r,b = (G_SS)⁻¹ and M̂_r = K_r,b M_r,b,SS K_r,b by Cholesky factors (see ``_residual_blocks``)."""
    c, info = lapack.dpotrf(G[np.ix_(S, S)], lower=0, clean=1)
    if info != 0:
        raise ValueError(
            "the residual flexibility at the kept boundary DOFs is not positive definite: too many free modes "
            "for the boundary size, or duplicate boundary DOFs"
        )
    inv, info = lapack.dpotri(c, lower=0)
    if info != 0:  # pragma: no cover - potri after a successful potrf fails only on an exact zero pivot
        raise ValueError("the residual flexibility at the kept boundary DOFs is singular")
    Krb = _sym_from_upper(inv)
    Mss = Mrb[np.ix_(S, S)]
    R, info = lapack.dpotrf(Mss, lower=1, clean=1)
    if info != 0:  # a semi-definite residual mass: plain products
        Mhat = Krb @ (Mss @ Krb)
        return Krb, 0.5 * (Mhat + Mhat.T)
    U = blas.dtrmm(1.0, R, Krb, lower=1, trans_a=1)  # Rᵀ K_r,b
    return Krb, _sym_from_upper(blas.dsyrk(1.0, U, trans=1))
