"""How a real specimen departs from its FE model, beyond the blades' own variation (issue 44, docs/twin.md).

Each effect is one pure function of the twin's parameters and a random stream:

* :func:`material_offsets` — the specimen's E and ρ off the handbook values the model starts from;
* :func:`truth_disk` — the disk with those offsets and a sector-to-sector modulus scatter (machining and
  material inhomogeneity), which splits the disk's doublets;
* :func:`contact_scale` — the contact stiffness per node: scattered per joint and flank, and following the
  contact pressure over the flank (k ∝ p^m);
* :func:`reseated_patterns` — the contact after the blades are taken out and re-inserted;
* :func:`bolt_masses` — the bolts that hold each mounted blade, as masses on the disk's rim;
* :func:`day_factors` — each test day's temperature, as a factor on every frequency of that day.

With every magnitude 0 (``TruthParams.ideal()``) each function returns the nominal value, so the ideal twin is
bitwise today's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp

from rom.academic import BladedDisk
from rom.component import Component
from rom.contact import FLANKS, ContactPattern, slot_flank_nodes
from rom.hex20 import assemble

__all__ = ["TEST_DAYS", "material_offsets", "truth_disk", "sector_of_elements", "contact_scale",
           "reseated_patterns", "bolt_masses", "day_factors"]

#: The day each test type is measured on: components first, then the disk–one-blade tests, then the full
#: assembly after the blades were re-seated (a lab's order of work).
TEST_DAYS = {"blade": 0, "disk": 0, "d1b": 1, "assembly": 2}


def material_offsets(rng: np.random.Generator, modulus_range: tuple[float, float],
                     density_range: tuple[float, float]) -> dict[str, float]:
    """Relative offsets of the specimen's E and ρ (disk and blades) from the model's nominal values.

    Each magnitude is uniform in its range, with a random sign: ``{"disk_E", "disk_rho", "blade_E",
    "blade_rho"}``. A zero range gives exactly 0.
    """
    out = {}
    for name, (lo, hi) in (("disk_E", modulus_range), ("disk_rho", density_range), ("blade_E", modulus_range),
                           ("blade_rho", density_range)):
        mag, sign = rng.uniform(lo, hi), rng.choice((-1.0, 1.0))
        out[name] = float(sign * mag) if hi > 0 else 0.0
    return out


def sector_of_elements(bd: BladedDisk) -> np.ndarray:
    """The sector (0-based) each disk element's centroid lies in, shape (n_elements,).

    Sector s spans the angles 2π (s ∓ ½) / N round the centre of slot s + 1 (from +y towards +x).
    """
    X = bd.disk.coords[np.asarray(bd.disk.elements)].mean(axis=1)
    angle = np.arctan2(X[:, 0], X[:, 1])  # from +y towards +x, as bd.slot_angle
    n = bd.n_slots
    return np.mod(np.round(angle / (2 * np.pi / n)).astype(np.int64), n)


def truth_disk(bd: BladedDisk, E_offset: float, rho_offset: float, sector_moduli: np.ndarray | None) -> Component:
    """The specimen's disk: the model's mesh with its own E and ρ, and a modulus factor per sector.

    Parameters
    ----------
    bd : BladedDisk
        The model (its disk is the mesh).
    E_offset, rho_offset : float
        Relative offsets of the whole disk's modulus and density.
    sector_moduli : ndarray, shape (n_slots,), or None
        Relative modulus offset of each sector (``None``: none).
    """
    disk = bd.disk
    if E_offset == 0 and rho_offset == 0 and sector_moduli is None:
        return disk
    mat = bd.params.disk_material
    E, rho = mat.E * (1.0 + E_offset), mat.rho * (1.0 + rho_offset)
    conn = np.asarray(disk.elements)
    if sector_moduli is None:
        K, M = assemble(disk.coords, conn, E, mat.nu, rho)
    else:
        # K is linear in E and M in ρ: each is the sum of the sectors' elements assembled on their own.
        sector = sector_of_elements(bd)
        K = M = None
        for s in range(bd.n_slots):
            Ks, Ms = assemble(disk.coords, conn[sector == s], E * (1.0 + sector_moduli[s]), mat.nu, rho)
            K, M = (Ks, Ms) if K is None else (K + Ks, M + Ms)
        K, M = sp.csr_matrix(K), sp.csr_matrix(M)
    meta = {**disk.meta, "E": E, "rho": rho}
    return Component(disk.name, K, M, disk.node_ids, disk.coords, dict(disk.node_sets), meta, disk.elements)


def contact_scale(node_pressure: np.ndarray | None, patterns: Sequence[ContactPattern], rng: np.random.Generator,
                  spread: float, exponent: float) -> np.ndarray | None:
    """Each flank node's contact stiffness as a multiple of the nominal law, shape (n_joints, 2, rows, cols).

    ``k_n = k_nominal · c_jf · (p / p̄_jf)^m``: ``c_jf`` is lognormal with ``spread`` (per joint and flank),
    ``p̄_jf`` the flank's mean pressure over its contact nodes and ``m = exponent`` (Hertz: 2/3). ``None`` when
    both are 0 (the nominal law everywhere).

    Parameters
    ----------
    node_pressure : ndarray, shape (n_joints, 2, rows, cols), or None
        Contact pressure (Pa) at the grid nodes; ``None``: uniform (only the joint-and-flank scatter acts).
    """
    if spread == 0 and exponent == 0:
        return None
    n = len(patterns)
    c = np.exp(spread * rng.standard_normal((n, 2)) - 0.5 * spread**2)  # mean 1
    masks = np.stack([np.stack([p.flank(f) for f in FLANKS]) for p in patterns])
    scale = np.broadcast_to(c[:, :, None, None], masks.shape).copy()
    if node_pressure is not None and exponent != 0:
        p = np.asarray(node_pressure, dtype=np.float64)
        for j in range(n):
            for k in range(2):
                m = masks[j, k]
                if m.any():
                    scale[j, k] *= (np.maximum(p[j, k], 1e-300) / p[j, k][m].mean()) ** exponent
    return scale


def reseated_patterns(patterns: Sequence[ContactPattern], node_pressure: np.ndarray | None,
                      rng: np.random.Generator, edge_share: float) -> tuple[ContactPattern, ...]:
    """The contact after re-seating: each flank gains or loses ``edge_share`` of its edge nodes.

    Re-tightening changes a flank's preload: its contact grows (the highest-pressure detached nodes come into
    contact) or shrinks (the lowest-pressure contact nodes come apart), each with probability ½. The count is
    ``round(edge_share · n_edge)``, ``n_edge`` the flank's nodes with a 4-neighbour in the other state.
    """
    if edge_share == 0:
        return tuple(patterns)
    out = []
    for j, pat in enumerate(patterns):
        flanks = []
        for k, f in enumerate(FLANKS):
            m = pat.flank(f).copy()
            p = m.astype(float) if node_pressure is None else np.asarray(node_pressure[j, k], dtype=np.float64)
            grow = bool(rng.integers(2))
            n_change = int(round(edge_share * _edge(m).sum()))
            candidates = np.flatnonzero(~m.ravel() if grow else m.ravel())
            # Rank by pressure (ties, as with no pressure given, broken at random).
            order = np.lexsort((rng.random(candidates.size), -p.ravel()[candidates] if grow else p.ravel()[candidates]))
            flip = candidates[order[:n_change]]
            if not grow:
                flip = flip[: max(0, min(flip.size, m.sum() - 1))]  # a flank keeps at least one contact node
            m.ravel()[flip] = grow
            flanks.append(m)
        out.append(ContactPattern(*flanks))
    return tuple(out)


def _edge(m: np.ndarray) -> np.ndarray:
    """Nodes with a 4-neighbour in the other state, shape of ``m``."""
    e = np.zeros_like(m)
    e[1:] |= m[1:] != m[:-1]
    e[:-1] |= m[1:] != m[:-1]
    e[:, 1:] |= m[:, 1:] != m[:, :-1]
    e[:, :-1] |= m[:, 1:] != m[:, :-1]
    return e


def bolt_masses(disk: Component, slots: Sequence[int], bolt_mass_kg: float, bolts_per_slot: int) -> sp.csr_matrix:
    """The bolts of the mounted blades as a diagonal mass matrix on the disk's DOFs, shape (n_dof, n_dof).

    The bolts press each root from the disk's rim: their mass is spread evenly over the disk's flank-grid
    nodes of the slot (translations only; a bolt's rotary inertia is left out).
    """
    return disk.node_masses([slot_flank_nodes(disk, s) for s in slots], max(bolt_mass_kg, 0.0) * bolts_per_slot)


def day_factors(rng: np.random.Generator, swing_k: float, modulus_coefficient_per_k: float) -> dict[str, float]:
    """A frequency factor per test type: √(1 + α ΔT) with ΔT ~ N(0, swing_k²) drawn per test day.

    Every modulus of the specimen (steel, and the contact's) scales with the day's temperature, so every
    frequency of that day scales by the same factor.
    """
    dT = swing_k * rng.standard_normal(max(TEST_DAYS.values()) + 1)
    return {kind: float(np.sqrt(1.0 + modulus_coefficient_per_k * dT[day])) for kind, day in TEST_DAYS.items()}
