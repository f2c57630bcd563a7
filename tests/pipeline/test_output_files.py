"""Figures drawn after the writer's block, on forked processes: the same files, the same warnings, nothing on error."""

from __future__ import annotations

import warnings

import matplotlib.pyplot as plt
import numpy as np
import pytest
from PIL import Image

from bladetwin.output_files import figures_deferred, save_figure
from bladetwin.user_warnings import recording
from bladetwin.util import figures_drawn


def _line(k: int):
    def make():
        if k == 1:
            warnings.warn(f"figure {k}: a user warning raised while drawing", UserWarning, stacklevel=1)
        fig, ax = plt.subplots(figsize=(2, 2))
        ax.plot(np.arange(5), np.arange(5) * k)
        return fig
    return make


def _pixels(path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


@pytest.mark.parametrize("workers", [1, 2])
def test_deferred_figures_match_direct_ones_and_keep_their_warnings(tmp_path, workers):
    direct = tmp_path / "direct"
    deferred = tmp_path / "deferred"
    direct.mkdir()
    deferred.mkdir()
    with recording() as texts_direct:
        names = [save_figure(_line(k), direct / f"f{k}.png") for k in range(3)]
    with recording() as texts, figures_deferred(workers):
        names_deferred = [save_figure(_line(k), deferred / f"f{k}.png") for k in range(3)]
        assert not any(deferred.iterdir())  # nothing drawn before the block ends
    assert names == names_deferred == ["f0.png", "f1.png", "f2.png"]
    for k in range(3):
        assert np.array_equal(_pixels(direct / f"f{k}.png"), _pixels(deferred / f"f{k}.png"))
    assert texts == texts_direct == ["figure 1: a user warning raised while drawing"]


def test_a_failing_block_draws_nothing(tmp_path):
    with pytest.raises(RuntimeError, match="stop"), figures_deferred(2):
        save_figure(_line(0), tmp_path / "f0.png")
        raise RuntimeError("stop")
    assert not any(tmp_path.iterdir())


def test_a_failing_figure_is_raised_in_the_caller(tmp_path):
    def bad():
        raise ValueError("no data to draw")

    with pytest.raises(ValueError, match="no data to draw"), figures_deferred(2):
        save_figure(bad, tmp_path / "bad.png")
        save_figure(_line(0), tmp_path / "f0.png")


def test_no_figures_defers_nothing(tmp_path):
    with figures_drawn(False), figures_deferred(2):
        assert save_figure(_line(0), tmp_path / "f0.png") is None
    assert not any(tmp_path.iterdir())
