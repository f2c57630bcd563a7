"""Synthetic truth for the EMA tests, built here independently of ema's own synthesis."""

from __future__ import annotations

from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2].parent / "shared"
PYUFF_DIR = SHARED / "external" / "pyuff"

# >= 8 modes, two pairs 0.5 % apart, damping 0.1-2 %
FN = np.array([100.0, 200.0, 201.0, 350.0, 480.0, 600.0, 603.0, 780.0, 900.0])
ZETA = np.array([0.01, 0.002, 0.003, 0.005, 0.02, 0.001, 0.0015, 0.008, 0.004])
FORM_POWER = {"receptance": 0, "mobility": 1, "accelerance": 2}


def modal_frfs(freq, fn, zeta, phi_out, phi_in, form="receptance"):
    """FRFs of a proportionally damped system with mass-normalised modes, shape (n_o, n_i, n_f)."""
    w = 2 * np.pi * np.asarray(freq)
    wn = 2 * np.pi * np.asarray(fn)
    den = wn[:, None] ** 2 - w[None, :] ** 2 + 2j * np.asarray(zeta)[:, None] * wn[:, None] * w[None, :]
    H = np.einsum("or,ir,rf->oif", phi_out, phi_in, 1.0 / den)
    return H * (1j * w) ** FORM_POWER[form]


def synthetic_case(form="receptance", n_o=12, n_i=1, noise=0.01, seed=0):
    """Truth and noisy FRFs on 0.25 Hz lines up to 1 kHz (0 Hz dropped), 1 % proportional complex noise."""
    rng = np.random.default_rng(seed)
    phi = rng.standard_normal((n_o, FN.size))
    # references (the first n_i outputs) excite every mode
    phi[:n_i] = np.sign(phi[:n_i]) * rng.uniform(0.7, 1.3, (n_i, FN.size))
    freq = np.linspace(0.0, 1000.0, 4001)[1:]
    H = modal_frfs(freq, FN, ZETA, phi, phi[:n_i], form)
    H = H + noise * np.abs(H) * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    return freq, H, phi


def rig_noise(H, rng):
    """``H`` with the virtual rig's noise: 0.5 % proportional and 0.2 % of each FRF's RMS additive, complex
    Gaussian (as lab.rig.measure, written out here)."""
    rms = np.sqrt(np.mean(np.abs(H) ** 2, axis=2, keepdims=True))

    def noise():
        return (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)

    return H * (1 + 0.005 * noise()) + 0.002 * rms * noise()
