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
import shutil
import sys
from pathlib import Path

import numpy as np

from .util import atomic_savefig, atomic_write_text, format_table, print_json, step

__all__ = ["register", "save_synthetic", "load_synthetic"]

DEFAULT_CAMPAIGN = "measurements/academic"


def register(sub) -> None:
    grp = sub.add_parser("identify", help="contact-pattern identification: patterns, sensitivity, dataset, predict, "
                         "validate", description="Identification stages on a campaign folder (docs/identify.md).")
    isub = grp.add_subparsers(dest="identify_command", metavar="SUBCOMMAND")
    isub.required = True

    def common(p, cache: bool = True) -> None:
        p.add_argument("campaign", nargs="?", default=DEFAULT_CAMPAIGN,
                       help="campaign folder with campaign.toml (default: %(default)s)")
        p.add_argument("--out", default=None, help="output folder (default: out/<campaign name>)")
        if cache:
            p.add_argument("--cache-dir", default=None,
                           help="cache folder for reduced models (default: $BLADETWIN_CACHE or .cache/bladetwin)")
        p.add_argument("--json", action="store_true", help="print JSON instead of tables")
        p.add_argument("--quiet", action="store_true", help="no progress on stderr")

    p = isub.add_parser("patterns", help="synthetic contact patterns from the known joints' films (PCA, Eqs. 23-32)")
    common(p, cache=False)
    p.add_argument("--n", type=int, default=10, help="synthetic patterns per flank (default: %(default)s)")
    p.add_argument("--scale", type=float, default=1.0, help="Eq. 31's Scale (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--no-plot", action="store_true", help="skip patterns.png")
    p.set_defaults(func=_cmd_patterns)

    p = isub.add_parser("sensitivity", help="d1b frequency spread over the pattern pairs; feature modes (§6.2)")
    common(p)
    p.add_argument("--patterns", default=None, help="synthetic patterns (default: <out>/patterns.npz)")
    p.add_argument("--features", type=int, default=3, help="number of feature modes (default: %(default)s)")
    p.add_argument("--no-plot", action="store_true", help="skip sensitivity.png and frequency_maps.png")
    p.set_defaults(func=_cmd_sensitivity)

    p = isub.add_parser("dataset", help="δ grid × pattern pairs → tracked d1b frequencies, Parquet (§6.3)")
    common(p)
    p.add_argument("--patterns", default=None, help="synthetic patterns (default: <out>/patterns.npz)")
    p.add_argument("--step", type=float, default=0.5, help="δ grid step in %% (default: %(default)s)")
    p.add_argument("--delta-modes", type=int, default=3, help="blade modes on the δ grid (default: %(default)s)")
    p.add_argument("--features", type=int, default=3, help="number of feature modes (default: %(default)s)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="build on a local Dask cluster of N worker processes (default: in process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="build on an existing Dask cluster, e.g. tcp://host:8786 (the parts stay here)")
    p.set_defaults(func=_cmd_dataset)

    p = isub.add_parser("predict", help="two-step weighted k-NN: a contact pattern for every joint (§6.4)")
    common(p)
    p.add_argument("--dataset", default=None, help="dataset (default: <out>/dataset.parquet)")
    p.add_argument("--neighbors", type=int, default=1, help="ranked candidates per joint (default: %(default)s)")
    p.add_argument("--no-bias", action="store_true",
                   help="don't remove the ROM's per-mode bias estimated on the filmed joints")
    p.set_defaults(func=_cmd_predict)

    p = isub.add_parser("validate", help="geometric and dynamic validation of the predicted patterns (§7)")
    common(p)
    p.add_argument("--predicted", default=None,
                   help="the k-NN's patterns, with their joints (default: <out>/predicted_knn.npz)")
    p.add_argument("--dataset", default=None, help="dataset (default: <out>/dataset.parquet)")
    p.add_argument("--no-plot", action="store_true", help="skip the validation figures")
    p.set_defaults(func=_cmd_validate)


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
    """Read :func:`save_synthetic`'s file back into a :class:`identify.sampler.SyntheticPatterns`."""
    import zipfile

    from identify.errors import IdentifyError
    from identify.sampler import SyntheticPatterns

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


def _dataset_path(args, out: Path) -> Path:
    return Path(args.dataset) if args.dataset else out / "dataset.parquet"


def _dataset_and_tracker(args, out: Path, models):
    """The stage's dataset and its mode tracker; a dataset of another model is refused, naming the file."""
    from bladetwin.pipeline import tracker
    from identify.dataset import load_dataset
    from identify.errors import IdentifyError

    path = _dataset_path(args, out)
    ds = load_dataset(path)
    try:
        return ds, tracker(models, ds)
    except IdentifyError as exc:
        raise IdentifyError(f"{path}: {exc} (`bladetwin identify dataset`)") from None


# ------------------------------------------------------------------------------------------------ commands
def _cmd_patterns(args) -> int:
    from bladetwin.campaign import read_campaign
    from bladetwin.pipeline import read_films, synthesize

    campaign = read_campaign(args.campaign)
    out = _out(args, campaign)
    with step(f"films of the known joints {list(campaign.known_joints)}", not args.quiet):
        films = read_films(campaign)
    with step(f"PCA sampler: {args.n} patterns per flank (scale {args.scale}, seed {args.seed})", not args.quiet):
        sp = synthesize(films, n_patterns=args.n, scale=args.scale, seed=args.seed)
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
    from bladetwin.campaign import read_campaign
    from bladetwin.pipeline import reduced_models
    from identify.sensitivity import sensitivity

    campaign = read_campaign(args.campaign)
    out = _out(args, campaign)
    sp = load_synthetic(args.patterns or out / "patterns.npz")
    with step("reduced models (cached)", not args.quiet):
        models = reduced_models(campaign, args.cache_dir)
    with step(f"sensitivity over {len(sp.L) * len(sp.R)} pattern pairs", not args.quiet):
        sens = sensitivity(models.disk, models.blade, sp.L, sp.R, n_features=args.features, progress=not args.quiet)
    rows = [[m + 1, float(sens.mean_hz[m]), float(sens.std_hz[m]), float(sens.std_rel_pct[m]),
             "feature" if m in sens.feature_modes else ""] for m in range(sens.n_modes)]
    csv = "mode,mean_hz,std_hz,std_pct,feature\n" + "".join(
        f"{r[0]},{r[1]:.6g},{r[2]:.6g},{r[3]:.6g},{int(bool(r[4]))}\n" for r in rows)
    atomic_write_text(out / "sensitivity.csv", csv)
    figures = []
    if not args.no_plot:
        from identify.plots import plot_frequency_maps, plot_sensitivity

        figures = [atomic_savefig(plot_sensitivity(sens), out / "sensitivity.png"),
                   atomic_savefig(plot_frequency_maps(sens), out / "frequency_maps.png")]
    if args.json:
        print_json({"feature_modes": [m + 1 for m in sens.feature_modes], "weights": sens.weights.tolist(),
                    "mean_hz": sens.mean_hz.tolist(), "std_hz": sens.std_hz.tolist(),
                    "std_pct": sens.std_rel_pct.tolist(), "table": str(out / "sensitivity.csv"),
                    "figures": [str(f) for f in figures]})
        return 0
    print(format_table(["mode", "mean Hz", "std Hz", "std %", ""], rows, "{:.4g}"))
    print(f"feature modes (1-based): {[m + 1 for m in sens.feature_modes]}, "
          f"weights {np.round(sens.weights, 3).tolist()}")
    return 0


def _cmd_dataset(args) -> int:
    from bladetwin.campaign import read_campaign
    from bladetwin.pipeline import blade_tests, query_deltas, reduced_models
    from identify.dataset import grid_from_deltas, save_dataset
    from identify.dataset_parts import build_dataset_parts

    campaign = read_campaign(args.campaign)
    out = _out(args, campaign)
    sp = load_synthetic(args.patterns or out / "patterns.npz")
    say = (lambda m: None) if args.quiet else (lambda m: print(f"  {m}", file=sys.stderr, flush=True))
    with step("EMA of the free blades (deltas, Eq. 37)", not args.quiet):
        blades = blade_tests(campaign, say)
    with step("reduced models (cached)", not args.quiet):
        models = reduced_models(campaign, args.cache_dir)
    # The grid spans the δ the queries will use: the measured deltas mapped onto the ROM's blade modes.
    grid = grid_from_deltas(query_deltas(blades, models, args.delta_modes), step=args.step / 100,
                            n_delta_modes=args.delta_modes)
    n = len(grid) ** args.delta_modes * len(sp.L) * len(sp.R)
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers {args.workers}: expected a positive number of Dask workers")
    with step(f"dataset: {len(grid)}^{args.delta_modes} δ rows × {len(sp.L) * len(sp.R)} pairs = {n} samples",
              not args.quiet):
        # resumable: each finished pattern pair is a Parquet part in dataset.parts/ until the table is written
        ds = build_dataset_parts(models.disk, models.blade, sp.L, sp.R, grid, out / "dataset.parts",
                                 n_delta_modes=args.delta_modes, n_features=args.features, workers=args.workers,
                                 scheduler=args.scheduler, say=say)
    path = save_dataset(ds, out / "dataset.parquet")
    shutil.rmtree(out / "dataset.parts", ignore_errors=True)
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


def _predict(campaign, out: Path, args, say):
    """What ``predict`` computes: (models, dataset, prediction, bias per tracked mode, δ of every blade)."""
    from bladetwin.pipeline import (
        MATCH_WINDOW,
        blade_tests,
        d1b_tests,
        film_patterns,
        filmed_frequencies,
        known_bias,
        measured_tracked,
        predict_joints,
        read_films,
        reduced_models,
    )
    from rom.mistuning import rom_deltas

    quiet = args.quiet
    with step("reduced models (cached)", not quiet):
        models = reduced_models(campaign, args.cache_dir)
    ds, tr = _dataset_and_tracker(args, out, models)  # before any EMA
    with step("EMA of the free blades and the disk-one-blade tests", not quiet):
        blades = blade_tests(campaign, say)
        d1b = d1b_tests(campaign, say)
    n_dm = ds.deltas.shape[1]
    joints = np.array(sorted(d1b))
    delta_all = rom_deltas(blades.frequencies_hz, blades.deltas_pct, models.blade.frequencies_hz)
    deltas = delta_all[joints - 1, :n_dm]
    measured = measured_tracked(ds, d1b, joints, deltas)
    bias = np.zeros(ds.frequencies_hz.shape[1])
    if not args.no_bias:
        with step("ROM bias on the filmed joints", not quiet):
            known = film_patterns(read_films(campaign))
            bias = known_bias(*filmed_frequencies(tr, known, delta_all, joints, measured))
    feats = measured[:, list(ds.feature_modes)] / (1 + bias[list(ds.feature_modes)])
    bad = ~np.isfinite(feats).all(axis=1)
    if bad.all():
        from identify.errors import IdentifyError

        raise IdentifyError("no disk-one-blade test has all feature modes "
                            f"{[m + 1 for m in ds.feature_modes]} within {100 * MATCH_WINDOW:.0f} % of the dataset's")
    if bad.any():
        import warnings

        warnings.warn(f"joints {joints[bad].tolist()}: a feature mode was not found in the EMA; not predicted",
                      stacklevel=2)
    pred = predict_joints(ds, joints[~bad], deltas[~bad], feats[~bad], n_neighbors=args.neighbors)
    return models, ds, pred, bias, delta_all


def _cmd_predict(args) -> int:
    from bladetwin.campaign import read_campaign
    from bladetwin.pipeline import film_patterns, read_films
    from rom.pattern_io import save_patterns

    campaign = read_campaign(args.campaign)
    out = _out(args, campaign)
    say = (lambda m: None) if args.quiet else (lambda m: print(f"  {m}", file=sys.stderr, flush=True))
    models, ds, pred, bias, _ = _predict(campaign, out, args, say)
    known = film_patterns(read_films(campaign))
    # The answer for every joint: the film where there is one, else the k-NN's best candidate.
    by_joint = {int(j): p for j, p in zip(pred.joints, pred.patterns, strict=True)}
    missing = [j for j in range(1, campaign.n_blades + 1) if j not in known and j not in by_joint]
    if missing:
        from identify.errors import IdentifyError

        raise IdentifyError(f"joints {missing}: neither filmed nor predicted (no usable disk-one-blade test)")
    final = [known.get(j, by_joint.get(j)) for j in range(1, campaign.n_blades + 1)]
    path = save_patterns(out / "predicted.npz", final)
    # The k-NN's own answer for every predicted joint (the filmed ones too, for validation), with the joints.
    from rom.fileio import atomic_path

    with atomic_path(out / "predicted_knn.npz") as tmp, open(tmp, "wb") as fh:
        np.savez(fh, L=np.stack([p.L for p in pred.patterns]), R=np.stack([p.R for p in pred.patterns]),
                 joints=pred.joints.astype(np.int64))
    rows = []
    for k, j in enumerate(pred.joints):
        lab = pred.match.label[k, 0]
        rows.append([int(j), "film" if int(j) in known else "k-NN", f"SP-{lab[0] + 1}", f"SP-{lab[1] + 1}",
                     float(pred.match.distance[k, 0]), *(100 * pred.deltas[k]).tolist()])
    csv = "joint,source,pattern_L,pattern_R,distance," + ",".join(f"delta{m + 1}_pct" for m in
                                                                 range(pred.deltas.shape[1])) + "\n"
    csv += "".join(",".join(str(c) if not isinstance(c, float) else f"{c:.6g}" for c in r) + "\n" for r in rows)
    atomic_write_text(out / "predictions.csv", csv)
    if args.json:
        print_json({"predicted": str(path), "table": str(out / "predictions.csv"),
                    "joints": pred.joints.tolist(), "pairs": pred.match.label[:, 0].tolist(),
                    "candidates": pred.match.label.tolist(), "distance": pred.match.distance.tolist(),
                    "bias_pct": (100 * bias).tolist(), "known_joints": list(campaign.known_joints)})
        return 0
    print(format_table(["joint", "answer", "L", "R", "distance"] + [f"δ{m + 1} %" for m in range(pred.deltas.shape[1])],
                       rows, "{:.3f}"))
    print(f"ROM bias on the filmed joints (%, per tracked mode): {np.round(100 * bias, 3).tolist()}")
    print(f"wrote {path} (films for the known joints, k-NN elsewhere) and {out / 'predictions.csv'}")
    return 0


def _cmd_validate(args) -> int:
    from bladetwin.campaign import read_campaign
    from bladetwin.pipeline import film_patterns, mean_known_pattern, read_films, reduced_models
    from identify.validation import geometric_validation
    from rom.contact import ContactPattern
    from rom.pattern_io import load_patterns

    campaign = read_campaign(args.campaign)
    out = _out(args, campaign)
    pred_path = Path(args.predicted) if args.predicted else out / "predicted_knn.npz"
    patterns = load_patterns(pred_path)
    with np.load(pred_path, allow_pickle=False) as z:
        pred_joints = [int(j) for j in z["joints"]] if "joints" in z.files else list(range(1, len(patterns) + 1))
    if len(pred_joints) != len(patterns) or not all(1 <= j <= campaign.n_blades for j in pred_joints):
        from identify.errors import IdentifyError

        raise IdentifyError(f"{pred_path}: joints {pred_joints} do not match its {len(patterns)} patterns or the "
                            f"campaign's {campaign.n_blades} joints")
    predicted = dict(zip(pred_joints, patterns, strict=True))
    known = film_patterns(read_films(campaign))
    truth_dir = campaign.truth_dir
    if truth_dir is not None and (truth_dir / "patterns.npz").is_file():
        with np.load(truth_dir / "patterns.npz") as z:
            reference = {j + 1: ContactPattern(a, b) for j, (a, b) in enumerate(zip(z["L"], z["R"], strict=True))}
        source = "truth (virtual campaign)"
    else:
        reference = known
        source = "films of the known joints"
    unknown = [j for j in predicted if j in reference and j not in known]
    joints = unknown or sorted(j for j in predicted if j in reference)
    with step("reduced models (cached)", not args.quiet):
        models = reduced_models(campaign, args.cache_dir)
    base = mean_known_pattern(known)
    geo = geometric_validation([predicted[j] for j in joints], [reference[j] for j in joints], models.bd)
    geo_base = geometric_validation([base for _ in joints], [reference[j] for j in joints], models.bd)
    ds, tr = _dataset_and_tracker(args, out, models)
    feat = list(ds.feature_modes)
    from bladetwin.pipeline import blade_tests
    from rom.mistuning import rom_deltas

    say = (lambda m: None) if args.quiet else (lambda m: print(f"  {m}", file=sys.stderr, flush=True))
    with step("EMA of the free blades (δ of each blade)", not args.quiet):
        blades = blade_tests(campaign, say)
    delta_all = rom_deltas(blades.frequencies_hz, blades.deltas_pct, models.blade.frequencies_hz)
    err_pred, err_base = [], []
    with step(f"d1b ROM: predicted, baseline and reference patterns on {len(joints)} joints", not args.quiet):
        for j in joints:
            f_ref = tr.track(reference[j], delta_all[j - 1]).frequencies_hz[feat]
            f_pred = tr.track(predicted[j], delta_all[j - 1]).frequencies_hz[feat]
            f_base = tr.track(base, delta_all[j - 1]).frequencies_hz[feat]
            err_pred.append(100 * (f_pred / f_ref - 1))
            err_base.append(100 * (f_base / f_ref - 1))
    err_pred, err_base = np.array(err_pred), np.array(err_base)
    summary = {
        "reference": source, "joints": joints,
        "area_error_pct": {"predicted": float(np.mean(np.abs(geo.area_error_pct))),
                           "baseline": float(np.mean(np.abs(geo_base.area_error_pct)))},
        "centroid_distance_mm": {"predicted": float(1e3 * np.nanmean(geo.centroid_distance)),
                                 "baseline": float(1e3 * np.nanmean(geo_base.centroid_distance))},
        "d1b_feature_error_pct": {"predicted": float(np.mean(np.abs(err_pred))),
                                  "baseline": float(np.mean(np.abs(err_base)))},
        "feature_modes": [m + 1 for m in feat],
    }
    atomic_write_text(out / "validation.json", json.dumps(summary, indent=2) + "\n")
    if not args.no_plot:
        from identify.plots import plot_area_fractions

        atomic_savefig(plot_area_fractions(geo, joint_labels=[str(j) for j in joints]), out / "area_fractions.png")
    if args.json:
        print_json(summary)
        return 0
    print(f"reference: {source}; joints {joints}")
    rows = [[k, summary[k]["predicted"], summary[k]["baseline"]]
            for k in ("area_error_pct", "centroid_distance_mm", "d1b_feature_error_pct")]
    print(format_table(["mean |error|", "predicted", "baseline (mean known)"], rows, "{:.4f}"))
    return 0
