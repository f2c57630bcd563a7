"""Modal assurance criterion and mode pairing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from .frf import DOF
from .modal import ModalModel

__all__ = ["mac", "automac", "common_dofs", "ModePairing", "pair_modes"]


def mac(phi_a: np.ndarray, phi_b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between two sets of shapes.

    Parameters
    ----------
    phi_a : ndarray, shape (n_dof,) or (n_dof, n_a)
    phi_b : ndarray, shape (n_dof,) or (n_dof, n_b)

    Returns
    -------
    ndarray, shape (n_a, n_b)
        ``|phi_a^H phi_b|^2 / ((phi_a^H phi_a)(phi_b^H phi_b))``, always 2-D; 0 where a shape is zero.
    """
    a = np.asarray(phi_a, dtype=np.complex128)
    b = np.asarray(phi_b, dtype=np.complex128)
    a = a[:, None] if a.ndim == 1 else a
    b = b[:, None] if b.ndim == 1 else b
    if a.ndim != 2 or b.ndim != 2 or a.shape[0] != b.shape[0]:
        raise ValueError(f"mac: shapes {a.shape} and {b.shape} must be (n_dof, n_modes) with the same n_dof")
    num = np.abs(a.conj().T @ b) ** 2
    den = np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)


def automac(phi: np.ndarray) -> np.ndarray:
    """MAC of a set of shapes with itself, shape (n_modes, n_modes)."""
    return mac(phi, phi)


def common_dofs(a: ModalModel, b: ModalModel) -> tuple[np.ndarray, np.ndarray, tuple[DOF, ...]]:
    """Shapes of two models restricted to their common DOFs.

    A label ``(node, -d)`` is the same DOF as ``(node, d)`` with the sign flipped.

    Returns
    -------
    phi_a : ndarray, shape (n_common, a.n_modes)
    phi_b : ndarray, shape (n_common, b.n_modes)
    dofs : tuple of (int, int)
        Common DOFs, positive directions, in the order of ``a``.

    Raises
    ------
    ValueError
        No DOF in common.
    """
    def canon(dofs: tuple[DOF, ...]) -> dict[DOF, tuple[int, float]]:
        return {(n, abs(d)): (k, -1.0 if d < 0 else 1.0) for k, (n, d) in enumerate(dofs)}

    ca, cb = canon(a.dofs), canon(b.dofs)
    keys = [k for k in ca if k in cb]
    if not keys:
        raise ValueError(f"no common DOF between models with {len(a.dofs)} and {len(b.dofs)} DOFs")
    ia = np.array([ca[k][0] for k in keys])
    sa = np.array([ca[k][1] for k in keys])
    ib = np.array([cb[k][0] for k in keys])
    sb = np.array([cb[k][1] for k in keys])
    return a.shapes[ia] * sa[:, None], b.shapes[ib] * sb[:, None], tuple(keys)


@dataclass(frozen=True)
class ModePairing:
    """Pairs of modes between model A and model B.

    Attributes
    ----------
    pairs : ndarray of int, shape (n_pairs, 2)
        ``(index_in_a, index_in_b)``, ascending in A.
    mac : ndarray, shape (n_pairs,)
    freq_error : ndarray, shape (n_pairs,)
        ``(f_b - f_a) / f_a``.
    unpaired_a, unpaired_b : ndarray of int
        Modes without a partner.
    mac_matrix : ndarray, shape (n_a, n_b)
    """

    pairs: np.ndarray
    mac: np.ndarray
    freq_error: np.ndarray
    unpaired_a: np.ndarray
    unpaired_b: np.ndarray
    mac_matrix: np.ndarray


def pair_modes(a: ModalModel, b: ModalModel, freq_window: float = 0.1, mac_min: float = 0.5) -> ModePairing:
    """Pair the modes of two models: Hungarian assignment on ``1 - MAC`` inside a frequency window.

    Parameters
    ----------
    a, b : ModalModel
        Shapes compared on their common DOFs.
    freq_window : float
        A pair is admissible when ``|f_b - f_a| <= freq_window * f_a``.
    mac_min : float
        A pair is admissible when its MAC reaches this.

    Returns
    -------
    ModePairing
        Inadmissible assignments are reported as unpaired.
    """
    if not freq_window > 0:
        raise ValueError(f"freq_window {freq_window}: expected > 0")
    pa, pb, _ = common_dofs(a, b)
    M = mac(pa, pb)
    fa, fb = a.frequency_hz, b.frequency_hz
    ferr = (fb[None, :] - fa[:, None]) / fa[:, None]
    ok = (np.abs(ferr) <= freq_window) & (M >= mac_min)
    big = 1e6
    cost = np.where(ok, 1.0 - M + 1e-3 * np.abs(ferr) / freq_window, big)
    rows, cols = linear_sum_assignment(cost) if M.size else (np.zeros(0, int), np.zeros(0, int))
    good = ok[rows, cols]
    rows, cols = rows[good], cols[good]
    srt = np.argsort(rows)
    rows, cols = rows[srt], cols[srt]
    return ModePairing(
        pairs=np.column_stack([rows, cols]).astype(int).reshape(-1, 2),
        mac=M[rows, cols],
        freq_error=ferr[rows, cols],
        unpaired_a=np.setdiff1d(np.arange(fa.size), rows),
        unpaired_b=np.setdiff1d(np.arange(fb.size), cols),
        mac_matrix=M,
    )
