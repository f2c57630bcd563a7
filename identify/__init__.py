"""identify: contact-pattern identification (floor 2; imports ``rom``, reads ``ema``'s results, never ``lab``).

Public API (see each module for details):

- :mod:`identify.film`: pressure-film scans → grayscale maps and contact grids (Eqs. 23–24)
- :mod:`identify.sampler`: the PCA pattern sampler, synthetic patterns SP-1..n per flank (Eqs. 25–32)
- :mod:`identify.sensitivity`: tracked d1b frequencies over the pattern pairs, feature modes (§6.2)
- :mod:`identify.dataset`, :mod:`identify.reanalysis`: the δ × pattern-pair dataset by reanalysis, Parquet (§6.3)
- :mod:`identify.tracking`: tracked d1b frequencies of any pattern and δ, consistent with a dataset (Eq. 34)
- :mod:`identify.knn`: the two-step weighted k-NN (Eqs. 33–36, 39)
- :mod:`identify.refine`: a compass search after the k-NN, in the synthetic family and the contact level
- :mod:`identify.validation`: step-1 grid error, geometric and dynamic validation (Eqs. 40–42, Table 8)
- :mod:`identify.plots`: the figures of paper §6–§7 (reading results only; imported on demand)
- :mod:`identify.errors`: :class:`IdentifyError`, the one-line errors written for users
"""

from .dataset import Dataset, build_dataset, grid_from_deltas, load_dataset, save_dataset
from .errors import IdentifyError
from .film import FilmGeometry, FilmMap, contact_pattern, load_image, map_film, otsu_threshold, read_film
from .knn import ExtrapolationWarning, TwoStepKNN, TwoStepMatch, dataset_xy, query_matrix
from .refine import RefinedPattern, SolveMemo, refine_pattern
from .sampler import PatternSampler, SideSample, SyntheticPatterns, draw_coefficients, sample_patterns
from .sensitivity import Sensitivity, model_key  # the function: identify.sensitivity.sensitivity
from .tracking import ModeTracker, TrackedModes
from .validation import (
    D1BValidation,
    GeometricValidation,
    GridError,
    ModeComparison,
    compare_modes,
    contact_area_fraction,
    contact_centroid,
    d1b_validation,
    geometric_validation,
    grid_error,
    pair_patterns,
)

__all__ = [
    "IdentifyError",
    "Dataset", "build_dataset", "grid_from_deltas", "load_dataset", "save_dataset",
    "Sensitivity", "model_key", "ModeTracker", "TrackedModes",
    "FilmGeometry", "FilmMap", "contact_pattern", "load_image", "map_film", "otsu_threshold", "read_film",
    "PatternSampler", "SideSample", "SyntheticPatterns", "draw_coefficients", "sample_patterns",
    "ExtrapolationWarning", "TwoStepKNN", "TwoStepMatch", "dataset_xy", "query_matrix",
    "RefinedPattern", "SolveMemo", "refine_pattern",
    "D1BValidation", "GeometricValidation", "GridError", "ModeComparison", "compare_modes",
    "contact_area_fraction", "contact_centroid", "d1b_validation", "geometric_validation", "grid_error",
    "pair_patterns",
]
