"""Mode shapes from residues, against a known modal model (issue 9: shapes of the full-assembly test).

Two situations of a multi-reference bladed-disk test that the shape estimate must survive:

- a mode with a node at the first reference (a disk mode whose nodal line runs through that hammer point,
  or a mistuned mode localised far from it): every reference must contribute to its shape, and the modal
  mass scaling must still hold;
- a weak mode that some response points barely see, in a band where the estimator missed a mode of a
  strong cluster far away: the shape must come from the mode's own neighbourhood, not from the misfit of
  the whole band.

The truth is built here (``tests/ema/synth.modal_frfs``), independently of ema's synthesis.
"""

from __future__ import annotations

import numpy as np

from ema import FRFSet, mac
from ema.lsfd import modal_model
from ema.modal import pole_from_modal

from .synth import modal_frfs


def _noisy(H: np.ndarray, rng: np.random.Generator, rel: float) -> np.ndarray:
    return H + rel * np.abs(H) * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)


def test_a_node_at_the_first_reference_leaves_the_shape_and_its_modal_mass():
    rng = np.random.default_rng(3)
    fn = np.array([120.0, 180.0, 250.0, 330.0])
    zeta = np.array([0.004, 0.003, 0.005, 0.002])
    phi = rng.standard_normal((10, fn.size))
    phi[:3] = np.sign(phi[:3]) * rng.uniform(0.6, 1.2, (3, fn.size))
    phi[0, 1] = 0.0  # mode 2 has a node at the first hammer point
    freq = np.arange(1, 1601) * 0.25
    H = _noisy(modal_frfs(freq, fn, zeta, phi, phi[:3], "mobility"), rng, 0.005)
    outputs = [(k + 1, 3) for k in range(10)]
    frf = FRFSet(freq, H, outputs, outputs[:3], form="mobility")
    model = modal_model(frf, pole_from_modal(fn, zeta))
    assert model.scaling == "mass"
    macs = np.diag(mac(model.shapes, phi))
    assert macs.min() > 0.999, macs
    # unit modal mass: the real part of each estimated shape (phase aligned) matches the truth's magnitude
    for r in range(fn.size):
        est = model.shapes[:, r] * np.exp(-1j * np.angle(model.shapes[np.argmax(np.abs(phi[:, r])), r]))
        assert np.allclose(np.abs(est.real), np.abs(phi[:, r]), atol=0.02 * np.abs(phi[:, r]).max()), r


def test_a_weak_mode_keeps_its_shape_when_a_distant_mode_was_missed():
    rng = np.random.default_rng(5)
    # a strong cluster near 200 Hz (one member missed by the estimator) and a weak mode at 600 Hz that the
    # last four response points barely see
    fn = np.array([200.0, 200.6, 201.3, 600.0])
    zeta = np.array([0.001, 0.0012, 0.0009, 0.002])
    phi = np.sign(rng.standard_normal((12, fn.size))) * rng.uniform(0.5, 1.5, (12, fn.size))
    phi[:, 3] *= 0.05
    phi[8:, 3] *= 0.02
    freq = np.arange(1, 3201) * 0.25
    H = _noisy(modal_frfs(freq, fn, zeta, phi, phi[:2], "mobility"), rng, 0.002)
    outputs = [(k + 1, 3) for k in range(12)]
    frf = FRFSet(freq, H, outputs, outputs[:2], form="mobility")
    found = [0, 2, 3]  # the estimator missed the 200.6 Hz mode
    poles = pole_from_modal(fn[found], zeta[found])
    local = modal_model(frf, poles)
    whole_band = modal_model(frf, poles, local_shapes=False)
    assert np.allclose(local.residues, whole_band.residues)  # the synthesis is the whole-band fit either way
    mac_local = mac(local.shapes[:, [2]], phi[:, [3]])[0, 0]
    mac_whole = mac(whole_band.shapes[:, [2]], phi[:, [3]])[0, 0]
    assert mac_local > 0.99, mac_local
    # why the local fit: the missed mode's misfit spreads over every residue of the whole-band fit
    assert mac_whole < mac_local, (mac_whole, mac_local)
