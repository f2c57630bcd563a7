"""Coherence in UFF: one data set 58 of function type 6 per FRF, written beside the FRFs and read back.

pyuff (an independent reader) must read the written coherence; :func:`ema.read_uff` must pass over it and
:func:`ema.read_coherence` must return it; a damaged coherence data set is refused in one line naming the file.
"""

from __future__ import annotations

import numpy as np
import pytest
import pyuff

from ema import EMAError, FRFSet, UFFError, read_coherence, read_uff, write_frfs

OUTPUTS = [(1, 3), (2, 3), (1003, 1)]
INPUTS = [(1, 3), (2, -3)]


def _case(freq=None, seed=0):
    freq = np.arange(1.0, 101.0) * 0.5 if freq is None else freq
    rng = np.random.default_rng(seed)
    shape = (len(OUTPUTS), len(INPUTS), freq.size)
    H = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * 1e-3
    coh = rng.uniform(0.0, 1.0, shape)
    coh[0, 0, :3] = [0.0, 1.0, 1.0]
    return FRFSet(freq, H, OUTPUTS, INPUTS, form="mobility", units="m/s/N"), coh


@pytest.mark.parametrize("kw, rtol", [({}, 0), ({"binary": False}, 1e-10), ({"precision": "single"}, 1e-7)])
def test_round_trip_and_read_uff_passes_over_the_coherence(tmp_path, kw, rtol):
    frf, coh = _case()
    plain, with_coh = tmp_path / "plain.uff", tmp_path / "coh.uff"
    write_frfs(plain, frf, **kw)
    write_frfs(with_coh, frf, coherence=coh, **kw)
    a, b = read_uff(plain), read_uff(with_coh)
    np.testing.assert_array_equal(a.H, b.H)  # the coherence is not mistaken for FRFs
    assert b.outputs == a.outputs and b.inputs == a.inputs and b.form == "mobility"
    back = read_coherence(with_coh)
    assert back.shape == coh.shape and back.dtype == np.float64
    np.testing.assert_allclose(back, coh, rtol=rtol, atol=rtol)
    assert np.all((back >= 0) & (back <= 1))
    assert read_coherence(plain) is None


def test_pyuff_reads_the_coherence_data_sets(tmp_path):
    frf, coh = _case(freq=np.cumsum(np.full(60, np.pi / 7)) + 3.3)  # uneven axis: abscissae in the data set
    for binary in (True, False):
        path = tmp_path / f"coh_{binary}.uff"
        write_frfs(path, frf, binary=binary, coherence=coh)
        sets = pyuff.UFF(str(path)).read_sets()
        frfs = [d for d in sets if d["func_type"] == 4]
        cohs = [d for d in sets if d["func_type"] == 6]
        assert len(frfs) == len(cohs) == len(OUTPUTS) * len(INPUTS)
        for d in cohs:
            o, i = OUTPUTS.index((d["rsp_node"], d["rsp_dir"])), INPUTS.index((d["ref_node"], d["ref_dir"]))
            assert not np.iscomplexobj(d["data"]) and d["ord_data_type"] == 4
            np.testing.assert_allclose(d["data"], coh[o, i], rtol=1e-10)
            np.testing.assert_allclose(d["x"], frf.freq_hz, rtol=1e-10 if binary else 1e-5)  # ASCII x: %13.5e


def test_a_dropped_0hz_line_drops_its_coherence_too(tmp_path):
    frf, coh = _case(freq=np.arange(0.0, 100.0) * 0.5)
    H = np.array(frf.H)
    H[:, :, 0] = np.nan  # a receptance's 0 Hz line
    path = tmp_path / "dc.uff"
    write_frfs(path, FRFSet(frf.freq_hz, H, OUTPUTS, INPUTS, form="receptance"), coherence=coh)
    assert read_uff(path).n_freq == 99
    np.testing.assert_array_equal(read_coherence(path), coh[..., 1:])


def test_nonfinite_drop_cuts_the_same_lines_of_the_coherence(tmp_path):
    frf, coh = _case()
    path = tmp_path / "nan.uff"
    write_frfs(path, frf, binary=False, coherence=coh)
    # FRF data set 2: its 6th value line holds lines 10 and 11 (re, im, re, im); make their real parts NaN
    nan = "nan".rjust(20)
    _corrupt(path, 2, lambda ls: ls[:17] + [nan + ls[17][20:40] + nan + ls[17][60:]] + ls[18:])
    with pytest.warns(UserWarning, match="dropped"):
        back = read_coherence(path, nonfinite="drop")
    keep = np.ones(frf.n_freq, bool)
    keep[[10, 11]] = False
    np.testing.assert_allclose(back, coh[..., keep], rtol=1e-10)
    with pytest.warns(UserWarning, match="dropped"):
        assert read_uff(path, nonfinite="drop").n_freq == back.shape[2]


def test_bad_coherence_is_refused_when_writing(tmp_path):
    frf, coh = _case()
    path = tmp_path / "x.uff"
    for bad, needle in ((coh[:2], "shape"), (coh + 0.5, "expected a value in [0, 1]"),
                        (np.where(coh > 0.5, np.nan, coh), "expected a value in [0, 1]")):
        with pytest.raises(EMAError) as err:
            write_frfs(path, frf, coherence=bad)
        assert needle in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value)
    assert not path.exists()


def _corrupt(path, first_coh_set, edit):
    """Apply ``edit`` to the lines of data set ``first_coh_set`` (0-based) of an ASCII UFF file."""
    text = path.read_text()
    blocks = text.split("    -1\n")  # ASCII: every delimiter line is exactly this
    # block 2k+1 is data set k (blocks between the opening and closing delimiters)
    lines = blocks[2 * first_coh_set + 1].split("\n")
    blocks[2 * first_coh_set + 1] = "\n".join(edit(lines))
    path.write_text("    -1\n".join(blocks))


@pytest.mark.parametrize(
    "edit, needle, field",
    [
        # a value out of range (a scrambled digit): 0.x -> 5.x
        (lambda ls: ls[:14] + [ls[14][:2] + "5" + ls[14][3:]] + ls[15:], "outside [0, 1]", "data"),
        # a lost data line: fewer values than the header announces
        (lambda ls: ls[:14] + ls[15:], "coherence header announces 100 points", "num_pts"),
        # the record names a response without an FRF
        (lambda ls: ls[:6] + [ls[6].replace("         1   3 ", "       777   3 ", 1)] + ls[7:],
         "coherence for (777, 3) / (1, 3) but the file has no such FRF", "rsp_node"),
    ],
)
def test_a_damaged_coherence_data_set_is_refused_in_one_line(tmp_path, edit, needle, field):
    frf, coh = _case()
    coh[0, 0] = np.linspace(0.2, 0.3, frf.n_freq)  # first value line starts " 2.0..." / " 2.xxx"
    path = tmp_path / "damaged.uff"
    write_frfs(path, frf, binary=False, coherence=coh)
    n_frf = len(OUTPUTS) * len(INPUTS)
    _corrupt(path, n_frf, edit)
    for reader in (read_uff, read_coherence):
        with pytest.raises(UFFError) as err:
            reader(path)
        msg = str(err.value)
        assert "\n" not in msg and str(path) in msg and f"data set {n_frf}" in msg, msg
        assert needle in msg and f"field {field!r}" in msg, msg


def test_a_file_of_coherence_only_has_no_frf(tmp_path):
    frf, coh = _case()
    path = tmp_path / "only.uff"
    write_frfs(path, frf, coherence=coh)
    sets = [d for d in pyuff.UFF(str(path)).read_sets() if d["func_type"] == 6]
    path.unlink()
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    with pytest.raises(UFFError, match="no FRF in file \\(only coherence data sets\\)"):
        read_uff(path)


def test_a_binary_coherence_data_set_that_lost_bytes_is_refused(tmp_path):
    frf, coh = _case()
    path = tmp_path / "short.uff"
    write_frfs(path, frf, coherence=coh)
    raw = path.read_bytes()
    n_frf = len(OUTPUTS) * len(INPUTS)
    # the opening delimiter of the first coherence data set, then 8 bytes (one value) cut from its payload
    starts = [k for k in range(len(raw)) if raw.startswith(b"    -1\n    58b", k)]
    start = starts[n_frf]
    cut = start + raw[start:].index(b"\n", raw[start:].index(b"NONE                 NONE")) + 400
    path.write_bytes(raw[:cut] + raw[cut + 8 :])
    for reader in (read_uff, read_coherence):
        with pytest.raises(UFFError) as err:
            reader(path)
        msg = str(err.value)
        assert "\n" not in msg and str(path) in msg and f"data set {n_frf}" in msg and "damaged" in msg, msg
