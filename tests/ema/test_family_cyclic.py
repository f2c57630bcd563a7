"""Dense families of a many-bladed disk (issue 49): the family fit against the exact modes of a lumped cyclic model.

The data are not made by the fit's own model. A lumped bladed disk (N blades, each a mass on a spring to its
disk sector; sectors on a ring of springs, grounded) with mistuned blade springs and a dashpot per blade of
scattered rate (non-proportional damping: complex modes) is solved directly, (K + jωC − ω²M) x = f, at every
line, read at every blade; the rig's noise is added. Its 24 blade-family modes lie within 0.84 %, a median
0.033 % apart (half of the spacings within 0.03–0.07 %, the closest 0.008 %), with half-power bandwidths about
five times their spacing. The exact modes come from the quadratic eigenproblem of the same matrices.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from threadpoolctl import threadpool_limits

from ema import FRFSet, fit
from lab.judge import AssemblyTruth, assembly_scores, shape_mac_bound

from .synth import rig_noise

N_BLADES = 24
F_BLADE = 500.0  # Hz, a blade alone on a rigid sector
REFERENCES = (1, 5, 9, 13, 17, 21)  # blades hammered, as the rig's six references


def _matrices(seed: int = 4):
    """M, K, C (SI) of the lumped disk: DOFs [blade 1..N, sector 1..N]."""
    rng = np.random.default_rng(seed)
    n = N_BLADES
    kb = (2 * np.pi * F_BLADE) ** 2 * (1 + 0.003 * rng.standard_normal(n))  # 0.3 % stiffness mistuning
    m_d, k_ring, k_ground = 4.0, 3.0e8, 6.0e8  # a stiff disk: a blade family within 1 %
    M = np.diag(np.r_[np.ones(n), np.full(n, m_d)])
    K = np.zeros((2 * n, 2 * n))
    C = np.zeros((2 * n, 2 * n))
    zeta = rng.uniform(0.0006, 0.0012, n)  # each blade's own damping ratio, scattered
    for j in range(n):
        b, d, e = j, n + j, n + (j + 1) % n
        for (p, q), k, c in (((b, d), kb[j], 2 * zeta[j] * np.sqrt(kb[j])), ((d, e), k_ring, 0.0)):
            K[np.ix_([p, q], [p, q])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
            C[np.ix_([p, q], [p, q])] += c * np.array([[1.0, -1.0], [-1.0, 1.0]])
        K[d, d] += k_ground
    return M, K, C


def _exact_family(M, K, C):
    """The blade family's exact modes: natural frequencies (Hz), damping ratios, real mass-normalised shapes (2N, n)."""
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-sla.solve(M, K), -sla.solve(M, C)]])
    s, V = np.linalg.eig(A)
    keep = (s.imag > 0) & (np.abs(s) / (2 * np.pi) < 1.2 * F_BLADE)
    s, V = s[keep], V[:n, keep]
    order = np.argsort(np.abs(s))
    s, V = s[order], V[:, order]
    # each complex shape turned to its largest entry's phase: nearly real under light damping
    k = np.argmax(np.abs(V), axis=0)
    V = (V * np.exp(-1j * np.angle(V[k, np.arange(V.shape[1])]))).real
    V = V / np.sqrt(np.einsum("ir,ij,jr->r", V, M, V))  # mass-normalised, as the noise bound reads them
    return np.abs(s) / (2 * np.pi), -s.real / np.abs(s), V


def _frfs(M, K, C, seed: int = 9) -> FRFSet:
    freq = np.arange(480.0, 525.0, 0.1)
    refs = [r - 1 for r in REFERENCES]
    H = np.empty((N_BLADES, len(refs), freq.size), complex)
    for i, f in enumerate(freq):
        w = 2 * np.pi * f
        x = sla.solve(K + 1j * w * C - w**2 * M, np.eye(M.shape[0])[:, refs])
        H[:, :, i] = 1j * w * x[:N_BLADES]  # mobility at every blade (the family's motion is the blades')
    H = rig_noise(H, np.random.default_rng(seed))
    outputs = [(k + 1, 3) for k in range(N_BLADES)]
    return FRFSet(freq, H, outputs, [outputs[r] for r in refs], form="mobility")


@pytest.fixture(scope="module")
def case():
    M, K, C = _matrices()
    f, zeta, shapes = _exact_family(M, K, C)
    frf = _frfs(M, K, C)
    truth = AssemblyTruth(frequencies_hz=f, all_frequencies_hz=f, shapes=shapes[:N_BLADES],
                          blade_energy=np.ones(f.size), outputs=tuple(frf.outputs), damping_ratio=zeta)
    # one BLAS thread, whatever the worker count, so that the figures do not follow the rounding: before the growth
    # took its candidates per output (design §8.60) they did (two threads: 23 modes, ± 2σ 0.74, MAC 0.84; one: 25,
    # 0.88, 0.95); now both give 24 modes, ± 2σ 1.00, MAC 0.97
    with threadpool_limits(1):
        return frf, truth, fit(frf, families=True)


def test_the_synthetic_family_is_as_dense_as_a_bladed_disk(case):
    """The case is what it claims: N modes within 1 %, a median 0.02–0.05 % apart, overlapping."""
    _, truth, _ = case
    f = truth.frequencies_hz
    gaps = np.diff(f) / f[:-1]
    assert f.size == N_BLADES
    assert f[-1] / f[0] - 1 < 0.01
    assert 2e-4 < np.median(gaps) < 5e-4
    assert np.median(2 * truth.damping_ratio[1:] / gaps) > 3  # half-power bandwidths over the spacings


@pytest.fixture(scope="module")
def scores(case):
    frf, truth, res = case
    return assembly_scores(res.model, truth), float(np.mean(shape_mac_bound(truth, frf)))


def test_families_find_every_mode(scores):
    """Issue 49's coverage against the exact modes: ≥ 95 % one-to-one within 0.05 %, none beyond 1 %."""
    s, _ = scores
    assert s["one_to_one_within_0p05pct"] >= 0.95, s
    assert s["n_more_than_1pct_off"] == 0, s


def test_family_shapes_reach_the_noise_ceiling(scores):
    """Issue 49's shapes: the mean MAC within 0.05 of what the noise allows (lab.judge.shape_mac_bound)."""
    s, ceiling = scores
    assert s["mean_shape_mac"] >= ceiling - 0.05, (s, ceiling)


def test_family_standard_deviations_cover_the_truth(scores):
    """Issue 49's calibration: ≥ 85 % of the found modes within ± 2σ of their truth."""
    s, _ = scores
    assert s["within_2sd"] >= 0.85, s
