"""``bladetwin fe``: the academic FE twin (model info, modes, mesh picture), imported FE components
(``--import``) and the export of the twin in the importable formats (``fe export``, docs/importers.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .cli_commands import command_help
from .cli_fe_import import add_import_args, cmd_info_import, import_from_args, import_info, import_modes, uses_import
from .util import atomic_savefig, atomic_write_text, format_table, print_json, step

__all__ = ["register", "add_model_args", "add_import_args", "parse_grid", "build_model", "fe_info", "fe_modes",
           "table1_rows", "import_from_args", "import_info", "import_modes"]

TABLE1_HZ = [1090.6, 1971.1, 2638.1, 3647.6, 4421.5, 5747.6, 5947.9]
TABLE1_ND = [2, 0, 3, 1, 4, 2, 0]
#: Modes solved to meet Table 1: each ND ≥ 1 row is a degenerate pair, plus spare modes for the nodal
#: diameters the table skips (12 + 6 = 18).
TABLE1_SOLVE_MODES = sum(1 if nd == 0 else 2 for nd in TABLE1_ND) + 6
TABLE3_HZ = [194.8, 540.4, 742.3, 1114.7, 1157.0, 1338.5, 1992.0, 2579.3, 2692.5, 3174.4]


def add_model_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--level", default="default", choices=["coarse", "default", "fine"],
                   help="mesh level (default: %(default)s; coarse is for tests)")
    p.add_argument("--grid", default=None, metavar="ROWSxCOLS",
                   help="contact grid per flank, e.g. 7x31 (default) or 3x7 for a quick look")


def register(sub) -> None:
    fe = sub.add_parser("fe", help=command_help("fe"),
                        description="Inspect the embedded academic bladed-disk FE model or an imported FE component; "
                                    "export the twin in the importable formats.")
    fsub = fe.add_subparsers(dest="fe_command", metavar="SUBCOMMAND")
    fsub.required = True

    p = fsub.add_parser("info", help="DOF counts, slots, grid, interface conformity (or an imported component's)")
    add_model_args(p)
    add_import_args(p)
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=_cmd_info)

    p = fsub.add_parser("modes", help="lowest elastic modes of the disk, the blade, the disk–one-blade, or an "
                                      "imported component")
    add_model_args(p)
    add_import_args(p)
    p.add_argument("--component", default=None, choices=["disk", "blade", "d1b"],
                   help="disk (free, the default), blade (free) or d1b (disk + blade in slot 1, fully bonded); "
                        "not with --import")
    p.add_argument("--n", type=int, default=10, help="number of elastic modes (default: %(default)s)")
    p.add_argument("--calibrate", action="store_true",
                   help="first set the disk modulus so its first mode is 1090.6 Hz (paper Table 1)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=_cmd_modes)

    p = fsub.add_parser("plot", help="mesh picture with contact grids and measurement nodes")
    add_model_args(p)
    p.add_argument("--out", required=True, help="output image, e.g. mesh.png")
    p.set_defaults(func=_cmd_plot)

    p = fsub.add_parser("demo", help="the FE demo: model info, calibrated disk vs Table 1, d1b vs Table 3, mesh")
    add_model_args(p)
    p.add_argument("--out", default="out/fe_demo", help="output folder (default: %(default)s)")
    p.set_defaults(func=_cmd_demo)

    p = fsub.add_parser("export", help="write the twin in the importable formats, with a ready [model] table",
                        description="Write the academic twin's disk and blade (K, M, DOF maps, coordinates, node "
                                    "sets, grids) as Matrix Market or OP4 files, and model.toml describing them.")
    add_model_args(p)
    p.add_argument("--format", dest="export_format", required=True, choices=["mtx", "op4"], help="matrix format")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--text", action="store_true", help="OP4 as text (default: binary)")
    p.set_defaults(func=_cmd_export)


def parse_grid(text: str | None):
    if text is None:
        return None
    try:
        rows, cols = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--grid must look like ROWSxCOLS, e.g. 7x31; got {text!r}") from None
    return rows, cols


def build_model(level: str = "default", grid=None, calibrate: bool = False, verbose: bool = True):
    """Build (and optionally calibrate) the academic bladed disk."""
    from rom.academic import AcademicParams, build_bladed_disk
    from rom.calibration import calibrate_bladed_disk

    kw = {"level": level}
    if grid is not None:
        kw["grid"] = grid
    params = AcademicParams(**kw)
    with step(f"building the academic bladed disk (level {level}, grid {params.grid[0]}×{params.grid[1]})", verbose):
        bd = build_bladed_disk(params)
    if calibrate:
        with step("calibrating the disk modulus to 1090.6 Hz (Table 1)", verbose):
            bd = calibrate_bladed_disk(bd, disk_target_hz=TABLE1_HZ[0])
    return bd


def fe_info(bd) -> dict:
    """The ``fe info`` JSON object."""
    return {
        "disk": {"n_dof": bd.disk.n_dof, "n_nodes": bd.disk.n_nodes, "n_slots": bd.n_slots,
                 "grid": list(bd.params.grid), "n_elements": int(bd.disk.meta["n_elements"])},
        "blade": {"n_dof": bd.blade.n_dof, "n_nodes": bd.blade.n_nodes, "n_elements": int(bd.blade.meta["n_elements"])},
        "max_interface_gap_m": max(bd.interface_gap(s) for s in range(1, bd.n_slots + 1)),
        "level": bd.params.level,
        "disk_E_pa": float(bd.disk.meta["E"]),
        "blade_E_pa": float(bd.blade.meta["E"]),
    }


def fe_modes(bd, component: str, n: int) -> dict:
    """The ``fe modes`` JSON object (elastic modes only; nodal diameters for the disk)."""
    from rom.contact import ContactPattern
    from rom.fe_assembly import assemble_fe
    from rom.solver import nodal_diameters, solve_modes

    if not (isinstance(n, int) and 1 <= n <= 200):
        raise ValueError(f"--n must be an integer in 1..200, got {n}")
    if component == "d1b":
        asm = assemble_fe(bd, {1: ContactPattern.full(bd.params.grid)})
        K, M = asm.K, asm.M
    else:
        comp = getattr(bd, component)
        K, M = comp.K, comp.M
    sol = solve_modes(K, M, n)
    out = {"component": component, "frequencies_hz": sol.frequencies_hz.tolist(), "n_rigid": sol.n_rigid,
           "n_dof": int(K.shape[0])}
    if component == "disk":
        out["nodal_diameters"] = nodal_diameters(sol.shapes[3 * bd.disk.node_set("meas") + 2]).tolist()
    if component == "d1b":
        # Character of each mode: share of kinetic energy in the blade, and the disk's dominant harmonic.
        full = asm.Z @ sol.shapes
        nd = bd.disk.n_dof
        blade_ke = np.einsum("ij,ij->j", full[nd:], bd.blade.M @ full[nd:])
        out["blade_energy_fraction"] = (blade_ke / np.einsum("ij,ij->j", sol.shapes, M @ sol.shapes)).tolist()
        out["disk_nodal_diameters"] = nodal_diameters(full[3 * bd.disk.node_set("meas") + 2]).tolist()
    return out


def _cmd_export(args) -> int:
    from rom.importers import export_bladed_disk

    bd = build_model(args.level, parse_grid(args.grid))
    with step(f"writing the twin as {args.export_format} files to {args.out}"):
        done = export_bladed_disk(bd, args.out, format=args.export_format, binary=not args.text)
    for f in done.files:
        print(f"wrote {f}")
    print(f"\n{done.model_toml} holds the [model] table: copy it into a campaign.toml, or read it with "
          "rom.importers.read_model_toml")
    return 0


def _cmd_info(args) -> int:
    if uses_import(args):
        return cmd_info_import(args)
    bd = build_model(args.level, parse_grid(args.grid), verbose=not args.json)
    info = fe_info(bd)
    if args.json:
        print_json(info)
        return 0
    p = bd.params
    print(format_table(["component", "nodes", "DOF", "hex20 elements"], [
        ["disk", f"{info['disk']['n_nodes']:,}", f"{info['disk']['n_dof']:,}", f"{info['disk']['n_elements']:,}"],
        ["blade", f"{info['blade']['n_nodes']:,}", f"{info['blade']['n_dof']:,}", f"{info['blade']['n_elements']:,}"],
    ]))
    print(f"\nslots: {bd.n_slots}, contact grid per flank: {p.grid[0]}×{p.grid[1]} "
          f"({2 * 3 * p.grid[0] * p.grid[1]} interface DOFs per slot)")
    print(f"disk Ø{2e3 * p.disk_outer_radius:.0f} mm × {1e3 * p.disk_thickness:.1f} mm, "
          f"bore Ø{2e3 * p.bore_radius:.0f} mm; "
          f"blade length {1e3 * p.blade_length:.1f} mm, assembled Ø{2e3 * p.blade_tip_radius:.0f} mm")
    print(f"largest disk/blade interface gap: {info['max_interface_gap_m']:.2e} m")
    return 0


def _cmd_modes(args) -> int:
    if uses_import(args):
        if args.component is not None or args.calibrate:
            raise ValueError("--component and --calibrate apply to the twin, not with --import")
        comp, _ = import_from_args(args, verbose=not args.json)
        with step(f"solving {args.n} modes of {comp.name}", not args.json):
            out = import_modes(comp, args.n)
        if args.json:
            print_json(out)
            return 0
        print(format_table(["mode", "frequency (Hz)"], [[k + 1, f] for k, f in enumerate(out["frequencies_hz"])]))
        print(f"\n{out['n_rigid']} rigid-body modes reported apart; {out['n_dof']:,} DOF")
        return 0
    args.component = args.component or "disk"
    # --calibrate changes the disk only: the blade needs no calibration solve, and for the free disk the
    # calibrated modes are the uncalibrated ones times 1090.6 / f₁ (one solve instead of two).
    calibrate_first = args.calibrate and args.component == "d1b"
    bd = build_model(args.level, parse_grid(args.grid), calibrate=calibrate_first, verbose=not args.json)
    with step(f"solving {args.n} modes of the {args.component}", not args.json):
        out = fe_modes(bd, args.component, args.n)
    if args.calibrate and args.component == "disk":
        scale = TABLE1_HZ[0] / out["frequencies_hz"][0]
        out["frequencies_hz"] = [f * scale for f in out["frequencies_hz"]]
    if args.json:
        print_json(out)
        return 0
    f = out["frequencies_hz"]
    if args.component == "disk":
        rows = [[k + 1, fk, out["nodal_diameters"][k]] for k, fk in enumerate(f)]
        print(format_table(["mode", "frequency (Hz)", "ND"], rows))
    else:
        print(format_table(["mode", "frequency (Hz)"], [[k + 1, fk] for k, fk in enumerate(f)]))
    print(f"\n{out['n_rigid']} rigid-body modes reported apart; {out['n_dof']:,} DOF")
    return 0


def _cmd_plot(args) -> int:
    from rom.plots import plot_mesh

    bd = build_model(args.level, parse_grid(args.grid))
    with step("drawing the mesh"):
        fig = plot_mesh(bd)
        path = atomic_savefig(fig, args.out)
    print(f"wrote {path}")
    return 0


def table1_rows(bd, sol=None, scale: float = 1.0) -> list[list]:
    """Free-disk modes beside the paper's Table 1, paired by nodal diameter (k-th family of each ND).

    ``sol`` is the disk's ``ModalSolution`` (``TABLE1_SOLVE_MODES`` are solved when not given); ``scale`` multiplies its
    frequencies (calibrating E scales every frequency of the homogeneous disk by one factor).
    Rows: [mode, Table 1 Hz, Table 1 ND, model Hz or "—", model ND, difference %].
    """
    from rom.solver import nodal_diameters, solve_modes

    sol = sol if sol is not None else solve_modes(bd.disk.K, bd.disk.M, TABLE1_SOLVE_MODES)
    nd = nodal_diameters(sol.shapes[3 * bd.disk.node_set("meas") + 2])
    f = sol.frequencies_hz * scale
    keep = [0] + [i for i in range(1, f.size) if f[i] / f[i - 1] - 1 > 1e-4]
    used: set[int] = set()
    rows = []
    for k, (ft, ndt) in enumerate(zip(TABLE1_HZ, TABLE1_ND, strict=True)):
        match = next((i for i in keep if nd[i] == ndt and i not in used), None)
        if match is None:
            rows.append([k + 1, ft, ndt, "—", "—", "—"])
            continue
        used.add(match)
        rows.append([k + 1, ft, ndt, float(f[match]), int(nd[match]), 100 * (f[match] / ft - 1)])
    return rows


def table3_rows(d1b: dict) -> list[list]:
    """Disk–one-blade modes beside Table 3 (by index), with the character of each model mode."""
    rows = []
    for k, f in enumerate(d1b["frequencies_hz"][: len(TABLE3_HZ)]):
        e = d1b["blade_energy_fraction"][k]
        kind = f"blade ({100 * e:.0f} % KE)" if e > 0.5 else f"disk ND{d1b['disk_nodal_diameters'][k]}"
        rows.append([k + 1, TABLE3_HZ[k], f, 100 * (f / TABLE3_HZ[k] - 1), kind])
    return rows


def _cmd_demo(args) -> int:
    import json

    from rom.plots import plot_mesh

    print("bladetwin fe demo: the FE demo on the embedded academic bladed-disk twin (model info, first modes, "
          "mesh picture).\n")
    out = Path(args.out)
    from rom.calibration import calibrate_bladed_disk
    from rom.solver import solve_modes

    bd = build_model(args.level, parse_grid(args.grid))
    # One modal solve serves the calibration and Table 1: calibrating E scales every frequency of the
    # homogeneous disk by the same factor, so the calibrated modes are these times 1090.6 / f₁.
    with step("free disk modes, calibrated to 1090.6 Hz, vs paper Table 1"):
        sol = solve_modes(bd.disk.K, bd.disk.M, TABLE1_SOLVE_MODES)
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
