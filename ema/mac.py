"""Modal assurance criterion and mode pairing.

:func:`mac` (matrix) and :func:`mac_paired` (row by row) are the one MAC implementation of ``ema``; the
stabilization, the selection and the band-by-band merge all call them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from .errors import EMAError
from .frf import DOF
from .modal import ModalModel

__all__ = [
    "mac", "mac_paired", "ScaledRows", "distinct_mac", "automac", "common_dofs", "ModePairing", "pair_by_frequency",
    "pair_modes",
]


def _unit_max(x: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """``x`` divided by its largest magnitude along ``axis`` (zero vectors stay zero), and its squared norms.

    The MAC is scale-free, so this changes nothing in exact arithmetic; it keeps ``|x|**2`` from
    under- or overflowing for shapes of any magnitude (1e-156 or 1e+144 squared is out of float64 range).
    """
    big = np.max(np.abs(x), axis=axis, keepdims=True) if x.size else np.ones_like(x, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        y = np.where(big > 0, x / np.where(big > 0, big, 1.0), 0.0)
    return y, np.sum(np.abs(y) ** 2, axis=axis)


def _ratio(cross: np.ndarray, norm_a: np.ndarray, norm_b: np.ndarray) -> np.ndarray:
    """``|cross|**2 / (norm_a * norm_b)``, 0 where a vector is zero."""
    den = norm_a * norm_b
    return np.where(den > 0, np.abs(cross) ** 2 / np.where(den > 0, den, 1.0), 0.0)


def mac(phi_a: np.ndarray, phi_b: np.ndarray, weight: np.ndarray | None = None) -> np.ndarray:
    """Modal assurance criterion between two sets of shapes (columns), optionally mass-weighted.

    Parameters
    ----------
    phi_a : ndarray, shape (n_dof,) or (n_dof, n_a)
    phi_b : ndarray, shape (n_dof,) or (n_dof, n_b)
    weight : ndarray, shape (n_dof, n_dof), optional
        Symmetric positive definite inner-product matrix W (e.g. the mass at the compared DOFs); identity
        if omitted.

    Returns
    -------
    ndarray, shape (n_a, n_b)
        ``|phi_a^H W phi_b|^2 / ((phi_a^H W phi_a)(phi_b^H W phi_b))``, always 2-D; 0 where a shape is zero.
        Each shape is scaled by its largest magnitude first, so any finite scale gives the same value.

    Raises
    ------
    EMAError
        Shapes that are not (n_dof, n_modes) arrays with the same n_dof, or a weight that is not
        (n_dof, n_dof).
    """
    # Real shapes stay real: the dataset compares thousands of real ROM shape sets.
    dtype = np.complex128 if np.iscomplexobj(phi_a) or np.iscomplexobj(phi_b) else np.float64
    a = np.asarray(phi_a, dtype=dtype)
    b = np.asarray(phi_b, dtype=dtype)
    a = a[:, None] if a.ndim == 1 else a
    b = b[:, None] if b.ndim == 1 else b
    if a.ndim != 2 or b.ndim != 2 or a.shape[0] != b.shape[0]:
        raise EMAError(f"mac: shapes {a.shape} and {b.shape} must be (n_dof, n_modes) with the same n_dof")
    a, na = _unit_max(a, axis=0)
    b, nb = _unit_max(b, axis=0)
    if weight is None:
        return _ratio(a.conj().T @ b, na[:, None], nb[None, :])
    W = np.asarray(weight, dtype=np.float64)
    if W.shape != (a.shape[0], a.shape[0]):
        raise EMAError(f"mac: weight of shape {W.shape} must be ({a.shape[0]}, {a.shape[0]})")
    Wa, Wb = W @ a, W @ b
    na = np.real(np.einsum("ij,ij->j", a.conj(), Wa))
    nb = np.real(np.einsum("ij,ij->j", b.conj(), Wb))
    return _ratio(a.conj().T @ Wb, na[:, None], nb[None, :])


def mac_paired(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """MAC of each row of ``a`` with the same row of ``b`` (the diagonal of ``mac(a.T, b.T)``, without the rest).

    Parameters
    ----------
    a, b : ndarray, shape (n, n_vec)
        Vectors as rows, e.g. pole vectors of a :class:`ema.poles.PoleSet` (mode shapes of a
        :class:`ema.modal.ModalModel` are columns: pass ``shapes.T``).

    Returns
    -------
    ndarray, shape (n,)
        Scale-safe as :func:`mac`; 0 where a vector is zero.

    Raises
    ------
    EMAError
        ``a`` and ``b`` not two 2-D arrays of the same shape.
    """
    a = np.asarray(a, dtype=np.complex128)
    b = np.asarray(b, dtype=np.complex128)
    if a.ndim != 2 or a.shape != b.shape:
        raise EMAError(f"mac_paired: shapes {a.shape} and {b.shape} must be the same (n, n_vec)")
    a, na = _unit_max(a, axis=1)
    b, nb = _unit_max(b, axis=1)
    return _ratio(np.sum(a.conj() * b, axis=1), na, nb)


@dataclass(frozen=True, eq=False)
class ScaledRows:
    """Vectors (rows) scaled once as :func:`mac_paired` scales them, for MACs of many pairs among them.

    The scaling of :func:`mac_paired` is row by row, so scaling every row once and then gathering pairs gives
    its values bit for bit; a pole in many candidate pairs is then no longer scaled again for each (the
    stabilization and the clustering of a large diagram spent most of their time there).

    Attributes
    ----------
    unit : ndarray of complex, shape (n, n_vec)
        Each row divided by its largest magnitude.
    norm2 : ndarray, shape (n,)
        Squared norms of the scaled rows.
    """

    unit: np.ndarray
    norm2: np.ndarray

    @classmethod
    def of(cls, a: np.ndarray) -> ScaledRows:
        a = np.asarray(a, dtype=np.complex128)
        if a.ndim != 2:
            raise EMAError(f"ScaledRows: vectors must be a 2-D (n, n_vec) array, got shape {a.shape}")
        return cls(*_unit_max(a, axis=1))

    def mac(self, i: np.ndarray, other: ScaledRows, j: np.ndarray, *, block_entries: int = 10_000_000) -> np.ndarray:
        """MAC of row ``i[k]`` here with row ``j[k]`` of ``other``, shape (n_pairs,) (``mac_paired(a[i], b[j])``).

        Pairs are gathered ``block_entries // n_vec`` at a time, which bounds the memory of the gathered rows.
        """
        i, j = np.asarray(i, dtype=np.intp).ravel(), np.asarray(j, dtype=np.intp).ravel()
        if i.shape != j.shape or self.unit.shape[1] != other.unit.shape[1]:
            raise EMAError(f"ScaledRows.mac: {i.size} and {j.size} row indices into vectors of "
                           f"{self.unit.shape[1]} and {other.unit.shape[1]} entries; expected equal counts")
        out = np.empty(i.size)
        step = max(1, block_entries // max(1, self.unit.shape[1]))
        for s in range(0, i.size, step):
            ii, jj = i[s : s + step], j[s : s + step]
            out[s : s + step] = _ratio(np.sum(self.unit[ii].conj() * other.unit[jj], axis=1), self.norm2[ii],
                                       other.norm2[jj])
        return out


def distinct_mac(mac_min: float) -> float:
    """MAC below which two vectors cannot belong to one mode, given the linking threshold ``mac_min``.

    A vector matches a mode when the angle between them, ``arccos(sqrt(MAC))``, is within
    ``theta = arccos(sqrt(mac_min))``; two vectors of one mode are then within ``2 theta`` of each other,
    so a pair farther apart than that cannot be one mode: ``cos(2 theta)**2`` (0.81 for ``mac_min`` 0.95),
    0 when ``2 theta`` reaches a right angle.
    """
    theta = np.arccos(np.sqrt(np.clip(mac_min, 0.0, 1.0)))
    return float(np.cos(min(2.0 * theta, np.pi / 2)) ** 2)


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
    EMAError
        No DOF in common.
    """
    def canon(dofs: tuple[DOF, ...]) -> dict[DOF, tuple[int, float]]:
        return {(n, abs(d)): (k, -1.0 if d < 0 else 1.0) for k, (n, d) in enumerate(dofs)}

    ca, cb = canon(a.dofs), canon(b.dofs)
    keys = [k for k in ca if k in cb]
    if not keys:
        raise EMAError(f"no common DOF between models with {len(a.dofs)} and {len(b.dofs)} DOFs")
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


def pair_by_frequency(fa, fb, freq_window: float = 0.05, *, unpaired_cost: bool = False
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Pair two frequency lists one-to-one (Hungarian on the relative distance) inside a window.

    For modes that shapes cannot tell apart (few measured DOFs), or lists without shapes.

    Parameters
    ----------
    fa, fb : array_like, shape (n_a,), (n_b,)
        Frequencies (Hz).
    freq_window : float
        A pair is admissible when ``|f_b - f_a| <= freq_window * f_a``.
    unpaired_cost : bool
        False (default): as many pairs as possible, then the smallest total distance. True: a mode of ``fa`` left
        unpaired costs ``freq_window``, as much as the furthest admissible pair, so no pair is made at the price
        of pushing others further off (the disk–one-blade pairing among the model's untracked modes,
        ``bladetwin.stages.bias.match_to_reference``).

    Returns
    -------
    rows, cols : ndarray of int
        Indices into ``fa`` and ``fb`` of the admissible pairs, by ascending ``rows``.
    """
    if not freq_window > 0:
        raise EMAError(f"freq_window {freq_window}: expected > 0")
    fa, fb = np.asarray(fa, float), np.asarray(fb, float)
    if fa.size == 0 or fb.size == 0:
        return np.zeros(0, int), np.zeros(0, int)
    rel = np.abs(fb[None, :] / fa[:, None] - 1)
    cost = np.where(rel <= freq_window, rel, 1e6)
    if unpaired_cost:  # one "left unpaired" column per mode of fa
        cost = np.hstack([cost, np.where(np.eye(fa.size, dtype=bool), freq_window, 1e6)])
    rows, cols = linear_sum_assignment(cost)
    keep = cols < fb.size
    rows, cols = rows[keep], cols[keep]
    ok = rel[rows, cols] <= freq_window
    return rows[ok], cols[ok]


def pair_modes(a: ModalModel, b: ModalModel, freq_window: float = 0.1, mac_min: float = 0.5) -> ModePairing:
    """Pair the modes of two models: Hungarian assignment on ``1 - MAC`` inside a frequency window.

    The one test-analysis pairing of the package (measured against identified or computed modes): shapes
    may be complex, DOF labels are matched (a ``-d`` direction flips the sign), and modes left without a
    partner are reported.

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

    Raises
    ------
    EMAError
        ``freq_window`` not positive, or no DOF in common.
    """
    if not freq_window > 0:
        raise EMAError(f"freq_window {freq_window}: expected > 0")
    pa, pb, _ = common_dofs(a, b)
    M = mac(pa, pb)
    fa, fb = a.frequencies_hz, b.frequencies_hz
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
