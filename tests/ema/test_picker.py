"""The interactive pole picker, driven by synthetic mouse events on a non-interactive canvas."""

import numpy as np
import pytest
from matplotlib.backend_bases import MouseEvent
from matplotlib.figure import Figure

from ema.frf import FRFSet
from ema.global_fit import estimate_poles
from ema.picker import PolePicker
from ema.selection import select_picks
from ema.stabilization import STABLE_FDV, stabilize

from .synth import FN, synthetic_case


@pytest.fixture(scope="module")
def diagram_and_frf():
    freq, H, _ = synthetic_case(n_o=6)
    frf = FRFSet(freq, H, tuple((k + 1, 3) for k in range(6)), ((1, 3),))
    return stabilize(estimate_poles(frf, "lscf", (50.0, 950.0), 30)), frf


def _click(picker, freq_hz, order, button=1):
    x, y = picker.ax.transData.transform((freq_hz, order))
    picker.on_click(MouseEvent("button_press_event", picker.fig.canvas, x, y, button=button))


def test_click_picks_the_nearest_most_stable_pole_and_toggles(diagram_and_frf):
    diagram, frf = diagram_and_frf
    before = diagram.frequencies_hz.copy()
    picker = PolePicker(diagram, frf, fig=Figure())
    top = max(diagram.orders)
    for f in FN[[0, 3, 7]]:
        _click(picker, f * 1.001, top)  # a slightly-off click still snaps to the pole
    assert len(picker.picks) == 3
    for (order, f), truth in zip(picker.picks, FN[[0, 3, 7]], strict=True):
        assert order == top and abs(f / truth - 1) < 5e-4
        k = np.flatnonzero((diagram.order == order) & (diagram.frequencies_hz == f))[0]
        assert diagram.stability[k] == STABLE_FDV
    # Clicking a picked pole again drops it; a right click drops too.
    _click(picker, picker.picks[0][1], top)
    _click(picker, picker.picks[0][1], top, button=3)
    assert len(picker.picks) == 1
    # A click far from any pole picks nothing.
    _click(picker, 60.0, 0.5 * top)
    assert len(picker.picks) == 1
    np.testing.assert_array_equal(diagram.frequencies_hz, before)  # the diagram is never modified


def test_selection_is_the_same_as_explicit_picks(diagram_and_frf):
    diagram, frf = diagram_and_frf
    top = max(diagram.orders)
    picker = PolePicker(diagram, initial=[(top, f) for f in FN], fig=Figure())
    sel = picker.selection()
    ref = select_picks(diagram, [(top, f) for f in FN])
    np.testing.assert_allclose(sel.frequencies_hz, ref.frequencies_hz)
    np.testing.assert_allclose(sel.frequencies_hz, FN, rtol=5e-4)


def test_bad_initial_pick(diagram_and_frf):
    diagram, _ = diagram_and_frf
    with pytest.raises(ValueError, match="order 999"):
        PolePicker(diagram, initial=[(999, 100.0)], fig=Figure())
