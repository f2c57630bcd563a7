"""``bladetwin rom``: reduced-order models (build, modes, validate) of the academic twin (docs/rom.md).

* ``rom build``: Craig–Bampton disk (one slot) and Rubin blade, through the on-disk cache; of the twin, or
  with ``--model`` of an imported model (a ``model.toml``) or a campaign's ``[model]`` (docs/campaign.md).
* ``rom modes --assembly d1b|full``: ROM modes for a contact pattern (file) and blade mistuning δ.
* ``rom validate``: ROM-vs-FE tables (frequency errors, MAC at the measurement DOFs); ``--json`` gives
  ``{"disk": {"max_rel_err"}, "blade": {...}, "d1b": {"max_rel_err", "min_mac"}, "full": {..., "n_modes"}}``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from .cli_commands import command_help
from .cli_fe import add_model_args, build_model, parse_grid
from .util import format_table, print_json, step

__all__ = ["register", "build_roms", "model_from_args", "parse_delta"]


def _common(p: argparse.ArgumentParser) -> None:
    add_model_args(p)
    p.add_argument("--calibrate", action="store_true", help="calibrate the disk modulus to Table 1 first")
    p.add_argument("--n-cb", type=int, default=None, help="fixed-interface disk modes n_k (default: 100)")
    p.add_argument("--n-free", type=int, default=None, help="free-interface blade modes m (default: 50)")
    p.add_argument("--cache-dir", default=None,
                   help="cache folder for reduced models (default: $BLADETWIN_CACHE or .cache/bladetwin)")
    p.add_argument("--no-cache", action="store_true", help="always rebuild, never read or write the cache")
    p.add_argument("--formulation", default=None, choices=["exact", "paper"],
                   help="contact formulation of the blade (default: exact, see docs/rom.md)")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")


def register(sub) -> None:
    rom = sub.add_parser("rom", help=command_help("rom"),
                         description="Craig–Bampton disk + Rubin blade ROMs of the academic bladed disk.")
    rsub = rom.add_subparsers(dest="rom_command", metavar="SUBCOMMAND")
    rsub.required = True

    p = rsub.add_parser("build", help="reduce the disk (CB, one slot) and the blade (Rubin), cached")
    _common(p)
    p.add_argument("--slot", type=int, default=1, help="slot whose grids form the disk boundary (default: 1)")
    p.add_argument("--model", default=None, metavar="PATH",
                   help="reduce this model instead of the twin: a model.toml with an imported [model] table (as "
                        "`bladetwin fe export` writes), or a campaign folder or its campaign.toml, whose [model] "
                        "`bladetwin run` would use (docs/campaign.md); not with --level, --grid, --calibrate")
    p.set_defaults(func=_cmd_build)

    p = rsub.add_parser("modes", help="modes of the disk–one-blade or the full bladed-disk ROM")
    _common(p)
    p.add_argument("--assembly", required=True, choices=["d1b", "full"])
    p.add_argument("--slot", type=int, default=1, help="slot of the disk–one-blade model (default: 1)")
    p.add_argument("--pattern", default=None, metavar="FILE",
                   help="contact pattern file (.npz with L, R or .txt/.csv grids; docs/rom.md); one pattern is used "
                        "for every slot of the full assembly, an .npz with (N, rows, cols) arrays gives one per slot "
                        "(default: all nodes in contact)")
    p.add_argument("--delta", nargs="+", default=None, metavar="D",
                   help="blade mistuning δ (fractions, 0.01 = 1 %%): values for modes 1..k of the blade (d1b; for "
                        "full, the same for every blade), or one .csv/.npy file with one row per blade (full)")
    p.add_argument("--n", type=int, default=None, help="number of modes (default: 10 for d1b, 3N for full)")
    p.set_defaults(func=_cmd_modes)

    p = rsub.add_parser("validate", help="ROM vs FE reference: frequency errors and MAC tables")
    _common(p)
    p.add_argument("--seed", type=int, default=0, help="seed of the random patterns and δ (default: 0)")
    p.add_argument("--parts", nargs="+", default=["disk", "blade", "d1b", "full"],
                   choices=["disk", "blade", "d1b", "full"], help="which checks to run (default: all)")
    p.set_defaults(func=_cmd_validate)


def model_from_args(args, verbose: bool = True):
    """The FE model of the command line: the twin (``--level``, ``--grid``, ``--calibrate``) or ``--model``."""
    path = getattr(args, "model", None)
    if path is None:
        return build_model(args.level, parse_grid(args.grid), calibrate=args.calibrate, verbose=verbose)
    # The twin's options would be silently ignored with --model: its files fix the mesh and the grid.
    given = [flag for flag, on in (("--level", args.level != "default"), ("--grid", args.grid is not None),
                                   ("--calibrate", args.calibrate)) if on]
    if given:
        raise ValueError(f"--model {path}: the model's files fix its mesh and grid; drop {', '.join(given)}")
    from .model import load_model_file

    with step(f"importing the model of {path}", verbose):
        return load_model_file(path)


def build_roms(args, slot: int = 1, verbose: bool = True):
    """Build the FE model (:func:`model_from_args`), then the cached CB disk (``slot``) and Rubin blade."""
    from rom import cache
    from rom.craig_bampton import DEFAULT_N_CB_MODES, reduce_disk
    from rom.rubin import DEFAULT_N_FREE_MODES, reduce_blade

    bd = model_from_args(args, verbose)
    bd.check_slot(slot)
    n_cb = args.n_cb or DEFAULT_N_CB_MODES
    m = args.n_free or DEFAULT_N_FREE_MODES
    times = {}
    t0 = time.perf_counter()
    with step(f"Craig–Bampton disk, slot {slot}, n_k = {n_cb}", verbose):
        if args.no_cache:
            cb = reduce_disk(bd, (slot,), n_cb)
        else:
            cb = cache.cached_reduce_disk(bd, (slot,), n_cb, cache_dir=args.cache_dir)
    times["disk_cb_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    with step(f"Rubin blade, m = {m}", verbose):
        blade = reduce_blade(bd, m) if args.no_cache else cache.cached_reduce_blade(bd, m, cache_dir=args.cache_dir)
    times["blade_rubin_s"] = time.perf_counter() - t0
    return bd, cb, blade, times


def parse_delta(values: list[str] | None, n_blades: int, assembly: str, m: int):
    """``--delta`` values: floats (one blade's δ vector) or one .csv/.npy file with one row per blade.

    Checked here, before any model is built, against ``m`` retained blade modes (:func:`rom.mistuning.as_delta`).

    Returns
    -------
    None, ndarray of shape (m,) for d1b, or of shape (n_blades, m) for full
    """
    from rom.mistuning import as_delta, as_deltas

    if not values:
        return None
    if len(values) == 1 and Path(values[0]).suffix.lower() in (".csv", ".npy", ".txt"):
        path = Path(values[0])
        if path.is_dir():
            raise ValueError(f"{path}: is a directory; expected a δ file (.csv/.txt or .npy)")
        if not path.exists():
            raise FileNotFoundError(f"delta file not found: {path}")
        source = str(path)
        try:
            d = np.load(path, allow_pickle=False) if path.suffix.lower() == ".npy" else np.loadtxt(
                path, delimiter=",", ndmin=2)
        except (ValueError, OSError, EOFError, UnicodeDecodeError) as exc:
            raise ValueError(f"{path}: not a readable δ table ({' '.join(str(exc).split())})") from None
        if assembly == "d1b":
            d = np.asarray(d, float).ravel()
    else:
        source = "--delta"
        try:
            d = np.array([float(v) for v in values])
        except ValueError:
            raise ValueError(f"--delta takes numbers (fractions) or one .csv/.npy file, got {values}") from None
        if assembly != "d1b":
            d = np.tile(d, (n_blades, 1))
    try:
        return as_delta(d, m) if assembly == "d1b" else as_deltas(d, n_blades, m)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


def _cmd_build(args) -> int:
    bd, cb, blade, times = build_roms(args, args.slot, verbose=not args.json)
    out = {
        "disk_cb": {"n_k": cb.n_k, "n_b": cb.n_b, "slots": cb.meta.get("slots"), "n_dof_fe": bd.disk.n_dof,
                    "first_fixed_interface_hz": float(cb.frequencies_hz[0]), "seconds": times["disk_cb_s"]},
        "blade_rubin": {"m": blade.m, "n_r": blade.n_r, "n_b": blade.n_b, "n_dof_fe": bd.blade.n_dof,
                        "free_interface_hz": blade.frequencies_hz[:10].tolist(), "seconds": times["blade_rubin_s"]},
    }
    if args.json:
        print_json(out)
        return 0
    print(format_table(["component", "FE DOF", "reduced DOF", "modes", "time (s)"], [
        ["disk (CB)", f"{bd.disk.n_dof:,}", f"{cb.n:,}", f"n_k = {cb.n_k}", times["disk_cb_s"]],
        ["blade (Rubin)", f"{bd.blade.n_dof:,}", f"{blade.n_r + blade.m + blade.n_b:,}", f"m = {blade.m}",
         times["blade_rubin_s"]],
    ]))
    return 0


def _cmd_modes(args) -> int:
    from rom.academic import AcademicParams
    from rom.contact import ContactPattern
    from rom.pattern_io import load_patterns
    from rom.rom_assembly import DEFAULT_FORMULATION, solve_d1b, solve_full
    from rom.rubin import DEFAULT_N_FREE_MODES

    form = args.formulation or DEFAULT_FORMULATION
    verbose = not args.json
    # Read and check the user's files before the (minutes-long) model build, not after it.
    pats = load_patterns(args.pattern) if args.pattern else None
    grid = tuple(parse_grid(args.grid) or AcademicParams().grid)
    for k, p in enumerate(pats or []):
        if p.shape != grid:
            where = f"{args.pattern}" + (f", joint {k + 1}" if len(pats) > 1 else "")
            raise ValueError(f"{where}: grid shape {p.shape}, but the model's contact grid is {grid} (--grid)")
    delta = parse_delta(args.delta, AcademicParams().n_blades, args.assembly, args.n_free or DEFAULT_N_FREE_MODES)
    bd, cb, blade, _ = build_roms(args, 1, verbose=verbose)
    pats = pats or [ContactPattern.full(grid)]
    if args.assembly == "d1b":
        if len(pats) != 1:
            raise ValueError(f"--pattern for d1b must hold one pattern, {args.pattern} holds {len(pats)}")
        with step(f"disk–one-blade ROM, slot {args.slot}", verbose):
            res = solve_d1b(cb, blade, pats[0], args.slot, n_modes=args.n or 10, delta=delta, formulation=form)
    else:
        if len(pats) == 1:
            patterns = {s: pats[0] for s in range(1, bd.n_slots + 1)}
        elif len(pats) == bd.n_slots:
            patterns = {s + 1: p for s, p in enumerate(pats)}
        else:
            raise ValueError(f"--pattern for full must hold 1 or {bd.n_slots} patterns, got {len(pats)}")
        with step("full bladed-disk ROM (sparse hybrid)", verbose):
            res = solve_full(bd, blade, patterns, delta, n_modes=args.n, formulation=form)
    out = {"assembly": args.assembly, "formulation": form, "frequencies_hz": res.frequencies_hz.tolist(),
           "meas_labels": [list(lab) for lab in res.meas_labels], "meas_shapes": res.meas_shapes.tolist()}
    if args.json:
        print_json(out)
        return 0
    print(format_table(["mode", "frequency (Hz)"], [[k + 1, f] for k, f in enumerate(res.frequencies_hz)]))
    return 0


def _cmd_validate(args) -> int:
    from tqdm import tqdm

    from rom.validation import run_validation

    verbose = not args.json
    bd, cb, blade, _ = build_roms(args, 1, verbose=verbose)
    steps = {"disk": 2, "blade": 1, "d1b": 4, "full": 2}
    bar = tqdm(total=sum(steps[p] for p in args.parts), file=sys.stderr, disable=args.json, desc="validate")

    def progress(msg: str) -> None:
        bar.set_postfix_str(msg)
        bar.update(1)

    try:
        res = run_validation(bd, cb, blade, seed=args.seed, parts=tuple(args.parts), formulation=args.formulation,
                             progress=progress)
    finally:
        bar.close()
    summary: dict = {}
    for part, comps in res.items():
        s = {"max_rel_err": max(c.max_rel_err for c in comps), "n_modes": int(max(c.f_fe.size for c in comps))}
        if comps[0].mac is not None:
            s["min_mac"] = min(c.min_mac for c in comps)
        summary[part] = s
    summary["level"] = bd.params.level
    summary["grid"] = list(bd.params.grid)
    if args.json:
        print_json(summary)
        return 0
    for comps in res.values():
        for c in comps:
            print(f"\n{c.name}")
            head = ["mode", "FE (Hz)", "ROM (Hz)", "error (%)"] + (["MAC"] if c.mac is not None else [])
            rows = []
            for k in range(c.f_fe.size):
                row = [k + 1, f"{c.f_fe[k]:.2f}", f"{c.f_rom[k]:.2f}", f"{100 * c.rel_err[k]:+.4f}"]
                if c.mac is not None:
                    row.append(f"{c.mac[k]:.4f}")
                rows.append(row)
            print(format_table(head, rows))
    print("\nsummary")
    print(format_table(["check", "modes", "max |error| (%)", "min MAC"], [
        [p, s["n_modes"], f"{100 * s['max_rel_err']:.4f}", f"{s['min_mac']:.4f}" if "min_mac" in s else "—"]
        for p, s in summary.items() if isinstance(s, dict)
    ]))
    return 0
