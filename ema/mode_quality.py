"""Mode-shape complexity indicators: MPC, MPD and MCF of complex mode shapes.

A lightly, proportionally damped structure has normal modes: every component of a shape moves in phase or in
antiphase, so the shape, plotted in the complex plane, lies on one line through the origin. Noise, close modes
sharing a pole, or a computational pole scatter the components off that line. These three numbers measure the
scatter; they are what users of PolyMAX-style tools, sdynpy's PolyPy and pyOMA2 read beside the stabilization
diagram to judge whether a mode is physical.

All three work on the second moments of the real and imaginary parts ``x = Re(phi)``, ``y = Im(phi)`` of one
shape over its measured DOFs::

    Sxx = x.x,  Syy = y.y,  Sxy = x.y,   S = [[Sxx, Sxy], [Sxy, Syy]]   (not centred)

with eigenvalues ``l1 >= l2 >= 0`` of ``S``. Every indicator is invariant to multiplying the shape by any
non-zero complex scalar (its scaling and its phase reference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ModeQuality", "mode_quality", "mpc", "mpd", "mcf"]


@dataclass(frozen=True)
class ModeQuality:
    """MPC, MPD and MCF of each mode (see :func:`mode_quality`).

    Attributes
    ----------
    mpc : ndarray, shape (n_modes,)
        Modal phase collinearity in [0, 1]; 1 for a real (normal) mode.
    mpd_deg : ndarray, shape (n_modes,)
        Mean phase deviation in degrees, in [0, 90]; 0 for a real mode.
    mcf : ndarray, shape (n_modes,)
        Mode complexity factor in [0, 1]; 0 for a real mode, 1 for a circular one.

    NaN for a mode whose shape is all zero or not finite.
    """

    mpc: np.ndarray
    mpd_deg: np.ndarray
    mcf: np.ndarray

    def columns(self) -> dict[str, np.ndarray]:
        """``{"mpc": ..., "mpd_deg": ..., "mcf": ...}``, e.g. to add to a DataFrame of the modes."""
        return {"mpc": self.mpc, "mpd_deg": self.mpd_deg, "mcf": self.mcf}


def _unit_columns(shapes: np.ndarray) -> np.ndarray:
    """Shapes as (n_dof, n_modes) complex, each column divided by its largest magnitude.

    Why: the indicators are ratios of squared components, and shapes of |phi| ~ 1e-160 (receptance residues in
    m/N) or 1e+160 under- or overflow when squared; dividing by a real positive number changes no phase.
    An all-zero column is left as NaN.
    """
    phi = np.asarray(shapes, dtype=np.complex128)
    if phi.ndim == 1:
        phi = phi[:, None]
    if phi.ndim != 2:
        raise ValueError(f"mode shapes must be (n_dof, n_modes), got an array of shape {phi.shape}")
    peak = np.max(np.abs(phi), axis=0, initial=0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return phi / np.where(peak > 0, peak, np.nan)


def _moments(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Sxx, Syy, Sxy``, each shape (n_modes,), of unit-scaled shapes ``phi`` (n_dof, n_modes)."""
    x, y = phi.real, phi.imag
    return np.sum(x * x, axis=0), np.sum(y * y, axis=0), np.sum(x * y, axis=0)


def mpc(shapes: np.ndarray) -> np.ndarray:
    """Modal phase collinearity (Pappa, Elliott & Schenk 1993).

    ``MPC = ((l1 - l2) / (l1 + l2))**2 = ((Sxx - Syy)**2 + 4 Sxy**2) / (Sxx + Syy)**2 = |phi^T phi|**2 /
    (phi^H phi)**2``, with ``l1, l2`` the eigenvalues of the (uncentred) moment matrix ``S`` of the module
    docstring: 1 when the components lie on one line through the origin (a real mode times any complex
    scalar), 0 when the shape has no preferred direction (``l1 = l2``, e.g. a travelling wave).

    The moments are taken about the origin, as in pyOMA2 and in Reynders, Houbrechts & De Roeck (2012). Some
    codes centre ``x`` and ``y`` on their means first (a covariance instead of moments); that version measures
    collinearity about any line, not one through the origin, so that any two-DOF shape scores 1.

    Parameters
    ----------
    shapes : array_like of complex, shape (n_dof, n_modes) or (n_dof,)

    Returns
    -------
    ndarray, shape (n_modes,)

    References
    ----------
    Pappa R.S., Elliott K.B., Schenk A. (1993), Consistent-mode indicator for the eigensystem realization
    algorithm, J. Guidance, Control, and Dynamics 16(5), 852–858.
    Reynders E., Houbrechts J., De Roeck G. (2012), Fully automated (operational) modal analysis, Mechanical
    Systems and Signal Processing 29, 228–250.
    """
    phi = _unit_columns(shapes)
    # |phi^T phi|^2 / (phi^H phi)^2: the same number as the eigenvalue form, without the eigenvalues.
    with np.errstate(invalid="ignore", divide="ignore"):
        value = np.abs(np.sum(phi * phi, axis=0)) ** 2 / np.sum(np.abs(phi) ** 2, axis=0) ** 2
    return np.clip(value, 0.0, 1.0)


def mcf(shapes: np.ndarray) -> np.ndarray:
    """Mode complexity factor.

    ``MCF = 1 - ((Sxx - Syy)**2 + 4 Sxy**2) / (Sxx + Syy)**2 = 4 (Sxx Syy - Sxy**2) / (Sxx + Syy)**2
    = 4 l1 l2 / (l1 + l2)**2 = 1 - MAC(phi, conj(phi))``: 0 for a real mode, 1 for a circular one (``l1 = l2``).
    The form ``1 - MAC(phi, conj(phi))`` is the one of Vacher, Jacquier & Bucharles (2010). With the
    origin-anchored MPC of :func:`mpc` it equals ``1 - MPC`` exactly (it differs from a centred MPC); it is
    reported by name because users ask for the three indicators by name. It is computed from the determinant
    form, which keeps its accuracy for nearly real modes.

    Parameters
    ----------
    shapes : array_like of complex, shape (n_dof, n_modes) or (n_dof,)

    Returns
    -------
    ndarray, shape (n_modes,)

    References
    ----------
    Vacher P., Jacquier B., Bucharles A. (2010), Extensions of the MAC criterion to complex modes, Proc. ISMA
    2010, Leuven.
    """
    sxx, syy, sxy = _moments(_unit_columns(shapes))
    with np.errstate(invalid="ignore", divide="ignore"):
        value = 4.0 * (sxx * syy - sxy * sxy) / (sxx + syy) ** 2
    return np.clip(value, 0.0, 1.0)


def mpd(shapes: np.ndarray) -> np.ndarray:
    """Mean phase deviation in degrees.

    ``MPD = sum_j |phi_j| d_j / sum_j |phi_j|``, where ``d_j`` in [0°, 90°] is the angle between the
    component ``phi_j`` (a vector in the complex plane) and the best-fit line through the origin, and the line
    is the total-least-squares one: the principal axis of ``S`` (the first right singular vector of
    ``[x, y]``), at the angle ``t0 = atan2(2 Sxy, Sxx - Syy) / 2``. So ``d_j = atan2(|Im(phi_j e^{-i t0})|,
    |Re(phi_j e^{-i t0})|)``: the phase of each component from the line, folded modulo 180° (antiphase is
    in phase). 0 for a real mode. A circular mode (``l1 = l2``) has no principal axis, and its MPD depends on the
    line ``atan2`` happens to give: near 45°, and exactly 45° on any line when its equal components, evenly spread
    in phase, number a multiple of 4 (they pair up at right angles). Up to 90° when many small components stand
    off the line of a few large ones.

    This is the MPD of Reynders, Houbrechts & De Roeck (2012) and pyOMA2. The angle is taken with ``atan2``,
    not ``arccos``, so that a real mode gives 0 to rounding (``arccos`` near 1 loses half the digits).

    Parameters
    ----------
    shapes : array_like of complex, shape (n_dof, n_modes) or (n_dof,)

    Returns
    -------
    ndarray, shape (n_modes,)
        Degrees.

    References
    ----------
    Reynders E., Houbrechts J., De Roeck G. (2012), Fully automated (operational) modal analysis, Mechanical
    Systems and Signal Processing 29, 228–250.
    """
    phi = _unit_columns(shapes)
    sxx, syy, sxy = _moments(phi)
    t0 = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    r = phi * np.exp(-1j * t0)[None, :]
    dev = np.arctan2(np.abs(r.imag), np.abs(r.real))
    w = np.abs(phi)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.degrees(np.sum(w * dev, axis=0) / np.sum(w, axis=0))


def mode_quality(shapes: np.ndarray) -> ModeQuality:
    """MPC, MPD (degrees) and MCF of each mode shape (:func:`mpc`, :func:`mpd`, :func:`mcf`).

    Parameters
    ----------
    shapes : array_like of complex, shape (n_dof, n_modes) or (n_dof,)
        Mode shapes as columns (e.g. ``ModalModel.shapes``); any scaling and phase reference.

    Returns
    -------
    ModeQuality
        Arrays of shape (n_modes,).
    """
    return ModeQuality(mpc=mpc(shapes), mpd_deg=mpd(shapes), mcf=mcf(shapes))
