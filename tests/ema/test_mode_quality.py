"""MPC, MPD and MCF (ema.mode_quality) against their definitions, and in the run's and the CLI's mode tables.

Notation of the definitions: for a shape ``phi`` with ``x = Re(phi)``, ``y = Im(phi)``, ``Sxx = x.x``,
``Syy = y.y``, ``Sxy = x.y``; ``l1 >= l2`` are the eigenvalues of ``[[Sxx, Sxy], [Sxy, Syy]]``.

- ``MPC = ((l1 - l2)/(l1 + l2))**2 = ((Sxx - Syy)**2 + 4 Sxy**2)/(Sxx + Syy)**2``;
- ``MCF = 1 - ((Sxx - Syy)**2 + 4 Sxy**2)/(Sxx + Syy)**2``;
- ``MPD = sum_j |phi_j| d_j / sum_j |phi_j|`` (degrees), ``d_j`` the angle in [0°, 90°] between ``phi_j`` and the
  principal axis of the matrix above (the total-least-squares line through the origin).

The expected values below are derived by hand, or computed from these formulas written out independently of
the implementation (eigenvalues, SVD, ``arccos``), never by calling the function under test.
"""

from __future__ import annotations

import argparse
import csv
from types import SimpleNamespace

import numpy as np
import pytest

import ema
from ema import ModalModel, ModeQuality, mode_quality
from ema.mode_quality import mcf, mpc, mpd

TOL = 1e-12


def _random_shapes(seed: int, n_dof: int = 9, n_modes: int = 6) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n_dof, n_modes)) + 1j * rng.standard_normal((n_dof, n_modes))


def test_a_real_normal_mode_times_any_complex_scalar_is_perfectly_collinear():
    """phi = r e^{i theta}, r real: every component lies on the line at theta (or theta + 180°) through the
    origin, so l2 = 0: MPC = 1, MCF = 0, and every component's deviation from the line is 0: MPD = 0."""
    rng = np.random.default_rng(1)
    r = rng.standard_normal((11, 1))            # signs mixed: antiphase components are still a normal mode
    thetas = np.array([0.0, 0.3, np.pi / 2, 2.0, np.pi, -1.1, 5.9])
    shapes = r * (rng.uniform(0.1, 10.0, thetas.size) * np.exp(1j * thetas))[None, :]
    q = mode_quality(shapes)
    assert isinstance(q, ModeQuality) and q.mpc.shape == q.mpd_deg.shape == q.mcf.shape == (thetas.size,)
    np.testing.assert_allclose(q.mpc, 1.0, rtol=0, atol=TOL)
    np.testing.assert_allclose(q.mpd_deg, 0.0, rtol=0, atol=TOL)
    np.testing.assert_allclose(q.mcf, 0.0, rtol=0, atol=TOL)


@pytest.mark.parametrize("phi_deg", [0.0, 10.0, 30.0, 45.0, 60.0, 89.0, 90.0, 120.0, 150.0, 179.0, 180.0])
def test_two_components_at_an_angle_give_the_closed_forms(phi_deg):
    """Shape [1, e^{i phi}], 0 <= phi <= 180°.

    Moments: x = (1, cos phi), y = (0, sin phi), so Sxx = 1 + cos²phi, Syy = sin²phi, Sxy = sin phi cos phi.
    Then Sxx + Syy = 2, Sxx - Syy = 1 + cos 2phi, 2 Sxy = sin 2phi, and
    (Sxx - Syy)² + 4 Sxy² = 1 + 2 cos 2phi + cos² 2phi + sin² 2phi = 2 (1 + cos 2phi) = 4 cos²phi:

        MPC = 4 cos²phi / 4 = cos²phi,     MCF = 1 - cos²phi = sin²phi.

    MPD: both components have magnitude 1, and the principal axis of S bisects them: at phi/2 when
    phi < 90° (both deviate by phi/2), at phi/2 - 90° when phi > 90° (the bisector of 1 and -e^{i phi}, both
    deviate by (180° - phi)/2). Equal weights:

        MPD = min(phi, 180° - phi) / 2.

    At phi = 90° the two axes tie (l1 = l2) and both give 45°.
    """
    p = np.radians(phi_deg)
    shape = np.array([1.0, np.exp(1j * p)])
    assert mpc(shape)[0] == pytest.approx(np.cos(p) ** 2, abs=TOL)
    assert mcf(shape)[0] == pytest.approx(np.sin(p) ** 2, abs=TOL)
    assert mpd(shape)[0] == pytest.approx(min(phi_deg, 180.0 - phi_deg) / 2, abs=1e-9)


@pytest.mark.parametrize("n", [3, 4, 5, 6, 8, 12])
def test_a_circular_mode_has_no_direction(n):
    """Components e^{2 pi i k/n}, k = 0..n-1 (a travelling wave over n equal points).

    phi^T phi = sum_k e^{4 pi i k/n} = 0 for n >= 3 (a full sum of n-th roots of unity taken twice round), and
    phi^T phi = (Sxx - Syy) + 2i Sxy, so Sxx = Syy and Sxy = 0: l1 = l2, MPC = 0, MCF = 1.

    MPD: the principal axis is undetermined. For n a multiple of 4 the components come in pairs at right angles
    (k and k + n/4), whose deviations from any line add to 90°: MPD = 45° whatever the line.
    """
    shape = np.exp(2j * np.pi * np.arange(n) / n)
    assert mpc(shape)[0] == pytest.approx(0.0, abs=TOL)
    assert mcf(shape)[0] == pytest.approx(1.0, abs=TOL)
    if n % 4 == 0:
        assert mpd(shape)[0] == pytest.approx(45.0, abs=1e-9)
    else:
        assert 30.0 < mpd(shape)[0] < 60.0


def test_mpd_weights_each_component_by_its_magnitude():
    """One component 1 at 0° and 100 components 0.05 at 90°.

    Sxx = 1, Syy = 100 * 0.05² = 0.25, Sxy = 0: the line is the real axis; the large component deviates by 0°,
    the small ones by 90°. Weighted by |phi_j|: MPD = 100 * 0.05 * 90° / (1 + 100 * 0.05) = 450°/6 = 75°
    (weights |phi_j|² would give 0.25 * 90°/1.25 = 18°). MPC = ((1 - 0.25)/(1.25))² = 0.36, MCF = 0.64.
    """
    shape = np.concatenate([[1.0], np.full(100, 0.05j)])
    assert mpd(shape)[0] == pytest.approx(75.0, abs=1e-9)
    assert mpc(shape)[0] == pytest.approx(0.36, abs=TOL)
    assert mcf(shape)[0] == pytest.approx(0.64, abs=TOL)


def test_random_shapes_match_the_eigenvalue_and_svd_forms():
    """On general complex shapes: MPC and MCF from the eigenvalues of S, MPD from the SVD of [x, y] with the
    arccos of the normalised cross product (the textbook recipe), mode by mode."""
    shapes = _random_shapes(2, 9, 6)
    q = mode_quality(shapes)
    for k in range(shapes.shape[1]):
        X = np.column_stack([shapes[:, k].real, shapes[:, k].imag])
        l2, l1 = np.linalg.eigvalsh(X.T @ X)
        assert q.mpc[k] == pytest.approx(((l1 - l2) / (l1 + l2)) ** 2, abs=TOL)
        assert q.mcf[k] == pytest.approx(4 * l1 * l2 / (l1 + l2) ** 2, abs=TOL)
        v = np.linalg.svd(X)[2][0]                 # the direction of the best-fit line
        mag = np.abs(shapes[:, k])
        cos_dev = np.abs(X @ v) / mag               # |cos| of each component's angle to the line
        expected = np.degrees(np.sum(mag * np.arccos(np.clip(cos_dev, 0, 1))) / np.sum(mag))
        assert q.mpd_deg[k] == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("c", [2.5 * np.exp(0.7j), -1.0, 1j, -3e-4j, 1e-300 * np.exp(2.1j), 1e300 * np.exp(-0.4j)])
def test_every_indicator_is_invariant_to_a_complex_scale(c):
    shapes = _random_shapes(3, 8, 5)
    shapes[:, 0] = np.arange(1, 9) * np.exp(0.2j)     # one real mode among them
    ref, scaled = mode_quality(shapes), mode_quality(c * shapes)
    for name in ("mpc", "mpd_deg", "mcf"):
        np.testing.assert_allclose(getattr(scaled, name), getattr(ref, name), rtol=1e-12, atol=1e-12)


def test_ranges_shapes_and_degenerate_input():
    q = mode_quality(_random_shapes(4, 5, 200))
    assert np.all((q.mpc >= 0) & (q.mpc <= 1)) and np.all((q.mcf >= 0) & (q.mcf <= 1))
    assert np.all((q.mpd_deg >= 0) & (q.mpd_deg <= 90))
    np.testing.assert_allclose(q.mpc + q.mcf, 1.0, atol=TOL)   # the two coincide for the origin-anchored MPC
    assert mpc(np.array([1.0 + 2.0j, 3.0 - 1.0j])).shape == (1,)          # one shape as a vector: one mode
    zero = mode_quality(np.zeros((4, 2), dtype=complex))
    assert np.all(np.isnan(zero.mpc)) and np.all(np.isnan(zero.mpd_deg)) and np.all(np.isnan(zero.mcf))
    assert mode_quality(np.array([[0.3 - 2j]])).mpc[0] == pytest.approx(1.0)  # one DOF is always real
    with pytest.raises(ValueError, match="n_dof, n_modes"):
        mpc(np.zeros((2, 2, 2)))


def test_modal_model_records_keep_their_keys_and_add_the_indicators():
    shapes = np.column_stack([np.array([1.0, -2.0, 0.5]) * np.exp(0.9j), [1.0, 1j, -1.0]])
    m = ModalModel([100.0, 200.0], [0.01, 0.02], shapes, [(1, 3), (2, 3), (3, 3)], quality=[0.9, 0.8])
    rec = m.as_records()
    assert list(rec[0]) == ["frequency_hz", "damping_ratio", "quality", "mpc", "mpd_deg", "mcf"]
    assert rec[0]["mpc"] == pytest.approx(1.0) and rec[0]["mcf"] == pytest.approx(0.0, abs=TOL)
    # [1, i, -1]: phi^T phi = 1 - 1 + 1 = 1, phi^H phi = 3, MPC = 1/9
    assert rec[1]["mpc"] == pytest.approx(1 / 9) and rec[1]["mcf"] == pytest.approx(8 / 9)


# ----------------------------------------------------------------------------- the run's CSVs


def _disk_model(n: int = 8) -> ModalModel:
    """Disk modes on one out-of-plane point per sector: standing waves ND 0, 1, 2 (real) and a travelling ND 3."""
    theta = 2 * np.pi * np.arange(n) / n
    shapes = np.column_stack([np.cos(0 * theta) + 0j, np.cos(theta) * np.exp(0.4j), np.sin(2 * theta),
                              np.exp(3j * theta)])
    return ModalModel([50.0, 80.0, 150.0, 300.0], np.full(4, 0.002), shapes, [(100 + k, 3) for k in range(n)])


def _rows(path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_the_runs_mode_tables_carry_the_indicators_in_range(tmp_path):
    """The run's EMA tables (bladetwin.outputs_ema), written from a RunResult-like object with a disk test and
    a full-assembly test (the full run is too slow for this check)."""
    from bladetwin.outputs_ema import _ema_tables

    asm_shapes = _random_shapes(5, 10, 5)
    asm_shapes[:, 0] = np.linspace(-1, 1, 10) * np.exp(1.2j)    # a normal mode
    asm = ModalModel(np.arange(1, 6) * 100.0, np.full(5, 0.003), asm_shapes, [(k + 1, 3) for k in range(10)])
    fit = lambda model: SimpleNamespace(model=model)  # noqa: E731
    res = SimpleNamespace(
        blades=SimpleNamespace(frequencies_hz=np.ones((2, 2)), deltas_pct=np.zeros((2, 2))),
        ema={"disk": (SimpleNamespace(type="disk"), fit(_disk_model())),
             "assembly": (SimpleNamespace(type="assembly"), fit(asm))},
        features=SimpleNamespace(measured_hz=np.ones((1, 2))), joints=[1])
    tables = _ema_tables(res, tmp_path, [])
    assert {"disk_modes.csv", "assembly_modes.csv"} <= {t["file"] for t in tables}

    rows = _rows(tmp_path / "assembly_modes.csv")
    assert len(rows) == 5 and {"MPC", "MPD (°)", "MCF"} <= set(rows[0])
    for r in rows:
        assert 0 <= float(r["MPC"]) <= 1 and 0 <= float(r["MPD (°)"]) <= 90 and 0 <= float(r["MCF"]) <= 1
    assert float(rows[0]["MPC"]) == pytest.approx(1.0) and float(rows[0]["MPD (°)"]) == pytest.approx(0, abs=1e-6)

    disk = _rows(tmp_path / "disk_modes.csv")
    assert [int(r["nodal_diameter"]) for r in disk] == [0, 1, 2, 3]
    assert [float(r["mpc"]) for r in disk] == pytest.approx([1, 1, 1, 0], abs=1e-6)   # the travelling wave: 0
    assert [float(r["mcf"]) for r in disk] == pytest.approx([0, 0, 0, 1], abs=1e-6)
    assert all(0 <= float(r["mpd_deg"]) <= 90 for r in disk)


# ----------------------------------------------------------------------------- the command line


def _run(argv):
    from bladetwin import cli_ema

    parser = argparse.ArgumentParser(prog="bladetwin")
    cli_ema.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    return args.func(args)


def test_ema_fit_prints_the_indicators_and_draws_the_cmif_under_the_diagram(tmp_path, capsys, monkeypatch):
    """A proportionally damped system has real modes: the fitted shapes' MPC is near 1. ``--background cmif``
    puts the CMIF under the stabilization diagram."""
    from bladetwin import cli_ema

    from .synth import synthetic_case

    freq, H, _ = synthetic_case(n_o=6, noise=0.002)
    path = tmp_path / "synthetic.uff"
    ema.write_frfs(path, ema.FRFSet(freq, H, [(k + 1, 3) for k in range(6)], [(1, 3)]))
    drawn = []
    monkeypatch.setattr(cli_ema, "atomic_savefig", lambda fig, *a, **k: drawn.append(fig))
    assert _run(["ema", "fit", str(path), "--method", "lscf", "--band", "20", "980", "--order", "40",
                 "--plot", str(tmp_path / "stab.png"), "--background", "cmif"]) == 0
    lines = capsys.readouterr().out.splitlines()
    head = lines[1].split()
    assert head[-4:] == ["MPC", "MPD", "[deg]", "MCF"]
    table = [line.split() for line in lines[2:] if line.split() and line.split()[0].isdigit()]
    assert len(table) >= 8
    assert min(float(r[-3]) for r in table) > 0.95          # MPC of each fitted mode
    assert drawn and drawn[0].axes[1].get_ylabel() == "CMIF"
    with pytest.raises(SystemExit):
        _run(["ema", "fit", str(path), "--background", "median"])
