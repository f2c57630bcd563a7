"""Contact patterns of a blade-root joint (paper §2.3.2, Eq. 20).

A pattern is two boolean grids, one per root flank (``"L"``, ``"R"``), of the model's grid shape
(7×31 by default; rows run axially, columns radially outward, see :mod:`rom.academic`). ``True`` marks a
contacting node pair (tied), ``False`` a detached one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ContactPattern", "slot_flank_nodes"]

FLANKS = ("L", "R")


def slot_flank_nodes(disk, slot: int) -> np.ndarray:
    """The disk's flank-grid node indices of one slot, the L grid then the R grid, row-major, shape (2·n_grid,).

    ``disk`` is a :class:`rom.component.Component` with the node sets ``slot{s}_L`` and ``slot{s}_R``.
    """
    return np.concatenate([disk.node_set(f"slot{slot}_{f}").ravel() for f in FLANKS])


def _as_bool_grid(name: str, grid) -> np.ndarray:
    a = np.asarray(grid)
    if a.ndim != 2:
        raise ValueError(f"contact grid {name} must be 2-D (rows, columns), got shape {a.shape}")
    if a.dtype != bool:
        if a.dtype.kind not in "iuf":
            raise ValueError(f"contact grid {name} must be boolean (or 0/1), got dtype {a.dtype}")
        bad = ~np.isin(a, (0, 1))
        if bad.any():
            i, j = np.argwhere(bad)[0]
            raise ValueError(f"contact grid {name} must be boolean (only 0/1), got {a[i, j].item()!r} at row {i + 1}, "
                             f"column {j + 1} ({int(bad.sum())} such value(s))")
        a = a.astype(bool)
    return a.copy()


@dataclass(frozen=True, eq=False)
class ContactPattern:
    """Contact state of one joint.

    Parameters
    ----------
    L, R : array_like of bool, shape (n_rows, n_cols)
        Contact grids of the left (local x = −w/2) and right (x = +w/2) flank.

    Raises
    ------
    ValueError
        If a grid is not 2-D boolean, the shapes differ, or the joint has fewer than 3 contacting nodes
        on a line or fewer (the blade would float free or hinge).
    """

    L: np.ndarray
    R: np.ndarray

    def __post_init__(self) -> None:
        L, R = _as_bool_grid("L", self.L), _as_bool_grid("R", self.R)
        if L.shape != R.shape:
            raise ValueError(f"contact grids L and R must have the same shape, got {L.shape} and {R.shape}")
        if not (L.any() or R.any()):
            raise ValueError("contact pattern has no contact on either flank: the blade would float free")
        # Rigid attachment needs three non-collinear contact points (grid position + flank side).
        pts = np.vstack([np.c_[np.full(L.sum(), -1.0), np.argwhere(L)], np.c_[np.full(R.sum(), 1.0), np.argwhere(R)]])
        if np.linalg.matrix_rank(pts[1:] - pts[0]) < 2:
            raise ValueError(
                "contact pattern needs ≥ 3 non-collinear contacting nodes, otherwise the blade hinges on the disk"
            )
        L.flags.writeable = False
        R.flags.writeable = False
        object.__setattr__(self, "L", L)
        object.__setattr__(self, "R", R)

    @property
    def shape(self) -> tuple[int, int]:
        return self.L.shape

    def flank(self, name: str) -> np.ndarray:
        if name not in FLANKS:
            raise ValueError(f"flank must be 'L' or 'R', got {name!r}")
        return self.L if name == "L" else self.R

    @property
    def contact_fraction(self) -> float:
        """Fraction of grid nodes in contact over both flanks."""
        return float((self.L.sum() + self.R.sum()) / (2 * self.L.size))

    def check_shape(self, grid: tuple[int, int]) -> None:
        if self.shape != tuple(grid):
            raise ValueError(f"contact pattern has grid shape {self.shape}, the model expects {tuple(grid)}")

    @classmethod
    def full(cls, grid: tuple[int, int]) -> ContactPattern:
        """All nodes of both flanks in contact (bonded joint)."""
        return cls(np.ones(grid, bool), np.ones(grid, bool))

    @classmethod
    def random(cls, grid: tuple[int, int], fraction: float, rng: np.random.Generator) -> ContactPattern:
        """Random pattern with about ``fraction`` of nodes in contact (for tests and demos)."""
        if not 0.0 < fraction <= 1.0:
            raise ValueError(f"fraction must lie in (0, 1], got {fraction}")
        while True:
            L, R = rng.random(grid) < fraction, rng.random(grid) < fraction
            try:
                return cls(L, R)
            except ValueError:
                continue

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ContactPattern) and np.array_equal(self.L, other.L) and np.array_equal(self.R, other.R)

    __hash__ = None  # type: ignore[assignment]
