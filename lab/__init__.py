"""lab: the virtual test rig (floor 2; imports ``rom`` and ``ema``, never ``identify`` or ``bladetwin``).

It turns a *truth* twin into a measurement campaign (docs/campaign.md):

- :mod:`lab.patterns`: true contact-pressure fields and the contact patterns they imply;
- :mod:`lab.films`: pressure-film scans of them;
- :mod:`lab.truth`: the truth twin (contact springs, FE-level blade variation, damping);
- :mod:`lab.rig`: virtual hammer tests (mobility FRFs with noise);
- :mod:`lab.campaign`: a whole campaign on disk (UFF files, films, manifest, truth);
- :mod:`lab.model_error`: Case C, the ROM with the true patterns against the campaign's EMA;
- :mod:`lab.truth_response`: the truth's full-assembly modes, mistuned and tuned, for the amplification factor.
"""

from .campaign import CampaignInfo, CampaignSpec, default_known_joints, simulate_campaign
from .films import FilmMeta, FilmParams, render_film, write_film
from .model_error import ModelError, case_c, rom_deltas
from .patterns import PressureParams, TruePressure, flank_coordinates, simulate_pressure
from .rig import RigSetup, damping_ratios, dof_label, measure, peak_snr, synthesize_mobility
from .truth import (
    REALISM,
    BladeVariation,
    TruthAssembly,
    TruthParams,
    TruthTwin,
    assemble_truth,
    make_truth_twin,
    solve_truth,
)
from .truth_response import ResponseTruth, load_response_truth, tuned_twin

__all__ = [
    "REALISM",
    "BladeVariation",
    "ResponseTruth",
    "load_response_truth",
    "tuned_twin",
    "CampaignInfo",
    "CampaignSpec",
    "FilmMeta",
    "FilmParams",
    "ModelError",
    "PressureParams",
    "RigSetup",
    "TruePressure",
    "TruthAssembly",
    "TruthParams",
    "TruthTwin",
    "assemble_truth",
    "case_c",
    "damping_ratios",
    "default_known_joints",
    "dof_label",
    "flank_coordinates",
    "make_truth_twin",
    "measure",
    "peak_snr",
    "render_film",
    "rom_deltas",
    "simulate_campaign",
    "simulate_pressure",
    "solve_truth",
    "synthesize_mobility",
    "write_film",
]
