"""Two-step weighted k-nearest-neighbour identification of contact patterns (paper §3.2 and §6.4, Eqs. 33–36, 39).

The dataset is a stack of subsets, one per blade-mistuning row δ = (δ¹, …, δⁿ) of the grid (paper Fig. 17);
each subset holds every contact-pattern pair (p_L, p_R) with its disk–one-blade frequencies. A joint is
identified in two steps (paper Fig. 18):

1. **δ step** — the subset whose δ row is nearest (Euclidean) to the joint's measured blade deltas.
2. **frequency step** — inside that subset, the features (frequencies of the sensitive modes, Hz) are
   normalised, ``f̂_i = (f_i − μ_i) / σ_i`` (Eq. 39), and compared with the weighted Euclidean distance
   ``d(x, y) = sqrt(Σ w_i (x_i − y_i)²)`` (Eq. 33); the nearest sample (Eqs. 35–36), or the ``k`` nearest,
   gives the pattern pair.

The weighted distance is the plain Euclidean distance of features scaled by ``sqrt(w)``, so scikit-learn's
:class:`~sklearn.neighbors.NearestNeighbors` does the search (one index per subset).

:class:`TwoStepKNN` follows the scikit-learn estimator contract and fits plain arrays: ``X`` holds the δ
columns first, then the feature frequencies; ``y`` holds labels (1-D) or label rows such as ``(i_L, i_R)``
pairs (2-D, multi-output). :meth:`TwoStepKNN.from_dataset` fits a dataset object (fields ``deltas``,
``pair``, ``frequencies_hz``, ``feature_modes``, ``weights``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from numbers import Integral

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.neighbors import NearestNeighbors
from sklearn.preprocessing import StandardScaler
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from .errors import IdentifyError

__all__ = ["ExtrapolationWarning", "TwoStepMatch", "TwoStepKNN", "dataset_xy", "query_matrix"]

NORMALIZE = ("subset", "dataset", None)

# k-d trees compute (x − y)² directly; sklearn's brute Euclidean uses |x|² − 2x·y + |y|², whose cancellation
# leaves ~1e-8 instead of 0 for a sample queried with its own features.
_ALGORITHM = "kd_tree"


def _unique_rows(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """``np.unique(A, axis=0, return_inverse=True)`` (rows in lexicographic order), and each column's values.

    Each column is factorized by hashing (``pandas.factorize``, sorted), the ranks make one integer key per
    row (mixed radix, the first column most significant), and the distinct keys are found by counting when
    their range is small (a δ grid: 26³ keys) or by a 1-D sort otherwise. A million rows then take a few
    O(n) passes instead of a sort of row records (4.2 s → 0.3 s on 1.76 M samples). 1-D input: ``np.unique``.
    """
    import pandas as pd

    if A.ndim == 1:
        u, inv = np.unique(A, return_inverse=True)
        return u, inv.reshape(-1), [u]
    columns, ranks = [], []
    for c in A.T:
        codes, u = pd.factorize(c, sort=True)
        columns.append(np.asarray(u))
        ranks.append(codes.astype(np.int64, copy=False))
    n_keys = np.prod([float(u.size) for u in columns])
    if n_keys >= 2.0**62:  # the key would overflow: sort the records
        u, inv = np.unique(A, axis=0, return_inverse=True)
        return u, inv.reshape(-1), columns
    key = np.zeros(A.shape[0], np.int64)
    for u, r in zip(columns, ranks, strict=True):
        key = key * u.size + r
    if n_keys <= 4 * A.shape[0] + 1024:  # distinct keys by counting, in key (= lexicographic) order
        present = np.zeros(int(n_keys), bool)
        present[key] = True
        first = np.full(int(n_keys), -1, np.int64)
        first[key[::-1]] = np.arange(A.shape[0] - 1, -1, -1)  # the first row of each key
        slot = np.cumsum(present) - 1
        return A[first[present]], slot[key], columns
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return A[first], inverse.reshape(-1), columns


class ExtrapolationWarning(UserWarning):
    """A query's blade delta lies beyond the dataset's δ grid by more than half a grid step."""


@dataclass(frozen=True)
class TwoStepMatch:
    """Ranked candidates of a two-step k-NN query.

    Attributes
    ----------
    delta : ndarray of float64, shape (n_queries, n_delta_modes)
        δ row of the subset chosen in step 1 (relative units, 0.01 = 1 %).
    subset : ndarray of int, shape (n_queries,)
        Index of that subset in :attr:`TwoStepKNN.subset_deltas_`.
    index : ndarray of int, shape (n_queries, n_neighbors)
        Training-sample indices, nearest first (step 2, Eqs. 35–36).
    distance : ndarray of float64, shape (n_queries, n_neighbors)
        Weighted Euclidean distances of the normalised features (Eqs. 33, 39), dimensionless, ascending.
    label : ndarray, shape (n_queries, n_neighbors) or (n_queries, n_neighbors, n_outputs)
        Training labels of the candidates, e.g. ``(i_L, i_R)`` pairs when fitted on a dataset.
    beyond : ndarray of float64, shape (n_queries, n_features)
        How far each query feature lies outside the range of its subset's training features, in the
        features' units (Hz for a dataset): ``f − max`` above it, ``f − min`` below it (negative), 0 inside.
        A non-zero value means no training sample reaches the query there: the nearest one is the edge of
        the family, not a match.
    """

    delta: np.ndarray
    subset: np.ndarray
    index: np.ndarray
    distance: np.ndarray
    label: np.ndarray
    beyond: np.ndarray | None = None


class TwoStepKNN(ClassifierMixin, BaseEstimator):
    """Two-step weighted k-NN classifier (paper §6.4): nearest δ row, then nearest frequencies in its subset.

    Parameters
    ----------
    n_delta_modes : int, default 3
        Number of leading columns of ``X`` that hold blade deltas (relative units); the remaining columns are
        the features (frequencies in Hz). 0 skips step 1 (one subset: plain weighted k-NN).
    n_neighbors : int, default 1
        Candidates returned per query; the paper uses 1 (1-NN, Eq. 36). Every δ subset must hold at least
        this many samples.
    weights : "sensitivity", None or array_like of shape (n_features,), default "sensitivity"
        Weights ``w_i`` of Eq. 33. ``"sensitivity"``: the standard deviation of each feature over the
        pattern pairs of a δ subset, averaged over the subsets (paper §6.2: more contact-sensitive modes
        weigh more; uniform if no subset has two samples). ``None``: uniform. An array: non-negative,
        finite, not all zero.
    normalize : {"subset", "dataset", None}, default "subset"
        Where μ_i and σ_i of Eq. 39 come from: the samples of the subset chosen in step 1 (the paper's
        step 2 works inside that subset), all samples, or no normalisation (distances in Hz). A constant
        feature keeps σ = 1 (as :class:`~sklearn.preprocessing.StandardScaler`). σ is the population
        standard deviation; ddof would only scale all distances of a subset alike.

    Attributes
    ----------
    classes_ : ndarray, shape (n_classes,) or (n_classes, n_outputs)
        Distinct labels (rows for 2-D ``y``).
    n_features_in_ : int
    subset_deltas_ : ndarray of float64, shape (n_subsets, n_delta_modes)
        Distinct δ rows of the training data (sorted); shape (1, 0) when ``n_delta_modes == 0``.
    subset_of_sample_ : ndarray of int, shape (n_samples,)
        Subset of each training sample.
    delta_bounds_ : ndarray of float64, shape (2, n_delta_modes)
        Per δ mode, the training range widened by half the grid step at each end; queries outside it warn
        with :class:`ExtrapolationWarning`.
    weights_ : ndarray of float64, shape (n_features,)
        The resolved weights of Eq. 33.
    sample_class_ : ndarray of int, shape (n_samples,)
        Row of ``classes_`` of each training sample.
    subset_samples_ : tuple of ndarray of int
        Training-sample indices of each subset.
    nn_delta_ : NearestNeighbors or None
        Step-1 index over ``subset_deltas_`` (None without δ columns).

    Each subset's μ and σ of Eq. 39 and its step-2 index (over its normalised features scaled by
    ``sqrt(weights_)``) are built the first time a query lands in it (:meth:`subset_normalization`): a
    million-sample dataset has some 10⁴ subsets, and a query touches a handful.

    Notes
    -----
    Distances are in the normalised space of the chosen subset, so they rank candidates of one query;
    comparing them across queries that fell in different subsets is meaningless with ``normalize="subset"``.
    δ rows are grouped by exact equality, as a dataset stores its grid values.

    Ties (a δ query exactly half-way between grid rows, equal distances) go to whichever the k-d tree
    returns first; it is deterministic.
    """

    def __init__(self, n_delta_modes: int = 3, n_neighbors: int = 1, weights="sensitivity", normalize="subset"):
        self.n_delta_modes = n_delta_modes
        self.n_neighbors = n_neighbors
        self.weights = weights
        self.normalize = normalize

    # ------------------------------------------------------------------------------------------- fit
    def _check_params(self, n_columns: int) -> tuple[int, int]:
        nd, k = self.n_delta_modes, self.n_neighbors
        if not isinstance(nd, Integral) or isinstance(nd, bool) or nd < 0:
            raise IdentifyError(f"n_delta_modes={nd!r}: expected an integer ≥ 0")
        if not isinstance(k, Integral) or isinstance(k, bool) or k < 1:
            raise IdentifyError(f"n_neighbors={k!r}: expected an integer ≥ 1")
        if self.normalize not in NORMALIZE:
            raise IdentifyError(f"normalize={self.normalize!r}: expected one of {NORMALIZE}")
        if n_columns <= nd:
            # Worded so that scikit-learn's check_fit2d_1feature recognises it ("1 feature(s)").
            raise IdentifyError(
                f"X has {n_columns} feature(s), expected n_delta_modes ({nd}) δ columns plus at least one frequency"
            )
        return int(nd), int(k)

    def _resolve_weights(self, F: np.ndarray, groups: list[np.ndarray]) -> np.ndarray:
        nf = F.shape[1]
        w = self.weights
        if w is None:
            return np.ones(nf)
        if isinstance(w, str):
            if w != "sensitivity":
                raise IdentifyError(f"weights={w!r}: expected 'sensitivity', None or an array of {nf} values")
            # Paper §6.2: sensitivity = std of each frequency over the contact configurations at fixed δ.
            stds = [F[g].std(axis=0) for g in groups if g.size > 1]
            sens = np.mean(stds, axis=0) if stds else np.zeros(nf)
            return sens if sens.sum() > 0 else np.ones(nf)
        w = np.asarray(w, dtype=np.float64)
        if w.shape != (nf,):
            raise IdentifyError(f"weights has shape {w.shape}, expected ({nf},): one weight per feature column")
        if not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
            raise IdentifyError(f"weights {np.array2string(w, precision=4)}: expected finite values ≥ 0, not all 0")
        return w.copy()

    def fit(self, X, y) -> TwoStepKNN:
        """Index the training samples.

        Parameters
        ----------
        X : array_like of float, shape (n_samples, n_delta_modes + n_features)
            δ columns (relative units), then feature frequencies (Hz).
        y : array_like, shape (n_samples,) or (n_samples, n_outputs)
            Labels, e.g. the ``(i_L, i_R)`` pattern pair of each sample.

        Returns
        -------
        self

        Raises
        ------
        IdentifyError
            Bad hyper-parameters, too few columns, or a δ subset smaller than ``n_neighbors``.
        """
        X, y = validate_data(self, X, y, multi_output=True, dtype=np.float64)
        if y.dtype.kind not in "iub":
            # Integer labels are always classification targets; the check's unique() over a million-row y
            # costs 0.16 s, so only other labels (floats, strings) go through it.
            check_classification_targets(y)
        nd, k = self._check_params(X.shape[1])
        D, F = X[:, :nd], X[:, nd:]

        self.classes_, codes, _ = _unique_rows(y)
        self.sample_class_ = codes.reshape(-1)

        if nd:
            self.subset_deltas_, inverse, columns = _unique_rows(D)
            self.subset_of_sample_ = inverse.reshape(-1)
            lo, hi = np.empty(nd), np.empty(nd)
            for m in range(nd):
                u = columns[m]
                # Half the grid step at each end of the range (0 for a single value: any other value extrapolates).
                lo[m] = u[0] - (0.5 * (u[1] - u[0]) if u.size > 1 else 0.0)
                hi[m] = u[-1] + (0.5 * (u[-1] - u[-2]) if u.size > 1 else 0.0)
            self.delta_bounds_ = np.vstack([lo, hi])
            self.nn_delta_ = NearestNeighbors(n_neighbors=1, algorithm=_ALGORITHM).fit(self.subset_deltas_)
        else:
            self.subset_deltas_ = np.zeros((1, 0))
            self.subset_of_sample_ = np.zeros(X.shape[0], dtype=int)
            self.delta_bounds_ = np.zeros((2, 0))
            self.nn_delta_ = None
        n_sub = self.subset_deltas_.shape[0]
        # Samples of each subset in ascending order, in O(n log n) (a stable sort, then cuts at the counts).
        order = np.argsort(self.subset_of_sample_, kind="stable")
        counts = np.bincount(self.subset_of_sample_, minlength=n_sub)
        groups = np.split(order, np.cumsum(counts)[:-1])
        small = int(np.argmin(counts))
        n_small = int(counts[small])
        if n_small < k:
            raise IdentifyError(
                f"n_neighbors={k} exceeds the {n_small} sample(s) of δ subset "
                f"{np.array2string(self.subset_deltas_[small], precision=6)}; expected n_neighbors ≤ {n_small}"
            )

        self.weights_ = self._resolve_weights(F, groups)
        nf = F.shape[1]
        self._features = F
        self._global_norm = (np.zeros(nf), np.ones(nf))
        if self.normalize == "dataset":
            sc = StandardScaler().fit(F)
            self._global_norm = (sc.mean_, sc.scale_)
        self._subset_models: dict[int, tuple] = {}
        self._smallest_subset = n_small
        self.subset_samples_ = tuple(groups)
        return self

    def subset_normalization(self, g: int) -> tuple[np.ndarray, np.ndarray]:
        """μ and σ of Eq. 39 (shape (n_features,) each) in δ subset ``g`` (global ones for ``normalize="dataset"``)."""
        return self._subset_model(int(g))[:2]

    def _subset_model(self, g: int) -> tuple[np.ndarray, np.ndarray, NearestNeighbors, np.ndarray, np.ndarray]:
        """(μ, σ, step-2 index, feature minima, feature maxima) of subset ``g``, built on first use and kept."""
        hit = self._subset_models.get(g)
        if hit is None:
            rows = self.subset_samples_[g]
            F = self._features[rows]
            if self.normalize == "subset":
                sc = StandardScaler().fit(F)  # Eq. 39 inside the subset; σ = 0 → 1
                mean, scale = sc.mean_, sc.scale_
            else:
                mean, scale = self._global_norm
            Z = (F - mean) / scale * np.sqrt(self.weights_)
            hit = (mean, scale, NearestNeighbors(algorithm=_ALGORITHM).fit(Z), F.min(axis=0), F.max(axis=0))
            self._subset_models[g] = hit
        return hit

    # ----------------------------------------------------------------------------------------- query
    def _warn_extrapolation(self, D: np.ndarray) -> None:
        lo, hi = self.delta_bounds_
        for i, m in np.argwhere((D < lo) | (D > hi)):
            warnings.warn(
                f"row {i} (0-based), δ mode {m + 1}: value {D[i, m]:.6g} lies outside the dataset's δ grid "
                f"[{lo[m]:.6g}, {hi[m]:.6g}] (range ± half a step); step 1 extrapolates to the nearest grid row",
                ExtrapolationWarning,
                stacklevel=4,
            )

    def match(self, X, n_neighbors: int | None = None) -> TwoStepMatch:
        """Ranked candidates of each query row (both steps).

        Parameters
        ----------
        X : array_like of float, shape (n_queries, n_delta_modes + n_features)
            Measured blade deltas (relative) and feature frequencies (Hz) of each joint, as in :meth:`fit`.
        n_neighbors : int, optional
            Candidates per query; default the ``n_neighbors`` hyper-parameter.

        Returns
        -------
        TwoStepMatch

        Warns
        -----
        ExtrapolationWarning
            For each query δ beyond the dataset grid by more than half a step (names the row and the mode).
        """
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        k = self.n_neighbors if n_neighbors is None else n_neighbors
        if not isinstance(k, Integral) or isinstance(k, bool) or k < 1:
            raise IdentifyError(f"n_neighbors={k!r}: expected an integer ≥ 1")
        smallest = self._smallest_subset
        if k > smallest:
            raise IdentifyError(f"n_neighbors={k} exceeds the smallest δ subset ({smallest} samples)")
        nd = self.subset_deltas_.shape[1]
        D, F = X[:, :nd], X[:, nd:]
        n = X.shape[0]
        if nd:
            self._warn_extrapolation(D)
            subset = self.nn_delta_.kneighbors(D, 1, return_distance=False)[:, 0]
        else:
            subset = np.zeros(n, dtype=int)
        index = np.empty((n, k), dtype=int)
        distance = np.empty((n, k))
        beyond = np.empty_like(F)
        sqrt_w = np.sqrt(self.weights_)
        for g in np.unique(subset):
            q = np.flatnonzero(subset == g)
            mean, scale, nn, lo, hi = self._subset_model(int(g))
            Z = (F[q] - mean) / scale * sqrt_w
            dist, loc = nn.kneighbors(Z, k)
            index[q], distance[q] = self.subset_samples_[g][loc], dist
            beyond[q] = np.maximum(F[q] - hi, 0.0) + np.minimum(F[q] - lo, 0.0)
        return TwoStepMatch(
            delta=self.subset_deltas_[subset].copy(), subset=subset, index=index, distance=distance,
            label=self.classes_[self.sample_class_[index]], beyond=beyond,
        )

    def kneighbors(self, X, n_neighbors: int | None = None, return_distance: bool = True):
        """Nearest training samples of each query (as :meth:`sklearn.neighbors.NearestNeighbors.kneighbors`).

        Returns
        -------
        distance : ndarray of float64, shape (n_queries, n_neighbors)
            Only if ``return_distance``; ascending (Eq. 33 on Eq. 39 features).
        index : ndarray of int, shape (n_queries, n_neighbors)
            Training-sample indices, nearest first.
        """
        m = self.match(X, n_neighbors)
        return (m.distance, m.index) if return_distance else m.index

    def predict(self, X) -> np.ndarray:
        """Label of the nearest sample (Eq. 36), shape (n_queries,) or (n_queries, n_outputs)."""
        return self.match(X, 1).label[:, 0]

    def score(self, X, y, sample_weight=None) -> float:
        """Fraction of queries whose predicted label equals ``y`` (the whole row for 2-D ``y``: both flanks right)."""
        y = np.asarray(y)
        if y.ndim == 1:
            return super().score(X, y, sample_weight)
        return float(np.average(np.all(self.predict(X) == y, axis=1), weights=sample_weight))

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        return tags

    # --------------------------------------------------------------------------------------- dataset
    @classmethod
    def from_dataset(cls, dataset, *, n_neighbors: int = 1, weights=None, normalize="subset") -> TwoStepKNN:
        """Fit on an identification dataset; labels are the ``(i_L, i_R)`` pattern pairs.

        Parameters
        ----------
        dataset : object
            With fields ``deltas`` (n_samples, n_delta_modes), ``pair`` (n_samples, 2) int,
            ``frequencies_hz`` (n_samples, n_modes), ``feature_modes`` (0-based columns of
            ``frequencies_hz``) and ``weights`` (n_features,), e.g. the dataset of :mod:`identify.dataset`.
        weights : None, "sensitivity" or array_like, optional
            None (default) takes ``dataset.weights`` (the sensitivity analysis of paper §6.2); pass
            ``np.ones(n_features)`` for uniform weights.

        Returns
        -------
        TwoStepKNN
            Fitted; query it with :func:`query_matrix` rows.
        """
        X, y = dataset_xy(dataset)
        w = np.asarray(dataset.weights, dtype=np.float64) if weights is None else weights
        est = cls(n_delta_modes=np.asarray(dataset.deltas).shape[1], n_neighbors=n_neighbors, weights=w,
                  normalize=normalize)
        return est.fit(X, y)


def _field(obj, name: str, ndim: int, dtype=np.float64) -> np.ndarray:
    if not hasattr(obj, name):
        raise IdentifyError(f"dataset has no field {name!r}")
    a = np.asarray(getattr(obj, name), dtype=dtype)
    if a.ndim != ndim:
        raise IdentifyError(f"dataset.{name} has shape {a.shape}, expected a {ndim}-D array")
    return a


def dataset_xy(dataset) -> tuple[np.ndarray, np.ndarray]:
    """``X`` and ``y`` of :meth:`TwoStepKNN.fit` from a dataset object.

    Returns
    -------
    X : ndarray of float64, shape (n_samples, n_delta_modes + n_features)
        ``hstack(dataset.deltas, dataset.frequencies_hz[:, feature_modes])``.
    y : ndarray of int, shape (n_samples, 2)
        ``dataset.pair``.

    Raises
    ------
    IdentifyError
        Missing fields, wrong shapes, or feature modes outside ``frequencies_hz``.
    """
    D = _field(dataset, "deltas", 2)
    f = _field(dataset, "frequencies_hz", 2)
    pair = _field(dataset, "pair", 2, dtype=None)
    modes = np.asarray(getattr(dataset, "feature_modes", ()), dtype=int).reshape(-1)
    n = D.shape[0]
    if f.shape[0] != n or pair.shape != (n, 2):
        raise IdentifyError(f"dataset fields disagree: deltas {D.shape}, frequencies_hz {f.shape}, pair {pair.shape};"
                            f" expected ({n}, ·), ({n}, n_modes), ({n}, 2)")
    if pair.dtype.kind not in "iu":
        raise IdentifyError(f"dataset.pair has dtype {pair.dtype}, expected integer (i_L, i_R) indices")
    if modes.size == 0 or modes.min() < 0 or modes.max() >= f.shape[1]:
        raise IdentifyError(
            f"dataset.feature_modes {tuple(modes.tolist())}: expected 1+ columns in 0..{f.shape[1] - 1}"
        )
    # One allocation, filled column by column (hstack of f[:, modes] would make a second million-row copy).
    X = np.empty((n, D.shape[1] + modes.size))
    X[:, :D.shape[1]] = D
    for j, m in enumerate(modes):
        X[:, D.shape[1] + j] = f[:, m]
    return X, pair


def query_matrix(deltas, feature_frequencies_hz) -> np.ndarray:
    """Query rows for :class:`TwoStepKNN`, one per joint.

    Parameters
    ----------
    deltas : array_like, shape (n_joints, n_delta_modes)
        Measured blade deltas of each joint's blade (relative units, Eq. 37 / 100).
    feature_frequencies_hz : array_like, shape (n_joints, n_features)
        Measured disk–one-blade frequencies of the feature modes, in the order of ``feature_modes``.

    Returns
    -------
    ndarray of float64, shape (n_joints, n_delta_modes + n_features)
    """
    D = np.asarray(deltas, dtype=np.float64)
    F = np.asarray(feature_frequencies_hz, dtype=np.float64)
    if D.ndim != 2 or F.ndim != 2 or D.shape[0] != F.shape[0]:
        raise IdentifyError(f"deltas {D.shape} and feature_frequencies_hz {F.shape}: expected (n_joints, ·) arrays "
                            "with the same number of rows")
    return np.hstack([D, F])
