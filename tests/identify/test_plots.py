"""Identification plots (Agg): axes and artists per figure, the one pattern orientation, one-line input errors."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from matplotlib.collections import QuadMesh
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.patches import Rectangle

from identify.errors import IdentifyError
from identify.plots import (
    plot_area_fractions,
    plot_centroids,
    plot_d1b_validation,
    plot_frequency_maps,
    plot_grid_error,
    plot_mode_comparison,
    plot_pattern,
    plot_sensitivity,
    plot_synthetic_patterns,
)
from identify.synthetic import sample_patterns
from identify.validation import compare_modes, d1b_validation, geometric_validation, grid_error

matplotlib.use("Agg")

ROWS, COLS = 3, 7


def _uv(rows: int = ROWS, cols: int = COLS) -> tuple[np.ndarray, np.ndarray]:
    """Flank coordinates (m) laid out as rom.academic.flank_coordinates: u grows with the row, v with the column."""
    u = np.repeat(np.linspace(-4.5e-3, 4.5e-3, rows)[:, None], cols, axis=1)
    v = np.repeat(np.linspace(88e-3, 100e-3, cols)[None, :], rows, axis=0)
    return u, v


def _render(fig: Figure, tmp_path, name: str) -> None:
    """Draw the figure (layout and artists run only at draw time) into a small PNG."""
    fig.savefig(tmp_path / f"{name}.png", dpi=40)


def _bars(ax) -> list[Rectangle]:
    return [p for p in ax.patches if isinstance(p, Rectangle)]


@pytest.fixture(scope="module")
def synthetic():
    rng = np.random.default_rng(0)
    known_L, known_R = rng.random((5, ROWS, COLS)), rng.random((5, ROWS, COLS))
    sp = sample_patterns(known_L, known_R, n_patterns=(4, 3), random_state=1)
    return sp, known_L > sp.threshold[0], known_R > sp.threshold[1]


@pytest.fixture(scope="module")
def geometric():
    rng = np.random.default_rng(2)
    ref = rng.random((4, 2, ROWS, COLS)) < 0.6
    pred = rng.random((4, 2, ROWS, COLS)) < 0.6
    ref[:, :, 0, 0] = pred[:, :, 0, 0] = True  # every flank has contact, so every centroid exists
    return geometric_validation(pred, ref, _uv()), ref, pred


@pytest.fixture(scope="module")
def dynamic():
    rng = np.random.default_rng(3)
    f = np.array([100.0, 210.0, 330.0, 460.0, 600.0, 750.0])
    phi = rng.standard_normal((12, f.size))
    refs, preds = [], []
    for _ in range(3):
        refs.append((f * (1 + 0.01 * rng.standard_normal(f.size)), phi))
        preds.append((f * (1 + 0.01 * rng.standard_normal(f.size)), phi + 0.2 * rng.standard_normal(phi.shape)))
    d1b = d1b_validation(refs, preds, (1, 2, 4))
    cmp = compare_modes(refs[0], preds[0])
    return d1b, cmp


# ------------------------------------------------------------------------------------------ orientation
def test_pattern_index_orientation(tmp_path):
    grid = np.zeros((ROWS, COLS), bool)
    grid[0, 0] = grid[0, 1] = grid[2, 6] = grid[1, 3] = True  # asymmetric: any flip or transpose shows
    fig = plot_pattern(grid, title="asymmetric")
    assert isinstance(fig, Figure) and len(fig.axes) == 1
    ax = fig.axes[0]
    (im,) = ax.images
    assert isinstance(im, AxesImage)
    np.testing.assert_array_equal(np.asarray(im.get_array()), grid.astype(float))
    assert im.origin == "upper"  # grid row i at image row i, counted from the top
    assert ax.get_ylim() == (ROWS - 0.5, -0.5)  # row 0 on top: the axial axis runs downwards
    assert ax.get_xlim() == (-0.5, COLS - 0.5)  # column 0 (slot bottom) on the left
    assert ax.get_xlabel() == "radial column → rim" and ax.get_ylabel() == "axial row"
    assert ax.get_aspect() == 1.0
    _render(fig, tmp_path, "pattern")


def test_pattern_physical_orientation():
    grid = np.zeros((ROWS, COLS), bool)
    grid[0, 0] = grid[2, 5] = True
    u, v = _uv()
    fig = plot_pattern(grid, coordinates=(u, v))
    ax = fig.axes[0]
    (mesh,) = [c for c in ax.collections if isinstance(c, QuadMesh)]
    np.testing.assert_array_equal(np.asarray(mesh.get_array()).reshape(ROWS, COLS), grid.astype(float))
    xy = mesh.get_coordinates()  # (rows + 1, cols + 1, 2) cell corners in mm: (v, u)
    bottom, top = ax.get_ylim()
    assert top == pytest.approx(xy[0, 0, 1]) and top < bottom  # row 0 (smallest u) on top, u grows downwards
    left, right = ax.get_xlim()
    assert left == pytest.approx(xy[0, 0, 0]) and left < right  # column 0 (slot bottom) at the left
    assert xy[0, 0, 0] < v[0, 0] * 1e3 < xy[0, 1, 0]  # node (0, 0) is the centre of cell (0, 0)
    assert xy[0, 0, 1] < u[0, 0] * 1e3 < xy[1, 0, 1]
    assert "mm" in ax.get_xlabel() and "mm" in ax.get_ylabel()
    with pytest.raises(IdentifyError, match="u must grow with the grid row"):
        plot_pattern(grid, coordinates=(u[::-1], v))
    with pytest.raises(IdentifyError, match="v must grow with the grid column"):
        plot_pattern(grid, coordinates=(u, v[:, ::-1]))


# ------------------------------------------------------------------------------------- Figs. 14–16
def test_synthetic_patterns(synthetic, tmp_path):
    sp, known_L, known_R = synthetic
    fig = plot_synthetic_patterns(sp)
    assert len(fig.axes) == 4 + 3  # one axes per pattern; the shorter R column's spare panel is removed
    by_title = {ax.get_title(): ax for ax in fig.axes}
    assert sorted(by_title) == sorted([f"L · SP-{k}" for k in range(1, 5)] + [f"R · SP-{k}" for k in range(1, 4)])
    assert by_title["R · SP-3"].get_subplotspec().colspan.start == 1  # the R column stands right of the L column
    for side, grids in (("L", sp.L), ("R", sp.R)):
        for k, grid in enumerate(grids):
            ax = by_title[f"{side} · SP-{k + 1}"]
            assert ax.get_subplotspec().rowspan.start == k
            np.testing.assert_array_equal(np.asarray(ax.images[0].get_array()), grid.astype(float))
    _render(fig, tmp_path, "synthetic")

    labels = ["BR-3", "BR-7", "BR-10", "BR-14", "BR-17"]
    fig = plot_synthetic_patterns(sp, known_L, known_R, known_labels=labels)
    assert len(fig.axes) == 5 + 4 + 5 + 3
    by_title = {ax.get_title(): ax for ax in fig.axes}
    assert [by_title[f"{s} · BR-3 (known)"].get_subplotspec().colspan.start for s in "LR"] == [0, 2]
    np.testing.assert_array_equal(np.asarray(by_title["L · BR-7 (known)"].images[0].get_array()),
                                  known_L[1].astype(float))
    _render(fig, tmp_path, "synthetic_known")

    fig = plot_synthetic_patterns(sp, gray=True)
    assert len(fig.axes) == 4 + 3 + 1  # and the colour bar
    by_title = {ax.get_title(): ax for ax in fig.axes}
    np.testing.assert_allclose(np.asarray(by_title["L · SP-1"].images[0].get_array()), sp.gray_L[0])
    _render(fig, tmp_path, "synthetic_gray")


def test_sensitivity(tmp_path):
    std_hz = np.array([0.1, 0.4, 0.2, 1.5, 2.0, 0.3, 0.9, 0.05])
    mean = np.array([195.0, 540, 742, 1115, 1157, 1338, 1992, 2579])
    # The fields of identify.sensitivity.Sensitivity
    sens = SimpleNamespace(std_hz=std_hz, std_rel_pct=std_hz / mean * 100, feature_modes=(3, 4, 6))
    fig = plot_sensitivity(sens)
    ax = fig.axes[0]
    bars = _bars(ax)
    assert len(bars) == 8
    np.testing.assert_allclose([b.get_height() for b in bars], sens.std_rel_pct)
    feature = [k for k, b in enumerate(bars) if b.get_facecolor() == bars[3].get_facecolor()]
    assert feature == [3, 4, 6]
    assert [t.get_text() for t in ax.texts][4] == "2.00 Hz"  # the other unit, annotated
    assert "4, 5, 7" in ax.get_title()  # 1-based mode numbers
    _render(fig, tmp_path, "sensitivity")
    fig = plot_sensitivity(std_hz, (4,), unit="hz")  # plain arrays
    assert len(_bars(fig.axes[0])) == 8 and "[Hz]" in fig.axes[0].get_ylabel() and not fig.axes[0].texts
    with pytest.raises(IdentifyError, match="unit"):
        plot_sensitivity(sens, unit="rad")
    with pytest.raises(IdentifyError, match="mode index 8 outside 0..7"):
        plot_sensitivity(std_hz, (8,))
    with pytest.raises(IdentifyError, match="std_hz"):
        plot_sensitivity(SimpleNamespace(std_rel_pct=std_hz), unit="hz")
    with pytest.raises(IdentifyError, match=r"sensitivity.std_hz has shape \(3,\): expected \(8\)"):
        plot_sensitivity(SimpleNamespace(std_rel_pct=std_hz, std_hz=std_hz[:3]))


def test_frequency_maps(tmp_path):
    F = 1000 + np.random.default_rng(4).random((4, 3, 6))
    fig = plot_frequency_maps(SimpleNamespace(frequencies_hz=F, feature_modes=(4, 5, 1)), labels_L=list("abcd"))
    assert len(fig.axes) == 3 + 3  # an image and a colour bar per mode
    images = [ax.images[0] for ax in fig.axes if ax.images]
    assert len(images) == 3
    # L pattern along x (image columns), R pattern along y (image rows)
    np.testing.assert_allclose(np.asarray(images[0].get_array()), F[:, :, 4].T)
    assert [ax.get_title() for ax in fig.axes if ax.images] == ["mode 5", "mode 6", "mode 2"]
    _render(fig, tmp_path, "frequency_maps")
    fig = plot_frequency_maps(F)  # plain array: every mode
    assert sum(1 for ax in fig.axes if ax.images) == 6
    with pytest.raises(IdentifyError, match="frequencies_hz has shape"):
        plot_frequency_maps(F[0])
    with pytest.raises(IdentifyError, match="labels_R holds 2 labels: expected 3"):
        plot_frequency_maps(F, labels_R=["a", "b"])


# -------------------------------------------------------------------------------------- validation
def test_grid_error(tmp_path):
    pred = [[0.010, 0.000, 0.010], [0.005, -0.005, 0.010], [0.0, 0.0, 0.0], [0.01, 0.01, 0.01]]
    ref = [[0.0112, 0.0024, 0.0126], [0.0075, -0.0050, 0.0074], [0.0, 0.001, -0.002], [0.01, 0.011, 0.012]]
    e = grid_error(pred, ref, 0.005)
    fig = plot_grid_error(e, blade_labels=["1", "5", "9", "13"])
    ax = fig.axes[0]
    bars = [b for b in _bars(ax) if b.get_width() < 0.5]  # the ±50 % band is a wide polygon, not a bar
    assert len(bars) == 4 * 3
    np.testing.assert_allclose(sorted(b.get_height() for b in bars), np.sort(e.epsilon_pct.ravel()), atol=1e-9)
    assert ax.get_title() == "step-1 grid error: 10 of 12 within ±50 %"
    assert [t.get_text() for t in ax.get_xticklabels()] == ["1", "5", "9", "13"]
    _render(fig, tmp_path, "grid_error")
    with pytest.raises(IdentifyError, match="epsilon_pct has shape"):
        plot_grid_error(SimpleNamespace(epsilon_pct=np.zeros(3)))


def test_area_fractions(geometric, tmp_path):
    geo, _, _ = geometric
    fig = plot_area_fractions(geo)
    assert len(fig.axes) == 2
    for f, ax in enumerate(fig.axes):
        heights = [b.get_height() for b in _bars(ax)]
        assert len(heights) == 2 * 4
        np.testing.assert_allclose(heights, [*geo.area_pct_ref[:, f], *geo.area_pct_pred[:, f]])
    _render(fig, tmp_path, "area_fractions")


def test_centroids(geometric, tmp_path):
    geo, ref, pred = geometric
    d = geo.centroid_distance.mean(axis=1)
    best, worst = int(np.argmin(d)), int(np.argmax(d))
    fig = plot_centroids(geo, ref, _uv(), pred)
    assert len(fig.axes) == 2 * 4  # best and worst joint × (L ref, L pred, R ref, R pred)
    assert fig.axes[0].get_title().startswith(f"joint {best + 1}, flank L, reference")
    assert fig.axes[4].get_title().startswith(f"joint {worst + 1}, flank L, reference")
    ax = fig.axes[6]  # worst joint, flank R, reference
    np.testing.assert_array_equal(np.asarray(ax.collections[0].get_array()).reshape(ROWS, COLS), ref[worst, 1])
    (m_ref, m_pred) = ax.lines
    assert m_ref.get_color() == "tab:red" and m_pred.get_color() == "tab:blue"
    # markers in mm at (v̄, ū): x radial, y axial
    np.testing.assert_allclose([m_ref.get_xdata()[0], m_ref.get_ydata()[0]], geo.centroid_ref[worst, 1, ::-1] * 1e3)
    np.testing.assert_allclose([m_pred.get_xdata()[0], m_pred.get_ydata()[0]], geo.centroid_pred[worst, 1, ::-1] * 1e3)
    _render(fig, tmp_path, "centroids")
    fig = plot_centroids(geo, ref, _uv(), joints=[2], joint_labels=list("ABCD"))
    assert len(fig.axes) == 2 and fig.axes[1].get_title().startswith("C, flank R, reference")
    with pytest.raises(IdentifyError, match="reference has shape"):
        plot_centroids(geo, ref[:3], _uv())
    with pytest.raises(IdentifyError, match="joint index 4 outside 0..3"):
        plot_centroids(geo, ref, _uv(), joints=[4])
    with pytest.raises(IdentifyError, match="coordinates u has shape"):
        plot_centroids(geo, ref, _uv(ROWS + 1, COLS))


def test_d1b_validation(dynamic, tmp_path):
    d1b, _ = dynamic
    fig = plot_d1b_validation(d1b)
    assert len(fig.axes) == 3 * 3  # rows: frequency, Δf, MAC; one column per feature mode
    assert [fig.axes[k].get_title() for k in (0, 1, 2)] == ["mode 2", "mode 3", "mode 5"]
    freq_ax = fig.axes[0]
    np.testing.assert_allclose(freq_ax.lines[0].get_ydata(), d1b.freq_ref_hz[:, 0])
    np.testing.assert_allclose(freq_ax.lines[1].get_ydata(), d1b.freq_pred_hz[:, 0])
    np.testing.assert_allclose([b.get_height() for b in _bars(fig.axes[8])], d1b.mac[:, 2])
    _render(fig, tmp_path, "d1b")
    bad = SimpleNamespace(feature_modes=(1, 2), freq_ref_hz=np.ones((3, 2)), freq_pred_hz=np.ones((3, 3)),
                          freq_error_pct=np.ones((3, 2)), mac=np.ones((3, 2)))
    with pytest.raises(IdentifyError, match=r"freq_pred_hz has shape \(3, 3\): expected \(3, 2\)"):
        plot_d1b_validation(bad)


def test_mode_comparison(dynamic, tmp_path):
    _, cmp = dynamic
    fig = plot_mode_comparison(cmp, title="Case A")
    assert len(fig.axes) == 4 + 1  # frequency, Δf, MAC, MAC matrix, colour bar
    mat = [ax for ax in fig.axes if ax.images]
    assert len(mat) == 1
    np.testing.assert_allclose(np.asarray(mat[0].images[0].get_array()), cmp.mac_matrix)
    assert f"mean MAC = {cmp.mean_mac:.2f}" in fig.get_suptitle() and fig.get_suptitle().startswith("Case A")
    _render(fig, tmp_path, "mode_comparison")
    bad = SimpleNamespace(**{**cmp.__dict__, "pairs": cmp.pairs + 10})
    with pytest.raises(IdentifyError, match="outside the"):
        plot_mode_comparison(bad)


@pytest.mark.parametrize("call", [
    lambda: plot_pattern(np.zeros(5, bool)),
    lambda: plot_pattern(np.zeros((3, 7)), coordinates=(np.zeros((3, 6)), np.zeros((3, 6)))),
    lambda: plot_synthetic_patterns(SimpleNamespace(L=np.zeros((2, 3, 7), bool))),
    lambda: plot_synthetic_patterns(
        SimpleNamespace(L=np.zeros((2, 3, 7)), R=np.zeros((2, 3, 7)), labels_L=("a", "b"), labels_R=("a", "b")),
        known_L=np.zeros((2, 3, 6))),
    lambda: plot_sensitivity(np.zeros((2, 3))),
    lambda: plot_frequency_maps(np.zeros((3, 3, 4)), modes=(0.5,)),
    lambda: plot_area_fractions(SimpleNamespace(area_pct_pred=np.zeros((4, 3)), area_pct_ref=np.zeros((4, 3)),
                                                centroid_pred=np.zeros((4, 2, 2)), centroid_ref=np.zeros((4, 2, 2)))),
    lambda: plot_grid_error(grid_error([[0.0, 0.0]], [[0.0, 0.0]], 0.005), mode_labels=["a"]),
], ids=["pattern-1d", "coords", "not-synthetic", "known-shape", "std-2d", "mode-frac", "area-shape", "labels"])
def test_bad_input_one_line(call):
    with pytest.raises(IdentifyError) as info:
        call()
    assert "\n" not in str(info.value) and str(info.value)
