"""The forced response's truth (issue 47, lab.truth_response): the truth twin's mistuned and tuned full-assembly
modes at the blade points, written with every campaign and added to an existing one.

One small campaign of the ideal twin (coarse mesh, 4 blades, 3×7 grid: its frequency-domain test takes a third of
the realistic twin's time-domain one), and the realistic twin of the same command built and solved without its
tests (sector scatter, re-seating, contact scatter and fillets all act, so the tuned twin has everything to undo).
"""

import json
import re
import shutil
import tomllib
from dataclasses import replace

import numpy as np
import pytest

from bladetwin.cli import main
from bladetwin.cli_lab import spec_from_command
from lab.campaign_spec import assembly_solve_modes, campaign_twin
from lab.truth_response import (
    RESPONSE_FILE,
    add_response_truth,
    load_response_truth,
    tuned_twin,
    write_response_truth,
)
from rom.forced import blade_modes

SMALL = ["--level", "coarse", "--blades", "4", "--grid", "3x7", "--known", "1,3", "--realism", "ideal"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("response") / "small"
    assert main(["lab", "simulate", *SMALL, "--seed", "5", "--coherence", "none", "--out", str(out)]) == 0
    return out


def _command(campaign) -> str:
    return tomllib.loads((campaign / "campaign.toml").read_text())["campaign"]["generated_by"]


def _nodal_diameters(modes) -> tuple[np.ndarray, np.ndarray]:
    """Each mode's dominant nodal diameter over the slots (blade rows) and the share of its DFT energy there."""
    lab = np.array([lab[1:3] for lab in modes.meas_labels])
    n = int(lab[:, 0].max())
    nd, purity = [], []
    for k in range(modes.frequencies_hz.size):
        X = np.zeros((n, int(lab[:, 1].max())))
        X[lab[:, 0] - 1, lab[:, 1] - 1] = modes.meas_shapes[:, k]
        P = np.sum(np.abs(np.fft.fft(X, axis=0)) ** 2, axis=1)
        h = np.array([P[j] + (P[n - j] if 0 < j < n - j else 0.0) for j in range(n // 2 + 1)])
        nd.append(int(np.argmax(h)))
        purity.append(h.max() / h.sum())
    return np.array(nd), np.array(purity)


def test_the_tuned_twin_is_cyclic_and_its_modes_come_in_pairs(campaign, tmp_path):
    spec = spec_from_command(_command(campaign))
    assert spec.command(campaign) == _command(campaign)  # the command line's parser reads the command back
    twin = campaign_twin(replace(spec, realism="realistic")).twin
    assert twin.sector_moduli is not None and twin.contact_scale is not None  # the realistic twin: mistuned
    tuned = tuned_twin(twin)
    b0 = tuned.blades[0]
    for b in tuned.blades[1:]:
        assert (b.K != b0.K).nnz == 0 and (b.M != b0.M).nnz == 0
    assert tuned.sector_moduli is None and tuned.patterns == tuned.assembly_patterns
    assert all(np.array_equal(p.L, tuned.patterns[0].L) and np.array_equal(p.R, tuned.patterns[0].R)
               for p in tuned.patterns)
    assert np.ptp(tuned.contact_scale, axis=0).max() == 0
    np.testing.assert_allclose(tuned.contact_scale[0], twin.contact_scale.mean(axis=0))
    assert tuned.materials == twin.materials and tuned.day_factors == twin.day_factors
    np.testing.assert_allclose(tuned.variations[0].thickness, np.mean([v.thickness for v in twin.variations]))

    # An independent physical check: every sector the same, the blade-dominated modes are pure nodal diameters,
    # and those of diameter 1..N/2-1 come in degenerate pairs (0 and N/2 alone).
    write_response_truth(twin, tmp_path, assembly_solve_modes(twin.n_blades))
    rt = load_response_truth(tmp_path)
    n = twin.n_blades
    for modes, is_tuned in ((rt.tuned, True), (rt.mistuned, False)):
        f = modes.frequencies_hz
        nd, purity = _nodal_diameters(modes)
        paired = []
        for k in np.flatnonzero(modes.blade_energy > 0.5):
            partners = np.flatnonzero((np.abs(f / f[k] - 1) < 1e-6) & (nd == nd[k]))
            paired.append(partners.size == (2 if 0 < nd[k] < n / 2 else 1) and purity[k] > 0.999)
        # the mistuned truth: localised modes, neither pure diameters nor pairs (its isolated ND 0 can be pure)
        assert all(paired) if is_tuned else sum(paired) < len(paired) / 4, (is_tuned, paired)
    blade_modes(rt.tuned, 0.001, 1)  # the forced response takes either as it takes a ROM's modes
    blade_modes(rt.mistuned, 0.001, 3)


def test_the_mistuned_modes_are_the_assembly_test_s_truth(campaign):
    truth = json.loads((campaign / "truth" / "truth.json").read_text())
    rt = load_response_truth(campaign / "truth")
    every = np.array(truth["all_frequencies_hz"]["assembly"])
    f = rt.mistuned.frequencies_hz
    inside = f[(f >= every[0] * (1 - 1e-9)) & (f <= every[-1] * (1 + 1e-9))]
    np.testing.assert_allclose(inside, every, rtol=1e-9)
    # every blade point of every slot, the same rows for both; mass-normalised shapes: blades hold ≤ all energy
    assert len(rt.mistuned.meas_labels) == 4 * 3 and rt.mistuned.meas_labels == rt.tuned.meas_labels
    assert rt.mistuned.meas_shapes.shape == (12, f.size) and np.all(rt.tuned.blade_energy <= 1 + 1e-9)
    assert (campaign / "truth" / RESPONSE_FILE).stat().st_size < 200_000


def test_an_existing_campaign_gets_the_same_file(campaign, tmp_path, capsys):
    old = tmp_path / "old"
    (old / "truth").mkdir(parents=True)
    for rel in ("campaign.toml", "truth/truth.json"):  # all a campaign written before needs
        shutil.copy(campaign / rel, old / rel)
    assert main(["lab", "response-truth", str(old)]) == 0
    captured = capsys.readouterr()
    assert "agree with truth.json" in captured.err and RESPONSE_FILE in captured.out
    with np.load(old / "truth" / RESPONSE_FILE) as a, np.load(campaign / "truth" / RESPONSE_FILE) as b:
        assert sorted(a.files) == sorted(b.files)
        for key in a.files:
            np.testing.assert_allclose(a[key], b[key], rtol=1e-9, atol=0, err_msg=key)


def test_a_campaign_whose_twin_cannot_be_rebuilt_is_refused(campaign, tmp_path):
    root = tmp_path / "c"
    (root / "truth").mkdir(parents=True)
    shutil.copy(campaign / "truth" / "truth.json", root / "truth" / "truth.json")
    command = _command(campaign)
    for bad, needle in ((command + " (plus settings made in Python: re-seated joints)", "settings made in Python"),
                        (command.replace("--seed 5", "--seed 6"), "seed 5 there, 6 here"),
                        (command.replace("--level coarse", "--level rough"), "invalid choice"),
                        ("python make.py", "bladetwin lab simulate")):
        (root / "campaign.toml").write_text(f'[campaign]\ngenerated_by = "{bad}"\n')
        with pytest.raises(ValueError, match=needle):
            add_response_truth(root, spec_of=spec_from_command)
    # A twin whose full-assembly frequencies are not the truth's is refused before the tuned solve (the
    # campaign's own solve stands in for the rebuilt one: no solve here).
    truth = json.loads((campaign / "truth" / "truth.json").read_text())
    twin = campaign_twin(spec_from_command(command)).twin
    rt = load_response_truth(campaign / "truth")
    solved = replace(rt.mistuned, frequencies_hz=rt.mistuned.frequencies_hz / twin.day_factor("assembly"))
    every = truth["all_frequencies_hz"]["assembly"]
    for check_hz, needle in (([f * (1 + 1e-6) for f in every], "differ from the truth.s by up to 1e-06"),
                             ([f * 100 for f in every], "could not be rebuilt: 1 of its full-assembly modes lie")):
        with pytest.raises(ValueError, match=needle):
            write_response_truth(twin, root / "truth", assembly_solve_modes(twin.n_blades), check_hz,
                                 mistuned=solved)
    assert not (root / "truth" / RESPONSE_FILE).exists()


def test_a_damaged_file_is_refused_naming_it(campaign, tmp_path):
    assert load_response_truth(tmp_path) is None
    path = tmp_path / RESPONSE_FILE
    data = (campaign / "truth" / RESPONSE_FILE).read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match=f"{re.escape(str(path))}.*unreadable"):
        load_response_truth(tmp_path)
    with np.load(campaign / "truth" / RESPONSE_FILE) as z:
        good = {k: z[k] for k in z.files}
    for key, value, needle in (("shapes", good["shapes"][:-1], "do not fit"),
                               ("tuned_frequencies_hz", good["tuned_frequencies_hz"][::-1], "ascending"),
                               ("labels", good["labels"][:, :2], "labels"),
                               ("blade_energy", None, "no blade_energy")):
        arrays = {**good, key: value} if value is not None else {k: v for k, v in good.items() if k != key}
        np.savez_compressed(path, **arrays)
        with pytest.raises(ValueError, match=f"{re.escape(str(path))}.*{needle}"):
            load_response_truth(tmp_path)


def test_the_command_refuses_a_folder_without_a_campaign(tmp_path, capsys):
    rc = main(["lab", "response-truth", str(tmp_path)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "campaign.toml" in err, err
