"""FE importers (issue 13): ANSYS .full, Matrix Market and OP4 into rom.Component, units, constrained DOFs,
the export → import round trip through the ROM, and one-line refusals of bad models.

Independent references: ansys-mapdl-reader's own ``load_km`` solved with ``scipy.sparse.linalg.eigsh`` (and the
frequencies its documentation lists), ``scipy.io.mmread``/``mmwrite``, dense ``scipy.linalg.eigh``, the native
academic twin and its ROM.
"""

import builtins
import warnings

import numpy as np
import pytest
import scipy.io as sio
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as ssla

from rom.academic import AcademicParams, build_bladed_disk
from rom.contact import ContactPattern
from rom.craig_bampton import reduce_disk
from rom.fe_assembly import assemble_fe, solve_fe
from rom.importers import (
    GridError,
    MissingDependencyError,
    ModelImportError,
    UnitsWarning,
    export_bladed_disk,
    import_component,
    read_matrix_market_component,
    read_model_toml,
    read_op4_component,
    unit_system,
    write_op4,
)
from rom.importers.csvio import write_coords_csv, write_dofmap_csv, write_node_sets_csv
from rom.importers.matrix_market import read_matrix_market
from rom.rom_assembly import solve_d1b
from rom.rubin import reduce_blade
from rom.solver import solve_modes

GRID = (3, 5)
N_CB, N_FREE = 30, 15


@pytest.fixture(scope="module")
def twin():
    return build_bladed_disk(AcademicParams(level="coarse", grid=GRID))


def _one_line(exc_info, *needles):
    msg = str(exc_info.value)
    assert "\n" not in msg, msg
    for n in needles:
        assert str(n) in msg, (n, msg)
    return msg


def _write_component(d, comp, *, K=None, M=None, rows=None, general=True):
    """Matrix Market pair (scipy's own writer) and CSV side files of a component; ``rows``: DOFs kept."""
    rows = np.arange(comp.n_dof) if rows is None else rows
    K = comp.K if K is None else K
    M = comp.M if M is None else M
    sym = "general" if general else "symmetric"
    sio.mmwrite(d / "K.mtx", sp.csr_matrix(K)[rows][:, rows], symmetry=sym)
    sio.mmwrite(d / "M.mtx", sp.csr_matrix(M)[rows][:, rows], symmetry=sym)
    write_dofmap_csv(d / "dofmap.csv", comp.node_ids[rows // 3], rows % 3 + 1)
    write_coords_csv(d / "coords.csv", comp.node_ids, comp.coords)
    write_node_sets_csv(d / "sets.csv", {k: comp.node_ids[np.asarray(v)] for k, v in comp.node_sets.items()})
    return dict(dofmap=d / "dofmap.csv", coords=d / "coords.csv", node_sets=d / "sets.csv")


# ------------------------------------------------------------------------------------------------ ANSYS .full
@pytest.fixture(scope="module")
def ansys_example():
    pytest.importorskip("ansys.mapdl.reader")
    from ansys.mapdl.reader import examples

    return examples


def test_ansys_full_example_matches_an_independent_solve(ansys_example):
    from ansys.mapdl import reader

    # Reference: the reader's own load_km, symmetrized as its documentation shows, constrained (empty) rows
    # dropped, solved by eigsh.
    full = reader.read_binary(ansys_example.fullfile)
    _, k, m = full.load_km()
    k = (k + sp.triu(k, 1).T).tocsr()
    m = (m + sp.triu(m, 1).T).tocsr()
    free = np.flatnonzero(k.diagonal() != 0)
    w = ssla.eigsh(k[free][:, free], k=10, M=m[free][:, free], sigma=0.0, which="LM")[0]
    ref = np.sort(np.sqrt(w)) / (2 * np.pi)
    # The frequencies ansys-mapdl-reader's examples.load_km() asserts for this file.
    documented = [1283.20036921, 1283.20036921, 5781.97486169, 6919.39887714, 6919.39887714, 10172.61497694,
                  16497.85701889, 16497.85701889, 17343.9939669, 27457.18472747]
    np.testing.assert_allclose(ref, documented, rtol=1e-8)

    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitsWarning)  # titanium in in-lbf-s: a plausible mass, no warning
        comp = import_component(ansys_example.fullfile, archive=ansys_example.hexarchivefile, units="in-lbf-s")
    assert comp.n_dof == 963 and comp.n_nodes == 321
    assert len(comp.meta["constrained_dofs"]) == 63 == comp.meta["ansys_constrained_dofs"]
    assert comp.meta["storage"] == "K upper triangle, M upper triangle"
    assert set(comp.node_sets) == {"NCOMP2", "NODE_SELECTION"}
    sol = solve_modes(comp.K, comp.M, 10)
    assert sol.n_rigid == 0
    np.testing.assert_allclose(sol.frequencies_hz, ref, rtol=1e-6)


def test_ansys_rst_beside_it_is_a_different_model(ansys_example):
    """file.rst has the same mesh as file.full (and HexBeam.cdb) but other boundary conditions: its modes move
    the nodes the .full file constrains. So its frequencies are no reference for the .full file."""
    from ansys.mapdl import reader

    full = reader.read_binary(ansys_example.fullfile)
    full.load_km()
    clamped = np.unique(full.const[:, 0])
    rst = reader.read_binary(ansys_example.rstfile)
    archive = reader.Archive(ansys_example.hexarchivefile)
    np.testing.assert_array_equal(rst.mesh.nnum, archive.nnum)
    np.testing.assert_allclose(rst.mesh.nodes[:, :3], archive.nodes[:, :3])
    nnum, disp = rst.nodal_solution(0)
    at_clamp = np.abs(disp[np.searchsorted(nnum, clamped)]).max()
    assert at_clamp > 0.1 * np.abs(disp).max()  # the .rst's first mode moves the .full's clamped face
    assert rst.time_values[0] == pytest.approx(7366.495, rel=1e-6)  # vs 1283.2 Hz for the clamped .full


def test_ansys_units_convert_and_a_wrong_guess_warns_with_the_mass(ansys_example):
    with pytest.warns(UnitsWarning) as rec:
        si = import_component(ansys_example.fullfile, archive=ansys_example.hexarchivefile, units="SI")
    msg = str(rec[0].message)
    assert f"{si.mass():.4g} kg" in msg and "SI" in msg and "file.full" in msg
    imp = import_component(ansys_example.fullfile, archive=ansys_example.hexarchivefile, units="BIN")
    lbf_s2_per_in = 4.4482216152605 / 0.0254
    assert imp.mass() == pytest.approx(si.mass() * lbf_s2_per_in, rel=1e-12)
    np.testing.assert_allclose(imp.coords, si.coords * 0.0254, rtol=1e-15)
    assert imp.meta["units"] == "in-lbf-s"
    # A consistent system scales K and M alike: the frequencies do not change.
    np.testing.assert_allclose(solve_modes(imp.K, imp.M, 3).frequencies_hz, solve_modes(si.K, si.M, 3).frequencies_hz,
                               rtol=1e-9)


def test_truncated_ansys_full_is_refused(ansys_example, tmp_path):
    data = open(ansys_example.fullfile, "rb").read()
    for cut in (2000, 700_000):  # inside the header's tables; inside the mass matrix (crashed the reader)
        p = tmp_path / "cut.full"
        p.write_bytes(data[:cut])
        with pytest.raises(ModelImportError) as exc:
            import_component(p)
        _one_line(exc, "cut.full")
    _one_line(exc, "truncated", "the file has 700000 bytes")


def test_missing_ansys_reader_says_what_to_install(monkeypatch, tmp_path):
    real_import = builtins.__import__

    def no_ansys(name, *args, **kwargs):
        if name.startswith("ansys"):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ansys)
    with pytest.raises(MissingDependencyError) as exc:
        import_component(tmp_path / "disk.full")
    _one_line(exc, "disk.full", 'pip install "bladetwin[ansys]"')


# ------------------------------------------------------------------------------------------------ Matrix Market
def test_matrix_market_reader_agrees_with_scipy_for_every_storage(tmp_path):
    rng = np.random.default_rng(0)
    A = sp.random(30, 30, density=0.2, random_state=rng)
    A = (A + A.T + 8 * sp.eye(30)).tocsr()
    sio.mmwrite(tmp_path / "sym.mtx", A, symmetry="symmetric")  # scipy writes the lower triangle
    sio.mmwrite(tmp_path / "gen.mtx", A, symmetry="general")
    sio.mmwrite(tmp_path / "upper.mtx", sp.triu(A), symmetry="general")  # ANSYS-style upper-triangle storage
    U = sp.triu(A).tocoo()
    body = "".join(f"{i + 1} {j + 1} {v:.17g}\n" for i, j, v in zip(U.row, U.col, U.data, strict=True))
    (tmp_path / "symup.mtx").write_text(f"%%MatrixMarket matrix coordinate real symmetric\n30 30 {U.nnz}\n{body}")
    expect = {"sym": "symmetric, lower", "gen": "general (full", "upper": "general, upper triangle only",
              "symup": "symmetric, upper"}
    for name, storage in expect.items():
        B, how = read_matrix_market(tmp_path / f"{name}.mtx")
        ref = sio.mmread(tmp_path / f"{name}.mtx").toarray()
        if name == "upper":
            ref = ref + np.triu(ref, 1).T
        np.testing.assert_array_equal(B.toarray(), ref)
        assert how.startswith(storage), (name, how)


def test_dof_map_places_rows_on_nodes_node_major(tmp_path):
    """A file in its own DOF order (direction-major, nodes shuffled) lands node-major: K_comp = P K_file Pᵀ."""
    rng = np.random.default_rng(1)
    n_nodes = 6
    node_ids = rng.permutation(np.arange(101, 101 + n_nodes))
    file_nodes = np.tile(node_ids, 3)  # rows: all x, then all y, then all z
    file_dirs = np.repeat([1, 2, 3], n_nodes)
    A = sp.random(18, 18, density=0.3, random_state=rng)
    A = (A + A.T + 5 * sp.eye(18)).tocsr()
    sio.mmwrite(tmp_path / "K.mtx", A, symmetry="symmetric")
    sio.mmwrite(tmp_path / "M.mtx", sp.eye(18) * 2.0, symmetry="symmetric")
    write_dofmap_csv(tmp_path / "map.csv", file_nodes, file_dirs)
    comp = read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", dofmap=tmp_path / "map.csv")
    sorted_ids = np.sort(node_ids)
    np.testing.assert_array_equal(comp.node_ids, sorted_ids)
    dest = 3 * np.searchsorted(sorted_ids, file_nodes) + file_dirs - 1
    P = np.zeros((18, 18))
    P[dest, np.arange(18)] = 1.0
    np.testing.assert_allclose(comp.K.toarray(), P @ A.toarray() @ P.T, rtol=0, atol=0)
    assert np.isnan(comp.coords).all() and comp.meta["constrained_dofs"] == []


def test_constrained_dofs_keep_three_dofs_per_node_and_the_eigenpairs(twin, tmp_path):
    blade = twin.blade
    clamped = blade.dofs_of(blade.node_set("L").ravel()).ravel()  # root flank L fixed
    free = np.setdiff1d(np.arange(blade.n_dof), clamped)
    files = _write_component(tmp_path, blade, rows=free)
    comp = read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    assert comp.n_dof == blade.n_dof and comp.n_nodes == blade.n_nodes
    np.testing.assert_array_equal(comp.meta["constrained_dofs"], np.sort(clamped))
    Kc = comp.K.toarray()
    assert (Kc[np.ix_(clamped, free)] == 0).all() and (comp.M.toarray()[clamped] == 0).all()
    # Reference: the clamped blade's dense eigenproblem on the free DOFs only.
    Kf = blade.K[free][:, free].toarray()
    Mf = blade.M[free][:, free].toarray()
    ref = np.sqrt(sla.eigh(Kf, Mf, eigvals_only=True, subset_by_index=[0, 5])) / (2 * np.pi)
    sol = solve_modes(comp.K, comp.M, 6)
    assert sol.n_rigid == 0
    np.testing.assert_allclose(sol.frequencies_hz, ref, rtol=1e-8)
    assert np.abs(sol.shapes[clamped]).max() < 1e-12  # no motion where the model is constrained


# ------------------------------------------------------------------------------------------------ round trip
@pytest.fixture(scope="module")
def native_d1b(twin):
    disk = reduce_disk(twin, (1,), N_CB)
    blade = reduce_blade(twin, N_FREE)
    return solve_d1b(disk, blade, ContactPattern.full(GRID), n_modes=8).frequencies_hz


@pytest.mark.parametrize("fmt", ["mtx", "op4"])
def test_export_import_round_trip_gives_the_native_rom(twin, native_d1b, tmp_path, fmt):
    done = export_bladed_disk(twin, tmp_path, format=fmt)
    bd = read_model_toml(done.model_toml)
    assert bd.n_slots == twin.n_slots and tuple(bd.params.grid) == GRID and bd.cyclic
    for key in ("disk", "blade"):
        a, b = getattr(twin, key), getattr(bd, key)
        assert (a.K != b.K).nnz == 0 and (a.M != b.M).nnz == 0
        np.testing.assert_array_equal(a.coords, b.coords)
        for s in ("meas", "L", "R", "slot7_R"):
            if s in a.node_sets:
                np.testing.assert_array_equal(a.node_set(s), b.node_set(s))
    for s in (1, 5, 18):
        np.testing.assert_allclose(bd.slot_rotation(s), twin.slot_rotation(s), atol=1e-15)
    assert bd.max_gap < 1e-12
    disk = reduce_disk(bd, (1,), N_CB)
    blade = reduce_blade(bd, N_FREE)
    f = solve_d1b(disk, blade, ContactPattern.full(GRID), n_modes=8).frequencies_hz
    np.testing.assert_allclose(f, native_d1b, rtol=1e-9)
    if fmt == "mtx":  # the FE assembly too, in a slot whose placement is a real rotation
        pattern = {7: ContactPattern.full(GRID)}
        ref = solve_fe(assemble_fe(twin, pattern), 6)
        got = solve_fe(assemble_fe(bd, pattern), 6)
        np.testing.assert_allclose(got.frequencies_hz, ref.frequencies_hz, rtol=1e-9)
        assert got.meas_labels == ref.meas_labels


def test_op4_component_finds_k_and_m_by_name(twin, tmp_path):
    blade = twin.blade
    files = _write_component(tmp_path, blade)
    write_op4(tmp_path / "b.op4", {"KGG": blade.K, "MGG": blade.M, "PHI": sp.eye(blade.n_dof, 2)})
    comp = read_op4_component(tmp_path / "b.op4", **files)
    assert comp.meta["matrices"] == ["KGG", "MGG"] and (comp.K != blade.K).nnz == 0
    write_op4(tmp_path / "c.op4", {"KAA": blade.K, "KGG": blade.K, "MAA": blade.M})
    with pytest.raises(ModelImportError) as exc:
        read_op4_component(tmp_path / "c.op4", **files)
    _one_line(exc, "c.op4", "cannot tell K and M apart", "KAA", "KGG")
    comp = read_op4_component(tmp_path / "c.op4", matrices=("KGG", "MAA"), **files)
    assert comp.n_dof == blade.n_dof


# ------------------------------------------------------------------------------------------------ bad models
def test_non_symmetric_k_is_refused(twin, tmp_path):
    K = twin.blade.K.tolil()
    K[0, 1] += 1e-3 * abs(K).max()
    files = _write_component(tmp_path, twin.blade, K=K.tocsr())
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "K.mtx", "K is not symmetric", "0.001 of max |K|")


def test_k_m_size_mismatch_is_refused(twin, tmp_path):
    files = _write_component(tmp_path, twin.blade)
    sio.mmwrite(tmp_path / "M.mtx", twin.blade.M[:-3, :-3])
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "M.mtx", f"M is {twin.blade.n_dof - 3} × {twin.blade.n_dof - 3}", "K (K.mtx)", "same size")
    write_op4(tmp_path / "b.op4", {"KAA": twin.blade.K, "MAA": twin.blade.M[:-3, :-3]})
    with pytest.raises(ModelImportError) as exc:
        read_op4_component(tmp_path / "b.op4", **files)
    _one_line(exc, "b.op4", "same size")


def test_dof_map_that_does_not_cover_the_matrix_is_refused(twin, tmp_path):
    files = _write_component(tmp_path, twin.blade)
    lines = files["dofmap"].read_text().splitlines()
    files["dofmap"].write_text("\n".join(lines[:10] + lines[11:]) + "\n")  # row 10 missing
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "dofmap.csv", "does not cover the matrix", "first: row 10")
    files["dofmap"].write_text("\n".join(lines[:10] + ["10,1,1"] + lines[11:]) + "\n")  # node 1 x twice
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "dofmap.csv", "node 1 direction 1", "2 matrix rows")
    files["dofmap"].write_text("\n".join(lines[:10] + ["10,4,4"] + lines[11:]) + "\n")
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "dofmap.csv", "got 4", "rotation")


def test_node_set_or_coordinates_naming_unknown_nodes_are_refused(twin, tmp_path):
    files = _write_component(tmp_path, twin.blade)
    with open(files["node_sets"], "a") as fh:
        fh.write("L,99999\n")
    with pytest.raises(GridError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "node set 'L'", "not in the mesh", "node 99999")
    files = _write_component(tmp_path, twin.blade)
    lines = files["coords"].read_text().splitlines()
    files["coords"].write_text("\n".join(lines[:5] + lines[6:]) + "\n")
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "lack 1 of the", "node 5")


def test_damaged_matrix_market_files_are_refused(twin, tmp_path):
    files = _write_component(tmp_path, twin.blade, general=False)
    text = (tmp_path / "K.mtx").read_text()
    (tmp_path / "K.mtx").write_text(text[: len(text) // 2].rsplit("\n", 1)[0] + "\n")
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "K.mtx", "ends after", "truncated")
    (tmp_path / "K.mtx").write_text(text.replace("real", "complex", 1))
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "K.mtx", "'complex'")
    head, rest = text.split("\n", 1)
    size_line_end = rest.index("\n", rest.index("\n") + 1)  # the comment line, then the size line
    (tmp_path / "K.mtx").write_text(head + "\n" + rest[: size_line_end + 1] + "1 2 3 4\n" + rest[size_line_end + 1:])
    with pytest.raises(ModelImportError) as exc:
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    _one_line(exc, "K.mtx", "row column value")


def test_steel_disk_with_mass_off_by_1e9_warns_with_the_mass(twin, tmp_path):
    files = _write_component(tmp_path, twin.disk, M=twin.disk.M * 1e9)
    with pytest.warns(UnitsWarning) as rec:
        comp = read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)
    msg = str(rec[0].message)
    assert f"total mass {comp.mass():.4g} kg" in msg and "units assumed were SI" in msg and "K.mtx" in msg
    assert comp.mass() == pytest.approx(twin.disk.mass() * 1e9, rel=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitsWarning)
        files = _write_component(tmp_path, twin.disk)  # the true mass: no warning
        read_matrix_market_component(tmp_path / "K.mtx", tmp_path / "M.mtx", **files)


def test_unit_systems_and_bad_names():
    assert unit_system("MMNS").stiffness == pytest.approx(1e3) and unit_system("mm-t-s").mass == 1e3
    assert unit_system("mm-kg-ms").stiffness == pytest.approx(1e6)
    with pytest.raises(ModelImportError, match="units must be one of"):
        unit_system("furlong")


def test_import_component_checks_its_options(twin, tmp_path):
    files = _write_component(tmp_path, twin.blade)
    with pytest.raises(ModelImportError) as exc:
        import_component(tmp_path / "K.mtx", **files)
    _one_line(exc, "K.mtx", "needs the mass matrix")
    with pytest.raises(ModelImportError) as exc:
        import_component(tmp_path / "K.mtx", mass=tmp_path / "M.mtx", archive=tmp_path / "x.cdb", **files)
    _one_line(exc, "archive", "'mtx'")
    with pytest.raises(ModelImportError) as exc:
        import_component(tmp_path / "K.txt")
    _one_line(exc, "K.txt", "cannot tell the format")
