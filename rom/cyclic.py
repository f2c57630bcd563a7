"""Full bladed-disk ROM built once per disk and solved in seconds (issue 12, item 4; docs/rom.md §4.2).

The sparse hybrid (:func:`rom.rom_assembly.assemble_full`) refactors the whole 171 k-DOF disk for every set
of patterns. Here the disk-side work is done once, and each new set of patterns and δ costs dense work on
a few hundred vectors.

**The disk, once** (:func:`reduce_disk_cyclic`): a Craig–Bampton model with *every* slot's contact grid as
boundary (N · n_i DOFs, 23 436 for the default disk). Its boundary blocks are block-circulant in the slots'
own frames, κ_bb[s, t] = C_((s − t) mod N), because the disk is N identical sectors and the slot frames
rotate with them. :mod:`rom.cyclic_sector` computes the model exactly from one sector: sector 1's interior
condensed statically onto its slot and both faces (once, real), then per harmonic h = 0 … N/2 the faces
eliminated densely, which gives Ĉ_h and D̂_h, the slot-DFT of the stiffness and mass blocks, and the
clamped disk's modes of that harmonic (shift-invert Lanczos on the same factors). The whole 148 k-DOF disk
interior is never factorized (45.7 s instead of 93–100 s; docs/rom.md §4.4). K and M are checked to be
cyclic first and the disk is refused otherwise. The characteristic-constraint (CC) modes of the boundary,
harmonic by harmonic, are stored too: eigenvectors of (Ĉ_h, D̂_h).

**Each solve** (:func:`solve_full_cyclic`) is a Rayleigh–Ritz on the all-slot CB model with the blades
(exact contact ties, the blades' Rubin super-elements, Eqs. 19–22), whose K and M are applied block by block
and never assembled. The Ritz space is refined until it is good enough:

1. start: the disk's fixed-interface modes η (all of them), the lowest CC modes of each harmonic (global
   shapes of the slots; each blade follows them statically), and in each slot a few local modes of the
   slot with its blade, the other slots held;
2. solve the projected pencil (dense), form each wanted mode's residual r = K x − λ M x in the full model;
3. enrich: each slot gets K_s⁻¹ r_s, its share of the residuals through its local stiffness (a block-Jacobi
   correction; the dominant directions of the corrections of all wanted modes), and go back to 2.

Local vectors live on one slot's coordinates, so their products with the circulant blocks cost
N · n_i² per vector; global vectors are kept Euclidean-orthogonal to the local ones (Gram–Schmidt against
each slot's local block, which preserves the span), so the basis is orthonormal without a global QR.
The relative residual of every returned mode in the full model is reported.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .academic import BladedDisk
from .contact import ContactPattern
from .craig_bampton import disk_boundary_dofs
from .cyclic_model import CyclicDiskModel
from .cyclic_partition import sector_blocks
from .cyclic_ritz import RitzSlot, append_local, global_cc, local_modes, new_local, outputs, residual_rows, ritz
from .cyclic_sector import reduce_sectors
from .errors import ROMError
from .fe_assembly import AssemblyModes
from .rom_assembly import (
    DEFAULT_FORMULATION,
    check_pattern,
    every_slot,
    grid_shape,
    measurement_labels,
    slot_deltas,
)
from .rubin import RubinModel

__all__ = [
    "CyclicDiskModel",
    "CyclicSolution",
    "reduce_disk_cyclic",
    "solve_full_cyclic",
    "DEFAULT_N_CC",
    "DEFAULT_N_CYCLIC_MODES",
    "DEFAULT_N_LOCAL_MODES",
    "DEFAULT_ROUNDS",
]

log = logging.getLogger(__name__)

#: Fixed-interface modes of the all-slot disk. Measured on the default disk (docs/rom.md §4.2): 30, 50 and 100
#: gave the same full-assembly frequencies and MACs to the digits reported; the 40th is near 30 kHz, 25× the
#: third blade family.
DEFAULT_N_CYCLIC_MODES = 40
#: CC modes kept per harmonic (stored with the disk; a solve may use fewer).
DEFAULT_N_CC = 6
#: Local modes per slot sought for the starting Ritz space (its subspace iteration keeps twice as many vectors).
DEFAULT_N_LOCAL_MODES = 6
#: Enrichment rounds.
DEFAULT_ROUNDS = 1
#: A slot's corrections keep the directions above this fraction of their largest singular value.
_ENRICH_TOL = 1e-3


def reduce_disk_cyclic(
    bd: BladedDisk,
    n_modes: int = DEFAULT_N_CYCLIC_MODES,
    *,
    n_cc: int = DEFAULT_N_CC,
    backend: str = "auto",
) -> CyclicDiskModel:
    """Cyclic Craig–Bampton model of the academic disk with every slot's grid as boundary (module notes).

    Computed from one sector and its harmonics (:mod:`rom.cyclic_sector`): exactly the all-slot CB model's
    blocks, without factorizing the whole disk.

    Parameters
    ----------
    bd : BladedDisk
        A disk of N identical sectors (``build_bladed_disk``); slot frames rotate with the sectors.
    n_modes : int
        Fixed-interface modes n_k (all slots clamped).
    n_cc : int
        CC modes stored per harmonic.
    backend : {"auto", "pardiso", "superlu"}
        Factorization of the sector interior.

    Raises
    ------
    ROMError
        If the disk is not cyclic (mesh, slot frames, K or M), or for a bad ``n_cc``.
    """
    t_all = time.perf_counter()
    N = bd.n_slots
    n_i = disk_boundary_dofs(bd, [1])[0].size
    if not (isinstance(n_cc, (int, np.integer)) and 1 <= n_cc <= n_i):
        raise ROMError(f"n_cc must be an integer in 1..{n_i}, got {n_cc!r}")
    sb = sector_blocks(bd)
    red = reduce_sectors(sb, int(n_modes), backend)
    # Ĉ_h = Σ_d C_d e^(−2πi h d / N): the inverse real FFT gives the block column (C_(−d) = C_dᵀ, as Ĉ_h is
    # Hermitian).
    kappa_col = np.fft.irfft(red.C_hat, n=N, axis=0)
    mu_col = np.fft.irfft(red.D_hat, n=N, axis=0)
    t0 = time.perf_counter()
    cc, cc_mass, cc_w2 = _cc_modes(red.C_hat, red.D_hat, int(n_cc))
    log.info("cyclic CB: %d CC modes per harmonic in %.1f s; n_e=%d per sector, N=%d slots × n_i=%d, n_k=%d; "
             "built in %.1f s", n_cc, time.perf_counter() - t0, sb.n_int + sb.n_face, N, n_i, n_modes,
             time.perf_counter() - t_all)
    return CyclicDiskModel(
        Lambda=red.Lambda, kappa_col=kappa_col, mu_col=mu_col, mu_be=red.mu_be,
        out_eta=red.out_eta, out_b1=red.out_b1, cc_modes=cc, cc_mass=cc_mass, cc_omega2=cc_w2,
        meta={"n_sectors": N, "grid": list(bd.params.grid), "sector_asymmetry": sb.asymmetry},
    )


def _cc_modes(C_hat: np.ndarray, D_hat: np.ndarray, n_cc: int):
    """The lowest ``n_cc`` CC modes of each harmonic 0..N//2: (Ĉ_h − ω² D̂_h) ψ = 0, Ĉ_h and D̂_h Hermitian.

    LAPACK's subset ``eigh`` (8.5 s for the default disk's ten 1 302² pencils). A block shift-invert Lanczos
    was tried: 0.35–0.65 s a harmonic where it converged, but the free disk's rigid-body pairs at h = 0 and 1
    (ω² ≈ 0 beside 1e8–1e12 rad²/s²) left it at residuals of 3e-4 after 60 blocks.
    """
    H, n_i = C_hat.shape[:2]
    psi = np.empty((H, n_i, n_cc), complex)
    dpsi = np.empty_like(psi)
    w2 = np.empty((H, n_cc))
    for h in range(H):
        w2[h], psi[h] = sla.eigh(C_hat[h], D_hat[h], subset_by_index=[0, n_cc - 1], check_finite=False)
        dpsi[h] = D_hat[h] @ psi[h]
    return psi, dpsi, w2


@dataclass(frozen=True, eq=False)
class CyclicSolution:
    """Modes of the full bladed disk from :func:`solve_full_cyclic`.

    Attributes
    ----------
    modes : AssemblyModes
        Frequencies (Hz) and shapes at the measurement DOFs, labelled as the hybrid's.
    residuals : ndarray, shape (n_modes,)
        Relative residual of each mode in the full all-slot CB model with the blades,
        ‖K x − λ M x‖ / (‖K x‖ + λ ‖M x‖).
    n_ritz : int
        Size of the Ritz space of the last round.
    """

    modes: AssemblyModes
    residuals: np.ndarray
    n_ritz: int


def solve_full_cyclic(
    disk: CyclicDiskModel,
    blade: RubinModel,
    patterns: Mapping[int, ContactPattern] | ContactPattern,
    deltas=None,
    *,
    n_modes: int | None = None,
    n_cc: int | None = None,
    n_local_modes: int = DEFAULT_N_LOCAL_MODES,
    rounds: int = DEFAULT_ROUNDS,
    formulation: str = DEFAULT_FORMULATION,
) -> CyclicSolution:
    """Lowest elastic modes of the full bladed disk on a :class:`CyclicDiskModel` (module notes).

    Parameters
    ----------
    disk : CyclicDiskModel
    blade : RubinModel
        From :func:`rom.rubin.reduce_blade`, on the disk's grid.
    patterns : mapping slot → ContactPattern (every slot 1..N), or one pattern for all
    deltas : None, array_like of shape (N, k), or a sequence of N per-blade δ (Eq. 19)
    n_modes : int, optional
        Elastic modes wanted (default 3 N, three blade families).
    n_cc : int, optional
        CC modes per harmonic in the starting space (default: all the disk stores).
    n_local_modes : int
        Local modes per slot in the starting space.
    rounds : int
        Enrichment rounds (module notes).
    formulation : {"exact", "paper"}
    """
    t0 = time.perf_counter()
    N, n_i = disk.n_slots, disk.n_i
    grid = grid_shape(blade)
    if tuple(disk.meta.get("grid", grid)) != grid:
        raise ROMError(f"blade model grid {grid} differs from the cyclic disk's {tuple(disk.meta['grid'])}")
    patterns = every_slot(patterns, N)
    dl = slot_deltas(deltas, N, blade.m)
    n_modes = 3 * N if n_modes is None else int(n_modes)
    n_cc = disk.cc_modes.shape[2] if n_cc is None else int(n_cc)
    slots = [RitzSlot(disk, blade, check_pattern(patterns[s], grid, s), dl.get(s), formulation, s)
             for s in range(1, N + 1)]
    append_local(disk, slots, [new_local(sl, local_modes(sl, n_local_modes, k), 0.0) for k, sl in enumerate(slots)])
    G0, CG0, DG0 = global_cc(disk, n_cc)
    # Each blade follows the global shapes statically: own = −K_oo⁻¹ K_ox x (no energy for rigid motion).
    G0own = [-sla.cho_solve(sl.own_chol, sl.Kb[n_i:, :n_i] @ G0[k], check_finite=False) for k, sl in enumerate(slots)]
    t1 = time.perf_counter()
    for rnd in range(rounds + 1):
        lam, Y, parts = ritz(disk, slots, G0, CG0, DG0, G0own, n_modes)
        R, KVn, MVn = residual_rows(disk, slots, parts, Y, lam)
        res = np.linalg.norm(np.concatenate(R, axis=0), axis=0) / (KVn + lam * MVn)
        log.info("cyclic full solve: round %d, Ritz space %d, max relative residual %.1e", rnd, Y.shape[0], res.max())
        if rnd == rounds:
            break
        append_local(disk, slots, [new_local(sl, sla.cho_solve(sl.K_chol, R[1 + k], check_finite=False), _ENRICH_TOL)
                                    for k, sl in enumerate(slots)])
    f_hz = np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)
    meas = outputs(disk, slots, parts, Y)
    labels = measurement_labels(N, range(1, N + 1), blade.n_b - blade.n_interface)
    log.info("cyclic full solve: start %.1f s, Ritz rounds %.1f s", t1 - t0, time.perf_counter() - t1)
    return CyclicSolution(AssemblyModes(f_hz, meas, labels), res, int(Y.shape[0]))
