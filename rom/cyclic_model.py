"""The cyclic all-slot Craig–Bampton disk's reduced matrices, stored by their first block column (Eq. 6).

Built by :func:`rom.cyclic.reduce_disk_cyclic`; solved with the blades by :func:`rom.cyclic.solve_full_cyclic`
(its Rayleigh–Ritz steps in :mod:`rom.cyclic_ritz`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CyclicDiskModel"]


@dataclass(frozen=True, eq=False)
class CyclicDiskModel:
    """Craig–Bampton disk reduced on all N slots of a cyclic disk, stored by its first block column.

    Boundary coordinates of slot s are its contact grid (L then R, row-major, x y z per node) in the slot's
    own frame, as in :func:`rom.craig_bampton.reduce_disk`.

    Attributes
    ----------
    Lambda : ndarray, shape (n_k,)
        Fixed-interface eigenvalues ω² (rad²/s²), every slot clamped.
    kappa_col : ndarray, shape (N, n_i, n_i)
        κ_bb[1 + d, 1]: κ_bb[s, t] = ``kappa_col[(s - t) % N]`` (Eq. 6, block-circulant).
    mu_col : ndarray, shape (N, n_i, n_i)
        μ_bb[1 + d, 1], the same way.
    mu_be : ndarray, shape (N, n_i, n_k)
        μ_be of each slot (Eq. 6).
    out_eta : ndarray, shape (N, n_k)
        Output rows (the disk measurement DOF of each sector) of the fixed-interface modes.
    out_b1 : ndarray, shape (N, n_i)
        Output rows of slot 1's constraint modes; slot s's are these with the sectors rolled by s − 1.
    cc_modes : ndarray, shape (N // 2 + 1, n_i, n_cc), complex
        The lowest CC modes ψ of each harmonic h: (Ĉ_h − ω² D̂_h) ψ = 0, Ĉ_h = Σ_d C_d e^(−2πi h d / N).
    cc_mass : ndarray, shape (N // 2 + 1, n_i, n_cc), complex
        D̂_h ψ (then Ĉ_h ψ = ω² D̂_h ψ).
    cc_omega2 : ndarray, shape (N // 2 + 1, n_cc)
        Their eigenvalues ω² (rad²/s²).
    meta : dict
    """

    Lambda: np.ndarray
    kappa_col: np.ndarray
    mu_col: np.ndarray
    mu_be: np.ndarray
    out_eta: np.ndarray
    out_b1: np.ndarray
    cc_modes: np.ndarray
    cc_mass: np.ndarray
    cc_omega2: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def n_slots(self) -> int:
        return int(self.kappa_col.shape[0])

    @property
    def n_i(self) -> int:
        return int(self.kappa_col.shape[1])

    @property
    def n_k(self) -> int:
        return int(self.Lambda.size)

    def kappa(self, s: int, t: int) -> np.ndarray:
        """κ_bb[s, t] (slots 1-based), shape (n_i, n_i)."""
        return self.kappa_col[(s - t) % self.n_slots]

    def mu(self, s: int, t: int) -> np.ndarray:
        """μ_bb[s, t] (slots 1-based), shape (n_i, n_i)."""
        return self.mu_col[(s - t) % self.n_slots]
