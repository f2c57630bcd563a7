"""True contact patterns: a smooth contact-pressure field on every flank of every joint.

The rig's *truth* for contact is a pressure field per joint (slot) and flank, defined as a continuous
function of the flank's physical coordinates, so that it can be evaluated at the grid nodes (the contact
pattern the truth twin uses) and at film-pixel resolution (:mod:`lab.films`). A node is in contact where
the pressure exceeds that flank's threshold.

Coordinates
-----------
``u`` is the axial position (m, the blade's local z; grid rows), ``v`` the radial position along the
slot wall (m, the blade's local y; grid columns, increasing outwards from the slot bottom). Inside the
model the field works in normalised flank coordinates

    ξ = (u − u_c) / (u_max − u_min),   η = (v − v_c) / (v_max − v_min),

where the box is the one spanned by the grid nodes and (u_c, v_c) its centre, so ξ, η ∈ [−½, ½] on the
flank and the shape parameters (length scales, island radii, seating offset) are fractions of the flank.

Pressure model
--------------
For joint ``s`` and flank ``f`` (``"L"`` or ``"R"``)

    z_sf(ξ, η) = C_f(ξ, η − d_s) + a_v G_sf(ξ, η) + g_sf · (ξ, η) − Σ_k h_k exp(−|(ξ, η) − c_k|² / (2 r_k²))
                 + a_r Q_sf(ξ, η)
    p_sf = p_ref · log(1 + exp(z_sf))                                                               [Pa]

* ``C_f``, the **common shape** of flank side ``f``, is drawn once for all joints (manufacturing is
  uniform): a Gaussian bearing core plus a smooth random field. Imprints of one flank side therefore share
  their dominant features.
* ``G_sf`` is a smooth random field of the joint (local variation), with amplitude ``a_v``.
* ``d_s`` is the joint's seating depth (radial offset of the imprint, shared by both flanks of a blade).
* ``g_sf`` is the misalignment tilt: a pressure gradient drawn per joint; its axial component changes sign
  from L to R (a root yawed in its slot bears on opposite axial ends of its two flanks).
* The Gaussian dips are local low-pressure islands (a Poisson number per flank).
* ``Q_sf`` is the flank's roughness, a smooth random field with a correlation length of about a node's
  spacing and amplitude ``a_r`` (0 on the ideal twin): it makes the contact's edge ragged and the film's
  imprint grainy, as a ground surface's does. Misalignment (``g``), form error (``C``, ``G``, the islands) and
  roughness are the three sources of a flank's pressure.
* The softplus keeps the pressure positive and smooth.

The smooth random fields are random-Fourier-feature samples of a unit-variance Gaussian process with a
squared-exponential covariance (Rahimi & Recht, 2007), which is what makes them continuous functions that
can be evaluated anywhere. Each flank's threshold is set from a target contact fraction drawn uniformly in
``PressureParams.fraction_range``; the contact count then moves by at most ``fraction_window`` of the nodes
so that the threshold, the (geometric) midpoint of the pressure gap between two consecutive nodes, has as few
nodes as possible within about ``threshold_margin`` (relative) of it. Nearly every node's pressure then
lies clearly above or below its threshold, so that a film reading can recover the grid (:mod:`lab.films`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtr

from rom.academic import flank_coordinates
from rom.contact import ContactPattern

from .pressure_fields import CommonShape, FlankField, Lattice, SmoothField

__all__ = ["PressureParams", "TruePressure", "flank_coordinates", "simulate_pressure", "redraw_joints"]

FLANKS = ("L", "R")


@dataclass(frozen=True)
class PressureParams:
    """Parameters of the true-pressure generator. Lengths are fractions of the flank's extent per axis.

    Attributes
    ----------
    fraction_range : (float, float)
        Range of the contact area fraction (share of grid nodes in contact) per joint and flank; each flank's
        target is drawn uniformly in it. Default (0.30, 0.85).
    p_ref : float
        Pressure scale (Pa): p = p_ref · softplus(z). Default 30 MPa.
    core_amplitude : float
        Height (z units) of the Gaussian bearing core of the common shape. Default 2.0.
    core_width : float
        Mean standard deviation of the core (flank extents); each axis draws ×U(0.75, 1.25). Default 0.45.
    core_offset : float
        The core's centre is drawn uniformly in [−core_offset, core_offset]² (flank extents). Default 0.15.
    shape_amplitude : float
        Standard deviation (z units) of the common smooth random field. Default 1.0.
    length_scale : float
        Correlation length of the common random field (flank extents). Default 0.35.
    variation : float
        Standard deviation (z units) of each joint's own smooth random field. Default 0.35.
    variation_length_scale : float
        Correlation length of the per-joint field (flank extents). Default 0.25.
    tilt_spread : float
        Standard deviation of each component of the misalignment gradient (z units per flank extent).
        Default 0.5.
    seating_spread : float
        Standard deviation of the seating depth, the radial offset of a joint's imprint (flank heights).
        Default 0.05.
    islands : float
        Mean number (Poisson) of low-pressure islands per flank. Default 0.8.
    island_radius : (float, float)
        Range of the islands' Gaussian radius (flank extents). Default (0.06, 0.14).
    island_depth : (float, float)
        Range of the islands' depth (z units). Default (1.0, 2.5).
    n_features : int
        Random Fourier features per smooth field. Default 64.
    fraction_window : float
        How far (fraction of the nodes, at least one node) the contact count may move from its target to
        put the threshold into a clear pressure gap between nodes. Default 0.05.
    threshold_margin : float
        Relative pressure uncertainty of a reading (a film's noise, say), used to keep nodes away from the
        threshold; 0 picks the widest gap instead. Default 0.01.
    roughness : float
        Standard deviation (z units) of each flank's roughness field: the pressure scatter that the surface's
        roughness adds on top of its form error, at about a node's spacing. Default 0 (no roughness: the
        ideal twin); the realistic twin's (:meth:`of`) is 0.3, about 15 % of the pressure where z ≈ 2
        (docs/twin.md).
    roughness_length_scale : float
        Correlation length of the roughness field (flank extents). Default 0.04.
    """

    fraction_range: tuple[float, float] = (0.30, 0.85)
    p_ref: float = 30e6
    core_amplitude: float = 2.0
    core_width: float = 0.45
    core_offset: float = 0.15
    shape_amplitude: float = 1.0
    length_scale: float = 0.35
    variation: float = 0.35
    variation_length_scale: float = 0.25
    tilt_spread: float = 0.5
    seating_spread: float = 0.05
    islands: float = 0.8
    island_radius: tuple[float, float] = (0.06, 0.14)
    island_depth: tuple[float, float] = (1.0, 2.5)
    n_features: int = 64
    fraction_window: float = 0.05
    threshold_margin: float = 0.01
    roughness: float = 0.0
    roughness_length_scale: float = 0.04

    @classmethod
    def of(cls, realism: str) -> PressureParams:
        """The generator of a realism setting (``"realistic"``: with roughness; ``"ideal"``: without)."""
        if realism not in ("realistic", "ideal"):
            raise ValueError(f"realism {realism!r}: expected 'realistic' or 'ideal'")
        return cls(roughness=0.3) if realism == "realistic" else cls()

    def __post_init__(self) -> None:
        lo, hi = self.fraction_range
        if not 0.0 < lo <= hi < 1.0:
            raise ValueError(f"fraction_range must satisfy 0 < low ≤ high < 1, got {self.fraction_range}")
        for name in ("p_ref", "core_width", "length_scale", "variation_length_scale", "roughness_length_scale"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        if not 0.0 <= self.fraction_window < 1.0:
            raise ValueError(f"fraction_window must lie in [0, 1), got {self.fraction_window!r}")
        if not (math.isfinite(self.threshold_margin) and self.threshold_margin >= 0):
            raise ValueError(f"threshold_margin must be ≥ 0 and finite, got {self.threshold_margin!r}")
        for name in ("core_amplitude", "core_offset", "shape_amplitude", "variation", "tilt_spread",
                     "seating_spread", "islands", "roughness"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be ≥ 0 and finite, got {v!r}")
        for name in ("island_radius", "island_depth"):
            a, b = getattr(self, name)
            if not 0.0 < a <= b < math.inf:
                raise ValueError(f"{name} must be a range 0 < low ≤ high, got {getattr(self, name)}")
        if not (isinstance(self.n_features, int) and self.n_features >= 1):
            raise ValueError(f"n_features must be an integer ≥ 1, got {self.n_features!r}")


def _softplus(z: np.ndarray) -> np.ndarray:
    return np.logaddexp(0.0, z)


@dataclass(frozen=True, eq=False)
class TruePressure:
    """True contact-pressure fields of every joint and flank, and the contact patterns they imply.

    Joints are numbered 1..n_joints as the slots of :mod:`rom`; the arrays :attr:`L`, :attr:`R`,
    :attr:`threshold` and :attr:`fractions` are indexed by ``joint − 1``. Build it with
    :func:`simulate_pressure`.

    Attributes
    ----------
    u, v : ndarray of float64, shape (rows, cols)
        Grid-node coordinates (m): axial (rows) and radial along the wall (columns).
    fields : tuple of (FlankField, FlankField)
        Per joint, the L and R flank fields.
    threshold : ndarray of float64, shape (n_joints, 2)
        Contact threshold pressure (Pa) per joint and flank (columns L, R).
    params : PressureParams
    L, R : ndarray of bool, shape (n_joints, rows, cols)
        Derived: contact at the grid nodes (pressure > threshold), read-only.
    """

    u: np.ndarray
    v: np.ndarray
    fields: tuple[tuple[FlankField, FlankField], ...]
    threshold: np.ndarray
    params: PressureParams
    L: np.ndarray = field(init=False, repr=False)
    R: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        u, v = _check_grid(self.u, self.v)
        thr = np.array(self.threshold, dtype=np.float64)
        if thr.shape != (len(self.fields), 2):
            raise ValueError(f"threshold must have shape (n_joints, 2) = ({len(self.fields)}, 2), got {thr.shape}")
        for a in (u, v, thr):
            a.flags.writeable = False
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "v", v)
        object.__setattr__(self, "threshold", thr)
        for k, name in enumerate(FLANKS):
            grids = np.stack([self.pressure(s, name, u, v) > thr[s - 1, k] for s in range(1, self.n_joints + 1)])
            grids.flags.writeable = False
            object.__setattr__(self, name, grids)

    @property
    def n_joints(self) -> int:
        return len(self.fields)

    @property
    def grid(self) -> tuple[int, int]:
        """Grid shape (rows, cols)."""
        return self.u.shape

    @property
    def fractions(self) -> np.ndarray:
        """Contact area fraction at the grid nodes, shape (n_joints, 2) (columns L, R)."""
        return np.stack([self.L.mean(axis=(1, 2)), self.R.mean(axis=(1, 2))], axis=1)

    def normalized(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normalised flank coordinates (ξ, η) of physical points (u, v) in m (any equal shapes)."""
        return _normalized(self.u, self.v, u, v)

    def _index(self, joint: int, flank: str) -> tuple[int, int]:
        if isinstance(joint, bool) or not isinstance(joint, (int, np.integer)) or not 1 <= joint <= self.n_joints:
            raise ValueError(f"joint must be an integer in 1..{self.n_joints}, got {joint!r}")
        if flank not in FLANKS:
            raise ValueError(f"flank must be 'L' or 'R', got {flank!r}")
        return int(joint) - 1, FLANKS.index(flank)

    def pressure(self, joint: int, flank: str, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Contact pressure (Pa) of a joint's flank at physical points.

        Parameters
        ----------
        joint : int
            Joint (slot) number, 1..n_joints.
        flank : {"L", "R"}
        u, v : array_like of float, broadcastable shapes
            Axial and radial positions (m), in the frame of :attr:`u`, :attr:`v`. Points off the flank are
            evaluated by the same smooth formula (the caller decides where the surface ends).

        Returns
        -------
        ndarray of float64, the broadcast shape of ``u`` and ``v``
        """
        s, k = self._index(joint, flank)
        xi, eta = self.normalized(*np.broadcast_arrays(u, v))
        return self.params.p_ref * _softplus(self.fields[s][k](xi, eta))

    def pressure_on_lattice(
        self,
        joint: int,
        flank: str,
        origin: tuple[float, float],
        row_step: tuple[float, float],
        col_step: tuple[float, float],
        shape: tuple[int, int],
    ) -> np.ndarray:
        """Contact pressure (Pa) on a regular lattice of points, e.g. an image's pixels.

        The points are (u, v) = origin + r · row_step + c · col_step (all in m) for r < shape[0],
        c < shape[1]. The values equal :meth:`pressure` at those points, computed separably (much faster on
        large lattices).

        Returns
        -------
        ndarray of float64, shape ``shape``
        """
        s, k = self._index(joint, flank)
        o = np.array(self.normalized(*origin))
        o0 = np.array(self.normalized(0.0, 0.0))
        # ξ, η are affine in (u, v): a step's image is the difference of the images of the step and of 0.
        lat = Lattice(o, np.array(self.normalized(*row_step)) - o0, np.array(self.normalized(*col_step)) - o0,
                      (int(shape[0]), int(shape[1])))
        xi, eta = lat.points()
        return self.params.p_ref * _softplus(self.fields[s][k](xi, eta, lat))

    def contact_threshold(self, joint: int, flank: str) -> float:
        """Threshold pressure (Pa) above which a point of this joint's flank is in contact."""
        s, k = self._index(joint, flank)
        return float(self.threshold[s, k])

    def patterns(self) -> list[ContactPattern]:
        """Contact patterns at the grid nodes; element ``joint − 1`` belongs to joint ``joint``."""
        return [ContactPattern(L, R) for L, R in zip(self.L, self.R, strict=True)]


def _check_grid(u, v) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.array(u, dtype=np.float64), np.array(v, dtype=np.float64)
    if u.ndim != 2 or u.shape != v.shape:
        raise ValueError(f"u and v must be 2-D arrays of the same shape (rows, cols), got {u.shape} and {v.shape}")
    if min(u.shape) < 2:
        raise ValueError(f"the grid needs ≥ 2 rows and ≥ 2 columns, got shape {u.shape}")
    if not (np.isfinite(u).all() and np.isfinite(v).all()):
        raise ValueError("u and v must be finite")
    if not (np.ptp(u) > 0 and np.ptp(v) > 0):
        raise ValueError("u and v must each span a positive extent (m)")
    return u, v


def _normalized(u_grid, v_grid, u, v) -> tuple[np.ndarray, np.ndarray]:
    u0, u1, v0, v1 = u_grid.min(), u_grid.max(), v_grid.min(), v_grid.max()
    xi = (np.asarray(u, np.float64) - 0.5 * (u0 + u1)) / (u1 - u0)
    return xi, (np.asarray(v, np.float64) - 0.5 * (v0 + v1)) / (v1 - v0)


def _threshold(p: np.ndarray, fraction: float, lo: float, hi: float, window: float, margin: float) -> float:
    """Threshold for the node pressures ``p`` (Pa) giving a contact fraction near ``fraction``, within [lo, hi].

    The contacting count k starts at round(fraction·n), clipped into [lo·n, hi·n] and 1..n−1. It may then move
    by up to ``window``·n nodes (at least one). Each candidate threshold is the geometric midpoint between the
    k-th highest node pressure and the next; the one kept has the fewest expected misreadings
    Σ_i Φ(−|ln p_i − ln t| / margin), i.e. few nodes within a hair of it, where their contact state would be
    a coin toss for any reading (and in the real joint).
    """
    n = p.size
    k_lo, k_hi = max(math.ceil(lo * n - 1e-9), 1), min(math.floor(hi * n + 1e-9), n - 1)
    if k_lo > k_hi:
        raise ValueError(f"a grid of {n} nodes has no node count with a fraction in [{lo}, {hi}] (and 0 < k < n)")
    k0 = min(max(round(fraction * n), k_lo), k_hi)
    w = max(1, round(window * n))
    q = np.log(np.sort(p.ravel()))[::-1]  # descending: the k highest nodes are q[:k]
    ks = np.arange(max(k0 - w, k_lo), min(k0 + w, k_hi) + 1)
    t = 0.5 * (q[ks - 1] + q[ks])
    if margin > 0:
        risk = ndtr(-np.abs(q[None, :] - t[:, None]) / margin).sum(axis=1)
    else:
        risk = -(q[ks - 1] - q[ks])  # the widest gap
    return float(np.exp(t[np.argmin(risk)]))


def simulate_pressure(
    u: np.ndarray, v: np.ndarray, n_joints: int, rng: np.random.Generator, params: PressureParams | None = None
) -> TruePressure:
    """Draw the true contact-pressure fields of ``n_joints`` joints.

    Parameters
    ----------
    u, v : array_like of float, shape (rows, cols)
        Grid-node coordinates (m): axial along the rows, radial along the columns (:func:`flank_coordinates`).
        Any grid shape with ≥ 2 rows and columns.
    n_joints : int
        Number of joints (slots), any positive integer.
    rng : numpy.random.Generator
        Source of all randomness. The common shapes are drawn first, then joint after joint, so the first
        joints do not change when ``n_joints`` grows.
    params : PressureParams, optional

    Returns
    -------
    TruePressure
        Every flank's contact fraction lies in ``params.fraction_range`` (node counts are rounded into it),
        and every joint is a valid :class:`rom.contact.ContactPattern`.

    Raises
    ------
    ValueError
        If the grid is too small for the fraction range (no whole node count inside it) or a joint would not
        hold three non-collinear contacting nodes.
    """
    p = params or PressureParams()
    if isinstance(n_joints, bool) or not isinstance(n_joints, (int, np.integer)) or n_joints < 1:
        raise ValueError(f"n_joints must be a positive integer, got {n_joints!r}")
    u, v = _check_grid(u, v)
    commons = tuple(
        CommonShape(
            centre=rng.uniform(-p.core_offset, p.core_offset, 2),
            width=p.core_width * rng.uniform(0.75, 1.25, 2),
            amplitude=p.core_amplitude,
            field=SmoothField.draw(rng, p.n_features, p.length_scale),
            field_amplitude=p.shape_amplitude,
        )
        for _ in FLANKS
    )
    xi, eta = _normalized(u, v, u, v)
    fields, thresholds = [], []
    for _ in range(int(n_joints)):
        pair, thr = _draw_joint(rng, commons, p, xi, eta)
        fields.append(pair)
        thresholds.append(thr)
    truth = TruePressure(u, v, tuple(fields), np.array(thresholds), p)
    truth.patterns()  # fail here, not in a later ROM, if a tiny grid cannot hold 3 non-collinear contacts
    return truth


def _draw_joint(rng: np.random.Generator, commons: tuple, p: PressureParams, xi: np.ndarray, eta: np.ndarray,
                fraction: float | None = None) -> tuple[tuple[FlankField, FlankField], list[float]]:
    """One joint's own parts (seating depth, tilt, local field, islands, roughness, contact fraction) drawn from
    ``rng`` on the flank sides' ``commons``: its two flank fields and their thresholds. ``fraction``: both
    flanks' contact fraction aimed at instead of a draw in ``p.fraction_range`` (the draw is made all the same,
    so that the stream advances alike)."""
    seat = rng.normal(0.0, p.seating_spread)
    g_axial, g_radial = rng.normal(0.0, p.tilt_spread, 2)
    pair, thr = [], []
    for k, common in enumerate(commons):
        n_isl = rng.poisson(p.islands)
        f = FlankField(
            common=common,
            seat=seat,
            tilt=np.array([g_axial if k == 0 else -g_axial, g_radial]),
            variation=SmoothField.draw(rng, p.n_features, p.variation_length_scale),
            variation_amplitude=p.variation,
            island_centre=rng.uniform(-0.5, 0.5, (n_isl, 2)),
            island_radius=rng.uniform(*p.island_radius, n_isl),
            island_depth=rng.uniform(*p.island_depth, n_isl),
            # drawn only where asked, so that the ideal generator's random stream stays as it was
            roughness=SmoothField.draw(rng, p.n_features, p.roughness_length_scale) if p.roughness else None,
            roughness_amplitude=p.roughness,
        )
        target = rng.uniform(*p.fraction_range)
        lo, hi = p.fraction_range
        if fraction is not None:
            target, lo, hi = fraction, min(lo, fraction), max(hi, fraction)
        p_nodes = p.p_ref * _softplus(f(xi, eta))
        thr.append(_threshold(p_nodes, target, lo, hi, p.fraction_window, p.threshold_margin))
        pair.append(f)
    return (pair[0], pair[1]), thr


def redraw_joints(truth: TruePressure, joints, rng: np.random.Generator,
                  fraction: float | None = None) -> TruePressure:
    """The same true pressure with the named joints drawn again: a blade pulled out and re-seated.

    Each named joint's own parts (seating depth, tilt, local field, islands, roughness and contact fraction) are
    drawn again from ``rng`` as :func:`simulate_pressure` draws them; the flank sides' common shapes and every
    other joint stay exactly as they were.

    Parameters
    ----------
    truth : TruePressure
        The pressure before re-seating (:func:`simulate_pressure`).
    joints : iterable of int
        The re-seated joints, 1..``truth.n_joints``.
    rng : numpy.random.Generator
        The re-draw's own stream (give one that the rest of the simulation does not use, so that nothing else
        changes).
    fraction : float, optional
        Both flanks' contact fraction in (0, 1) after re-seating, within a node or ``fraction_window``: a
        re-seat that is sure to change the contact (say 0.2, a narrow strip, for a joint that bore on most of
        its flank). Default: drawn in ``truth.params.fraction_range``, as any joint's.

    Returns
    -------
    TruePressure
    """
    if fraction is not None and not 0.0 < fraction < 1.0:
        raise ValueError(f"fraction must lie in (0, 1), got {fraction!r}")
    named = sorted({truth._index(j, "L")[0] for j in joints})
    commons = tuple(f.common for f in truth.fields[0])
    xi, eta = _normalized(truth.u, truth.v, truth.u, truth.v)
    fields, thresholds = list(truth.fields), np.array(truth.threshold)
    for s in named:
        fields[s], thresholds[s] = _draw_joint(rng, commons, truth.params, xi, eta, fraction)
    out = TruePressure(truth.u, truth.v, tuple(fields), thresholds, truth.params)
    out.patterns()  # as simulate_pressure: fail here if a joint cannot hold 3 non-collinear contacts
    return out
