"""Where the blade component sits in each disk slot: a rigid placement per slot.

The blade is modelled once, in its own frame. Slot ``s`` receives it by

    x_global = R_axis(θ_s) · (R_0 · x_blade + t_0),

a base placement ``(R_0, t_0)`` that puts the blade into the slot at angle 0, followed by a rotation by
``θ_s`` about ``axis`` (through the origin: the disk's axis of rotation). DOFs rotate with
``R_s = R_axis(θ_s) · R_0`` (:meth:`BladePlacement.rotation`), which is what
:meth:`rom.academic.BladedDisk.slot_rotation` means: physical DOFs of the placed blade are ``R_s`` times its
local DOFs. The academic twin is ``axis = (0, 0, −1)``, ``θ_s = 2π (s − 1) / N``, ``R_0 = I``, ``t_0 = 0``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .errors import ModelImportError

__all__ = ["BladePlacement", "axis_rotation"]


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Right-handed rotation by ``angle`` (rad) about the unit vector ``axis`` (Rodrigues), shape (3, 3)."""
    k = np.asarray(axis, dtype=np.float64)
    c, s = math.cos(angle), math.sin(angle)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return c * np.eye(3) + s * kx + (1.0 - c) * np.outer(k, k)


@dataclass(frozen=True, eq=False)
class BladePlacement:
    """Rigid placement of the blade in each of ``n_slots`` slots.

    Parameters
    ----------
    axis : array_like, shape (3,)
        Rotation axis of the disk (through the origin); normalised.
    angles : array_like, shape (n_slots,)
        Angle θ_s of slot s = 1..n_slots about ``axis`` (rad, right-handed).
    rotation0 : array_like, shape (3, 3), optional
        Base rotation R_0 from the blade frame to the slot at angle 0 (default: identity). Must be proper
        orthogonal.
    origin0 : array_like, shape (3,), optional
        Base translation t_0 (m, default: zero).
    """

    axis: np.ndarray
    angles: np.ndarray
    rotation0: np.ndarray = field(default_factory=lambda: np.eye(3))
    origin0: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        axis = np.asarray(self.axis, dtype=np.float64).reshape(-1)
        if axis.shape != (3,) or not np.isfinite(axis).all() or np.linalg.norm(axis) == 0:
            raise ModelImportError(f"placement axis must be a non-zero 3-vector, got {self.axis!r}")
        angles = np.asarray(self.angles, dtype=np.float64).reshape(-1)
        if angles.size < 1 or not np.isfinite(angles).all():
            raise ModelImportError(f"placement angles must be finite, one per slot, got {self.angles!r}")
        R0 = np.asarray(self.rotation0, dtype=np.float64)
        if R0.shape != (3, 3) or not np.allclose(R0 @ R0.T, np.eye(3), atol=1e-9) or np.linalg.det(R0) < 0:
            raise ModelImportError("placement rotation0 must be a proper rotation matrix (orthonormal, det +1)")
        t0 = np.asarray(self.origin0, dtype=np.float64).reshape(-1)
        if t0.shape != (3,) or not np.isfinite(t0).all():
            raise ModelImportError(f"placement origin0 must be a finite 3-vector, got {self.origin0!r}")
        object.__setattr__(self, "axis", axis / np.linalg.norm(axis))
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "rotation0", R0)
        object.__setattr__(self, "origin0", t0)

    @classmethod
    def uniform(cls, n_slots: int, axis: Sequence[float] = (0.0, 0.0, 1.0), **kw) -> BladePlacement:
        """Slots evenly spaced: θ_s = 2π (s − 1) / n_slots."""
        if not (isinstance(n_slots, (int, np.integer)) and n_slots >= 1):
            raise ModelImportError(f"n_slots must be a positive integer, got {n_slots!r}")
        return cls(np.asarray(axis, dtype=np.float64), 2 * np.pi * np.arange(n_slots) / n_slots, **kw)

    @property
    def n_slots(self) -> int:
        return int(self.angles.size)

    def _slot(self, slot: int) -> int:
        if isinstance(slot, bool) or not isinstance(slot, (int, np.integer)) or not 1 <= slot <= self.n_slots:
            raise ModelImportError(f"slot must be an integer in 1..{self.n_slots}, got {slot!r}")
        return int(slot)

    def rotation(self, slot: int) -> np.ndarray:
        """R_s (3×3): physical DOFs of the blade placed in ``slot`` are R_s times its local DOFs."""
        return axis_rotation(self.axis, float(self.angles[self._slot(slot) - 1])) @ self.rotation0

    def place(self, X: np.ndarray, slot: int) -> np.ndarray:
        """Blade-frame points ``X`` (…, 3) placed in ``slot`` (global frame)."""
        Ra = axis_rotation(self.axis, float(self.angles[self._slot(slot) - 1]))
        return (np.asarray(X) @ self.rotation0.T + self.origin0) @ Ra.T

    def to_blade_frame(self, X: np.ndarray, slot: int) -> np.ndarray:
        """Global points ``X`` (…, 3) in the frame of the blade placed in ``slot`` (the inverse of :meth:`place`)."""
        Ra = axis_rotation(self.axis, float(self.angles[self._slot(slot) - 1]))
        return (np.asarray(X) @ Ra - self.origin0) @ self.rotation0
