"""``bladetwin identify``: the identification stages on a campaign folder (paper §6–§7, docs/identify.md).

* ``identify patterns``: known films → contact maps → PCA sampler → synthetic patterns SP-1..n per flank;
* ``identify sensitivity``: tuned-blade d1b frequencies over all pattern pairs, tracked by MAC; feature modes;
* ``identify dataset``: δ grid (from the measured blade deltas) × pattern pairs → Parquet, by reanalysis;
* ``identify predict``: EMA of the blades and the d1b tests → two-step k-NN → a pattern for every joint;
* ``identify validate``: geometric (vs the truth of a virtual campaign, or the filmed joints) and dynamic
  (tracked d1b ROM frequencies of the feature modes with the predicted pattern vs with the reference one),
  beside the baseline that gives every joint the mean known pattern.

Stages read the previous stage's file from the output folder (``--out``, default ``out/<campaign>``), so
they can be run one by one; each prints a table, or JSON with ``--json``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from .cli_commands import command_help
from .cli_options import add_stage_options, stage_options
from .stages import names
from .util import atomic_savefig, atomic_write_text, format_table, print_json

__all__ = ["register", "save_synthetic", "load_synthetic"]

DEFAULT_CAMPAIGN = "measurements/academic"


def register(sub) -> None:
    grp = sub.add_parser("identify", help=command_help("identify"),
                         description="Identification stages on a campaign folder (docs/identify.md). Each runs the "
                                     "nodes of `bladetwin run` it needs, from the same store: after a run with the "
                                     "same settings, nothing is recomputed.")
    isub = grp.add_subparsers(dest="identify_command", metavar="SUBCOMMAND")
    isub.required = True

    def common(name: str, help: str, func, *, dask: bool = False, plot: bool = True):
        p = isub.add_parser(name, help=help)
        p.add_argument("campaign", nargs="?", default=DEFAULT_CAMPAIGN,
                       help="campaign folder with campaign.toml (default: %(default)s)")
        p.add_argument("--out", default=None, help="output folder (default: out/<campaign name>)")
        add_stage_options(p)
        if dask:
            p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                           help="build on an existing Dask cluster, e.g. tcp://host:8786 (the parts stay here)")
        p.add_argument("--json", action="store_true", help="print JSON instead of tables")
        p.add_argument("--quiet", action="store_true", help="no progress on stderr")
        if plot:
            p.add_argument("--no-plot", action="store_true", help="skip the figures")
        p.set_defaults(func=func)

    common("patterns", "synthetic contact patterns from the known joints' films (PCA, Eqs. 23-32)", _cmd_patterns)
    common("sensitivity", "d1b frequency spread over the pattern pairs; feature modes (§6.2)", _cmd_sensitivity)
    common("dataset", "δ grid × pattern pairs → tracked d1b frequencies (§6.3)", _cmd_dataset, dask=True, plot=False)
    common("predict", "two-step weighted k-NN and its refinement: a contact pattern for every joint (§6.4)",
           _cmd_predict, plot=False)
    common("validate", "geometric and disk–one-blade validation of the identified patterns (§7)", _cmd_validate)


# ------------------------------------------------------------------------------------------------ files
def _out(args, campaign) -> Path:
    out = Path(args.out) if args.out else Path("out") / campaign.name
    out.mkdir(parents=True, exist_ok=True)
    return out


def save_synthetic(path: Path, sp) -> Path:
    """Synthetic patterns to ``.npz`` (no pickles: labels as a fixed-width string array); atomic."""
    from rom.fileio import atomic_path

    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, L=sp.L, R=sp.R, gray_L=sp.gray_L, gray_R=sp.gray_R, labels_L=np.array(sp.labels_L, dtype="U"),
                 labels_R=np.array(sp.labels_R, dtype="U"), scale=np.float64(sp.scale),
                 threshold=np.asarray(sp.threshold, np.float64))
    return path


def load_synthetic(path: str | Path):
    """Read :func:`save_synthetic`'s file back into a :class:`identify.synthetic.SyntheticPatterns`."""
    import zipfile

    from identify.errors import IdentifyError
    from identify.synthetic import SyntheticPatterns

    path = Path(path)
    if not path.is_file():
        raise IdentifyError(f"{path}: no synthetic-pattern file; run `bladetwin identify patterns` first")
    keys = ("L", "R", "gray_L", "gray_R", "labels_L", "labels_R", "scale", "threshold")
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in keys if k not in z.files]
            if missing:
                raise IdentifyError(f"{path}: not a synthetic-pattern file (missing {', '.join(missing)})")
            d = {k: z[k] for k in keys}
    except (zipfile.BadZipFile, ValueError, OSError) as exc:
        if isinstance(exc, IdentifyError):
            raise
        raise IdentifyError(f"{path}: unreadable synthetic-pattern file ({exc})") from None
    return SyntheticPatterns(L=d["L"].astype(bool), R=d["R"].astype(bool), gray_L=d["gray_L"], gray_R=d["gray_R"],
                             labels_L=tuple(str(s) for s in d["labels_L"]),
                             labels_R=tuple(str(s) for s in d["labels_R"]),
                             scale=float(d["scale"]), threshold=tuple(float(t) for t in d["threshold"]))


def _stage(args, targets: list[str]):
    """Run ``targets`` of the campaign's graph from the store; returns (campaign, outputs, output folder, runner)."""
    from bladetwin.campaign import read_campaign
    from bladetwin.run import run_nodes

    opts = stage_options(args, scheduler=getattr(args, "scheduler", None))
    campaign = read_campaign(args.campaign, allow_outside=args.allow_outside)
    say = (lambda m: None) if args.quiet else (lambda m: print(f"  {m}", file=sys.stderr, flush=True))
    res, runner = run_nodes(campaign, targets, opts, say)
    if not args.quiet:
        print(f"  {len(runner.computed)} stage nodes computed, {len(runner.reused)} read from the store",
              file=sys.stderr, flush=True)
    return campaign, res, _out(args, campaign), runner


def _cmd_patterns(args) -> int:
    campaign, res, out, _ = _stage(args, [names.SYNTHETIC, names.FILMS])
    sp, films = res[names.SYNTHETIC], res[names.FILMS]
    path = save_synthetic(out / "patterns.npz", sp)
    figure = None
    if not args.no_plot:
        from identify.plots import plot_synthetic_patterns

        figure = atomic_savefig(plot_synthetic_patterns(sp, [a for a, _ in films.values()],
                                                        [b for _, b in films.values()],
                                                        known_labels=[f"joint {j}" for j in films]),
                                out / "patterns.png")
    area = {f: (100 * getattr(sp, f).reshape(len(getattr(sp, f)), -1).mean(axis=1)).tolist() for f in ("L", "R")}
    known = {f: [100 * float(m[k].contact.mean()) for m in films.values()] for k, f in enumerate(("L", "R"))}
    if args.json:
        print_json({"patterns": str(path), "figure": str(figure) if figure else None, "n_L": int(len(sp.L)),
                    "n_R": int(len(sp.R)), "area_pct": area, "known_area_pct": known,
                    "known_joints": list(campaign.known_joints), "threshold": list(sp.threshold)})
        return 0
    rows = [[sp.labels_L[k], area["L"][k], area["R"][k]] for k in range(min(len(sp.L), len(sp.R)))]
    print(f"known joints {list(campaign.known_joints)}: contact area L {_span(known['L'])} %, R {_span(known['R'])} %")
    print(format_table(["pattern", "area L %", "area R %"], rows))
    print(f"wrote {path}" + (f" and {figure}" if figure else ""))
    return 0


def _span(values) -> str:
    return f"{min(values):.0f}-{max(values):.0f}"


def _cmd_sensitivity(args) -> int:
    from bladetwin.outputs import write_sensitivity

    _, res, out, _ = _stage(args, [names.SENSITIVITY])
    sens = res[names.SENSITIVITY]
    files = write_sensitivity(sens, out, plot=not args.no_plot)
    rows = [[m + 1, float(sens.mean_hz[m]), float(sens.std_hz[m]), float(sens.std_rel_pct[m]),
             "feature" if m in sens.feature_modes else ""] for m in range(sens.n_modes)]
    if args.json:
        print_json({"feature_modes": [m + 1 for m in sens.feature_modes], "weights": sens.weights.tolist(),
                    "mean_hz": sens.mean_hz.tolist(), "std_hz": sens.std_hz.tolist(),
                    "std_pct": sens.std_rel_pct.tolist(), "table": str(out / "sensitivity.csv"),
                    "figures": [str(out / f) for f in files if f.endswith(".png")]})
        return 0
    print(format_table(["mode", "mean Hz", "std Hz", "std %", ""], rows, "{:.4g}"))
    print(f"feature modes (1-based): {[m + 1 for m in sens.feature_modes]}, "
          f"weights {np.round(sens.weights, 3).tolist()}")
    return 0


def _cmd_dataset(args) -> int:
    from identify.dataset import save_dataset

    _, res, out, _ = _stage(args, [names.DATASET])
    ds = res[names.DATASET]
    path = save_dataset(ds, out / "dataset.parquet")
    info = {"dataset": str(path), "n_samples": int(len(ds.deltas)), "delta_grid_pct": (100 * ds.delta_grid).tolist(),
            "feature_modes": [m + 1 for m in ds.feature_modes], "weights": ds.weights.tolist(),
            "n_fallbacks": int(np.sum(ds.fallback)) if ds.fallback is not None else 0, "model_key": ds.model_key}
    if args.json:
        print_json(info)
        return 0
    print(f"δ grid (%): {np.round(100 * ds.delta_grid, 3).tolist()}")
    print(f"{info['n_samples']} samples, feature modes {info['feature_modes']}, {info['n_fallbacks']} direct "
          f"fallbacks; wrote {path}")
    return 0


def _prediction_rows(campaign, res, args) -> list[list]:
    pred, delta_all = res[names.PREDICTIONS], res[names.DELTA_ALL]
    nd = res[names.DATASET].deltas.shape[1]
    rows = []
    for j in range(1, campaign.n_blades + 1):
        lab = pred.labels["experimental"].get(j)
        src = ("film" if j in campaign.known_joints else
               ("k-NN + refinement" if args.refine else "k-NN") if lab else "baseline")
        pair = [f"SP-{lab[0] + 1}", f"SP-{lab[1] + 1}", float(lab[2])] if lab else ["", "", ""]
        rows.append([j, src, *pair, *(100 * delta_all[j - 1, :nd]).tolist()])
    return rows


def _cmd_predict(args) -> int:
    from rom.pattern_io import save_patterns

    answer = names.patterns("experimental")
    campaign, res, out, _ = _stage(args, [answer, names.PREDICTIONS, names.FEATURES])
    path = save_patterns(out / "predicted.npz", res[answer])
    rows = _prediction_rows(campaign, res, args)
    nd = len(rows[0]) - 5
    header = ["joint", "answer", "L", "R", "distance"] + [f"δ{m + 1} %" for m in range(nd)]
    csv = ",".join(header) + "\n" + "".join(
        ",".join(str(c) if not isinstance(c, float) else f"{c:.6g}" for c in r) + "\n" for r in rows)
    atomic_write_text(out / "predictions.csv", csv)
    bias = res[names.FEATURES].bias
    if args.json:
        print_json({"predicted": str(path), "table": str(out / "predictions.csv"),
                    "joints": [r[0] for r in rows], "answer": [r[1] for r in rows],
                    "pairs": [r[2:4] for r in rows], "bias_pct": (100 * bias).tolist(),
                    "known_joints": list(campaign.known_joints)})
        return 0
    print(format_table(header, rows, "{:.3f}"))
    print(f"ROM bias on the filmed joints (%, per tracked mode): {np.round(100 * bias, 3).tolist()}")
    print(f"wrote {path} (films at the known joints, the identified pattern elsewhere) and {out / 'predictions.csv'}")
    return 0


def _cmd_validate(args) -> int:
    from identify.validation import geometric_validation

    answer = names.patterns("experimental")
    campaign, res, out, _ = _stage(args, [answer, names.D1B_ROWS, names.BASELINE, names.KNOWN, names.REFERENCE])
    known, identified = res[names.KNOWN], res[answer]
    reference = res[names.REFERENCE]
    source = "truth (virtual campaign)" if reference is not None else "films of the known joints"
    ref = {j + 1: p for j, p in enumerate(reference)} if reference is not None else known
    joints = [j for j in range(1, campaign.n_blades + 1) if j in ref and j not in known] or sorted(ref)
    bd = res[names.FE_MODEL]
    geo = geometric_validation([identified[j - 1] for j in joints], [ref[j] for j in joints], bd)
    geo_b = geometric_validation([res[names.BASELINE] for _ in joints], [ref[j] for j in joints], bd)
    rows = [r for r in res[names.D1B_ROWS] if r["source"] != "film" and "reference_hz" in r]
    bias = res[names.FEATURES].bias[list(res[names.DATASET].feature_modes)]
    err = [100 * (np.asarray(r["identified_hz"]) / (1 + bias) / r["reference_hz"] - 1) for r in rows]
    summary = {
        "reference": source, "joints": joints,
        "area_error_pct": {"identified": float(np.mean(np.abs(geo.area_error_pct))),
                           "baseline": float(np.mean(np.abs(geo_b.area_error_pct)))},
        "centroid_distance_mm": {"identified": float(1e3 * np.nanmean(geo.centroid_distance)),
                                 "baseline": float(1e3 * np.nanmean(geo_b.centroid_distance))},
        "d1b_feature_error_pct": {"identified": float(np.mean(np.abs(err))) if err else None},
        "feature_modes": [m + 1 for m in res[names.DATASET].feature_modes],
    }
    atomic_write_text(out / "validation.json", json.dumps(summary, indent=2) + "\n")
    if not args.no_plot:
        from identify.plots import plot_area_fractions

        atomic_savefig(plot_area_fractions(geo, joint_labels=[str(j) for j in joints]), out / "area_fractions.png")
    if args.json:
        print_json(summary)
        return 0
    print(f"reference: {source}; joints {joints}")
    rows = [[k, summary[k]["identified"], summary[k].get("baseline")]
            for k in ("area_error_pct", "centroid_distance_mm", "d1b_feature_error_pct")]
    print(format_table(["mean |error|", "identified", "baseline (majority of the films)"], rows, "{:.4f}"))
    return 0
