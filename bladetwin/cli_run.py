"""``bladetwin run``: the main job.

Until the identification pipeline exists, it runs the FE demo on the embedded academic twin: model info,
the calibrated free disk beside the paper's Table 1, the first modes of the blade and the disk–one-blade,
and a mesh picture in ``out/fe_demo/``.
"""

from __future__ import annotations

from pathlib import Path

from .cli_fe import TABLE1_HZ, add_model_args, build_model, fe_info, fe_modes, parse_grid, table1_rows
from .util import atomic_savefig, atomic_write_text, format_table, step

__all__ = ["register"]

TABLE3_HZ = [194.8, 540.4, 742.3, 1114.7, 1157.0, 1338.5, 1992.0, 2579.3, 2692.5, 3174.4]


def register(sub) -> None:
    p = sub.add_parser("run", help="the main job (for now: the FE demo on the academic twin)",
                       description="Run the main job. The identification pipeline is not built yet, so this runs "
                                   "the FE demo: model info, first modes, and a mesh picture.")
    p.add_argument("campaign", nargs="?", default=None, help="campaign folder (not used by the FE demo yet)")
    add_model_args(p)
    p.add_argument("--out", default="out/fe_demo", help="output folder (default: %(default)s)")
    p.set_defaults(func=_cmd_run)


def table3_rows(d1b: dict) -> list[list]:
    """Disk–one-blade modes beside Table 3 (by index), with the character of each model mode."""
    rows = []
    for k, f in enumerate(d1b["frequencies_hz"][: len(TABLE3_HZ)]):
        e = d1b["blade_energy_fraction"][k]
        kind = f"blade ({100 * e:.0f} % KE)" if e > 0.5 else f"disk ND{d1b['disk_nodal_diameters'][k]}"
        rows.append([k + 1, TABLE3_HZ[k], f, 100 * (f / TABLE3_HZ[k] - 1), kind])
    return rows


def _cmd_run(args) -> int:
    import json

    from rom.plots import plot_mesh

    print("bladetwin run: the identification pipeline is not built yet; running the FE demo on the "
          "embedded academic bladed-disk twin (model info, first modes, mesh picture).\n")
    out = Path(args.out)
    from rom.calibration import calibrate_bladed_disk
    from rom.solver import solve_modes

    bd = build_model(args.level, parse_grid(args.grid))
    # One modal solve serves the calibration and Table 1: calibrating E scales every frequency of the
    # homogeneous disk by the same factor, so the calibrated modes are these times 1090.6 / f₁.
    with step("free disk modes, calibrated to 1090.6 Hz, vs paper Table 1"):
        sol = solve_modes(bd.disk.K, bd.disk.M, 18)
        f1 = float(sol.frequencies_hz[0])
        bd = calibrate_bladed_disk(bd, disk_target_hz=TABLE1_HZ[0], disk_current_hz=f1)
        t1 = table1_rows(bd, sol, scale=TABLE1_HZ[0] / f1)
    info = fe_info(bd)
    print(f"disk {info['disk']['n_dof']:,} DOF, blade {info['blade']['n_dof']:,} DOF, {bd.n_slots} slots, "
          f"grid {bd.params.grid[0]}×{bd.params.grid[1]}, interface gap {info['max_interface_gap_m']:.1e} m, "
          f"calibrated disk E = {info['disk_E_pa'] / 1e9:.1f} GPa\n")
    print(format_table(["mode", "Table 1 (Hz)", "ND", "model (Hz)", "model ND", "diff (%)"], t1))
    with step("free blade modes"):
        blade = fe_modes(bd, "blade", 6)
    print(format_table(["mode", "blade (Hz)"], [[k + 1, f] for k, f in enumerate(blade["frequencies_hz"])]))
    with step("disk–one-blade (slot 1, fully bonded) modes vs paper Table 3"):
        d1b = fe_modes(bd, "d1b", 10)
    print(format_table(["mode", "Table 3 (Hz)", "model (Hz)", "diff (%)", "model mode"], table3_rows(d1b)))
    with step("drawing the mesh"):
        png = atomic_savefig(plot_mesh(bd), out / "mesh.png")
    summary = {"info": info, "disk_table1": t1, "blade": blade, "d1b": d1b}
    atomic_write_text(out / "fe_demo.json", json.dumps(summary, indent=2))
    print(f"\nwrote {png} and {out / 'fe_demo.json'}")
    return 0
