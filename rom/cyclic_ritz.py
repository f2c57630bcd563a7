"""The Rayleigh–Ritz space of :func:`rom.cyclic.solve_full_cyclic` (module notes of :mod:`rom.cyclic`, steps 1–3).

Each slot with its blade carries an orthonormal local basis in its own coordinates (:class:`RitzSlot`),
grown from approximate local modes (:func:`local_modes`) and block-Jacobi corrections (:func:`new_local`,
:func:`append_local`); the global CC vectors (:func:`global_cc`) are made orthogonal to every local basis
in :func:`ritz`, which solves the projected pencil. :func:`residual_rows` gives the residuals in the full
all-slot CB model with the blades, :func:`outputs` the measurement rows.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .contact import ContactPattern
from .cyclic_model import CyclicDiskModel
from .errors import ROMError
from .modal import dense_modes
from .rom_assembly import blade_part
from .rubin import RubinModel

__all__ = ["RitzSlot", "local_modes", "new_local", "append_local", "global_cc", "ritz", "residual_rows", "outputs"]

#: Local subspace iterations for the starting local modes.
_LOCAL_ITERATIONS = 4


class RitzSlot:
    """One slot with its blade in local coordinates [x (n_i, slot frame), the blade's own coordinates]."""

    def __init__(self, disk: CyclicDiskModel, blade: RubinModel, pattern: ContactPattern, delta, formulation: str,
                 slot: int):
        se, iface_pos, contact = blade_part(blade, pattern, delta, formulation)
        n_i = disk.n_i
        nm = se.n_modal
        n_free = int((~contact).sum())
        self.n = n_i + nm + n_free
        idx = np.empty(se.n, np.int64)
        idx[:nm] = n_i + np.arange(nm)
        bidx = idx[nm:]
        bidx[contact] = iface_pos[contact]
        bidx[~contact] = n_i + nm + np.arange(n_free)
        self.Kb = np.zeros((self.n, self.n))
        self.Mb = np.zeros((self.n, self.n))
        self.Kb[np.ix_(idx, idx)] = se.K
        self.Mb[np.ix_(idx, idx)] = se.M
        self.acc = bidx[iface_pos < 0]
        K = self.Kb.copy()
        K[:n_i, :n_i] += disk.kappa_col[0]
        self.M = self.Mb.copy()
        self.M[:n_i, :n_i] += disk.mu_col[0]
        # The slot held by the others is positive definite: one Cholesky factor serves the local modes and
        # every block-Jacobi correction. ContactPattern already refuses patterns that leave the blade a
        # mechanism; a nearly collinear one can still fail numerically.
        try:
            self.K_chol = sla.cho_factor(K, overwrite_a=True, check_finite=False)  # K is this call's own copy
            self.own_chol = sla.cho_factor(self.Kb[n_i:, n_i:], check_finite=False)
        except np.linalg.LinAlgError:
            raise ROMError(f"slot {slot}: its contact pattern ({int(contact.sum()) // 3} contacting nodes) does not "
                           "hold the blade firmly enough; solve this assembly with the sparse hybrid "
                           "(rom.rom_assembly.solve_full)") from None
        self.L = np.zeros((self.n, 0))  # orthonormal local basis
        self.CL = np.zeros((disk.n_slots, n_i, 0))  # κ_bb[t, s] X_s for every slot t
        self.DL = np.zeros((disk.n_slots, n_i, 0))  # μ_bb[t, s] X_s


def local_modes(slot: RitzSlot, n_modes: int, seed: int) -> np.ndarray:
    """Approximate lowest local modes: subspace iteration on the slot's Cholesky factor (a start, not a result)."""
    X = np.random.default_rng(seed).standard_normal((slot.n, 2 * n_modes))
    for _ in range(_LOCAL_ITERATIONS):
        X = sla.cho_solve(slot.K_chol, slot.M @ X, check_finite=False)
        X, _ = np.linalg.qr(X)
    return X


def new_local(slot: RitzSlot, W: np.ndarray, tol: float) -> np.ndarray:
    """The dominant directions of ``W`` (local coordinates) not yet in the slot's basis, orthonormal."""
    if slot.L.shape[1]:
        for _ in range(2):  # CGS2 against the basis already there
            W = W - slot.L @ (slot.L.T @ W)
    nrm = np.linalg.norm(W, axis=0)
    W = W[:, nrm > 0] / nrm[nrm > 0]
    if W.shape[1] == 0:
        return W
    u, sv, _ = np.linalg.svd(W, full_matrices=False)
    u = u[:, sv > tol * sv[0]]
    if slot.L.shape[1]:
        u = u - slot.L @ (slot.L.T @ u)
        u, _ = np.linalg.qr(u)
    return u


def append_local(disk: CyclicDiskModel, slots: list[RitzSlot], new: list[np.ndarray]) -> None:
    """Append new local columns to every slot's basis, with their products with the circulant blocks.

    κ_bb[t, s] = C_((t − s) mod N): one product of the stacked first block column (N · n_i × n_i) with every
    slot's new columns side by side reads the blocks once (the products are memory-bound one slot at a time).
    """
    N, n_i = disk.n_slots, disk.n_i
    X = np.hstack([u[:n_i] for u in new])
    CX = (disk.kappa_col.reshape(N * n_i, n_i) @ X).reshape(N, n_i, -1)
    DX = (disk.mu_col.reshape(N * n_i, n_i) @ X).reshape(N, n_i, -1)
    c0 = 0
    for s, (sl, u) in enumerate(zip(slots, new, strict=True)):
        cs = slice(c0, c0 + u.shape[1])
        c0 += u.shape[1]
        order = (np.arange(N) - s) % N
        sl.L = np.hstack([sl.L, u])
        # Index the slot's own columns first: CX[order] alone would copy every slot's columns N times.
        sl.CL = np.concatenate([sl.CL, CX[order, :, cs]], axis=2)
        sl.DL = np.concatenate([sl.DL, DX[order, :, cs]], axis=2)


def global_cc(disk: CyclicDiskModel, n_cc: int):
    """Real global CC vectors at the slots and their products with the circulant K and M blocks.

    Returns
    -------
    G, CG, DG : ndarray, shape (N, n_i, n_g)
    """
    N = disk.n_slots
    ph = np.exp(2j * np.pi * np.outer(np.arange(N), np.arange(disk.cc_modes.shape[0])) / N)  # (N, H)
    G, CG, DG = [], [], []
    for h in range(disk.cc_modes.shape[0]):
        psi = disk.cc_modes[h][:, :n_cc]
        dpsi = disk.cc_mass[h][:, :n_cc]
        w2 = disk.cc_omega2[h][:n_cc]
        # A harmonic vector x_s = ψ e^(2πi h s / N) has (C x)_s = e^(2πi h s / N) Ĉ_h ψ = ω² (D x)_s.
        x = ph[:, h, None, None] * psi[None]
        dx = ph[:, h, None, None] * dpsi[None]
        parts = [np.real] if h == 0 or 2 * h == N else [np.real, np.imag]
        for part in parts:
            G.append(part(x))
            DG.append(part(dx))
            CG.append(part(dx) * w2)
    return np.concatenate(G, axis=2), np.concatenate(CG, axis=2), np.concatenate(DG, axis=2)


def ritz(disk, slots, G0, CG0, DG0, G0own, n_modes):
    """Rayleigh–Ritz on [η, every slot's local basis, the global CC vectors made orthogonal to them]."""
    N, n_i, n_k = disk.n_slots, disk.n_i, disk.n_k
    # Global vectors minus their local components (span kept, now orthogonal to every local basis).
    coef = [sl.L.T @ np.vstack([G0[k], G0own[k]]) for k, sl in enumerate(slots)]
    Gx = G0.copy()
    Gown = [g.copy() for g in G0own]
    CG, DG = CG0.copy(), DG0.copy()
    for k, sl in enumerate(slots):
        loc = sl.L @ coef[k]
        Gx[k] -= loc[:n_i]
        Gown[k] -= loc[n_i:]
        CG -= sl.CL @ coef[k]
        DG -= sl.DL @ coef[k]
    # Orthonormalise what is left (directions already in the local spaces drop out).
    flat = np.vstack([Gx.reshape(N * n_i, -1)] + Gown)
    u, sv, vt = np.linalg.svd(flat, full_matrices=False)
    keep = sv > 1e-6 * sv[0]  # what is left of a dropped direction is within 1e-6 of the local spaces
    T = vt[keep].T / sv[keep]  # Gflat @ T = u[:, keep]
    Gx, CG, DG = Gx @ T, CG @ T, DG @ T
    Gown = [g @ T for g in Gown]
    Gflat = Gx.reshape(N * n_i, -1)
    mu_be_flat = disk.mu_be.reshape(N * n_i, n_k)
    n_g = T.shape[1]
    sizes = [n_k] + [sl.L.shape[1] for sl in slots] + [n_g]
    off = np.concatenate([[0], np.cumsum(sizes)])
    n_red = int(off[-1])
    Kr = np.zeros((n_red, n_red))
    Mr = np.zeros((n_red, n_red))
    Kr[np.arange(n_k), np.arange(n_k)] = disk.Lambda
    Mr[np.arange(n_k), np.arange(n_k)] = 1.0
    gsl = slice(off[-2], off[-1])
    # Global–global: disk blocks, then each blade on its slot.
    Kr[gsl, gsl] = Gflat.T @ CG.reshape(N * n_i, -1)
    Mr[gsl, gsl] = Gflat.T @ DG.reshape(N * n_i, -1)
    Mr[:n_k, gsl] = mu_be_flat.T @ Gflat
    # Each blade's products with the slot's global and local columns, formed once: the Ritz blocks and the
    # residuals (residual_rows) take them, and the n × n products are most of a round's work.
    KG, MG, KL, ML = [], [], [], []
    for k, sl in enumerate(slots):
        ls = slice(off[1 + k], off[2 + k])
        X = sl.L[:n_i]
        gl = np.vstack([Gx[k], Gown[k]])
        KG.append(sl.Kb @ gl)
        MG.append(sl.Mb @ gl)
        KL.append(sl.Kb @ sl.L)
        ML.append(sl.Mb @ sl.L)
        Kr[gsl, gsl] += gl.T @ KG[k]
        Mr[gsl, gsl] += gl.T @ MG[k]
        # η–local: mass coupling only (K_ηb = 0 in a CB model).
        Mr[:n_k, ls] = disk.mu_be[k].T @ X
        # local–local, every slot pair: X_tᵀ κ_bb[t, s] X_s.
        for j, sj in enumerate(slots):
            lj = slice(off[1 + j], off[2 + j])
            Xj = sj.L[:n_i]
            Kr[lj, ls] = Xj.T @ sl.CL[j]
            Mr[lj, ls] = Xj.T @ sl.DL[j]
        Kr[ls, ls] += sl.L.T @ KL[k]
        Mr[ls, ls] += sl.L.T @ ML[k]
        # global–local: Gᵀ K L_s = Σ_t G_tᵀ κ_bb[t, s] X_s + (slot s's blade); κ_bb is symmetric, so the sum is
        # (κ_bb G)_sᵀ X_s, which CG holds: N times fewer products than summing over the slots.
        Kr[gsl, ls] = CG[k].T @ X + gl.T @ KL[k]
        Mr[gsl, ls] = DG[k].T @ X + gl.T @ ML[k]
    # Mirror the blocks filled on one side only, then even out round-off.
    Mr[gsl, :n_k] = Mr[:n_k, gsl].T
    Mr[n_k : off[-2], :n_k] = Mr[:n_k, n_k : off[-2]].T
    Kr[n_k : off[-2], gsl] = Kr[gsl, n_k : off[-2]].T
    Mr[n_k : off[-2], gsl] = Mr[gsl, n_k : off[-2]].T
    Kr = 0.5 * (Kr + Kr.T)
    Mr = 0.5 * (Mr + Mr.T)
    dm = dense_modes(Kr, Mr, n_modes)
    lam = (2 * np.pi * dm.frequencies_hz) ** 2
    parts = {"off": off, "Gx": Gx, "Gown": Gown, "CG": CG, "DG": DG, "KG": KG, "MG": MG, "KL": KL, "ML": ML}
    return lam, dm.shapes, parts


def residual_rows(disk, slots, parts, Y, lam):
    """Residuals K v − λ M v of the Ritz vectors, by row group: [η, slot 1 local, …, slot N local].

    Also returns ‖K v‖ and ‖M v‖ over all rows.
    """
    N, n_i, n_k = disk.n_slots, disk.n_i, disk.n_k
    off, Gx, CG, DG = parts["off"], parts["Gx"], parts["CG"], parts["DG"]
    Yg = Y[off[-2] : off[-1]]
    Ye = Y[:n_k]
    # x rows of every slot: disk blocks on the global and local parts, μ_be on η.
    KX = CG @ Yg
    MX = DG @ Yg + disk.mu_be @ Ye
    Mη = Ye + disk.mu_be.reshape(N * n_i, n_k).T @ (Gx @ Yg).reshape(N * n_i, -1)
    for k, sl in enumerate(slots):
        Yl = Y[off[1 + k] : off[2 + k]]
        KX += sl.CL @ Yl
        MX += sl.DL @ Yl
        Mη += disk.mu_be[k].T @ (sl.L[:n_i] @ Yl)
    Kη = disk.Lambda[:, None] * Ye
    R = [Kη - Mη * lam]
    kn2 = np.sum(Kη**2, axis=0)
    mn2 = np.sum(Mη**2, axis=0)
    for k in range(len(slots)):
        Yl = Y[off[1 + k] : off[2 + k]]
        # the blade's K v and M v from its products with the slot's columns (v = L Y_l + g Y_g)
        Kv = parts["KL"][k] @ Yl + parts["KG"][k] @ Yg
        Mv = parts["ML"][k] @ Yl + parts["MG"][k] @ Yg
        Kv[:n_i] += KX[k]
        Mv[:n_i] += MX[k]
        R.append(Kv - Mv * lam)
        kn2 += np.sum(Kv**2, axis=0)
        mn2 += np.sum(Mv**2, axis=0)
    return R, np.sqrt(kn2), np.sqrt(mn2)


def outputs(disk, slots, parts, Y):
    """Disk measurement DOFs (one per sector) then each blade's accessory DOFs, shape (n_meas, n_modes)."""
    n_i, n_k = disk.n_i, disk.n_k
    off, Gx, Gown = parts["off"], parts["Gx"], parts["Gown"]
    Yg = Y[off[-2] : off[-1]]
    meas_disk = disk.out_eta @ Y[:n_k]
    rows = []
    for k, sl in enumerate(slots):
        v = sl.L @ Y[off[1 + k] : off[2 + k]] + np.vstack([Gx[k], Gown[k]]) @ Yg
        meas_disk += np.roll(disk.out_b1, k, axis=0) @ v[:n_i]
        rows.append(v[sl.acc])
    return np.vstack([meas_disk] + rows)
