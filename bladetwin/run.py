"""``bladetwin run``: every stage on one or several campaigns, through one graph and one store (design §2.1).

:func:`run_campaigns` checks every campaign's files, builds each campaign's pipeline
(:func:`bladetwin.stages.campaign_pipeline`), runs them together on one :class:`~bladetwin.stages.Runner` (so
campaigns of the same disk share its reduced models) and gathers each campaign's
:class:`~bladetwin.stages.RunResult`. :func:`run_nodes` runs part of one campaign's graph, for the stage
commands (``bladetwin identify …``). Computing lives in the stages; :mod:`bladetwin.outputs` writes files.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace

from .campaign import Campaign, CampaignError
from .campaign_checks import check_files
from .model import load_model
from .stages import (
    Pipeline,
    Runner,
    RunOptions,
    RunResult,
    Source,
    Store,
    campaign_pipeline,
    campaign_sources,
    gather,
    names,
)
from .stages.patterns import read_films
from .user_warnings import recording, unique

__all__ = ["STAGE_GROUPS", "check_campaign", "run_campaigns", "run_nodes"]

#: Which nodes each figure of ``timings_s`` adds up (compute seconds; the stages overlap on the workers): a node
#: counts in a group where its name starts with one of the group's names or families (:mod:`~.stages.names`).
STAGE_GROUPS = {"ema": (names.EMA, names.BLADE_TABLE, names.CALIBRATION),
                "rom": (names.DISK_CB, names.BLADE_RUBIN, names.DISK_CYCLIC, names.DELTA_ALL),
                "dataset": (names.SYNTHETIC, names.SENSITIVITY, names.DATASET),
                "identify": (names.FEATURES, names.PREDICTIONS, names.REFINE, names.PATTERNS, names.POSTERIOR),
                "rom_update": (names.ROM_UPDATE,),
                "validation": (names.FULL, names.VALIDATION, names.D1B_ROWS, names.N_FULL_MODES),
                "response": (names.RESPONSE,)}


def check_campaign(campaign: Campaign) -> None:
    """Every check that needs no computation: files, films, the tests the stages need (one-line errors)."""
    manifest = campaign.root / "campaign.toml"
    check_files(campaign)
    read_films(campaign)  # every film must read before the long stages
    if not campaign.of_type("d1b"):
        raise CampaignError(f"{manifest}: no disk-one-blade (d1b) test: the k-NN needs their frequencies")
    if len(campaign.of_type("blade")) != campaign.n_blades:
        raise CampaignError(f"{manifest}: {len(campaign.of_type('blade'))} blade tests for {campaign.n_blades} "
                            "blades; the deltas need every blade")


class _Prefixed(Mapping):
    """One campaign's outputs within a run of several, by their unprefixed names."""

    def __init__(self, results: Mapping, prefix: str) -> None:
        self._r, self._p = results, prefix

    def __getitem__(self, name: str):
        return self._r[self._p + name]

    def __iter__(self):
        return (k[len(self._p):] for k in self._r if k.startswith(self._p))

    def __len__(self) -> int:
        return sum(1 for _ in self)


def _prefixes(campaigns: list[Campaign]) -> list[str]:
    if len(campaigns) == 1:
        return [""]
    titles = [c.name for c in campaigns]  # not ``names``: that is the catalog of node names
    return [f"{n}#{k + 1}/" if titles.count(n) > 1 else f"{n}/" for k, n in enumerate(titles)]


def _timings(seconds: dict[str, float], prefix: str) -> dict[str, float]:
    out = {}
    for group, heads in STAGE_GROUPS.items():
        out[group] = sum(s for name, s in seconds.items() if name.startswith(prefix)
                         and name[len(prefix):].startswith(heads))
    return out


def _calibration(c: Campaign, p: Pipeline, nominal: Source, store: Store, opts: RunOptions, say,
                 problems: list[str]):
    """The campaign's calibration (paper §5): its node runs first, on its own runner (the blade and disk EMA it
    needs are stored for the main run); the store's problems it met go to ``problems``, for the summary.

    The disk–one-blade tests' EMA runs here too, as fillers (:meth:`Runner.run`), stored for the main run: it needs
    no model, and it keeps the second worker busy while the calibration solves (a worker idle for 13 s of the
    bundled campaign's run); the fits left when the calibration is done run in the main run.
    """
    src = campaign_sources(c, nominal, store, opts)
    runner = Runner(store, opts.workers, say)
    d1b = [names.ema(names.test_name(t)) for t in c.of_type("d1b")]
    cal = runner.run(p, [names.CALIBRATION], src, fillers=d1b)[names.CALIBRATION]
    problems.extend(runner.warnings_of())
    return cal


def _calibrated(nominal: Source, cals: list) -> tuple[Source, str | None]:
    """The model calibrated on its campaigns' tests, and a note where several campaigns pooled theirs.

    Re-assemblies of one disk test the same disk and blades: their calibrations are pooled
    (:func:`rom.calibration.pool_calibrations`) into one model, which every campaign's reduced models share.
    The model is scaled here, before the main run's workers fork, so that they inherit it (a model is never
    pickled to a worker).
    """
    from rom.calibration import apply_calibration, pool_calibrations

    from .stages.models import model_key

    disk = [c.disk for c in cals if c.disk is not None]
    blade = [c.blade for c in cals if c.blade is not None]
    if not disk and not blade:
        return nominal, None
    disk_cal = pool_calibrations(disk) if disk else None
    blade_cal = pool_calibrations(blade) if blade else None
    bd = apply_calibration(nominal.value, disk_cal, blade_cal)
    note = None
    if len(cals) > 1:
        parts = [f"{x.component} E {100 * (x.E_scale - 1):+.2f} %, ρ {100 * (x.rho_scale - 1):+.2f} %"
                 for x in (disk_cal, blade_cal) if x is not None]
        note = (f"The {len(cals)} campaigns of this disk share one calibrated model, the geometric mean of their "
                f"calibrations ({'; '.join(parts)}); each campaign's own is in its summary.json:calibration.")
    return Source(bd, model_key(bd)), note


def _graph(campaigns: list[Campaign], opts: RunOptions, store: Store, say
           ) -> tuple[Pipeline, dict, list[str], list[list[str]]]:
    """The graph of every campaign, its sources, the campaigns' prefixes, and each campaign's warnings so far."""
    from .stages.models import model_key

    pipeline, sources, prefixes = Pipeline(), {}, _prefixes(campaigns)
    models: dict[str, Source] = {}
    spec_of, pipes = [], []
    for c in campaigns:
        spec = repr(sorted(c.model.items())) + (str(c.root) if c.model.get("family") == "imported" else "")
        if spec not in models:
            say(f"FE model of {c.name} (its hash keys the reduced models)")
            bd = load_model(c)
            models[spec] = Source(bd, model_key(bd))
        spec_of.append(spec)
        pipes.append(campaign_pipeline(c, opts))
    used, notes = dict(models), [[] for _ in campaigns]
    if opts.calibrate:
        cals: dict[str, list] = {}
        for k, (c, p, spec) in enumerate(zip(campaigns, pipes, spec_of, strict=True)):
            say(f"calibrating the FE model's materials on the tests of {c.name} (paper §5); the disk–one-blade "
                "tests are fitted beside it")
            cals.setdefault(spec, []).append(_calibration(c, p, models[spec], store, opts, say, notes[k]))
        for spec, found in cals.items():
            used[spec], note = _calibrated(models[spec], found)
            for k, s in enumerate(spec_of):
                if note and s == spec:
                    notes[k].append(note)
    for c, p, spec, pre in zip(campaigns, pipes, spec_of, prefixes, strict=True):
        p = p.prefixed(pre.rstrip("/")) if pre else p
        for n in p:
            pipeline.add(n)
        src = campaign_sources(c, used[spec], store, opts, nominal=models[spec])
        sources.update({pre + k: v for k, v in src.items()})
    return pipeline, sources, prefixes, notes


def run_campaigns(campaigns: Iterable[Campaign], opts: RunOptions | None = None,
                  say: Callable[[str], None] = lambda m: None) -> list[RunResult]:
    """Run every stage on each campaign (one graph, one store); each campaign's result, in order."""
    t0 = time.perf_counter()
    opts = RunOptions() if opts is None else opts
    campaigns = list(campaigns)
    store = Store(opts.cache_dir)
    runner = Runner(store, opts.workers, say)
    checked: list[list[str]] = []
    for c in campaigns:
        say(f"checking the files of {c.name}")
        with recording() as texts:
            check_campaign(c)
        checked.append(runner.emit(unique(texts)))
    pipeline, sources, prefixes, pooled = _graph(campaigns, opts, store, say)
    checked = [[*found, *runner.emit(note)] for found, note in zip(checked, pooled, strict=True)]
    say(f"running {len(pipeline)} stage nodes on {opts.workers} worker(s); the store is {store.root}")
    res = runner.run(pipeline, pipeline.names(), sources)
    out = []
    for c, pre in zip(campaigns, prefixes, strict=True):
        timings = _timings(runner.seconds, pre)
        timings["total"] = time.perf_counter() - t0
        view = _Prefixed(res, pre) if pre else res
        computed = [n for n in runner.computed if n.startswith(pre)]
        counts = {"computed": len(computed), "reused": sum(n.startswith(pre) for n in runner.reused),
                  # where a cold run's time goes: each computed node's own seconds, largest first
                  "seconds": dict(sorted(((n[len(pre):], round(runner.seconds[n], 2)) for n in computed
                                          if runner.seconds.get(n, 0.0) >= 0.05), key=lambda kv: -kv[1]))}
        with recording() as texts:
            res_c = gather(view, c, opts, sources[pre + names.FE_MODEL].value, timings)
        found = unique([*checked[len(out)], *runner.warnings_of(pre), *runner.emit(unique(texts))])
        out.append(replace(res_c, stage_counts=counts, warnings=found))
    return out


def run_nodes(campaign: Campaign, targets: list[str], opts: RunOptions | None = None,
              say: Callable[[str], None] = lambda m: None) -> tuple[Mapping, Runner]:
    """Run the nodes ``targets`` of one campaign's graph (and what they need) against the store."""
    opts = RunOptions() if opts is None else opts
    check_campaign(campaign)
    store = Store(opts.cache_dir)
    pipeline, sources, _, _ = _graph([campaign], opts, store, say)
    runner = Runner(store, opts.workers, say)
    return runner.run(pipeline, targets, sources), runner


