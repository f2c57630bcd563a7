"""Plots of FE components and models. Plot functions only read results; they compute nothing physical.

Contact-grid orientation (the same in every bladetwin plot): a flank is drawn with the radial direction
(grid columns j, outward) to the right and the axial direction (grid rows i, +z) upward.
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from .academic import BladedDisk

__all__ = ["plot_mesh", "front_edges"]

# Edges of the hex20 element as node triples (corner, mid-side, corner).
_EDGES = np.array([
    [0, 8, 1], [1, 9, 2], [2, 10, 3], [3, 11, 0], [4, 12, 5], [5, 13, 6], [6, 14, 7], [7, 15, 4],
    [0, 16, 4], [1, 17, 5], [2, 18, 6], [3, 19, 7],
])


def front_edges(coords: np.ndarray, elements: np.ndarray) -> np.ndarray:
    """Element edges lying on the front face (largest z), as polylines of shape (n_edges, 3, 2) in x–y."""
    z_front = coords[:, 2].max()
    tri = elements[:, _EDGES].reshape(-1, 3)
    on_front = np.all(np.abs(coords[tri, 2] - z_front) < 1e-9 * max(1.0, abs(z_front)), axis=1)
    tri = tri[on_front]
    return coords[tri][:, :, :2]


def plot_mesh(bd: BladedDisk, fig: Figure | None = None, slot: int = 1) -> Figure:
    """Front view of the bladed disk mesh, a zoom on one slot, and the unrolled contact flank.

    Contact-grid nodes are red (flank L) and blue (flank R); measurement nodes are black triangles (disk,
    measure z) and orange stars (blades, measure the out-of-plane direction).
    """
    fig = fig or Figure(figsize=(15, 5.5), layout="constrained")
    ax_all, ax_zoom, ax_flank = fig.subplots(1, 3, width_ratios=[1.2, 1.0, 0.9])
    disk, blade = bd.disk, bd.blade
    d_edges = front_edges(disk.coords, disk.elements) * 1e3
    b_edges_local = front_edges(blade.coords, blade.elements)
    for ax in (ax_all, ax_zoom):
        ax.add_collection(LineCollection(d_edges, colors="0.55", linewidths=0.3))
        for s in range(1, bd.n_slots + 1):
            R = bd.slot_rotation(s)[:2, :2]
            ax.add_collection(LineCollection(b_edges_local @ R.T * 1e3, colors="tab:green", linewidths=0.3))
        for s in range(1, bd.n_slots + 1):
            for f, c in (("L", "tab:red"), ("R", "tab:blue")):
                P = disk.coords[disk.node_set(f"slot{s}_{f}")].reshape(-1, 3) * 1e3
                ax.plot(P[:, 0], P[:, 1], ".", color=c, ms=2.5)
        P = disk.coords[disk.node_set("meas")] * 1e3
        ax.plot(P[:, 0], P[:, 1], "^", color="k", ms=5, label="disk measurement (z)")
        for s in range(1, bd.n_slots + 1):
            P = bd.placed_blade_coords(s)[blade.node_set("meas")] * 1e3
            label = "blade measurement (out of plane)" if s == 1 else None
            ax.plot(P[:, 0], P[:, 1], "*", color="tab:orange", ms=7, label=label)
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    ax_all.autoscale()
    ax_all.set_title(f"{bd.n_slots} blades, disk {disk.n_dof:,} DOF, blade {blade.n_dof:,} DOF")
    ax_all.legend(loc="lower left", fontsize=7)
    # Zoom on the root of one slot.
    a = bd.slot_angle(slot)
    c = np.array([np.sin(a), np.cos(a)]) * bd.params.disk_outer_radius * 1e3
    half = 1.4 * bd.params.slot_width * 1e3
    ax_zoom.set_xlim(c[0] - half, c[0] + half)
    ax_zoom.set_ylim(c[1] - 1.3 * half, c[1] + 0.7 * half)
    ax_zoom.set_title(f"slot {slot}: flank L (red), R (blue)")
    # Unrolled flank: columns j (radial, outward) to the right, rows i (axial, +z) upward.
    G = blade.node_set("L")
    X = blade.coords[G] * 1e3
    ax_flank.plot(X[..., 1].ravel(), X[..., 2].ravel(), "o", color="tab:red", ms=3)
    ni, nj = G.shape
    for (i, j) in ((0, 0), (ni - 1, 0), (0, nj - 1), (ni - 1, nj - 1)):
        ax_flank.annotate(f"({i},{j})", X[i, j, [1, 2]], fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax_flank.set_xlabel("radial position y (mm)  →  grid column j")
    ax_flank.set_ylabel("axial position z (mm)  →  grid row i")
    ax_flank.set_title(f"contact grid {ni}×{nj} (flank L, blade frame)")
    ax_flank.set_aspect("equal")
    return fig
