"""``bladetwin run [CAMPAIGN_DIR]``: the main job, the whole identification on a campaign folder.

EMA of every UFF → ROM → films, PCA sampler, sensitivity, dataset → model bias on the filmed joints →
two-step k-NN for every joint → geometric, disk–one-blade and full-assembly validation (Cases A/B/C) →
``out/<campaign>/``: report.html, summary.json, a CSV per table, a PNG per figure, the identified patterns
(``identified_patterns.npz``, for ``bladetwin rom modes --pattern``) and the identified ROM's modes (UFF 55).
Every stage is cached by its inputs, so a warm re-run recomputes only what changed.
"""

from __future__ import annotations

import shlex
import sys
import time
from pathlib import Path

from .cli_commands import command_help
from .cli_options import add_stage_options, stage_options
from .util import format_table, print_json

__all__ = ["register", "DEFAULT_CAMPAIGN"]

DEFAULT_CAMPAIGN = "measurements/academic"


def register(sub) -> None:
    p = sub.add_parser("run", help=command_help("run"),
                       description="Identify the contact pattern of every blade-root joint of a campaign folder "
                                   "(UFF tests + a few film scans), build the mistuned ROM, validate it (paper "
                                   "Table 8) and write an HTML report. Default: the bundled academic campaign.")
    p.add_argument("campaign", nargs="*", default=[DEFAULT_CAMPAIGN],
                   help="campaign folders with campaign.toml; several campaigns of one disk (re-assemblies) share "
                        "its reduced models and get an index page comparing them (default: %(default)s)")
    p.add_argument("--out", default=None, help="output folder (default: out/<campaign name>); with several "
                   "campaigns, one folder per campaign under it and index.html (default: out)")
    add_stage_options(p)
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="send each campaign's graph to an existing Dask cluster, e.g. tcp://host:8786 (the store "
                        "must be a folder the cluster's workers share)")
    p.add_argument("--json", action="store_true", help="print summary.json instead of the short summary")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.add_argument("--no-figures", action="store_true",
                   help="write the tables, summary.json, the UFF export and the report, but draw no PNG figures "
                        "(most of a small run's writing time; for batch studies)")
    p.set_defaults(func=_cmd_run)


def _say(args, t0: float):
    def say(msg: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)
    return say


def _outs(args, campaigns) -> list[Path]:
    if len(campaigns) == 1:
        return [Path(args.out) if args.out else Path("out") / campaigns[0].name]
    names = [c.name for c in campaigns]
    return [Path(args.out or "out") / (n if names.count(n) == 1 else f"{n}-{k + 1}") for k, n in enumerate(names)]


def _cmd_run(args) -> int:
    from .campaign import read_campaign
    from .out_dir import check_out_dir, previous_summary, remove_stale
    from .outputs import write_outputs
    from .report import render_report

    opts = stage_options(args)
    t0 = time.perf_counter()
    say = _say(args, t0)
    if not getattr(args, "verbose", False):
        # ema logs each pole refinement it declines; over 38 files that is noise next to the fit quality the
        # report gives per test (`bladetwin -v run` shows them)
        import logging

        logging.getLogger("ema").setLevel(logging.ERROR)
    campaigns = [read_campaign(c, allow_outside=args.allow_outside) for c in args.campaign]
    outs = _outs(args, campaigns)
    for out in outs:  # before any computation: a folder that cannot be written fails now, not in minutes
        check_out_dir(out)
    results = _compute(campaigns, opts, args.scheduler, say)
    command = "bladetwin run " + " ".join(shlex.quote(a) for a in sys.argv[2:]) if sys.argv[1:2] == ["run"] \
        else "bladetwin run " + " ".join(args.campaign)
    summaries, reports = [], []
    for res, out in zip(results, outs, strict=True):
        t_rep = time.perf_counter()
        say(f"writing tables{'' if args.no_figures else ', figures'} and the report to {out}")
        res.timings_s["report"] = 0.0
        before = previous_summary(out)
        stale = remove_stale(out, before, write_outputs(res, out, command=command, figures=not args.no_figures,
                                                          workers=opts.workers))
        if stale:
            say(f"removed {len(stale)} file(s) an earlier run wrote to {out} and this one did not")
        res.timings_s["report"] = time.perf_counter() - t_rep
        res.timings_s["total"] = time.perf_counter() - t0
        summaries.append(_final_timings(out, res.timings_s))
        reports.append(render_report(out))
    if len(campaigns) > 1:
        from .index_page import render_index

        reports.append(render_index(Path(args.out or "out"), outs))
    if args.json:
        print_json(summaries[0] if len(summaries) == 1 else summaries)
        return 0
    for s, report in zip(summaries, reports, strict=False):
        _print_summary(s, report)
    if len(campaigns) > 1:
        print(f"index: {reports[-1]}")
    return 0


def _compute(campaigns, opts, scheduler: str | None, say) -> list:
    """Every campaign's results: here on the runner, or each campaign's graph as a task of a Dask cluster."""
    from .run import run_campaigns

    if scheduler is None:
        return run_campaigns(campaigns, opts, say)
    from dataclasses import replace

    from distributed import Client

    say(f"sending {len(campaigns)} campaign graph(s) to the Dask scheduler at {scheduler}")
    # one process per task on the cluster: its own runner without a pool (Dask's workers are daemons)
    solo = replace(opts, workers=1)
    with Client(scheduler) as client:
        futures = [client.submit(run_campaigns, [c], solo, pure=False) for c in campaigns]
        return [f.result()[0] for f in futures]


def _final_timings(out: Path, timings: dict) -> dict:
    """summary.json with the final timings (the report stage and the total included)."""
    import json

    from .util import atomic_write_text

    path = out / "summary.json"
    summary = json.loads(path.read_text(encoding="utf-8"))
    summary["timings_s"] = {k: round(v, 2) for k, v in timings.items()}
    atomic_write_text(path, json.dumps(summary, indent=2) + "\n")
    return summary


def _print_summary(s: dict, report: Path) -> None:
    def cell(v, key):
        return "unavailable" if v is None else v[key]

    print(f"campaign {s['campaign']}: {s['n_blades']} joints, filmed {s['known_joints']}, feature modes "
          f"{s['feature_modes']}, step-1 max |ε| {s['step1']['max_abs_eps_pct']:.1f} %")
    rows = [[j["joint"], j["source"], j["pattern_L"], j["pattern_R"], j["area_fraction_L_pct"],
             j["area_fraction_R_pct"]] for j in s["joints"]]
    print(format_table(["joint", "source", "L", "R", "area L %", "area R %"], rows))
    cases = s["cases"]
    rows = []
    for key, label in (("A", "A"), ("B", "B"), ("B_no_bias", "B, no bias"), ("C", "C")):
        rows.append([label, cell(cases[key], "mean_abs_df_pct"), cell(cases[key], "mean_mac")])
    for key in ("A", "B"):
        v = cases["baseline"][key]
        rows.append([f"baseline ({key})", cell(v, "mean_abs_df_pct"), cell(v, "mean_mac")])
    print(format_table(["Table 8", "mean |Δf| %", "mean MAC"], rows, "{:.3f}"))
    for n in s["notes"]:
        print(f"note: {n}")
    if s.get("warnings"):
        print(f"{len(s['warnings'])} warning(s), printed above as they arose; also in summary.json and the report")
    t = s["timings_s"]
    print("time (s): " + ", ".join(f"{k} {v:.1f}" for k, v in t.items()))
    print(f"report: {report}")
