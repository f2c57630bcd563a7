"""The identification pipeline's steps on a campaign folder (floor 3: files, caching, EMA, ROM, identify).

Each step is a plain function on a :class:`bladetwin.campaign.Campaign`; ``bladetwin identify …`` runs them
one at a time and ``bladetwin run`` chains them (design §2).

The model is the campaign's ``[model]``: the academic twin (``family = "academic"``) or a lab's imported FE
model (``family = "imported"``, :func:`rom.importers.model.load_bladed_disk`; docs/campaign.md). Both give a
:class:`rom.academic.BladedDisk`, reduced through the same cache.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import ema
from identify.dataset import Dataset
from identify.film import FilmGeometry, FilmMap, contact_pattern, read_film
from identify.knn import TwoStepKNN, TwoStepMatch, query_matrix
from identify.sampler import PatternSampler, SyntheticPatterns, sample_patterns
from identify.tracking import ModeTracker
from rom import cache
from rom.academic import AcademicParams, BladedDisk, build_bladed_disk
from rom.contact import ContactPattern
from rom.craig_bampton import CraigBamptonModel
from rom.importers.model import load_bladed_disk, read_model_toml
from rom.mistuning import rom_deltas
from rom.rubin import RubinModel

from .campaign import Campaign, CampaignError, imported_model_table, model_family, read_campaign

__all__ = [
    "MATCH_WINDOW", "Models", "BladeTests", "Prediction", "model_params", "load_model", "load_model_file",
    "reduced_models", "read_films", "film_patterns", "synthesize", "family_samplers", "blade_tests", "d1b_tests",
    "match_to_reference", "subset_reference",
    "known_bias", "measured_tracked", "filmed_frequencies", "bias_spread", "predict_joints", "mean_known_pattern",
    "query_deltas", "tracker",
]

#: Window of the frequency matching between measured and tracked modes (relative).
MATCH_WINDOW = 0.05


@dataclass(frozen=True, eq=False)
class Models:
    """The campaign's FE model (the twin or an imported one) and its reduced models (CB disk on slot 1, Rubin
    blade)."""

    bd: BladedDisk
    disk: CraigBamptonModel
    blade: RubinModel


def model_params(campaign: Campaign) -> AcademicParams:
    """The academic twin named by the manifest's ``[model]`` table.

    Raises
    ------
    CampaignError
        The table describes an imported model (:func:`load_model` builds that).
    """
    m = campaign.model
    manifest = campaign.root / "campaign.toml"
    if model_family(m, f"{manifest} [model]") != "academic":
        raise CampaignError(f"{manifest} [model]: an imported model has no academic parameters (load_model "
                            "builds it)")
    return AcademicParams(n_blades=int(m.get("n_blades", campaign.n_blades)), grid=tuple(m.get("grid", campaign.grid)),
                          level=str(m.get("level", "default")))


def load_model(campaign: Campaign) -> BladedDisk:
    """The FE model of the campaign's ``[model]``: the academic twin, or the imported model it describes.

    An imported model's paths are relative to the campaign folder, or to the TOML file its ``file`` key names
    (:func:`bladetwin.campaign.imported_model_table`). The model must have the campaign's number of blades
    (one slot each) and contact grid.

    Returns
    -------
    rom.academic.BladedDisk
        An :class:`rom.importers.model.ImportedBladedDisk` for an imported model.

    Raises
    ------
    CampaignError, rom.importers.errors.ModelImportError
        One line naming the file and what is wrong: a missing or bad model file, slots or grid other than
        the campaign's.
    """
    manifest = campaign.root / "campaign.toml"
    if model_family(campaign.model, f"{manifest} [model]") == "academic":
        return build_bladed_disk(model_params(campaign))
    table, base, where = imported_model_table(campaign.model, campaign.root, str(manifest))
    bd = load_bladed_disk(table, base, where=where)
    # read_campaign checked the table's n_slots and grid shape where it gives them; the built model is the
    # authority (a grid shape comes from the node sets when the table gives none).
    if bd.n_slots != campaign.n_blades:
        raise CampaignError(f"{where}: [model.placement] n_slots = {bd.n_slots}, but the campaign has n_blades = "
                            f"{campaign.n_blades}")
    if tuple(bd.params.grid) != tuple(campaign.grid):
        raise CampaignError(f"{where}: [model.grids] the model's grids are {bd.params.grid[0]} × "
                            f"{bd.params.grid[1]}, but the campaign's grid is {list(campaign.grid)}")
    return bd


def load_model_file(path: str | os.PathLike) -> BladedDisk:
    """The FE model a file names: a ``model.toml`` (``bladetwin fe export``'s), or a campaign's ``[model]``.

    Parameters
    ----------
    path : path-like
        A TOML file whose ``[model]`` table describes an imported model (paths relative to its folder), or a
        campaign folder or its ``campaign.toml`` (:func:`load_model` of the campaign, academic or imported).

    Raises
    ------
    CampaignError, rom.importers.errors.ModelImportError
        One line naming the file and what is wrong.
    """
    p = Path(path)
    if p.is_dir() or p.name == "campaign.toml":
        return load_model(read_campaign(p if p.is_dir() else p.parent))
    if not p.is_file():
        raise CampaignError(f"{p}: not found (expected a model.toml, a campaign folder or its campaign.toml)")
    return read_model_toml(p)


def reduced_models(campaign: Campaign, cache_dir=None) -> Models:
    """FE model and reduced models of the campaign's model, through the on-disk cache (``rom.cache``)."""
    bd = load_model(campaign)
    return Models(bd, cache.cached_reduce_disk(bd, (1,), cache_dir=cache_dir),
                  cache.cached_reduce_blade(bd, cache_dir=cache_dir))


def read_films(campaign: Campaign, joints=None) -> dict[int, tuple[FilmMap, FilmMap]]:
    """Film maps (L, R) of the known joints (or ``joints``), with each film's own geometry and contact level."""
    out = {}
    for j in campaign.known_joints if joints is None else joints:
        maps = []
        for flank in ("L", "R"):
            f = campaign.film(j, flank)
            geometry = FilmGeometry.from_mapping(f.meta) if "origin" in f.meta else None
            maps.append(read_film(f.file, campaign.grid, geometry, threshold=f.contact_level,
                                  white=f.meta.get("white")))
        out[int(j)] = (maps[0], maps[1])
    return out


def film_patterns(films: dict[int, tuple[FilmMap, FilmMap]]) -> dict[int, ContactPattern]:
    """The contact pattern of each filmed joint."""
    return {j: contact_pattern(a, b) for j, (a, b) in films.items()}


def synthesize(films: dict[int, tuple[FilmMap, FilmMap]], *, n_patterns: int = 10, scale: float = 1.0,
               seed: int = 0) -> SyntheticPatterns:
    """Synthetic patterns SP-1..n per flank from the known films (paper §3.1, §6.1).

    The maps are thresholded at the known films' mean contact level per side (each film's own level is how
    the lab read it; a histogram rule such as Otsu misreads films whose threshold comes from calibration).
    """
    (L, R), threshold = _family_maps(films)
    return sample_patterns(L, R, n_patterns=n_patterns, scale=scale, threshold=threshold, random_state=seed)


def _family_maps(films: dict[int, tuple[FilmMap, FilmMap]]) -> tuple[tuple[list, list], tuple[float, float]]:
    """The known films' maps per side (L, R) and each side's contact threshold, their mean level."""
    sides = ([a for a, _ in films.values()], [b for _, b in films.values()])
    return sides, tuple(float(np.mean([m.level for m in maps])) for maps in sides)  # type: ignore[return-value]


def family_samplers(films: dict[int, tuple[FilmMap, FilmMap]]) -> tuple[PatternSampler, PatternSampler]:
    """The fitted PCA samplers (L, R) behind :func:`synthesize`'s patterns, for :func:`identify.refine_pattern`."""
    sides, thresholds = _family_maps(films)
    return tuple(PatternSampler(threshold=t).fit(maps)  # type: ignore[return-value]
                 for maps, t in zip(sides, thresholds, strict=True))


@dataclass(frozen=True, eq=False)
class BladeTests:
    """EMA of the free blades: the tracked frequencies (Hz) and deltas (%, Eq. 37), shape (n_blades, k)."""

    models: dict
    frequencies_hz: np.ndarray
    deltas_pct: np.ndarray


def _ema(test) -> ema.ModalModel:
    return ema.fit(ema.read_uff(test.file), max_order=test.max_order).model


def blade_tests(campaign: Campaign, say: Callable[[str], None] = lambda m: None) -> BladeTests:
    """Automatic EMA of every blade test, then the blade deltas (Eq. 37, modes tracked by MAC)."""
    tests = campaign.of_type("blade")
    if len(tests) != campaign.n_blades:
        raise CampaignError(f"{campaign.root / 'campaign.toml'}: {len(tests)} blade tests for {campaign.n_blades} "
                            "blades; the deltas need every blade")
    models = {}
    for t in tests:
        say(f"EMA blade {t.index}")
        models[f"blade_{t.index:02d}"] = _ema(t)
    return BladeTests(models, ema.campaign.frequency_table(models).to_numpy(), ema.blade_deltas(models).to_numpy())


def d1b_tests(campaign: Campaign, say: Callable[[str], None] = lambda m: None) -> dict[int, ema.ModalModel]:
    """Automatic EMA of every disk–one-blade test, by joint."""
    out = {}
    for t in campaign.of_type("d1b"):
        say(f"EMA disk-one-blade {t.index}")
        out[int(t.index)] = _ema(t)
    return out


def match_to_reference(
    frequencies_hz: np.ndarray, reference_hz: np.ndarray, window: float = MATCH_WINDOW
) -> np.ndarray:
    """Measured frequencies matched one-to-one to tracked modes (Hungarian on relative distance).

    Parameters
    ----------
    frequencies_hz : ndarray, shape (n_measured,)
    reference_hz : ndarray, shape (n_modes,)
        The tracked modes' frequencies expected for this joint (e.g. the dataset's mean over the step-1 subset).
    window : float
        Largest relative distance of a match.

    Returns
    -------
    ndarray, shape (n_modes,)
        The measured frequency matched to each tracked mode; NaN where none lies within ``window``.
    """
    f = np.asarray(frequencies_hz, float)
    out = np.full(np.size(reference_hz), np.nan)
    rows, cols = ema.pair_by_frequency(reference_hz, f, window)
    out[rows] = f[cols]
    return out


def subset_reference(dataset: Dataset, deltas: np.ndarray) -> np.ndarray:
    """Mean tracked frequencies (Hz) of the dataset's δ row nearest to each joint's δ, shape (n_joints, n_modes)."""
    rows = np.unique(dataset.deltas, axis=0)
    out = np.empty((len(deltas), dataset.frequencies_hz.shape[1]))
    for k, d in enumerate(np.asarray(deltas, float)):
        near = rows[np.argmin(np.linalg.norm(rows - d, axis=1))]
        out[k] = dataset.frequencies_hz[np.all(dataset.deltas == near, axis=1)].mean(axis=0)
    return out


def measured_tracked(dataset: Dataset, d1b: dict[int, ema.ModalModel], joints, deltas) -> np.ndarray:
    """Each joint's EMA frequencies matched to the dataset's tracked modes (Hz; NaN: not found).

    Parameters
    ----------
    dataset : Dataset
    d1b : dict joint → ema.ModalModel
        The disk–one-blade EMA of each joint.
    joints : array_like of int, shape (n_joints,)
    deltas : ndarray, shape (n_joints, n_delta_modes)
        Each joint's δ (relative): the dataset's δ row nearest to it gives the expected frequencies.

    Returns
    -------
    ndarray, shape (n_joints, n_tracked)
    """
    ref = subset_reference(dataset, deltas)
    return np.array([match_to_reference(d1b[int(j)].frequency_hz, ref[k]) for k, j in enumerate(joints)])


def filmed_frequencies(tracker: ModeTracker, known: dict[int, ContactPattern], delta_all: np.ndarray, joints,
                       measured: np.ndarray) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """(measured, ROM) tracked frequencies (Hz) of each filmed joint with a d1b test: :func:`known_bias`'s inputs.

    ``delta_all`` (shape (n_blades, m)) holds every blade's δ on the ROM's modes; ``measured`` is
    :func:`measured_tracked` of ``joints``.
    """
    row = {int(j): k for k, j in enumerate(joints)}
    rom_hz = {j: tracker.track(p, delta_all[j - 1]).frequencies_hz for j, p in known.items() if j in row}
    return {j: measured[row[j]] for j in rom_hz}, rom_hz


def bias_spread(measured_hz: dict[int, np.ndarray], rom_hz: dict[int, np.ndarray]) -> np.ndarray:
    """Spread (std over the filmed joints) of f_measured / f_ROM − 1 per mode; 0 with fewer than 2 joints."""
    ratios = np.array([measured_hz[j] / rom_hz[j] - 1 for j in measured_hz])
    if len(ratios) < 2:
        return np.zeros(ratios.shape[1] if ratios.ndim == 2 else 0)
    with np.errstate(all="ignore"):
        return np.nan_to_num(np.nanstd(ratios, axis=0))


def known_bias(measured_hz: dict[int, np.ndarray], rom_hz: dict[int, np.ndarray]) -> np.ndarray:
    """Per-mode relative bias of the ROM against the measurement on the filmed joints (design §2, step 4).

    Parameters
    ----------
    measured_hz, rom_hz : dict joint → ndarray, shape (n_modes,)
        Tracked frequencies of each known joint: measured (NaN where unmatched) and the ROM's with the
        joint's film pattern and measured δ.

    Returns
    -------
    ndarray, shape (n_modes,)
        Median over the known joints of f_measured / f_ROM − 1 (0 where no joint has the mode).
    """
    ratios = np.array([measured_hz[j] / rom_hz[j] - 1 for j in measured_hz])
    with np.errstate(all="ignore"):
        b = np.nanmedian(np.where(np.isfinite(ratios), ratios, np.nan), axis=0) if ratios.size else np.zeros(0)
    return np.nan_to_num(b)


@dataclass(frozen=True, eq=False)
class Prediction:
    """The k-NN's answer for every joint.

    Attributes
    ----------
    joints : ndarray of int, shape (n_joints,)
        1-based joints.
    deltas : ndarray, shape (n_joints, n_delta_modes)
        Query δ (relative).
    features_hz : ndarray, shape (n_joints, n_features)
        Query frequencies (Hz), bias-corrected.
    match : identify.knn.TwoStepMatch
    patterns : list of ContactPattern
        The best candidate of each joint.
    """

    joints: np.ndarray
    deltas: np.ndarray
    features_hz: np.ndarray
    match: TwoStepMatch
    patterns: list


def predict_joints(dataset: Dataset, joints, deltas, features_hz, *, n_neighbors: int = 1) -> Prediction:
    """Two-step weighted k-NN (paper §6.4) for each joint's δ (relative) and feature frequencies (Hz)."""
    knn = TwoStepKNN.from_dataset(dataset, n_neighbors=n_neighbors)
    X = query_matrix(np.asarray(deltas, float), np.asarray(features_hz, float))
    m = knn.match(X)
    pats = [ContactPattern(dataset.patterns_L[int(lab[0, 0])], dataset.patterns_R[int(lab[0, 1])]) for lab in m.label]
    return Prediction(np.asarray(joints), np.asarray(deltas, float), np.asarray(features_hz, float), m, pats)


def mean_known_pattern(known: dict[int, ContactPattern]) -> ContactPattern:
    """Baseline: every node in contact where most filmed joints are (majority vote per flank node)."""
    L = np.mean([p.L for p in known.values()], axis=0) >= 0.5
    R = np.mean([p.R for p in known.values()], axis=0) >= 0.5
    return ContactPattern(L, R)


def query_deltas(blades: BladeTests, models: Models, n_delta_modes: int) -> np.ndarray:
    """Each blade's δ of the ROM's first ``n_delta_modes`` modes (relative) from the measured deltas."""
    return rom_deltas(blades.frequencies_hz, blades.deltas_pct, models.blade.frequencies_hz)[:, :n_delta_modes]


def tracker(models: Models, dataset: Dataset) -> ModeTracker:
    return ModeTracker.from_dataset(models.disk, models.blade, dataset)
