"""ROM-vs-FE validation: FE references with blade mistuning, MAC-paired comparisons, the validation suite.

Blade mistuning has two FE counterparts, both built on :func:`rom.fe_assembly.assemble_fe`'s tie matrix Z:

``scale``
    Blade j's FE stiffness multiplied by (1 + δ_j) (a Young's-modulus change). Its free-interface
    eigenvalues are then exactly (1 + δ_j) ω_i² with unchanged shapes, so Eq. 19 with δ_i = δ_j is the
    physical truth for the retained modes; the ROM still keeps the tuned residual flexibility, which is the
    approximation the paper makes. This is the physical reference used by the acceptance tests.
``modal``
    K_j = K + M Φ_f diag(δ_i ω_i²) Φ_fᵀ M: a rank-m update that moves exactly the retained eigenvalues by
    (1 + δ_i) and nothing else, the FE model Eq. 19 describes for mode-dependent δ.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linear_sum_assignment

from .academic import BladedDisk
from .contact import ContactPattern
from .fe_assembly import AssemblyModes, FEAssembly, assemble_fe

__all__ = [
    "fe_assembly_mistuned",
    "compare",
    "Comparison",
    "random_patterns",
    "one_flank_pattern",
    "validation_patterns",
    "run_validation",
    "solve_fe_modes",
]

log = logging.getLogger(__name__)


def fe_assembly_mistuned(
    bd: BladedDisk,
    patterns: Mapping[int, ContactPattern],
    deltas: np.ndarray | None = None,
    *,
    kind: str = "scale",
    Phi_f: np.ndarray | None = None,
    omega2: np.ndarray | None = None,
) -> FEAssembly:
    """FE reference assembly with blade mistuning (see module notes).

    Parameters
    ----------
    bd : BladedDisk
    patterns : mapping slot → ContactPattern
    deltas : ndarray, shape (n_populated,) for ``kind="scale"`` or (n_populated, k) for ``kind="modal"``
        One row per populated slot, in increasing slot order.
    kind : {"scale", "modal"}
    Phi_f, omega2 : ndarray, shapes (n_blade_dof, k) and (k,)
        Mass-normalised blade free-interface modes and eigenvalues (``kind="modal"`` only).
    """
    asm = assemble_fe(bd, patterns)
    if deltas is None:
        return asm
    d = np.asarray(deltas, dtype=np.float64)
    n_pop = len(asm.slots)
    if d.shape[0] != n_pop or not np.all(np.isfinite(d)):
        raise ValueError(f"deltas must be finite with one row per populated slot ({n_pop}), got shape {d.shape}")
    nd, Kb, Mb = bd.disk.n_dof, bd.blade.K, bd.blade.M
    if kind == "scale":
        if d.ndim != 1:
            raise ValueError(f"kind='scale' takes one δ per blade, shape ({n_pop},), got {d.shape}")
        blocks = [sp.csr_matrix((nd, nd))] + [float(dj) * Kb for dj in d]
        dK = asm.Z.T @ sp.block_diag(blocks, format="csr") @ asm.Z
    elif kind == "modal":
        if Phi_f is None or omega2 is None:
            raise ValueError("kind='modal' needs the blade's free-interface modes Phi_f and eigenvalues omega2")
        d = np.atleast_2d(d)
        k = d.shape[1]
        MP = np.asarray(Mb @ Phi_f[:, :k])
        # Low-rank: dK = Zbᵀ (M Φ) diag(δ ω²) (M Φ)ᵀ Zb, assembled blade by blade as dense-free sparse products.
        U = sp.block_diag([sp.csr_matrix((nd, 0))] + [sp.csr_matrix(MP)] * n_pop, format="csr")
        D = sp.diags(np.concatenate([dj * omega2[:k] for dj in d]))
        ZU = (asm.Z.T @ U).tocsr()
        dK = ZU @ D @ ZU.T
    else:
        raise ValueError(f"kind must be 'scale' or 'modal', got {kind!r}")
    return FEAssembly((asm.K + dK).tocsr(), asm.M, asm.Z, asm.meas_rows, asm.meas_labels, asm.slots)


@dataclass(frozen=True, eq=False)
class Comparison:
    """ROM-vs-FE comparison of one model.

    Attributes
    ----------
    name : str
    f_fe, f_rom : ndarray, shape (n,)
        Paired frequencies (Hz), FE order.
    rel_err : ndarray, shape (n,)
        (f_rom − f_fe) / f_fe (fractions).
    mac : ndarray, shape (n,) or None
        MAC of each pair at the measurement DOFs (None for substructures compared by frequency only).
    meta : dict
    """

    name: str
    f_fe: np.ndarray
    f_rom: np.ndarray
    rel_err: np.ndarray
    mac: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    @property
    def max_rel_err(self) -> float:
        return float(np.max(np.abs(self.rel_err)))

    @property
    def min_mac(self) -> float:
        return float(np.min(self.mac)) if self.mac is not None else float("nan")

    def to_dict(self) -> dict:
        out = {"max_rel_err": self.max_rel_err, "n_modes": int(self.f_fe.size)}
        if self.mac is not None:
            out["min_mac"] = self.min_mac
        return out


def compare(name: str, fe: AssemblyModes, rom: AssemblyModes, n: int, *, by_mac: bool = True, **meta) -> Comparison:
    """Compare the first ``n`` FE modes with ROM modes, paired by MAC (Hungarian) or by index.

    The ROM may carry more modes than ``n`` so that MAC pairing has room; labels must agree.
    """
    if list(fe.meas_labels) != list(rom.meas_labels):
        raise ValueError("FE and ROM measurement labels differ; cannot compare shapes")
    if by_mac:
        i, j, m = _assign_by_mac(fe.frequencies_hz[:n], fe.meas_shapes[:, :n], rom.frequencies_hz, rom.meas_shapes)
        f0, f1 = fe.frequencies_hz[:n][i], rom.frequencies_hz[j]
        return Comparison(name, f0, f1, (f1 - f0) / f0, m, {**meta, "rom_index": j.tolist()})
    m = np.diag(_mac(fe.meas_shapes[:, :n], rom.meas_shapes[:, :n]))
    f0, f1 = fe.frequencies_hz[:n], rom.frequencies_hz[:n]
    return Comparison(name, f0, f1, (f1 - f0) / f0, m, dict(meta))


def _mac(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """MAC between the columns of real shapes ``A`` (n, a) and ``B`` (n, b); shape (a, b).

    Private on purpose: the one public test–analysis correlation API is ``ema.mac`` / ``ema.pair_modes``
    (complex shapes, labelled DOFs). ``rom`` may not import ``ema`` (design §1), and ROM-vs-FE checks only
    need real shapes on identical DOFs.
    """
    num = (A.T @ B) ** 2
    den = np.outer(np.einsum("ij,ij->j", A, A), np.einsum("ij,ij->j", B, B))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, 0.0)


def _assign_by_mac(
    f_ref: np.ndarray, shapes_ref: np.ndarray, f_test: np.ndarray, shapes_test: np.ndarray, window: float = 0.05
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Forced MAC assignment of every reference (FE) mode to a test (ROM) mode.

    Unlike ``ema.pair_modes``, which reports unpaired modes, a validation must give every FE mode a partner:
    the Hungarian assignment maximises the total MAC among test modes within ``window`` (relative frequency)
    and uses pairs outside it (score −1) only when nothing else is left.

    Returns
    -------
    ref_index, test_index : ndarray of int, shape (n_ref,)
    mac : ndarray, shape (n_ref,)
    """
    if f_test.size < f_ref.size:
        raise ValueError(f"need at least as many test modes as reference modes, got {f_test.size} < {f_ref.size}")
    C = _mac(shapes_ref, shapes_test)
    rel = (f_test[None, :] - f_ref[:, None]) / f_ref[:, None]
    r, c = linear_sum_assignment(np.where(np.abs(rel) <= window, C, -1.0), maximize=True)
    order = np.argsort(r)
    return r[order], c[order], C[r[order], c[order]]


def one_flank_pattern(grid: tuple[int, int], flank: str = "L") -> ContactPattern:
    """All nodes of one flank in contact, none on the other."""
    on, off = np.ones(grid, bool), np.zeros(grid, bool)
    return ContactPattern(on, off) if flank == "L" else ContactPattern(off, on)


def random_patterns(
    grid: tuple[int, int], slots, rng: np.random.Generator, fraction: tuple[float, float] = (0.3, 0.9)
) -> dict[int, ContactPattern]:
    """Random pattern per slot with a contact fraction drawn uniformly in ``fraction``."""
    return {int(s): ContactPattern.random(grid, float(rng.uniform(*fraction)), rng) for s in slots}




def validation_patterns(grid: tuple[int, int], rng: np.random.Generator) -> dict[str, ContactPattern]:
    """The four disk–one-blade validation patterns: all contact, ~30 % contact, one flank, ~70 % random."""
    n = grid[0] * grid[1]
    grids = []
    for _ in range(2):
        g = np.zeros(grid, bool)
        g.flat[rng.choice(n, max(3, round(0.3 * n)), replace=False)] = True
        grids.append(g)
    return {
        "all contact": ContactPattern.full(grid),
        "~30 % contact": ContactPattern(*grids),
        "one flank (L)": one_flank_pattern(grid, "L"),
        "~70 % random": ContactPattern.random(grid, 0.7, rng),
    }


def run_validation(
    bd: BladedDisk,
    disk_cb,
    blade,
    *,
    seed: int = 0,
    parts: tuple[str, ...] = ("disk", "blade", "d1b", "full"),
    formulation: str | None = None,
    progress=None,
) -> dict[str, list[Comparison]]:
    """ROM-vs-FE validation suite (the acceptance checks of issue 3).

    * ``disk``: 20 elastic modes of the free disk, CB (boundary freed) vs FE, by index.
    * ``blade``: 20 elastic modes of the free blade, Rubin vs FE, by index.
    * ``d1b``: 10 modes for the four :func:`validation_patterns` in the CB model's slot, MAC at the
      measurement DOFs, by index.
    * ``full``: 3 N modes with a random pattern per slot and a random δ per blade within ±2 % (FE reference:
      blade stiffness scaled by 1 + δ), sparse hybrid ROM, paired by MAC.

    ``progress`` is called with a short message before each step (the CLI maps it to its progress display).
    """
    from .rom_assembly import DEFAULT_FORMULATION, solve_d1b, solve_full
    from .solver import solve_modes

    form = formulation or DEFAULT_FORMULATION
    say = progress or (lambda msg: log.info(msg))
    rng = np.random.default_rng(seed)
    out: dict[str, list[Comparison]] = {}
    if "disk" in parts:
        say("disk: FE free modes")
        fe = solve_modes(bd.disk.K, bd.disk.M, 20).frequencies_hz
        say("disk: CB free modes")
        rom = disk_cb.free_modes(20).frequencies_hz
        out["disk"] = [Comparison("free disk", fe, rom, rom / fe - 1, None, {"n_k": disk_cb.n_k})]
    if "blade" in parts:
        say("blade: FE free modes")
        fe = solve_modes(bd.blade.K, bd.blade.M, 20).frequencies_hz
        rom = blade.free_modes(20).frequencies_hz
        out["blade"] = [Comparison("free blade", fe, rom, rom / fe - 1, None, {"m": blade.m})]
    if "d1b" in parts:
        slot = int(disk_cb.meta["slots"][0])
        res = []
        for name, p in validation_patterns(bd.params.grid, rng).items():
            say(f"d1b: FE reference, {name}")
            fe = solve_fe_modes(bd, {slot: p}, 10)
            rom = solve_d1b(disk_cb, blade, p, slot, n_modes=10, formulation=form)
            res.append(compare(f"d1b slot {slot}, {name}", fe, rom, 10, by_mac=False,
                               contact_fraction=p.contact_fraction))
        out["d1b"] = res
    if "full" in parts:
        n = 3 * bd.n_slots
        pats = random_patterns(bd.params.grid, range(1, bd.n_slots + 1), rng)
        delta = rng.uniform(-0.02, 0.02, bd.n_slots)
        say(f"full: FE reference ({n} modes)")
        from .fe_assembly import solve_fe

        fe = solve_fe(fe_assembly_mistuned(bd, pats, delta), n)
        say(f"full: hybrid ROM ({n} modes)")
        rom = solve_full(bd, blade, pats, delta[:, None] * np.ones(blade.m), n_modes=n + 12, formulation=form)
        out["full"] = [compare("full, random δ ±2 % and patterns", fe, rom, n)]
    return out


def solve_fe_modes(bd: BladedDisk, patterns: Mapping[int, ContactPattern], n: int) -> AssemblyModes:
    """FE reference modes of an assembly (:func:`rom.fe_assembly.solve_fe` of :func:`assemble_fe`)."""
    from .fe_assembly import solve_fe

    return solve_fe(assemble_fe(bd, patterns), n)
