"""Stage nodes on the films: contact maps of the filmed joints, the PCA family and the baseline pattern."""

from __future__ import annotations

import numpy as np

from identify.film import FilmGeometry, FilmMap, contact_pattern, read_film
from identify.sampler import PatternSampler
from identify.synthetic import SyntheticPatterns, sample_patterns
from rom.contact import ContactPattern

__all__ = ["read_films", "film_patterns", "synthetic_patterns", "family_samplers", "mean_known_pattern"]

Films = dict[int, tuple[FilmMap, FilmMap]]


def read_films(campaign, joints=None) -> Films:
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


def film_patterns(films: Films) -> dict[int, ContactPattern]:
    """The contact pattern of each filmed joint."""
    return {j: contact_pattern(a, b) for j, (a, b) in films.items()}


def _family_maps(films: Films) -> tuple[tuple[list, list], tuple[float, float]]:
    """The known films' maps per side (L, R) and each side's contact threshold, their mean level."""
    sides = ([a for a, _ in films.values()], [b for _, b in films.values()])
    return sides, tuple(float(np.mean([m.level for m in maps])) for maps in sides)  # type: ignore[return-value]


def synthetic_patterns(films: Films, *, n_patterns: int = 10, scale: float = 1.0,
                       seed: int = 0) -> SyntheticPatterns:
    """Synthetic patterns SP-1..n per flank from the known films (paper §3.1, §6.1, Eqs. 23–32).

    The maps are thresholded at the known films' mean contact level per side (each film's own level is how
    the lab read it; a histogram rule such as Otsu misreads films whose threshold comes from calibration).
    """
    (L, R), threshold = _family_maps(films)
    return sample_patterns(L, R, n_patterns=n_patterns, scale=scale, threshold=threshold, random_state=seed)


def family_samplers(films: Films) -> tuple[PatternSampler, PatternSampler]:
    """The fitted PCA samplers (L, R) behind :func:`synthetic_patterns`, for :func:`identify.refine_pattern`."""
    sides, thresholds = _family_maps(films)
    return tuple(PatternSampler(threshold=t).fit(maps)  # type: ignore[return-value]
                 for maps, t in zip(sides, thresholds, strict=True))


def mean_known_pattern(known: dict[int, ContactPattern]) -> ContactPattern:
    """Baseline: every node in contact where most filmed joints are (majority vote per flank node)."""
    L = np.mean([p.L for p in known.values()], axis=0) >= 0.5
    R = np.mean([p.R for p in known.values()], axis=0) >= 0.5
    return ContactPattern(L, R)
