"""The truth twin: the FE model a virtual campaign is "measured" on (issue 9, item 3).

It differs from the identification ROM (``rom``: exact node-to-node ties, eigenvalue-perturbation mistuning)
in the ways a real specimen differs from its model:

* **Finite contact stiffness.** Each contacting node pair of a blade-root joint is coupled by a spring, not
  tied: normal stiffness ``k_n = contact_stiffness_n_per_m3 · A`` (``A`` = the node's tributary area on the
  flank) and tangential stiffness ``tangential_ratio · k_n``. Detached node pairs are free.
* **Blade-to-blade variation made at the FE level.** Every blade has its own mesh geometry and modulus:
  airfoil thickness, chord and span scale factors, a Young's-modulus factor and, for a subgroup of blades, a
  root *fillet* (extra thickness that fades out along the span). Root nodes never move, so every blade still
  conforms to its slot. Mode shapes change slightly too, which the ROM's eigenvalue perturbation (Eq. 19)
  cannot represent.
* **Light damping**: modal damping ratios drawn per test and mode (:func:`damping_ratios`).

All randomness comes from one ``numpy.random.Generator``; the same seed gives the same twin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from rom.academic import BladedDisk
from rom.component import Component
from rom.contact import FLANKS, ContactPattern
from rom.contact_stiffness import tributary_areas
from rom.fe_assembly import AssemblyModes
from rom.hex20 import assemble
from rom.solver import solve_modes

__all__ = [
    "TruthParams",
    "BladeVariation",
    "TruthTwin",
    "TruthAssembly",
    "draw_blade_variations",
    "make_truth_twin",
    "assemble_truth",
    "solve_truth",
    "canonical_degenerate",
    "damping_ratios",
]


@dataclass(frozen=True)
class TruthParams:
    """How the truth twin departs from the identification model (SI units; spreads are standard deviations).

    The contact-stiffness default, 1e14 N/m³ normal (tangential 0.7 of it), lies at the stiff end of the range
    measured for ground steel-on-steel joints under moderate contact pressure (1e13–1e14 N/m³); on the coarse
    twin 5e13 put the ROM's edgewise disk–one-blade mode 2 % above the truth, 1e14 half that. The blade spreads give
    free-blade eigenvalue deltas of a few tenths of a percent to about 2 % (paper Table 2), and the fillet
    blades stand well apart on the modes that bend the blade root. The fillet's 8 % thickening is kept small
    because the ROM's eigenvalue perturbation cannot follow it: once the root is held in the disk, the ROM
    under-predicts a fillet blade's first mode (−1.4 % on the coarse twin at 8 %, −2 % at 12 %).
    """

    contact_stiffness_n_per_m3: float = 1e14
    tangential_ratio: float = 0.7
    thickness_spread: float = 0.002
    chord_spread: float = 0.002
    span_spread: float = 0.001
    modulus_spread: float = 0.0015
    fillet_fraction: float = 0.25
    fillet_thickening: float = 0.08
    fillet_length_m: float = 0.004
    damping_range: tuple[float, float] = (0.0005, 0.005)

    def validate(self) -> None:
        if not (np.isfinite(self.contact_stiffness_n_per_m3) and self.contact_stiffness_n_per_m3 > 0):
            raise ValueError(f"contact_stiffness_n_per_m3 must be > 0 (N/m³), got {self.contact_stiffness_n_per_m3}")
        if not 0 <= self.tangential_ratio <= 1:
            raise ValueError(f"tangential_ratio must lie in [0, 1], got {self.tangential_ratio}")
        if not 0 <= self.fillet_fraction <= 1:
            raise ValueError(f"fillet_fraction must lie in [0, 1], got {self.fillet_fraction}")
        lo, hi = self.damping_range
        if not 0 < lo <= hi < 0.1:
            raise ValueError(f"damping_range must satisfy 0 < low ≤ high < 0.1, got {self.damping_range}")


@dataclass(frozen=True)
class BladeVariation:
    """FE-level variation of one truth blade (relative factors; 0 = nominal)."""

    thickness: float = 0.0
    chord: float = 0.0
    span: float = 0.0
    modulus: float = 0.0
    fillet: bool = False

    def to_dict(self) -> dict:
        return {"thickness": self.thickness, "chord": self.chord, "span": self.span, "modulus": self.modulus,
                "fillet": self.fillet}


@dataclass(frozen=True, eq=False)
class TruthTwin:
    """The truth bladed disk: the nominal disk, one FE blade per slot, the true contact patterns.

    Attributes
    ----------
    bd : BladedDisk
        The nominal academic twin (its disk is the truth disk; its blade is the nominal blade).
    blades : tuple of Component, length n_blades
        The truth blade of each slot (slot s is ``blades[s - 1]``), in the blade's local frame.
    variations : tuple of BladeVariation
    patterns : tuple of ContactPattern, length n_blades
        True contact pattern of each joint.
    params : TruthParams
    """

    bd: BladedDisk
    blades: tuple[Component, ...]
    variations: tuple[BladeVariation, ...]
    patterns: tuple[ContactPattern, ...]
    params: TruthParams = field(default_factory=TruthParams)

    @property
    def n_blades(self) -> int:
        return len(self.blades)


def draw_blade_variations(n_blades: int, rng: np.random.Generator, params: TruthParams) -> list[BladeVariation]:
    """Per-blade variations; ``round(fillet_fraction · n_blades)`` blades (at least one) get a fillet."""
    n_fillet = min(n_blades, max(1, round(params.fillet_fraction * n_blades))) if params.fillet_fraction > 0 else 0
    fillet = np.zeros(n_blades, bool)
    fillet[rng.choice(n_blades, n_fillet, replace=False)] = True
    z = rng.standard_normal((n_blades, 4))
    return [
        BladeVariation(
            thickness=float(params.thickness_spread * z[b, 0]),
            chord=float(params.chord_spread * z[b, 1]),
            span=float(params.span_spread * z[b, 2]),
            modulus=float(params.modulus_spread * z[b, 3]),
            fillet=bool(fillet[b]),
        )
        for b in range(n_blades)
    ]


def _varied_blade(bd: BladedDisk, var: BladeVariation, params: TruthParams, name: str) -> Component:
    """The nominal blade with its shank and airfoil reshaped by ``var``; root nodes stay where they are."""
    p = bd.params
    blade = bd.blade
    X = blade.coords.copy()
    y_top = p.wall_y_range[1]
    y_sh = y_top + p.shank_length
    above = X[:, 1] - y_top
    # Ramp from 0 at the top of the slot wall to 1 at the end of the shank: the root (and its contact grid)
    # keeps its exact geometry, so the blade still conforms node-to-node with its slot.
    w = np.clip(above / p.shank_length, 0.0, 1.0)
    thick = 1.0 + var.thickness * w
    if var.fillet:
        # A fillet: extra thickness at the shank–airfoil junction fading out along the span.
        fade = np.exp(-np.clip(X[:, 1] - y_sh, 0.0, None) / params.fillet_length_m)
        thick = thick + params.fillet_thickening * w * fade
    X[:, 0] *= thick
    X[:, 2] *= 1.0 + var.chord * w
    X[:, 1] = np.where(above > 0, y_top + above * (1.0 + var.span * w), X[:, 1])
    mat = p.blade_material
    K, M = assemble(X, blade.elements, mat.E * (1.0 + var.modulus), mat.nu, mat.rho)
    return Component(name, K, M, blade.node_ids, X, dict(blade.node_sets), {**blade.meta, "variation": var.to_dict()},
                     blade.elements)


def make_truth_twin(
    bd: BladedDisk,
    patterns: Sequence[ContactPattern],
    rng: np.random.Generator,
    params: TruthParams | None = None,
) -> TruthTwin:
    """Build the truth twin of ``bd`` with the given true patterns (one per slot, slot order)."""
    params = params or TruthParams()
    params.validate()
    if len(patterns) != bd.n_slots:
        raise ValueError(f"need one true pattern per slot ({bd.n_slots}), got {len(patterns)}")
    for s, pat in enumerate(patterns, start=1):
        if pat.shape != tuple(bd.params.grid):
            raise ValueError(f"true pattern of joint {s} has grid {pat.shape}, the model's grid is {bd.params.grid}")
    variations = draw_blade_variations(bd.n_slots, rng, params)
    blades = tuple(_varied_blade(bd, v, params, f"blade{s + 1}") for s, v in enumerate(variations))
    return TruthTwin(bd, blades, tuple(variations), tuple(patterns), params)


@dataclass(frozen=True, eq=False)
class TruthAssembly:
    """Sparse K, M of a truth assembly over the DOFs [disk | blade of slot s₁ | blade of s₂ | ...].

    Attributes
    ----------
    K, M : csr_matrix, shape (n, n)
    meas_rows : ndarray of int, shape (n_meas,)
        Rows of the measurement DOFs (disk: z at each sector; blades: local x, out of plane).
    meas_labels : list of tuple
        ``("disk", sector, 1, 3)`` or ``("blade", slot, point, 1)`` per measurement DOF, as in ``rom``.
    slots : tuple of int
    n_disk_dof : int
        The disk's DOFs, first in the ordering (0 without the disk).
    """

    K: sp.csr_matrix
    M: sp.csr_matrix
    meas_rows: np.ndarray
    meas_labels: list
    slots: tuple[int, ...]
    n_disk_dof: int = 0


def assemble_truth(twin: TruthTwin, slots: Sequence[int] | None, *, with_disk: bool = True) -> TruthAssembly:
    """Truth assembly of the disk with the blades of ``slots`` (``None``: every slot), joined by contact springs.

    Parameters
    ----------
    twin : TruthTwin
    slots : sequence of int (1-based) or None
    with_disk : bool
        ``False`` with one slot gives that blade alone (free–free), without the disk.
    """
    bd = twin.bd
    slots = tuple(range(1, twin.n_blades + 1)) if slots is None else tuple(int(s) for s in slots)
    for s in slots:
        bd.check_slot(s)
    disk = bd.disk
    nd = disk.n_dof if with_disk else 0
    blocks_k = ([disk.K] if with_disk else []) + [twin.blades[s - 1].K for s in slots]
    blocks_m = ([disk.M] if with_disk else []) + [twin.blades[s - 1].M for s in slots]
    offsets = nd + np.r_[0, np.cumsum([twin.blades[s - 1].n_dof for s in slots])][:-1].astype(np.int64)
    rows, cols, vals = [], [], []
    if with_disk:
        kn = twin.params.contact_stiffness_n_per_m3
        C_local = np.diag([1.0, twin.params.tangential_ratio, twin.params.tangential_ratio])
        for s, off in zip(slots, offsets, strict=True):
            blade = twin.blades[s - 1]
            R = bd.slot_rotation(s)
            for f in FLANKS:
                grid_b = blade.node_set(f)
                area = tributary_areas(blade.coords[grid_b])
                mask = twin.patterns[s - 1].flank(f)
                nb_idx, dk_idx, k = grid_b[mask], disk.node_set(f"slot{s}_{f}")[mask], kn * area[mask]
                # Spring energy ½ dᵀ C d with d = u_disk − R u_blade (global frame); the flank normal is the
                # blade's local x, so C = R C_local Rᵀ and the four 3×3 blocks are below.
                blocks = (
                    (3 * dk_idx, 3 * dk_idx, R @ C_local @ R.T),
                    (off + 3 * nb_idx, off + 3 * nb_idx, C_local),
                    (3 * dk_idx, off + 3 * nb_idx, -R @ C_local),
                    (off + 3 * nb_idx, 3 * dk_idx, -C_local @ R.T),
                )
                for r0, c0, B in blocks:
                    r = r0[:, None, None] + np.arange(3)[None, :, None]
                    c = c0[:, None, None] + np.arange(3)[None, None, :]
                    rows.append(np.broadcast_to(r, (k.size, 3, 3)).ravel())
                    cols.append(np.broadcast_to(c, (k.size, 3, 3)).ravel())
                    vals.append((k[:, None, None] * B[None]).ravel())
    K = sp.block_diag(blocks_k, format="csr")
    if rows:
        n = K.shape[0]
        K = (K + sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)))
    M = sp.block_diag(blocks_m, format="csr")
    meas_rows: list[int] = []
    meas_labels: list = []
    if with_disk:
        meas_rows += list(3 * disk.node_set("meas") + disk.meta["meas_direction"] - 1)
        meas_labels += [("disk", k + 1, 1, int(disk.meta["meas_direction"])) for k in range(bd.n_slots)]
    for s, off in zip(slots, offsets, strict=True):
        blade = twin.blades[s - 1]
        meas = blade.node_set("meas")
        d = int(blade.meta["meas_direction"])
        meas_rows += list(off + 3 * meas + d - 1)
        meas_labels += [("blade", s, p + 1, d) for p in range(meas.size)]
    return TruthAssembly(K.tocsr(), M.tocsr(), np.asarray(meas_rows, dtype=np.int64), meas_labels, slots, nd)


def solve_truth(asm: TruthAssembly, n_modes: int) -> AssemblyModes:
    """The lowest ``n_modes`` elastic modes of a truth assembly (free–free: the rigid modes come apart).

    The solve runs with one MKL/BLAS thread. Multithreaded Pardiso sums in a run-dependent order: two solves
    of the same default-level disk–one-blade differed by up to 1.2e-9 in frequency, and regenerating a
    campaign must reproduce its truth within 1e-9 (measured: one thread gives bitwise-equal results, for
    about 20 % more time per solve).
    """
    with threadpool_limits(limits=1):
        sol = solve_modes(asm.K, asm.M, n_modes)
    nd = asm.n_disk_dof
    # Mass-normalised shapes: total kinetic energy 1, so the blades hold 1 − the disk's share.
    disk_energy = np.einsum("ij,ij->j", sol.shapes[:nd], asm.M[:nd, :nd] @ sol.shapes[:nd])
    return AssemblyModes(sol.frequencies_hz, np.asarray(sol.shapes[asm.meas_rows]), list(asm.meas_labels),
                         rigid_shapes=np.asarray(sol.rigid_shapes[asm.meas_rows]),
                         blade_energy=1.0 - disk_energy)


def canonical_degenerate(modes: AssemblyModes, inputs: Sequence[int], rtol: float = 1e-7) -> AssemblyModes:
    """The same modes with every group of repeated frequencies in a basis fixed by the hammer ``inputs``.

    A cyclic disk's double modes are one eigenspace: the solver returns an arbitrary basis of it, so the
    response of each member at the hammer (and whether a test "sees" it) would change from run to run. Here
    each group (frequencies within ``rtol``) is rotated by the SVD of its rows at the inputs: the first members
    carry the input participation in decreasing order, the rest have none (a hammer excites only that
    combination). The group's frequencies become their mean and each shape's largest value is positive, so
    the result does not depend on the solver's basis or order.

    Parameters
    ----------
    modes : AssemblyModes
    inputs : sequence of int
        Rows of ``modes.meas_shapes`` that are hammer points.
    """
    f = np.array(modes.frequencies_hz, dtype=np.float64)
    shapes = np.array(modes.meas_shapes, dtype=np.float64)
    energy = None if modes.blade_energy is None else np.array(modes.blade_energy, dtype=np.float64)
    start = 0
    while start < f.size:
        stop = start + 1
        while stop < f.size and f[stop] <= f[start] * (1 + rtol):
            stop += 1
        if stop - start > 1:
            g = slice(start, stop)
            _, _, vt = np.linalg.svd(shapes[list(inputs), g], full_matrices=True)
            shapes[:, g] = shapes[:, g] @ vt.T
            f[g] = f[g].mean()
            if energy is not None:
                energy[g] = energy[g].mean()
        start = stop
    k = np.argmax(np.abs(shapes), axis=0)
    shapes *= np.where(shapes[k, np.arange(shapes.shape[1])] < 0, -1.0, 1.0)
    return AssemblyModes(f, shapes, modes.meas_labels, rigid_shapes=modes.rigid_shapes, blade_energy=energy)


def damping_ratios(n_modes: int, rng: np.random.Generator, damping_range: tuple[float, float]) -> np.ndarray:
    """Modal damping ratios, log-uniform in ``damping_range`` and varying from mode to mode, shape (n_modes,)."""
    lo, hi = damping_range
    return np.exp(rng.uniform(np.log(lo), np.log(hi), n_modes))
