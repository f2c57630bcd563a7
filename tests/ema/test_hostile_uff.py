"""Hostile inputs to the EMA front end (issue 8, items 2-6): damaged UFF files, unit mixes, NaN blocks, extreme
scales, FRFs without signal, absurd model orders, and paths that are no UFF file.

Every refusal is checked at library level and through the command line, where it must be one line on stderr,
naming the file, with exit code 2. Extreme scales must not be refused: they must give the same modes.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from bladetwin.cli import main
from ema import EMAError, FitSettings, FRFSet, UFFError, fit, merge_frfsets, read_frfs, read_uff, write_frfs
from ema.lscf import lscf
from ema.lscf import max_supported_order as lscf_max_order
from ema.lsrf import lsrf
from ema.lsrf import max_supported_order as lsrf_max_order
from ema.poles import check_workspace

from .synth import modal_frfs

FN = np.array([60.0, 140.0, 250.0, 380.0])
ZETA = np.array([0.01, 0.005, 0.01, 0.008])
FREQ = np.linspace(0.0, 500.0, 1001)[1:]  # 0.5 Hz lines, 0 Hz left out


def _case(n_o: int = 4, n_i: int = 1, noise: float = 1e-3, seed: int = 5) -> np.ndarray:
    """FRFs (n_o, n_i, n_f) of four modes on FREQ, references at the first n_i outputs, proportional noise."""
    rng = np.random.default_rng(seed)
    phi = rng.standard_normal((n_o, FN.size))
    phi[:n_i] = np.abs(phi[:n_i]) + 0.5  # the references excite every mode
    H = modal_frfs(FREQ, FN, ZETA, phi, phi[:n_i])
    return H + noise * np.abs(H) * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)


def _outputs(n: int) -> list[tuple[int, int]]:
    return [(k + 1, 3) for k in range(n)]


def _write(path, H, binary=True, units="m/N", inputs=None, freq=FREQ):
    inputs = inputs or [(k + 1, 3) for k in range(H.shape[1])]
    write_frfs(path, FRFSet(freq, H, _outputs(H.shape[0]), inputs, units=units), binary=binary)
    return path


def _one_line(text: str) -> None:
    assert text.endswith("\n") and text.count("\n") == 1, f"not one line: {text!r}"


def _cli_error(capsys, argv, *needles) -> str:
    """Run the CLI, expect exit code 2 and exactly one line on stderr that contains every needle."""
    rc = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert rc == 2, captured
    _one_line(captured.err)
    for needle in needles:
        assert str(needle) in captured.err, (needle, captured.err)
    return captured.err


def _cli_modes(capsys, argv) -> np.ndarray:
    """Run ``ema fit --json``, expect success, return the identified frequencies (Hz)."""
    rc = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    return np.array([m["frequency_hz"] for m in json.loads(captured.out)["modes"]])


def _assert_modes(found: np.ndarray, rtol: float = 1e-3) -> None:
    assert found.size == FN.size, found
    np.testing.assert_allclose(np.sort(found), FN, rtol=rtol)


def _fit_cli(*paths, extra=()):
    return ["ema", "fit", *paths, "--auto", "--json", *extra]


# ------------------------------------------------------------------------------------ truncated files
def _delimiter_lines(raw: bytes) -> list[int]:
    """Offsets of the '    -1' delimiters (at a line end or end of file) of a file written by write_frfs."""
    out, pos = [], raw.find(b"    -1")
    while pos != -1:
        end = pos + 6
        if end == len(raw) or raw[end] in (10, 13):
            out.append(pos)
        pos = raw.find(b"    -1", pos + 1)
    return out


def _damage(raw: bytes, how: str) -> bytes:
    last = _delimiter_lines(raw)[-1]
    if how == "cut at 50 %":
        return raw[: len(raw) // 2]
    if how == "cut at 90 %":
        return raw[: int(0.9 * len(raw))]
    if how == "no final -1":
        return raw[:last]
    if how == "cut inside the last data":
        return raw[: last - 30]
    raise AssertionError(how)


DAMAGES = ["cut at 50 %", "cut at 90 %", "no final -1", "cut inside the last data"]


@pytest.mark.parametrize("binary", [True, False], ids=["58b", "58"])
@pytest.mark.parametrize("how", DAMAGES)
def test_truncated_file_is_refused(tmp_path, binary, how):
    # three data sets: 50 % and 90 % of the file fall inside one (a cut exactly between two data sets
    # leaves a valid, shorter UFF file that nothing can tell from a whole one)
    whole = _write(tmp_path / "whole.uff", _case(n_o=3), binary=binary)
    assert read_uff(whole).n_outputs == 3
    cut = tmp_path / "cut.uff"
    cut.write_bytes(_damage(whole.read_bytes(), how))
    with pytest.raises(UFFError) as err:
        read_uff(cut)
    msg = str(err.value)
    assert "\n" not in msg and str(cut) in msg and "truncated" in msg and "no closing '-1'" in msg
    assert err.value.dataset == (1 if how == "cut at 50 %" else 2)
    assert f"data set {err.value.dataset}" in msg


@pytest.mark.parametrize("how", ["cut at 50 %", "no final -1", "cut inside the last data"])
def test_truncated_file_is_refused_by_the_cli(tmp_path, capsys, how):
    whole = _write(tmp_path / "whole.uff", _case(n_o=3))
    cut = tmp_path / "cut.uff"
    cut.write_bytes(_damage(whole.read_bytes(), how))
    _cli_error(capsys, _fit_cli(cut), cut, "truncated")


def test_short_binary_data_set_is_refused(tmp_path):
    path = _write(tmp_path / "short.uff", _case(n_o=3))
    raw = path.read_bytes()
    # drop one complex value (16 bytes) from the middle of data set 1's payload; its delimiters stay
    header = raw.find(b"    58b", raw.find(b"    58b") + 1)
    payload = header
    for _ in range(12):
        payload = raw.index(b"\n", payload) + 1
    path.write_bytes(raw[: payload + 800] + raw[payload + 816 :])
    with pytest.raises(UFFError) as err:
        read_uff(path)
    msg = str(err.value)
    assert err.value.dataset == 1 and err.value.field == "num_pts" and "\n" not in msg
    assert f"{FREQ.size} points ({16 * FREQ.size} data bytes)" in msg and f"holds {16 * FREQ.size - 16} bytes" in msg


def test_short_ascii_data_set_is_refused(tmp_path):
    path = _write(tmp_path / "short.uff", _case(n_o=3), binary=False)
    lines = path.read_bytes().split(b"\n")
    second = [k for k, line in enumerate(lines) if line.rstrip() == b"    58"][1]
    del lines[second + 20]  # one data line (two complex values) of data set 1
    path.write_bytes(b"\n".join(lines))
    with pytest.raises(UFFError) as err:
        read_uff(path)
    assert err.value.dataset == 1 and err.value.field == "num_pts" and "short or damaged" in str(err.value)


def test_binary_line_break_before_closing_delimiter_is_read(tmp_path):
    # a common exporter habit (pyuff.fix_58b exists for it): "<payload>\n    -1" instead of "<payload>    -1"
    H = _case(n_o=2)
    path = _write(tmp_path / "crlf.uff", H)
    raw = path.read_bytes()
    raw = raw.replace(b"    -1\n    -1\n", b"\n    -1\n    -1\n")
    assert raw.endswith(b"    -1\n")
    path.write_bytes(raw[:-7] + b"\r\n    -1\n")
    np.testing.assert_array_equal(read_uff(path).H, H)


def test_real_files_are_not_taken_for_damaged_ones(pyuff_dir):
    """The vendor files (ASCII, binary 4- and 8-byte, CR/LF) pass the structure checks; see test_uff for the rest."""
    for path in sorted(pyuff_dir.glob("*.uff")):
        try:
            read_uff(path)
        except UFFError as err:
            assert "truncated" not in str(err) and "damaged" not in str(err), str(err)


# ------------------------------------------------------------------------------ paths that are no UFF
def test_directory_garbage_and_empty_files_are_refused(tmp_path, capsys):
    with pytest.raises(UFFError, match="is a directory") as err:
        read_uff(tmp_path)
    assert str(tmp_path) in str(err.value)
    _cli_error(capsys, _fit_cli(tmp_path), tmp_path, "directory")

    binary = tmp_path / "noise.uff"
    binary.write_bytes(np.random.default_rng(0).bytes(5000))
    text = tmp_path / "text.uff"
    text.write_text("this is not a universal file\n" * 10)
    empty = tmp_path / "empty.uff"
    empty.write_bytes(b"")
    for path in (binary, text, empty):
        with pytest.raises(UFFError) as err:
            read_uff(path)
        assert "\n" not in str(err.value) and str(path) in str(err.value)
        _cli_error(capsys, _fit_cli(path), path)


# ---------------------------------------------------------------------------------------------- units
def _roving_hammer(tmp_path, units_b: str, factor_b: float):
    """Two files of one roving-hammer test (inputs 1 and 2); file b in ``units_b``, values times ``factor_b``."""
    H = _case(n_o=4, n_i=2)
    a = _write(tmp_path / "a.uff", H[:, :1], units="m/N", inputs=[(1, 3)])
    b = _write(tmp_path / "b.uff", H[:, 1:] * factor_b, units=units_b, inputs=[(2, 3)])
    return H, a, b


def test_merge_converts_convertible_units(tmp_path):
    H, a, b = _roving_hammer(tmp_path, "mm/N", 1e3)
    merged = read_frfs([a, b])
    assert merged.units == "m/N"
    np.testing.assert_allclose(merged.H, H, rtol=1e-14)
    # the other way round everything is in mm/N
    back = read_frfs([b, a])
    assert back.units == "mm/N" and back.inputs == ((2, 3), (1, 3))
    np.testing.assert_allclose(back.H[:, 1], H[:, 0] * 1e3, rtol=1e-14)
    # g (standard gravity) against m/s^2, in memory
    acc = [FRFSet(FREQ, H[:, k : k + 1], _outputs(4), [(k + 1, 3)], form="accelerance", units=u, sources=(f"{k}",))
           for k, u in enumerate(("m/s^2/N", "g/N"))]
    np.testing.assert_allclose(merge_frfsets(acc).H[:, 1], H[:, 1] * 9.80665, rtol=1e-14)


def test_merge_refuses_units_it_cannot_reconcile(tmp_path):
    _, a, b = _roving_hammer(tmp_path, "V/N", 1.0)
    with pytest.raises(EMAError) as err:
        read_frfs([a, b])
    msg = str(err.value)
    assert str(a) in msg and str(b) in msg and "'V/N'" in msg and "\n" not in msg
    H = _case(n_o=2, n_i=2)
    known = FRFSet(FREQ, H[:, :1], _outputs(2), [(1, 3)], units="m/N", sources=("known.uff",))
    unknown = FRFSet(FREQ, H[:, 1:], _outputs(2), [(2, 3)], units="", sources=("unlabelled.uff",))
    with pytest.raises(EMAError, match="unlabelled.uff.*known.uff.*does not state its units"):
        merge_frfsets([known, unknown])


def test_unit_mix_through_the_cli(tmp_path, capsys):
    H, a, b = _roving_hammer(tmp_path, "V/N", 1.0)
    _cli_error(capsys, _fit_cli(a, b), a, b, "V/N")
    mm = _write(tmp_path / "mm.uff", H[:, 1:] * 1e3, units="mm/N", inputs=[(2, 3)])
    same = _write(tmp_path / "same.uff", H[:, 1:], units="m/N", inputs=[(2, 3)])
    converted = _cli_modes(capsys, _fit_cli(a, mm))
    _assert_modes(converted)
    np.testing.assert_allclose(converted, _cli_modes(capsys, _fit_cli(a, same)), rtol=1e-8)


# ------------------------------------------------------------------------------------------- NaN lines
def _poke(path, dataset: int, points, value: float, binary: bool) -> None:
    """Overwrite the real part of some points of a data set, in place, as another tool would have written it.

    (write_frfs refuses non-finite values, and pyuff's writer would turn them into 0.)
    """
    raw = path.read_bytes()
    if binary:
        pos = -1
        for _ in range(dataset + 1):
            pos = raw.index(b"    58b", pos + 1)
        for _ in range(12):  # the 58b line and 11 more header lines, then the interleaved (re, im) doubles
            pos = raw.index(b"\n", pos) + 1
        data = bytearray(raw)
        for k in points:
            data[pos + 16 * k : pos + 16 * k + 8] = np.array([value], dtype="<f8").tobytes()
        path.write_bytes(bytes(data))
        return
    lines = raw.split(b"\n")
    first = [k for k, line in enumerate(lines) if line.rstrip() == b"    58"][dataset] + 12
    for k in points:  # four 20-character fields per line: (re, im) of two points
        row, col = first + k // 2, 40 * (k % 2)
        lines[row] = lines[row][:col] + b"%20.11e" % value + lines[row][col + 20 :]
    path.write_bytes(b"\n".join(lines))


@pytest.mark.parametrize("binary", [True, False], ids=["58b", "58"])
def test_nan_block_is_refused_with_its_lines(tmp_path, binary):
    path = _write(tmp_path / "nan.uff", _case(n_o=3), binary=binary)
    _poke(path, 1, range(100), np.nan, binary)
    with pytest.raises(UFFError) as err:
        read_uff(path)
    msg = str(err.value)
    assert err.value.dataset == 1 and err.value.field == "data" and "\n" not in msg and str(path) in msg
    assert f"100 lines, {FREQ[0]:.6g}-{FREQ[99]:.6g} Hz" in msg


def test_nan_repair_is_opt_in_and_warns(tmp_path):
    path = _write(tmp_path / "nan.uff", _case(n_o=3))
    _poke(path, 1, range(100), np.nan, True)
    _poke(path, 2, [500], np.inf, True)
    with pytest.warns(UserWarning, match=r"dropped 101 lines, 0.5-50 Hz, 250.5 Hz .*data sets 1, 2"):
        frf = read_uff(path, nonfinite="drop")
    assert frf.n_freq == FREQ.size - 101 and np.all(np.isfinite(frf.H))


def test_nan_in_memory_is_refused_by_the_estimators_and_the_writer(tmp_path):
    H = _case(n_o=3)
    H[1, 0, 200:300] = np.nan
    frf = FRFSet(FREQ, H, _outputs(3), [(1, 3)], sources=("bench.uff",))
    for run in (lambda: lscf(frf, max_order=10), lambda: lsrf(frf, max_order=10), lambda: fit(frf, max_order=10)):
        with pytest.raises(EMAError) as err:
            run()
        msg = str(err.value)
        assert "bench.uff" in msg and "(2, 3) / (1, 3)" in msg and "100 lines, 100.5-150 Hz" in msg
    # a band that leaves the block out is fine
    assert lscf(frf, band=(160.0, 480.0), max_order=10).pole.size
    # pyuff would write zeros in place of the NaN: refused
    with pytest.raises(EMAError, match="cannot write FRF .2, 3. / .1, 3.: non-finite values on 100 lines"):
        write_frfs(tmp_path / "out.uff", frf)
    assert not (tmp_path / "out.uff").exists()


def test_nan_at_0_hz_is_left_out_not_refused(tmp_path):
    freq = np.concatenate([[0.0], FREQ])
    H = np.concatenate([np.full((4, 1, 1), np.nan + 0j), _case()], axis=2)
    frf = FRFSet(freq, H, _outputs(4), [(1, 3)])
    _assert_modes(fit(frf, settings=FitSettings(method="lscf"), max_order=40).model.frequencies_hz)
    path = _write(tmp_path / "dc.uff", H, freq=freq)
    back = read_uff(path)
    np.testing.assert_array_equal(back.freq_hz, FREQ)
    np.testing.assert_array_equal(back.H, H[:, :, 1:])


def test_nan_block_through_the_cli(tmp_path, capsys):
    path = _write(tmp_path / "nan.uff", _case(n_o=3))
    _poke(path, 0, range(100), np.nan, True)
    _cli_error(capsys, _fit_cli(path), path, "data set 0", "non-finite", "0.5-50 Hz")
    # The opt-in repair: the lines go, a warning names them, and the modes above them are still found.
    with pytest.warns(UserWarning, match=r"dropped 100 lines, 0.5-50 Hz"):
        assert main([str(a) for a in _fit_cli(path, extra=("--nonfinite", "drop"))]) == 0
    _assert_modes(np.array([m["frequency_hz"] for m in json.loads(capsys.readouterr().out)["modes"]]))


# --------------------------------------------------------------------------------------- extreme scales
SCALES = (1e-156, 1.0, 1e144)


def _physical(poles) -> np.ndarray:
    """Poles within 0.1 % in frequency and 10 % in damping of a true mode."""
    f, z = poles.frequencies_hz, poles.damping_ratio
    k = np.argmin(np.abs(f[:, None] - FN[None, :]), axis=1)
    return (np.abs(f - FN[k]) <= 1e-3 * FN[k]) & (np.abs(z - ZETA[k]) <= 0.1 * ZETA[k])


@pytest.mark.parametrize("estimate", [
    lambda frf: lscf(frf, max_order=40),
    lambda frf: lscf(frf, max_order=30, normalize=False),
    lambda frf: lsrf(frf, max_order=40),
    lambda frf: lsrf(frf, max_order=30, coefficients="complex"),
], ids=["lscf", "lscf-unnormalized", "lsrf-real", "lsrf-complex"])
def test_poles_do_not_depend_on_the_unit_scale(estimate):
    H = _case()
    sets = [estimate(FRFSet(FREQ, H * s, _outputs(4), [(1, 3)])) for s in SCALES]
    ref = sets[1]
    keep = _physical(ref)
    assert keep.sum() >= 30  # every mode found at many orders
    assert set(np.argmin(np.abs(ref.frequencies_hz[keep, None] - FN), axis=1)) == set(range(FN.size))
    for other in (sets[0], sets[2]):
        assert other.pole.size == ref.pole.size
        np.testing.assert_array_equal(other.order, ref.order)
        np.testing.assert_array_equal(_physical(other), keep)
        np.testing.assert_allclose(other.pole[keep], ref.pole[keep], rtol=1e-8)
        assert np.all(np.isfinite(other.vector)) and np.all(np.abs(other.vector) <= 1.0 + 1e-12)


@pytest.mark.parametrize("method", ["lscf", "lsrf"])
def test_fit_does_not_depend_on_the_unit_scale(method):
    H = _case()
    results = [fit(FRFSet(FREQ, H * s, _outputs(4), [(1, 3)]), settings=FitSettings(method=method), max_order=40)
               for s in SCALES]
    ref = results[1].model
    _assert_modes(ref.frequencies_hz)
    for s, res in zip(SCALES, results, strict=True):
        m = res.model
        np.testing.assert_allclose(m.frequencies_hz, ref.frequencies_hz, rtol=1e-8)
        np.testing.assert_allclose(m.damping_ratio, ref.damping_ratio, rtol=1e-6)
        # residues scale with the data; shapes (mass-normalised, driving point) with its square root
        np.testing.assert_allclose(m.residues / s, ref.residues, rtol=1e-6, atol=1e-9 * np.abs(ref.residues).max())
        np.testing.assert_allclose(res.quality, results[1].quality, atol=1e-9)


@pytest.mark.parametrize("scale", [1e-156, 1e144])
def test_extreme_scales_through_the_cli(tmp_path, capsys, scale):
    path = _write(tmp_path / "scaled.uff", _case() * scale)
    _assert_modes(_cli_modes(capsys, _fit_cli(path)))


def test_values_below_the_normal_range_are_refused():
    frf = FRFSet(FREQ, _case() * 1e-310, _outputs(4), [(1, 3)], sources=("subnormal.uff",))
    with pytest.raises(EMAError, match="subnormal.uff.*below the normal float64 range"):
        lscf(frf, max_order=10)


# ------------------------------------------------------------------------------------- FRFs without signal
@pytest.mark.parametrize("what, value", [("zero", 0.0), ("constant", 2.5 - 1j)])
def test_frf_without_signal_is_refused(tmp_path, capsys, what, value):
    H = _case(n_o=3)
    H[2, 0] = value
    path = _write(tmp_path / f"{what}.uff", H)
    with pytest.raises(UFFError) as err:
        read_uff(path)
    assert err.value.dataset == 2 and err.value.field == "data" and what in str(err.value)
    _cli_error(capsys, _fit_cli(path), path, "data set 2", what, "no signal")
    frf = FRFSet(FREQ, H, _outputs(3), [(1, 3)], sources=("memory.uff",))
    for run in (lambda: lscf(frf, max_order=10), lambda: lsrf(frf, max_order=10)):
        with pytest.raises(EMAError, match=f"memory.uff: FRF \\(3, 3\\) / \\(1, 3\\) is {what}"):
            run()


# ------------------------------------------------------------------------------------------ model order
def test_absurd_order_through_the_cli(tmp_path, capsys):
    path = _write(tmp_path / "order.uff", _case(n_o=3))
    # Refused before anything large is built (a MemoryError or a hang otherwise); the default is complex LSRF.
    top = lscf_max_order(FREQ.size, 3, 1)
    _cli_error(capsys, [*_fit_cli(path), "--method", "lscf", "--order", "100000"], path, "model order 100000",
               f"maximum {top}")
    top = lsrf_max_order(FREQ.size, 3, real=False)
    _cli_error(capsys, [*_fit_cli(path), "--order", "100000"], path, "model order 100000", f"maximum {top}")


def test_order_bound_is_the_least_squares_size():
    rng = np.random.default_rng(1)
    freq = np.arange(1.0, 11.0)
    H = rng.standard_normal((2, 1, 10)) + 1j * rng.standard_normal((2, 1, 10))
    frf = FRFSet(freq, H, _outputs(2), [(1, 3)], sources=("tiny.uff",))
    # LSCF: (p+1) n_o n_i + p n_i^2 <= 2 n_f n_o n_i  ->  p <= 2 * 19 // 3 = 12
    assert lscf_max_order(10, 2, 1) == 12
    lscf(frf, orders=[12])
    with pytest.raises(EMAError, match="tiny.uff: LSCF on 10 lines x 2 outputs x 1 inputs"):
        lscf(frf, orders=[13])
    # LSRF real: n_frf (n+1) + n <= 2 n_f n_frf; complex: n_frf (n+1) + n <= n_f n_frf
    assert (lsrf_max_order(10, 2, True), lsrf_max_order(10, 2, False)) == (12, 6)
    lsrf(frf, orders=[12])
    lsrf(frf, orders=[6], coefficients="complex")
    with pytest.raises(EMAError, match="model order 13 is above the maximum 12"):
        lsrf(frf, max_order=13)
    with pytest.raises(EMAError, match="model order 7 is above the maximum 6"):
        lsrf(frf, max_order=7, coefficients="complex")
    # huge requests fail at once, without listing the orders
    for run in (lambda: lscf(frf, max_order=10**15), lambda: lsrf(frf, orders=range(1, 10**15))):
        with pytest.raises(EMAError, match="maximum 12"):
            run()
    with pytest.raises(EMAError, match="expected an integer"):
        lscf(frf, max_order=4.5)


@pytest.mark.skipif(not hasattr(os, "sysconf"), reason="physical memory size needs POSIX sysconf")
def test_order_the_memory_cannot_hold_is_refused_before_allocating():
    freq = np.arange(1.0, 1_000_001.0)
    frf = FRFSet(freq, np.exp(1j * freq / 7.0)[None, None] * (1 + freq / 1e5), [(1, 3)], [(1, 3)])
    for run in (lambda: lscf(frf, orders=[900_000]), lambda: lsrf(frf, orders=[900_000])):
        with pytest.raises(EMAError, match="order 900000 .* GiB of memory"):
            run()
    with pytest.raises(EMAError, match="lower the model order"):
        check_workspace(1e30, "test")
    check_workspace(1.0, "test")


@pytest.mark.parametrize("label", ["p0", ("a", 3), (1, None)])
def test_a_dof_label_that_is_not_two_integers_is_named(label):
    freq = np.linspace(1.0, 10.0, 10)
    with pytest.raises(ValueError, match=r"output DOF .*expected \(node_id, direction\)"):
        FRFSet(freq, np.ones((1, 1, 10), complex), [label], [(1, 3)])
