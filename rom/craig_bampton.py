"""Craig–Bampton reduction of the disk (paper §2.1, Eqs. 2–6).

Full model, reductor and reduced model are kept apart (design §6, pyMOR style): a :class:`~rom.component.Component`
is the full model, :func:`craig_bampton` (or the academic convenience :func:`reduce_disk`) is the reductor, and
it returns a new frozen :class:`CraigBamptonModel` holding the blocks of Eqs. 4–5, with
:meth:`CraigBamptonModel.reconstruct` mapping reduced coordinates back to physical DOFs.

Reduced coordinates are ordered as in the matrix of Eq. 3: ``q = [η_k (n_k); x_b (n_b)]``.

Boundary coordinates may be expressed in rotated nodal frames: with ``boundary_rotations`` the physical
boundary displacement of node triplet ``j`` is ``x_b,phys = R_j x_b``. :func:`reduce_disk` uses the slot
rotations, so the disk's slot DOFs come out in each slot's blade-local frame and tie to the blade's root
DOFs without further rotation (and the reduced model of one slot serves every slot of a cyclic disk).

Memory: the constraint modes Ψ (Eq. 3) would be a dense ``(n_e, n_b)`` array, 171 k × 1 302 doubles ≈ 1.8 GB
for one slot of the default academic disk. The reduction works through them one block of boundary DOFs at a
time and holds them whole only with ``keep_basis=True`` (the default disk's build peaks at 3.2 GB).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from .component import Component
from .contact import slot_flank_nodes
from .modal import DenseModes, dense_modes
from .solver import available_backends, factorize, solve_modes_factored

__all__ = ["CraigBamptonModel", "craig_bampton", "reduce_disk", "disk_boundary_dofs", "DEFAULT_N_CB_MODES"]

log = logging.getLogger(__name__)

#: Default number of fixed-interface modes, from the convergence study in docs/rom.md.
DEFAULT_N_CB_MODES = 100


@dataclass(frozen=True, eq=False)
class CraigBamptonModel:
    """A Craig–Bampton reduced component (Eqs. 3–6).

    Attributes
    ----------
    Lambda : ndarray, shape (n_k,)
        Fixed-interface eigenvalues ω² (rad²/s²), the diagonal of Λ in Eq. 4.
    kappa_bb : ndarray, shape (n_b, n_b)
        Boundary stiffness κ_bb (Eqs. 4, 6).
    mu_be : ndarray, shape (n_b, n_k)
        Mass coupling μ_be (Eqs. 5, 6).
    mu_bb : ndarray, shape (n_b, n_b)
        Boundary mass μ_bb (Eqs. 5, 6).
    boundary_dofs : ndarray of int, shape (n_b,)
        Component DOF of each boundary coordinate (rotated frames: the DOF triplet of the node).
    boundary_rotations : ndarray, shape (n_b // 3, 3, 3) or None
        Frame of each boundary node triplet (``x_phys = R x_b``); ``None`` for the component frame.
    output_dofs : ndarray of int, shape (n_out,)
        Physical DOFs kept for cheap output (e.g. measurement DOFs).
    output_basis : ndarray, shape (n_out, n_k + n_b)
        Rows of the reduction basis R_CB (Eq. 3) at ``output_dofs``.
    n_dof : int
        DOFs of the full component.
    Phi, Psi : ndarray or None, shapes (n_e, n_k), (n_e, n_b)
        Fixed-interface and constraint modes on the excess DOFs (kept only with ``keep_basis=True``).
    excess_dofs : ndarray of int, shape (n_e,) or None
    meta : dict
        Provenance (``slots``, ``n_sectors``, ``cyclic`` for the academic disk).
    """

    Lambda: np.ndarray
    kappa_bb: np.ndarray
    mu_be: np.ndarray
    mu_bb: np.ndarray
    boundary_dofs: np.ndarray
    boundary_rotations: np.ndarray | None
    output_dofs: np.ndarray
    output_basis: np.ndarray
    n_dof: int
    Phi: np.ndarray | None = None
    Psi: np.ndarray | None = None
    excess_dofs: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    @property
    def n_k(self) -> int:
        return int(self.Lambda.size)

    @property
    def n_b(self) -> int:
        return int(self.boundary_dofs.size)

    @property
    def n(self) -> int:
        """Size of the reduced model, n_k + n_b."""
        return self.n_k + self.n_b

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Fixed-interface natural frequencies (Hz), shape (n_k,)."""
        return np.sqrt(self.Lambda) / (2 * np.pi)

    def K(self, out: np.ndarray | None = None) -> np.ndarray:
        """Reduced stiffness K̃ = [[Λ, 0], [0, κ_bb]] (Eq. 4), shape (n, n).

        With ``out`` (zeros, at least (n, n)), the blocks are written into its leading (n, n) block and it
        is returned: assemblies fill their matrix without an intermediate copy.
        """
        K = np.zeros((self.n, self.n)) if out is None else out
        k, n = self.n_k, self.n
        K[np.arange(k), np.arange(k)] = self.Lambda
        K[k:n, k:n] = self.kappa_bb
        return K

    def M(self, out: np.ndarray | None = None) -> np.ndarray:
        """Reduced mass M̃ = [[I, μ_beᵀ], [μ_be, μ_bb]] (Eq. 5), shape (n, n); ``out`` as in :meth:`K`."""
        M = np.zeros((self.n, self.n)) if out is None else out
        k, n = self.n_k, self.n
        M[np.arange(k), np.arange(k)] = 1.0
        M[k:n, :k] = self.mu_be
        M[:k, k:n] = self.mu_be.T
        M[k:n, k:n] = self.mu_bb
        return M

    def truncated(self, n_k: int) -> CraigBamptonModel:
        """The same model keeping only the first ``n_k`` fixed-interface modes (exactly the CB model with n_k)."""
        if not (isinstance(n_k, (int, np.integer)) and 1 <= n_k <= self.n_k):
            raise ValueError(f"n_k must be an integer in 1..{self.n_k}, got {n_k!r}")
        keep = np.r_[np.arange(n_k), self.n_k + np.arange(self.n_b)]
        return replace(
            self,
            Lambda=self.Lambda[:n_k],
            mu_be=self.mu_be[:, :n_k],
            output_basis=self.output_basis[:, keep],
            Phi=None if self.Phi is None else self.Phi[:, :n_k],
        )

    def free_modes(self, n_modes: int) -> DenseModes:
        """Elastic modes of the reduced component with its boundary free (rigid-body modes dropped)."""
        return dense_modes(self.K(), self.M(), n_modes)

    def outputs(self, q: np.ndarray) -> np.ndarray:
        """Physical displacements at ``output_dofs`` for reduced coordinates ``q`` of shape (n,) or (n, k)."""
        return self.output_basis @ q

    def reconstruct(self, q: np.ndarray) -> np.ndarray:
        """Physical displacements x = R_CB q (Eq. 3) of all component DOFs, shape (n_dof,) or (n_dof, k).

        Raises
        ------
        ValueError
            When the model was reduced without ``keep_basis=True`` (use :meth:`outputs` then).
        """
        if self.Phi is None or self.Psi is None or self.excess_dofs is None:
            raise ValueError("this CraigBamptonModel was reduced with keep_basis=False; use outputs() instead")
        q = np.asarray(q, dtype=np.float64)
        if q.shape[0] != self.n:
            raise ValueError(f"q must have {self.n} rows (n_k + n_b), got {q.shape[0]}")
        eta, xb = q[: self.n_k], q[self.n_k :]
        x = np.zeros((self.n_dof,) + q.shape[1:])
        x[self.excess_dofs] = self.Phi @ eta + self.Psi @ xb
        x[self.boundary_dofs] = _rotate(self.boundary_rotations, xb)
        return x


def _rotate(R: np.ndarray | None, x: np.ndarray, transpose: bool = False) -> np.ndarray:
    """T x (or Tᵀ x) with T = blockdiag(R_j): node rotations applied to the rows of ``x`` in triplets."""
    if R is None:
        return x
    shp = x.shape
    xr = x.reshape((R.shape[0], 3) + shp[1:])
    return np.einsum("nji,nj...->ni..." if transpose else "nij,nj...->ni...", R, xr).reshape(shp)


def craig_bampton(
    component: Component,
    boundary_dofs: np.ndarray,
    n_modes: int = DEFAULT_N_CB_MODES,
    *,
    output_dofs: np.ndarray | None = None,
    boundary_rotations: np.ndarray | None = None,
    keep_basis: bool = False,
    block_size: int = 64,
    backend: str = "auto",
    meta: dict | None = None,
) -> CraigBamptonModel:
    """Reduce a component by Craig–Bampton (Eqs. 2–6).

    Parameters
    ----------
    component : Component
        Full model (sparse K, M).
    boundary_dofs : ndarray of int, shape (n_b,)
        Boundary DOFs (interface and accessory). With ``boundary_rotations`` they must come in node
        triplets (x, y, z of one node).
    n_modes : int
        Number n_k of fixed-interface normal modes Φ_ke kept.
    output_dofs : ndarray of int, shape (n_out,), optional
        Physical DOFs whose rows of R_CB are stored for cheap output (measurement DOFs).
    boundary_rotations : ndarray, shape (n_b // 3, 3, 3), optional
        Frames of the boundary node triplets: physical x_b = R_j · (reduced boundary coordinates).
    keep_basis : bool
        Keep Φ and Ψ (dense, n_e × (n_k + n_b)) so :meth:`CraigBamptonModel.reconstruct` works.
    block_size : int
        Right-hand sides per block for the constraint-mode solves (64: Pardiso's cost per vector has levelled
        off there, and the three (n_e, 64) work arrays stay near 0.3 GB for the default disk).
    backend : str
        Factorization backend (see :func:`rom.solver.factorize`).

    Returns
    -------
    CraigBamptonModel
    """
    n = component.n_dof
    b, R = _checked_boundary(n, boundary_dofs, n_modes, boundary_rotations)
    is_b = np.zeros(n, bool)
    is_b[b] = True
    e = np.flatnonzero(~is_b)
    out = np.zeros(0, np.int64) if output_dofs is None else np.asarray(output_dofs, dtype=np.int64).ravel()
    pos_e = np.full(n, -1)
    pos_e[e] = np.arange(e.size)
    out_e = np.flatnonzero(pos_e[out] >= 0)  # output rows that are excess DOFs
    Phi, Lambda, kappa, mu_be, mu_bb, Psi_out, Psi_kept = _factored_reduction(
        component, e, b, int(n_modes), pos_e[out[out_e]], block_size, keep_basis, backend)
    # Express the boundary coordinates in the given frames: x_phys = T x_b, T = blockdiag(R_j).
    if R is not None:
        kappa = _rotate(R, _rotate(R, kappa, True).T, True).T
        mu_bb = _rotate(R, _rotate(R, mu_bb, True).T, True).T
        mu_be = _rotate(R, mu_be, True)
    return CraigBamptonModel(
        Lambda=Lambda, kappa_bb=kappa, mu_be=mu_be, mu_bb=mu_bb, boundary_dofs=b, boundary_rotations=R,
        output_dofs=out, output_basis=_output_basis(n, b, pos_e, out, out_e, Phi, Psi_out, R), n_dof=n,
        Phi=Phi if keep_basis else None, Psi=None if Psi_kept is None else _rotate(R, Psi_kept.T, True).T,
        excess_dofs=e if keep_basis else None, meta=dict(meta or {}),
    )


def _factored_reduction(component: Component, e: np.ndarray, b: np.ndarray, n_modes: int, out_rows: np.ndarray,
                        block_size: int, keep_basis: bool, backend: str):
    """Fixed-interface modes and the blocks of Eq. 6 on one factorization of K_ee, in the component frame.

    One factorization of K_ee serves the fixed-interface modes (shift-invert at σ = 0: with the boundary clamped
    K_ee is positive definite) and the constraint modes. Many right-hand sides: Pardiso's blocked solve wins even
    below the size where SuperLU is the default.

    Returns
    -------
    Phi, Lambda : ndarray, shapes (n_e, n_k), (n_k,)
        Fixed-interface modes and their ω² (rad²/s²).
    kappa, mu_be, mu_bb, Psi_out, Psi_kept
        As :func:`_constraint_modes` gives them, κ_bb and μ_bb symmetrised.
    """
    K, M = component.K, component.M
    Kee, Keb, Kbb = K[e][:, e].tocsr(), K[e][:, b].tocsr(), K[b][:, b].toarray()
    Mee, Meb, Mbb = M[e][:, e].tocsr(), M[e][:, b].tocsr(), M[b][:, b].toarray()
    multi = "pardiso" if backend == "auto" and b.size >= 64 and "pardiso" in available_backends() else backend
    t0 = time.perf_counter()
    fac = factorize(Kee, multi)
    try:
        # Fixed-interface normal modes Φ_ke (Eq. 3): boundary clamped, no rigid-body modes.
        sol = solve_modes_factored(Kee, Mee, n_modes, fac)  # blocked Krylov on Pardiso
        Phi = sol.shapes
        Lambda = sol.omega2
        log.info("craig_bampton: %d fixed-interface modes in %.1f s", n_modes, time.perf_counter() - t0)
        t0 = time.perf_counter()
        kappa, mu_be, mu_bb, Psi_out, Psi_kept = _constraint_modes(
            fac, (Keb, Kbb), (Mee, Meb, Mbb), Phi, out_rows, block_size, keep_basis)
    finally:
        fac.free()
    kappa = 0.5 * (kappa + kappa.T)
    mu_bb = 0.5 * (mu_bb + mu_bb.T)
    log.info("craig_bampton: n_e=%d, n_b=%d, n_k=%d (%.1f–%.1f Hz); constraint modes and Eq. 6 blocks in %.1f s",
             e.size, b.size, n_modes, sol.frequencies_hz[0], sol.frequencies_hz[-1], time.perf_counter() - t0)
    return Phi, Lambda, kappa, mu_be, mu_bb, Psi_out, Psi_kept


def _checked_boundary(n: int, boundary_dofs, n_modes, boundary_rotations) -> tuple[np.ndarray, np.ndarray | None]:
    """The boundary DOFs as int64 and their frames as float64, checked against a component of ``n`` DOFs.

    Raises
    ------
    ValueError
        Naming the bad boundary DOFs, mode count or frame shape.
    """
    b = np.asarray(boundary_dofs, dtype=np.int64).ravel()
    if b.size == 0:
        raise ValueError("boundary_dofs must not be empty")
    if b.min() < 0 or b.max() >= n:
        raise ValueError(f"boundary_dofs must index 0..{n - 1}")
    if np.unique(b).size != b.size:
        raise ValueError("boundary_dofs contains duplicates")
    if not (isinstance(n_modes, (int, np.integer)) and 1 <= n_modes < n - b.size):
        raise ValueError(f"n_modes must be an integer in 1..{n - b.size - 1}, got {n_modes!r}")
    if boundary_rotations is not None:
        boundary_rotations = np.asarray(boundary_rotations, dtype=np.float64)
        if boundary_rotations.shape != (b.size // 3, 3, 3) or b.size % 3:
            raise ValueError(f"boundary_rotations must have shape ({b.size // 3}, 3, 3) for {b.size} boundary DOFs")
    return b, boundary_rotations


def _constraint_modes(fac, Kb: tuple, Mb: tuple, Phi: np.ndarray, out_rows: np.ndarray, block_size: int,
                     keep_basis: bool):
    """Constraint modes Ψ = −K_ee⁻¹ K_eb (Eq. 3) and the blocks of Eq. 6, one block of boundary DOFs at a time.

    κ_bb = K_bb + K_be Ψ, μ_be = Ψᵀ M_ee Φ + M_be Φ (stored n_b × n_k), and μ_bb = Ψᵀ W + M_be Ψ + M_bb with
    W = M_ee Ψ + M_eb. Since Ψᵀ = −K_be K_ee⁻¹, the product Ψᵀ W_j is −K_be (K_ee⁻¹ W_j): a second block solve
    and a sparse product instead of the dense Ψᵀ W_j over all of Ψ. So Ψ (171 k × 1 302 doubles, 1.8 GB for a
    default slot) is never held whole unless it is kept, and the 0.6 TFlop product disappears.

    Parameters
    ----------
    fac : object with ``solve(b)``
        The factorization of K_ee.
    Kb, Mb : tuple
        (K_eb, K_bb) and (M_ee, M_eb, M_bb).
    Phi : ndarray, shape (n_e, n_k)
    out_rows : ndarray of int, shape (n_out_e,)
        Excess-DOF positions of the output DOFs that are excess DOFs.

    Returns
    -------
    kappa, mu_be, mu_bb : ndarray, shapes (n_b, n_b), (n_b, n_k), (n_b, n_b)
        Before symmetrisation, in the component frame.
    Psi_out : ndarray, shape (n_out_e, n_b)
        Rows of Ψ at ``out_rows``.
    Psi_kept : ndarray, shape (n_e, n_b), or None
        Ψ whole with ``keep_basis``.
    """
    Keb, Kbb = Kb
    Mee, Meb, Mbb = Mb
    n_e, n_b = Keb.shape
    kappa = np.empty((n_b, n_b))
    mu_be = np.empty((n_b, Phi.shape[1]))
    mu_bb = np.empty((n_b, n_b))
    Psi_out = np.empty((out_rows.size, n_b))
    Psi_kept = np.empty((n_e, n_b)) if keep_basis else None
    Kbe = Keb.T.tocsr()
    for j0 in range(0, n_b, block_size):
        j1 = min(j0 + block_size, n_b)
        Psi_j = -np.asarray(fac.solve(Keb[:, j0:j1].toarray(order="F"))).reshape(n_e, j1 - j0)
        W = Mee @ Psi_j + Meb[:, j0:j1]  # (n_e, bs)
        Y = np.asarray(fac.solve(W)).reshape(n_e, j1 - j0)
        kappa[:, j0:j1] = Kbb[:, j0:j1] + Kbe @ Psi_j
        mu_be[j0:j1] = W.T @ Phi
        mu_bb[:, j0:j1] = -(Kbe @ Y) + Meb.T @ Psi_j + Mbb[:, j0:j1]
        Psi_out[:, j0:j1] = Psi_j[out_rows]
        if Psi_kept is not None:
            Psi_kept[:, j0:j1] = Psi_j
    return kappa, mu_be, mu_bb, Psi_out, Psi_kept


def _output_basis(n: int, b: np.ndarray, pos_e: np.ndarray, out: np.ndarray, out_e: np.ndarray, Phi: np.ndarray,
                  Psi_out: np.ndarray, R: np.ndarray | None) -> np.ndarray:
    """Output rows of R_CB (Eq. 3), shape (n_out, n_k + n_b), with the boundary columns in the boundary frames."""
    pos_b = np.full(n, -1)
    pos_b[b] = np.arange(b.size)
    basis_out = np.zeros((out.size, Phi.shape[1] + b.size))
    basis_out[out_e, : Phi.shape[1]] = Phi[pos_e[out[out_e]]]
    basis_out[out_e, Phi.shape[1] :] = _rotate(R, Psi_out.T, True).T
    for r in np.flatnonzero(pos_e[out] < 0):
        unit = np.zeros(b.size)
        unit[pos_b[out[r]]] = 1.0
        basis_out[r, Phi.shape[1] :] = _rotate(R, unit[:, None], True)[:, 0]
    return basis_out


def disk_boundary_dofs(bd, slots: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Boundary DOFs of the disk slots ``slots`` and their slot rotations.

    For each slot: the ``L`` grid nodes (row-major), then the ``R`` grid nodes, three DOFs (x, y, z) per
    node. This is also the order of the blade's root boundary (:func:`rom.rubin.blade_boundary_dofs`).

    Returns
    -------
    dofs : ndarray of int, shape (n_slots · 2 · n_grid · 3,)
    rotations : ndarray, shape (n_slots · 2 · n_grid, 3, 3)
    """
    dofs, rots = [], []
    for s in slots:
        bd.check_slot(s)
        nodes = slot_flank_nodes(bd.disk, s)
        dofs.append(bd.disk.dofs_of(nodes).ravel())
        rots.append(np.broadcast_to(bd.slot_rotation(s), (nodes.size, 3, 3)))
    return np.concatenate(dofs), np.concatenate(rots)


def reduce_disk(
    bd,
    slots: Sequence[int] = (1,),
    n_modes: int = DEFAULT_N_CB_MODES,
    *,
    keep_basis: bool = False,
    backend: str = "auto",
) -> CraigBamptonModel:
    """Craig–Bampton model of the academic disk with the grids of ``slots`` as boundary.

    Boundary coordinates are in each slot's blade-local frame (see module notes); the output DOFs are the
    disk measurement DOFs (one per sector, direction z), in sector order.

    Parameters
    ----------
    bd : rom.academic.BladedDisk
    slots : sequence of int
        Slots (1..N) whose contact grids form the boundary: one slot for a disk–one-blade model.
    n_modes : int
        Fixed-interface modes n_k.
    """
    slots = tuple(int(s) for s in slots)
    if not slots:
        raise ValueError("slots must name at least one slot")
    if len(set(slots)) != len(slots):
        raise ValueError(f"slots contains duplicates: {slots}")
    dofs, rots = disk_boundary_dofs(bd, slots)
    meas = 3 * bd.disk.node_set("meas") + int(bd.disk.meta["meas_direction"]) - 1
    return craig_bampton(
        bd.disk,
        dofs,
        n_modes,
        output_dofs=meas,
        boundary_rotations=rots,
        keep_basis=keep_basis,
        backend=backend,
        meta={"slots": list(slots), "n_sectors": bd.n_slots, "grid": list(bd.params.grid),
              "cyclic": bool(getattr(bd, "cyclic", True))},
    )

