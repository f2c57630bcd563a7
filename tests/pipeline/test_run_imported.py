"""A campaign whose ``[model]`` is an imported FE model (issue 13, item 3).

The acceptance check: ``bladetwin run`` on a small simulated campaign (coarse mesh, 4 blades, 3×7 grid) whose
``[model]`` points to the twin exported as Matrix Market files identifies the same patterns as the same campaign
on the native twin. Each run has its own cache, so that the imported run
reduces the imported matrices rather than finding the twin's reduced models (only the EMA's, keyed by the UFF
files' bytes, is copied over).
"""

from __future__ import annotations

import json
import shutil
import tomllib

import numpy as np
import pytest
import tomli_w

from bladetwin.campaign import CampaignError, read_campaign
from bladetwin.cli import main
from bladetwin.model import load_model, model_params
from rom.academic import build_bladed_disk, flank_coordinates
from rom.importers.export import export_bladed_disk
from rom.importers.model import ImportedBladedDisk
from rom.pattern_io import load_patterns

#: The ideal twin: these tests check the pipeline's behaviour, not its accuracy on a realistic specimen.
N_BLADES = 4
SMALL = ["--level", "coarse", "--blades", str(N_BLADES), "--grid", "3x7", "--known", "1,3", "--realism", "ideal"]
_FILE_KEYS = ("K", "M", "file", "archive", "dofmap", "coords", "node_sets")


def _imported_table(model_toml, prefix: str) -> dict:
    """The ``[model]`` table of an exported ``model.toml``, its paths made relative to the campaign folder."""
    table = tomllib.loads(model_toml.read_text())["model"]
    for comp in ("disk", "blade"):
        for k in _FILE_KEYS:
            if k in table[comp]:
                table[comp][k] = f"{prefix}/{table[comp][k]}"
    table["grids"]["file"] = f"{prefix}/{table['grids']['file']}"
    return {"family": "imported", **table}


def _set_model(folder, model: dict) -> None:
    path = folder / "campaign.toml"
    doc = tomllib.loads(path.read_text())
    doc["model"] = model
    path.write_text(tomli_w.dumps(doc))


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """(root, native campaign, the same campaign on the exported twin)."""
    root = tmp_path_factory.mktemp("run_imported")
    native = root / "native"
    assert main(["lab", "simulate", *SMALL, "--seed", "3", "--out", str(native)]) == 0
    imported = root / "imported"
    shutil.copytree(native, imported)
    bd = build_bladed_disk(model_params(read_campaign(native)))
    exported = export_bladed_disk(bd, imported / "fe", format="mtx")
    _set_model(imported, _imported_table(exported.model_toml, "fe"))
    return root, native, imported


@pytest.fixture(scope="module")
def runs(campaigns):
    root, native, imported = campaigns
    out = {}
    for name, camp in (("native", native), ("imported", imported)):
        o = root / f"out_{name}"
        if name == "imported":
            # Same UFF files byte for byte, so the EMA's cache (keyed by them) is shared; the reduced models
            # and everything after are not: the imported run reduces the imported matrices.
            ema_fits = ("nodes", "fit_test")
            shutil.copytree(root.joinpath("cache_native", *ema_fits), root.joinpath("cache_imported", *ema_fits))
        # --no-calibrate: an imported model keeps its materials (bladetwin does not know them; the calibration
        # says so), so the native model must keep its own for the two runs to be the same
        assert main(["run", str(camp), "--no-calibrate", "--refine", "0", "--rom", "paper", "--method", "knn",
                     "--no-figures",
                     "--out", str(o),
                     "--cache-dir", str(root / f"cache_{name}"), "--quiet"]) == 0
        out[name] = o, json.loads((o / "summary.json").read_text())
    return out


def test_run_on_the_exported_twin_identifies_the_same_patterns(runs):
    (out_n, s_n), (out_i, s_i) = runs["native"], runs["imported"]
    pats_n = load_patterns(out_n / "identified_patterns.npz")
    pats_i = load_patterns(out_i / "identified_patterns.npz")
    assert len(pats_n) == len(pats_i) == N_BLADES
    for a, b in zip(pats_n, pats_i, strict=True):
        assert np.array_equal(a.L, b.L) and np.array_equal(a.R, b.R)
    assert s_i["joints"] == s_n["joints"]
    assert s_i["cases"] == s_n["cases"]


def test_imported_model_is_checked_and_knows_its_flank_coordinates(campaigns):
    _, native, imported = campaigns
    bd_n = load_model(read_campaign(native))
    bd_i = load_model(read_campaign(imported))
    assert isinstance(bd_i, ImportedBladedDisk) and bd_i.n_slots == N_BLADES and tuple(bd_i.params.grid) == (3, 7)
    # rom.academic.flank_coordinates dispatches to the imported model's own axes (here the twin's z, y)
    for a, b in zip(flank_coordinates(bd_n), flank_coordinates(bd_i), strict=True):
        assert np.array_equal(a, b)


def test_model_file_form_and_rom_build_on_the_imported_model(campaigns, runs, tmp_path, capsys):
    root, native, imported = campaigns
    # [model] file = "fe/model.toml": the exported file as it is, paths relative to it
    camp = tmp_path / "by_file"
    shutil.copytree(imported, camp)
    _set_model(camp, {"family": "imported", "file": "fe/model.toml"})
    bd = load_model(read_campaign(camp))
    assert isinstance(bd, ImportedBladedDisk) and bd.disk.n_dof == load_model(read_campaign(imported)).disk.n_dof

    # `rom build --model`: the exported model.toml and the native campaign give the same reduced models
    # (`rom build` keeps its own cache of reduced models, rom.cache)
    capsys.readouterr()
    outs = []
    for model, cache in ((imported / "fe" / "model.toml", "cache_imported"), (native, "cache_native")):
        assert main(["rom", "build", "--model", str(model), "--cache-dir", str(root / cache), "--json"]) == 0
        outs.append(json.loads(capsys.readouterr().out))
    for key in ("disk_cb", "blade_rubin"):
        for k in ("first_fixed_interface_hz", "free_interface_hz", "n_dof_fe", "n_b"):
            if k in outs[0][key]:
                assert outs[0][key][k] == outs[1][key][k], (key, k)


def _one_line_error(capsys, argv, *needles) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err


def test_bad_model_tables_give_one_line_errors(campaigns, tmp_path, capsys):
    _, _, imported = campaigns
    camp = tmp_path / "bad"
    shutil.copytree(imported, camp)
    good = tomllib.loads((imported / "campaign.toml").read_text())["model"]

    (camp / "fe" / "blade_M.mtx").unlink()
    _one_line_error(capsys, ["run", str(camp), "--out", str(tmp_path / "o"), "--quiet"],
                    "campaign.toml", "[model.blade] M", "blade_M.mtx")

    _set_model(camp, {**good, "placement": {**good["placement"], "n_slots": N_BLADES + 1}})
    with pytest.raises(CampaignError, match=rf"n_slots = {N_BLADES + 1}.*n_blades = {N_BLADES}"):
        read_campaign(camp)
    _set_model(camp, {**good, "grids": {**good["grids"], "shape": [3, 5]}})
    with pytest.raises(CampaignError, match=r"shape = \[3, 5\].*\[3, 7\]"):
        read_campaign(camp)
    _set_model(camp, {**good, "level": "coarse"})
    with pytest.raises(CampaignError, match=r"\['level'\] belong to the academic twin"):
        read_campaign(camp)
    _set_model(camp, {"family": "academic", "level": "coarse", "format": "mtx"})
    with pytest.raises(CampaignError, match=r"unknown key\(s\) \['format'\] for family 'academic'"):
        read_campaign(camp)
    _set_model(camp, {"family": "nastran"})
    with pytest.raises(CampaignError, match="family = 'nastran'"):
        read_campaign(camp)
    _set_model(camp, {"family": "imported", "file": "fe/nowhere.toml"})
    _one_line_error(capsys, ["rom", "build", "--model", str(camp), "--json"], "nowhere.toml", "not found")
    _one_line_error(capsys, ["rom", "build", "--model", str(imported / "fe" / "model.toml"), "--grid", "3x7",
                             "--json"], "--model", "--grid")
