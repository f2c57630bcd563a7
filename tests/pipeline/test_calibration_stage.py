"""The calibration stage of ``bladetwin run`` (paper §5) on small simulated campaigns, against the twin's truth:
it recovers the specimen's disk modulus and density, and leaves a model that is the specimen alone."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from bladetwin.campaign import read_campaign
from bladetwin.run import run_nodes
from bladetwin.stages import RunOptions
from lab.campaign import CampaignSpec, simulate_campaign
from lab.truth import TruthParams

SMALL = {"level": "coarse", "n_blades": 4, "grid": (3, 7), "known_joints": (1, 3)}


def _calibrate(tmp_path, truth: TruthParams, seed: int):
    camp = tmp_path / f"camp{seed}"
    simulate_campaign(CampaignSpec(seed=seed, truth=truth, **SMALL), camp)
    opts = RunOptions(cache_dir=tmp_path / "cache", workers=1, calibrate=True)
    res, _ = run_nodes(read_campaign(camp), ["calibration"], opts)
    return res["calibration"], json.loads((camp / "truth" / "truth.json").read_text())


def test_the_calibration_recovers_the_specimen_s_disk_material(tmp_path):
    """Realistic specimen on the model's mesh: the disk's E and ρ come back from its first mode and its mass.

    The tolerance on E is the test day's temperature (1.5 K × 2.6e-4/K, 3 σ: 0.12 %) plus the EMA's error;
    ρ comes from the weighed mass (0.1 g on about 1.9 kg)."""
    truth = dataclasses.replace(TruthParams(), mesh_refinement=0)
    cal, t = _calibrate(tmp_path, truth, 8)
    off = t["material_offsets"]
    # the sectors' modulus scatter moves the disk's mean modulus too (4 sectors: by 0.25 % at one σ)
    E_specimen = (1 + off["disk_E"]) * (1 + np.mean(t["disk_sector_moduli"]))
    assert cal.disk.E_scale == pytest.approx(E_specimen, abs=2e-3)
    assert cal.disk.rho_scale == pytest.approx(1 + off["disk_rho"], abs=1e-4)
    assert cal.disk.rho_source == cal.blade.rho_source == "masses"
    assert abs(off["disk_E"]) >= 0.01  # the model was off: the calibration had something to find


def test_a_specimen_that_is_the_model_calibrates_to_the_model(tmp_path):
    """The ideal twin without its blade-to-blade variation (the fillet blades' and the variations' mean, which
    the calibration rightly follows, moved the blade's E by 0.45 % on a 6-blade ideal campaign): E and ρ stay
    within 0.1 % of the model's."""
    same = dataclasses.replace(TruthParams.ideal(), fillet_fraction=0.0, thickness_spread=0.0, chord_spread=0.0,
                               span_spread=0.0, modulus_spread=0.0)
    cal, _ = _calibrate(tmp_path, same, 2)
    for c in (cal.disk, cal.blade):
        assert abs(c.E_scale - 1) < 1e-3 and abs(c.rho_scale - 1) < 1e-3, c
