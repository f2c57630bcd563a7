"""``bladetwin campaign init`` (issue 48 item 5): drafts checked against the truth of known manifests.

The bundled campaign and a small simulated one, each with its ``campaign.toml`` taken away: every test's type
and blade/joint must be guessed as the original manifest gives them, and the small one's draft, once the fields
nothing tells are given from the original, must run to the same figures (on tests/pipeline/test_run.py's campaign,
whose cold run is already there). Folders no rule explains are refused in one line. Runs through
:func:`bladetwin.cli.main`, as a user would.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import tomllib
from pathlib import Path

import pytest
import tomli_w

import ema
from bladetwin.cli import main
from lab.campaign import CampaignSpec, simulate_campaign

REPO = Path(__file__).resolve().parents[2]
ACADEMIC = REPO / "measurements" / "academic"
#: The small campaign of tests/pipeline/test_calibration_stage.py (4 blades, joints 1 and 3 filmed).
SMALL = {"level": "coarse", "n_blades": 4, "grid": (3, 7), "known_joints": (1, 3)}
#: The cheapest run that still identifies every joint and validates the ROM: the paper's k-NN and ROM.
FAST = ["--no-figures", "--method", "knn", "--refine", "0", "--rom", "paper", "--quiet"]
UFF_DIRS = ("blades", "disk", "d1b", "assembly")


def _tests(doc: dict) -> dict[str, tuple]:
    """file → (type, blade or joint) of a manifest's tests."""
    return {t["file"]: (t["type"], t.get("blade", t.get("joint"))) for t in doc["tests"]}


def _films(doc: dict) -> dict[str, tuple]:
    return {f["file"]: (f["joint"], f["flank"]) for f in doc.get("films", [])}


def _init(folder: Path, *extra: str) -> int:
    return main(["campaign", "init", str(folder), *extra])


def _refusal(capsys) -> str:
    """The one line a refused command printed (nothing on stdout, no traceback)."""
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bladetwin: error: "), err
    return lines[0]


def test_the_bundled_campaign_is_guessed_as_its_manifest_says(tmp_path, capsys):
    folder = tmp_path / "academic"
    for sub in (*UFF_DIRS, "films"):
        shutil.copytree(ACADEMIC / sub, folder / sub)
    assert _init(folder) == 0
    out = capsys.readouterr().out
    truth = tomllib.loads((ACADEMIC / "campaign.toml").read_text())
    draft = tomllib.loads((folder / "campaign.toml").read_text())
    assert _tests(draft) == _tests(truth)
    assert len(draft["tests"]) == 38
    assert _films(draft) == _films(truth)
    for key in ("n_blades", "known_joints", "frf_units"):
        assert draft["campaign"][key] == truth["campaign"][key], key
    assert "blade      18  blades 1–18" in out and "d1b        18  joints 1–18" in out
    assert f"draft: {folder / 'campaign.toml'}" in out


@pytest.fixture(scope="module")
def drafted(tmp_path_factory):
    """A small simulated campaign with its manifest replaced by campaign init's draft. (That a filled draft runs
    to the original's figures is checked on tests/pipeline/test_run.py's campaign, whose cold run is there.)"""
    root = tmp_path_factory.mktemp("init")
    camp = root / "camp"
    simulate_campaign(CampaignSpec(seed=3, name="camp", **SMALL), camp)
    original = tomllib.loads((camp / "campaign.toml").read_text())
    (camp / "campaign.toml").unlink()
    assert _init(camp) == 0
    return camp, root, original, (camp / "campaign.toml").read_text()


def filled_draft(draft: dict, original: dict, keys=("grid", "model", "masses", "films")) -> dict:
    """The draft with the fields nothing in the files tells given from the original manifest."""
    doc = json.loads(json.dumps(draft))
    if "grid" in keys:
        doc["campaign"]["grid"] = original["campaign"]["grid"]
    if "model" in keys:
        doc["model"] = original["model"]
    if "masses" in keys and "masses" in original:
        doc["masses"] = original["masses"]
    if "films" in keys:
        meta = {(f["joint"], f["flank"]): f for f in original["films"]}
        doc["films"] = [{**meta[f["joint"], f["flank"]], "file": f["file"]} for f in doc["films"]]
    return doc


def _run(camp: Path, root: Path, doc: dict, out: str) -> int:
    (camp / "campaign.toml").write_text(tomli_w.dumps(doc))
    return main(["run", str(camp), *FAST, "--out", str(root / out), "--cache-dir", str(root / "cache")])


def test_the_small_campaign_is_guessed_as_its_manifest_says(drafted):
    camp, _, original, text = drafted
    draft = tomllib.loads(text)
    assert _tests(draft) == _tests(original)
    assert _films(draft) == _films(original)
    assert draft["campaign"]["n_blades"] == 4 and draft["campaign"]["known_joints"] == [1, 3]
    assert draft["campaign"]["kind"] == "virtual"  # truth/ is here, and its films were not taken for scans
    assert all(not f["file"].startswith("truth/") for f in draft["films"])


def test_an_unfilled_draft_is_refused_field_by_field(drafted, capsys):
    """``bladetwin run`` names each placeholder in one line, in the manifest's order, before any computation."""
    camp, root, original, text = drafted
    draft = tomllib.loads(text)
    capsys.readouterr()
    (camp / "campaign.toml").write_text(text)  # the draft as written, comments and all
    assert main(["run", str(camp), *FAST, "--out", str(root / "unfilled"), "--cache-dir", str(root / "cache")]) == 2
    line = _refusal(capsys)
    assert "campaign.toml [campaign]: grid = [], expected [rows, cols]" in line, line
    for given, named in ((("grid",), "family = 'FILL IN'"), (("grid", "model"), "pixel_size = 'FILL IN'")):
        assert _run(camp, root, filled_draft(draft, original, given), "unfilled") == 2
        line = _refusal(capsys)
        assert named in line and "campaign.toml" in line, line
    (camp / "campaign.toml").write_text(text)


def _relabel(src: Path, dst: Path, node) -> None:
    """``src``'s FRFs written to ``dst`` with every node number mapped by ``node``."""
    frf = ema.read_uff(src)
    ema.write_frfs(dst, dataclasses.replace(frf, outputs=tuple((node(n), d) for n, d in frf.outputs),
                                            inputs=tuple((node(n), d) for n, d in frf.inputs)), precision="single")


def _uffs(camp: Path, folder: Path, node=lambda n: n) -> None:
    for path in sorted(camp.glob("*/*.uff")):
        (folder / path.parent.name).mkdir(parents=True, exist_ok=True)
        _relabel(path, folder / path.parent.name / path.name, node)


def test_a_folder_without_uff_files_is_refused_in_one_line(tmp_path, capsys):
    (tmp_path / "films").mkdir()
    shutil.copy(ACADEMIC / "films" / "joint_03_L.png", tmp_path / "films")
    assert _init(tmp_path) == 2
    line = _refusal(capsys)
    assert str(tmp_path) in line and "no UFF file" in line
    assert not (tmp_path / "campaign.toml").exists()


def test_a_file_no_rule_explains_is_refused_in_one_line(drafted, tmp_path, capsys):
    camp = drafted[0]
    _uffs(camp, tmp_path)
    # a blade file whose points are nobody's: not the slot tests' blade points, not one point per sector
    _relabel(camp / "blades" / "blade_02.uff", tmp_path / "blades" / "blade_02.uff", lambda n: n + 500)
    assert _init(tmp_path) == 2
    line = _refusal(capsys)
    assert "blades/blade_02.uff" in line and "no rule" in line, line
    assert not (tmp_path / "campaign.toml").exists()


def test_a_lab_numbering_is_given_by_numbering(drafted, tmp_path, capsys):
    """Blade point p of slot s as node 100 s + p and sector s as node 50 + s: refused without --numbering, guessed
    right with it, and the d1b tests (which `bladetwin run` checks on the default numbering) marked."""
    camp, _, original, _ = drafted

    def lab(n: int) -> int:
        return 100 * (n // 1000) + n % 1000 if n >= 1000 else n + 50

    _uffs(camp, tmp_path, lab)
    for path in (camp / "blades").glob("*.uff"):  # a free blade's points stay nodes 1, 2, 3
        _relabel(path, tmp_path / "blades" / path.name, lambda n: n)
    assert _init(tmp_path) == 2
    assert "--numbering" in _refusal(capsys)
    assert _init(tmp_path, "--numbering", "stride=100,disk_offset=50") == 0
    draft = tomllib.loads((tmp_path / "campaign.toml").read_text())
    assert _tests(draft) == _tests(original)
    assert {t["file"] for t in draft["tests"] if t.get("check_numbering") is False} == {
        t["file"] for t in original["tests"] if t["type"] == "d1b"}
    capsys.readouterr()
    assert _init(tmp_path, "--numbering", "stride=100") == 2  # an existing manifest is kept
    assert "campaign.toml: exists" in _refusal(capsys)
    assert _init(tmp_path, "--numbering", "strid=100", "--force") == 2
    assert "did you mean 'stride'" in _refusal(capsys)
    assert _init(tmp_path, "--numbering", "stride=100,disk_offset=50", "--force") == 0
