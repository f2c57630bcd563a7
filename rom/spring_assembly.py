"""The disk–one-blade ROM on contact springs in affine form: the full model of :mod:`rom.reduced_basis` (issue 46).

The CB disk of one slot (Eqs. 2–6) and the Rubin super-element with *every* boundary DOF kept (Eqs. 15–17) are
joined node by node by massless springs (:mod:`rom.contact_stiffness`). Both sides of every flank node stay
coordinates, so size and mass never depend on the pattern, and the stiffness is affine in the pattern and in
the blade mistuning δ (Eq. 19 moves only the modal diagonal, Ω_f² = diag((1 + δ_j) ω_j²))::

    K(θ) = K₀ + Σ_i p_i D_i S_i D_iᵀ + Σ_j δ_j ω_j² e_j e_jᵀ = K₀ + E S(θ) Eᵀ,   M fixed,   θ = [p; δ],

p_i ∈ {0, 1} per flank node (L grid then R grid, row-major), S_i = A_i (k_n n nᵀ + k_t (I − n nᵀ)) its spring
(N/m), D_iᵀ x = x_blade,i − x_disk,i (index arrays, never an n × n matrix), e_j the free-interface coordinate j.
A detached node is a node without spring.

The "exact" compliance formulation (``solve_d1b`` of ``with_contact_stiffness``) is this model with the blade's
residual-attachment coordinates condensed statically onto the springs: a Rayleigh–Ritz restriction of it, so its
frequencies lie above, by ≤ 1e-10 at the joint's 1e14 N/m³ (accurate eigen-solves, coarse and default levels;
the dense solvers' own scatter is ~1e-8). Stiffer springs approach the rigid ties as 1/k (5e-6 at 1e17 N/m³).
The model is a penalty form: from k ≈ 1e18 N/m³ (coarse model) the springs swamp the structure's stiffness in
double precision and its solves fail; the compliance formulation stays exact up to rigid ties.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .contact import ContactPattern
from .contact_stiffness import ContactStiffness, interface_compliance
from .craig_bampton import CraigBamptonModel
from .fe_assembly import AssemblyModes
from .mistuning import as_delta
from .modal import dense_modes, single_thread_blas
from .rom_assembly import check_pattern, d1b_slot, grid_shape, measurement_labels
from .rubin import RubinModel

__all__ = ["SpringD1B", "spring_d1b", "solve_spring_d1b"]

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True, eq=False)
class SpringD1B:
    """The disk–one-blade ROM on contact springs in affine form (module notes); build it with :func:`spring_d1b`.

    Coordinates ``[η_k; x_slot; η_r; η_f; x_root; x_acc]``: the CB disk's, then the Rubin super-element's.

    Attributes
    ----------
    K0, M : ndarray, shape (n, n)
        Stiffness without springs at δ = 0 (N/m) and mass (kg, positive definite, the same at every θ).
    springs : ndarray, shape (n_nodes, 3, 3)
        S_i, each flank node's spring (N/m) in the blade frame.
    blade_dofs, disk_dofs : ndarray of int, shape (n_nodes, 3)
        The coordinates each spring joins: D_iᵀ x = x[blade_dofs[i]] − x[disk_dofs[i]].
    modal_index : ndarray of int, shape (m,)
        The coordinates η_f (e_j of Eq. 19's affine term).
    omega2, delta : ndarray, shape (m,)
        Tuned free-interface eigenvalues ω_j² (rad²/s²); the blade's own δ (used where a solve gets none).
    out : ndarray, shape (n_meas, n)
        Coordinates to measurement DOFs, labelled by ``meas_labels``.
    grid : (int, int)
    rigid : ndarray, shape (n, 6)
        M-orthonormal rigid-body modes, null vectors of K(θ) at every pattern that holds the blade.
    """

    K0: np.ndarray
    M: np.ndarray
    springs: np.ndarray
    blade_dofs: np.ndarray
    disk_dofs: np.ndarray
    modal_index: np.ndarray
    omega2: np.ndarray
    delta: np.ndarray
    out: np.ndarray
    meas_labels: list
    grid: tuple[int, int]
    rigid: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(self.K0.shape[0])

    @property
    def n_nodes(self) -> int:
        return int(self.springs.shape[0])

    @property
    def m(self) -> int:
        return int(self.omega2.size)

    def operator(self) -> sp.csr_matrix:
        """E = [D_1 … D_N, e_1 … e_m], shape (n, 3 n_nodes + m): the affine terms' columns (sparse)."""
        n3 = 3 * self.n_nodes
        rows = np.concatenate([self.blade_dofs.ravel(), self.disk_dofs.ravel(), self.modal_index])
        cols = np.concatenate([np.arange(n3), np.arange(n3), n3 + np.arange(self.m)])
        vals = np.concatenate([np.ones(n3), -np.ones(n3), np.ones(self.m)])
        return sp.csr_matrix((vals, (rows, cols)), shape=(self.n, n3 + self.m))

    def parameters(self, pattern: ContactPattern, delta=None) -> np.ndarray:
        """θ = [p (n_nodes); δ (m)] of a pattern and a δ (None: the blade's own), shape (n_nodes + m,)."""
        check_pattern(pattern, self.grid, int(self.meta.get("slot", 1)))
        p = np.concatenate([pattern.L.ravel(), pattern.R.ravel()]).astype(np.float64)
        return np.concatenate([p, self.delta if delta is None else as_delta(delta, self.m)])

    def K(self, theta: np.ndarray) -> np.ndarray:
        """K(θ) = K₀ + E S(θ) Eᵀ, dense, shape (n, n) (N/m)."""
        theta = np.asarray(theta, np.float64)
        K = self.K0.copy()
        S = self.springs * theta[: self.n_nodes, None, None]
        b, k = self.blade_dofs, self.disk_dofs
        for r, c, sign in ((b, b, 1.0), (k, k, 1.0), (b, k, -1.0), (k, b, -1.0)):
            np.add.at(K, (r[:, :, None], c[:, None, :]), sign * S)
        K[self.modal_index, self.modal_index] += theta[self.n_nodes :] * self.omega2
        return K


def spring_d1b(
    disk: CraigBamptonModel,
    blade: RubinModel,
    parts: np.ndarray,
    stiffness: ContactStiffness,
    slot: int | None = None,
) -> SpringD1B:
    """Assemble the affine disk–one-blade model on springs (module notes).

    Parameters
    ----------
    disk : CraigBamptonModel
        Reduced on one slot (as for :func:`rom.rom_assembly.assemble_d1b`).
    blade : RubinModel
        The blade without springs (``G_bb`` the rigid-tie one); its δ becomes the model's default δ.
    parts : ndarray, shape (2, n_nodes, 3, 3)
        :func:`rom.contact_stiffness.blade_compliance_parts` of the FE blade (m³/N at 1 N/m³).
    stiffness : ContactStiffness
        k_n, k_t (N/m³).
    slot : int, optional
        Slot 1..N of a cyclic disk (default: the disk model's own).

    Returns
    -------
    SpringD1B
    """
    if not isinstance(stiffness, ContactStiffness):
        raise ValueError(f"stiffness must be a ContactStiffness (N/m³), got {type(stiffness).__name__}")
    if blade.meta.get("contact_compliance"):
        raise ValueError("the blade already carries spring compliance (with_contact_stiffness); pass the bare blade")
    ref, slot, n_sec = d1b_slot(disk, slot)
    n_i, n_nodes = blade.n_interface, blade.n_interface // 3
    if disk.n_b != n_i:
        raise ValueError(f"disk boundary ({disk.n_b} DOFs) does not match the blade root ({n_i} DOFs)")
    if np.shape(parts) != (2, n_nodes, 3, 3):
        raise ValueError(f"parts must have shape (2, {n_nodes}, 3, 3) (blade_compliance_parts), got {np.shape(parts)}")
    # Each node's spring from its compliance, node by node: S_i = C_i⁻¹ = A_i (k_n n nᵀ + k_t (I − n nᵀ)).
    C = interface_compliance(np.asarray(parts, np.float64), stiffness)
    S = np.linalg.inv(0.5 * (C + C.transpose(0, 2, 1)))
    S = 0.5 * (S + S.transpose(0, 2, 1))
    se = blade.with_delta(0.0).superelement()  # every boundary DOF kept; δ enters as an affine term
    nd, nb = disk.n, se.n
    n = nd + nb
    K0, M = np.zeros((n, n)), np.zeros((n, n))
    disk.K(out=K0)
    disk.M(out=M)
    K0[nd:, nd:] = se.K
    M[nd:, nd:] = se.M
    root = nd + se.n_modal + np.arange(n_i)
    out = np.zeros((n_sec + blade.n_b - n_i, n))
    out[:n_sec, :nd] = disk.output_basis[(np.arange(n_sec) - (slot - ref)) % n_sec]
    out[n_sec + np.arange(blade.n_b - n_i), nd + se.n_modal + n_i + np.arange(blade.n_b - n_i)] = 1.0
    model = SpringD1B(K0, M, S, root.reshape(-1, 3), disk.n_k + np.arange(n_i).reshape(-1, 3),
                      nd + se.n_r + np.arange(blade.m), blade.omega2_tuned.copy(), blade.delta.copy(), out,
                      measurement_labels(n_sec, [slot], blade.n_b - n_i), grid_shape(blade), np.zeros((n, 0)),
                      {"slot": slot, "stiffness_n_per_m3": (stiffness.normal_n_per_m3, stiffness.tangential_n_per_m3)})
    return replace(model, rigid=_rigid_modes(model.K(np.r_[np.ones(n_nodes), np.zeros(blade.m)]), M))


def _rigid_modes(K: np.ndarray, M: np.ndarray, n_rigid: int = 6) -> np.ndarray:
    """M-orthonormal null space (n, n_rigid) of the bonded K by shifted inverse iteration.

    Rigid motions strain no spring, so they are null vectors of K(θ) at every pattern that holds the blade.
    A shift of 1 Hz² separates ω² = 0 from the lowest elastic ω² by ≥ 4 decades per iteration.
    """
    cho = sla.cho_factor(K + (TWO_PI * 1.0) ** 2 * M, lower=True)
    X = np.random.default_rng(0).standard_normal((K.shape[0], 2 * n_rigid))
    for _ in range(4):
        X = sla.qr(sla.cho_solve(cho, M @ X), mode="economic")[0]
    _, Y = sla.eigh(X.T @ K @ X, X.T @ M @ X)
    return X @ Y[:, :n_rigid]


def solve_spring_d1b(model: SpringD1B, pattern: ContactPattern, n_modes: int = 10, *, delta=None) -> AssemblyModes:
    """Direct full-order solve of the spring model at one pattern (dense eigen-solve, rigid modes dropped)."""
    with single_thread_blas():
        K = model.K(model.parameters(pattern, delta))
        dm = dense_modes(K, model.M.copy(), n_modes, overwrite=True)
    return AssemblyModes(dm.frequencies_hz, model.out @ dm.shapes, list(model.meas_labels))
