"""``bladetwin ema``: fit UFF FRFs (``ema fit``) and build campaign tables (``ema blades|disk|assembly DIR``)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .cli_commands import command_help
from .util import atomic_savefig

__all__ = ["register"]


def _add_fit_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", choices=("lscf", "lsrf"), default="lsrf",
                   help="pole estimator (default: lsrf, the library's default: it separates close modes at every "
                        "order and stays conditioned on narrow bands; docs/ema.md)")
    p.add_argument("--band", nargs=2, type=float, metavar=("F1", "F2"), help="band in Hz (default: all lines)")
    p.add_argument("--order", type=_order, default=60, help="highest model order, or 'auto': grown from 20 by "
                   "doubling until the selection stops gaining modes (ema.fit_auto_order; default 60)")
    p.add_argument("--bands", type=int, default=1, help="fit band by band in this many sub-bands (dense spectra)")
    p.add_argument("--freq-tol", type=float, default=0.01, help="stability: relative frequency change (0.01)")
    p.add_argument("--damping-tol", type=float, default=0.05, help="stability: relative damping change (0.05)")
    p.add_argument("--mac-min", type=float, default=0.95, help="stability: minimum MAC (0.95)")
    p.add_argument("--no-refine", action="store_true", help="keep the estimator's poles (no nonlinear refinement)")
    p.add_argument("--families", action="store_true",
                   help="resolve dense mode families with a rank-one residue fit (a whole bladed disk's test)")
    p.add_argument("--form", choices=("receptance", "mobility", "accelerance"),
                   help="FRF form when the files do not state it")
    p.add_argument("--nonfinite", choices=("refuse", "drop"), default="refuse",
                   help="NaN/inf lines: refuse the file (default) or drop those lines from every FRF, with a "
                        "warning that names them")


def _order(text: str) -> int | str:
    """``--order``: a positive integer or ``auto``."""
    if text == "auto":
        return text
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected an integer ≥ 2 or 'auto'") from None
    if value < 2:
        raise argparse.ArgumentTypeError(f"{text!r}: expected an integer ≥ 2 or 'auto'")
    return value


def _criteria(args: argparse.Namespace):
    from ema import StabilityCriteria

    return StabilityCriteria(freq_tol=args.freq_tol, damping_tol=args.damping_tol, mac_min=args.mac_min)


def _method(args: argparse.Namespace) -> str:
    if args.method == "lscf" and args.bands > 1:
        print("bladetwin: warning: LSCF band-by-band fitting is poorly conditioned on narrow bands; "
              "--method lsrf recovers far more modes on dense spectra (docs/ema.md)", file=sys.stderr)
    return args.method


def _fit(frf, args: argparse.Namespace, freqs=None):
    from ema import FitSettings, fit, fit_auto_order

    if args.bands < 1:
        raise ValueError(f"--bands must be ≥ 1, got {args.bands}")
    band = tuple(args.band) if args.band else None
    settings = FitSettings(method=_method(args), criteria=_criteria(args), n_bands=args.bands,
                           refine=not args.no_refine)
    order = args.order
    if order == "auto":
        result, order = fit_auto_order(frf, band, settings, frequencies_hz=freqs)
        print(f"model order chosen from the data: {order}", file=sys.stderr)
        if not getattr(args, "families", False):
            return result
        # the families grow from the fit at the chosen order
    return fit(frf, band, settings, max_order=order, frequencies_hz=freqs, progress=sys.stderr.isatty(),
               families=getattr(args, "families", False))


def _print_modes(result, out=None) -> None:
    out = out or sys.stdout
    m = result.model
    print(f"{result.diagram.method}: {m.n_modes} modes in {result.diagram.band_hz[0]:g}-"
          f"{result.diagram.band_hz[1]:g} Hz", file=out)
    mq = m.mode_quality()
    print(f"{'mode':>4}  {'f [Hz]':>12}  {'zeta [%]':>9}  {'quality':>7}  {'dominance':>9}  {'MPC':>5}  "
          f"{'MPD [deg]':>9}  {'MCF':>5}", file=out)
    for k in range(m.n_modes):
        q = m.quality[k] if m.quality is not None else float("nan")
        print(f"{k + 1:>4}  {m.frequencies_hz[k]:>12.4f}  {100 * m.damping_ratio[k]:>9.4f}  {q:>7.2f}  "
              f"{result.dominance[k]:>9.2f}  {mq.mpc[k]:>5.3f}  {mq.mpd_deg[k]:>9.2f}  {mq.mcf[k]:>5.3f}", file=out)
    if result.quality.size:
        print(f"FRF fit quality: min {np.min(result.quality):.4f}, mean {np.mean(result.quality):.4f}", file=out)


def _cmd_fit(args: argparse.Namespace) -> int:
    from ema import read_frfs

    if args.plot and Path(args.plot).is_dir():
        # Refuse before the fit, not after it.
        raise ValueError(f"--plot {args.plot}: is a directory; expected an image file name such as stab.png")
    frf = read_frfs(args.files, form=args.form, nonfinite=args.nonfinite)
    result = _fit(frf, args, freqs=args.freqs)
    if args.plot:
        from ema.plots import plot_stabilization

        fig = plot_stabilization(result.diagram, frf, indicator=args.background,
                                 selected_hz=result.model.frequencies_hz)
        atomic_savefig(fig, args.plot, dpi=120)
    if args.json:
        payload = result.as_dict()
        payload["files"] = [str(f) for f in args.files]
        print(json.dumps(payload, indent=2))
    else:
        _print_modes(result)
    return 0


def _uff_files(directory: str) -> list[Path]:
    d = Path(directory)
    if not d.is_dir():
        raise FileNotFoundError(f"{d}: not a directory")
    files = sorted(p for p in d.iterdir() if p.suffix.lower() in (".uff", ".unv"))
    if not files:
        raise FileNotFoundError(f"{d}: no .uff files")
    return files


def _out_dir(args: argparse.Namespace) -> Path:
    return Path(args.out) if args.out else Path("out") / "ema" / Path(args.dir).resolve().name


def _emit(tables: dict, args: argparse.Namespace) -> None:
    """Write each table as ``<name>.csv`` and print them: text tables, or ONE JSON document for ``--json``.

    The JSON document maps each table's name to pandas' ``split`` layout (``columns``, ``index``, ``data``)
    and adds ``written``, the CSV paths.
    """
    from ema import write_table

    written = {name: str(write_table(table, _out_dir(args) / f"{name}.csv")) for name, table in tables.items()}
    if args.json:
        doc = {name: json.loads(table.to_json(orient="split", double_precision=10)) for name, table in tables.items()}
        doc["written"] = list(written.values())
        print(json.dumps(doc, indent=2))
        return
    for name, table in tables.items():
        print(f"{name}\n{table.to_string(float_format=lambda v: f'{v:.4f}')}\n")
        print(f"written: {written[name]}", file=sys.stderr)


def _fit_each(args: argparse.Namespace) -> dict:
    from ema import read_uff

    models = {}
    for path in _uff_files(args.dir):
        result = _fit(read_uff(path, form=args.form, nonfinite=args.nonfinite), args)
        models[path.stem] = result.model
    return models


def _cmd_blades(args: argparse.Namespace) -> int:
    from ema import blade_deltas
    from ema.campaign import frequency_table

    models = _fit_each(args)
    kw = {"freq_window": args.freq_window}
    _emit({"blade_frequencies": frequency_table(models, **kw), "blade_deltas": blade_deltas(models, **kw)}, args)
    return 0


def _cmd_joints(args: argparse.Namespace) -> int:
    from ema import joint_frequencies

    _emit({"joint_frequencies": joint_frequencies(_fit_each(args), freq_window=args.freq_window)}, args)
    return 0


def _cmd_disk(args: argparse.Namespace) -> int:
    from ema import disk_modes, read_frfs

    frf = read_frfs(_uff_files(args.dir), form=args.form, nonfinite=args.nonfinite)
    model = _fit(frf, args).model
    _emit({"disk_modes": disk_modes(model).assign(**model.mode_quality().columns())}, args)
    return 0


def _cmd_assembly(args: argparse.Namespace) -> int:
    import pandas as pd

    from ema import read_frfs

    result = _fit(read_frfs(_uff_files(args.dir), form=args.form, nonfinite=args.nonfinite), args)
    m = result.model
    table = pd.DataFrame(
        {"frequency_hz": m.frequencies_hz, "damping_ratio": m.damping_ratio, "dominance": result.dominance,
         "quality": m.quality if m.quality is not None else np.nan, **m.mode_quality().columns()},
        index=pd.Index(np.arange(1, m.n_modes + 1), name="mode"),
    )
    _emit({"assembly_modes": table}, args)
    return 0


def register(subparsers) -> None:
    """Add the ``ema`` command group to the ``bladetwin`` parser."""
    ema = subparsers.add_parser("ema", help=command_help("ema"))
    sub = ema.add_subparsers(dest="ema_command", metavar="SUBCOMMAND")
    sub.required = True

    p = sub.add_parser("fit", help="identify modes from UFF FRFs (58/58b)")
    p.add_argument("files", nargs="+", metavar="FILE.uff", help="UFF files, merged into one FRF matrix")
    _add_fit_options(p)
    sel = p.add_mutually_exclusive_group()
    sel.add_argument("--auto", action="store_true", help="automatic selection (default)")
    sel.add_argument("--freqs", nargs="+", type=float, metavar="F", help="select modes near these frequencies [Hz]")
    p.add_argument("--plot", metavar="OUT.png", help="write the stabilization diagram")
    p.add_argument("--background", choices=("mean", "cmif"), default="mean",
                   help="curve under the --plot diagram: the mean |FRF| (default) or the CMIF, the squared "
                        "singular values of the FRF matrix at each line (with several references, its curves "
                        "separate close and repeated modes)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=_cmd_fit)

    for name, func, what in (
        ("blades", _cmd_blades, "blade frequencies and deltas (Eq. 37), one UFF per blade"),
        ("disk", _cmd_disk, "disk modes with nodal diameters, one out-of-plane point per sector"),
        ("assembly", _cmd_assembly, "assembly modes (use --families for dense blade families)"),
        ("joints", _cmd_joints, "disk-one-blade frequencies, one UFF per joint"),
    ):
        q = sub.add_parser(name, help=what)
        q.add_argument("dir", metavar="DIR", help="folder with .uff files")
        _add_fit_options(q)
        q.add_argument("--freq-window", type=float, default=0.1, help="mode tracking frequency window (0.1)")
        q.add_argument("--out", metavar="DIR", help="folder for the CSV tables (default out/ema/<DIR name>)")
        q.add_argument("--json", action="store_true", help="print JSON instead of a table")
        q.set_defaults(func=func)
