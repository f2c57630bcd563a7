"""The family's modes under per-blade changes (rom.forced.perturbation), against direct eigen-solves.

Reference: a lumped bladed disk, one disk mass and one blade mass per sector, the disk masses coupled round the
ring and grounded, each blade on its own root spring (the "joint"). The changed assembly is solved directly;
the perturbation sees only the unchanged assembly's modes and, for each changed blade, two direct solves of its
disk–one-blade model (the whole disk ring with that one blade): the change of its blade-mode eigenvalue, and
the mode's value at the blade. Nothing is made by the perturbation's own model.
"""

import math

import numpy as np
import pytest
import scipy.linalg as sla

from rom.errors import ROMError
from rom.forced import BladeModes, amplification_factor, family_band, forced_response, sample_model
from rom.forced.perturbation import perturbed_family

N, M_DISK, M_BLADE = 12, 4.0, 1.0
K_ROOT = (2 * math.pi * 200.0) ** 2  # N/m: a 1 kg blade on its root spring alone is at 200 Hz
K_DISK, K_RING = 10.0 * K_ROOT, 1.0 * K_ROOT  # disk ground and ring springs: a family spread over 3.5 %


def bladed_disk(k_root: np.ndarray, slots=None):
    """K, M over [disk masses (N) | blade masses of ``slots``], and the blade DOFs' indices."""
    slots = list(range(N)) if slots is None else list(slots)
    n = N + len(slots)
    K, M = np.zeros((n, n)), np.diag([M_DISK] * N + [M_BLADE] * len(slots))
    for j in range(N):
        K[j, j] += K_DISK + 2 * K_RING
        K[j, (j + 1) % N] -= K_RING
        K[(j + 1) % N, j] -= K_RING
    for b, s in enumerate(slots):
        k = k_root[s]
        K[s, s] += k
        K[N + b, N + b] += k
        K[s, N + b] -= k
        K[N + b, s] -= k
    return K, M


def blade_rows(K, M, zeta=0.004):
    lam, Phi = sla.eigh(K, M)
    return BladeModes(np.sqrt(lam) / (2 * math.pi), zeta, Phi[N:2 * N]), lam, Phi


def d1b_blade_mode(k_root, slot):
    """(eigenvalue, value at the blade) of the disk–one-blade model's blade-dominated mode."""
    K, M = bladed_disk(k_root, [slot])
    lam, Phi = sla.eigh(K, M)
    r = int(np.argmax(Phi[N] ** 2 * M_BLADE))  # the mode with the most energy in the blade
    return lam[r], Phi[N, r]


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(3)
    k_a = K_ROOT * (1 + 0.01 * rng.standard_normal(N))  # the solved assembly: 1 % root scatter
    changed = [1, 4, 5, 9]
    k_b = k_a.copy()
    k_b[changed] *= 1 + np.array([-0.02, 0.015, -0.01, 0.02])  # the sample: four joints changed by 1–2 %
    model_a, _, _ = blade_rows(*bladed_disk(k_a))
    model_b, _, _ = blade_rows(*bladed_disk(k_b))
    dl = np.zeros(N)
    psi = []
    for s in changed:
        la, pa = d1b_blade_mode(k_a, s)
        lb, _ = d1b_blade_mode(k_b, s)
        dl[s] = lb - la
        psi.append(abs(pa))
    # the d1b blade mode's value at the blade barely depends on the slot: one value for all, as the run uses
    tuned, _, _ = blade_rows(*bladed_disk(np.full(N, K_ROOT)))
    return model_a, model_b, tuned, dl, float(np.mean(psi))


def test_perturbed_frequencies_match_the_direct_solve(case):
    model_a, model_b, tuned, dl, psi = case
    band = family_band(tuned, 1)
    f, _ = perturbed_family(model_a, band, dl[None], psi)
    fa = model_a.frequencies_hz[(model_a.frequencies_hz >= band[0]) & (model_a.frequencies_hz <= band[1])]
    fb = model_b.frequencies_hz[(model_b.frequencies_hz >= band[0]) & (model_b.frequencies_hz <= band[1])]
    shift = np.max(np.abs(fb - fa))
    err = np.max(np.abs(f[0] - fb))
    assert shift > 0.5  # Hz: the change is large against the damping's half-power bandwidth (1.6 Hz at 200 Hz)
    assert err < 0.05 * shift, (err, shift)


def test_perturbed_af_matches_the_direct_solve_at_every_eo(case):
    model_a, model_b, tuned, dl, psi = case
    band = family_band(tuned, 1)
    f, phi = perturbed_family(model_a, band, dl[None], psi)
    pert = sample_model(model_a, band, f[0], phi[0])
    moved = []
    for eo in range(N // 2 + 1):
        ref = forced_response(tuned, eo, band)
        a = amplification_factor(model_a, tuned, eo, band, tuned_response=ref).af
        b = amplification_factor(model_b, tuned, eo, band, tuned_response=ref).af
        p = amplification_factor(pert, tuned, eo, band, tuned_response=ref).af
        moved.append(abs(b - a))
        # the perturbation recovers at least 90 % of the AF's change, and is within 2 % of the direct AF
        assert abs(p - b) <= max(0.1 * abs(b - a), 0.02 * b), (eo, a, b, p)
    assert max(moved) > 0.05  # the change moves some AF by more than 5 %: the check has something to see


def test_no_change_leaves_the_modes(case):
    model_a, _, tuned, _, psi = case
    band = family_band(tuned, 1)
    f, phi = perturbed_family(model_a, band, np.zeros((2, N)), psi)
    idx = (model_a.frequencies_hz >= band[0]) & (model_a.frequencies_hz <= band[1])
    np.testing.assert_allclose(f[1], model_a.frequencies_hz[idx], rtol=1e-12)
    # the same modes up to sign: each column of Φ v is ± a column of Φ
    np.testing.assert_allclose(np.abs(phi[1].T @ model_a.shapes[:, idx]) > 0.5, np.eye(idx.sum(), dtype=bool))


@pytest.mark.parametrize(("dl", "psi", "message"), [
    (np.zeros((1, N - 1)), 0.5, "delta_lambda has shape"),
    (np.full((1, N), np.nan), 0.5, "expected finite"),
    (np.zeros((1, N)), 0.0, "psi_point"),
    (np.full((1, N), -1e12), 0.5, "non-positive eigenvalue"),
])
def test_bad_input_is_refused_in_one_line(case, dl, psi, message):
    model_a, _, tuned, _, _ = case
    with pytest.raises(ROMError, match=message):
        perturbed_family(model_a, family_band(tuned, 1), dl, psi)
