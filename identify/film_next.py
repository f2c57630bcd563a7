"""Which joint to film next: the unfilmed joints ranked by how much a film there would tell (issue 46, item 5).

A film fixes its own joint's pattern and joins the prior's family (:mod:`identify.contact_prior`), so it moves
every other joint's posterior through the family it is drawn from. The joint the films' family explains worst is
the one whose film changes that family most: the ranking puts first the joint whose answer lies furthest outside
the films' range of contact area (summed over both flanks), and among those inside it, the widest posterior.

Measured on one small campaign (docs/design.md §8.56): with 2 films every posterior was overconfident (intervals
0–10 pp wide, none covering the truth), and every added film widened the other joints' intervals. The ranking
ordered the films by the area error they removed from the other joints: the first cut it most (27.8 → 15.1 pp),
the last least (31.0 → 30.2 pp). So the ranking says where a film helps, not where it narrows the others.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FilmCandidate", "outside_family_pp", "rank_film_next"]


@dataclass(frozen=True)
class FilmCandidate:
    """One unfilmed joint's case for a film.

    Attributes
    ----------
    joint : int
        1-based.
    outside_pp : float
        How far the answer's area fractions lie outside the films' range, summed over the flanks (pp; 0 inside).
    width_pp : float
        Mean width of its two flanks' 90 % area intervals (pp).
    """

    joint: int
    outside_pp: float
    width_pp: float


def outside_family_pp(area_pct: np.ndarray, film_area_pct: np.ndarray) -> float:
    """Σ over flanks of the distance (pp) from ``area_pct`` (shape (2,)) to the films' [min, max] per flank.

    ``film_area_pct``: shape (n_films, 2), each filmed joint's area fraction per flank (%).
    """
    films = np.asarray(film_area_pct, float).reshape(-1, 2)
    a = np.asarray(area_pct, float)
    below = np.maximum(films.min(axis=0) - a, 0.0)
    above = np.maximum(a - films.max(axis=0), 0.0)
    return float(np.sum(below + above))


def rank_film_next(joints, area_pct: np.ndarray, ci90_pct: np.ndarray,
                   film_area_pct: np.ndarray) -> list[FilmCandidate]:
    """The unfilmed joints, best to film first.

    Parameters
    ----------
    joints : sequence of int, length n
    area_pct : ndarray, shape (n, 2)
        Each joint's answer: area fraction per flank (L, R), %.
    ci90_pct : ndarray, shape (n, 2, 2)
        Flank × (5 %, 95 %) quantiles of the area fraction, %.
    film_area_pct : ndarray, shape (n_films, 2)
        The filmed joints' area fractions, %.

    Returns
    -------
    list of FilmCandidate, ordered by ``outside_pp`` then ``width_pp``, both descending (ties: lower joint first).
    """
    ci = np.asarray(ci90_pct, float)
    out = [FilmCandidate(int(j), outside_family_pp(a, film_area_pct), float(np.mean(c[:, 1] - c[:, 0])))
           for j, a, c in zip(joints, np.asarray(area_pct, float), ci, strict=True)]
    return sorted(out, key=lambda c: (-c.outside_pp, -c.width_pp, c.joint))
