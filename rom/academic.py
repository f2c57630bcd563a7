"""The academic bladed disk: a parametric FE twin with the dimensions of the paper's specimen.

Geometry (SI units, global frame: z = rotation axis, slot 1 centred on +y)
-------------------------------------------------------------------------
* **Disk**: flat annulus, bore radius ``bore_radius`` to ``disk_outer_radius`` (Ø200 mm), thickness
  ``disk_thickness``, with ``n_blades`` straight axial slots of width ``slot_width`` reaching down to
  ``slot_bottom_radius``. The slot walls are planes parallel to the slot's centre line.
* **Blade** (local frame: x = thickness/out-of-plane, y = span/radial, z = chord/axial): a rectangular root
  that fills the slot (its bottom follows the slot-bottom arc), a short shank tapering from the slot width
  to ``blade_thickness``, and a flat airfoil up to ``blade_tip_radius`` (Ø412 mm assembled). The blade
  length is ``blade_tip_radius - slot_bottom_radius`` (117.5 mm) and its chord equals the disk thickness.
* **Contact grids**: flank ``"L"`` is the slot wall at local x = −w/2, ``"R"`` at x = +w/2. Grid node
  ``(i, j)``: row ``i`` runs axially (z from −t/2 to +t/2, the corner planes of ``grid[0] − 1`` element
  layers), column ``j`` runs radially outward along the wall (every node, corner and mid-side, of
  ``(grid[1] − 1) / 2`` quadratic elements). Disk slot ``s`` and the blade placed in it share each node's
  position exactly.
* **Measurement nodes**: the blade has 3 nodes on its leading edge (z = −t/2) on the +x face, at 1/3, 2/3
  and 3/3 of the airfoil span; they measure local x (out of plane). The disk has one node per sector on
  the +z face at the sector centre; it measures z.

Slot ``s`` (1-based) is centred at the angle ``2π (s − 1) / n_blades`` from +y towards +x; the placed blade
is the blade component rotated about z by that angle (:meth:`BladedDisk.slot_rotation`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from .component import Component
from .errors import ROMError
from .hex20 import assemble
from .mesh import StructuredMesh, structured_hex20

__all__ = [
    "Material", "AcademicParams", "BladedDisk", "build_bladed_disk", "check_slot", "flank_coordinates", "MESH_LEVELS",
    "SLOT_SHARE", "disk_scale_for",
]

#: Largest share of the slot pitch (at the slot bottom) that a slot of the paper's width may take before
#: :func:`disk_scale_for` enlarges the disk: the paper's 18-blade disk has 0.52, and up to 24 blades fit
#: below 0.7 unchanged. Above it the teeth between slots grow thinner than about half a slot.
SLOT_SHARE = 0.7

#: Mesh resolution per level: cells per tooth half, per slot (hub), hub rings, blade cells through the
#: thickness, in the shank and along the airfoil span. The contact grid fixes the rim rings and the axial
#: layers, so it is not part of the level.
MESH_LEVELS: dict[str, dict[str, int]] = {
    "coarse": dict(n_tooth=1, n_slot=1, n_hub=3, n_thick=1, n_shank=1, n_airfoil=8),
    "default": dict(n_tooth=2, n_slot=2, n_hub=7, n_thick=2, n_shank=2, n_airfoil=20),
    "fine": dict(n_tooth=3, n_slot=3, n_hub=10, n_thick=2, n_shank=3, n_airfoil=30),
}


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material: ``E`` in Pa, ``rho`` in kg/m³, Poisson's ratio ``nu``."""

    E: float
    rho: float
    nu: float = 0.3

    def validate(self, name: str) -> None:
        if not (math.isfinite(self.E) and self.E > 0):
            raise ValueError(f"{name}.E must be a positive Young's modulus in Pa, got {self.E}")
        if not (math.isfinite(self.rho) and self.rho > 0):
            raise ValueError(f"{name}.rho must be a positive density in kg/m³, got {self.rho}")
        if not (-1.0 < self.nu < 0.5):
            raise ValueError(f"{name}.nu must lie in (-1, 0.5), got {self.nu}")


@dataclass(frozen=True)
class AcademicParams:
    """Every parameter of the academic bladed disk (SI units). Defaults follow the paper's specimen.

    Materials are the calibrated C40 values of the paper's Table 4 (disk ρ = 7864.6 kg/m³, E = 202 GPa;
    blade ρ = 7832.5 kg/m³, E = 212 GPa; ν = 0.3).
    """

    n_blades: int = 18
    disk_outer_radius: float = 0.100
    bore_radius: float = 0.034
    disk_thickness: float = 0.009
    slot_bottom_radius: float = 0.0885
    slot_width: float = 0.016
    blade_tip_radius: float = 0.206
    blade_thickness: float = 0.0024
    shank_length: float = 0.004
    disk_material: Material = field(default_factory=lambda: Material(E=202e9, rho=7864.6))
    blade_material: Material = field(default_factory=lambda: Material(E=212e9, rho=7832.5))
    grid: tuple[int, int] = (7, 31)
    level: str = "default"

    # ------------------------------------------------------------------ derived geometry
    @property
    def blade_length(self) -> float:
        """Blade length from slot bottom to tip (m)."""
        return self.blade_tip_radius - self.slot_bottom_radius

    @property
    def wall_y_range(self) -> tuple[float, float]:
        """Local y of the slot wall's bottom and top (m): where the wall meets the slot-bottom arc and the rim."""
        h = self.slot_width / 2
        return math.sqrt(self.slot_bottom_radius**2 - h * h), math.sqrt(self.disk_outer_radius**2 - h * h)

    def with_(self, **changes) -> AcademicParams:
        """A copy with some parameters changed (validated)."""
        return replace(self, **changes)

    @classmethod
    def for_blades(cls, n_blades: int, disk_scale: float | None = None, **changes) -> AcademicParams:
        """``n_blades`` blades on the paper's disk, enlarged by ``disk_scale`` (default :func:`disk_scale_for`:
        1 up to 24 blades) so that the slots fit; ``changes`` set other parameters (not ``n_blades``)."""
        base = cls(**changes)
        scale = disk_scale_for(n_blades, base) if disk_scale is None else disk_scale
        return replace(base.with_disk_scale(scale), n_blades=int(n_blades))

    def with_disk_scale(self, scale: float) -> AcademicParams:
        """The same blades on a disk whose bore and slot-bottom radii are ``scale`` times these.

        The slots keep their depth and width (the rim moves out with the slot bottom) and the blade its length,
        root and airfoil (its tip moves with the slot bottom); only the slot bottom's arc flattens. The disk
        keeps its thickness: a larger disk of the same design that holds more blades.
        """
        s = float(scale)
        if not (math.isfinite(s) and s > 0):
            raise ValueError(f"disk_scale must be a positive finite factor, got {scale!r}")
        if s == 1.0:
            return self
        rb = s * self.slot_bottom_radius
        return replace(self, disk_outer_radius=rb + (self.disk_outer_radius - self.slot_bottom_radius),
                       bore_radius=s * self.bore_radius, slot_bottom_radius=rb,
                       blade_tip_radius=rb + self.blade_length)

    def to_dict(self) -> dict:
        return asdict(self)

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first bad parameter and its allowed range."""
        if not isinstance(self.n_blades, int) or self.n_blades < 2:
            raise ValueError(f"n_blades must be an integer ≥ 2, got {self.n_blades!r}")
        for name in (
            "disk_outer_radius", "bore_radius", "disk_thickness", "slot_bottom_radius", "slot_width",
            "blade_tip_radius", "blade_thickness", "shank_length",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive length in m, got {v!r}")
        if not self.bore_radius < self.slot_bottom_radius:
            raise ValueError(
                f"bore_radius must be < slot_bottom_radius = {self.slot_bottom_radius} m, got {self.bore_radius}"
            )
        if not self.slot_bottom_radius < self.disk_outer_radius:
            raise ValueError(
                f"slot_bottom_radius must lie in (bore_radius, disk_outer_radius) = "
                f"({self.bore_radius}, {self.disk_outer_radius}) m, got {self.slot_bottom_radius}"
            )
        w_max = 2 * self.slot_bottom_radius * math.sin(math.pi / self.n_blades)
        if not self.slot_width < 0.9 * w_max:
            raise ValueError(
                f"slot_width must be < {0.9 * w_max:.6g} m (90 % of the slot pitch at the slot bottom) so that "
                f"neighbouring slots and blade roots do not overlap, got {self.slot_width}"
            )
        if not self.blade_thickness <= self.slot_width:
            raise ValueError(
                f"blade_thickness must be ≤ slot_width = {self.slot_width} m, got {self.blade_thickness}"
            )
        y_top = self.wall_y_range[1]
        if not self.blade_tip_radius > y_top + self.shank_length:
            raise ValueError(
                f"blade_tip_radius must be > {y_top + self.shank_length:.6g} m (rim + shank), "
                f"got {self.blade_tip_radius}"
            )
        self.disk_material.validate("disk_material")
        self.blade_material.validate("blade_material")
        g = tuple(self.grid)
        if len(g) != 2 or not all(isinstance(n, (int, np.integer)) for n in g):
            raise ValueError(f"grid must be a pair of integers (rows, columns), got {self.grid!r}")
        if g[0] < 2:
            raise ValueError(f"grid[0] (axial rows) must be ≥ 2, got {g[0]}")
        if g[1] < 3 or g[1] % 2 == 0:
            raise ValueError(
                f"grid[1] (radial columns) must be odd and ≥ 3: it takes every node of (grid[1] − 1)/2 "
                f"quadratic elements along the flank; got {g[1]}"
            )
        if self.level not in MESH_LEVELS:
            raise ValueError(f"level must be one of {sorted(MESH_LEVELS)}, got {self.level!r}")

    # ------------------------------------------------------------------ analytic volumes
    def disk_volume(self) -> float:
        """Exact volume of the slotted disk (m³)."""
        R, rb, ri, h = self.disk_outer_radius, self.slot_bottom_radius, self.bore_radius, self.slot_width / 2
        slot_area = 2 * (_arc_area(h, R) - _arc_area(h, rb))
        return self.disk_thickness * (math.pi * (R * R - ri * ri) - self.n_blades * slot_area)

    def blade_volume(self) -> float:
        """Exact volume of one blade (m³)."""
        h, rb = self.slot_width / 2, self.slot_bottom_radius
        y_top = self.wall_y_range[1]
        root = 2 * h * y_top - 2 * _arc_area(h, rb)
        shank = 0.5 * (self.slot_width + self.blade_thickness) * self.shank_length
        airfoil = self.blade_thickness * (self.blade_tip_radius - y_top - self.shank_length)
        return self.disk_thickness * (root + shank + airfoil)


def disk_scale_for(n_blades: int, params: AcademicParams | None = None) -> float:
    """Factor on the disk's bore and slot-bottom radii (:meth:`AcademicParams.with_disk_scale`) that lets
    ``n_blades`` slots of ``params``' width (default: the paper's) take at most :data:`SLOT_SHARE` of the
    pitch; 1 where they do.

    How the virtual rig sizes a disk of many blades (``bladetwin lab simulate --blades 48``): real disks with
    more blades are larger, and the paper's Ø200 mm disk holds at most 31 slots of its 16 mm width.
    """
    p = params or AcademicParams()
    n = int(n_blades)
    if n < 2:
        raise ValueError(f"n_blades must be an integer ≥ 2, got {n_blades!r}")
    pitch = 2 * p.slot_bottom_radius * math.sin(math.pi / n)
    return max(1.0, p.slot_width / (SLOT_SHARE * pitch))


def _arc_area(x: float, rho: float) -> float:
    """∫₀ˣ √(ρ² − s²) ds."""
    return 0.5 * (x * math.sqrt(rho * rho - x * x) + rho * rho * math.asin(x / rho))


@dataclass(frozen=True, eq=False)
class BladedDisk:
    """The disk and blade components of a bladed disk plus the placement of blades into slots.

    Node sets of ``disk``: ``"slot{s}_L"``, ``"slot{s}_R"`` (shape ``grid``) for s = 1..n_slots and
    ``"meas"`` (shape (n_slots,), measures z). Node sets of ``blade``: ``"L"``, ``"R"`` (shape ``grid``),
    ``"meas"`` (shape (3,), measures local x). ``meta["meas_direction"]`` gives the measured direction.
    """

    params: AcademicParams
    disk: Component
    blade: Component

    @property
    def n_slots(self) -> int:
        return self.params.n_blades

    def slot_angle(self, slot: int) -> float:
        """Angle of slot ``slot`` (1-based) in rad, from +y towards +x."""
        self.check_slot(slot)
        return 2 * math.pi * (slot - 1) / self.n_slots

    def slot_rotation(self, slot: int) -> np.ndarray:
        """Rotation R (3×3) placing the blade in ``slot``: x_global = R @ x_blade_local."""
        a = self.slot_angle(slot)
        c, s = math.cos(a), math.sin(a)
        # Rotation about z by −a: local +y (radial) goes to (sin a, cos a, 0).
        return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])

    def placed_blade_coords(self, slot: int) -> np.ndarray:
        """Blade node coordinates in the global frame for ``slot``, shape (n_nodes, 3)."""
        return self.blade.coords @ self.slot_rotation(slot).T

    def interface_gap(self, slot: int) -> float:
        """Largest distance (m) between a disk-slot grid node and the placed blade's grid node."""
        X = self.placed_blade_coords(slot)
        gaps = [
            np.linalg.norm(X[self.blade.node_set(f)] - self.disk.coords[self.disk.node_set(f"slot{slot}_{f}")], axis=-1)
            for f in ("L", "R")
        ]
        return float(max(g.max() for g in gaps))

    def check_slot(self, slot: int) -> int:
        """``slot`` as an int if it names one of this disk's slots (1-based), else :class:`ROMError`."""
        return check_slot(slot, self.n_slots)


def check_slot(slot, n_slots: int) -> int:
    """``slot`` as an int if it lies in 1..n_slots; otherwise a one-line :class:`ROMError` naming it."""
    if isinstance(slot, bool) or not isinstance(slot, (int, np.integer)) or not 1 <= slot <= n_slots:
        raise ROMError(f"slot must be an integer in 1..{n_slots}, got {slot!r}")
    return int(slot)


# ---------------------------------------------------------------------------------------------------
def _disk_mesh(p: AcademicParams) -> tuple[StructuredMesh, dict[str, int]]:
    lv = MESH_LEVELS[p.level]
    N, nt, ns, nh = p.n_blades, lv["n_tooth"], lv["n_slot"], lv["n_hub"]
    nz, nr = p.grid[0] - 1, (p.grid[1] - 1) // 2
    nc = 2 * nt + ns
    R, rb, ri, hw, t = p.disk_outer_radius, p.slot_bottom_radius, p.bore_radius, p.slot_width / 2, p.disk_thickness
    half = math.pi / N
    th_w0 = math.asin(hw / rb)
    y_bot, y_top = p.wall_y_range

    def position(I, J, K):
        I = I.astype(float)
        J = J.astype(float)
        sector, Il = np.divmod(I, 2 * nc)
        # Hub: polar grid; the slot columns span ±θ_w0, the tooth columns the rest of the sector.
        th_hub = np.where(
            Il <= 2 * nt,
            -half + Il / (2 * nt) * (half - th_w0),
            np.where(
                Il <= 2 * (nt + ns),
                -th_w0 + (Il - 2 * nt) / (2 * ns) * 2 * th_w0,
                th_w0 + (Il - 2 * (nt + ns)) / (2 * nt) * (half - th_w0),
            ),
        )
        r = ri + np.minimum(J, 2 * nh) / (2 * nh) * (rb - ri)
        th = th_hub
        # Rim teeth: blend, in polar coordinates, from the straight slot wall to the sector edge.
        tr = np.clip((J - 2 * nh) / (2 * nr), 0.0, 1.0)
        rim = J > 2 * nh
        yw = y_bot + tr * (y_top - y_bot)
        rw, thw = np.hypot(hw, yw), np.arctan2(hw, yw)
        re = rb + tr * (R - rb)
        u = np.where(Il <= 2 * nt, (2 * nt - Il) / (2 * nt), (Il - 2 * (nt + ns)) / (2 * nt))
        u = np.clip(u, 0.0, 1.0)
        sign = np.where(Il <= 2 * nt + ns, -1.0, 1.0)
        r = np.where(rim, rw + u * (re - rw), r)
        th = np.where(rim, sign * (thw + u * (half - thw)), th)
        ang = sector * 2 * half + th
        z = -t / 2 + K / (2 * nz) * t
        return np.stack([r * np.sin(ang), r * np.cos(ang), z], axis=1)

    active = np.ones((N * nc, nh + nr, nz), dtype=bool)
    slot_cols = (np.arange(N * nc) % nc >= nt) & (np.arange(N * nc) % nc < nt + ns)
    active[np.ix_(slot_cols, np.arange(nh, nh + nr), np.arange(nz))] = False
    mesh = structured_hex20((N * nc, nh + nr, nz), position, active, periodic_first=True)
    return mesh, dict(nc=nc, nt=nt, ns=ns, nh=nh, nr=nr, nz=nz)


def _blade_mesh(p: AcademicParams) -> tuple[StructuredMesh, dict[str, int]]:
    lv = MESH_LEVELS[p.level]
    na, nsh, naf = lv["n_thick"], lv["n_shank"], lv["n_airfoil"]
    nz, nr = p.grid[0] - 1, (p.grid[1] - 1) // 2
    hw, hb, rb, t = p.slot_width / 2, p.blade_thickness / 2, p.slot_bottom_radius, p.disk_thickness
    y_bot, y_top = p.wall_y_range
    y_sh = y_top + p.shank_length

    def position(I, J, K):
        s = I / (2 * na)  # 0..1 across the thickness
        J = J.astype(float)
        # Root: x spans the slot; y from the slot-bottom arc to the (flat) root top.
        x_root = -hw + 2 * hw * s
        y_root = np.sqrt(rb * rb - x_root**2)
        t1 = np.clip(J / (2 * nr), 0, 1)
        t2 = np.clip((J - 2 * nr) / (2 * nsh), 0, 1)
        t3 = np.clip((J - 2 * (nr + nsh)) / (2 * naf), 0, 1)
        half_w = np.where(J <= 2 * nr, hw, hw + t2 * (hb - hw))
        x = -half_w + 2 * half_w * s
        y = np.where(
            J <= 2 * nr,
            y_root + t1 * (y_top - y_root),
            np.where(J <= 2 * (nr + nsh), y_top + t2 * p.shank_length, y_sh + t3 * (p.blade_tip_radius - y_sh)),
        )
        z = -t / 2 + K / (2 * nz) * t
        return np.stack([x, y, z], axis=1)

    mesh = structured_hex20((na, nr + nsh + naf, nz), position)
    return mesh, dict(na=na, nr=nr, nsh=nsh, naf=naf, nz=nz)


def build_bladed_disk(params: AcademicParams | None = None) -> BladedDisk:
    """Build the disk and blade components of the academic bladed disk.

    Parameters
    ----------
    params : AcademicParams, optional
        Geometry, materials, grid and mesh level (default: the paper's specimen at the default level).

    Returns
    -------
    BladedDisk
    """
    p = params or AcademicParams()
    gi, gj = p.grid
    dmesh, d = _disk_mesh(p)
    bmesh, b = _blade_mesh(p)

    # Disk node sets: slot grids and one measurement node per sector.
    ii = np.arange(gi)[:, None]
    jj = np.arange(gj)[None, :]
    disk_sets: dict[str, np.ndarray] = {}
    for s in range(p.n_blades):
        base = 2 * d["nc"] * s
        for flank, col in (("L", 2 * d["nt"]), ("R", 2 * (d["nt"] + d["ns"]))):
            disk_sets[f"slot{s + 1}_{flank}"] = dmesh.node_at(base + col + 0 * jj, 2 * d["nh"] + jj, 2 * ii)
    # Measurement: +z face, sector centre, on the hub ring closest to 80 % of the slot-bottom radius.
    frac = (0.8 * p.slot_bottom_radius - p.bore_radius) / (p.slot_bottom_radius - p.bore_radius)
    j_meas = 2 * int(round(frac * d["nh"]))
    centre = 2 * d["nt"] + d["ns"]
    disk_sets["meas"] = dmesh.node_at(2 * d["nc"] * np.arange(p.n_blades) + centre, j_meas, 2 * d["nz"])

    blade_sets = {
        "L": bmesh.node_at(0 * jj + 0 * ii, jj + 0 * ii, 2 * ii),
        "R": bmesh.node_at(2 * b["na"] + 0 * jj + 0 * ii, jj + 0 * ii, 2 * ii),
    }
    j0 = 2 * (b["nr"] + b["nsh"])
    j_le = j0 + np.round(np.array([1, 2, 3]) / 3 * 2 * b["naf"]).astype(int)
    blade_sets["meas"] = bmesh.node_at(np.full(3, 2 * b["na"]), j_le, np.zeros(3, dtype=int))

    Kd, Md = assemble(dmesh.coords, dmesh.conn, p.disk_material.E, p.disk_material.nu, p.disk_material.rho)
    Kb, Mb = assemble(bmesh.coords, bmesh.conn, p.blade_material.E, p.blade_material.nu, p.blade_material.rho)
    disk = Component(
        "disk", Kd, Md, np.arange(1, dmesh.coords.shape[0] + 1), dmesh.coords, disk_sets,
        meta={"meas_direction": 3, "n_elements": int(dmesh.conn.shape[0]), "E": p.disk_material.E},
        elements=dmesh.conn,
    )
    blade = Component(
        "blade", Kb, Mb, np.arange(1, bmesh.coords.shape[0] + 1), bmesh.coords, blade_sets,
        meta={"meas_direction": 1, "n_elements": int(bmesh.conn.shape[0]), "E": p.blade_material.E},
        elements=bmesh.conn,
    )
    return BladedDisk(p, disk, blade)


def flank_coordinates(bd: BladedDisk) -> tuple[np.ndarray, np.ndarray]:
    """Physical in-plane coordinates of the contact-grid nodes of a blade root flank.

    Parameters
    ----------
    bd : rom.academic.BladedDisk
        The bladed disk; the blade's node sets ``"L"`` and ``"R"`` have the grid shape (rows, cols). A bladed
        disk with its own ``flank_coordinates()`` method (an imported one) answers for itself.

    Returns
    -------
    u : ndarray of float64, shape (rows, cols)
        Axial position of each node (m, the blade's local z); it varies along the rows.
    v : ndarray of float64, shape (rows, cols)
        Radial position along the slot wall (m, the blade's local y); it increases with the column.

    Raises
    ------
    ValueError
        If the L and R flanks do not share the same (u, v) layout.
    """
    own = getattr(bd, "flank_coordinates", None)
    if callable(own):
        # An imported bladed disk (rom.importers.model.ImportedBladedDisk) knows its own flank axes; the
        # academic frame below (x thickness, y radial, z axial) would misread any other blade frame.
        return own()
    # (rows, cols, 3) per flank: x thickness, y radial, z axial
    X = {f: bd.blade.coords[bd.blade.node_set(f)] for f in ("L", "R")}
    if not np.allclose(X["L"][..., 1:], X["R"][..., 1:], rtol=0.0, atol=1e-12):
        raise ValueError("flanks L and R of the blade do not share the same (radial, axial) node layout")
    return X["L"][..., 2].astype(np.float64), X["L"][..., 1].astype(np.float64)
