"""identify: contact-pattern identification (floor 2; imports ``rom``, reads ``ema``'s results, never ``lab``).

Public API (see each module for details):

- :mod:`identify.film`, :mod:`identify.film_image`: pressure-film scans → grayscale maps and contact grids
  (Eqs. 23–24)
- :mod:`identify.sampler`, :mod:`identify.synthetic`: the PCA pattern sampler, synthetic patterns SP-1..n per
  flank and their pairs (Eqs. 25–32)
- :mod:`identify.sensitivity`: tracked d1b frequencies over the pattern pairs, feature modes (§6.2)
- :mod:`identify.dataset_build`, :mod:`identify.reanalysis`, :mod:`identify.delta_grid`: the δ × pattern-pair dataset
  by reanalysis (§6.3); :mod:`identify.dataset`: the dataset and its Parquet storage
- :mod:`identify.tracking`: the d1b tracker (pencil, shared coordinates, MAC assignment) for any pattern and δ (Eq. 34)
- :mod:`identify.knn`: the two-step weighted k-NN (Eqs. 33–36, 39)
- :mod:`identify.refine`: a compass search after the k-NN, in the synthetic family and the contact level
- :mod:`identify.validation`: step-1 grid error, geometric and dynamic validation (Eqs. 40–42, Table 8)
- :mod:`identify.film_next`: the unfilmed joints ranked for the next film (beyond the paper)
- :mod:`identify.plots`: the figures of paper §6–§7 (reading results only; imported on demand)
- :mod:`identify.errors`: :class:`IdentifyError`, the one-line errors written for users
"""

from .dataset import Dataset, load_dataset, save_dataset
from .dataset_build import build_dataset
from .delta_grid import grid_from_deltas
from .errors import IdentifyError
from .film import FilmGeometry, FilmMap, contact_pattern, map_film, read_film
from .film_image import load_image, otsu_threshold
from .knn import ExtrapolationWarning, TwoStepKNN, TwoStepMatch, dataset_xy, query_matrix
from .refine import RefinedPattern, SolveMemo, refine_pattern
from .sampler import PatternSampler, SideSample, draw_coefficients
from .sensitivity import Sensitivity  # the function: identify.sensitivity.sensitivity
from .synthetic import SyntheticPatterns, sample_patterns
from .tracking import ModeTracker, TrackedModes, model_key
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
