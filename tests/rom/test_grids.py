"""Interface grids from node sets and coordinates, blade placement, and the conformity check (issue 13 item 2).

References: the academic twin's own grids (built by index, not by position) and synthetic lattices whose
grid is known by construction.
"""

import re

import numpy as np
import pandas as pd
import pytest

from rom.academic import AcademicParams, build_bladed_disk
from rom.importers import (
    BladePlacement,
    FlankAxes,
    GridError,
    export_bladed_disk,
    grid_from_points,
    principal_axes,
    read_model_toml,
)
from rom.importers.placement import axis_rotation

GRID = (3, 5)


@pytest.fixture(scope="module")
def twin():
    return build_bladed_disk(AcademicParams(level="coarse", grid=GRID))


@pytest.fixture(scope="module")
def exported(twin, tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    export_bladed_disk(twin, d, format="mtx")
    return d


def _copy(src, dst):
    dst.mkdir(exist_ok=True)
    for f in src.iterdir():
        (dst / f.name).write_bytes(f.read_bytes())
    return dst


def _lattice(rows, cols, rng, spacing_r=None, spacing_c=None):
    """Points of a graded (rows × cols) lattice in a tilted plane, in random order; the grid by construction."""
    sr = np.cumsum(np.r_[0, spacing_r if spacing_r is not None else rng.uniform(1.0, 2.0, rows - 1)])
    sc = np.cumsum(np.r_[0, spacing_c if spacing_c is not None else rng.uniform(0.5, 1.5, cols - 1)])
    R = axis_rotation(np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5]), 0.7)
    row_ax, col_ax = R[:, 0], R[:, 1]
    P = sr[:, None, None] * row_ax + sc[None, :, None] * col_ax + np.array([3.0, -1.0, 2.0])
    order = rng.permutation(rows * cols)
    X = P.reshape(-1, 3)[order]
    truth = np.empty(rows * cols, dtype=np.int64)
    truth[order] = np.arange(rows * cols)  # truth[k]: position in X of lattice node k (row-major)
    return X, truth.reshape(rows, cols), FlankAxes.of(row_ax, col_ax)


def test_lattice_is_recovered_from_positions_whatever_the_order(tmp_path):
    rng = np.random.default_rng(4)
    X, truth, axes = _lattice(4, 7, rng)
    h = 0.5
    X = X + rng.uniform(-1e-3, 1e-3, X.shape) * h  # mesh noise well below the spacing
    grid, spacing = grid_from_points(X, axes)
    np.testing.assert_array_equal(grid, truth)
    assert 0.49 < spacing <= 1.01
    # Default axes: columns along the longest extent (7 columns ~7 units vs 4 rows ~4.5 units here).
    X2, truth2, axes2 = _lattice(4, 7, rng, spacing_r=np.ones(3), spacing_c=np.full(6, 1.5))
    g2, _ = grid_from_points(X2, principal_axes(X2))
    ax = principal_axes(X2)
    sign_r, sign_c = np.sign(ax.row @ axes2.row), np.sign(ax.col @ axes2.col)
    expect = truth2[:: int(sign_r), :: int(sign_c)]
    np.testing.assert_array_equal(g2, expect)


def test_quadratic_flank_mid_side_nodes(tmp_path):
    rng = np.random.default_rng(5)
    X, truth, axes = _lattice(5, 7, rng)
    keep = np.ones((5, 7), bool)
    keep[1::2, 1::2] = False  # no node at the centre of a quadratic face: not a full lattice
    sel = truth[keep]
    Xs = X[sel]
    with pytest.raises(GridError) as exc:
        grid_from_points(Xs, axes, where="set 'L'")
    msg = str(exc.value)
    assert "set 'L'" in msg and "fill 29 of the 5 × 7 positions" in msg and "drop_rows" in msg and "\n" not in msg
    g, _ = grid_from_points(Xs, axes, incomplete="drop_rows")  # the corner rows, every node along them
    np.testing.assert_array_equal(sel[g], truth[0::2])
    g, _ = grid_from_points(Xs, axes, incomplete="drop_cols")
    np.testing.assert_array_equal(sel[g], truth[:, 0::2])


def test_grid_builder_refusals():
    rng = np.random.default_rng(6)
    X, _, axes = _lattice(3, 4, rng)
    with pytest.raises(GridError, match="expected 3 × 5"):
        grid_from_points(X, axes, shape=(3, 5))
    with pytest.raises(GridError, match="same point"):
        grid_from_points(np.vstack([X, X[:1]]), axes)
    with pytest.raises(GridError, match="missing"):
        grid_from_points(np.full((6, 3), np.nan), axes)
    with pytest.raises(GridError, match="orthogonal"):
        FlankAxes.of([1, 0, 0], [1, 1, 0])


def test_academic_placement_is_the_twins(twin):
    p = BladePlacement.uniform(twin.n_slots, axis=(0.0, 0.0, -1.0))
    for s in range(1, twin.n_slots + 1):
        np.testing.assert_allclose(p.rotation(s), twin.slot_rotation(s), atol=1e-15)
        np.testing.assert_allclose(p.place(twin.blade.coords, s), twin.placed_blade_coords(s), atol=1e-15)


def test_general_placement_inverts():
    rng = np.random.default_rng(7)
    R0 = axis_rotation(np.array([0.3, -0.4, 0.866]) / np.linalg.norm([0.3, -0.4, 0.866]), 1.1)
    p = BladePlacement([0.0, 1.0, 0.0], np.radians([0.0, 45.0, 170.0]), rotation0=R0, origin0=[0.01, 0.2, -0.03])
    X = rng.standard_normal((10, 3))
    for s in (1, 2, 3):
        np.testing.assert_allclose(p.to_blade_frame(p.place(X, s), s), X, atol=1e-14)
        # DOFs turn with the rotation part of the placement.
        d = rng.standard_normal(3)
        np.testing.assert_allclose(p.place(X[0] + d, s) - p.place(X[0], s), p.rotation(s) @ d, atol=1e-14)
    with pytest.raises(Exception, match="proper rotation"):
        BladePlacement([0, 0, 1], [0.0], rotation0=np.diag([1.0, 1.0, -1.0]))


def _rewrite_scrambled(d, rng):
    """Renumber every node of the exported files at random and shuffle the lines of each CSV."""
    new_ids = {}
    for comp in ("disk", "blade"):
        coords = pd.read_csv(d / f"{comp}_coords.csv")
        old = coords["node"].to_numpy()
        new = rng.choice(np.arange(10, 10 * old.size + 10), old.size, replace=False)
        new_ids[comp] = dict(zip(old.tolist(), new.tolist(), strict=True))
        m = new_ids[comp]
        coords["node"] = coords["node"].map(m)
        coords.sample(frac=1, random_state=1).to_csv(d / f"{comp}_coords.csv", index=False, float_format="%.17g")
        dofmap = pd.read_csv(d / f"{comp}_dofmap.csv")
        dofmap["node"] = dofmap["node"].map(m)
        dofmap.sample(frac=1, random_state=2).to_csv(d / f"{comp}_dofmap.csv", index=False)
        sets = pd.read_csv(d / f"{comp}_node_sets.csv")
        sets["node"] = sets["node"].map(m)
        grids = sets[sets["set"] != "meas"].sample(frac=1, random_state=3)  # flank sets in no order at all
        pd.concat([grids, sets[sets["set"] == "meas"]]).to_csv(d / f"{comp}_node_sets.csv", index=False)
    return new_ids


@pytest.mark.parametrize("axes", ["given", "principal"])
def test_scrambled_numbering_grids_are_recovered_exactly_from_coordinates(twin, exported, tmp_path, axes):
    d = _copy(exported, tmp_path / "m")
    new_ids = _rewrite_scrambled(d, np.random.default_rng(11))
    toml = (d / "model.toml").read_text()
    toml = toml.replace('file = "grids.csv"\n', "")  # build the grids from the node sets
    if axes == "principal":
        toml = re.sub(r"(row|col)_axis = .*\n", "", toml)
    (d / "model.toml").write_text(toml)
    bd = read_model_toml(d / "model.toml")
    for s in range(1, twin.n_slots + 1):
        for f in ("L", "R"):
            want = np.vectorize(new_ids["disk"].get)(twin.disk.node_ids[twin.disk.node_set(f"slot{s}_{f}")])
            np.testing.assert_array_equal(bd.disk.node_ids[bd.disk.node_set(f"slot{s}_{f}")], want)
    for f in ("L", "R"):
        want = np.vectorize(new_ids["blade"].get)(twin.blade.node_ids[twin.blade.node_set(f)])
        np.testing.assert_array_equal(bd.blade.node_ids[bd.blade.node_set(f)], want)
    want = np.vectorize(new_ids["disk"].get)(twin.disk.node_ids[twin.disk.node_set("meas")])
    np.testing.assert_array_equal(bd.disk.node_ids[bd.disk.node_set("meas")], want)
    assert bd.max_gap < 1e-12 and max(bd.interface_gap(s) for s in (1, 9, 18)) < 1e-12
    # The imported flank coordinates are the academic ones (rows axial, columns radial).
    u, v = bd.flank_coordinates()
    from rom.academic import flank_coordinates

    u0, v0 = flank_coordinates(twin)
    np.testing.assert_allclose(u, u0, atol=1e-15)
    np.testing.assert_allclose(v, v0, atol=1e-15)


def test_non_conforming_grids_are_refused_with_the_gap(twin, exported, tmp_path):
    d = _copy(exported, tmp_path / "m")
    coords = pd.read_csv(d / "disk_coords.csv")
    node = int(twin.disk.node_ids[twin.disk.node_set("slot3_L")[1, 2]])
    coords.loc[coords["node"] == node, "x"] += 2e-5  # 2e-5 m off; the grid spacing is ~1 mm
    coords.to_csv(d / "disk_coords.csv", index=False, float_format="%.17g")
    with pytest.raises(GridError) as exc:
        read_model_toml(d / "model.toml")
    msg = str(exc.value)
    assert "\n" not in msg
    for needle in ("slot 3 flank 'L'", "gap 2e-05 m", "row 2, col 3", f"disk node {node}", "tolerance"):
        assert needle in msg, (needle, msg)
    toml = (d / "model.toml").read_text().replace("[model.grids]\n", "[model.grids]\ntolerance = 1e-4\n")
    (d / "model.toml").write_text(toml)
    bd = read_model_toml(d / "model.toml")
    assert bd.max_gap == pytest.approx(2e-5, rel=1e-6)


def test_grid_nodes_missing_from_the_mesh_are_refused(exported, tmp_path):
    d = _copy(exported, tmp_path / "m")
    grids = pd.read_csv(d / "grids.csv")
    grids.loc[(grids["slot"] == 2) & (grids["flank"] == "R"), "node"] += 10**7
    grids.to_csv(d / "grids.csv", index=False)
    with pytest.raises(GridError) as exc:
        read_model_toml(d / "model.toml")
    msg = str(exc.value)
    assert "grids.csv" in msg and "slot 2 flank 'R'" in msg and "not in the mesh" in msg and "\n" not in msg


def test_model_table_typos_and_gaps_are_named(exported, tmp_path):
    d = _copy(exported, tmp_path / "m")
    toml = (d / "model.toml").read_text()
    (d / "model.toml").write_text(toml.replace("dofmap =", "dofmpa =", 1))
    with pytest.raises(Exception, match=r"unknown key\(s\) \['dofmpa'\] in \[model.disk\]"):
        read_model_toml(d / "model.toml")
    (d / "model.toml").write_text(toml.replace("n_slots = 18", "n_slots = 17"))
    with pytest.raises(Exception, match="angles_deg has 18 entries for n_slots = 17"):
        read_model_toml(d / "model.toml")
