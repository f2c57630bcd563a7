"""``bladetwin fe --import``: the options, reading and summaries of an imported FE component (docs/importers.md).

The helpers of :mod:`bladetwin.cli_fe` for the ``--import`` path of ``fe info`` and ``fe modes``; this module
registers no command of its own.
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

from .util import format_table, print_json, step

__all__ = ["add_import_args", "import_from_args", "import_info", "import_modes"]


def add_import_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("imported component (docs/importers.md)")
    g.add_argument("--import", dest="import_path", default=None, metavar="PATH",
                   help="work on an imported FE component instead of the twin: an ANSYS .full file, an OP4 file, "
                        "or the Matrix Market file of K")
    g.add_argument("--format", dest="import_format", default=None, choices=["full", "mtx", "op4"],
                   help="format of --import (default: from its suffix)")
    g.add_argument("--mass", default=None, metavar="PATH", help="Matrix Market file of M (mtx)")
    g.add_argument("--dofmap", default=None, metavar="CSV", help="row,node,dir for every matrix row (mtx, op4)")
    g.add_argument("--coords", default=None, metavar="CSV", help="node,x,y,z (mtx, op4)")
    g.add_argument("--node-sets", default=None, metavar="CSV", help="set,node (mtx, op4)")
    g.add_argument("--archive", default=None, metavar="CDB", help="ANSYS .cdb archive: coordinates, components (full)")
    g.add_argument("--matrices", default=None, metavar="K,M", help="names of K and M in the OP4 file (op4)")
    g.add_argument("--units", default="SI", metavar="SYSTEM",
                   help="unit system of the files: SI, mm-t-s, mm-kg-ms, cm-g-s or in-lbf-s (default: %(default)s)")


def uses_import(args) -> bool:
    """Whether the command works on ``--import``; the import-only options are refused without it."""
    if args.import_path is not None:
        return True
    used = [f"--{k.replace('_', '-')}" for k in ("mass", "dofmap", "coords", "node_sets", "archive", "matrices")
            if getattr(args, k) is not None]
    used += ["--format"] if args.import_format is not None else []
    used += ["--units"] if args.units != "SI" else []
    if used:
        raise ValueError(f"{', '.join(used)} only apply with --import PATH")
    return False


def import_from_args(args, verbose: bool = True):
    """The component ``--import`` names, with its side files; unit warnings go to stderr as one line each.

    Returns
    -------
    component : rom.component.Component
    warnings_ : list of str
    """
    from rom.importers import UnitsWarning, import_component

    matrices = None
    if args.matrices is not None:
        names = [n.strip() for n in args.matrices.split(",")]
        if len(names) != 2 or not all(names):
            raise ValueError(f"--matrices must be two names K,M, got {args.matrices!r}")
        matrices = (names[0], names[1])
    with warnings.catch_warnings(record=True) as caught, step(f"importing {args.import_path}", verbose):
        warnings.simplefilter("always", UnitsWarning)
        comp = import_component(args.import_path, format=args.import_format, mass=args.mass, dofmap=args.dofmap,
                                coords=args.coords, node_sets=args.node_sets, archive=args.archive,
                                matrices=matrices, units=args.units)
    notes = [" ".join(str(w.message).split()) for w in caught if issubclass(w.category, UnitsWarning)]
    for note in notes:
        print(f"bladetwin: warning: {note}", file=sys.stderr)
    for w in caught:  # any other warning: shown as Python would have shown it
        if not issubclass(w.category, UnitsWarning):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return comp, notes


def import_info(comp) -> dict:
    """The ``fe info --import`` JSON object."""
    X = comp.coords
    known = bool(np.isfinite(X).all())
    return {
        "component": comp.name,
        "file": comp.meta.get("source"),
        "format": comp.meta.get("format"),
        "units": comp.meta.get("units"),
        "units_conversion": comp.meta.get("units_conversion"),
        "storage": comp.meta.get("storage"),
        "n_dof": comp.n_dof,
        "n_nodes": comp.n_nodes,
        "n_constrained_dofs": len(comp.meta.get("constrained_dofs") or []),
        "nnz_K": int(comp.K.nnz),
        "nnz_M": int(comp.M.nnz),
        "mass_kg": comp.mass(),
        "bounding_box_m": [X.min(axis=0).tolist(), X.max(axis=0).tolist()] if known else None,
        "node_sets": {k: int(np.asarray(v).size) for k, v in comp.node_sets.items()},
    }


def import_modes(comp, n: int) -> dict:
    """The ``fe modes --import`` JSON object (the twin's keys: frequencies_hz, n_rigid, n_dof)."""
    from rom.solver import solve_modes

    if not (isinstance(n, int) and 1 <= n <= 200):
        raise ValueError(f"--n must be an integer in 1..200, got {n}")
    sol = solve_modes(comp.K, comp.M, n)
    return {"component": comp.name, "frequencies_hz": sol.frequencies_hz.tolist(), "n_rigid": sol.n_rigid,
            "n_dof": int(comp.K.shape[0])}


def cmd_info_import(args) -> int:
    """``fe info --import``: the imported component's counts, file, units, size and node sets (or JSON)."""
    comp, notes = import_from_args(args, verbose=not args.json)
    info = import_info(comp)
    if notes:
        info["warnings"] = notes
    if args.json:
        print_json(info)
        return 0
    print(format_table(["component", "nodes", "DOF", "constrained DOF", "nnz(K)", "mass (kg)"], [
        [info["component"], f"{info['n_nodes']:,}", f"{info['n_dof']:,}", f"{info['n_constrained_dofs']:,}",
         f"{info['nnz_K']:,}", f"{info['mass_kg']:.4g}"]]))
    print(f"\n{info['file']} ({info['format']}; {info['storage']})")
    print(f"units: {info['units_conversion']}")
    if info["bounding_box_m"] is not None:
        lo, hi = np.array(info["bounding_box_m"])
        print("bounding box: " + " × ".join(f"{v * 1e3:.4g}" for v in hi - lo) + " mm")
    else:
        print("no node coordinates (give --coords, or --archive for a .full file)")
    if info["node_sets"]:
        print("node sets: " + ", ".join(f"{k} ({v})" for k, v in info["node_sets"].items()))
    return 0
