"""Validation metrics of an identification (paper §7, Eqs. 40–42, §8 Table 8).

* δ step: the grid error ε of each blade and mode (Eq. 40), :func:`grid_error`.
* Geometric: contact area fraction (Eq. 41) and centroid (Eq. 42) of each flank, predicted against
  reference patterns, :func:`geometric_validation`.
* Dynamic: modes of two models compared after a MAC pairing (Hungarian assignment inside a frequency
  window, design §5), :func:`compare_modes`. On the full bladed disk its mean absolute frequency error and
  mean MAC are the figures of Table 8 (Cases A, B and C are different inputs to it);
  :func:`d1b_validation` reports the feature modes of each disk–one-blade joint (paper Figs. 23, 27).

Modes are accepted as a ``(frequencies_hz, shapes)`` tuple (shapes ``(n_dof, n_modes)``, rows of both models
in the same order), as :class:`rom.fe_assembly.AssemblyModes` (rows matched by ``meas_labels``) or as
:class:`ema.modal.ModalModel` (rows matched by DOF label, sign-aware, :func:`ema.mac.common_dofs`). A ROM
against a measurement (Case B/C) needs the caller to map ROM measurement labels to test DOFs and pass tuples.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from ema.errors import EMAError
from ema.mac import common_dofs, mac
from rom.academic import flank_coordinates

from .errors import IdentifyError

__all__ = [
    "GridError",
    "grid_error",
    "contact_area_fraction",
    "contact_centroid",
    "GeometricValidation",
    "geometric_validation",
    "pair_patterns",
    "ModeComparison",
    "compare_modes",
    "D1BValidation",
    "d1b_validation",
]

#: Default admissible relative frequency distance of a mode pair (design §5: pair inside a window).
DEFAULT_FREQ_WINDOW = 0.1

#: Grids whose centroids are summed at a time (:func:`contact_centroid`).
_CENTROID_BLOCK = 4096


# ---------------------------------------------------------------------------------------------- δ step
@dataclass(frozen=True)
class GridError:
    """Grid error of the δ step (Eq. 40).

    Attributes
    ----------
    epsilon_pct : ndarray of float64, shape (n_blades, n_modes)
        ``(δ_pred − δ_ref) / Δδ × 100 %``.
    step : ndarray of float64, shape (n_modes,)
        Grid step Δδ of each mode (relative units).
    """

    epsilon_pct: np.ndarray
    step: np.ndarray

    @property
    def nearest(self) -> np.ndarray:
        """bool, shape (n_blades, n_modes): ``|ε| ≤ 50 %``, the predicted value is the nearest grid value.

        A 1e-9 relative slack absorbs rounding of values that lie exactly half-way between grid values.
        """
        return np.abs(self.epsilon_pct) <= 50.0 * (1 + 1e-9)


def grid_error(delta_pred, delta_ref, step) -> GridError:
    """Normalised δ error of the first k-NN step (Eq. 40).

    Parameters
    ----------
    delta_pred : array_like, shape (n_blades, n_modes)
        δ row chosen in step 1 for each blade (relative units, 0.01 = 1 %), e.g. ``TwoStepMatch.delta``.
    delta_ref : array_like, shape (n_blades, n_modes)
        Measured (or true) blade deltas, relative units.
    step : float or array_like of shape (n_modes,)
        Grid step Δδ (relative units; the paper's 0.5 % is 0.005).

    Returns
    -------
    GridError

    Raises
    ------
    IdentifyError
        Shapes that differ or are not 2-D, non-finite values, a step that is not positive.
    """
    p = np.asarray(delta_pred, dtype=np.float64)
    r = np.asarray(delta_ref, dtype=np.float64)
    if p.ndim != 2 or p.shape != r.shape:
        raise IdentifyError(f"delta_pred {p.shape} and delta_ref {r.shape}: expected two (n_blades, n_modes) arrays")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(r))):
        raise IdentifyError("delta_pred and delta_ref must be finite")
    s = np.asarray(step, dtype=np.float64)
    s = np.full(p.shape[1], float(s)) if s.ndim == 0 else s
    if s.shape != (p.shape[1],) or not np.all(np.isfinite(s) & (s > 0)):
        raise IdentifyError(f"step {step!r}: expected a positive value or {p.shape[1]} positive values (one per mode)")
    return GridError(epsilon_pct=(p - r) / s * 100.0, step=s)


# ------------------------------------------------------------------------------------------- geometric
def _bool_grids(name: str, a) -> np.ndarray:
    g = np.asarray(a)
    if g.dtype != bool:
        if g.dtype.kind not in "iuf" or not np.isin(g, (0, 1)).all():
            raise IdentifyError(f"{name}: expected a boolean contact grid (or 0/1), got dtype {g.dtype}")
        g = g.astype(bool)
    if g.ndim < 2:
        raise IdentifyError(f"{name} has shape {g.shape}: expected (..., rows, cols)")
    return g


def contact_area_fraction(grid) -> np.ndarray:
    """Contact area fraction ``A_c = N_cont / N_total × 100 %`` of each grid (Eq. 41).

    Parameters
    ----------
    grid : array_like of bool, shape (..., rows, cols)
        One flank per trailing (rows, cols) grid.

    Returns
    -------
    ndarray of float64, shape (...)
        Percent of grid nodes in contact.
    """
    g = _bool_grids("grid", grid)
    return g.sum(axis=(-2, -1)) / (g.shape[-2] * g.shape[-1]) * 100.0


def contact_centroid(grid, u, v) -> np.ndarray:
    """Centroid of the contacting nodes of each grid (Eq. 42).

    Parameters
    ----------
    grid : array_like of bool, shape (..., rows, cols)
    u, v : array_like of float, shape (rows, cols)
        Physical in-plane coordinates of the grid nodes (m), e.g. :func:`rom.academic.flank_coordinates`
        (u axial, v radial).

    Returns
    -------
    ndarray of float64, shape (..., 2)
        ``(ū, v̄)`` in the units of ``u, v``; NaN for a grid without contact (it has no centroid).
    """
    g = _bool_grids("grid", grid)
    u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
    if u.shape != g.shape[-2:] or v.shape != g.shape[-2:]:
        raise IdentifyError(f"coordinates u {u.shape}, v {v.shape}: expected the grid shape {g.shape[-2:]}")
    flat = g.reshape(-1, u.size)
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    sums = np.empty((flat.shape[0], 2))
    # In blocks, as one product each: a posterior's ~1e5 kept grid pairs would need two float copies at once
    for a in range(0, flat.shape[0], _CENTROID_BLOCK):
        sums[a:a + _CENTROID_BLOCK] = flat[a:a + _CENTROID_BLOCK] @ uv
    n = flat.sum(axis=1, dtype=np.float64)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        cen = np.where(n > 0, sums / n, np.nan)
    return cen.reshape(*g.shape[:-2], 2)


@dataclass(frozen=True)
class GeometricValidation:
    """Geometric comparison of predicted and reference contact patterns (paper §7, Eqs. 41–42).

    Flank axis order is ``("L", "R")``.

    Attributes
    ----------
    area_pct_pred, area_pct_ref : ndarray of float64, shape (n_joints, 2)
        Contact area fraction A_c (%), Eq. 41.
    centroid_pred, centroid_ref : ndarray of float64, shape (n_joints, 2, 2)
        Centroid ``(ū, v̄)`` per flank (m, SI as the coordinates), Eq. 42; NaN for a flank without contact.
    """

    area_pct_pred: np.ndarray
    area_pct_ref: np.ndarray
    centroid_pred: np.ndarray
    centroid_ref: np.ndarray

    @property
    def area_error_pct(self) -> np.ndarray:
        """Predicted minus reference A_c, percentage points, shape (n_joints, 2)."""
        return self.area_pct_pred - self.area_pct_ref

    @property
    def centroid_distance(self) -> np.ndarray:
        """Distance between predicted and reference centroids (m), shape (n_joints, 2)."""
        return np.linalg.norm(self.centroid_pred - self.centroid_ref, axis=-1)


def _stack_patterns(name: str, patterns) -> np.ndarray:
    """(n_joints, 2, rows, cols) from such an array or from a sequence of objects with ``.L`` and ``.R``."""
    if isinstance(patterns, Sequence) and len(patterns) and hasattr(patterns[0], "L"):
        patterns = np.array([[p.L, p.R] for p in patterns])
    g = _bool_grids(name, patterns)
    if g.ndim != 4 or g.shape[1] != 2:
        raise IdentifyError(f"{name} has shape {g.shape}: expected (n_joints, 2 flanks L/R, rows, cols)")
    return g


def geometric_validation(predicted, reference, coordinates) -> GeometricValidation:
    """Area fraction and centroid of predicted and reference patterns, joint by joint.

    Parameters
    ----------
    predicted, reference : array_like of bool, shape (n_joints, 2, rows, cols), or sequence of ContactPattern
        Flank axis ``(L, R)``; :func:`pair_patterns` turns predicted pairs into this.
    coordinates : (u, v) or rom.academic.BladedDisk
        Node coordinates (m), arrays of shape (rows, cols), or a bladed disk whose
        :func:`rom.academic.flank_coordinates` gives them. Both flanks share the layout.

    Returns
    -------
    GeometricValidation
    """
    p, r = _stack_patterns("predicted", predicted), _stack_patterns("reference", reference)
    if p.shape != r.shape:
        raise IdentifyError(f"predicted {p.shape} and reference {r.shape} patterns: expected the same shape")
    if hasattr(coordinates, "blade"):
        coordinates = flank_coordinates(coordinates)
    u, v = coordinates
    return GeometricValidation(
        area_pct_pred=contact_area_fraction(p), area_pct_ref=contact_area_fraction(r),
        centroid_pred=contact_centroid(p, u, v), centroid_ref=contact_centroid(r, u, v),
    )


def pair_patterns(dataset, pairs) -> np.ndarray:
    """Contact grids of ``(i_L, i_R)`` pattern pairs of a dataset.

    Parameters
    ----------
    dataset : object
        With ``patterns_L`` (n_L, rows, cols) and ``patterns_R`` (n_R, rows, cols) boolean arrays.
    pairs : array_like of int, shape (n_joints, 2)
        E.g. :meth:`identify.knn.TwoStepKNN.predict` on a dataset-fitted estimator.

    Returns
    -------
    ndarray of bool, shape (n_joints, 2, rows, cols)
    """
    PL, PR = np.asarray(dataset.patterns_L, dtype=bool), np.asarray(dataset.patterns_R, dtype=bool)
    q = np.asarray(pairs)
    if q.ndim != 2 or q.shape[1] != 2 or q.dtype.kind not in "iu":
        raise IdentifyError(f"pairs has shape {q.shape} and dtype {q.dtype}: expected (n_joints, 2) integers")
    for j, (name, n) in enumerate((("patterns_L", PL.shape[0]), ("patterns_R", PR.shape[0]))):
        bad = (q[:, j] < 0) | (q[:, j] >= n)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise IdentifyError(f"pairs row {i}: index {q[i, j]} outside dataset.{name} (0..{n - 1})")
    return np.stack([PL[q[:, 0]], PR[q[:, 1]]], axis=1)


# --------------------------------------------------------------------------------------------- dynamic
def _modes(name: str, m) -> tuple[np.ndarray, np.ndarray, object]:
    """(frequencies (n,), shapes (n_dof, n), labels or None) of the accepted mode containers."""
    if isinstance(m, tuple) and len(m) == 2:
        f, phi, labels = m[0], m[1], None
    elif hasattr(m, "meas_shapes"):
        f, phi, labels = m.frequencies_hz, m.meas_shapes, [tuple(lab) for lab in m.meas_labels]
    elif hasattr(m, "dofs"):
        f, phi, labels = m.frequencies_hz, m.shapes, "dofs"
    else:
        raise IdentifyError(f"{name}: expected (frequencies_hz, shapes), rom AssemblyModes or ema ModalModel, "
                            f"got {type(m).__name__}")
    f = np.asarray(f, dtype=np.float64).reshape(-1)
    phi = np.asarray(phi)
    phi = phi[:, None] if phi.ndim == 1 else phi
    if phi.ndim != 2 or phi.shape[1] != f.size:
        raise IdentifyError(f"{name}: shapes {phi.shape} do not hold one column per frequency ({f.size})")
    if not (np.all(np.isfinite(f)) and np.all(f > 0)):
        raise IdentifyError(f"{name}: frequencies must be finite and > 0 Hz, got {f}")
    return f, phi, labels


def _common_rows(ref, pred, a, b) -> tuple[np.ndarray, np.ndarray]:
    (_, pa, la), (_, pb, lb) = a, b
    if la == "dofs" and lb == "dofs":
        try:
            pa, pb, _ = common_dofs(ref, pred)
        except EMAError as e:
            raise IdentifyError(f"reference and predicted modes: {e}") from e
        return pa, pb
    if isinstance(la, list) and isinstance(lb, list):
        where = {lab: k for k, lab in enumerate(lb)}
        keep = [(k, where[lab]) for k, lab in enumerate(la) if lab in where]
        if not keep:
            raise IdentifyError("reference and predicted modes have no measurement label in common")
        ia, ib = np.array(keep).T
        return pa[ia], pb[ib]
    if la is not None or lb is not None:
        raise IdentifyError("reference and predicted modes: pass both with labels (same kind) or both as tuples")
    if pa.shape[0] != pb.shape[0]:
        raise IdentifyError(f"reference shapes have {pa.shape[0]} rows, predicted {pb.shape[0]}: expected the same")
    return pa, pb


@dataclass(frozen=True)
class ModeComparison:
    """Reference and predicted modes, paired.

    Attributes
    ----------
    pairs : ndarray of int, shape (n_pairs, 2)
        ``(index_in_reference, index_in_predicted)``, ascending in the reference.
    freq_ref_hz, freq_pred_hz : ndarray of float64, shape (n_pairs,)
    freq_error_pct : ndarray of float64, shape (n_pairs,)
        ``(f_pred − f_ref) / f_ref × 100 %``.
    mac : ndarray of float64, shape (n_pairs,)
        MAC of each pair (the diagonal of the paired MAC matrix, paper Figs. 24, 28).
    mac_matrix : ndarray of float64, shape (n_ref, n_pred)
    unpaired_ref, unpaired_pred : ndarray of int
        Modes left without an admissible partner (outside the frequency window).
    """

    pairs: np.ndarray
    freq_ref_hz: np.ndarray
    freq_pred_hz: np.ndarray
    freq_error_pct: np.ndarray
    mac: np.ndarray
    mac_matrix: np.ndarray
    unpaired_ref: np.ndarray
    unpaired_pred: np.ndarray

    @property
    def mean_abs_freq_error_pct(self) -> float:
        """Mean of ``|freq_error_pct|`` over the pairs (paper Table 8, first row); NaN without pairs."""
        return float(np.mean(np.abs(self.freq_error_pct))) if self.pairs.size else float("nan")

    @property
    def mean_mac(self) -> float:
        """Mean MAC over the pairs (paper Table 8, second row); NaN without pairs."""
        return float(np.mean(self.mac)) if self.pairs.size else float("nan")


def compare_modes(reference, predicted, *, pairing: str = "mac", freq_window: float | None = DEFAULT_FREQ_WINDOW,
                  mac_min: float = 0.0) -> ModeComparison:
    """Pair predicted modes with reference modes and compare frequencies and shapes.

    Used for the full bladed disk (paper Figs. 24, 28 and Table 8: Case A = ROM with predicted patterns
    against ROM with true patterns, B = predicted against measured, C = true against measured).

    Parameters
    ----------
    reference, predicted : (frequencies_hz, shapes), rom AssemblyModes or ema ModalModel
        Frequencies (Hz) of shape (n_modes,), shapes (n_dof, n_modes), real or complex.
    pairing : {"mac", "index"}
        ``"mac"``: one-to-one assignment maximising the summed MAC (Hungarian,
        :func:`scipy.optimize.linear_sum_assignment` on ``1 − MAC``; a 1e-6 frequency term breaks ties of
        degenerate pairs). Every reference mode gets a partner when one is admissible, however low its MAC,
        so the mean MAC is not flattered by dropping poor matches. ``"index"``: mode i with mode i.
    freq_window : float or None
        With ``"mac"``, a pair is admissible only when ``|f_pred − f_ref| ≤ freq_window · f_ref``; None
        admits every pair.
    mac_min : float
        With ``"mac"``, a pair is admissible only when its MAC reaches this (default 0: any). Against a
        measurement, whose shapes in dense families can be poorly identified, a small threshold (0.3) keeps
        a mode without a credible partner unpaired instead of forcing it onto a distant one; the number of
        pairs then says how many measured modes were compared.

    Returns
    -------
    ModeComparison

    Raises
    ------
    IdentifyError
        Unknown ``pairing``, a window that is not positive, modes that do not share DOFs.
    """
    if pairing not in ("mac", "index"):
        raise IdentifyError(f"pairing={pairing!r}: expected 'mac' or 'index'")
    if freq_window is not None and not freq_window > 0:
        raise IdentifyError(f"freq_window={freq_window!r}: expected > 0 or None")
    if not 0 <= mac_min < 1:
        raise IdentifyError(f"mac_min={mac_min!r}: expected 0 <= mac_min < 1")
    a, b = _modes("reference", reference), _modes("predicted", predicted)
    pa, pb = _common_rows(reference, predicted, a, b)
    fa, fb = a[0], b[0]
    M = mac(pa, pb)
    ferr = (fb[None, :] - fa[:, None]) / fa[:, None]
    if pairing == "index":
        rows = cols = np.arange(min(fa.size, fb.size))
    else:
        ok = np.ones(M.shape, bool) if freq_window is None else np.abs(ferr) <= freq_window
        ok &= M >= mac_min
        cost = np.where(ok, 1.0 - M + 1e-6 * np.abs(ferr), 1e6)
        rows, cols = linear_sum_assignment(cost)
        good = ok[rows, cols]
        rows, cols = rows[good], cols[good]
    return ModeComparison(
        pairs=np.column_stack([rows, cols]).astype(int).reshape(-1, 2),
        freq_ref_hz=fa[rows], freq_pred_hz=fb[cols], freq_error_pct=ferr[rows, cols] * 100.0,
        mac=M[rows, cols], mac_matrix=M,
        unpaired_ref=np.setdiff1d(np.arange(fa.size), rows), unpaired_pred=np.setdiff1d(np.arange(fb.size), cols),
    )


@dataclass(frozen=True)
class D1BValidation:
    """Disk–one-blade feature modes, predicted against reference, joint by joint (paper Figs. 23, 27).

    Attributes
    ----------
    feature_modes : tuple of int
        0-based reference mode indices compared.
    freq_ref_hz : ndarray of float64, shape (n_joints, n_features)
    freq_pred_hz : ndarray of float64, shape (n_joints, n_features)
        Frequency of the paired predicted mode; NaN (as the error and MAC) where the reference mode found no
        admissible partner.
    freq_error_pct : ndarray of float64, shape (n_joints, n_features)
        ``(f_pred − f_ref) / f_ref × 100 %``.
    mac : ndarray of float64, shape (n_joints, n_features)
    """

    feature_modes: tuple[int, ...]
    freq_ref_hz: np.ndarray
    freq_pred_hz: np.ndarray
    freq_error_pct: np.ndarray
    mac: np.ndarray


def d1b_validation(reference: Sequence, predicted: Sequence, feature_modes, *, pairing: str = "mac",
                   freq_window: float | None = DEFAULT_FREQ_WINDOW) -> D1BValidation:
    """Compare the feature modes of each joint's disk–one-blade model, predicted against reference.

    Each joint's modes are paired as a whole by :func:`compare_modes` (a contact change can swap close
    modes), then the rows of the reference feature modes are reported.

    Parameters
    ----------
    reference, predicted : sequence of modes, length n_joints
        Each as accepted by :func:`compare_modes` (e.g. :func:`rom.rom_assembly.solve_d1b` results).
    feature_modes : sequence of int
        0-based indices into each reference's modes (e.g. ``dataset.feature_modes``).

    Returns
    -------
    D1BValidation
    """
    if len(reference) != len(predicted):
        raise IdentifyError(f"{len(reference)} reference and {len(predicted)} predicted joints: expected as many")
    fm = tuple(int(k) for k in np.asarray(feature_modes, dtype=int).reshape(-1))
    out = np.full((4, len(reference), len(fm)), np.nan)
    for j, (r, p) in enumerate(zip(reference, predicted, strict=True)):
        c = compare_modes(r, p, pairing=pairing, freq_window=freq_window)
        f_ref = _modes("reference", r)[0]
        n_ref = f_ref.size
        for col, k in enumerate(fm):
            if not 0 <= k < n_ref:
                raise IdentifyError(f"feature mode {k} (0-based) outside joint {j}'s {n_ref} reference modes")
            out[0, j, col] = f_ref[k]
            hit = np.flatnonzero(c.pairs[:, 0] == k)
            if hit.size:
                i = hit[0]
                out[:, j, col] = c.freq_ref_hz[i], c.freq_pred_hz[i], c.freq_error_pct[i], c.mac[i]
    return D1BValidation(fm, *out)
