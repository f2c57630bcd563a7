"""The graph of ``bladetwin run`` for one campaign: every stage as a named node (design §2.1).

:func:`campaign_pipeline` lists the nodes a campaign needs (one EMA node per test, one refinement per unfilmed
joint and input, one full solve per set of patterns), :func:`campaign_sources` the values they start from, each
under its name in :mod:`~bladetwin.stages.names`. ``bladetwin run`` asks for every output; ``bladetwin identify
…`` asks for one node and gets it, and what it needs, from the same store.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rom.cache import hash_inputs

from . import (
    bias,
    calibration,
    dataset,
    full,
    knn,
    measured,
    models,
    names,
    patterns,
    posterior,
    refinement,
    response,
    rom_update,
    validation,
)
from .graph import Node, Pipeline
from .runner import Source

__all__ = ["METHODS", "RunOptions", "reference_patterns", "campaign_pipeline", "campaign_sources", "identify_inputs"]


@dataclass(frozen=True)
class RunOptions:
    """Settings of a run (defaults: the paper's, and the refinement after the k-NN, which is beyond it).

    Attributes
    ----------
    cache_dir : Path or None
        The store (stage results and reduced models); default ``$BLADETWIN_CACHE`` or ``.cache/bladetwin``.
    n_patterns, scale, seed :
        PCA sampler: synthetic patterns per flank, Eq. 31's Scale, random seed.
    step_pct : float
        δ grid step (%).
    n_features, n_delta_modes : int
        Feature modes of the k-NN, blade modes on the δ grid.
    bias : bool
        Remove the ROM's per-mode bias estimated on the filmed joints.
    workers : int
        Worker processes of the runner (each single-threaded); 1 runs every node in this process.
    dask_workers, scheduler :
        Build the dataset on a local Dask cluster of that many workers, or on the Dask scheduler at that
        address; default in a worker. The dataset is the same either way.
    refine : int
        After the k-NN, refine every unfilmed joint's pattern by a compass search of at most this many d1b
        solves (:func:`identify.refine.refine_pattern`, beyond the paper); 0: the k-NN's pair, as the paper.
    method : {"knn", "posterior", "both"}
        Identify unfilmed joints by the k-NN (and its refinement), the contact posterior (beyond the paper) or
        both. With ``"posterior"`` the k-NN still runs (it gives the features) but is not refined or reported.
    n_components : int or None
        PCA components per flank of the posterior's prior; default: enough for 95 % of the films' variance.
    posterior_steps : int
        Steps of each joint's sampler per round, run until its chains converge (:mod:`identify.posterior`).
    calibrate : bool
        Calibrate E and ρ of the disk and the blades on the tests before any reduction (paper §5, Table 4;
        :mod:`bladetwin.stages.calibration`); ``True`` by default; ``False`` (``bladetwin run --no-calibrate``)
        keeps the model's materials.
    rom : {"updated", "paper"}
        ``"updated"`` (default) also calibrates the ROM beyond Eq. 19 on the disk–one-blade tests (contact
        stiffness, in-situ blade corrections: :mod:`identify.rom_update`) and validates it beside the paper's;
        ``"paper"``: the paper's ROM only (rigid ties, Eq. 19).
    """

    cache_dir: Path | None = None
    n_patterns: int = 10
    scale: float = 1.0
    seed: int = 0
    step_pct: float = 0.5
    n_features: int = 3
    n_delta_modes: int = 3
    bias: bool = True
    workers: int = 2
    dask_workers: int | None = None
    scheduler: str | None = None
    refine: int = 40
    method: str = "both"
    n_components: int | None = None
    posterior_steps: int = 1500
    rom: str = "updated"
    calibrate: bool = True

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method {self.method!r}: expected one of {', '.join(METHODS)}")
        if self.rom not in rom_update.ROM_KINDS:
            raise ValueError(f"rom {self.rom!r}: expected one of {', '.join(rom_update.ROM_KINDS)}")

    @property
    def updated(self) -> bool:
        """Whether the ROM is updated beyond Eq. 19 (:mod:`bladetwin.stages.rom_update`)."""
        return self.rom == "updated"

    @property
    def knn_reported(self) -> bool:
        """Whether the k-NN's answer is one of the run's methods."""
        return self.method in ("knn", "both")

    @property
    def posterior(self) -> bool:
        """Whether the contact posterior runs."""
        return self.method in ("posterior", "both")


#: The identification methods of ``bladetwin run --method`` (``both`` runs the first two side by side).
METHODS = ("knn", "posterior", "both")


def reference_patterns(campaign) -> list | None:
    """Reference patterns of every joint: ``truth/patterns.npz`` of a virtual campaign, or films of all joints."""
    from ..campaign import CampaignError

    truth = campaign.truth_dir
    if truth is not None and (truth / "patterns.npz").is_file():
        from rom.pattern_io import load_patterns

        pats = load_patterns(truth / "patterns.npz")
        if len(pats) != campaign.n_blades:
            raise CampaignError(f"{truth / 'patterns.npz'}: {len(pats)} patterns for {campaign.n_blades} joints")
        return pats
    if len(campaign.known_joints) == campaign.n_blades:
        films = patterns.read_films(campaign)
        return [patterns.film_patterns(films)[j] for j in range(1, campaign.n_blades + 1)]
    return None


def identify_inputs(campaign, opts: RunOptions) -> list[str]:
    """The inputs the identification runs on (:data:`bladetwin.stages.knn.INPUTS`) for this campaign."""
    truth, n_known = campaign.truth_dir, len(campaign.known_joints)
    reference = (truth is not None and (truth / "patterns.npz").is_file()) or n_known == campaign.n_blades
    return [n for n in knn.INPUTS if (n != "experimental_no_bias" or opts.bias) and (n != "numerical" or reference)]


def campaign_sources(campaign, model: Source, store, opts: RunOptions, nominal: Source | None = None
                     ) -> dict[str, Source]:
    """The values a campaign's pipeline starts from, each with the key its dependants hash.

    ``model`` is the FE model the stages use, keyed by :func:`~bladetwin.stages.models.model_key` (calibrated
    where the run calibrates); ``nominal`` the uncalibrated one the calibration starts from (default: ``model``).
    """
    # the campaign's key hashes the word "campaign" with its manifest: kept, so that stored entries stay valid
    src = {names.CAMPAIGN: Source(campaign, hash_inputs("campaign", str(campaign.root),
                                                         (campaign.root / "campaign.toml").read_bytes())),
           names.FE_MODEL: model, names.FE_NOMINAL: model if nominal is None else nominal,
           names.STORE: Source(store, "store"),
           names.DASK: Source(dataset.DaskSettings(opts.dask_workers, opts.scheduler), "dask")}
    for t in campaign.tests:
        src[names.test_source(names.test_name(t))] = Source(t, measured.test_key(t.file, t.picks, t.max_order))
    return src


def _ema_nodes(p: Pipeline, campaign) -> None:
    for t in campaign.tests:
        name = names.test_name(t)
        # a version per change of the EMA's results (design §8: assembly 13 in §8.61, all +1 in §8.62, assembly 15 in
        # §8.63, all +1 in §8.64, assembly 17-20 in §8.66, §8.67, §8.70, §8.73; all +1 in §8.93; assembly 22 in §8.94)
        p.add(Node(names.ema(name), measured.fit_test, {"test": names.test_source(name)}, label=f"EMA {name}",
                   version=22 if t.type == "assembly" else 6))
    p.add(Node(names.BLADE_TABLE, measured.blade_table, _ema_of(campaign, "blade"), where="parent"))


def _ema_of(campaign, kind: str) -> dict[str, str]:
    """The EMA nodes of a campaign's tests of one type, by test name (the arguments of the nodes that take them)."""
    return {names.test_name(t): names.ema(names.test_name(t)) for t in campaign.of_type(kind)}


def _calibration_node(p: Pipeline, campaign) -> None:
    """The paper's calibration (§5): a worker node, since it solves the model's first modes."""
    cal = {"bd": names.FE_NOMINAL, "campaign": names.CAMPAIGN, "blades": names.BLADE_TABLE}
    if campaign.of_type("disk"):
        cal["disk"] = names.ema("disk")
    p.add(Node(names.CALIBRATION, calibration.calibrate, cal, label="material calibrated"))


def _model_nodes(p: Pipeline, campaign) -> None:
    bd, hw = {"bd": names.FE_MODEL}, {"hardware_kg": float(campaign.masses.get("slot_hardware_kg", 0.0))}
    p.add(Node(names.DISK_CB, models.reduce_disk_cb, bd, hw, label="Craig–Bampton disk built"))
    p.add(Node(names.BLADE_RUBIN, models.reduce_blade_rubin, bd, label="Rubin blade built"))
    p.add(Node(names.DISK_CYCLIC, models.reduce_disk_all_slots, bd, hw, label="cyclic all-slot disk built",
               version=2))  # 2: the build names the hardware it carries (design §8.78)
    p.add(Node(names.DELTA_ALL, models.blade_deltas, {"blades": names.BLADE_TABLE, "blade": names.BLADE_RUBIN},
               where="parent"))


def _pattern_nodes(p: Pipeline, opts: RunOptions, n_blades: int) -> None:
    p.add(Node(names.FILMS, patterns.read_films, {"campaign": names.CAMPAIGN}, where="parent", stored=False,
               content_key=True))
    p.add(Node(names.KNOWN, patterns.film_patterns, {"films": names.FILMS}, where="parent", stored=False,
               content_key=True))
    p.add(Node(names.BASELINE, patterns.mean_known_pattern, {"known": names.KNOWN}, where="parent", stored=False,
               content_key=True))
    p.add(Node(names.REFERENCE, reference_patterns, {"campaign": names.CAMPAIGN}, where="parent", stored=False,
               content_key=True))
    p.add(Node(names.SYNTHETIC, patterns.synthetic_patterns, {"films": names.FILMS},
               {"n_patterns": opts.n_patterns, "scale": opts.scale, "seed": opts.seed}, where="parent"))
    p.add(Node(names.PATTERNS_BASELINE, refinement.pattern_list, {"known": names.KNOWN, "baseline": names.BASELINE},
               {"n_blades": n_blades}, where="parent", stored=False, content_key=True))


def _identify_nodes(p: Pipeline, campaign, opts: RunOptions) -> None:
    rom = {"disk": names.DISK_CB, "blade": names.BLADE_RUBIN}
    p.add(Node(names.SENSITIVITY, dataset.sensitivity_node, {**rom, "synthetic": names.SYNTHETIC},
               {"n_features": opts.n_features}, label="sensitivity"))
    in_parent = opts.dask_workers is not None or opts.scheduler is not None  # a Dask client from a worker: no
    p.add(Node(names.DATASET, dataset.dataset_node,
               {**rom, "synthetic": names.SYNTHETIC, "delta_all": names.DELTA_ALL, "sens": names.SENSITIVITY,
                "store": names.STORE, "dask": names.DASK},
               {"n_features": opts.n_features, "n_delta_modes": opts.n_delta_modes, "step_pct": opts.step_pct},
               where="parent" if in_parent else "worker", label="dataset"))
    p.add(Node(names.FEATURES, bias.features,
               {**rom, "dataset": names.DATASET, "delta_all": names.DELTA_ALL, "known": names.KNOWN,
                "reference": names.REFERENCE, **_ema_of(campaign, "d1b")},
               {"n_delta_modes": opts.n_delta_modes, "bias": opts.bias}, version=6,
               label="bias on the filmed joints"))
    p.add(Node(names.PREDICTIONS, knn.predict, {"dataset": names.DATASET, "features": names.FEATURES,
                                                "delta_all": names.DELTA_ALL, "known": names.KNOWN},
               {"n_delta_modes": opts.n_delta_modes, "bias": opts.bias, "step_pct": opts.step_pct}, where="parent",
               version=3))
    unfilmed = [t.index for t in campaign.of_type("d1b") if t.index not in campaign.known_joints]
    for name in identify_inputs(campaign, opts):
        refined = {}
        for j in unfilmed if opts.refine and opts.knn_reported else ():
            refined[names.joint_key(j)] = p.add(Node(
                names.refine(name, j), refinement.refine_joint,
                {**rom, "dataset": names.DATASET, "films": names.FILMS, "synthetic": names.SYNTHETIC,
                 "predictions": names.PREDICTIONS, "delta_all": names.DELTA_ALL, "store": names.STORE},
                {"input": name, "joint": int(j), "max_solves": int(opts.refine)},
                label=f"joint {j} refined ({name} input)", version=2)).name
        p.add(Node(names.patterns(name), refinement.joint_patterns,
                   {"predictions": names.PREDICTIONS, "known": names.KNOWN, "baseline": names.BASELINE, **refined},
                   {"input": name, "n_blades": campaign.n_blades}, where="parent", stored=False, content_key=True))


def _posterior_nodes(p: Pipeline, campaign, opts: RunOptions) -> None:
    from ..campaign import CampaignError

    n_known = len(campaign.known_joints)
    if opts.n_components is not None and opts.n_components > n_known - 1:
        # refused before any computation: the prior's PCA has at most one component fewer than the films
        raise CampaignError(f"--components {opts.n_components}: the {n_known} filmed joints of {campaign.name} "
                            f"support at most {max(n_known - 1, 0)} per flank")
    rom = {"disk": names.DISK_CB, "blade": names.BLADE_RUBIN, "dataset": names.DATASET}
    p.add(Node(names.POSTERIOR_PRIOR, posterior.prior_node, {"films": names.FILMS},
               {"scale": opts.scale, "n_components": opts.n_components}, where="parent", version=2))  # §8.81
    n = posterior.N_SOLVES // posterior.N_PARTS
    parts = {f"part_{k}": p.add(Node(names.posterior_part(k), posterior.surrogate_solves,
                                     {**rom, "prior": names.POSTERIOR_PRIOR},
                                     {"part": k, "n": n, "seed": opts.seed, "widen": posterior.WIDEN},
                                     label=f"surrogate solves {k + 1}/{posterior.N_PARTS}")).name
             for k in range(posterior.N_PARTS)}
    p.add(Node(names.POSTERIOR_SURROGATE, posterior.surrogate_node, parts, where="parent"))
    p.add(Node(names.POSTERIOR_REPRESENTATION, posterior.representation_error,
               {**rom, "films": names.FILMS, "prior": names.POSTERIOR_PRIOR},
               label="the prior family's error on the films"))
    unfilmed = [t.index for t in campaign.of_type("d1b") if t.index not in campaign.known_joints]
    p.add(Node(names.POSTERIOR_FACTORS, posterior.delta_factors,
               {**rom, "baseline": names.BASELINE, "delta_all": names.DELTA_ALL},
               {"joints": [int(j) for j in unfilmed]}, label="δ factors of the posterior"))
    fits = {t.index: names.ema(names.test_name(t)) for t in campaign.of_type("d1b")}
    # the full solves take the experimental (bias removed) and numerical inputs' answers
    for name in (n for n in identify_inputs(campaign, opts) if n != "experimental_no_bias"):
        posts = {}
        for j in unfilmed:
            posts[names.joint_key(j)] = p.add(Node(
                names.posterior_joint(name, j), posterior.posterior_joint,
                {**rom, "features": names.FEATURES, "prior": names.POSTERIOR_PRIOR,
                 "surrogate": names.POSTERIOR_SURROGATE, "delta_all": names.DELTA_ALL,
                 "factors": names.POSTERIOR_FACTORS, "bd": names.FE_MODEL, "reference": names.REFERENCE,
                 "fit": fits[j], "representation": names.POSTERIOR_REPRESENTATION},
                {"input": name, "joint": int(j), "seed": opts.seed, "n_steps": opts.posterior_steps}, version=15,
                label=f"joint {j} posterior ({name} input)")).name
        p.add(Node(names.posterior_patterns(name), posterior.posterior_patterns,
                   {"known": names.KNOWN, "baseline": names.BASELINE, **posts}, {"n_blades": campaign.n_blades},
                   where="parent", stored=False, content_key=True))
        if name == "experimental":  # the ROM update's plausible patterns (rom_update.candidates_node)
            p.add(Node(names.POSTERIOR_CANDIDATES, rom_update.candidates_node, posts, where="parent", stored=False,
                       content_key=True))


#: The full solves: name → the patterns they take.
FULL = {"baseline": names.PATTERNS_BASELINE, "reference": names.REFERENCE,
        "identified": names.patterns("experimental"), "identified_no_bias": names.patterns("experimental_no_bias"),
        "numerical": names.patterns("numerical"), "posterior": names.posterior_patterns("experimental"),
        "posterior_numerical": names.posterior_patterns("numerical")}


def _full_wanted(name: str, inputs: list[str], opts: RunOptions) -> bool:
    """Whether the run solves the full assembly ``name`` (:data:`FULL`): its patterns' input ran."""
    if name in ("baseline", "reference"):
        return name == "baseline" or "numerical" in inputs
    by_posterior, source = names.answer_of(FULL[name])
    return (opts.posterior or not by_posterior) and source in inputs


def _answer(opts: RunOptions, name: str) -> str:
    """The node of the run's answer for input ``name``: the posterior's where it ran, else the k-NN's."""
    return names.posterior_patterns(name) if opts.posterior else names.patterns(name)


#: The ROM update's sets of patterns: name → what its progress message calls them. ``baseline`` is the control
#: (Case B with the films' majority at every unfilmed joint).
UPDATE_SETS = {"answer": "identified", "reference": "true", "baseline": "films' majority"}


def _update_nodes(p: Pipeline, campaign, opts: RunOptions) -> list[str]:
    """The ROM update's nodes (beyond Eq. 19); returns the names of its full solves. Never the assembly test.

    The control ``full/updated_baseline`` (each blade's ε re-fitted for the baseline patterns) only where the
    campaign has a full-assembly test, the one thing it is compared with (Case B).
    """
    rom = {"disk": names.DISK_CB, "blade": names.BLADE_RUBIN, "dataset": names.DATASET, "features": names.FEATURES,
           "delta_all": names.DELTA_ALL, "bd": names.FE_MODEL}
    d1b = _ema_of(campaign, "d1b")
    p.add(Node(names.ROM_UPDATE_STIFFNESS, rom_update.stiffness_node, {**rom, "known": names.KNOWN, **d1b},
               label="contact stiffness fitted", version=5))  # 2: δ on the tuned pencil (§8.76); 3: settled; 5: χ²
    inputs = identify_inputs(campaign, opts)
    sets = {"answer": _answer(opts, "experimental")}
    if "numerical" in inputs:
        sets["reference"] = names.REFERENCE
    if campaign.of_type("assembly"):
        sets["baseline"] = names.PATTERNS_BASELINE
    cand = {"candidates": names.POSTERIOR_CANDIDATES} if opts.posterior else {}  # answers not borne out: §8.84
    for name, pats in sets.items():
        # Only the exported ROM's update warns: the controls would repeat its warnings with other figures.
        p.add(Node(names.rom_update(name), rom_update.update_node,
                   {**rom, "stiffness": names.ROM_UPDATE_STIFFNESS, "patterns": pats, **d1b,
                    **(cand if name == "answer" else {})}, {"warn": name == "answer"},
                   label=f"in-situ corrections ({UPDATE_SETS[name]} patterns)",
                   version=9))  # 3: joint pattern first; 4: none if calibrated otherwise; 5, 6: §8.53; 7-9: §8.76-84
    solves = {"updated": (_answer(opts, "experimental"), "answer")}
    if "reference" in sets:
        solves["updated_reference"] = (names.REFERENCE, "reference")
        solves["updated_numerical"] = (_answer(opts, "numerical"), "reference")
    if "baseline" in sets:
        solves["updated_baseline"] = (names.PATTERNS_BASELINE, "baseline")
    for name, (pats, upd) in solves.items():
        p.add(Node(names.full(name), rom_update.solve_updated,
                   {**_full_inputs(pats), "update": names.rom_update(upd)}, label=f"full-assembly ROM '{name}' solved",
                   version=full.VERSION))
    return list(solves)


def _validation_nodes(p: Pipeline, campaign, opts: RunOptions) -> None:
    inputs = identify_inputs(campaign, opts)
    assembly = {"assembly": names.ema("assembly")} if campaign.of_type("assembly") else {}
    p.add(Node(names.N_FULL_MODES, full.n_full_modes, assembly, {"n_blades": campaign.n_blades}, where="parent",
               stored=False))
    solves = [n for n in FULL if _full_wanted(n, inputs, opts)]
    for name in solves:
        pats = FULL[name]
        p.add(Node(names.full(name), full.solve_assembly, _full_inputs(pats),
                   label=f"full-assembly ROM '{name}' solved", version=full.VERSION))
    if opts.updated:
        solves += _update_nodes(p, campaign, opts)
    # version 2: the control B_baseline of both ROMs (cases["rom"])
    p.add(Node(names.VALIDATION, validation.full_validation, {**assembly, **{n: names.full(n) for n in solves}},
               {"bias": opts.bias, "answer": "posterior" if opts.posterior else "knn"}, version=2, where="parent"))
    numerical = names.patterns("numerical") if "numerical" in inputs else names.REFERENCE
    p.add(Node(names.D1B_ROWS, validation.d1b_rows, {
        "disk": names.DISK_CB, "blade": names.BLADE_RUBIN, "dataset": names.DATASET, "features": names.FEATURES,
        "delta_all": names.DELTA_ALL, "known": names.KNOWN, "identified": names.patterns("experimental"),
        "reference": names.REFERENCE, "numerical": numerical},
        {"source": "k-NN + refinement" if opts.refine else "k-NN"}, label="disk-one-blade validation"))


def _full_inputs(patterns: str) -> dict[str, str]:
    """The inputs of a full-assembly solve with the answer ``patterns`` (the paper's ROM's and the updated one's)."""
    return {"cyclic": names.DISK_CYCLIC, "bd": names.FE_MODEL, "blade": names.BLADE_RUBIN, "patterns": patterns,
            "delta_all": names.DELTA_ALL, "n_modes": names.N_FULL_MODES}


def campaign_pipeline(campaign, opts: RunOptions) -> Pipeline:
    """Every node of ``bladetwin run`` for ``campaign``, named as in :mod:`~bladetwin.stages.names`."""
    p = Pipeline()
    _ema_nodes(p, campaign)
    if opts.calibrate:
        _calibration_node(p, campaign)
    _model_nodes(p, campaign)
    _pattern_nodes(p, opts, campaign.n_blades)
    _identify_nodes(p, campaign, opts)
    if opts.posterior:
        _posterior_nodes(p, campaign, opts)
    _validation_nodes(p, campaign, opts)
    response.add_response_node(p, campaign, opts)
    return p
