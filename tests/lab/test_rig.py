"""Virtual hammer tests: the modal FRF synthesis against a direct frequency-domain solve."""

import numpy as np
import pytest
import scipy.linalg as sla

from lab.rig import RigSetup, dof_label, measure, peak_snr, synthesize_mobility
from rom.fe_assembly import AssemblyModes


def _free_chain(n: int = 8):
    """A free–free spring–mass chain (one rigid-body mode), masses 1..2 kg, springs 1e6..3e6 N/m."""
    rng = np.random.default_rng(4)
    m = rng.uniform(1.0, 2.0, n)
    k = rng.uniform(1e6, 3e6, n - 1)
    K = np.zeros((n, n))
    for i, ki in enumerate(k):
        K[i : i + 2, i : i + 2] += ki * np.array([[1, -1], [-1, 1]])
    return K, np.diag(m)


def test_modal_synthesis_matches_a_direct_solve_with_classical_damping():
    K, M = _free_chain()
    lam, Phi = sla.eigh(K, M)
    rigid, elastic = Phi[:, :1], Phi[:, 1:]
    wn = np.sqrt(lam[1:])
    zeta = np.linspace(0.001, 0.01, wn.size)
    # Classical damping with exactly these modal ratios: C = M Φ diag(2 ζ ω) Φᵀ M.
    C = M @ elastic @ np.diag(2 * zeta * wn) @ elastic.T @ M
    labels = [("blade", 1, p + 1, 1) for p in range(K.shape[0])]
    modes = AssemblyModes(wn / (2 * np.pi), elastic, labels, rigid_shapes=rigid)
    freq = np.linspace(5.0, 1.2 * wn.max() / (2 * np.pi), 400)
    H = synthesize_mobility(modes, zeta, freq, outputs=range(K.shape[0]), inputs=[0, 3])
    for f_idx in (0, 137, 399):
        w = 2 * np.pi * freq[f_idx]
        direct = 1j * w * np.linalg.inv(K - w**2 * M + 1j * w * C)
        np.testing.assert_allclose(H[:, :, f_idx], direct[:, [0, 3]], rtol=1e-8, atol=1e-14)


def test_measure_labels_units_noise_and_snr():
    K, M = _free_chain()
    lam, Phi = sla.eigh(K, M)
    wn = np.sqrt(lam[1:])
    labels = [("disk", p + 1, 1, 3) for p in range(K.shape[0])]
    modes = AssemblyModes(wn / (2 * np.pi), Phi[:, 1:], labels, rigid_shapes=Phi[:, :1])
    zeta = np.full(wn.size, 0.002)
    setup = RigSetup((10.0, 1.1 * wn.max() / (2 * np.pi)), 0.5, multiplicative_noise=0.01, additive_noise=0.0)
    a = measure(modes, zeta, setup, np.random.default_rng(1), inputs=[0])
    b = measure(modes, zeta, setup, np.random.default_rng(1), inputs=[0])
    np.testing.assert_array_equal(a.H, b.H)  # the same rng gives the same test
    clean = synthesize_mobility(modes, zeta, setup.frequencies(), range(K.shape[0]), [0])
    rel = np.abs(a.H / clean - 1)
    assert 0.005 < np.sqrt(np.mean(rel**2)) < 0.02  # 1 % multiplicative noise
    assert a.form == "mobility" and a.units == "m/s/N" and a.inputs == ((1, 3),) and a.outputs[2] == (3, 3)
    assert dof_label(("blade", 7, 2, 1)) == (7002, 1)
    snr = peak_snr(modes, zeta, RigSetup(setup.band_hz, 0.5), range(K.shape[0]), [0])
    assert snr.shape == wn.shape and np.all(snr > 0)


def test_bad_band_is_refused():
    with pytest.raises(ValueError, match="test band"):
        RigSetup((100.0, 50.0), 0.5).frequencies()
