"""The small simulated campaign and its cold ``bladetwin run``, shared by the run modules of this package.

Coarse mesh, 6 blades, 3×7 grid, joints 3 and 4 filmed, seed 3; the cold run is the paper's k-NN alone
(``--refine 0``). ``test_run.py`` re-runs it warm and on edited copies; ``test_run_imported.py`` compares it
with the same campaign on the exported twin. One simulation and one cold run serve both.
"""

from __future__ import annotations

import json

import pytest

from bladetwin.cli import main

SMALL = ["--level", "coarse", "--blades", "6", "--grid", "3x7", "--known", "3,4"]
#: The paper's k-NN alone: every run test but the refinement's runs without it, so the modules stay short.
KNN_ONLY = ["--refine", "0"]


@pytest.fixture(scope="session")
def small_campaign(tmp_path_factory):
    """(root folder, campaign folder). Tests copy the campaign before editing it; ``root / "cache"`` is the cache."""
    root = tmp_path_factory.mktemp("run")
    camp = root / "small"
    assert main(["lab", "simulate", *SMALL, "--seed", "3", "--out", str(camp)]) == 0
    return root, camp


@pytest.fixture(scope="session")
def small_cold(small_campaign):
    """(output folder, summary) of the cold run on :func:`small_campaign` with ``root / "cache"``."""
    root, camp = small_campaign
    out = root / "out"
    assert main(["run", str(camp), *KNN_ONLY, "--out", str(out), "--cache-dir", str(root / "cache"), "--quiet"]) == 0
    return out, json.loads((out / "summary.json").read_text())
