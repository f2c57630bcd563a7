"""bladetwin.twin_table: the twin tables format the runs' own figures (nothing computed), and bad input is one line."""

from __future__ import annotations

import json

from bladetwin.twin_table import compare_markdown, effects_markdown, main


def _summary(e_change: float, bias: list[float]) -> dict:
    modes = [{"component": "blade", "mode": 1, "test_hz": 700.0, "before_hz": 714.0, "after_hz": 700.0,
              "before_pct": 2.0, "after_pct": 0.0},
             {"component": "disk", "mode": 1, "test_hz": 1000.0, "before_hz": 1010.0, "after_hz": 1000.0,
              "before_pct": 1.0, "after_pct": 0.0},
             {"component": "disk", "mode": 2, "test_hz": 1000.5, "before_hz": 1010.0, "after_hz": 1000.0,
              "before_pct": 0.95, "after_pct": -0.05}]
    ema = {"blade_01": {"modes": [{"frequency_hz": 699.0}]}, "blade_02": {"modes": [{"frequency_hz": 701.0}]},
           "disk": {"modes": [{"frequency_hz": 1000.0}, {"frequency_hz": 1000.5}]}}
    return {"campaign": "c", "n_blades": 2, "calibration": {"modes": modes, "blade": {"E_change_pct": e_change}},
            "ema": ema, "bias": {"per_mode_pct": bias, "spread_pct": [0.1, 0.0], "joints": [1]},
            "cases": {"A": {"mean_abs_df_pct": 0.1234}}}


def test_the_tables_carry_the_runs_figures():
    cal, nocal = _summary(-2.5, [1.0, 0.0]), _summary(0.0, [3.0, 0.0])
    truth = {"realism": "realistic", "frequencies_hz": {"disk": [1000.0, 1000.5]}, "disk_nodal_diameters": [2, 2]}
    text = effects_markdown(cal, nocal, truth)
    assert "| 1 | 700.0 | 0.14 | +2.00 | +0.00 |" in text        # blade scatter: std/mean of 699 and 701
    assert "| 2 | 1000.2 | 0.50 / 0.050 |" in text                  # one ND 2 doublet, split 0.5 Hz
    # the bias is f_test / f_ROM − 1: model − test = 1/(1 + b) − 1; a mode no joint found shows "–"
    assert f"| 1 | {100 * (1 / 1.03 - 1):+.2f} | {100 * (1 / 1.01 - 1):+.2f} | 0.10 |" in text
    assert "| 2 | – | – |" in text
    table = compare_markdown({"ideal": nocal, "realistic": cal})
    assert "| Table 8 A, paper's ROM: mean |Δf| (%) | 0.123 | 0.123 |" in table
    assert "| calibration: blade E change (%) | +0.00 | -2.50 |" in table


def test_bad_input_is_one_line(tmp_path, capsys):
    bad = tmp_path / "s.json"
    bad.write_text("{not json")
    assert main(["compare", f"a={bad}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err
    good = tmp_path / "g.json"
    good.write_text(json.dumps(_summary(0.0, [])))
    assert main(["compare", str(good)]) == 2
    assert "NAME=" in capsys.readouterr().err
