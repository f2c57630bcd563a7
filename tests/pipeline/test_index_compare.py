"""Re-assemblies compared where they differ (issue 48, item 4): the index page of several campaigns of one disk
marks the joints whose contact changed, and no other.

The acceptance test: two campaigns of one disk from one seed, the second after one unfilmed joint was re-seated
(:func:`lab.patterns.redraw_joints` through ``CampaignSpec.reseat``). The page marks that joint and no joint whose
truth did not change. The comparison rule itself (:func:`bladetwin.index_compare.changed_quantities`) is checked
on hand-made entries, and the page's other blocks on hand-made output folders.
"""

from __future__ import annotations

import csv
import json
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from bladetwin.cli import main
from bladetwin.index_compare import (
    CHANGED,
    FILM_CHANGE_PP,
    campaign_pairs,
    changed_quantities,
    joint_contact,
)
from bladetwin.index_page import render_index
from bladetwin.methods import POSTERIOR_HEADER
from lab.campaign import CampaignSpec, simulate_campaign
from lab.patterns import redraw_joints, simulate_pressure

#: The small ideal twin of test_one_path.py (its `--level coarse --blades 4 --grid 3x7 --known 1,3 --realism
#: ideal`), through the lab's Python API: re-seating a joint is a setting made in Python (CampaignSpec.reseat).
SMALL = {"level": "coarse", "n_blades": 4, "grid": (3, 7), "known_joints": (1, 3), "realism": "ideal", "seed": 5}
#: The re-seated joint: an unfilmed one, so that the posterior decides. Its contact is drawn again with both flanks
# near 25 % of the nodes, where it bore on about 50 % and 75 % before: at 4 blades and a 3 × 7 grid the posterior's
# 90 % area intervals span 15–25 pp, so a re-draw within the usual 30–85 % may move a flank by less than that and
# be honestly undetectable; a re-seat to a narrow strip is a change the page must find.
RESEATED, RESEAT_FRACTION = 2, 0.25
#: `bladetwin run` settings: the posterior gives the intervals the rule compares (the k-NN gives none); no figures
#: (the page's maps are checked on hand-made folders below), the paper's ROM only, the smallest dataset.
RUN = ["run", "--no-figures", "--refine", "0", "--n", "3", "--rom", "paper", "--method", "posterior",
       "--posterior-steps", "500"]


class _Tables(HTMLParser):
    """Each table's body cells by its aria-label, and every <img>'s src."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: dict[str, list[list[str]]] = {}
        self.images: list[str] = []
        self._label: str | None = None
        self._body = False
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._label = a.get("aria-label") or ""
            self.tables[self._label] = []
        elif tag == "tbody":
            self._body = True
        elif tag == "tr" and self._body:
            self.tables[self._label].append([])
        elif tag == "td" and self._body:
            self._cell = []
        elif tag == "img":
            self.images.append(a["src"])

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            self.tables[self._label][-1].append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tbody":
            self._body = False

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def _page(path: Path) -> _Tables:
    p = _Tables()
    p.feed(path.read_text(encoding="utf-8"))
    return p


def _marked(page: _Tables, n_campaigns: int = 2) -> list[set[int]]:
    """The joints marked changed, per pair column of the joint table (after joint, and source/L/R per campaign)."""
    rows = page.tables["joints"]
    first = 1 + 3 * n_campaigns
    return [{int(r[0]) for r in rows if r[k] == CHANGED} for k in range(first, len(rows[0]))]


# ------------------------------------------------------------------------------------------ acceptance


@pytest.fixture(scope="module")
def reassembled(tmp_path_factory):
    """The two campaigns run as a lab has them, without their truth (kept apart under ``simulated/``): the page
    compares the runs' own answers, and a run without a truth skips the numerical-input posterior and the
    validation solves, which this test does not look at."""
    root = tmp_path_factory.mktemp("reassembly")
    simulate_campaign(CampaignSpec(name="before", **SMALL), root / "simulated" / "before")
    simulate_campaign(CampaignSpec(name="reseated", reseat=(RESEATED,), reseat_fraction=RESEAT_FRACTION, **SMALL),
                      root / "simulated" / "reseated")
    for name in ("before", "reseated"):
        shutil.copytree(root / "simulated" / name, root / name, ignore=shutil.ignore_patterns("truth"))
    assert main([*RUN, str(root / "before"), str(root / "reseated"), "--out", str(root / "run"),
                 "--cache-dir", str(root / "store")]) == 0
    return root


def _truth(folder: Path) -> np.ndarray:
    z = np.load(folder.parent / "simulated" / folder.name / "truth" / "patterns.npz")
    return np.stack([z["L"], z["R"]], axis=1)


def test_the_index_marks_the_reseated_joint_and_no_other(reassembled):
    before, after = _truth(reassembled / "before"), _truth(reassembled / "reseated")
    truly = {j + 1 for j in range(len(before)) if not np.array_equal(before[j], after[j])}
    assert truly == {RESEATED}, "the re-seat changes that joint's contact and no other's"
    page = _page(reassembled / "run" / "index.html")
    assert _marked(page) == [truly]
    text = re.sub(r"<[^>]+>", "", (reassembled / "run" / "index.html").read_text(encoding="utf-8"))
    assert f"before → reseated: {CHANGED} joint {RESEATED} (" in text  # the list above the tables
    # the filmed joints' films side by side: the scans each campaign's manifest names, found from the page
    films = page.tables["films"]
    assert [r[0] for r in films] == ["1", "3"]
    scans = [src for src in page.images if "/films/" in src]
    assert len(scans) == 2 * 2 * 2 and all((reassembled / "run" / src).is_file() for src in scans)
    # --no-figures: no map to show, said so; --rom paper: the updated ROM's Table 8 says it did not run
    assert "no contact map drawn" in text
    assert all(cell == "unavailable" for row in page.tables["table 8, updated ROM"] for cell in row[1:])


def test_redraw_changes_the_named_joint_only():
    u, v = np.meshgrid(np.linspace(0, 0.01, 5), np.linspace(0, 0.02, 9), indexing="ij")
    truth = simulate_pressure(u, v, 4, np.random.default_rng(3))
    again = redraw_joints(truth, [2], np.random.default_rng(4), fraction=0.25)
    for j in (0, 2, 3):
        assert np.array_equal(truth.L[j], again.L[j]) and np.array_equal(truth.R[j], again.R[j])
    assert not np.array_equal(truth.L[1], again.L[1])
    assert np.allclose(again.fractions[1], 0.25, atol=0.05 + 1 / u.size)  # within the window and a node
    with pytest.raises(ValueError, match="fraction"):
        redraw_joints(truth, [2], np.random.default_rng(4), fraction=1.0)


# ------------------------------------------------------------------------------------------ the rule


def _post(**values) -> dict:
    return {"film": False, "values": values, "units": {}}


def _film(L: float, R: float) -> dict:
    return {"film": True, "values": {"area L": (L, L, L), "area R": (R, R, R)}, "units": {}}


def test_the_rule_marks_intervals_that_do_not_overlap():
    a = _post(**{"area L": (60.0, 50.0, 70.0), "area R": (40.0, 30.0, 50.0), "centroid u L": (1.0, 0.5, 1.5)})
    overlapping = _post(**{"area L": (72.0, 65.0, 80.0), "area R": (45.0, 35.0, 55.0),
                           "centroid u L": (1.4, 1.2, 2.0)})
    assert changed_quantities(a, overlapping) == []
    # touching intervals share a value: not changed
    touching = _post(**{"area L": (75.0, 70.0, 80.0)})
    assert changed_quantities(a, touching) == []
    apart = _post(**{"area L": (60.0, 52.0, 68.0), "area R": (80.0, 70.0, 90.0), "centroid u L": (3.0, 2.0, 4.0)})
    assert changed_quantities(a, apart) == ["area R", "centroid u L"]
    assert changed_quantities(apart, a) == ["area R", "centroid u L"]  # symmetric
    # an estimate outside the other's interval is not enough while the intervals overlap
    edge = _post(**{"area L": (72.0, 69.0, 90.0)})
    assert changed_quantities(a, edge) == []


def test_films_are_compared_directly_and_a_film_against_a_posterior_as_a_point():
    a = _film(60.0, 40.0)
    assert changed_quantities(a, _film(60.0 + 0.9 * FILM_CHANGE_PP, 40.0)) == []
    assert changed_quantities(a, _film(60.0, 40.0 - 1.1 * FILM_CHANGE_PP)) == ["area R"]
    assert changed_quantities(a, _post(**{"area L": (55.0, 50.0, 65.0), "area R": (45.0, 35.0, 50.0)})) == []
    assert changed_quantities(a, _post(**{"area L": (75.0, 65.0, 85.0)})) == ["area L"]
    assert changed_quantities(a, _post()) is None  # the k-NN gives no interval: nothing to compare


def test_pairs_are_every_pair_of_few_campaigns_else_consecutive():
    assert campaign_pairs(2) == [(0, 1)]
    assert campaign_pairs(3) == [(0, 1), (0, 2), (1, 2)]
    assert campaign_pairs(5) == [(0, 1), (1, 2), (2, 3), (3, 4)]


# ------------------------------------------------------------------------------- hand-made output folders


def _area(L: float, R: float) -> list:
    """A posterior table row's area columns: each flank's value with a ±8 pp interval."""
    return [L, L - 8, L + 8, R, R - 8, R + 8]


def _summary(name: str, posterior: dict[int, tuple[float, float]], films: dict[int, tuple[float, float]],
             updated: bool) -> dict:
    joints = [{"joint": j, "source": "film", "area_fraction_L_pct": L, "area_fraction_R_pct": R}
              for j, (L, R) in films.items()]
    joints += [{"joint": j, "source": "posterior", "area_fraction_L_pct": L, "area_fraction_R_pct": R}
               for j, (L, R) in posterior.items()]
    case = {"mean_abs_df_pct": 0.4117, "mean_mac": 0.9512}
    cases = {"A": case, "B": case, "C": case, "B_baseline": case}
    return {"campaign": name, "kind": "virtual", "n_blades": 4, "known_joints": sorted(films), "report": "report.html",
            "joints": sorted(joints, key=lambda r: r["joint"]),
            "cases": {"A": case, "B": case, "B_no_bias": case, "C": case, "baseline": {"B": case}},
            "rom": {"paper": {"cases": cases}, "updated": {"cases": cases}} if updated else None,
            "sections": [{"id": "posterior", "figures": [{"file": "contact_probability.png", "caption": "maps"}],
                          "tables": [{"file": "posterior_contact.csv", "caption": "posterior"}]}]}


def _folder(root: Path, summary: dict, posterior: dict[int, tuple[float, float]]) -> Path:
    d = root / summary["campaign"]
    d.mkdir()
    (d / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    (d / "contact_probability.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    with (d / "posterior_contact.csv").open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(POSTERIOR_HEADER)
        for j, (L, R) in posterior.items():  # the centroids' intervals wide: only the areas decide here
            w.writerow([j, *_area(L, R)[:6], "", "", *([1.0, -10.0, 10.0] * 4)])
    return d


def test_the_page_marks_per_pair_and_shows_maps_and_both_rom_tables(tmp_path):
    films = {1: (60.0, 50.0), 3: (70.0, 40.0)}
    runs = [("first", {2: (60.0, 60.0), 4: (50.0, 50.0)}, films, True),
            ("second", {2: (60.0, 30.0), 4: (52.0, 50.0)}, films, False),  # joint 2's R flank moved 30 pp
            ("third", {2: (60.0, 30.0), 4: (50.0, 50.0)}, {1: (60.0, 50.0), 3: (70.0, 50.0)}, False)]  # film 3 R
    outs = [_folder(tmp_path, _summary(*r), r[1]) for r in runs]
    page = _page(render_index(tmp_path, outs))
    # pairs first → second, first → third, second → third
    assert _marked(page, 3) == [{2}, {2, 3}, {3}]
    # the maps each run drew, relative to the page
    assert page.images == ["first/contact_probability.png", "second/contact_probability.png",
                           "third/contact_probability.png"]
    # Table 8 of the updated ROM beside the paper's: values where the update ran, "unavailable" where it did not
    updated = page.tables["table 8, updated ROM"]
    assert [r[0] for r in updated] == ["Case A", "Case B", "Case C", "control (as Case B)"]
    assert updated[1][1:] == ["0.41", "0.951", *["unavailable"] * 4]
    assert page.tables["table 8, paper's ROM"][1][1:3] == ["0.41", "0.951"]
    text = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "Films not found" in text  # hand-made summaries name no campaign folder


def test_joint_contact_reads_the_intervals_and_the_films_areas():
    s = _summary("one", {2: (60.0, 40.0)}, {1: (55.0, 45.0)}, False)
    row = ["2", *map(str, _area(60.0, 40.0)), "", "", *map(str, [1.0, 0.5, 1.5] * 4)]
    c = joint_contact(s, POSTERIOR_HEADER, [row])
    assert c[1] == {"film": True, "values": {"area L": (55.0, 55.0, 55.0), "area R": (45.0, 45.0, 45.0)},
                    "units": {}}
    assert c[2]["values"]["area R"] == (40.0, 32.0, 48.0) and c[2]["units"]["area R"] == "%"
    assert c[2]["values"]["centroid v R"] == (1.0, 0.5, 1.5) and c[2]["units"]["centroid v R"] == "mm"
    assert joint_contact(s)[2]["values"] == {}  # the k-NN alone: no interval
