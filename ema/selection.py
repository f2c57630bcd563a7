"""Pole selection from a stabilization diagram: automatic, by approximate frequencies, by explicit picks.

Automatic selection clusters the stable poles across model orders with a constrained agglomerative
(single-linkage, Kruskal) scheme: candidate pairs within the frequency tolerance and above the MAC
threshold are merged in order of increasing distance ``|lambda_a - lambda_b| / |lambda_b| + (1 - MAC)``,
except that two clusters are never merged when they hold poles of the same model order (one physical
mode gives at most one pole per order) or when the merged cluster would span more than twice the frequency
tolerance. This keeps close modes apart even when they are closer than the stability tolerance. Each
cluster that covers enough orders is one mode.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .errors import EMAError
from .mac import ScaledRows, mac
from .modal import pole_from_modal
from .stabilization import STABLE_FD, STABLE_FDV, StabilizationDiagram

__all__ = ["PoleSelection", "cluster_poles", "merge_selections", "select_auto", "select_near", "select_picks"]

#: Pole-vector entries gathered per block of candidate pairs in :func:`cluster_poles` (complex, 16 bytes each).
#: The bundled full-assembly test (72 outputs × 6 inputs, orders to 140) has 688 k pairs within the frequency
#: tolerance: gathered at once, the two (688 k × 432) complex arrays and their normalised copies took the EMA
#: process to 19 GB. In blocks of 1e7 entries (160 MB per array) it stays near 1 GB, with the same MACs.
_PAIR_BLOCK_ENTRIES = 10_000_000
#: The fields of :class:`PoleSelection` with one entry per mode.
_MODE_FIELDS = ("pole", "frequencies_hz", "damping_ratio", "quality", "vector", "n_poles")


@dataclass(frozen=True)
class PoleSelection:
    """Poles chosen as physical modes.

    Attributes
    ----------
    pole : ndarray of complex128, shape (n_modes,)
        Continuous-time poles in rad/s, ascending frequency.
    frequencies_hz, damping_ratio : ndarray, shape (n_modes,)
    quality : ndarray, shape (n_modes,)
        Score in [0, 1]: fraction of the model orders in which the mode is found, times the mean MAC of
        its poles' vectors with the representative vector (1 for explicit picks).
    vector : ndarray of complex128, shape (n_modes, n_vec)
        Representative pole vector of each mode.
    n_poles : ndarray of int, shape (n_modes,)
        Number of diagram poles behind each mode.
    how : str
        "auto", "near" or "picks".
    """

    pole: np.ndarray
    frequencies_hz: np.ndarray
    damping_ratio: np.ndarray
    quality: np.ndarray
    vector: np.ndarray
    n_poles: np.ndarray
    how: str

    def __post_init__(self) -> None:
        for name in _MODE_FIELDS:
            arr = np.array(getattr(self, name))
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n_modes(self) -> int:
        return int(self.pole.size)

    def take(self, keep: np.ndarray) -> PoleSelection:
        """The modes ``keep`` (bool or indices) selects."""
        return replace(self, **{name: getattr(self, name)[keep] for name in _MODE_FIELDS})


def merge_selections(a: PoleSelection, b: PoleSelection) -> PoleSelection:
    """Two selections as one (ascending frequency), named after the first."""
    both = {name: np.concatenate([getattr(a, name), getattr(b, name)]) for name in _MODE_FIELDS}
    srt = np.argsort(np.abs(both["pole"]), kind="stable")
    return replace(a, **{name: value[srt] for name, value in both.items()})


def _empty(n_vec: int, how: str) -> PoleSelection:
    return PoleSelection(
        pole=np.zeros(0, complex), frequencies_hz=np.zeros(0), damping_ratio=np.zeros(0), quality=np.zeros(0),
        vector=np.zeros((0, n_vec), complex), n_poles=np.zeros(0, int), how=how,
    )


def cluster_poles(
    diagram: StabilizationDiagram,
    min_class: int = STABLE_FDV,
    freq_tol: float | None = None,
    mac_min: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Cluster the stable poles of a diagram into modes (constrained single linkage).

    Pairs of candidate poles within ``freq_tol`` whose vectors reach ``mac_min`` are merged in order of
    increasing ``|lambda_a - lambda_b| / |lambda_b| + (1 - MAC)``, with two cannot-link constraints that
    refuse a merge:

    - the two clusters hold poles of the same model order (a mode gives at most one pole per order), so
      the two modes of a close pair stay apart at every order that resolves them, however close;
    - the merged cluster would span more than ``2 freq_tol`` in frequency (each pole of a mode is within
      ``freq_tol`` of it; chains of poles that drift with the order are not one mode).

    Two poles with distinct vectors are never linked directly (``mac_min``). A further cannot-link
    between any two poles of a cluster with distinct vectors was tried and dropped: below the order that
    separates a close pair, the estimators return one mixed pole for both modes, whose vector differs
    from either, so that constraint split each pair into three or four clusters on the sets of
    tests/ema/test_close_modes.py; a mixed pole instead joins the cluster of one member, and the median
    over the cluster's upper orders (:func:`select_auto`) comes from the separated poles.

    Parameters
    ----------
    diagram : StabilizationDiagram
    min_class : int
        Lowest stability class taken into account.
    freq_tol, mac_min : float, optional
        Linking tolerances; default the diagram's stability criteria.

    Returns
    -------
    index : ndarray of int, shape (n_candidates,)
        Indices of the candidate poles in the diagram.
    label : ndarray of int, shape (n_candidates,)
        Cluster label of each candidate (0..n_clusters-1, by ascending frequency of the cluster).
    """
    crit = diagram.criteria
    freq_tol = crit.freq_tol if freq_tol is None else float(freq_tol)
    mac_min = crit.mac_min if mac_min is None else float(mac_min)
    idx = np.flatnonzero(diagram.stability >= min_class)
    if idx.size == 0:
        return idx, np.zeros(0, dtype=int)
    f = diagram.frequencies_hz[idx]
    srt = np.argsort(f, kind="stable")
    idx, f = idx[srt], f[srt]
    orders = diagram.order[idx]
    ii, jj, dist = _candidate_pairs(f, diagram.pole[idx], diagram.vector[idx], orders, freq_tol, mac_min)
    roots = _link(f, orders, ii, jj, dist, freq_tol)
    uniq, label = np.unique(roots, return_inverse=True)
    # relabel by ascending mean frequency
    means = np.array([f[label == k].mean() for k in range(uniq.size)])
    rank = np.empty(uniq.size, dtype=int)
    rank[np.argsort(means, kind="stable")] = np.arange(uniq.size)
    return idx, rank[label]


def _candidate_pairs(f: np.ndarray, lam: np.ndarray, vec: np.ndarray, orders: np.ndarray, freq_tol: float,
                     mac_min: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs (i < j) of poles (ascending frequency ``f``) that :func:`cluster_poles` may link, and their distance.

    A pair is within ``freq_tol``, of two orders, with vectors of MAC at least ``mac_min``; its distance is
    ``|lambda_i - lambda_j| / |lambda_j| + (1 - MAC)``.
    """
    # all pairs (i < j) within the frequency tolerance (f is sorted)
    hi = np.searchsorted(f, f * (1.0 + freq_tol), side="right")
    counts = hi - np.arange(f.size) - 1
    ii = np.repeat(np.arange(f.size), counts)
    jj = ii + 1 + np.arange(ii.size) - np.repeat(np.cumsum(counts) - counts, counts)
    # Row-wise MACs, in blocks of pairs (see _PAIR_BLOCK_ENTRIES), each vector scaled once.
    sv = ScaledRows.of(vec)
    mac = sv.mac(ii, sv, jj, block_entries=_PAIR_BLOCK_ENTRIES)
    ok = (mac >= mac_min) & (orders[ii] != orders[jj])
    ii, jj, mac = ii[ok], jj[ok], mac[ok]
    return ii, jj, np.abs(lam[ii] - lam[jj]) / np.abs(lam[jj]) + (1.0 - mac)


def _link(f: np.ndarray, orders: np.ndarray, ii: np.ndarray, jj: np.ndarray, dist: np.ndarray, freq_tol: float
          ) -> np.ndarray:
    """Single linkage of the pairs ``(ii, jj)`` in order of ``dist`` under :func:`cluster_poles`' two cannot-links
    (no order twice in a cluster, no cluster wider than ``2 freq_tol``); the root of each pole's cluster."""
    order_ids = {o: k for k, o in enumerate(sorted(set(orders.tolist())))}
    parent = list(range(f.size))
    order_mask = [1 << order_ids[o] for o in orders.tolist()]
    f_lo, f_hi = f.tolist(), f.tolist()
    span = 1.0 + 2.0 * freq_tol

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for e in np.argsort(dist, kind="stable").tolist():
        ra, rb = find(int(ii[e])), find(int(jj[e]))
        if ra == rb or order_mask[ra] & order_mask[rb]:
            continue
        lo, hi = min(f_lo[ra], f_lo[rb]), max(f_hi[ra], f_hi[rb])
        if hi > span * lo:
            continue
        parent[rb] = ra
        f_lo[ra], f_hi[ra] = lo, hi
        order_mask[ra] |= order_mask[rb]
    return np.array([find(a) for a in range(f.size)])


def _representative(diagram: StabilizationDiagram, members: np.ndarray) -> tuple[complex, np.ndarray, float]:
    """Pole, vector and mean MAC of a cluster: medians over the upper half of its orders."""
    orders = diagram.order[members]
    top = members[orders >= np.median(orders)]
    f = float(np.median(diagram.frequencies_hz[top]))
    z = float(np.median(diagram.damping_ratio[top]))
    dev = np.abs(diagram.frequencies_hz[top] - f) / f + np.abs(diagram.damping_ratio[top] - z) / max(z, 1e-9)
    k = top[np.argmin(dev)]
    v = diagram.vector[k]
    mac_v = mac(diagram.vector[members].T, v)[:, 0]
    return complex(pole_from_modal(np.array([f]), np.array([z]))[0]), v, float(np.mean(mac_v))


def _build(diagram: StabilizationDiagram, groups: list[np.ndarray], how: str) -> PoleSelection:
    if not groups:
        return _empty(diagram.vector.shape[1], how)
    n_orders = max(len(diagram.orders) - 1, 1)
    poles, vecs, qual, npol = [], [], [], []
    for members in groups:
        lam, v, mean_mac = _representative(diagram, members)
        poles.append(lam)
        vecs.append(v)
        qual.append(min(1.0, len(set(diagram.order[members].tolist())) / n_orders) * mean_mac)
        npol.append(members.size)
    poles = np.asarray(poles)
    srt = np.argsort(np.abs(poles), kind="stable")
    poles = poles[srt]
    wn = np.abs(poles)
    return PoleSelection(
        pole=poles,
        frequencies_hz=wn / (2 * np.pi),
        damping_ratio=-poles.real / wn,
        quality=np.asarray(qual)[srt],
        vector=np.vstack(vecs)[srt],
        n_poles=np.asarray(npol)[srt],
        how=how,
    )


def select_auto(
    diagram: StabilizationDiagram,
    min_quality: float = 0.15,
    min_class: int = STABLE_FD,
    freq_tol: float | None = None,
    mac_min: float | None = None,
    edge: float = 0.01,
) -> PoleSelection:
    """Select the physical modes automatically: one mode per cluster of stable poles.

    Parameters
    ----------
    diagram : StabilizationDiagram
    min_quality : float
        Keep clusters whose quality (order coverage x mean MAC, see :class:`PoleSelection`) reaches this.
    min_class : int
        Lowest stability class clustered (default f+d+v).
    freq_tol, mac_min : float, optional
        Cluster linking tolerances; default the diagram's criteria.
    edge : float
        Drop modes within this fraction of the band width from the band edges (edge effects).

    Returns
    -------
    PoleSelection
    """
    if not 0 <= min_quality <= 1:
        raise EMAError(f"min_quality {min_quality}: expected in [0, 1]")
    idx, label = cluster_poles(diagram, min_class, freq_tol, mac_min)
    groups = [idx[label == k] for k in range(int(label.max()) + 1)] if idx.size else []
    sel = _build(diagram, groups, "auto")
    f_lo, f_hi = diagram.band_hz
    margin = edge * (f_hi - f_lo)
    keep = (sel.quality >= min_quality) & (sel.frequencies_hz >= f_lo + margin) & (sel.frequencies_hz <= f_hi - margin)
    return sel.take(keep)


def select_near(
    diagram: StabilizationDiagram,
    frequencies_hz: Sequence[float],
    window: float = 0.02,
    min_class: int = STABLE_FD,
) -> PoleSelection:
    """Select one mode near each approximate frequency.

    Among the pole clusters (of class ``min_class`` or better) within ``window`` (relative) of the
    target, the one present in the most orders wins; without stable poles there, the nearest pole of the
    highest order is taken.

    Raises
    ------
    EMAError
        No pole at all within the window of a target frequency.
    """
    targets = np.asarray(list(frequencies_hz), dtype=float)
    if targets.size == 0:
        raise EMAError("select_near: no frequencies given")
    idx, label = cluster_poles(diagram, min_class)
    groups = []
    for ft in targets:
        best = None
        if idx.size:
            for k in range(int(label.max()) + 1):
                members = idx[label == k]
                fm = float(np.median(diagram.frequencies_hz[members]))
                if abs(fm - ft) <= window * ft and (best is None or members.size > best.size):
                    best = members
        if best is None:
            near = np.flatnonzero(np.abs(diagram.frequencies_hz - ft) <= window * ft)
            if near.size == 0:
                raise EMAError(
                    f"no pole within {window:.1%} of {ft:g} Hz in the stabilization diagram "
                    f"(band {diagram.band_hz[0]:g}-{diagram.band_hz[1]:g} Hz)"
                )
            top = near[diagram.order[near] == diagram.order[near].max()]
            best = top[[int(np.argmin(np.abs(diagram.frequencies_hz[top] - ft)))]]
        groups.append(best)
    return _build(diagram, groups, "near")


def select_picks(diagram: StabilizationDiagram, picks: Sequence[tuple[int, float]]) -> PoleSelection:
    """Select explicit poles: for each ``(order, frequency_hz)`` the pole of that order nearest in frequency.

    Raises
    ------
    EMAError
        An order with no pole in the diagram.
    """
    chosen = []
    for order, ft in picks:
        cand = np.flatnonzero(diagram.order == int(order))
        if cand.size == 0:
            raise EMAError(f"pick ({order}, {ft} Hz): order {order} has no pole in the diagram")
        chosen.append(int(cand[np.argmin(np.abs(diagram.frequencies_hz[cand] - float(ft)))]))
    if not chosen:
        return _empty(diagram.vector.shape[1], "picks")
    chosen_arr = np.asarray(chosen)
    poles = diagram.pole[chosen_arr]
    srt = np.argsort(np.abs(poles), kind="stable")
    chosen_arr = chosen_arr[srt]
    return PoleSelection(
        pole=diagram.pole[chosen_arr], frequencies_hz=diagram.frequencies_hz[chosen_arr],
        damping_ratio=diagram.damping_ratio[chosen_arr], quality=np.ones(chosen_arr.size),
        vector=diagram.vector[chosen_arr], n_poles=np.ones(chosen_arr.size, dtype=int), how="picks",
    )
