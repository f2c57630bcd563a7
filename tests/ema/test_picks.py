"""Picks files: a hand selection saved, loaded back and fitted again; damaged files refused in one line."""

import json

import numpy as np
import pytest
from matplotlib.figure import Figure

import ema
from ema import EMAError, FRFSet, Picks, fit, fit_with_picks, load_picks, save_picks
from ema.picker import PolePicker
from ema.picks import FORMAT, VERSION, picks_from_picker

from .synth import modal_frfs

FN = np.array([150.0, 320.0, 470.0])
ZETA = np.array([0.01, 0.005, 0.008])
BAND = (100.0, 550.0)
ORDER = 20
KEEP = [0, 2]  # the modes picked by hand: the 320 Hz mode is left out


@pytest.fixture(scope="module")
def frf():
    rng = np.random.default_rng(3)
    phi = rng.standard_normal((4, FN.size))
    phi[0] = np.abs(phi[0]) + 0.5  # the reference sees every mode
    freq = np.linspace(0.0, 600.0, 1201)[1:]
    H = modal_frfs(freq, FN, ZETA, phi, phi[:1])
    H = H + 0.005 * np.abs(H) * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    return FRFSet(freq, H, tuple((k + 1, 3) for k in range(4)), ((1, 3),))


@pytest.fixture(scope="module")
def auto(frf):
    return fit(frf, BAND, max_order=ORDER)


def _top_order_picks(diagram, freqs):
    top = max(diagram.orders)
    cand = np.flatnonzero(diagram.order == top)
    out = []
    for f in freqs:
        k = cand[np.argmin(np.abs(diagram.frequencies_hz[cand] - f))]
        out.append((int(diagram.order[k]), float(diagram.frequencies_hz[k])))
    return tuple(out)


@pytest.fixture(scope="module")
def picks(auto):
    return Picks(file="blades/blade_03.uff", method="lsrf", band_hz=BAND, max_order=ORDER,
                 picks=_top_order_picks(auto.diagram, FN[KEEP]), note="320 Hz left out")


def _doc(picks):
    return picks.as_dict()


# ------------------------------------------------------------------------------------------------ round trip
def test_exported_from_ema():
    for name in ("Picks", "save_picks", "load_picks", "fit_with_picks"):
        assert name in ema.__all__ and getattr(ema, name) is getattr(ema.picks, name)
    assert ema.__all__ == sorted(ema.__all__)


def test_save_load_round_trip(picks, tmp_path):
    path = save_picks(tmp_path / "picks" / "blade_03.json", picks)
    assert path == tmp_path / "picks" / "blade_03.json"
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["format"] == FORMAT == "bladetwin-picks" and doc["version"] == VERSION == 1
    assert doc["picks"][0] == {"order": picks.picks[0][0], "frequency_hz": picks.picks[0][1]}
    loaded = load_picks(path)
    assert loaded == picks
    assert loaded.picks == picks.picks  # floats exactly, through JSON
    assert [p.name for p in path.parent.iterdir()] == ["blade_03.json"]  # no temporary file left


def test_optional_fields_default(picks, tmp_path):
    doc = _doc(picks)
    del doc["n_bands"], doc["note"]
    doc["band_hz"] = None
    path = tmp_path / "p.json"
    path.write_text(json.dumps(doc))
    loaded = load_picks(path)
    assert loaded.n_bands == 1 and loaded.note == "" and loaded.band_hz is None


def test_fit_with_picks_gives_exactly_the_picked_modes(frf, auto, picks, tmp_path):
    result = fit_with_picks(frf, load_picks(save_picks(tmp_path / "p.json", picks)))
    got = np.sort(result.model.frequencies_hz)
    assert got.size == len(KEEP)
    np.testing.assert_allclose(got, FN[KEEP], rtol=1e-3)
    assert result.selection.how == "picks"
    # the automatic fit finds all three modes: the picks really replaced the selection
    ref = np.sort(auto.model.frequencies_hz)
    assert ref.size == FN.size
    np.testing.assert_allclose(ref, FN, rtol=1e-3)
    assert not np.any(np.abs(got / FN[1] - 1) < 0.01)


def test_picks_from_picker(auto, frf):
    diagram = auto.diagram
    initial = _top_order_picks(diagram, FN[KEEP])
    picker = PolePicker(diagram, frf, initial=initial, fig=Figure())
    p = picks_from_picker(picker, "blade_03.uff", "lsrf", BAND, ORDER, note="by hand")
    assert p.picks == tuple(sorted(initial, key=lambda t: t[1]))
    assert (p.file, p.method, p.band_hz, p.max_order, p.n_bands, p.note) == (
        "blade_03.uff", "lsrf", BAND, ORDER, 1, "by hand")


# ------------------------------------------------------------------------------------------------ fitting errors
def test_pick_of_an_order_not_computed(frf, picks):
    bad = Picks(picks.file, picks.method, picks.band_hz, picks.max_order, ((ORDER + 5, 150.0),))
    with pytest.raises(EMAError) as err:
        fit_with_picks(frf, bad)
    msg = str(err.value)
    assert f"pick ({ORDER + 5}, 150 Hz)" in msg and "blade_03.uff" in msg and "\n" not in msg


def test_pick_far_from_every_pole(frf, auto, picks):
    d = auto.diagram
    top = max(d.orders)
    poles = d.frequencies_hz[d.order == top]
    grid = np.linspace(BAND[0] + 5, BAND[1] - 5, 500)
    far = grid[np.argmax([np.min(np.abs(poles - f)) / f for f in grid])]
    assert np.min(np.abs(poles - far)) > 0.01 * far  # a frequency with no pole of that order within 1 %
    bad = Picks(picks.file, picks.method, picks.band_hz, picks.max_order, (picks.picks[0], (top, float(far))))
    with pytest.raises(EMAError) as err:
        fit_with_picks(frf, bad)
    msg = str(err.value)
    assert f"pick ({top}, {far:.6g} Hz)" in msg and "\n" not in msg


def test_two_picks_of_one_pole(frf, picks):
    order, f = picks.picks[0]
    bad = Picks(picks.file, picks.method, picks.band_hz, picks.max_order, ((order, f), (order, f * 1.0001)))
    with pytest.raises(EMAError, match="same pole"):
        fit_with_picks(frf, bad)


# ------------------------------------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"method": "ssi"}, "method"),
        ({"band_hz": (500.0, 100.0)}, "band_hz"),
        ({"band_hz": (-1.0, 100.0)}, "band_hz"),
        ({"band_hz": (100.0,)}, "band_hz"),
        ({"max_order": 1}, "max_order"),
        ({"max_order": 20.0}, "max_order"),
        ({"picks": ()}, "picks"),
        ({"picks": ((0, 150.0),)}, "picks[0].order"),
        ({"picks": ((True, 150.0),)}, "picks[0].order"),
        ({"picks": ((20, float("nan")),)}, "picks[0].frequencies_hz"),
        ({"picks": ((20, -150.0),)}, "picks[0].frequencies_hz"),
        ({"picks": ((20, 50.0),)}, "picks[0]"),  # outside the band
        ({"picks": ((20, 150.0), (20, 150.0))}, "picks[1]"),
        ({"n_bands": 0}, "n_bands"),
        ({"file": ""}, "file"),
    ],
)
def test_picks_validation(picks, change, field):
    kwargs = {name: getattr(picks, name) for name in ("file", "method", "band_hz", "max_order", "picks")}
    kwargs.update(change)
    with pytest.raises(EMAError) as err:
        Picks(**kwargs)
    assert str(err.value).startswith(field) and "\n" not in str(err.value)


# ------------------------------------------------------------------------------------------------ damaged files
def _set(key, value):
    def edit(doc):
        doc[key] = value
        return json.dumps(doc)
    return edit


def _drop(key):
    def edit(doc):
        del doc[key]
        return json.dumps(doc)
    return edit


def _pick0(key, value):
    def edit(doc):
        if value is _drop:
            del doc["picks"][0][key]
        else:
            doc["picks"][0][key] = value
        return json.dumps(doc)
    return edit


DAMAGED = {
    "empty": (lambda doc: "", "empty"),
    "not-json": (lambda doc: "order 20 at 150 Hz", "not JSON"),
    "truncated": (lambda doc: json.dumps(doc)[:-20], "not JSON"),
    "list": (lambda doc: json.dumps([doc]), "JSON object"),
    "deep": (lambda doc: "[" * 100000 + "]" * 100000, "not a picks file"),
    "no-format": (_drop("format"), "format"),
    "format": (_set("format", "bladetwin-modes"), "format"),
    "no-version": (_drop("version"), "version"),
    "version-2": (_set("version", 2), "version"),
    "version-str": (_set("version", "1"), "version"),
    "unknown-field": (_set("nbands", 2), "nbands"),
    "no-file": (_drop("file"), "file"),
    "no-picks": (_drop("picks"), "picks"),
    "file-number": (_set("file", 3), "file"),
    "method": (_set("method", "fft"), "method"),
    "method-null": (_set("method", None), "method"),
    "band-reversed": (_set("band_hz", [550.0, 100.0]), "band_hz"),
    "band-one": (_set("band_hz", [100.0]), "band_hz"),
    "band-str": (_set("band_hz", "100-550"), "band_hz"),
    "band-text": (_set("band_hz", ["100", 550]), "band_hz"),
    "max-order-str": (_set("max_order", "20"), "max_order"),
    "max-order-float": (_set("max_order", 20.5), "max_order"),
    "max-order-1": (_set("max_order", 1), "max_order"),
    "n-bands-0": (_set("n_bands", 0), "n_bands"),
    "note-number": (_set("note", 5), "note"),
    "picks-empty": (_set("picks", []), "picks"),
    "picks-object": (_set("picks", {"order": 20}), "picks"),
    "pick-pair": (_set("picks", [[20, 150.0]]), "picks[0]"),
    "pick-no-frequency": (_pick0("frequency_hz", _drop), "picks[0]"),
    "pick-extra-key": (_pick0("stable", True), "picks[0]"),
    "pick-order-0": (_pick0("order", 0), "picks[0].order"),
    "pick-order-float": (_pick0("order", 20.0), "picks[0].order"),
    "pick-order-bool": (_pick0("order", True), "picks[0].order"),
    "pick-frequency-str": (_pick0("frequency_hz", "150"), "picks[0].frequencies_hz"),
    "pick-frequency-neg": (_pick0("frequency_hz", -150.0), "picks[0].frequencies_hz"),
    "pick-frequency-out-of-band": (_pick0("frequency_hz", 900.0), "picks[0]"),
    "pick-nan": (lambda doc: json.dumps(doc).replace(str(doc["picks"][0]["frequency_hz"]), "NaN"),
                 "picks[0].frequencies_hz"),
    "pick-inf": (lambda doc: json.dumps(doc).replace(str(doc["picks"][0]["frequency_hz"]), "1e999"),
                 "picks[0].frequencies_hz"),
}


@pytest.mark.parametrize("case", list(DAMAGED))
def test_damaged_file_is_refused_in_one_line(picks, tmp_path, case):
    damage, field = DAMAGED[case]
    path = tmp_path / f"{case}.json"
    path.write_text(damage(_doc(picks)), encoding="utf-8")
    with pytest.raises(EMAError) as err:
        load_picks(path)
    msg = str(err.value)
    assert msg.startswith(str(path) + ": ") and "\n" not in msg
    assert field in msg


@pytest.mark.parametrize("case", ["missing", "folder", "binary"])
def test_unreadable_file_is_refused_in_one_line(tmp_path, case):
    path = tmp_path / "picks.json"
    if case == "folder":
        path.mkdir()
    elif case == "binary":
        path.write_bytes(b"\xff\xfe\x00\x81" * 10)
    with pytest.raises(EMAError) as err:
        load_picks(path)
    msg = str(err.value)
    assert msg.startswith(str(path) + ": ") and "\n" not in msg


def test_save_onto_a_folder_is_refused(picks, tmp_path):
    with pytest.raises(EMAError) as err:
        save_picks(tmp_path, picks)
    assert str(tmp_path) in str(err.value) and "\n" not in str(err.value)


def test_picks_of_one_band_with_the_automatic_fit_elsewhere(frf):
    """Picks covering one band (a mode family of a full assembly) and ``elsewhere``: the modes outside the band
    come from the automatic fit, the ones inside from the picks, all against the truth."""
    band = (400.0, 550.0)
    zoom = fit(frf, band, max_order=ORDER)
    one = Picks(file="assembly.uff", method="lsrf", band_hz=band, max_order=ORDER,
                picks=_top_order_picks(zoom.diagram, FN[2:]))
    alone = fit_with_picks(frf, one)
    assert np.allclose(alone.model.frequencies_hz, FN[2:], rtol=2e-3)
    both = fit_with_picks(frf, one, elsewhere={"max_order": ORDER})
    assert np.allclose(np.sort(both.model.frequencies_hz), FN, rtol=2e-3), both.model.frequencies_hz
    # the picked mode is the one of the picks' fit, with its standard deviation; the others the automatic fit's
    k = int(np.argmin(np.abs(both.model.frequencies_hz - FN[2])))
    assert np.isclose(both.model.frequencies_hz[k], alone.model.frequencies_hz[0], rtol=1e-12)
    assert both.model.frequency_std_hz[k] == alone.model.frequency_std_hz[0]
    assert both.quality.shape == (frf.n_outputs, frf.n_inputs) and np.all(both.quality > 0.9)
    # picks that cover every line are the whole answer, with or without elsewhere
    full = Picks(file="assembly.uff", method="lsrf", band_hz=None, max_order=ORDER,
                 picks=_top_order_picks(fit(frf, max_order=ORDER).diagram, FN[KEEP]))
    assert fit_with_picks(frf, full, elsewhere={"max_order": ORDER}).model.n_modes == len(KEEP)
