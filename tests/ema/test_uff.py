"""UFF reading, refusing and writing, against pyuff and the real files in ../shared/external/pyuff."""

from __future__ import annotations

import numpy as np
import pytest
import pyuff

from ema import (
    EMAError,
    FRFSet,
    ModalModel,
    UFFError,
    merge_frfsets,
    read_frfs,
    read_modes,
    read_nodes,
    read_uff,
    read_units,
    write_frfs,
    write_modes,
)
from ema.uff_write import even_axis

EXPECTED_REFUSAL = {
    "1858.uff": "no FRF",
    "Artemis export - Geometry RPBC_setup_05_14102016_105117.uff": "no FRF",
    "Sample_UFF58_ascii.uff": "not an FRF",
    "Sample_UFF58b_bin.uff": "not an FRF",
    "TestLab 161 164 18 15 82.uff": "no FRF",
    "binary8byte.uff": "not an FRF",
    "dataset_milestone_in_header.uff": "not an FRF",
    "heat_engine_housing.uff": "no FRF",
    "sample_dataset58_psd.uff": "not an FRF (function type 9 = power spectral density)",
    "time-history-not-all-columns-filled.uff": "not an FRF",
    "uff55_translation.uff": "no FRF",
    "uff55_translation_rotation.uff": "no FRF",
}


def test_every_shared_uff_read_or_refused_in_one_line(pyuff_dir):
    files = sorted(pyuff_dir.glob("*.uff"))
    assert files
    for path in files:
        try:
            frf = read_uff(path)
        except UFFError as err:
            msg = str(err)
            assert "\n" not in msg and str(path) in msg
            assert path.name in EXPECTED_REFUSAL, f"unexpected refusal: {msg}"
            assert EXPECTED_REFUSAL[path.name] in msg
        else:
            assert path.name == "non_ascii_header.uff"
            raw = pyuff.UFF(str(path)).read_sets(0)
            assert frf.form == "accelerance"  # from the unit label (1/N)*(m/s2)
            np.testing.assert_array_equal(frf.H[0, 0], raw["data"])
            np.testing.assert_array_equal(frf.freq_hz, raw["x"])


def test_nodes_and_units(pyuff_dir):
    nodes = read_nodes(pyuff_dir / "heat_engine_housing.uff")
    raw = [d for d in pyuff.UFF(str(pyuff_dir / "heat_engine_housing.uff")).read_sets() if d["type"] == 2411][0]
    np.testing.assert_array_equal(nodes.ids, np.asarray(raw["node_nums"], dtype=int))
    np.testing.assert_array_equal(nodes.xyz[:, 2], raw["z"])
    units = read_units(pyuff_dir / "TestLab 161 164 18 15 82.uff")
    assert units is not None and units.length > 0
    assert read_units(pyuff_dir / "uff55_translation.uff") is None
    modes = read_modes(pyuff_dir / "uff55_translation.uff")
    assert modes.n_modes == 3


def _random_set(rng, outputs, inputs, freq, form="mobility"):
    H = rng.standard_normal((len(outputs), len(inputs), freq.size)) * 1e-3 * np.exp(
        1j * rng.uniform(-np.pi, np.pi, (len(outputs), len(inputs), freq.size))
    )
    return FRFSet(freq, H, outputs, inputs, form=form)


@pytest.mark.parametrize("freq", [np.arange(1.0, 201.0) * 0.5, np.cumsum(np.full(150, np.pi / 7)) + 3.3])
def test_58_round_trip_is_lossless(tmp_path, freq):
    rng = np.random.default_rng(1)
    frf = _random_set(rng, [(1, 3), (2, -3), (7, 1)], [(1, 3), (4, 2)], freq)
    path = tmp_path / "frf.uff"
    write_frfs(path, frf)
    back = read_uff(path)
    assert back.outputs == frf.outputs and back.inputs == frf.inputs and back.form == frf.form
    assert np.max(np.abs(back.freq_hz - frf.freq_hz) / frf.freq_hz) <= 1e-12
    assert np.max(np.abs(back.H - frf.H) / np.abs(frf.H)) <= 1e-12
    # pyuff itself reads what we wrote
    raw = pyuff.UFF(str(path)).read_sets()
    assert all(d["func_type"] == 4 for d in raw) and len(raw) == 6


@pytest.mark.parametrize("freq", [np.arange(1.0, 201.0) * 0.5, np.cumsum(np.full(150, np.pi / 7)) + 3.3])
def test_58b_single_precision(tmp_path, freq):
    """precision="single": ordinate type 5, half the bytes, values to float32 rounding, read by pyuff too."""
    rng = np.random.default_rng(3)
    frf = _random_set(rng, [(1, 3), (2, -3), (7, 1)], [(1, 3), (4, 2)], freq)
    write_frfs(tmp_path / "d.uff", frf)
    write_frfs(tmp_path / "s.uff", frf, precision="single")
    back = read_uff(tmp_path / "s.uff")
    assert back.outputs == frf.outputs and back.inputs == frf.inputs and back.form == frf.form
    eps32 = np.finfo(np.float32).eps
    assert np.max(np.abs(back.freq_hz - frf.freq_hz) / frf.freq_hz) <= eps32
    # each of the real and imaginary parts rounds to float32 on its own
    assert np.max(np.abs(back.H - frf.H) / np.abs(frf.H)) <= 2 * eps32
    assert np.max(np.abs(back.H - frf.H) / np.abs(frf.H)) > 0  # it really is single precision
    raw = pyuff.UFF(str(tmp_path / "s.uff")).read_sets()
    assert [d["ord_data_type"] for d in raw] == [5] * 6
    np.testing.assert_allclose(raw[0]["data"], frf.H[0, 0], rtol=2 * eps32)
    # values per point: re, im, and the abscissa when the header cannot rebuild it (uneven axis)
    n_values = freq.size * 6 * (2 if even_axis(freq) else 3)
    saved = (tmp_path / "d.uff").stat().st_size - (tmp_path / "s.uff").stat().st_size
    assert saved == 4 * n_values
    with pytest.raises(EMAError, match="precision"):
        write_frfs(tmp_path / "x.uff", frf, precision="half")


def test_ascii_58_and_modes_55(tmp_path):
    rng = np.random.default_rng(2)
    freq = np.arange(0.0, 100.0, 0.25)
    frf = _random_set(rng, [(1, 3)], [(1, 3)], freq, form="accelerance")
    write_frfs(tmp_path / "a.uff", frf, binary=False)
    back = read_uff(tmp_path / "a.uff")
    assert np.max(np.abs(back.H - frf.H) / np.abs(frf.H)) < 1e-10
    dofs = [(n, d) for n in (1, 2) for d in (1, 2, 3)]
    model = ModalModel([10.0, 20.0], [0.01, 0.02], rng.standard_normal((6, 2)), dofs)
    write_modes(tmp_path / "m.uff", model)
    m2 = read_modes(tmp_path / "m.uff")
    np.testing.assert_allclose(m2.frequencies_hz, [10.0, 20.0], rtol=1e-5)
    np.testing.assert_allclose(m2.damping_ratio, [0.01, 0.02], rtol=1e-4)


def test_refusals_name_file_dataset_field(tmp_path):
    rng = np.random.default_rng(3)
    a = _random_set(rng, [(1, 3)], [(1, 3)], np.arange(1.0, 50.0))
    b = _random_set(rng, [(1, 3)], [(2, 3)], np.arange(1.0, 60.0))
    write_frfs(tmp_path / "a.uff", a)
    write_frfs(tmp_path / "b.uff", b)
    with pytest.raises(ValueError, match="frequency axis"):
        read_frfs([tmp_path / "a.uff", tmp_path / "b.uff"])
    # two data sets with different axes in one file: inconsistent
    sets = [
        pyuff.prepare_58(func_type=4, rsp_node=1, rsp_dir=3, ref_node=k, ref_dir=3, data=np.ones(n) * (1 + 1j),
                         x=np.arange(1.0, n + 1), abscissa_spacing=1, abscissa_spec_data_type=18,
                         ordinate_spec_data_type=12, orddenom_spec_data_type=13, binary=1)
        for k, n in ((1, 10), (2, 12))
    ]
    u = pyuff.UFF(str(tmp_path / "mixed.uff"))
    u.write_sets(sets, mode="add")
    with pytest.raises(UFFError) as err:
        read_uff(tmp_path / "mixed.uff")
    assert "data set 1" in str(err.value) and "'x'" in str(err.value) and "\n" not in str(err.value)
    (tmp_path / "junk.uff").write_text("this is not a universal file\n")
    with pytest.raises(UFFError):
        read_uff(tmp_path / "junk.uff")
    with pytest.raises(FileNotFoundError):
        read_uff(tmp_path / "missing.uff")


def test_merge_roving_hammer_and_forms():
    rng = np.random.default_rng(4)
    freq = np.arange(1.0, 30.0)
    sets = [_random_set(rng, [(1, 1)], [(k, 1)], freq, form="accelerance") for k in (1, 2, 3)]
    merged = merge_frfsets(sets)
    assert merged.H.shape == (1, 3, freq.size) and merged.inputs == ((1, 1), (2, 1), (3, 1))
    np.testing.assert_array_equal(merged.H[0, 2], sets[2].H[0, 0])
    with pytest.raises(ValueError, match="twice"):
        merge_frfsets([sets[0], sets[0]])
    rec = merged.with_form("receptance")
    w = 2 * np.pi * freq
    np.testing.assert_allclose(rec.H * -(w**2), merged.H, rtol=1e-13)
    np.testing.assert_allclose(rec.with_form("accelerance").H, merged.H, rtol=1e-13)
