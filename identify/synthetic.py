"""Synthetic contact patterns of both flank sides and their left × right pairs (paper §6.1, Fig. 14).

Each side (L, R) is sampled by its own :class:`identify.sampler.PatternSampler` (Eqs. 25–32) fitted on that
side's known maps, from an independent child stream of one seed; every left × right combination is a joint
pattern of the sensitivity analysis and the dataset.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from rom.contact import ContactPattern

from .errors import IdentifyError
from .sampler import N_PATTERNS, PatternSampler

__all__ = ["SyntheticPatterns", "sample_patterns"]


def _labels(n: int) -> tuple[str, ...]:
    return tuple(f"SP-{i}" for i in range(1, n + 1))


@dataclass(frozen=True, eq=False)
class SyntheticPatterns:
    """Synthetic contact patterns of both flank sides and their left × right pairs (paper §6.1, Fig. 14).

    Attributes
    ----------
    L, R : ndarray of bool, shape (n_L, rows, cols) and (n_R, rows, cols)
        Contact grids per side, read-only.
    gray_L, gray_R : ndarray of float64, same shapes
        The reconstructed grayscale maps (Eq. 32).
    labels_L, labels_R : tuple of str
        "SP-1" … "SP-n" per side.
    scale : float
        Eq. 31's Scale used.
    threshold : (float, float)
        Contact threshold used per side (L, R), on the maps' scale.
    """

    L: np.ndarray
    R: np.ndarray
    gray_L: np.ndarray
    gray_R: np.ndarray
    labels_L: tuple[str, ...]
    labels_R: tuple[str, ...]
    scale: float
    threshold: tuple[float, float]

    def __post_init__(self) -> None:
        for name in ("L", "R", "gray_L", "gray_R"):
            a = np.array(getattr(self, name), dtype=bool if name in ("L", "R") else np.float64)
            if a.ndim != 3:
                raise IdentifyError(f"SyntheticPatterns.{name} must have shape (n, rows, cols), got {a.shape}")
            a.flags.writeable = False
            object.__setattr__(self, name, a)
        if self.L.shape[1:] != self.R.shape[1:]:
            raise IdentifyError(f"synthetic L and R grids differ in shape: {self.L.shape[1:]} and {self.R.shape[1:]}")
        for side in "LR":
            object.__setattr__(self, f"labels_{side}", tuple(getattr(self, f"labels_{side}")))
            n = getattr(self, side).shape[0]
            if getattr(self, f"gray_{side}").shape != getattr(self, side).shape:
                raise IdentifyError(f"SyntheticPatterns.gray_{side} must have the shape of {side}")
            if len(getattr(self, f"labels_{side}")) != n:
                raise IdentifyError(f"SyntheticPatterns.labels_{side} must hold {n} labels")

    @property
    def grid(self) -> tuple[int, int]:
        """Grid shape (rows, cols)."""
        return self.L.shape[1:]

    @property
    def n_pairs(self) -> int:
        """Number of left × right combinations."""
        return self.L.shape[0] * self.R.shape[0]

    def _index(self, side: str, i: int | str) -> int:
        labels = getattr(self, f"labels_{side}")
        if isinstance(i, str):
            if i not in labels:
                raise IdentifyError(f"no synthetic {side} pattern labelled {i!r} (have {labels[0]}..{labels[-1]})")
            return labels.index(i)
        if isinstance(i, bool) or not isinstance(i, numbers.Integral) or not 0 <= i < len(labels):
            raise IdentifyError(f"synthetic {side} pattern index must be an integer in 0..{len(labels) - 1} "
                                f"(or a label), got {i!r}")
        return int(i)

    def pattern(self, i_L: int | str, i_R: int | str) -> ContactPattern:
        """The joint pattern of pair (i_L, i_R): 0-based indices or labels such as "SP-3"."""
        return ContactPattern(self.L[self._index("L", i_L)], self.R[self._index("R", i_R)])

    def pairs(self) -> Iterator[tuple[str, str]]:
        """Labels (left, right) of all pairs, left-major: (SP-1, SP-1), (SP-1, SP-2), …"""
        return ((a, b) for a in self.labels_L for b in self.labels_R)


def sample_patterns(
    known_L,
    known_R,
    *,
    n_patterns: int | tuple[int, int] = N_PATTERNS,
    scale: float = 1.0,
    n_components: int | None = None,
    threshold: float | tuple[float, float] | None = None,
    max_draws: int = 100,
    random_state: int | np.random.Generator | None = None,
) -> SyntheticPatterns:
    """Synthetic patterns for both flank sides, sampled independently per side (paper §6.1).

    Parameters
    ----------
    known_L, known_R : array_like, shape (n_known, rows, cols); or sequences of FilmMap
        The known joints' grayscale maps per side (``FilmMap.gray``), at least 2 each, one grid.
    n_patterns : int or (int, int)
        Patterns per side (or per side L, R). Default 10, i.e. 100 pairs.
    scale : float
        Eq. 31's Scale. Default 1.
    n_components : int, optional
        See :class:`PatternSampler`.
    threshold : float or (float, float) or None
        Contact threshold on the maps' scale, both sides or per side (L, R). None: Otsu per side; for film maps
        the known films' mean ``FilmMap.level`` is usually the better choice.
    max_draws : int
        See :class:`PatternSampler`.
    random_state : int, numpy.random.Generator or None
        Seed; the L and R sides draw from two independent child streams (``Generator.spawn``).

    Returns
    -------
    SyntheticPatterns

    Raises
    ------
    IdentifyError
        For fewer than 2 known maps, grids of different shapes (within or between sides), or a side whose
        samples keep leaving the measured family; messages name the side.
    """
    def per_side(x) -> tuple:
        if isinstance(x, Sequence) or (isinstance(x, np.ndarray) and x.ndim == 1):
            return tuple(x.tolist() if isinstance(x, np.ndarray) else x)
        return (x, x)

    counts, thresholds = per_side(n_patterns), per_side(threshold)
    if len(counts) != 2 or len(thresholds) != 2:
        raise IdentifyError("n_patterns and threshold take one value or a pair (L, R)")
    streams = np.random.default_rng(random_state).spawn(2)
    out, shapes = {}, {}
    for side, known, n, thr, rng in zip("LR", (known_L, known_R), counts, thresholds, streams, strict=True):
        try:
            est = PatternSampler(n_components=n_components, n_patterns=n, scale=scale, threshold=thr,
                                 max_draws=max_draws, random_state=rng).fit(known)
            shapes[side] = est.grid_shape_
            if side == "R" and shapes["R"] != shapes["L"]:
                raise IdentifyError(f"grid shapes differ between sides: L {shapes['L']}, R {shapes['R']}")
            out[side] = (est.sample(), est.threshold_)
        except IdentifyError as e:
            raise IdentifyError(f"flank {side}: {e}") from None
    (sL, tL), (sR, tR) = out["L"], out["R"]
    return SyntheticPatterns(
        L=sL.contact, R=sR.contact, gray_L=sL.gray, gray_R=sR.gray, labels_L=_labels(sL.contact.shape[0]),
        labels_R=_labels(sR.contact.shape[0]), scale=float(scale), threshold=(tL, tR),
    )
