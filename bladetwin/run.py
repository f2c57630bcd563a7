"""``bladetwin run``: the whole identification on a campaign folder (design §2, issue 11).

Stages, each timed and each cached by the hash of its inputs (a warm re-run recomputes nothing unchanged):

1. **EMA** of every UFF of the manifest: automatic selection (LSRF), or the test's picks file. Gives the
   blade deltas (Eq. 37), the disk modes with nodal diameters, the disk–one-blade table and the full
   assembly's modes.
2. **ROM**: reduced disk (one slot) and Rubin blade (``rom.cache``).
3. **Films → synthetic patterns → sensitivity → dataset** (PCA sampler, §6.1–6.3).
4. **Model bias** of the ROM, per tracked mode, on the filmed joints (their patterns are known).
5. **Two-step k-NN** for every joint, from the measured deltas and d1b frequencies (experimental input,
   bias removed); with reference patterns for every joint (``truth/``), also from the numerical input.
6. **Validation**: geometric, disk–one-blade, and the full assembly's Cases A/B/C (paper §8) beside a
   baseline that gives every unfilmed joint the majority pattern of the films.

Stages overlap where they can (design §8.17): the EMA runs in forked workers while the CB disk builds in a
forked process of its own; the full-assembly solves that need no identification (they use the FE disk and the
Rubin blade, not the CB) start as soon as the EMA is done (the baseline) and the CB (the reference); with the
refinement, each input's full solve starts as soon as that input's searches end, the numerical input's first.

Computing lives here; :mod:`bladetwin.run_outputs` writes the tables, figures and the report.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import multiprocessing
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import ema
from identify.dataset import Dataset, grid_from_deltas, load_dataset, save_dataset
from identify.dataset_parts import build_dataset_parts
from identify.errors import IdentifyError
from identify.knn import TwoStepKNN, query_matrix
from identify.refine import refine_pattern
from identify.sensitivity import Sensitivity, model_key, sensitivity
from identify.tracking import ModeTracker
from identify.validation import GridError, ModeComparison, compare_modes, grid_error
from lab.rig import rom_modal_model
from rom import cache
from rom.contact import ContactPattern
from rom.fileio import atomic_path
from rom.mistuning import rom_deltas
from rom.rubin import RubinModel

from .campaign import Campaign, CampaignError, TestEntry, check_files
from .pipeline import (
    MATCH_WINDOW,
    BladeTests,
    Models,
    bias_spread,
    family_samplers,
    film_patterns,
    filmed_frequencies,
    known_bias,
    load_model,
    mean_known_pattern,
    measured_tracked,
    read_films,
    synthesize,
)

__all__ = ["RunOptions", "EMAOutcome", "FullModes", "RunResult", "run_campaign", "ema_stage", "blade_table",
           "dataset_stage"]

#: Bump when a stage's results change for the same inputs (invalidates the stage caches).
EMA_CACHE_VERSION = 2
FULL_CACHE_VERSION = 1
#: Bump when rom.cyclic's solve changes its results for the same inputs (the full solves' cache key).
CYCLIC_SOLVE_VERSION = 1
REFINE_CACHE_VERSION = 1

#: The paper's Table 8 (mean |Δf| in %, mean MAC), shown beside the run's own cases.
PAPER_TABLE8 = {"A": {"mean_abs_df_pct": 0.07, "mean_mac": 0.91}, "B": {"mean_abs_df_pct": 0.73, "mean_mac": 0.85},
                "C": {"mean_abs_df_pct": 0.46, "mean_mac": 0.82}}


@dataclass(frozen=True)
class RunOptions:
    """Settings of a run (defaults: the paper's, and the refinement after the k-NN, which is beyond it).

    Attributes
    ----------
    cache_dir : Path or None
        Stage caches (EMA, datasets, full-assembly solves) and reduced models; default ``rom.cache``'s.
    n_patterns, scale, seed :
        PCA sampler: synthetic patterns per flank, Eq. 31's Scale, random seed.
    step_pct : float
        δ grid step (%).
    n_features, n_delta_modes : int
        Feature modes of the k-NN, blade modes on the δ grid.
    bias : bool
        Remove the ROM's per-mode bias estimated on the filmed joints (step 4).
    workers : int
        Processes for the EMA and the full-assembly solves (each single-threaded).
    dask_workers, scheduler :
        Build the dataset on a local Dask cluster of that many workers, or on the Dask scheduler at that
        address (``identify.dataset_parts``); default in this process. The table is the same either way.
    refine : int
        After the k-NN, refine every unfilmed joint's pattern by a compass search of at most this many d1b
        solves (:func:`identify.refine.refine_pattern`, beyond the paper); 0: the k-NN's pair, as the paper.
        The default, 40, is what Case A's MAC needs on the bundled campaign (README, "Refining the k-NN's
        answer"): 0.896 with the k-NN alone, 0.934 with 30, 0.946 with 40.
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


@dataclass(frozen=True, eq=False)
class EMAOutcome:
    """One test's EMA: its modal model, fit quality, how its poles were chosen, and its diagram figure."""

    test: TestEntry
    model: ema.ModalModel
    fit_quality: np.ndarray
    method: str
    picked: bool
    diagram_png: Path | None
    cached: bool


@dataclass(frozen=True, eq=False)
class FullModes:
    """Modes of one full-assembly ROM: frequencies (Hz, shape (n,)), shapes at the measurement DOFs, labels."""

    frequencies_hz: np.ndarray
    meas_shapes: np.ndarray
    meas_labels: list


@dataclass(frozen=True, eq=False)
class RunResult:
    """Everything a run computed (inputs of :mod:`bladetwin.run_outputs`).

    Frequencies are in Hz, δ and bias relative (0.01 = 1 %). ``joints`` (shape (n_joints,)) are the joints
    with a disk–one-blade test; ``measured_hz`` (shape (n_joints, n_tracked)) their EMA frequencies matched to
    the dataset's tracked modes (NaN: not found); ``final_patterns`` holds one pattern per joint 1..N (films
    at the known joints); ``full`` the full-assembly ROM modes by name (identified, identified_no_bias,
    baseline, reference, numerical); ``cases`` Table 8 (None where unavailable).
    """

    campaign: Campaign
    options: RunOptions
    ema: dict[str, EMAOutcome]
    blades: BladeTests
    models: Models
    films: dict
    known: dict[int, ContactPattern]
    synthetic: object
    sensitivity_files: dict[str, Path]
    dataset: Dataset
    delta_all: np.ndarray
    joints: np.ndarray
    measured_hz: np.ndarray
    bias: np.ndarray
    bias_spread: np.ndarray
    predictions: dict
    final_patterns: list[ContactPattern]
    baseline_pattern: ContactPattern
    reference: list[ContactPattern] | None
    d1b_rows: list[dict]
    full: dict[str, FullModes]
    cases: dict
    comparisons: dict[str, ModeComparison]
    step1: GridError
    notes: list[str]
    timings_s: dict[str, float] = field(default_factory=dict)


# ------------------------------------------------------------------------------------------------- helpers
def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _save_npz(path: Path, **arrays) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)


class _Background:
    """Cache-writing jobs in ``workers`` forked processes while this process goes on (design §8.17).

    Forked children share the parent's memory copy-on-write as it was at the fork (the models: see
    :data:`_MODELS`); every job takes small arguments, writes its result to the cache and returns its name.
    Without ``fork``, or with one worker, jobs run at once in this process. Progress goes to ``say`` as jobs
    finish; :meth:`wait` re-raises a job's error here.
    """

    def __init__(self, workers: int, say: Callable[[str], None], processes: int | None = None) -> None:
        self.say = say
        self.pending: list = []
        self.done = 0
        fork = "fork" in multiprocessing.get_all_start_methods()
        # ``processes``: a smaller pool for a job that should only leave this process free (the CB build)
        self.pool = (multiprocessing.get_context("fork").Pool(processes or workers) if workers >= 2 and fork
                     else None)

    def _finished(self, label: str) -> None:
        self.done += 1
        self.say(f"  {label} ({self.done} of {len(self.pending) or self.done} done)")

    def submit(self, fn, job, label: str):
        """Run ``fn(job)``; returns its pending result (``None`` when it ran at once here)."""
        if self.pool is None:
            fn(job)
            self._finished(label)
            return None
        r = self.pool.apply_async(fn, (job,), callback=lambda _: self._finished(label))
        self.pending.append(r)
        return r

    @staticmethod
    def wait_for(results) -> None:
        """Wait for some of the submitted jobs (re-raising their errors), the others going on."""
        for r in results:
            if r is not None:
                r.get()

    def wait(self) -> None:
        try:
            for r in self.pending:
                r.get()
        finally:
            self.close()

    def close(self) -> None:
        if self.pool is not None:
            self.pool.terminate() if any(not r.ready() for r in self.pending) else self.pool.close()
            self.pool.join()
            self.pool = None


# ------------------------------------------------------------------------------------------------- stage 1: EMA
def _test_name(t: TestEntry) -> str:
    return t.type if t.index is None else f"{t.type}_{t.index:02d}"


def _ema_key(t: TestEntry) -> str:
    picks = _sha(t.picks) if t.picks is not None else ""
    return cache.hash_inputs("ema", EMA_CACHE_VERSION, _sha(t.file), t.max_order, picks)[:32]


def _ema_job(job: tuple[TestEntry, Path, bool]) -> str:
    """Fit one test (automatic selection or its picks) and store the model (+ diagram figure) in the cache."""
    t, path, plot = job
    frf = ema.read_uff(t.file)
    if t.picks is not None:
        res = ema.fit_with_picks(frf, ema.load_picks(t.picks))
    else:
        res = ema.fit(frf, max_order=t.max_order)
    m = res.model
    if plot:
        from ema.plots import plot_stabilization

        from .util import atomic_savefig

        fig = plot_stabilization(res.diagram, frf, selected_hz=m.frequency_hz)
        fig.axes[0].set_title(f"{t.file.name}: {res.diagram.method.upper()}, "
                              f"{'picked by hand' if t.picks is not None else 'automatic selection'}, "
                              f"{m.n_modes} modes")
        atomic_savefig(fig, path.with_suffix(".png"), dpi=110)
        import matplotlib.pyplot as plt

        plt.close(fig)
    _save_npz(path, frequency_hz=m.frequency_hz, damping_ratio=m.damping_ratio, shapes=m.shapes,
              dofs=np.asarray(m.dofs, np.int64).reshape(-1, 2), fit_quality=np.asarray(res.quality, float),
              method=np.array(res.diagram.method), scaling=np.array(m.scaling),
              picked=np.array(t.picks is not None))
    return path.name


def _ema_plan(campaign: Campaign, cache_dir: Path) -> tuple[dict, list[str]]:
    """Each test's (entry, cache file, draw its diagram?) by name, and the names not in the cache yet."""
    folder = cache_dir / "ema"
    folder.mkdir(parents=True, exist_ok=True)
    tests, first = {}, set()
    for t in campaign.tests:
        name = _test_name(t)
        plot = t.type not in first or t.picks is not None
        first.add(t.type)
        tests[name] = (t, folder / f"{name}-{_ema_key(t)}.npz", plot)
    todo = [n for n, (_, p, plot) in tests.items() if not p.is_file() or (plot and not p.with_suffix(".png").is_file())]
    # the dense full-assembly spectrum first: it is the longest job, the others fill the other worker
    todo.sort(key=lambda n: (tests[n][0].type != "assembly", n))
    return tests, todo


def _ema_submit(bg: _Background, tests: dict, todo: list[str]) -> None:
    for name in todo:
        bg.submit(_ema_job, tests[name], f"EMA {name}")


def _ema_load(tests: dict, todo: list[str]) -> dict[str, EMAOutcome]:
    out = {}
    for name, (t, path, plot) in tests.items():
        with np.load(path, allow_pickle=False) as z:
            m = ema.ModalModel(z["frequency_hz"], z["damping_ratio"], z["shapes"],
                               tuple((int(a), int(b)) for a, b in z["dofs"]), scaling=str(z["scaling"]))
            out[name] = EMAOutcome(t, m, z["fit_quality"], str(z["method"]), bool(z["picked"]),
                                   path.with_suffix(".png") if plot else None, name not in todo)
    return out


def ema_stage(campaign: Campaign, cache_dir: Path, *, workers: int = 2,
              say: Callable[[str], None] = lambda m: None) -> dict[str, EMAOutcome]:
    """EMA of every test of the campaign, through the EMA cache (keyed by file bytes, order and picks).

    The first test of each type, and every test with picks, also gets its stabilization diagram (PNG
    beside the cached model).
    """
    tests, todo = _ema_plan(campaign, cache_dir)
    if todo:
        say(f"EMA of {len(todo)} of {len(tests)} tests ({len(tests) - len(todo)} cached)")
        bg = _Background(workers, say)
        _ema_submit(bg, tests, todo)
        bg.wait()
    return _ema_load(tests, todo)


def blade_table(outcomes: dict[str, EMAOutcome], campaign: Campaign) -> BladeTests:
    """Blade frequencies and deltas (Eq. 37) from the blade tests' EMA."""
    models = {n: o.model for n, o in outcomes.items() if o.test.type == "blade"}
    if len(models) != campaign.n_blades:
        raise CampaignError(f"{campaign.root / 'campaign.toml'}: {len(models)} blade tests for {campaign.n_blades} "
                            "blades; the deltas need every blade")
    return BladeTests(models, ema.campaign.frequency_table(models).to_numpy(), ema.blade_deltas(models).to_numpy())


# ------------------------------------------------------------------------------------------------- stage 3: dataset
def dataset_stage(models: Models, synthetic, grid: np.ndarray, opts: RunOptions, cache_dir: Path,
                  say: Callable[[str], None] = lambda m: None) -> tuple[Dataset, dict[str, Path]]:
    """Sensitivity and dataset through the dataset cache (keyed by the model, patterns, δ grid and features).

    Returns the dataset and its sensitivity files (figures of paper Figs. 15–16 and a table), kept beside
    it in the cache. The sensitivity is computed whenever the dataset or any of those files is missing.
    """
    mk = model_key(models.disk, models.blade)
    key = cache.hash_inputs("dataset", mk, np.asarray(synthetic.L), np.asarray(synthetic.R), np.asarray(grid),
                            opts.n_features, opts.n_delta_modes)[:32]
    folder = cache_dir / "datasets"
    path = folder / f"dataset-{key}.parquet"
    files = {"sensitivity.png": folder / f"dataset-{key}-sensitivity.png",
             "frequency_maps.png": folder / f"dataset-{key}-frequency_maps.png",
             "sensitivity.csv": folder / f"dataset-{key}-sensitivity.csv"}
    if path.is_file() and all(f.is_file() for f in files.values()):
        return load_dataset(path, model_key=mk), files
    say(f"sensitivity over {len(synthetic.L) * len(synthetic.R)} pattern pairs")
    sens = sensitivity(models.disk, models.blade, synthetic.L, synthetic.R, n_features=opts.n_features,
                       progress=False)
    folder.mkdir(parents=True, exist_ok=True)
    _write_sensitivity(sens, files)
    if path.is_file():
        return load_dataset(path, model_key=mk), files
    n = len(grid) ** opts.n_delta_modes * len(synthetic.L) * len(synthetic.R)
    say(f"dataset: {len(grid)}^{opts.n_delta_modes} δ rows × {len(synthetic.L) * len(synthetic.R)} pairs = {n} "
        "samples (reanalysis)")
    # In Parquet parts beside the cache entry: a build that is interrupted resumes where it stopped.
    parts = folder / f"dataset-{key}.parts"
    ds = build_dataset_parts(models.disk, models.blade, synthetic.L, synthetic.R, grid, parts,
                             n_delta_modes=opts.n_delta_modes, sensitivity=sens, n_features=opts.n_features,
                             workers=opts.dask_workers, scheduler=opts.scheduler, say=say)
    save_dataset(ds, path)
    shutil.rmtree(parts, ignore_errors=True)  # the table holds it all now
    return ds, files


def _write_sensitivity(sens: Sensitivity, files: dict[str, Path]) -> None:
    """The sensitivity figures (paper Figs. 15–16) and table, written beside the dataset."""
    import matplotlib.pyplot as plt

    from identify.plots import plot_frequency_maps, plot_sensitivity

    from .util import atomic_savefig, atomic_write_text

    for name, fig in (("sensitivity.png", plot_sensitivity(sens)),
                      ("frequency_maps.png", plot_frequency_maps(sens))):
        atomic_savefig(fig, files[name], dpi=110)
        plt.close(fig)
    rows = "".join(f"{m + 1},{sens.mean_hz[m]:.6g},{sens.std_hz[m]:.6g},{sens.std_rel_pct[m]:.6g},"
                   f"{int(m in sens.feature_modes)}\n" for m in range(sens.n_modes))
    atomic_write_text(files["sensitivity.csv"], "mode,mean_hz,std_hz,std_pct,feature\n" + rows)


# ------------------------------------------------------------------------------------------------- stage 6: full
#: The models the forked full-assembly workers solve with (set just before their pool forks).
_MODELS: dict = {}


def _full_job(job: tuple) -> str:
    """One full-assembly ROM solve (one BLAS thread when solves run side by side), stored in the cache."""
    from threadpoolctl import threadpool_limits

    from rom.cyclic import solve_full_cyclic
    from rom.errors import ROMError
    from rom.rom_assembly import solve_full

    L, R, deltas, n_modes, path, single = job
    method, disk, blade, bd = _MODELS["full"]
    patterns = {s + 1: ContactPattern(L[s], R[s]) for s in range(len(L))}
    with threadpool_limits(1 if single else None):
        modes = None
        if method == "cyclic":
            try:
                modes = solve_full_cyclic(disk, blade, patterns, deltas, n_modes=n_modes).modes
            except ROMError:  # a slot's local stiffness not numerically positive definite: the hybrid copes
                method = "hybrid"
        if modes is None:
            modes = solve_full(bd, blade, patterns, deltas, n_modes=n_modes)
    _save_npz(path, frequencies_hz=modes.frequencies_hz, meas_shapes=modes.meas_shapes,
              meas_labels=np.array(json.dumps([list(lab) for lab in modes.meas_labels])),
              method=np.array(method))
    return path.name


def _full_path(model_key: str, patterns: list[ContactPattern], deltas: np.ndarray, n_modes: int,
               cache_dir: Path) -> Path:
    key = cache.hash_inputs("full", FULL_CACHE_VERSION, model_key,
                            np.stack([p.L for p in patterns]), np.stack([p.R for p in patterns]),
                            np.asarray(deltas, float), int(n_modes))[:32]
    return cache_dir / "full" / f"full-{key}.npz"


def _disk_job(job: tuple[str, Path, bool, str]) -> float:
    """A disk model of :data:`_MODELS` ``["bd"]`` built into the cache; returns the seconds it took.

    ``job`` = (kind, cache folder, forked, cache key): kind ``"cb"`` is the one-slot CB of the disk–one-blade
    ROMs, ``"cyclic"`` the all-slot cyclic CB of the full-assembly solves (:mod:`rom.cyclic`). A disk that is
    not cyclic leaves a note (:func:`_cyclic_refused`) instead, and the full solves use the sparse hybrid.

    In a forked process, one BLAS/MKL thread: once the parent has run MKL's OpenMP thread team (any earlier
    Pardiso factorization in it), a forked child that enters a threaded Pardiso phase waits forever on that
    team (seen as a hang of the test suite). The EMA or the other build hold the other core then.
    """
    from threadpoolctl import threadpool_limits

    from rom.errors import ROMError

    kind, cache_dir, forked, key = job
    if forked and kind == "cyclic":
        # Only the full-assembly solves need the cyclic disk, late in the run, while the CB disk and the EMA
        # hold up the next stage: at a lower priority the cyclic build takes the cores they leave idle.
        with contextlib.suppress(OSError):  # a priority is a preference: where it is refused, build anyway
            os.nice(5)
    t = time.perf_counter()
    with threadpool_limits(1 if forked else None):
        if kind == "cb":
            cache.cached_reduce_disk(_MODELS["bd"], (1,), cache_dir=cache_dir, key=key)
        else:
            try:
                cache.cached_reduce_disk_cyclic(_MODELS["bd"], cache_dir=cache_dir, key=key)
            except ROMError as exc:
                from .util import atomic_write_text

                atomic_write_text(_cyclic_refused(cache_dir, key), f"{exc}\n")
    return time.perf_counter() - t


def _cyclic_refused(cache_dir: Path, key: str) -> Path:
    """Where a disk that :func:`rom.cyclic.reduce_disk_cyclic` refused keeps its reason (not retried)."""
    return cache_dir / f"disk-cyclic-{key[:32]}.refused"


class _SolveMemo:
    """The refinement's d1b solves on disk (``refine_pattern``'s ``memo``), one ``.npy`` per grid pair and δ.

    A joint's searches for the three inputs start from the same grids, often the same pair, and share their
    first polls; the forked workers share the solves through this folder. Writes are atomic; an unreadable
    entry reads as absent, so it is solved again.
    """

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def get(self, key: str):
        try:
            return np.load(self.folder / f"{key}.npy", allow_pickle=False)
        except (OSError, ValueError, EOFError):
            return None

    def __setitem__(self, key: str, value: np.ndarray) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        with atomic_path(self.folder / f"{key}.npy") as tmp, open(tmp, "wb") as fh:
            np.save(fh, np.asarray(value, np.float64), allow_pickle=False)


def _refine_job(job: tuple) -> str:
    """One joint's compass search (:func:`identify.refine.refine_pattern`), its grids stored in the cache."""
    gray_L, gray_R, target, delta, max_solves, tol_pct, path = job
    tracker, samplers, feat, memo = _MODELS["refine"]
    r = refine_pattern(tracker, *samplers, target, feat, gray_L, gray_R, delta=delta, max_solves=max_solves,
                       tol_pct=tol_pct, memo=memo)
    _save_npz(path, L=r.pattern.L, R=r.pattern.R, error_pct=r.error_pct, start_error_pct=r.start_error_pct,
              n_solves=r.n_solves)
    return path.name


def _refine_stage(sets: dict, joints: np.ndarray, known, sp, films, tracker: ModeTracker, feat: list[int],
                  delta_all: np.ndarray, opts: RunOptions, cache_dir: Path, say,
                  on_set: Callable[[str, dict], None] = lambda name, patterns: None) -> dict:
    """Refine every unfilmed joint's k-NN pair, per input; cached by its inputs, in ``opts.workers`` processes.

    ``sets`` maps an input's name to (patterns by joint, k-NN labels by joint, targets (n_joints, n_features)
    in ``joints`` order, the error % at which a search stops). The inputs are searched in that order, and
    ``on_set(name, refined patterns by joint)`` is called as soon as one input's joints are all done, while the
    next input's searches go on: the caller starts that input's full-assembly solve there. Returns name →
    (refined patterns by joint, mean k-NN error %, mean refined error %).
    """
    samplers = family_samplers(films)
    folder = cache_dir / "refine"
    folder.mkdir(parents=True, exist_ok=True)
    fam = cache.hash_inputs("family", tracker.shapes, *(x for s in samplers for x in
                                                         (s.mean_, s.components_, s.score_std_, s.threshold_)))
    jobs = {}
    for name, (_, labels, targets, tol_pct) in sets.items():
        for k, j in enumerate(joints):
            j = int(j)
            if j in known or j not in labels:
                continue
            iL, iR = labels[j][:2]
            key = cache.hash_inputs("refine", REFINE_CACHE_VERSION, fam, sp.gray_L[iL], sp.gray_R[iR],
                                    np.asarray(targets[k], float), np.asarray(delta_all[j - 1], float), feat,
                                    int(opts.refine), float(tol_pct))[:32]
            jobs[(name, j)] = (sp.gray_L[iL], sp.gray_R[iR], np.asarray(targets[k], float), delta_all[j - 1],
                               int(opts.refine), float(tol_pct), folder / f"refine-{key}.npz")
    todo = {kj: job for kj, job in jobs.items() if not job[-1].is_file()}
    bg = None
    if todo:
        say(f"refining {len(todo)} joint patterns (≤ {opts.refine} d1b solves each)")
        # The solves depend on the d1b ROM and the tracker's reference modes only (not on the family).
        memo_key = cache.hash_inputs("refine-solves", model_key(tracker.disk, tracker.blade, tracker.formulation),
                                     tracker.shapes, tracker.weight, int(tracker.n_extra))[:32]
        _MODELS["refine"] = (tracker, samplers, feat, _SolveMemo(folder / f"solves-{memo_key}"))
        bg = _Background(opts.workers, say)
    out = {}
    try:
        handles = {kj: bg.submit(_refine_job, job, f"joint {kj[1]} refined ({kj[0]} input)")
                   for kj, job in todo.items()} if bg is not None else {}
        for name, (pats, _, _, _) in sets.items():
            mine = [kj for kj in jobs if kj[0] == name]
            _Background.wait_for(handles[kj] for kj in mine if kj in handles)
            new, before, after = dict(pats), [], []
            for kj in mine:
                with np.load(jobs[kj][-1], allow_pickle=False) as z:
                    new[kj[1]] = ContactPattern(z["L"], z["R"])
                    before.append(float(z["start_error_pct"]))
                    after.append(float(z["error_pct"]))
            out[name] = (new, float(np.mean(before)) if before else float("nan"),
                         float(np.mean(after)) if after else float("nan"))
            on_set(name, new)
        if bg is not None:
            bg.wait()
    finally:
        if bg is not None:
            bg.close()
        _MODELS.pop("refine", None)
    return out


class _FullSolves:
    """Full-assembly ROM solves, cached by their inputs, run in the background as they are asked for.

    They run on the cyclic all-slot CB (:mod:`rom.cyclic`) once it is built (``cyclic_job``, in the
    background), or on the sparse hybrid (FE disk + Rubin blades) for a disk that is not cyclic. Until the
    cyclic build ends, solves are queued: :meth:`submit` and :meth:`poll` start them as soon as it has.
    ``keys`` = {"hybrid": …, "cyclic": …}: the full solves' model keys; ``cyclic_key`` is the cyclic disk's
    cache key.
    """

    def __init__(self, bd, blade: RubinModel, keys: dict[str, str], cyclic_key: str, cyclic_job,
                 deltas: np.ndarray, n_modes: int, cache_dir: Path, workers: int,
                 say: Callable[[str], None]) -> None:
        (cache_dir / "full").mkdir(parents=True, exist_ok=True)
        self.bd, self.blade = bd, blade
        self.keys, self.cyclic_key, self.cyclic_job = keys, cyclic_key, cyclic_job
        self.deltas, self.n_modes, self.cache_dir = deltas, n_modes, cache_dir
        self.say, self.workers = say, workers
        self.paths: dict[str, Path] = {}
        self.queue: list[tuple[str, list[ContactPattern]]] = []
        self.method: str | None = None
        self.refused = ""
        self.bg: _Background | None = None

    def submit(self, name: str, patterns: list[ContactPattern]) -> None:
        self.queue.append((name, patterns))
        self.poll()

    def poll(self, block: bool = False) -> None:
        """Start the queued solves if the model they run on is known (``block``: wait for its build)."""
        if self.method is None:
            job = self.cyclic_job
            if job is not None and not job.ready() and not block:
                return
            if job is not None:
                job.get()  # the build's own error, if any, surfaces here
            refused = _cyclic_refused(self.cache_dir, self.cyclic_key)
            if cache.cache_file("disk-cyclic", self.cyclic_key, self.cache_dir).is_file():
                self.method = "cyclic"
            else:
                self.method = "hybrid"
                self.refused = refused.read_text().strip() if refused.is_file() else "no cyclic model was built"
        queue, self.queue = self.queue, []
        for name, patterns in queue:
            self._start(name, patterns)

    def _start(self, name: str, patterns: list[ContactPattern]) -> None:
        path = _full_path(self.keys[self.method], patterns, self.deltas, self.n_modes, self.cache_dir)
        new = not path.is_file() and path not in self.paths.values()  # identical inputs are solved once
        self.paths[name] = path
        if not new:
            return
        if self.bg is None:
            if self.method == "cyclic":
                disk = cache.load_model(cache.cache_file("disk-cyclic", self.cyclic_key, self.cache_dir))
            else:
                disk = self.bd
            # The workers fork now and keep these (the bladed disk: the hybrid, for a solve the cyclic one refuses).
            _MODELS["full"] = (self.method, disk, self.blade, self.bd)
            self.bg = _Background(self.workers, self.say)
        where = " in the background" if self.bg.pool is not None else ""
        self.say(f"full-assembly ROM ({self.method}): solving '{name}' ({self.n_modes} modes){where}")
        job = (np.stack([p.L for p in patterns]), np.stack([p.R for p in patterns]), self.deltas, self.n_modes,
               path, self.bg.pool is not None)
        self.bg.submit(_full_job, job, f"full-assembly ROM '{name}' solved")

    def results(self) -> dict[str, FullModes]:
        self.poll(block=True)
        if self.bg is not None:
            try:
                self.bg.wait()
            finally:
                _MODELS.clear()
        out = {}
        for name, path in self.paths.items():
            with np.load(path, allow_pickle=False) as z:
                out[name] = FullModes(z["frequencies_hz"], z["meas_shapes"],
                                      [tuple(lab) for lab in json.loads(str(z["meas_labels"]))])
        return out

    def note(self) -> str:
        """How the full-assembly modes were computed, for the report (after :meth:`results`)."""
        if self.method != "cyclic":
            return f"Full-assembly ROM: the sparse hybrid (FE disk + Rubin blades): {self.refused}."
        fell_back = []
        for name, path in self.paths.items():
            with np.load(path, allow_pickle=False) as z:
                if "method" in z.files and str(z["method"]) == "hybrid":
                    fell_back.append(name)
        tail = (f" The cyclic solve refused the patterns of {', '.join(fell_back)} (a slot's stiffness not positive "
                "definite); those ran on the sparse hybrid." if fell_back else "")
        return ("Full-assembly ROM: the cyclic all-slot Craig–Bampton disk (built once per disk) with the Rubin "
                "blades, solved by Rayleigh–Ritz refined on its residuals (beyond the paper; against the FE "
                "reference on the default disk as close as the sparse hybrid: 0.012 %, MAC ≥ 0.9996, "
                "docs/rom.md §4.2 and §4.4)." + tail)


def _case(c: ModeComparison | None) -> dict | None:
    """Table 8's figures of one comparison: mean |Δf| (%), mean MAC, pairs, and the reference modes offered."""
    if c is None or not c.pairs.size:
        return None
    return {"mean_abs_df_pct": c.mean_abs_freq_error_pct, "mean_mac": c.mean_mac, "n_modes": int(len(c.pairs)),
            "n_reference_modes": int(c.mac_matrix.shape[0])}


#: Pairing of a ROM's modes with measured ones (Cases B, C): MAC-maximizing, within ±5 %, MAC ≥ 0.3, as the
#: rig's own Case C check (``lab.model_error``). Measured shapes in dense families can be poor; a mode without
#: a credible partner stays unpaired (counted in ``n_reference_modes``) rather than being forced onto a distant one.
MEASURED_WINDOW, MEASURED_MAC_MIN = 0.05, 0.3


def _vs_measured(measured: ema.ModalModel, rom: FullModes) -> ModeComparison:
    """A ROM's modes against the measured ones, on their common DOFs (shapes sign-aware through the MAC)."""
    from ema.mac import common_dofs

    model = rom_modal_model(rom)
    pa, pb, _ = common_dofs(measured, model)
    if pa.shape[0] < 2:
        raise CampaignError("the full-assembly test and the ROM share fewer than 2 measurement DOFs: the node "
                            "numbering of the UFF file does not follow the rig's convention (docs/campaign.md)")
    return compare_modes((measured.frequency_hz, pa), (model.frequency_hz, pb), freq_window=MEASURED_WINDOW,
                         mac_min=MEASURED_MAC_MIN)


def _in_band(m: FullModes, f_max: float) -> FullModes:
    keep = m.frequencies_hz <= f_max
    return FullModes(m.frequencies_hz[keep], m.meas_shapes[:, keep], m.meas_labels)


# ------------------------------------------------------------------------------------------------- the run
def run_campaign(campaign: Campaign, opts: RunOptions = RunOptions(),
                 say: Callable[[str], None] = lambda m: None) -> RunResult:
    """Run every stage on ``campaign`` (module docstring). Checks every file first (one-line errors)."""
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    cache_dir = Path(opts.cache_dir) if opts.cache_dir is not None else cache.default_cache_dir()
    notes: list[str] = []

    t0 = time.perf_counter()
    say("checking the campaign's files")
    check_files(campaign)
    films = read_films(campaign)  # every film must read before the long stages
    if not campaign.of_type("d1b"):
        raise CampaignError(f"{campaign.root / 'campaign.toml'}: no disk-one-blade (d1b) test: the k-NN needs "
                            "their frequencies")
    # The EMA runs in the background while this process builds the reduced models: the full-assembly EMA is
    # one long job, so a worker would otherwise idle for most of the stage.
    tests, todo = _ema_plan(campaign, cache_dir)
    ema_bg = None
    if todo:
        say(f"EMA of {len(todo)} of {len(tests)} tests ({len(tests) - len(todo)} cached), in the background")
        ema_bg = _Background(opts.workers, say)
        _ema_submit(ema_bg, tests, todo)
    disk_bg, disk_job, cyclic_job = None, None, None
    try:
        t1 = time.perf_counter()
        say("reduced models (from the cache; the first build takes a few minutes at the default level)")
        bd = load_model(campaign)
        # The two disk builds, the long ones, run in forked processes of their own, side by side: the one-slot
        # CB (the d1b ROMs, needed first) and the cyclic all-slot CB (the full-assembly solves, needed later).
        disk_key = cache.disk_key(bd)  # hashes the disk's K and M (~2 s): once per run
        cyclic_key = cache.cyclic_disk_key(bd, base_key=disk_key)
        builds = []
        if not cache.cache_file("disk-cb", disk_key, cache_dir).is_file():
            builds.append(("cb", disk_key, "Craig–Bampton disk built"))
        if not (cache.cache_file("disk-cyclic", cyclic_key, cache_dir).is_file()
                or _cyclic_refused(cache_dir, cyclic_key).is_file()):
            builds.append(("cyclic", cyclic_key, "cyclic all-slot disk built"))
        if builds:
            _MODELS["bd"] = bd
            disk_bg = _Background(opts.workers, say, processes=len(builds))
            handles = {kind: disk_bg.submit(_disk_job, (kind, cache_dir, disk_bg.pool is not None, key), label)
                       for kind, key, label in builds}
            disk_job, cyclic_job = handles.get("cb"), handles.get("cyclic")
        # The blade after the disk builds have started: the CB disk is the longer way to the dataset.
        blade = cache.cached_reduce_blade(bd, cache_dir=cache_dir)
        rom_s = time.perf_counter() - t1
        if ema_bg is not None:
            ema_bg.wait()
    except BaseException:
        if disk_bg is not None:
            disk_bg.close()
        _MODELS.pop("bd", None)
        raise
    finally:
        if ema_bg is not None:
            ema_bg.close()
    outcomes = _ema_load(tests, todo)
    blades = blade_table(outcomes, campaign)
    timings["ema"] = time.perf_counter() - t0  # includes the ROM build it overlapped
    if any(o.picked for o in outcomes.values()):
        notes.append("Picks files replaced the automatic pole selection for: "
                     + ", ".join(o.test.file.name for o in outcomes.values() if o.picked) + ".")

    known = film_patterns(films)
    base = mean_known_pattern(known)
    delta_all = rom_deltas(blades.frequencies_hz, blades.deltas_pct, blade.frequencies_hz)
    reference = _reference_patterns(campaign)
    assembly = [o for o in outcomes.values() if o.test.type == "assembly"]
    measured_full = assembly[0].model if assembly else None
    n = campaign.n_blades
    n_modes = 3 * n if measured_full is None else max(3 * n, measured_full.n_modes + n)
    # The solves that need no identification are asked for now; they start when the cyclic disk is built.
    solves = None
    try:
        blade_key = cache.blade_key(bd)
        keys = {"hybrid": cache.hash_inputs("full-hybrid", disk_key, blade_key),
                "cyclic": cache.hash_inputs("full-cyclic", cyclic_key, blade_key, CYCLIC_SOLVE_VERSION)}
        solves = _FullSolves(bd, blade, keys, cyclic_key, cyclic_job, delta_all, n_modes, cache_dir, opts.workers,
                             say)
        solves.submit("baseline", [known.get(j, base) for j in range(1, n + 1)])
        if reference is not None:
            solves.submit("reference", list(reference))
        t1 = time.perf_counter()
        if disk_job is not None:
            say("waiting for the Craig–Bampton disk")
            while not disk_job.ready():  # the early solves start as soon as the cyclic disk is there
                solves.poll()
                disk_job.wait(1.0)
            _Background.wait_for([disk_job])
        _MODELS.pop("bd", None)
        models = Models(bd, cache.cached_reduce_disk(bd, (1,), cache_dir=cache_dir, key=disk_key), blade)
        timings["rom"] = rom_s + (disk_job.get() if disk_job is not None else time.perf_counter() - t1)
        t0 = time.perf_counter()
        say(f"PCA sampler: {opts.n_patterns} synthetic patterns per flank from {len(films)} filmed joints")
        sp = synthesize(films, n_patterns=opts.n_patterns, scale=opts.scale, seed=opts.seed)
        nd = opts.n_delta_modes
        grid = grid_from_deltas(delta_all[:, :nd], step=opts.step_pct / 100, n_delta_modes=nd)
        ds, sens_files = dataset_stage(models, sp, grid, opts, cache_dir, say)
        timings["dataset"] = time.perf_counter() - t0
        solves.poll()
        return _identify_and_validate(campaign, opts, say, timings, t_all, notes, outcomes, blades, models, films,
                                      known, base, sp, sens_files, ds, delta_all, reference, measured_full, solves)
    finally:
        if disk_bg is not None:
            disk_bg.close()
        if solves is not None and solves.bg is not None:
            solves.bg.close()
            _MODELS.clear()


def _identify_and_validate(campaign, opts, say, timings, t_all, notes, outcomes, blades, models, films, known, base,
                           sp, sens_files, ds, delta_all, reference, measured_full, solves) -> RunResult:
    """Steps 4–6 of :func:`run_campaign` (bias, k-NN, validation), the early full solves under way."""
    t0 = time.perf_counter()
    say("bias on the filmed joints and the two-step k-NN for every joint")
    tracker = ModeTracker.from_dataset(models.disk, models.blade, ds)
    knn = TwoStepKNN.from_dataset(ds)
    feat = list(ds.feature_modes)
    d1b = {o.test.index: o.model for o in outcomes.values() if o.test.type == "d1b"}
    joints = np.array(sorted(d1b))
    nd = opts.n_delta_modes
    deltas = delta_all[joints - 1, :nd]
    measured = measured_tracked(ds, d1b, joints, deltas)
    meas_known, rom_known = filmed_frequencies(tracker, known, delta_all, joints, measured)
    if len(rom_known) < 2 and opts.bias:
        notes.append("Fewer than 2 filmed joints have a disk-one-blade test: the model bias was not estimated.")
    n_tracked = ds.frequencies_hz.shape[1]
    bias = known_bias(meas_known, rom_known) if opts.bias and len(rom_known) >= 2 else np.zeros(n_tracked)
    spread = bias_spread(meas_known, rom_known) if rom_known else np.zeros(n_tracked)

    def predict(features: np.ndarray) -> tuple[dict[int, ContactPattern], np.ndarray, dict[int, tuple]]:
        ok = np.isfinite(features).all(axis=1)
        pats, labels = {}, {}
        match = knn.match(query_matrix(deltas, np.where(np.isfinite(features), features, 0.0)))
        # How far each feature lies outside what the synthetic pairs reach at the joint's δ, relative.
        beyond = match.beyond / np.where(ok[:, None], features, 1.0)
        for k, j in enumerate(joints):
            if ok[k]:
                iL, iR = (int(x) for x in match.label[k, 0])
                pats[int(j)] = ContactPattern(ds.patterns_L[iL], ds.patterns_R[iR])
                labels[int(j)] = (iL, iR, float(match.distance[k, 0]), beyond[k])
        return pats, match.delta, labels

    f_exp = measured[:, feat]
    missing = joints[~np.isfinite(f_exp).all(axis=1)].tolist()
    if missing:
        notes.append(f"Joints {missing}: a feature mode was not found in the disk-one-blade EMA within "
                     f"{100 * MATCH_WINDOW:.0f} %; they get the baseline pattern.")
    if len(missing) == len(joints):
        raise IdentifyError("no disk-one-blade test has all feature modes "
                            f"{[m + 1 for m in feat]} within {100 * MATCH_WINDOW:.0f} % of the dataset's")
    pred_exp, step1_delta, labels_exp = predict(f_exp / (1 + bias[feat]))
    # A joint whose measured features lie beyond what the synthetic pairs reach, by more than twice the ROM's
    # scatter on the filmed joints (the model error the bias correction leaves, std per mode), is one the
    # family does not cover: the k-NN can only return the family's nearest edge for it.
    tol = 2 * spread[feat]
    outside = {j: lab[3] for j, lab in labels_exp.items() if j not in known and np.any(np.abs(lab[3]) > tol)}
    if outside:
        worst = max(outside, key=lambda j: np.max(np.abs(outside[j]) - tol))
        m = int(np.argmax(np.abs(outside[worst]) - tol))
        notes.append(f"Joints {sorted(outside)}: their measured feature frequencies"
                     f"{' (bias removed)' if opts.bias else ''} lie outside the range the {len(ds.patterns_L)} × "
                     f"{len(ds.patterns_R)} synthetic pattern pairs reach at their δ, by more than twice the ROM's "
                     f"scatter on the filmed joints (joint {worst}: {100 * abs(outside[worst][m]):.2f} % on mode "
                     f"{feat[m] + 1}, scatter {100 * spread[feat[m]]:.2f} %). Their contact is likely outside the "
                     "synthetic family and their identified pattern its nearest edge, not a match: trust it less, "
                     "and film one of them to widen the family.")
    for j, lab in labels_exp.items():
        labels_exp[j] = (*lab[:4], j in outside)
    pred_raw, _, labels_raw = predict(f_exp) if opts.bias else (pred_exp, None, labels_exp)
    step1 = grid_error(step1_delta, deltas, opts.step_pct / 100)
    pred_num, labels_num = {}, {}
    if reference is not None:
        f_num = np.array([tracker.track(reference[j - 1], delta_all[j - 1]).frequencies_hz[feat] for j in joints])
        pred_num, _, labels_num = predict(f_num)

    def final(pred: dict[int, ContactPattern]) -> list[ContactPattern]:
        # the film where there is one, else the k-NN's answer, else (no usable d1b test) the baseline
        out = []
        for j in range(1, campaign.n_blades + 1):
            p = known.get(j, pred.get(j))
            out.append(base if p is None else p)
        return out

    if opts.refine:
        # Measured targets are fitted down to the model error (the ROM's scatter on the filmed joints; without
        # the bias correction, bias and scatter together), not below it; the numerical input has none.
        tol_exp = float(100 * np.mean(spread[feat]))
        sets = {}
        # The identification proper first, the numerical input (a check against the reference) last. The
        # three inputs share most of their solves through the memo, so whichever comes later is nearly free;
        # the measured inputs' full-assembly solves then run beside the last searches, and only the
        # numerical one is left for the end (design §8.17).
        sets["experimental"] = (pred_exp, labels_exp, f_exp / (1 + bias[feat]), tol_exp)
        if opts.bias:
            tol_raw = float(100 * np.mean(np.hypot(bias[feat], spread[feat])))
            sets["experimental_no_bias"] = (pred_raw, labels_raw, f_exp, tol_raw)
        if reference is not None:
            sets["numerical"] = (pred_num, labels_num, f_num, 0.0)
        full_name = {"numerical": "numerical", "experimental": "identified",
                     "experimental_no_bias": "identified_no_bias"}
        refined = _refine_stage(sets, joints, known, sp, films, tracker, feat, delta_all, opts, solves.cache_dir,
                                say, on_set=lambda name, pats: solves.submit(full_name[name], final(pats)))
        pred_exp = refined["experimental"][0]
        pred_raw = refined["experimental_no_bias"][0] if opts.bias else pred_exp
        if reference is not None:
            pred_num = refined["numerical"][0]
        in_order = sorted(refined.items(), key=lambda kv: kv[0] == "numerical")  # the measured inputs first
        notes.append("Unfilmed joints' patterns refined after the k-NN by a compass search in the synthetic family "
                     f"and the contact level (≤ {opts.refine} d1b solves each, stopping at the model error: "
                     f"{tol_exp:.3f} %{' with the bias correction' if opts.bias else ''}; beyond the paper). Mean "
                     "feature error, k-NN pair → refined: " + "; ".join(
                         f"{k.replace('_', ' ')} input {b:.3f} % → {a:.3f} %" for k, (_, b, a) in in_order))

    predictions = {"experimental": labels_exp, "experimental_no_bias": labels_raw, "numerical": labels_num}
    timings["identify"] = time.perf_counter() - t0

    identified, numerical = final(pred_exp), final(pred_num)
    solves.submit("identified", identified)
    if opts.bias:
        solves.submit("identified_no_bias", final(pred_raw))
    if reference is not None:
        solves.submit("numerical", numerical)
    t0 = time.perf_counter()
    d1b_rows = []
    for k, j in enumerate(joints):
        j = int(j)
        # a filmed joint's identified pattern is its film: its ROM frequencies were tracked for the bias already
        f_id = rom_known[j] if j in rom_known else tracker.track(identified[j - 1], delta_all[j - 1]).frequencies_hz
        source = "film" if j in known else ("k-NN + refinement" if opts.refine else "k-NN")
        row = {"joint": j, "source": source, "measured_hz": measured[k, feat],
               "identified_hz": f_id[feat] * (1 + bias[feat])}
        if reference is not None:
            row["reference_hz"] = tracker.track(reference[j - 1], delta_all[j - 1]).frequencies_hz[feat]
            row["numerical_hz"] = tracker.track(numerical[j - 1], delta_all[j - 1]).frequencies_hz[feat]
        d1b_rows.append(row)

    full = solves.results()
    n_modes = solves.n_modes
    notes.append(solves.note())

    comps: dict[str, ModeComparison] = {}
    f_max = float(measured_full.frequency_hz.max()) if measured_full is not None and measured_full.n_modes else None
    if measured_full is not None and measured_full.n_modes:
        top = float(min(m.frequencies_hz.max() for m in full.values()))
        if top < f_max:
            notes.append(f"The ROM's {n_modes} modes reach {top:.1f} Hz, below the highest measured mode "
                         f"({f_max:.1f} Hz): the measured modes above are not compared.")
            keep = measured_full.frequency_hz <= top
            measured_full = ema.ModalModel(measured_full.frequency_hz[keep], measured_full.damping_ratio[keep],
                                           measured_full.shapes[:, keep], measured_full.dofs)
            f_max = top
        comps["B"] = _vs_measured(measured_full, full["identified"])
        comps["baseline_B"] = _vs_measured(measured_full, full["baseline"])
        if opts.bias:
            comps["B_no_bias"] = _vs_measured(measured_full, full["identified_no_bias"])
        if reference is not None:
            comps["C"] = _vs_measured(measured_full, full["reference"])
    else:
        notes.append("No full-assembly test: Cases B and C are unavailable.")
    if reference is not None:
        ref_modes = full["reference"] if f_max is None else _in_band(full["reference"], f_max)
        comps["A"] = compare_modes((ref_modes.frequencies_hz, ref_modes.meas_shapes),
                                   (full["numerical"].frequencies_hz, full["numerical"].meas_shapes))
        comps["baseline_A"] = compare_modes((ref_modes.frequencies_hz, ref_modes.meas_shapes),
                                            (full["baseline"].frequencies_hz, full["baseline"].meas_shapes))
    else:
        notes.append("Cases A and C need a reference pattern for every joint (truth/ of a virtual campaign, or "
                     "a film of every joint); this campaign has none, so they are unavailable.")
    cases = {"A": _case(comps.get("A")), "B": _case(comps.get("B")), "B_no_bias": _case(comps.get("B_no_bias")),
             "C": _case(comps.get("C")),
             "baseline": {"A": _case(comps.get("baseline_A")), "B": _case(comps.get("baseline_B"))}}
    timings["validation"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    return RunResult(campaign, opts, outcomes, blades, models, films, known, sp, sens_files, ds, delta_all, joints,
                     measured, bias, spread, predictions, identified, base, reference, d1b_rows, full,
                     cases, comps, step1, notes, timings)


def _reference_patterns(campaign: Campaign) -> list[ContactPattern] | None:
    """Reference patterns of every joint: ``truth/patterns.npz`` of a virtual campaign, or films of all joints."""
    truth = campaign.truth_dir
    if truth is not None and (truth / "patterns.npz").is_file():
        from rom.pattern_io import load_patterns

        pats = load_patterns(truth / "patterns.npz")
        if len(pats) != campaign.n_blades:
            raise CampaignError(f"{truth / 'patterns.npz'}: {len(pats)} patterns for {campaign.n_blades} joints")
        return pats
    if len(campaign.known_joints) == campaign.n_blades:
        return [film_patterns(read_films(campaign, [j]))[j] for j in range(1, campaign.n_blades + 1)]
    return None
