"""The family window's Gauss–Newton normal equations from kernel Gram matrices (ema.gram) against two
independent references: the Jacobian formed explicitly over every row (``FamilyWindow.scores``), and the gradient
of the variable-projection cost by central differences."""

from __future__ import annotations

import numpy as np
import pytest

from ema import FRFSet
from ema.family import FamilyWindow, normalised_participations, step_parameters
from ema.modal import pole_from_modal


def _window(form: str, n_in: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    freq = 0.5 * np.arange(800, 900)
    H = rng.standard_normal((9, n_in, freq.size)) + 1j * rng.standard_normal((9, n_in, freq.size))
    outputs = tuple((o + 1, 3) for o in range(9))
    frf = FRFSet(freq, H, outputs, outputs[:n_in], form=form, units="m/s/N")
    n = 5
    f = np.sort(rng.uniform(405.0, 445.0, n))
    zeta = rng.uniform(0.001, 0.02, n)
    part, pivot = normalised_participations(rng.standard_normal((n_in, n)) + 1j * rng.standard_normal((n_in, n)))
    return FamilyWindow(frf, (402.0, 448.0)), f, zeta, part, pivot


@pytest.mark.parametrize("form,n_in", [("mobility", 3), ("receptance", 1), ("accelerance", 4)])
def test_gram_normal_equations_equal_the_explicit_jacobian_and_finite_differences(form, n_in):
    win, f, zeta, part, pivot = _window(form, n_in)
    lam = pole_from_modal(f, zeta)
    cost, JJ, grad = win.gauss_newton(lam, part, pivot)
    JJ_explicit, per_line = win.scores(lam, part, pivot, np.zeros((0, *win.Y.shape)))
    np.testing.assert_allclose(JJ, JJ_explicit, rtol=0, atol=1e-10 * np.abs(JJ_explicit).max())
    # the gradient of ½‖P⊥ y‖² in (f, log ζ, Re/Im l), by central differences of the cost
    fd = np.empty(grad.size)
    for k in range(grad.size):
        h = np.zeros(grad.size)
        h[k] = 1e-6
        costs = []
        for sign in (1, -1):
            f2, logz2, part2 = step_parameters(f, np.log(zeta), part, pivot, sign * h)
            costs.append(win.solve(pole_from_modal(f2, np.exp(logz2)), part2)[0])
        fd[k] = (costs[0] - costs[1]) / 2e-6
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    assert cost == pytest.approx(win.solve(lam, part)[0], rel=1e-14)


def test_a_rank_deficient_design_still_gets_the_explicit_normal_equations():
    """Two equal poles with equal participations make the design singular; the Gram route's triangular solve
    would return garbage, so the window forms the Jacobian row by row (finite, and the gradient of the cost)."""
    win, f, zeta, part, pivot = _window("mobility", 2)
    f, zeta = np.r_[f[:2], f[1]], np.r_[zeta[:2], zeta[1]]
    part, pivot = np.c_[part[:, :2], part[:, 1]], np.r_[pivot[:2], pivot[1]]
    lam = pole_from_modal(f, zeta)
    _, JJ, grad = win.gauss_newton(lam, part, pivot)
    JJ_explicit, per_line = win.scores(lam, part, pivot, np.zeros((0, *win.Y.shape)))
    assert np.all(np.isfinite(JJ)) and np.all(np.isfinite(grad))
    np.testing.assert_allclose(JJ, JJ_explicit, rtol=0, atol=1e-8 * np.abs(JJ_explicit).max())
    np.testing.assert_allclose(grad, per_line[0].sum(axis=0), rtol=0, atol=1e-8 * np.abs(grad).max())


@pytest.mark.parametrize("n,n_in", [(1, 1), (4, 2), (12, 6)])
def test_the_mode_blocks_from_the_columns_structure_equal_the_sums_over_every_reference(n, n_in):
    """``_mode_grams`` sums over the references before it multiplies (the columns' structure); the reference
    spells every column out over the references and sums every product (one einsum), for random Gram entries,
    poles, participations and pivots."""
    from ema.gram import _coefficients, _mode_grams

    rng = np.random.default_rng(n + n_in)
    A = rng.standard_normal((4 * n, 4 * n)) + 1j * rng.standard_normal((4 * n, 4 * n))
    Gm = (A @ A.conj().T).reshape(4, n, 4, n)
    part = rng.standard_normal((n_in, n)) + 1j * rng.standard_normal((n_in, n))
    pivot = rng.integers(0, n_in, n)
    part[pivot, np.arange(n)] = 1.0
    lam = pole_from_modal(rng.uniform(100.0, 900.0, n), rng.uniform(1e-3, 2e-2, n))
    WC, WD = _coefficients(lam, part, pivot)
    DD, CD = _mode_grams(Gm, part, pivot, lam)
    for got, W in ((DD, WD), (CD, WC)):
        want = np.einsum("rcki,krqs,sdqi->rcsd", W.conj(), Gm, WD).real
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())
