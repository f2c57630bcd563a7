"""The family-wise view (identify.families): gap clustering and the subspace correlation by principal angles."""

import numpy as np
import pytest

from identify.families import family_view, mode_families
from identify.validation import compare_modes


def test_families_split_at_gaps_wider_than_the_threshold():
    f = np.array([100.0, 100.05, 100.1, 130.0, 131.0, 200.0])
    fams = mode_families(f[::-1], gap=0.02)
    assert [sorted(f[::-1][g].tolist()) for g in fams] == [[100.0, 100.05, 100.1], [130.0, 131.0], [200.0]]
    assert mode_families(np.zeros(0)) == []


def test_subspace_correlation_sees_a_rotated_family_that_single_mode_mac_misses():
    """Two close modes whose shapes the ROM mixes by 45°: pairwise MAC 0.5, the family's subspace exact."""
    rng = np.random.default_rng(2)
    q, _ = np.linalg.qr(rng.standard_normal((12, 3)))
    meas = q  # modes at 100, 100.05 (one family) and 150 Hz
    c = np.sqrt(0.5)
    rom = np.c_[c * (q[:, 0] + q[:, 1]), c * (q[:, 0] - q[:, 1]), q[:, 2]]
    f_meas, f_rom = np.array([100.0, 100.05, 150.0]), np.array([100.01, 100.04, 150.3])
    comp = compare_modes((f_meas, meas), (f_rom, rom))
    rows = family_view(comp, f_meas, meas, f_rom, rom)
    assert len(rows) == 2 and rows[0].n_measured == 2 and rows[1].n_measured == 1
    assert rows[0].mean_mac == pytest.approx(0.5, abs=1e-9)
    assert rows[0].subspace_cos_min == pytest.approx(1.0, abs=1e-9)
    assert rows[1].subspace_mean_cos2 == pytest.approx(1.0, abs=1e-9)
    assert rows[1].mean_abs_df_pct == pytest.approx(0.2, rel=1e-9)
