"""A family's modes under small per-blade changes, without a new assembly solve (the intervals of issue 47).

A posterior sample changes the contact of the unfilmed joints, and so each blade's disk–one-blade frequency of
the family's blade mode by a relative r_j. A full-assembly solve per sample would take minutes for 200 samples;
instead the family's modes of one solved assembly (the run's answer) are corrected in their own span, as the
subset-of-nominal-modes method does from the tuned modes (M.-T. Yang & J. H. Griffin, "A reduced-order model of
mistuning using a subset of nominal system modes", J. Eng. Gas Turbines Power 123(4), 2001).

**Model.** Near joint j, a mode r of a blade-dominated family moves as q_jr times the disk–one-blade mode ψ of
that family (mass-normalised over the disk–one-blade model, its value at the blade point ψ_p), so φ_jr = q_jr ψ_p
at blade j's point. A stiffness change at joint j that moves the disk–one-blade eigenvalue by Δλ_j = ψᵀ ΔK_j ψ
then adds Σ_j q_jr q_js Δλ_j to the family's stiffness in modal coordinates:

    A = diag(ω_r²) + Φᵀ diag(Δλ_j / ψ_p²) Φ,       Φ: the family's shapes at the blade points, (N, m),

and the perturbed modes are A's eigenpairs (ω'², v) with shapes Φ v (Rayleigh–Ritz in the family's span; the
modes outside the band are kept). With one blade it is exact to first order (A = ω² + Δλ). It assumes each
blade moves in the family's one blade mode: a disk-dominated mode in the band, whose blade motion is no ψ, is
coupled only through its small blade amplitudes. Δλ_j = ω_j² ((1 + r_j)² − 1) from the relative change r_j of
the blade's disk–one-blade frequency.

**Accuracy** (tests/rom/test_forced_perturbation.py: a lumped disk, four root springs changed by 1–2 %, against
direct eigen-solves): with the family spread over 3.5 % in frequency, the perturbed frequencies are off by 1.8 %
of their shift and the AF by at most 0.3 % at every EO; with a 7.5 % spread (stronger disk coupling, the blade
moving less like its disk–one-blade mode), by up to 2.3 %.
"""

from __future__ import annotations

import numpy as np

from ..errors import ROMError
from .model import BladeModes

__all__ = ["family_columns", "perturbed_family", "sample_model"]


def family_columns(model: BladeModes, band_hz) -> np.ndarray:
    """Indices of ``model``'s modes inside ``band_hz`` (Hz, inclusive), shape (m,)."""
    lo, hi = (float(b) for b in band_hz)
    idx = np.flatnonzero((model.frequencies_hz >= lo) & (model.frequencies_hz <= hi))
    if idx.size == 0:
        raise ROMError(f"no mode of the model inside the band {lo:.6g}–{hi:.6g} Hz")
    return idx


def perturbed_family(model: BladeModes, band_hz, delta_lambda, psi_point: float) -> tuple[np.ndarray, np.ndarray]:
    """The family's modes after per-blade eigenvalue changes ``delta_lambda`` (module notes).

    Parameters
    ----------
    model : BladeModes
        The solved assembly's modes at one DOF per blade (real, mass-normalised shapes).
    band_hz : (float, float)
        The family's band: its modes are corrected, the others kept.
    delta_lambda : array_like, shape (n_samples, n_blades)
        Each sample's change of each blade's disk–one-blade eigenvalue ((rad/s)²).
    psi_point : float
        The disk–one-blade mode's mass-normalised value at the same blade DOF (m/√kg), nonzero.

    Returns
    -------
    frequencies_hz : ndarray, shape (n_samples, m)
    shapes : ndarray, shape (n_samples, n_blades, m)
        The perturbed family modes, mass-normalised in the family's span.

    Raises
    ------
    ROMError
        On complex shapes, a ``delta_lambda`` of the wrong shape or non-finite, ``psi_point`` zero, or a change
        so large that an eigenvalue is no longer positive.
    """
    if np.iscomplexobj(model.shapes):
        raise ROMError("the perturbation needs real (normal) mode shapes")
    dl = np.atleast_2d(np.asarray(delta_lambda, np.float64))
    if dl.ndim != 2 or dl.shape[1] != model.n_blades or not np.all(np.isfinite(dl)):
        raise ROMError(f"delta_lambda has shape {dl.shape}, expected finite (n_samples, {model.n_blades})")
    if not (np.isfinite(psi_point) and psi_point != 0):
        raise ROMError(f"psi_point {psi_point} must be finite and nonzero")
    idx = family_columns(model, band_hz)
    phi = model.shapes[:, idx]
    lam = model.omega[idx] ** 2
    A = np.einsum("jr,sj,jt->srt", phi, dl / psi_point**2, phi)
    A[:, np.arange(idx.size), np.arange(idx.size)] += lam
    w, V = np.linalg.eigh(A)
    if np.any(w <= 0):
        raise ROMError("a per-blade change leaves a non-positive eigenvalue: far outside the perturbation's reach")
    return np.sqrt(w) / (2 * np.pi), np.einsum("jr,srt->sjt", phi, V)


def sample_model(model: BladeModes, band_hz, frequencies_hz: np.ndarray, shapes: np.ndarray) -> BladeModes:
    """``model`` with its family's modes (those in ``band_hz``) replaced by one sample of :func:`perturbed_family`
    (``frequencies_hz`` shape (m,), ``shapes`` shape (n_blades, m)); each keeps its damping ratio."""
    idx = family_columns(model, band_hz)
    f = model.frequencies_hz.copy()
    phi = model.shapes.copy()
    f[idx], phi[:, idx] = frequencies_hz, shapes
    return BladeModes(f, model.damping_ratio, phi)
