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

from rom.academic import MESH_LEVELS, BladedDisk, build_bladed_disk
from rom.component import Component
from rom.contact import FLANKS, ContactPattern
from rom.contact_stiffness import tributary_areas
from rom.fe_assembly import AssemblyModes
from rom.hex20 import assemble
from rom.solver import solve_modes

from . import specimen
from .hammer import HammerSettings

__all__ = [
    "REALISM",
    "TruthParams",
    "BladeVariation",
    "TruthTwin",
    "TruthAssembly",
    "draw_blade_variations",
    "make_truth_twin",
    "assemble_truth",
    "solve_truth",
    "varied_blade",
]


#: The realism settings of ``bladetwin lab simulate --realism`` (:meth:`TruthParams.of`).
REALISM = ("realistic", "ideal")


@dataclass(frozen=True)
class TruthParams:
    """How the truth twin departs from the identification model (SI units; spreads are standard deviations).

    The defaults are the **realistic** twin (docs/twin.md names the source of each magnitude);
    :meth:`ideal` is the twin of the model's own parts that isolates one stage in a test.

    Attributes
    ----------
    contact_stiffness_n_per_m3 : float
        Nominal normal contact stiffness per unit area, 1e14 N/m³: the stiff end of the range measured for
        ground steel-on-steel joints under moderate contact pressure (1e13–1e14 N/m³).
    tangential_ratio : float
        k_t / k_n. Realistic: Mindlin's 2(1 − ν)/(2 − ν) = 0.82 for steel; ideal: the model's fitted 0.7.
    contact_spread : float
        Lognormal scatter of each joint's and flank's contact stiffness (0.3: a factor of about 1.35).
    contact_pressure_exponent : float
        k_n ∝ p^m over a flank (Hertz: 2/3); 0 keeps k_n uniform.
    thickness_spread, chord_spread, span_spread, modulus_spread : float
        Blade-to-blade variation (relative): free-blade eigenvalue deltas of a few tenths of a percent to about
        2 % (paper Table 2).
    fillet_fraction, fillet_thickening, fillet_length_m, fillet_spread : float
        Share of blades with a root fillet the model leaves out (realistic: every blade), its extra thickness
        at the shank, its fade length along the span, and the blade-to-blade scatter of its size (relative).
    modulus_offset_range, density_offset_range : (float, float)
        Magnitude range of the specimen's E and ρ offsets from the model's handbook values (disk and blades
        drawn apart, random sign).
    disk_sector_spread : float
        Sector-to-sector scatter of the disk's modulus (relative), which splits its doublets.
    bolt_mass_kg, bolts_per_slot :
        The bolts holding each mounted blade, as masses on the disk's rim (absent from the model).
    reseat_edge_share : float
        Share of each flank's edge nodes whose contact changes when the blades are re-seated between the
        disk–one-blade tests and the full-assembly test.
    temperature_swing_k, modulus_temperature_coefficient_per_k : float
        Standard deviation of a test day's temperature off the reference (K), and dE/dT / E (1/K).
    mesh_refinement : int
        Mesh levels of the truth above the model's (capped at ``"fine"``); the contact grid is the same.
    damping_range : (float, float)
        Range of the modal damping ratios (log-uniform).
    hammer : HammerSettings or None
        The time-domain hammer test (:mod:`lab.hammer`: impulses, double hits, channel noise, windows, H1
        and coherence over averages). None: exact FRFs with noise added in the frequency domain
        (:func:`lab.rig.measure`), the ideal twin's test.
    """

    contact_stiffness_n_per_m3: float = 1e14
    tangential_ratio: float = 0.82
    contact_spread: float = 0.3
    contact_pressure_exponent: float = 2 / 3
    thickness_spread: float = 0.002
    chord_spread: float = 0.002
    span_spread: float = 0.001
    modulus_spread: float = 0.0015
    fillet_fraction: float = 1.0
    fillet_thickening: float = 0.08
    fillet_length_m: float = 0.004
    fillet_spread: float = 0.3
    modulus_offset_range: tuple[float, float] = (0.01, 0.04)
    density_offset_range: tuple[float, float] = (0.001, 0.005)
    disk_sector_spread: float = 0.005
    bolt_mass_kg: float = 0.005
    bolts_per_slot: int = 2
    reseat_edge_share: float = 0.2
    temperature_swing_k: float = 1.5
    modulus_temperature_coefficient_per_k: float = -2.6e-4
    mesh_refinement: int = 1
    damping_range: tuple[float, float] = (0.0005, 0.005)
    hammer: HammerSettings | None = HammerSettings()  # noqa: RUF009  (frozen: a shared default is safe)

    @classmethod
    def ideal(cls) -> TruthParams:
        """The twin of the model's own parts: one uniform contact law of the fitted form on the model's mesh and
        material, a fillet on a quarter of the blades, no disk mistuning, bolts, re-seating or temperature."""
        return cls(tangential_ratio=0.7, contact_spread=0.0, contact_pressure_exponent=0.0, fillet_fraction=0.25,
                   fillet_spread=0.0, modulus_offset_range=(0.0, 0.0), density_offset_range=(0.0, 0.0),
                   disk_sector_spread=0.0, bolt_mass_kg=0.0, reseat_edge_share=0.0, temperature_swing_k=0.0,
                   mesh_refinement=0, hammer=None)

    @classmethod
    def of(cls, realism: str) -> TruthParams:
        """The parameters of a realism setting (:data:`REALISM`)."""
        if realism not in REALISM:
            raise ValueError(f"realism {realism!r}: expected one of {', '.join(REALISM)}")
        return cls() if realism == "realistic" else cls.ideal()

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
        for name in ("modulus_offset_range", "density_offset_range"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi < 0.5:
                raise ValueError(f"{name} must satisfy 0 ≤ low ≤ high < 0.5, got {(lo, hi)}")
        for name in ("contact_spread", "fillet_spread", "disk_sector_spread", "bolt_mass_kg", "temperature_swing_k"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number ≥ 0, got {v}")
        if not 0 <= self.reseat_edge_share <= 1:
            raise ValueError(f"reseat_edge_share must lie in [0, 1], got {self.reseat_edge_share}")
        if not (isinstance(self.mesh_refinement, int) and 0 <= self.mesh_refinement <= 2):
            raise ValueError(f"mesh_refinement must be 0, 1 or 2 levels, got {self.mesh_refinement!r}")
        if self.hammer is not None:
            self.hammer.validate()


@dataclass(frozen=True)
class BladeVariation:
    """FE-level variation of one truth blade (relative factors; 0 = nominal)."""

    thickness: float = 0.0
    chord: float = 0.0
    span: float = 0.0
    modulus: float = 0.0
    fillet: bool = False
    fillet_scale: float = 1.0

    def to_dict(self) -> dict:
        return {"thickness": self.thickness, "chord": self.chord, "span": self.span, "modulus": self.modulus,
                "fillet": self.fillet, "fillet_scale": self.fillet_scale}


@dataclass(frozen=True, eq=False)
class TruthTwin:
    """The truth bladed disk: its disk, one FE blade per slot, the true contact and the test days.

    Attributes
    ----------
    bd : BladedDisk
        The nominal academic twin on the truth's mesh (its geometry and node sets; its blade is the nominal
        blade). Its mesh is the model's, or finer (``params.mesh_refinement``).
    blades : tuple of Component, length n_blades
        The truth blade of each slot (slot s is ``blades[s - 1]``), in the blade's local frame.
    variations : tuple of BladeVariation
    patterns : tuple of ContactPattern, length n_blades
        True contact pattern of each joint in the state the films were taken in (the disk–one-blade tests).
    params : TruthParams
    disk : Component or None
        The truth disk (material offsets, sector scatter); ``None``: ``bd.disk``.
    assembly_patterns : tuple of ContactPattern or None
        The contact after re-seating, in the full-assembly test; ``None``: ``patterns``.
    contact_scale : ndarray, shape (n_blades, 2, rows, cols), or None
        Each flank node's contact stiffness as a multiple of the nominal law (``None``: 1).
    materials : dict
        Relative offsets of E and ρ of disk and blades from the model's (``specimen.material_offsets``).
    sector_moduli : ndarray, shape (n_blades,), or None
        The disk's relative modulus offset per sector.
    day_factors : dict
        Frequency factor of each test type's day (``specimen.day_factors``).
    """

    bd: BladedDisk
    blades: tuple[Component, ...]
    variations: tuple[BladeVariation, ...]
    patterns: tuple[ContactPattern, ...]
    params: TruthParams = field(default_factory=TruthParams)
    disk: Component | None = None
    assembly_patterns: tuple[ContactPattern, ...] | None = None
    contact_scale: np.ndarray | None = None
    materials: dict = field(default_factory=dict)
    sector_moduli: np.ndarray | None = None
    day_factors: dict = field(default_factory=dict)

    @property
    def n_blades(self) -> int:
        return len(self.blades)

    @property
    def truth_disk(self) -> Component:
        return self.bd.disk if self.disk is None else self.disk

    def patterns_of(self, state: str) -> tuple[ContactPattern, ...]:
        """The contact of ``state``: ``"d1b"`` (the films' state) or ``"assembly"`` (after re-seating)."""
        if state not in ("d1b", "assembly"):
            raise ValueError(f"state {state!r}: expected 'd1b' or 'assembly'")
        return self.patterns if state == "d1b" or self.assembly_patterns is None else self.assembly_patterns

    def day_factor(self, kind: str) -> float:
        """The frequency factor of the day test type ``kind`` is measured on (1 without temperature)."""
        return float(self.day_factors.get(kind, 1.0))


def draw_blade_variations(n_blades: int, rng: np.random.Generator, params: TruthParams) -> list[BladeVariation]:
    """Per-blade variations; ``round(fillet_fraction · n_blades)`` blades (at least one) get a fillet.

    The fillets' size scatter (``fillet_spread``) comes from a stream spawned after the other draws, so the
    ideal twin's variations are those of a twin without it.
    """
    n_fillet = min(n_blades, max(1, round(params.fillet_fraction * n_blades))) if params.fillet_fraction > 0 else 0
    fillet = np.zeros(n_blades, bool)
    fillet[rng.choice(n_blades, n_fillet, replace=False)] = True
    z = rng.standard_normal((n_blades, 4))
    size = np.ones(n_blades)
    if params.fillet_spread > 0:
        s = params.fillet_spread
        size = np.exp(s * rng.spawn(1)[0].standard_normal(n_blades) - 0.5 * s * s)
    return [
        BladeVariation(
            thickness=float(params.thickness_spread * z[b, 0]),
            chord=float(params.chord_spread * z[b, 1]),
            span=float(params.span_spread * z[b, 2]),
            modulus=float(params.modulus_spread * z[b, 3]),
            fillet=bool(fillet[b]),
            fillet_scale=float(size[b]),
        )
        for b in range(n_blades)
    ]


def varied_blade(bd: BladedDisk, var: BladeVariation, params: TruthParams, name: str,
                  materials: dict | None = None) -> Component:
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
        thick = thick + params.fillet_thickening * var.fillet_scale * w * fade
    X[:, 0] *= thick
    X[:, 2] *= 1.0 + var.chord * w
    X[:, 1] = np.where(above > 0, y_top + above * (1.0 + var.span * w), X[:, 1])
    mat = p.blade_material
    m = materials or {}
    E = mat.E * (1.0 + var.modulus) * (1.0 + m.get("blade_E", 0.0))
    rho = mat.rho * (1.0 + m.get("blade_rho", 0.0))
    K, M = assemble(X, blade.elements, E, mat.nu, rho)
    return Component(name, K, M, blade.node_ids, X, dict(blade.node_sets), {**blade.meta, "variation": var.to_dict()},
                     blade.elements)


def _truth_mesh(bd: BladedDisk, refinement: int) -> BladedDisk:
    """The nominal twin ``refinement`` mesh levels finer than ``bd`` (same contact grid; capped at the finest)."""
    levels = list(MESH_LEVELS)
    level = bd.params.level
    if refinement == 0 or level not in levels:
        return bd
    finer = levels[min(levels.index(level) + refinement, len(levels) - 1)]
    return bd if finer == level else build_bladed_disk(bd.params.with_(level=finer))


def make_truth_twin(
    bd: BladedDisk,
    patterns: Sequence[ContactPattern],
    rng: np.random.Generator,
    params: TruthParams | None = None,
    node_pressure: np.ndarray | None = None,
) -> TruthTwin:
    """Build the truth twin of ``bd`` with the given true patterns (one per slot, slot order).

    Parameters
    ----------
    bd : BladedDisk
        The identification model (academic twin); the truth's mesh is this one or finer.
    patterns : sequence of ContactPattern
        True contact of each joint in the films' state.
    rng : numpy.random.Generator
    params : TruthParams, optional
        Default: the realistic twin.
    node_pressure : ndarray, shape (n_blades, 2, rows, cols), optional
        Contact pressure (Pa) at the grid nodes, for the pressure-dependent stiffness and the re-seating.
    """
    params = params or TruthParams()
    params.validate()
    if len(patterns) != bd.n_slots:
        raise ValueError(f"need one true pattern per slot ({bd.n_slots}), got {len(patterns)}")
    for s, pat in enumerate(patterns, start=1):
        if pat.shape != tuple(bd.params.grid):
            raise ValueError(f"true pattern of joint {s} has grid {pat.shape}, the model's grid is {bd.params.grid}")
    variations = draw_blade_variations(bd.n_slots, rng, params)
    # The specimen's other effects from their own stream, drawn after the blades' (the ideal twin is unchanged).
    rng_mat, rng_disk, rng_contact, rng_seat, rng_day = rng.spawn(5)
    materials = specimen.material_offsets(rng_mat, params.modulus_offset_range, params.density_offset_range)
    sector = None
    if params.disk_sector_spread > 0:
        sector = params.disk_sector_spread * rng_disk.standard_normal(bd.n_slots)
    tbd = _truth_mesh(bd, params.mesh_refinement)
    disk = specimen.truth_disk(tbd, materials["disk_E"], materials["disk_rho"], sector)
    blades = tuple(varied_blade(tbd, v, params, f"blade{s + 1}", materials) for s, v in enumerate(variations))
    scale = specimen.contact_scale(node_pressure, patterns, rng_contact, params.contact_spread,
                                   params.contact_pressure_exponent)
    seated = specimen.reseated_patterns(patterns, node_pressure, rng_seat, params.reseat_edge_share)
    days = specimen.day_factors(rng_day, params.temperature_swing_k, params.modulus_temperature_coefficient_per_k)
    return TruthTwin(tbd, blades, tuple(variations), tuple(patterns), params, disk=disk, assembly_patterns=seated,
                     contact_scale=scale, materials=materials, sector_moduli=sector, day_factors=days)


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


def _contact_triplets(twin: TruthTwin, slots: Sequence[int], offsets: np.ndarray, state: str) -> list:
    """(rows, cols, values) of every contact spring between the disk and the blades of ``slots``."""
    bd, disk = twin.bd, twin.truth_disk
    kn = twin.params.contact_stiffness_n_per_m3
    C_local = np.diag([1.0, twin.params.tangential_ratio, twin.params.tangential_ratio])
    patterns = twin.patterns_of(state)
    rows, cols, vals = [], [], []
    for s, off in zip(slots, offsets, strict=True):
        blade = twin.blades[s - 1]
        R = bd.slot_rotation(s)
        for fi, f in enumerate(FLANKS):
            grid_b = blade.node_set(f)
            area = tributary_areas(blade.coords[grid_b])
            if twin.contact_scale is not None:
                area = area * twin.contact_scale[s - 1, fi]
            mask = patterns[s - 1].flank(f)
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
    return [rows, cols, vals]


def assemble_truth(twin: TruthTwin, slots: Sequence[int] | None, *, with_disk: bool = True,
                   state: str = "d1b") -> TruthAssembly:
    """Truth assembly of the disk with the blades of ``slots`` (``None``: every slot), joined by contact springs.

    Parameters
    ----------
    twin : TruthTwin
    slots : sequence of int (1-based) or None
    with_disk : bool
        ``False`` with one slot gives that blade alone (free–free), without the disk.
    state : {"d1b", "assembly"}
        The contact state (:meth:`TruthTwin.patterns_of`): the films' state, or after re-seating.
    """
    bd = twin.bd
    slots = tuple(range(1, twin.n_blades + 1)) if slots is None else tuple(int(s) for s in slots)
    for s in slots:
        bd.check_slot(s)
    disk = twin.truth_disk
    nd = disk.n_dof if with_disk else 0
    disk_m = disk.M
    if with_disk and twin.params.bolt_mass_kg > 0 and slots:
        disk_m = disk.M + specimen.bolt_masses(disk, slots, twin.params.bolt_mass_kg, twin.params.bolts_per_slot)
    blocks_k = ([disk.K] if with_disk else []) + [twin.blades[s - 1].K for s in slots]
    blocks_m = ([disk_m] if with_disk else []) + [twin.blades[s - 1].M for s in slots]
    offsets = nd + np.r_[0, np.cumsum([twin.blades[s - 1].n_dof for s in slots])][:-1].astype(np.int64)
    rows, cols, vals = _contact_triplets(twin, slots, offsets, state) if with_disk else ([], [], [])
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
