"""The all-slot Craig–Bampton disk from one sector and its harmonics (issue 12 item 4; docs/rom.md §4.4).

:func:`rom.cyclic.reduce_disk_cyclic` needs, for a disk of N identical sectors with every slot's contact grid
as boundary, the first block column of κ_bb and μ_bb (Eq. 6), the fixed-interface modes with every slot
clamped, their mass coupling μ_be to each slot, and the output rows. Factorizing the whole 148 k-DOF disk
interior and solving its 2 × n_i constraint-mode right-hand sides took 97–100 s. Here the same model is
computed exactly from sector 1 alone:

1. **Partition** (:func:`rom.cyclic_partition.sector_blocks`). Each node gets a sector (α = 2π/N) and the node
   of sector 1 it is a rotated copy of; sector s's nodes split into its left face c_s, its slot grid b_s and
   its interior i_s, and sector 1's couplings with every sector are kept.
2. **Sector condensation** (real, once). Sector 1's interior i_1 is eliminated statically, keeping
   q̃ = [c_1, b_1, c_2]: n_i + 2 n_c right-hand sides on a ~7 k-DOF factor. The ring of sectors then
   reduces to the q_s = [c_s, b_s] of every sector with block-circulant stiffness and mass
   (S_d = couplings of sector 1 with sector 1 + d).
3. **Harmonics** h = 0 … N/2 (dense, complex). Ŝ_h = Σ_d S_d e^(i h d α); eliminating the face c statically
   gives Ĉ_h (stiffness) and D̂_h (mass), the slot-DFT of the circulant blocks of Eq. 6; an inverse real FFT
   gives the block column. The face elimination is exact, so these are the all-slot CB's own blocks.
4. **Fixed-interface modes**: per harmonic, sector 1's interior and face (i, c) with the phase condition on
   the next sector's face: shift-invert ARPACK on that Hermitian pencil (complex for 0 < h < N/2), applied
   through the interior's factor and the face's Cholesky factor of step 3, so no harmonic is factorized.
   Each complex mode x gives two physical modes of the clamped disk, Re and Im of x e^(i h (s−1) α) in
   sector s, M-orthonormal after scaling by √(2/N) (one mode and √(1/N) for h = 0, N/2). The n_k lowest over
   all harmonics are kept.

Every quantity is in sector-local frames: a node of sector s is the rotated copy of a sector-1 node, and its
displacement is expressed in the frame rotated with it (slot grid nodes in their slot frames). Step 1 checks
that the disk is cyclic first.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .cyclic_partition import SectorBlocks
from .errors import ROMError
from .solver import anything_missed, available_backends, factorize, solve_modes_factored

__all__ = ["SectorReduction", "reduce_sectors"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class SectorReduction:
    """The all-slot CB disk's blocks, in harmonics, and its clamped modes (module notes, steps 2–4).

    Attributes
    ----------
    C_hat, D_hat : ndarray, shape (N // 2 + 1, n_i, n_i), complex
        Ĉ_h = Σ_d C_d e^(−2πi h d / N) (stiffness, κ_bb[s, t] = C_((s − t) mod N)) and D̂_h (mass), Hermitian.
    out_b1 : ndarray, shape (n_out, n_i)
        Output rows of slot 1's constraint modes.
    Lambda : ndarray, shape (n_k,)
        Clamped-disk eigenvalues ω² (rad²/s²), ascending.
    mu_be : ndarray, shape (N, n_i, n_k)
        μ_be = M_be Φ − K_be Φ Λ⁻¹ of each slot (Eq. 6; K_ee⁻¹ M_ee Φ = Φ Λ⁻¹ for exact modes).
    out_eta : ndarray, shape (n_out, n_k)
        Output rows of the mass-normalised clamped modes.
    """

    C_hat: np.ndarray
    D_hat: np.ndarray
    out_b1: np.ndarray
    Lambda: np.ndarray
    mu_be: np.ndarray
    out_eta: np.ndarray


def reduce_sectors(sb: SectorBlocks, n_modes: int, backend: str = "auto") -> SectorReduction:
    """Steps 2–4 of the module notes on the blocks of :func:`rom.cyclic_partition.sector_blocks`."""
    N, ni, nc, nb = sb.n_sectors, sb.n_int, sb.n_face, sb.n_i
    I_, C_ = slice(0, ni), slice(ni, ni + nc)
    nq = nc + nb
    t0 = time.perf_counter()
    K0, M0 = sb.K[0], sb.M[0]
    K1 = sb.K.get(1 % N, sp.csr_matrix(K0.shape))
    M1 = sb.M.get(1 % N, sp.csr_matrix(M0.shape))
    # Interior condensation: q̃ = [c_1, b_1, c_2].
    Kiq = sp.hstack([K0[I_, ni:], K1[I_, C_]]).tocsc()
    Miq = sp.hstack([M0[I_, ni:], M1[I_, C_]]).tocsc()
    Kii, Mii = K0[I_, I_].tocsr(), M0[I_, I_].tocsr()
    backend = "pardiso" if backend == "auto" and "pardiso" in available_backends() else backend
    fac = factorize(Kii, backend)  # kept: the clamped modes' operator uses it too
    try:
        # Blocks of 256 right-hand sides: one 4 020-column solve took 2.4 s, blocks of 256 1.1 s.
        Psi = np.empty((ni, nq + nc))
        for j0 in range(0, nq + nc, 256):
            j1 = min(j0 + 256, nq + nc)
            Psi[:, j0:j1] = -np.asarray(fac.solve(Kiq[:, j0:j1].toarray(order="F"))).reshape(ni, j1 - j0)
        t1 = time.perf_counter()
        ZK = np.asarray(Kiq.T @ Psi)  # K_q̃i Ψ = −K_q̃i K_ii⁻¹ K_iq̃
        A = np.asarray(Miq.T @ Psi)
        ZM = Psi.T @ (Mii @ Psi) + A + A.T  # the i-dependent part of Ψ̃ᵀ M Ψ̃ on q̃
        del A
        ZK = 0.5 * (ZK + ZK.T)
        ZM = 0.5 * (ZM + ZM.T)
        t2 = time.perf_counter()
        C_hat, D_hat, Gm, chol = _harmonics(sb, Psi, ZK, ZM)
        del ZK, ZM
        t3 = time.perf_counter()
        # Slot 1 displaced alone: b_s = δ_s1 = (1/N) Σ_h e^(i h (s−1) α); the face follows each harmonic.
        U = np.fft.irfft(Gm, n=N, axis=0)  # (N, n_out, 3, nb): sector s's response
        out_b1 = np.empty((len(sb.meas), nb))
        for k, s, dof3, w in sb.meas:
            u_s = U[s, k]
            if s == 0 and dof3[0] < ni:
                u_s = u_s + Psi[dof3, nc:nq]
            out_b1[k] = w @ u_s
        del Psi, U
        Lambda, mu_be, out_eta = _clamped_modes(sb, int(n_modes), fac, chol)
        t4 = time.perf_counter()
    finally:
        fac.free()
    log.info("cyclic CB: sector interior condensation %.1f s (%d right-hand sides), products %.1f s, "
             "%d harmonics %.1f s, %d clamped modes %.1f s", t1 - t0, nq + nc, t2 - t1, C_hat.shape[0], t3 - t2,
             n_modes, t4 - t3)
    return SectorReduction(C_hat, D_hat, out_b1, Lambda, mu_be, out_eta)


def _harmonics(sb: SectorBlocks, Psi, ZK, ZM):
    """Ĉ_h, D̂_h, the outputs' face-driven rows and the face's Cholesky factor for h = 0 … N/2 (step 3)."""
    N, ni, nc, nb = sb.n_sectors, sb.n_int, sb.n_face, sb.n_i
    nq = nc + nb
    c_sl, b_sl = slice(0, nc), slice(nc, nq)
    # Ring blocks on q_s = [c_s, b_s]: S_d couples sector 1's q with sector 1 + d's; sector 1's interior
    # condensation adds to d = 0, 1 and N − 1 (its c_2 is sector 2's face).
    S = {}
    for name, blk, Z in (("K", sb.K, ZK), ("M", sb.M, ZM)):
        Sd = {d: np.asarray(B[ni:, ni:].todense()) for d, B in blk.items()}
        for d in (0, 1 % N, (N - 1) % N):
            Sd.setdefault(d, np.zeros((nq, nq)))
        Sd[0] += Z[:nq, :nq]
        Sd[0][:nc, :nc] += Z[nq:, nq:]
        Sd[1 % N][:, :nc] += Z[:nq, nq:]
        Sd[(N - 1) % N][:nc, :] += Z[nq:, :nq]
        S[name] = Sd
    # The sub-blocks each harmonic needs, contiguous, and only the sector offsets d where they are non-zero
    # (a slot couples to no other slot, so Ŝ_bb is S_0's).
    parts = {(name, key): {d: np.ascontiguousarray(B[r, c]) for d, B in S[name].items() if np.any(B[r, c])}
             for name in ("K", "M")
             for key, (r, c) in {"cc": (c_sl, c_sl), "cb": (c_sl, b_sl), "bb": (b_sl, b_sl)}.items()}
    del S
    H = N // 2 + 1
    C_hat = np.empty((H, nb, nb), complex)
    D_hat = np.empty_like(C_hat)
    Gm = np.zeros((H, len(sb.meas), 3, nb), complex)  # output rows of the face-driven part, per harmonic
    chol = []
    for h in range(H):
        Sk = {key: _phase_sum(parts["K", key], h, N) for key in ("cc", "cb", "bb")}
        Sm = {key: _phase_sum(parts["M", key], h, N) for key in ("cc", "cb", "bb")}
        # Ŝ_cc = L Lᴴ, W = L⁻¹ Ŝ_cb: Ĉ = Ŝ_bb − Wᴴ W; the face follows the slot as X = −Ŝ_cc⁻¹ Ŝ_cb = −L⁻ᴴ W.
        try:
            L = sla.cholesky(Sk["cc"], lower=True, check_finite=False)  # reads the lower triangle only
        except np.linalg.LinAlgError:
            raise ROMError(f"harmonic {h}: the disk with every slot clamped is not positive definite at the "
                           "sector faces; check its stiffness matrix") from None
        W = sla.solve_triangular(L, Sk["cb"], lower=True, check_finite=False)
        C_hat[h] = _herm(Sk["bb"] - _gram(W))
        X = -sla.solve_triangular(L, W, lower=True, trans="C", check_finite=False)
        del W
        # D̂ = M_bb + M_bc X + Xᴴ M_cb + Xᴴ M_cc X, the Hermitian part of M_bb + Xᴴ (M_cc X + 2 M_cb).
        D_hat[h] = _herm(Sm["bb"] + X.conj().T @ (Sm["cc"] @ X + 2 * Sm["cb"]))
        ph = np.exp(2j * np.pi * h / N)
        for k, (_, _, dof3, _) in enumerate(sb.meas):
            if dof3[0] < ni:  # interior node: Ψ row on [c_1, b_1, c_2]
                Gm[h, k] = Psi[dof3, :nc] @ X + Psi[dof3, nq:] @ X * ph
            else:
                Gm[h, k] = X[dof3 - ni]
        chol.append(L)
    return C_hat, D_hat, Gm, chol


def _phase_sum(parts: dict, h: int, N: int):
    """Σ_d B_d e^(i h d α) (dense or sparse blocks), real where every phase is (h = 0, N/2, or only d = 0)."""
    re = sum(B * math.cos(2 * math.pi * h * d / N) for d, B in parts.items())
    im = [B * math.sin(2 * math.pi * h * d / N) for d, B in parts.items() if (2 * h * d) % N]
    return re + 1j * sum(im) if im else re


def _herm(A: np.ndarray) -> np.ndarray:
    """The Hermitian part of a square matrix (evens out round-off)."""
    return 0.5 * (A + A.conj().T)


def _gram(W: np.ndarray) -> np.ndarray:
    """Wᴴ W by a rank-k update (half a product's work), both triangles filled."""
    herk = sla.blas.zherk if np.iscomplexobj(W) else sla.blas.dsyrk
    G = herk(1.0, np.asfortranarray(W), trans=2 if np.iscomplexobj(W) else 1)  # upper triangle
    return np.triu(G) + np.triu(G, 1).conj().T


class _HarmonicInverse:
    """Harmonic h's (K̂_ee)⁻¹ from the interior factor and the face's Schur complement L Lᴴ.

    K̂_ee on [i, c] has K_ii (real, the same for every h) and Ŝ_cc = K̂_cc − K̂_ci K_ii⁻¹ K̂_ic, factored in
    :func:`_harmonics`; so no harmonic needs a factorization of its own. Complex vectors for 0 < h < N/2.
    """

    def __init__(self, fac, Kic, Kci, L, ni: int):
        self.fac, self.Kic, self.Kci, self.L, self.ni = fac, Kic, Kci, L, ni

    def _kii(self, z: np.ndarray) -> np.ndarray:
        if not np.iscomplexobj(z):
            return np.asarray(self.fac.solve(z)).reshape(z.shape)
        k = z.shape[1]
        y = np.asarray(self.fac.solve(np.hstack([z.real, z.imag]))).reshape(z.shape[0], 2 * k)
        return y[:, :k] + 1j * y[:, k:]

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b)
        z = b.reshape(b.shape[0], -1)
        ni = self.ni
        y = self._kii(z[:ni])
        xc = sla.solve_triangular(self.L, z[ni:] - self.Kci @ y, lower=True, check_finite=False)
        xc = sla.solve_triangular(self.L, xc, lower=True, trans="C", check_finite=False)
        x = np.vstack([self._kii(z[:ni] - self.Kic @ xc), xc])
        return x.reshape(b.shape)


def _clamped_modes(sb: SectorBlocks, n_modes: int, fac, chol: list):
    """The ``n_modes`` lowest modes of the disk with every slot clamped (module notes, step 4).

    Harmonic h's complex modes x each give two physical modes, Re and Im of x e^(i h (s−1) α) in sector s
    (one for h = 0, N/2). Each harmonic is asked for a few more modes than an even share; one whose highest
    mode is still below the n-th lowest overall may hold more and is asked again for twice as many.
    """
    N, nb = sb.n_sectors, sb.n_i
    H = N // 2 + 1
    ne = sb.n_int + sb.n_face

    def mult(h):  # physical modes per harmonic mode
        return 1 if h == 0 or 2 * h == N else 2

    per = {}
    k_h = dict.fromkeys(range(H), math.ceil(n_modes / N) + 3)
    for _ in range(12):
        for h in range(H):
            if h not in per or per[h][0].size < k_h[h]:
                per[h] = _harmonic_modes(sb, h, min(k_h[h], ne - 2), fac, chol[h])
        lam_all = np.sort(np.concatenate([np.repeat(per[h][0], mult(h)) for h in range(H)]))
        cut = lam_all[min(n_modes, lam_all.size) - 1]
        short = [h for h in range(H) if per[h][0][-1] <= cut * (1 + 1e-9) and per[h][0].size < ne - 2]
        if lam_all.size >= n_modes and not short:
            break
        for h in short or range(H):
            k_h[h] *= 2
    else:  # pragma: no cover - the doubling reaches every harmonic's size long before
        raise ROMError("the clamped disk's modes could not be collected harmonic by harmonic")
    # Physical modes: (λ, h, index in the harmonic, part 0 = Re / 1 = Im).
    rows = [(lam, h, q, part) for h in range(H) for q, lam in enumerate(per[h][0]) for part in range(mult(h))]
    rows.sort()
    rows = rows[:n_modes]
    s = np.arange(N)
    mu_be = np.empty((N, nb, n_modes))
    out_eta = np.empty((len(sb.meas), n_modes))
    for j, (_, h, q, part) in enumerate(rows):
        _, x, mb = per[h]
        # Unit Hermitian mass per sector: the cos (sin) shape has mass N/2 over the disk, N for h = 0, N/2.
        scale = math.sqrt(mult(h) / N)
        ph = np.exp(2j * np.pi * h * s / N) * (1 if part == 0 else -1j)  # Im(z) = Re(−i z)
        mu_be[:, :, j] = scale * np.real(ph[:, None] * mb[None, :, q])
        for k, sec, dof3, w in sb.meas:
            out_eta[k, j] = scale * np.real(ph[sec] * (w @ x[dof3, q]))
    log.info("cyclic CB: %d clamped modes from %d harmonics (%d harmonic modes)", n_modes, H,
             sum(per[h][0].size for h in range(H)))
    return np.array([r[0] for r in rows]), mu_be, out_eta


def _harmonic_modes(sb: SectorBlocks, h: int, k: int, fac, L):
    """Lowest ``k`` modes of harmonic h on sector 1's interior and face: ω², M̂-normalised x, μ_be rows of slot 1.

    ARPACK on the Hermitian pencil itself (complex for 0 < h < N/2). Its real form [[A, −B], [B, A]] doubles
    every eigenvalue and needed about twice the operator applications; a block Lanczos needed ~3.5× the
    vectors (docs/rom.md §4.4).
    """
    N, ni, nc = sb.n_sectors, sb.n_int, sb.n_face
    ne = ni + nc
    E, Bs, I_, C_ = slice(0, ne), slice(ne, None), slice(0, ni), slice(ni, ne)
    real = h == 0 or 2 * h == N

    def hsum(blk, r, c):
        return sp.csr_matrix(_phase_sum({d: B[r, c] for d, B in blk.items()}, h, N))

    Kh, Mh = hsum(sb.K, E, E), hsum(sb.M, E, E)
    Kh, Mh = 0.5 * (Kh + Kh.conj().T), 0.5 * (Mh + Mh.conj().T)
    inv = _HarmonicInverse(fac, hsum(sb.K, I_, C_), hsum(sb.K, C_, I_), L, ni)
    if real:
        sol = solve_modes_factored(Kh, Mh, int(k), inv)
        lam, x = sol.omega2, sol.shapes
    else:
        lam, x = _complex_modes(Kh, Mh, int(k), inv)
    mb = (hsum(sb.M, Bs, E) @ x) - (hsum(sb.K, Bs, E) @ x) / lam
    return lam, x, mb


def _complex_modes(K, M, k: int, inv, max_rounds: int = 4):
    """Lowest ``k`` eigenpairs of a Hermitian positive-definite pencil by shift-invert ARPACK (σ = 0).

    Like :func:`rom.solver.solve_modes_factored` for real pencils: a cheap deflated block check after the
    Lanczos run looks for an eigenvalue below the highest found that Lanczos missed (a repeated one); if it
    finds one, the run is repeated for more modes.
    """
    n = K.shape[0]
    op = spla.LinearOperator((n, n), matvec=inv.solve, dtype=complex)
    v0 = np.random.default_rng(0).standard_normal(n).astype(complex)
    kk = k
    for _ in range(max_rounds):
        vals, vecs = spla.eigs(K, k=kk, M=M, sigma=0.0, which="LM", OPinv=op, tol=1e-12, v0=v0)
        # The non-Hermitian driver leaves nearly equal eigenvalues' vectors not quite M-orthogonal: a
        # Rayleigh–Ritz step on them gives M-orthonormal vectors (μ_ηη = I) with the same span.
        lam, Y = sla.eigh(_herm(vecs.conj().T @ (K @ vecs)), _herm(vecs.conj().T @ (M @ vecs)), check_finite=False)
        X = vecs @ Y
        if not anything_missed(K, M, inv, lam, X, 2):
            return lam[:k], X[:, :k]
        kk = min(2 * kk, n - 2)
    raise ROMError("the clamped disk's harmonic modes are incomplete after repeated Lanczos runs")
