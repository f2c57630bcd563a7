"""A fast surrogate of the disk–one-blade frequencies as a function of the contact grid (beyond the paper).

A direct, MAC-tracked d1b solve (:meth:`identify.ModeTracker.track`) costs about 0.2 s; a posterior needs
tens of thousands of evaluations. Two facts make a cheap model possible:

* **δ separates.** The blade mistuning of Eq. 19 scales the tracked frequencies by a factor that does not
  depend on the contact: over 60 patterns of the prior, ``f(pattern, δ) / f(pattern, 0)`` varied by less than
  1e-6 relative on every mode (docs/identify.md). So one surrogate at δ = 0 serves every joint, times that
  joint's factor from two direct solves.
* **Contacts add up, nearly.** ``log f_m`` is close to linear in the nodes' contact indicators. Fitted by ridge
  regression (the penalty chosen by scikit-learn's efficient leave-one-out), the model's error is measured on
  solves held out of the fit and reported; the posterior adds it to its noise model.

What it cannot do: the frequency of the mode that feels the contact most (mode 2 of the academic twin) also
depends on which nodes touch which, beyond their sum; docs/identify.md gives the held-out error per mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import IdentifyError

__all__ = ["ContactSurrogate", "fit_surrogate"]

#: Ridge penalties tried (contact indicators are 0/1 and targets log-frequencies: a scale-free grid).
ALPHAS = np.logspace(-6, 3, 19)

#: Grids predicted at a time (:meth:`ContactSurrogate.predict_hz`).
_PREDICT_BLOCK = 4096


@dataclass(frozen=True, eq=False)
class ContactSurrogate:
    """``log f ≈ intercept + c · coef`` with c the contact indicators of both flanks (L then R).

    Attributes
    ----------
    coef : ndarray, shape (2 · n_nodes, n_modes)
    intercept : ndarray, shape (n_modes,)
    alpha : float
        The ridge penalty chosen.
    error_pct : ndarray, shape (n_modes,)
        Root-mean-square relative error on the held-out solves, %.
    max_error_pct : ndarray, shape (n_modes,)
        Largest relative error on them, %.
    n_train, n_test : int
        Direct solves fitted and held out.
    """

    coef: np.ndarray
    intercept: np.ndarray
    alpha: float
    error_pct: np.ndarray
    max_error_pct: np.ndarray
    n_train: int
    n_test: int

    def predict_hz(self, contact) -> np.ndarray:
        """Tracked d1b frequencies at δ = 0 (Hz), shape (n, n_modes), of grids shaped (n, 2, rows, cols)."""
        c = np.asarray(contact)
        c = c.reshape(c.shape[0], -1) if c.ndim > 2 else np.atleast_2d(c)
        if c.shape[1] != self.coef.shape[0]:
            raise IdentifyError(f"contact grids hold {c.shape[1]} nodes, the surrogate {self.coef.shape[0]}")
        out = np.empty((c.shape[0], self.coef.shape[1]))
        # In blocks: a posterior's ~1e5 kept grids as floats at once would be 8× their size (memory-bound)
        for a in range(0, c.shape[0], _PREDICT_BLOCK):
            out[a:a + _PREDICT_BLOCK] = c[a:a + _PREDICT_BLOCK].astype(np.float64) @ self.coef
        return np.exp(self.intercept + out)


def fit_surrogate(contact, frequencies_hz, *, test_fraction: float = 0.25, seed: int = 0) -> ContactSurrogate:
    """Fit :class:`ContactSurrogate` on direct solves, holding ``test_fraction`` of them out to measure its error.

    Parameters
    ----------
    contact : array_like of bool, shape (n, 2, rows, cols)
        The solved grids.
    frequencies_hz : array_like, shape (n, n_modes)
        Their tracked frequencies at δ = 0 (Hz).
    test_fraction : float
        Share of the solves held out (drawn with ``seed``), in (0, 1); at least 2 are held out and 10 fitted.

    Raises
    ------
    IdentifyError
        Mismatched shapes, non-positive frequencies, or too few solves.
    """
    from sklearn.linear_model import RidgeCV

    X = np.asarray(contact, np.float64)
    X = X.reshape(X.shape[0], -1)
    F = np.asarray(frequencies_hz, np.float64)
    if F.ndim != 2 or F.shape[0] != X.shape[0]:
        raise IdentifyError(f"{X.shape[0]} grids but frequencies of shape {F.shape}")
    if not np.all(np.isfinite(F)) or np.any(F <= 0):
        raise IdentifyError("surrogate training frequencies must be positive and finite")
    if not 0 < test_fraction < 1:
        raise IdentifyError(f"test_fraction must lie in (0, 1), got {test_fraction!r}")
    n_test = max(2, int(round(test_fraction * len(X))))
    if len(X) - n_test < 10:
        raise IdentifyError(f"{len(X)} direct solves: the surrogate needs at least {10 + n_test}")
    order = np.random.default_rng(seed).permutation(len(X))
    test, train = order[:n_test], order[n_test:]
    Y = np.log(F)
    model = RidgeCV(alphas=ALPHAS).fit(X[train], Y[train])
    err = np.exp(model.predict(X[test]) - Y[test]) - 1
    return ContactSurrogate(np.asarray(model.coef_.T, np.float64), np.asarray(model.intercept_, np.float64),
                            float(model.alpha_), 100 * np.sqrt(np.mean(err ** 2, axis=0)),
                            100 * np.max(np.abs(err), axis=0), len(train), n_test)
