"""Mode shapes from residues, against a known modal model (issue 9: shapes of the full-assembly test).

Two situations of a multi-reference bladed-disk test that the shape estimate must survive:

- a mode with a node at the first reference (a disk mode whose nodal line runs through that hammer point,
  or a mistuned mode localised far from it): every reference must contribute to its shape, and the modal
  mass scaling must still hold;
- a weak mode that some response points barely see, in a band where the estimator missed a mode of a
  strong cluster far away: the shape must come from the mode's own neighbourhood, not from the misfit of
  the whole band;
- FRFs beside a hammer's impact point whose noise (a mass line far above the resonances) is not shared by the
  same outputs under the other references: each residue counts by its own FRF's noise.

The truth is built here (``tests/ema/synth.modal_frfs``), independently of ema's synthesis.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from ema import FRFSet, mac
from ema.lsfd import local_residues, local_windows, lsfd, modal_model, shapes_from_residues, weighted_rank_one
from ema.modal import pole_from_modal

from .synth import modal_frfs, rig_noise


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


def test_a_weak_mode_beside_a_strong_family_outside_its_window():
    # a strong family at 300-302 Hz (all found), large at the first eight points; a weak mode at 289.5 Hz,
    # seen mainly at the last four points, whose local window ends 5 Hz short of the family (a disk mode beside
    # a blade family, as seed 11's 1139 Hz pair beside the 1190 Hz family)
    rng = np.random.default_rng(7)
    fn = np.array([289.5, 300.0, 300.9, 301.7, 302.4])
    zeta = np.array([0.001, 0.002, 0.0015, 0.002, 0.0012])
    phi = np.zeros((12, fn.size))
    phi[:8, 1:] = np.sign(rng.standard_normal((8, 4))) * rng.uniform(5.0, 15.0, (8, 4))
    phi[8:, 1:] = 0.1 * rng.standard_normal((4, 4))
    phi[8:, 0] = rng.uniform(0.5, 1.0, 4)
    phi[:8, 0] = 0.02 * rng.standard_normal(8)
    freq = np.arange(1, 2401) * 0.25
    refs = [0, 1, 8]
    H = rig_noise(modal_frfs(freq, fn, zeta, phi, phi[refs], "mobility"), rng)
    outputs = [(k + 1, 3) for k in range(12)]
    frf = FRFSet(freq, H, outputs, [outputs[k] for k in refs], form="mobility")
    poles = pole_from_modal(fn, zeta)
    model = modal_model(frf, poles, (200.0, 400.0))
    window, near = local_windows(poles, frf, model.band_hz)[0]
    assert list(near) == [0]  # the family is outside the weak mode's window
    mac_model = mac(model.shapes[:, [0]], phi[:, [0]])[0, 0]
    # the raw window alone: two residual terms for the family's tail at the strong points
    A_raw = lsfd(frf, poles[:1], window)[0]
    mac_raw = mac(np.linalg.svd(A_raw[0])[0][:, [0]], phi[:, [0]])[0, 0]
    assert mac_model > 0.99, (mac_model, mac_raw)
    assert mac_raw < mac_model, (mac_raw, mac_model)


def _disk_mode_beside_a_struck_blade(seed: int) -> tuple[FRFSet, np.ndarray, np.ndarray, np.ndarray]:
    """A disk mode seen alike at 18 points, three modes around it, four references; near reference 0's impact
    point three outputs carry a mass line 30 times the largest resonance, with the rig's noise on it: the noise is
    not rank one (the 48-blade campaign's 322.7 Hz, design §8.93)."""
    rng = np.random.default_rng(seed)
    fn, zeta = np.array([250.0, 322.7, 400.0, 455.0]), np.array([0.003, 0.0035, 0.002, 0.004])
    n_out = 18
    phi = rng.standard_normal((n_out, fn.size))
    phi[:, 1] = 0.15 * (1 + 0.05 * rng.standard_normal(n_out))
    refs = [0, 5, 10, 15]
    freq = np.arange(400, 2201) * 0.25
    H = modal_frfs(freq, fn, zeta, phi, phi[refs], "mobility")
    H[[1, 2, 3], 0] += 30 * np.max(np.abs(H)) * (2 * np.pi * 322.7) / (2j * np.pi * freq)
    outputs = [(k + 1, 3) for k in range(n_out)]
    return FRFSet(freq, rig_noise(H, rng), outputs, [outputs[k] for k in refs], form="mobility"), fn, zeta, phi


@pytest.mark.parametrize("seed", [0, 1])
def test_a_mode_keeps_its_shape_beside_the_noise_of_a_struck_blade(seed):
    frf, fn, zeta, phi = _disk_mode_beside_a_struck_blade(seed)
    poles = pole_from_modal(fn, zeta)
    model = modal_model(frf, poles)
    weighted = mac(model.shapes[:, [1]], phi[:, [1]])[0, 0]
    # the same residues, rank one without the weights: the struck FRFs' residues take the shape
    A = local_residues(frf, poles, model.band_hz, model.residues)
    plain = mac(shapes_from_residues(A, poles, frf)[0][:, [1]], phi[:, [1]])[0, 0]
    assert weighted > 0.99, (weighted, plain)
    assert plain < weighted - 0.1, (weighted, plain)
    # the other modes, which stand well above that noise everywhere, keep their shapes
    assert np.diag(mac(model.shapes, phi)).min() > 0.98


def test_the_weighted_rank_one_is_the_singular_vector_under_equal_weights_and_the_weighted_minimum_otherwise():
    rng = np.random.default_rng(2)
    m, n = 12, 5
    psi, lv = rng.standard_normal(m) + 1j * rng.standard_normal(m), rng.standard_normal(n) + 1j * rng.standard_normal(n)
    B = np.outer(psi, lv) + 0.3 * (rng.standard_normal((m, n)) + 1j * rng.standard_normal((m, n)))
    u = weighted_rank_one(B, np.ones((m, n)))
    svd = np.linalg.svd(B)[0][:, 0]
    assert abs(np.vdot(svd, u)) == pytest.approx(1.0, abs=1e-9)
    # weights that are not rank one: the cost at the answer against scipy's least squares over both factors,
    # started from the truth (the cost with the best l for a given ψ, so only ψ's direction is compared)
    w = np.exp(rng.uniform(-3.0, 3.0, (m, n)))

    def cost(p: np.ndarray) -> float:
        best_l = ((w * B).T @ np.conj(p)) / (w.T @ np.abs(p) ** 2)
        return float(np.sum(w * np.abs(B - np.outer(p, best_l)) ** 2))

    def residual(x: np.ndarray) -> np.ndarray:
        p, q = x[:m] + 1j * x[m:2 * m], x[2 * m:2 * m + n] + 1j * x[2 * m + n:]
        r = np.sqrt(w) * (B - np.outer(p, q))
        return np.r_[r.real.ravel(), r.imag.ravel()]

    ref = least_squares(residual, np.r_[psi.real, psi.imag, lv.real, lv.imag], xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    got = weighted_rank_one(B, w)
    assert cost(got) <= cost(ref[:m] + 1j * ref[m:2 * m]) * (1 + 1e-8)
    assert cost(got) < cost(svd) * 0.99         # the weights change the answer
