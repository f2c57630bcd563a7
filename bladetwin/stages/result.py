"""A campaign's run gathered from its nodes' outputs: what the writer turns into tables, figures and a report."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from identify.dataset import Dataset
from identify.film import orientation_checked
from identify.validation import GridError
from rom.contact import ContactPattern

from . import names
from .bias import MATCH_WINDOW, Features
from .campaign_graph import RunOptions, identify_inputs
from .full import method_note
from .knn import Predictions
from .measured import BladeTests
from .validation import FullValidation

__all__ = ["PAPER_TABLE8", "RunResult", "gather"]

#: The paper's Table 8 (mean |Δf| in %, mean MAC), shown beside the run's own cases.
PAPER_TABLE8 = {"A": {"mean_abs_df_pct": 0.07, "mean_mac": 0.91}, "B": {"mean_abs_df_pct": 0.73, "mean_mac": 0.85},
                "C": {"mean_abs_df_pct": 0.46, "mean_mac": 0.82}}


@dataclass(frozen=True, eq=False)
class RunResult:
    """Everything a campaign's run computed (the input of :mod:`bladetwin.outputs`).

    Frequencies in Hz, δ and bias relative (0.01 = 1 %). ``ema`` maps each test's name to (its manifest entry,
    its :class:`~bladetwin.stages.measured.TestFit`); ``final_patterns`` holds one pattern per joint 1..N (films
    at the filmed joints); ``full`` the full-assembly ROM modes by name (identified, identified_no_bias,
    baseline, reference, numerical; with the updated ROM also updated, updated_reference, updated_numerical and
    the control updated_baseline).
    """

    campaign: object
    options: RunOptions
    bd: object
    ema: dict
    blades: BladeTests
    films: dict
    known: dict[int, ContactPattern]
    synthetic: object
    sensitivity: object
    dataset: Dataset
    delta_all: np.ndarray
    features: Features
    predictions: Predictions
    final_patterns: list[ContactPattern]
    baseline_pattern: ContactPattern
    reference: list[ContactPattern] | None
    d1b_rows: list[dict]
    full: dict
    validation: FullValidation
    notes: list[str]
    timings_s: dict[str, float] = field(default_factory=dict)
    #: Stage nodes of this campaign computed in this run and found in the store (``computed``, ``reused``):
    #: a run's timings are a cold run's only when nothing was reused; ``seconds``: each computed node's own time.
    stage_counts: dict = field(default_factory=dict)
    #: What the user should know about the inputs and the run (one line each; :mod:`bladetwin.user_warnings`):
    #: a film read under a stated interpretation, a stage's numerical warning, a damaged store entry recomputed.
    warnings: list[str] = field(default_factory=list)
    #: The contact posterior's results, when it ran (``--method posterior|both``): ``"prior"``, ``"surrogate"`` and
    #: per input (``"experimental"``, ``"numerical"``) a dict joint → :class:`identify.JointPosterior`.
    posterior: dict = field(default_factory=dict)
    #: Each reported method's answers (``"knn"``, ``"posterior"``) per input (``"experimental"``, ``"numerical"``):
    #: one pattern per joint 1..N, films at the filmed joints.
    answers: dict = field(default_factory=dict)
    #: The ROM update beyond Eq. 19, when it ran (``--rom updated``): ``"stiffness"``
    #: (:class:`identify.rom_update.StiffnessFit` or None), ``"answer"`` and, with reference patterns,
    #: ``"reference"`` (:class:`identify.rom_update.UpdatedROM` with the run's answer or the true patterns) and,
    #: with a full-assembly test, ``"baseline"`` (the control's: the films' majority at every unfilmed joint).
    rom_update: dict = field(default_factory=dict)
    #: The paper's material calibration (:class:`bladetwin.stages.calibration.CalibrationResult`), None when off.
    calibration: object = None
    #: The forced response and amplification factors (:class:`bladetwin.stages.response.Response`), None if absent.
    response: object = None

    @property
    def joints(self) -> np.ndarray:
        return self.features.joints

    @property
    def step1(self) -> GridError:
        return self.predictions.step1

    @property
    def cases(self) -> dict:
        return self.validation.cases


def _outside_note(res: dict, opts: RunOptions) -> str | None:
    pred, f, ds = res[names.PREDICTIONS], res[names.FEATURES], res[names.DATASET]
    feat = list(ds.feature_modes)
    tol = 2 * f.spread[feat]
    outside = {j: lab[3] for j, lab in pred.labels["experimental"].items() if lab[4]}
    if not outside:
        return None
    worst = max(outside, key=lambda j: np.max(np.abs(outside[j]) - tol))
    m = int(np.argmax(np.abs(outside[worst]) - tol))
    return (f"Joints {sorted(outside)}: their measured feature frequencies{' (bias removed)' if opts.bias else ''} "
            f"lie outside the range the {len(ds.patterns_L)} × {len(ds.patterns_R)} synthetic pattern pairs reach at "
            f"their δ, by more than twice the ROM's scatter on the filmed joints (joint {worst}: "
            f"{100 * abs(outside[worst][m]):.2f} % on mode {feat[m] + 1}, scatter {100 * f.spread[feat[m]]:.2f} %). "
            "Their contact is likely outside the synthetic family and their identified pattern its nearest edge, "
            "not a match: trust it less, and film one of them to widen the family.")


def _refine_note(res: dict, campaign, opts: RunOptions) -> str:
    parts = []
    refined = {k: ij[0] for k in res if (ij := names.per_joint(k, names.REFINE)) is not None}
    for name in identify_inputs(campaign, opts):
        found = [r for r in (res[k] for k, i in refined.items() if i == name) if r is not None]
        before = float(np.mean([r.start_error_pct for r in found])) if found else float("nan")
        after = float(np.mean([r.error_pct for r in found])) if found else float("nan")
        parts.append(f"{name.replace('_', ' ')} input {before:.3f} % → {after:.3f} %")
    tol = res[names.PREDICTIONS].tolerance_pct["experimental"]
    return ("Unfilmed joints' patterns refined after the k-NN by a compass search in the synthetic family and the "
            f"contact level (≤ {opts.refine} d1b solves each, stopping at the model error: {tol:.3f} %"
            f"{' with the bias correction' if opts.bias else ''}; beyond the paper). Mean feature error, k-NN pair "
            "→ refined: " + "; ".join(parts))


def _film_note(films: dict) -> str | None:
    """How films without full metadata were read (the reader's fallbacks), naming them: the interpretation taken."""
    maps = [m for pair in films.values() for m in pair]
    placed = [Path(m.name).name for m in maps if m.geometry_source != "given"]
    otsu = [Path(m.name).name for m in maps if m.threshold_source == "otsu"]
    unturned = [Path(m.name).name for m in maps if m.geometry_source == "given" and not orientation_checked(m)]
    parts = []
    if placed:
        parts.append(f"placed by their imprint's bounding box (no origin, spacing and pixel_size): {', '.join(placed)}")
    if otsu:
        parts.append(f"thresholded by Otsu's rule (no contact_level): {', '.join(otsu)}")
    if unturned:
        parts.append("read as scanned, image rows along the grid's rows: their flank's cells are square in the "
                     f"image, so a scan rotated by 90° cannot be told from the imprint: {', '.join(unturned)}")
    return ("Films " + "; ".join(parts) + ".") if parts else None


def _notes(res: dict, campaign, opts: RunOptions, fits: dict) -> list[str]:
    notes = []
    film_note = _film_note(res[names.FILMS])
    if film_note:
        notes.append(film_note)
    picked = [t.file.name for t, fit in fits.values() if fit.picked]
    if picked:
        notes.append("Picks files replaced the automatic pole selection for: " + ", ".join(picked) + ".")
    if opts.bias and not res[names.FEATURES].bias_estimated:
        notes.append("Fewer than 2 filmed joints have a disk-one-blade test: the model bias was not estimated.")
    tested = {t.index for t in campaign.of_type("d1b")}
    untested = [j for j in range(1, campaign.n_blades + 1) if j not in tested and j not in campaign.known_joints]
    if untested:
        notes.append(f"Joints {untested}: no disk-one-blade test in the manifest; they get the baseline pattern "
                     "(the films' majority), not an identification.")
    missing = res[names.PREDICTIONS].missing
    if missing:
        notes.append(f"Joints {missing}: none of the feature modes was found in the disk-one-blade EMA within "
                     f"{100 * MATCH_WINDOW:.0f} %; they get the baseline pattern.")
    partial = res[names.PREDICTIONS].partial
    if partial:
        which = "; ".join(f"joint {j}: mode {', '.join(map(str, m))}" for j, m in partial.items())
        notes.append(f"Feature modes not found in the disk-one-blade EMA within {100 * MATCH_WINDOW:.0f} % ({which}): "
                     "those joints are identified on their other feature modes (less information: trust them less).")
    outside = _outside_note(res, opts)
    if outside:
        notes.append(outside)
    if opts.refine and opts.knn_reported:
        notes.append(_refine_note(res, campaign, opts))
    notes.append(method_note(names.members(res, names.FULL)))
    return notes + list(res[names.VALIDATION].notes)


def gather(res, campaign, opts: RunOptions, bd, timings: dict[str, float]) -> RunResult:
    """The :class:`RunResult` of one campaign from the runner's outputs, asked for by their names in
    :mod:`~bladetwin.stages.names`."""
    fits = {names.test_name(t): (t, res[names.ema(names.test_name(t))]) for t in campaign.tests}
    fulls = {solve: s.modes for solve, s in names.members(res, names.FULL).items()}
    post = _posterior(res) if opts.posterior else {}
    # the run's answer is the posterior's where it ran (design §8.30), else the k-NN's
    final = res[names.posterior_patterns("experimental") if post else names.patterns("experimental")]
    return RunResult(
        campaign=campaign, options=opts, bd=bd, ema=fits, blades=res[names.BLADE_TABLE], films=res[names.FILMS],
        known=res[names.KNOWN], synthetic=res[names.SYNTHETIC], sensitivity=res[names.SENSITIVITY],
        dataset=res[names.DATASET], delta_all=res[names.DELTA_ALL], features=res[names.FEATURES],
        predictions=res[names.PREDICTIONS], final_patterns=final, baseline_pattern=res[names.BASELINE],
        reference=res[names.REFERENCE], d1b_rows=res[names.D1B_ROWS], full=fulls, validation=res[names.VALIDATION],
        notes=_notes(res, campaign, opts, fits), timings_s=timings, posterior=post, answers=_answers(res, opts),
        rom_update=names.members(res, names.ROM_UPDATE),
        calibration=res[names.CALIBRATION] if names.CALIBRATION in res else None,
        response=res[names.RESPONSE] if names.RESPONSE in res else None)


def _answers(res, opts: RunOptions) -> dict:
    out = {}
    for method, answer, on in (("knn", names.patterns, opts.knn_reported),
                               ("posterior", names.posterior_patterns, opts.posterior)):
        if on:
            out[method] = {i: res[answer(i)] for i in ("experimental", "numerical") if answer(i) in res}
    return out


def _posterior(res) -> dict:
    """The posterior's nodes gathered: prior, surrogate, and per input each joint's posterior."""
    out: dict = {"prior": res[names.POSTERIOR_PRIOR], "surrogate": res[names.POSTERIOR_SURROGATE]}
    for k in res:
        input_joint = names.per_joint(k, names.POSTERIOR)
        if input_joint is not None and res[k] is not None:
            out.setdefault(input_joint[0], {})[input_joint[1]] = res[k]
    return out

