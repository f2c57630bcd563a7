"""The campaign manifest reader (bladetwin.campaign) and the pipeline's small numerics (bladetwin.stages)."""

from __future__ import annotations

import numpy as np
import pytest

import ema
from bladetwin.campaign import CampaignError, read_campaign
from bladetwin.cli import main
from bladetwin.stages.bias import known_bias, match_to_reference, recentred_reference
from bladetwin.stages.patterns import mean_known_pattern
from rom.contact import ContactPattern

MANIFEST = """
[campaign]
name = "mini"
n_blades = 3
grid = [3, 7]
known_joints = [1, 2]

[model]
family = "academic"
level = "coarse"

[[tests]]
type = "blade"
file = "b1.uff"
blade = 1

[[tests]]
type = "assembly"
file = "a.uff"
max_order = 120

[[films]]
joint = 1
flank = "L"
file = "f1L.png"

[[films]]
joint = 1
flank = "R"
file = "f1R.png"

[[films]]
joint = 2
flank = "L"
file = "f2L.png"

[[films]]
joint = 2
flank = "R"
file = "f2R.png"
"""


@pytest.fixture
def folder(tmp_path):
    for name in ("b1.uff", "a.uff", "f1L.png", "f1R.png", "f2L.png", "f2R.png"):
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / "campaign.toml").write_text(MANIFEST)
    return tmp_path


def test_reads_a_good_manifest(folder):
    c = read_campaign(folder)
    assert (c.name, c.n_blades, c.grid, c.known_joints) == ("mini", 3, (3, 7), (1, 2))
    assert [t.type for t in c.tests] == ["blade", "assembly"]
    assert c.of_type("assembly")[0].max_order == 120 and c.of_type("blade")[0].max_order == 60
    assert c.film(2, "R").file == (folder / "f2R.png").resolve()
    assert c.truth_dir is None


def test_the_blades_hardware_reaches_the_disk_reductions(folder):
    """``[masses] slot_hardware_kg`` becomes the disk nodes' parameter: the one-slot CB disk puts it on its slot,
    the cyclic all-slot disk on every slot (the reduction itself: tests/rom/test_craig_bampton.py)."""
    from bladetwin.stages import RunOptions, campaign_pipeline, names
    from bladetwin.stages.models import mounted
    from rom.academic import build_bladed_disk
    from tests.rom.rom_models import COARSE

    for text, kg in (("", 0.0), ("\n[masses]\nslot_hardware_kg = 0.02\n", 0.02)):
        (folder / "campaign.toml").write_text(MANIFEST + text)
        p = campaign_pipeline(read_campaign(folder), RunOptions())
        assert p[names.DISK_CB].params == p[names.DISK_CYCLIC].params == {"hardware_kg": kg}
    bd = build_bladed_disk(COARSE.with_(n_blades=3))
    assert mounted(bd, (1,), 0.0) is bd
    for slots in ((1,), (1, 2, 3)):
        assert mounted(bd, slots, 0.02).disk.mass() == pytest.approx(bd.disk.mass() + 0.02 * len(slots), rel=1e-12)


@pytest.mark.parametrize("old, new, needle", [
    ('file = "b1.uff"', 'file = "missing.uff"', "'missing.uff' not found"),
    ('type = "blade"', 'type = "rotor"', "type = 'rotor'"),
    ("blade = 1", "blade = 4", "blade = 4, expected 1..3"),
    ("known_joints = [1, 2]", "known_joints = [1, 3]", "known joint 3 has no film for flank L"),
    ("known_joints = [1, 2]", "known_joints = [0]", "known_joints = [0]"),
    ("grid = [3, 7]", "grid = [3]", "grid = [3]"),
    ("max_order = 120", "max_order = -1", "max_order = -1"),
    ("n_blades = 3", 'n_blades = "3"', "'n_blades'"),
    ("[campaign]", "[campaign", "not valid TOML"),
    ("max_order = 120", "max_order = 120\n\n[masses]\nslot_hardware_kg = -0.01", "slot_hardware_kg = -0.01"),
])
def test_bad_manifests_are_one_line_errors_naming_the_field(folder, capsys, old, new, needle):
    path = folder / "campaign.toml"
    path.write_text(MANIFEST.replace(old, new, 1))
    with pytest.raises(CampaignError, match=None) as exc:
        read_campaign(folder)
    msg = str(exc.value)
    assert needle in msg and str(path) in msg and "\n" not in msg, msg
    # through the command line: exit 2, one line
    assert main(["identify", "patterns", str(folder), "--out", str(folder / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and needle in err


def test_not_a_campaign_folder(tmp_path):
    with pytest.raises(CampaignError, match="no campaign.toml"):
        read_campaign(tmp_path)
    with pytest.raises(CampaignError, match="not a campaign folder"):
        read_campaign(tmp_path / "nope")


def test_match_to_reference_is_one_to_one_within_the_window():
    ref = np.array([100.0, 200.0, 205.0, 400.0])
    measured = np.array([201.0, 99.0, 204.0, 330.0])
    got = match_to_reference(measured, ref, window=0.05)
    np.testing.assert_array_equal(got[:3], [99.0, 201.0, 204.0])
    assert np.isnan(got[3])  # 330 Hz is 17.5 % away from 400 Hz
    assert np.isnan(match_to_reference(np.array([]), ref)).all()


def test_match_to_reference_leaves_a_mode_unpaired_rather_than_push_the_others_off():
    # a realistic twin's joint (coarse seed 41, joint 3): its test's modes 9 and 10 at 3426.7 and 3342.9 Hz, a
    # spurious pole at 3196.6 Hz; the model's next, untracked mode at 3598.9 Hz
    measured = np.array([3196.6, 3342.9, 3426.7])
    got = match_to_reference(measured, np.array([3438.1, 3346.8]), neighbours_hz=np.array([3598.9]))
    np.testing.assert_array_equal(got, [3426.7, 3342.9])
    # pairing as many modes as possible gives the neighbour 3426.7 Hz (4.8 %) and shifts both tracked modes
    rows, cols = ema.pair_by_frequency(np.array([3438.1, 3346.8, 3598.9]), measured, 0.05)
    assert measured[cols[rows == 1]][0] == 3196.6


def test_a_neighbouring_untracked_mode_keeps_its_own_measured_mode():
    # coarse seed 43, joint 1: the model's tracked modes 9, 10 and its untracked mode 11 at 3649.6 Hz; the
    # specimen's mode 10 is 3398.0 Hz, 3.8 % below the model's, and its mode 11 sits where the model's does
    ref, measured = np.array([3462.5, 3535.1]), np.array([3398.0, 3436.9, 3650.2])
    np.testing.assert_array_equal(match_to_reference(measured, ref), [3436.9, 3650.2])
    np.testing.assert_array_equal(match_to_reference(measured, ref, neighbours_hz=np.array([3649.6])),
                                  [3436.9, 3398.0])


def test_the_second_pairing_is_centred_where_the_joints_agree():
    # Eight joints (coarse seed 43's, two made closer to the model) whose mode 10 lies 2.6-3.9 % below the
    # model's 3535.1 Hz and whose mode 9 lies 0.4-0.8 % below 3462.5 Hz; every test also has the next mode at
    # 3650.5 Hz. The truth is the construction.
    true = np.array([[3436.9, 3398.0], [3447.9, 3425.4], [3435.5, 3431.0], [3439.9, 3428.0],
                     [3444.7, 3441.1], [3442.7, 3395.9], [3446.6, 3432.6], [3448.0, 3429.4]])
    tests = [np.r_[t, 3650.5] for t in true]
    ref = np.tile([3462.5, 3535.1], (len(true), 1))
    first = np.array([match_to_reference(f, r) for f, r in zip(tests, ref, strict=True)])
    np.testing.assert_array_equal(np.flatnonzero(first[:, 1] == 3650.5), [0, 5])  # joints 1 and 6: the next mode
    centred = recentred_reference(first, ref)
    second = np.array([match_to_reference(f, r) for f, r in zip(tests, centred, strict=True)])
    np.testing.assert_array_equal(second, true)
    # fewer than 3 joints with a mode: no median to trust, the reference stays
    np.testing.assert_array_equal(recentred_reference(first[:2], ref[:2]), ref[:2])


def test_known_bias_is_the_median_ratio_and_ignores_unmatched_modes():
    rom = {1: np.array([100.0, 200.0]), 2: np.array([100.0, 200.0]), 3: np.array([100.0, 200.0])}
    meas = {1: np.array([101.0, np.nan]), 2: np.array([102.0, 202.0]), 3: np.array([103.0, 204.0])}
    np.testing.assert_allclose(known_bias(meas, rom), [0.02, 0.015])


def test_mean_known_pattern_is_the_majority_vote():
    a = np.zeros((3, 7), bool)
    a[:, :4] = True
    b = np.zeros((3, 7), bool)
    b[:, 2:] = True
    c = np.zeros((3, 7), bool)
    c[:, 3:6] = True
    base = mean_known_pattern({1: ContactPattern(a, b), 2: ContactPattern(b, c), 3: ContactPattern(c, a)})
    np.testing.assert_array_equal(base.L, (a.astype(int) + b + c) >= 2)
