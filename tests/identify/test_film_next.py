"""Which joint to film next (identify.film_next): distances outside the films' range, and the order."""

from __future__ import annotations

import numpy as np

from identify.film_next import outside_family_pp, rank_film_next

#: Two films, as on the small test campaign (joints 3 and 4): flank L 43 and 48 %, flank R 33 and 52 %.
FILMS = np.array([[43.0, 33.0], [48.0, 52.0]])


def test_the_distance_is_zero_inside_and_the_flanks_add_outside():
    assert outside_family_pp([45.0, 40.0], FILMS) == 0.0
    assert outside_family_pp([43.0, 52.0], FILMS) == 0.0  # on the edges
    assert np.isclose(outside_family_pp([85.7, 90.5], FILMS), (85.7 - 48) + (90.5 - 52))
    assert np.isclose(outside_family_pp([66.7, 28.6], FILMS), (66.7 - 48) + (33 - 28.6))  # above on L, below on R


def test_the_joint_furthest_outside_goes_first_then_the_widest():
    joints = [1, 2, 5, 6]
    area = np.array([[76.2, 85.7], [85.7, 90.5], [66.7, 28.6], [85.7, 90.5]])
    ci = np.array([[[71.4, 76.2], [85.7, 85.7]], [[85.7, 85.7], [90.5, 90.5]],
                   [[61.9, 71.4], [23.8, 33.3]], [[81.0, 85.7], [90.5, 90.5]]])
    ranked = rank_film_next(joints, area, ci, FILMS)
    # joints 2 and 6 lie equally far outside (76.2 pp); 6's interval is wider (2.4 pp against 0)
    assert [c.joint for c in ranked] == [6, 2, 1, 5]
    assert np.isclose(ranked[0].width_pp, np.mean([85.7 - 81.0, 0.0]))
    inside = rank_film_next([7, 8], np.array([[45.0, 40.0], [46.0, 41.0]]),
                            np.array([[[40.0, 50.0], [35.0, 45.0]], [[30.0, 60.0], [30.0, 50.0]]]), FILMS)
    assert [c.joint for c in inside] == [8, 7] and all(c.outside_pp == 0 for c in inside)
