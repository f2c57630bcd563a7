"""The pieces of a flank's dimensionless pressure field z(ξ, η) (:mod:`lab.patterns`, "Pressure model").

:class:`SmoothField` is a random-Fourier-feature sample of a Gaussian process; :class:`CommonShape` the shape
one flank side shares over every joint; :class:`FlankField` one joint's flank. Each evaluates anywhere, and
separably on a :class:`Lattice` of points (a film's pixels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Lattice", "SmoothField", "CommonShape", "FlankField"]

#: Points per chunk of :meth:`SmoothField.__call__`: bounds its (points × features) temporary.
_CHUNK = 1 << 15


@dataclass(frozen=True)
class Lattice:
    """Points x(r, c) = origin + r · row_step + c · col_step in (ξ, η), for r < shape[0], c < shape[1].

    A film's pixels form such a lattice in flank coordinates (an affine map: scale, shift, small rotation),
    which lets :class:`SmoothField` evaluate separably instead of point by point.
    """

    origin: np.ndarray
    row_step: np.ndarray
    col_step: np.ndarray
    shape: tuple[int, int]

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(ξ, η), each of shape ``shape``."""
        r, c = np.arange(self.shape[0])[:, None], np.arange(self.shape[1])[None, :]
        return tuple(self.origin[k] + r * self.row_step[k] + c * self.col_step[k] for k in (0, 1))

    def shifted(self, d: np.ndarray) -> Lattice:
        return Lattice(self.origin + d, self.row_step, self.col_step, self.shape)


@dataclass(frozen=True, eq=False)
class SmoothField:
    """A smooth random field f(ξ, η) = √(2/m) Σ_k w_k cos(ω_k · (ξ, η) + φ_k), with unit variance.

    It is a random-Fourier-feature sample of a Gaussian process with covariance exp(−|Δ|² / (2 ℓ²)):
    ω_k ~ N(0, ℓ⁻² I), φ_k ~ U(0, 2π), w_k ~ N(0, 1).

    Attributes
    ----------
    omega : ndarray, shape (m, 2)
        Angular wave vectors (rad per flank extent).
    phase : ndarray, shape (m,)
    weight : ndarray, shape (m,)
    """

    omega: np.ndarray
    phase: np.ndarray
    weight: np.ndarray

    @classmethod
    def draw(cls, rng: np.random.Generator, n_features: int, length_scale: float) -> SmoothField:
        return cls(rng.normal(0.0, 1.0 / length_scale, (n_features, 2)), rng.uniform(0.0, 2 * np.pi, n_features),
                   rng.normal(0.0, 1.0, n_features))

    def __call__(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        xi, eta = np.broadcast_arrays(np.asarray(xi, np.float64), np.asarray(eta, np.float64))
        out = np.empty(xi.shape)
        x, y, res = xi.reshape(-1), eta.reshape(-1), out.reshape(-1)
        for a in range(0, x.size, _CHUNK):  # chunks bound the (points × features) temporary
            arg = np.multiply.outer(x[a:a + _CHUNK], self.omega[:, 0])
            arg += np.multiply.outer(y[a:a + _CHUNK], self.omega[:, 1])
            arg += self.phase
            np.cos(arg, out=arg)
            res[a:a + _CHUNK] = arg @ self.weight
        return math.sqrt(2.0 / self.weight.size) * out

    def on_lattice(self, lat: Lattice) -> np.ndarray:
        """The field on a lattice, shape ``lat.shape``: the same values as ``self(*lat.points())``.

        Separable, because cos(a + b) = cos a cos b − sin a sin b: two (rows × m) by (m × cols) products
        instead of a cosine per point and feature.
        """
        r, c = np.arange(lat.shape[0]), np.arange(lat.shape[1])
        a = np.outer(r, self.omega @ lat.row_step) + (self.omega @ lat.origin + self.phase)  # (rows, m)
        b = np.outer(self.omega @ lat.col_step, c)  # (m, cols), C-contiguous: the fast BLAS layout
        out = (np.cos(a) * self.weight) @ np.cos(b) - (np.sin(a) * self.weight) @ np.sin(b)
        return math.sqrt(2.0 / self.weight.size) * out


def _smooth(f: SmoothField, xi: np.ndarray, eta: np.ndarray, lat: Lattice | None) -> np.ndarray:
    """``f`` at (ξ, η); separably when the points are the lattice ``lat``."""
    return f(xi, eta) if lat is None else f.on_lattice(lat)


@dataclass(frozen=True, eq=False)
class CommonShape:
    """The shape shared by one flank side of every joint: a Gaussian bearing core plus a smooth field.

    Attributes
    ----------
    centre : ndarray, shape (2,)
        Core centre (ξ, η).
    width : ndarray, shape (2,)
        Core standard deviations along ξ and η (flank extents).
    amplitude : float
        Core height (z units).
    field : SmoothField
    field_amplitude : float
    """

    centre: np.ndarray
    width: np.ndarray
    amplitude: float
    field: SmoothField
    field_amplitude: float

    def __call__(self, xi: np.ndarray, eta: np.ndarray, lat: Lattice | None = None) -> np.ndarray:
        """Values at (ξ, η); pass ``lat`` when (ξ, η) are ``lat.points()`` (faster, same values)."""
        q = ((xi - self.centre[0]) / self.width[0]) ** 2 + ((eta - self.centre[1]) / self.width[1]) ** 2
        return self.amplitude * np.exp(-0.5 * q) + self.field_amplitude * _smooth(self.field, xi, eta, lat)


@dataclass(frozen=True, eq=False)
class FlankField:
    """The dimensionless field z(ξ, η) of one flank of one joint (see the module docstring).

    Attributes
    ----------
    common : CommonShape
        The flank side's common shape (the same object for every joint).
    seat : float
        Seating depth d: radial offset of the common shape (flank heights).
    tilt : ndarray, shape (2,)
        Misalignment gradient (dz/dξ, dz/dη).
    variation : SmoothField
    variation_amplitude : float
    island_centre : ndarray, shape (k, 2)
    island_radius : ndarray, shape (k,)
    island_depth : ndarray, shape (k,)
    roughness : SmoothField or None
        The flank's roughness (a short-correlation field; None: a smooth flank).
    roughness_amplitude : float
    """

    common: CommonShape
    seat: float
    tilt: np.ndarray
    variation: SmoothField
    variation_amplitude: float
    island_centre: np.ndarray
    island_radius: np.ndarray
    island_depth: np.ndarray
    roughness: SmoothField | None = None
    roughness_amplitude: float = 0.0

    def __call__(self, xi: np.ndarray, eta: np.ndarray, lat: Lattice | None = None) -> np.ndarray:
        """z at (ξ, η); pass ``lat`` when (ξ, η) are ``lat.points()`` (faster, same values)."""
        seated = None if lat is None else lat.shifted(np.array([0.0, -self.seat]))
        z = self.common(xi, eta - self.seat, seated) + self.variation_amplitude * _smooth(self.variation, xi, eta, lat)
        z = z + self.tilt[0] * xi + self.tilt[1] * eta
        if self.roughness is not None:
            z = z + self.roughness_amplitude * _smooth(self.roughness, xi, eta, lat)
        for (cx, cy), r, h in zip(self.island_centre, self.island_radius, self.island_depth, strict=True):
            z = z - h * np.exp(-((xi - cx) ** 2 + (eta - cy) ** 2) / (2 * r * r))
        return z
