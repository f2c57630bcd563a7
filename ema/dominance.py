"""The dominance of each mode of a modal model: a resonance of the data, or a pole that only patches the fit.

:func:`ema.lsfd.dominance` compares a mode's own term with the measured FRF at its frequency;
:func:`mode_dominance` also separates close modes with distinct shapes, which :func:`ema.fit` filters on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frf import FRF_FORMS, FRFSet
from .lsfd import dominance, synthesize
from .mac import distinct_mac, mac
from .modal import ModalModel

__all__ = ["SEPARATION_SNR", "mode_dominance", "Kept"]

#: How far (amplitude ratio) a mode's own term must stand above the local fit residual for its separated
#: dominance to count (see :func:`mode_dominance`).
SEPARATION_SNR = 10.0


def mode_dominance(frf: FRFSet, model: ModalModel, mac_min: float = 0.95) -> np.ndarray:
    """Dominance of each mode, telling close modes with distinct shapes apart (what ``fit`` filters on).

    The larger of :func:`ema.lsfd.dominance` (own term over the measured FRF at the mode's frequency) and
    a separated dominance: the own term over what the measured FRF leaves once the terms of the modes
    with other shapes are taken off, plus the RMS fit residual around the mode,

    ``d_r = max_f |H_f,r(f_r)| / (|H_f(f_r) - sum_s H_f,s(f_r)| + rms_f(H_f - H_f,model))``,

    the sum over the modes s whose shapes are distinct from mode r's (MAC below
    :func:`ema.mac.distinct_mac` of ``mac_min``), the maximum over the FRFs f where the own term stands
    :data:`SEPARATION_SNR` times (20 dB) above that residual. At a close pair the stronger member's term
    covers the weaker one at every response point, so its plain dominance is low although it is a
    resonance; with the partner's term taken off it is about 1 again. A pole that only fits noise
    absorbs that noise, so its term stands only a few times above the residual left (2-7 in the tests,
    against 50 and more for the weaker member of a close pair at 1 % noise): the 20 dB margin keeps it
    at its plain dominance. The separation is trusted only between
    resolved modes, whose half-power band ``2 zeta f`` spans at least one line: around a peak narrower
    than the line spacing the estimators place extra poles that patch its shape, with vectors that
    differ at few response points, and those must keep their low plain dominance. Modes with no
    resolved, distinct partner get the plain dominance.

    Parameters
    ----------
    frf : FRFSet
    model : ModalModel
        With residues (:func:`ema.lsfd.modal_model`).
    mac_min : float
        MAC threshold of the stability criteria; shapes below ``distinct_mac(mac_min)`` are distinct.

    Returns
    -------
    ndarray, shape (n_modes,)
    """
    plain = dominance(frf, model)
    if model.n_modes < 2:
        return plain
    data = frf.with_form(model.form) if frf.form != model.form else frf
    valid = data.valid_lines()
    lines, H = data.freq_hz[valid], data.H[:, :, valid]
    if lines.size < 2:
        return plain
    spacing = np.interp(model.frequencies_hz, lines, np.gradient(lines))
    half_width = model.damping_ratio * model.frequencies_hz
    resolved = 2.0 * half_width >= spacing
    distinct = (mac(model.shapes, model.shapes) < distinct_mac(mac_min)) & resolved[None, :] & resolved[:, None]
    out = plain.copy()
    for r in np.flatnonzero(distinct.any(axis=1)):
        # residual level from the lines of the half-power band, at least the nearest five
        near = np.flatnonzero(np.abs(lines - model.frequencies_hz[r]) <= max(half_width[r], 2.0 * spacing[r]))
        if near.size == 0:
            continue
        resid = H[:, :, near] - synthesize(model, lines[near]).H
        rms = np.sqrt(np.mean(np.abs(resid) ** 2, axis=2))
        i = near[np.argmin(np.abs(lines[near] - model.frequencies_hz[r]))]
        terms = _mode_terms(model, lines[i])  # (n_modes, n_outputs, n_inputs)
        own = np.abs(terms[r])
        rest = np.abs(H[:, :, i] - terms[distinct[r]].sum(axis=0)) + rms
        sep = np.where(own >= SEPARATION_SNR * rms, own / np.where(rest > 0, rest, np.inf), 0.0)
        out[r] = max(out[r], float(np.max(sep)))
    return out


def _mode_terms(model: ModalModel, freq_hz: float) -> np.ndarray:
    """Each mode's term of the synthesis at one frequency, in the model's form, shape (n_modes, n_o, n_i)."""
    jw = 1j * 2 * np.pi * freq_hz
    lam = model.poles[:, None, None]
    A = model.residues
    return (A / (jw - lam) + A.conj() / (jw - lam.conj())) * jw ** FRF_FORMS[model.form]


@dataclass(frozen=True)
class Kept:
    """A modal model as the dominance filter left it.

    Attributes
    ----------
    model : ModalModel
        With residues.
    dominance : ndarray, shape (n_modes,)
        :func:`mode_dominance` of each mode.
    dropped : list of float
        Frequencies (Hz) of the modes dropped as non-dominant.
    """

    model: ModalModel
    dominance: np.ndarray
    dropped: list[float]
