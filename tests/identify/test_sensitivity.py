"""Sensitivity of the disk–one-blade frequencies to contact (paper §6.2), tracked by MAC.

References: direct dense solves by SciPy's ``eigh`` on the assembled ROM (not rom's Lanczos), a mass-weighted
MAC written out here, ema's MAC on the measurement DOFs, and NumPy statistics.

The mode-order acceptance case: on the coarse model (3×7 grid) the bonded joint (all nodes in contact) has
modes 9 and 10 at 3491 and 3540 Hz; with contact only on a 2×2 corner of each flank the second of them drops
to 3360 Hz, below the first (3479 Hz). The patterns are hard-coded; the swap is found by the direct solves.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import linear_sum_assignment

from ema.mac import mac as ema_mac
from identify.errors import IdentifyError
from identify.sensitivity import reference_pair, sensitivity, summarize
from identify.tracking import model_key
from rom import ContactPattern, assemble_d1b, solve_d1b
from rom.modal import single_thread_blas

from ..rom.rom_models import blade, disk_cb

GRID = (3, 7)
N_MODES = 10


def _corner() -> np.ndarray:
    a = np.zeros(GRID, bool)
    a[:2, :2] = True
    return a


FULL = np.ones(GRID, bool)
CORNER = _corner()


def _direct(L, R, n: int = N_MODES + 4):
    """Lowest n elastic modes (frequencies Hz, M-normalised shapes) and M, by SciPy eigh of the assembled ROM."""
    # One BLAS thread: threaded BLAS on small matrices crawls on a loaded 2-core machine.
    with single_thread_blas():
        asm = assemble_d1b(disk_cb(), blade(), ContactPattern(L, R), delta=0.0)
        lam, X = sla.eigh(asm.K, asm.M, subset_by_index=[0, n + 5])
    keep = lam > (2 * np.pi) ** 2  # drop the 6 rigid-body modes (below 1 Hz)
    return np.sqrt(lam[keep][:n]) / (2 * np.pi), X[:, keep][:, :n], asm.M


def _wmac(A, B, W):
    num = (A.T @ W @ B) ** 2
    return num / np.outer(np.einsum("ij,ij->j", A, W @ A), np.einsum("ij,ij->j", B, W @ B))


@pytest.fixture(scope="module")
def swap_case():
    return sensitivity(disk_cb(), blade(), np.array([FULL, CORNER]), np.array([FULL, CORNER]), reference=(0, 0),
                       progress=False)


def test_contact_swaps_mode_order_and_mac_tracking_keeps_the_mode(swap_case):
    f_ref, X_ref, M_ref = _direct(FULL, FULL)
    f_b, X_b, _ = _direct(CORNER, CORNER)
    m = _wmac(X_ref, X_b, M_ref)
    # Index order swaps modes 9 and 10 (0-based 8, 9): same index, different mode; crossed, the same mode.
    assert m[8, 8] < 0.2 and m[9, 9] < 0.2
    assert m[8, 9] > 0.8 and m[9, 8] > 0.8
    # The measured view agrees: ema's MAC on the 18 disk + 3 blade measurement DOFs.
    pat_a, pat_b = ContactPattern(FULL, FULL), ContactPattern(CORNER, CORNER)
    ma = ema_mac(solve_d1b(disk_cb(), blade(), pat_a, n_modes=12).meas_shapes,
                 solve_d1b(disk_cb(), blade(), pat_b, n_modes=12).meas_shapes)
    assert ma[8, 8] < 0.5 and ma[9, 8] > 0.8
    # Tracking by MAC: reference mode 9 is the pair's 10th mode and vice versa, so the tracked frequencies
    # of that pair are not in ascending order, and equal the direct frequencies crossed.
    s = swap_case
    np.testing.assert_array_equal(s.mode_index[1, 1], [0, 1, 2, 3, 4, 5, 6, 7, 9, 8])
    np.testing.assert_array_equal(s.mode_index[0, 0], np.arange(N_MODES))
    perm = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]
    np.testing.assert_allclose(s.frequencies_hz[1, 1], f_b[perm], rtol=1e-7)
    np.testing.assert_allclose(s.frequencies_hz[0, 0], f_ref[:N_MODES], rtol=1e-7)
    assert s.frequencies_hz[1, 1, 8] > s.frequencies_hz[1, 1, 9]
    assert s.mac[1, 1].min() > 0.8


def test_every_pair_tracks_like_an_independent_assignment(swap_case):
    """Each pair's tracked modes equal a Hungarian assignment on the mass-weighted MAC, computed here."""
    s = swap_case
    _, X_ref, M_ref = _direct(FULL, FULL)
    for i, L in enumerate((FULL, CORNER)):
        for j, R in enumerate((FULL, CORNER)):
            f, X, _ = _direct(L, R)
            rows, cols = linear_sum_assignment(_wmac(X_ref[:, :N_MODES], X, M_ref), maximize=True)
            np.testing.assert_array_equal(s.mode_index[i, j], cols[np.argsort(rows)])
            np.testing.assert_allclose(s.frequencies_hz[i, j], f[cols[np.argsort(rows)]], rtol=1e-7)


def test_statistics_and_feature_choice():
    rng = np.random.default_rng(4)
    PL = np.array([FULL, CORNER, rng.random(GRID) < 0.5])
    PR = np.array([FULL, rng.random(GRID) < 0.6])
    s = sensitivity(disk_cb(), blade(), PL, PR, n_features=3, progress=False)
    f = s.frequencies_hz.reshape(-1, N_MODES)
    np.testing.assert_allclose(s.mean_hz, np.mean(f, axis=0), rtol=1e-12)
    np.testing.assert_allclose(s.std_hz, np.std(f, axis=0), rtol=1e-9)
    np.testing.assert_allclose(s.std_rel_pct, 100 * np.std(f, axis=0) / np.mean(f, axis=0), rtol=1e-9)
    top = sorted(np.argsort(s.std_rel_pct)[-3:].tolist())
    assert s.feature_modes == tuple(top)
    np.testing.assert_allclose(s.weights, s.std_hz[top] / s.std_hz[top].sum())
    assert s.reference == reference_pair(PL, PR)
    # Every tracked frequency is one of the pair's direct frequencies, each used once.
    for i in range(len(PL)):
        for j in range(len(PR)):
            fd, _, _ = _direct(PL[i], PR[j])
            k = np.argmin(np.abs(s.frequencies_hz[i, j][:, None] / fd[None, :] - 1), axis=1)
            assert np.unique(k).size == N_MODES
            np.testing.assert_allclose(s.frequencies_hz[i, j], fd[k], rtol=1e-7)
    # Transform: other features, default weights follow the std rule.
    t = s.with_features([0, 4])
    assert t.feature_modes == (0, 4) and t.weights.sum() == pytest.approx(1.0)
    with pytest.raises(IdentifyError, match="feature_modes"):
        s.with_features([0, 10])


def test_summarize_against_numpy():
    f = np.array([[1.0, 10.0, 100.0], [1.0, 12.0, 101.0], [1.0, 14.0, 99.0]])
    mean, std, rel, modes, w = summarize(f, n_features=2)
    np.testing.assert_allclose(std, f.std(axis=0))
    np.testing.assert_allclose(rel, 100 * f.std(axis=0) / f.mean(axis=0))
    assert modes == (1, 2)  # mode 0 does not move; mode 1 moves most relative to its mean
    np.testing.assert_allclose(w, std[[1, 2]] / std[[1, 2]].sum())
    with pytest.raises(IdentifyError, match="n_features"):
        summarize(f, n_features=4)


def test_reference_pair_is_the_medoid():
    rows01 = np.zeros(GRID, bool)
    rows01[:2] = True
    row0 = np.zeros(GRID, bool)
    row0[0] = True
    # Hamming distances: full–rows01 7, rows01–row0 7, full–row0 14: rows01 is central.
    assert reference_pair(np.array([FULL, rows01, row0]), np.array([row0, FULL, rows01])) == (1, 2)


def test_model_key_identifies_the_rom():
    d, b = disk_cb(), blade()
    k = model_key(d, b)
    assert k == model_key(dataclasses.replace(d), dataclasses.replace(b, delta=np.full(b.m, 0.01)))
    assert k != model_key(d, b, "paper")
    w2 = b.omega2_tuned.copy()
    w2[0] *= 1.001
    assert k != model_key(d, dataclasses.replace(b, omega2_tuned=w2))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"patterns_L": np.ones((1, 3, 6), bool)}, "grid"),
        ({"patterns_L": np.full((1, 3, 7), 2)}, "boolean"),
        ({"patterns_L": np.ones((3, 7), bool)}, "shape"),
        ({"reference": (0, 5)}, "reference"),
        ({"n_features": 11}, "n_features"),
        ({"n_modes": 0}, "n_modes"),
        ({"patterns_L": np.zeros((1, 3, 7), bool), "patterns_R": np.zeros((1, 3, 7), bool)}, "pattern pair"),
    ],
)
def test_bad_input_is_refused(kwargs, match):
    args = {"patterns_L": FULL[None], "patterns_R": FULL[None], **kwargs}
    PL, PR = args.pop("patterns_L"), args.pop("patterns_R")
    with pytest.raises(IdentifyError, match=match):
        sensitivity(disk_cb(), blade(), PL, PR, progress=False, **args)
