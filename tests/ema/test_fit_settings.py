"""ema.fit's tuning comes as one FitSettings; the keywords it replaced are refused with one line naming the setting."""

import inspect
from dataclasses import FrozenInstanceError, fields

import numpy as np
import pytest

from ema import EMAError, FitSettings, FRFSet, fit, fit_auto_order
from ema.settings import SETTING_NAMES


def _frf() -> FRFSet:
    freq = np.linspace(1.0, 100.0, 50)
    return FRFSet(freq, np.ones((2, 1, freq.size), complex), [(1, 3), (2, 3)], [(1, 3)])


def test_fit_takes_at_most_eight_parameters():
    assert len(inspect.signature(fit).parameters) <= 8


@pytest.mark.parametrize("name", sorted(SETTING_NAMES))
@pytest.mark.parametrize("call", [fit, fit_auto_order], ids=["fit", "fit_auto_order"])
def test_a_moved_keyword_is_refused_with_the_setting_to_use(call, name):
    value = getattr(FitSettings(), name)
    with pytest.raises(TypeError) as info:
        call(_frf(), **{name: value})
    message = str(info.value)
    assert message == (f"ema.{call.__name__}: {name!r} is a setting now: pass settings=FitSettings({name}=...)")
    assert "\n" not in message


def test_a_method_in_place_of_the_band_is_refused():
    with pytest.raises(TypeError) as info:
        fit(_frf(), "lscf")
    assert str(info.value) == "ema.fit: the method is a setting now: pass settings=FitSettings(method='lscf')"


def test_settings_are_frozen_with_the_old_defaults():
    s = FitSettings()
    assert {f.name: getattr(s, f.name) for f in fields(s)} == {
        "method": "lsrf", "orders": None, "criteria": None, "min_quality": 0.15, "min_dominance": 0.7, "n_bands": 1,
        "refine": True, "pad": 0.25, "split": True, "grow": True,
    }
    with pytest.raises(FrozenInstanceError):
        s.pad = 0.5  # type: ignore[misc]
    with pytest.raises(EMAError, match="pad -0.1"):
        FitSettings(pad=-0.1)


def test_the_order_ladder_refuses_explicit_orders():
    with pytest.raises(EMAError, match="max_order or orders"):
        fit_auto_order(_frf(), settings=FitSettings(orders=(2, 4)))
