"""The HTML report of ``bladetwin run`` (``bladetwin report``): one self-contained page from an output folder.

A fake output folder (small matplotlib PNGs, two CSV tables, a ``summary.json`` with some null cases) is
rendered through the command line, as a user would, and the page is parsed with ``html.parser``.
"""

from __future__ import annotations

import base64
import csv
import json
from html.parser import HTMLParser
from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from bladetwin.cli import main  # noqa: E402
from bladetwin.report import ReportError, format_number, read_csv_table, render_report  # noqa: E402
from bladetwin.report_cells import format_column  # noqa: E402
from bladetwin.util import atomic_savefig  # noqa: E402

N_BLADES, N_MODES = 18, 7


class _Page(HTMLParser):
    """Collects what the checks need: images, links, ids, tables (cells with their attributes)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.imgs: list[dict] = []
        self.hrefs: list[str] = []
        self.ids: set[str] = set()
        self.tables: list[dict] = []
        self._stack: list[dict] = []  # open tables (nested tables are not expected, but stay correct)
        self._cell: dict | None = None
        self._in_tbody = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            assert a["id"] not in self.ids, f"duplicate id {a['id']}"
            self.ids.add(a["id"])
        if tag == "img":
            self.imgs.append(a)
        elif tag == "a" and "href" in a:
            self.hrefs.append(a["href"])
        elif tag == "table":
            t = {"attrs": a, "head": [], "body": []}
            self.tables.append(t)
            self._stack.append(t)
        elif tag == "tbody":
            self._in_tbody = True
        elif tag == "tr" and self._stack:
            (self._stack[-1]["body"] if self._in_tbody else self._stack[-1]["head"]).append([])
        elif tag in ("td", "th") and self._stack:
            self._cell = {"tag": tag, "attrs": a, "text": ""}
            rows = self._stack[-1]["body"] if self._in_tbody else self._stack[-1]["head"]
            rows[-1].append(self._cell)

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            if self._cell is not None:
                self._cell["text"] = " ".join(self._cell["text"].split())
            self._cell = None
        elif tag == "tbody":
            self._in_tbody = False
        elif tag == "table" and self._stack:
            self._stack.pop()

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data


def _parse(html: str) -> _Page:
    page = _Page()
    page.feed(html)
    page.close()
    return page


def _figure(path: Path, kind: int) -> None:
    fig, ax = plt.subplots(figsize=(3, 2))
    x = np.linspace(0, 1, 50)
    if kind == 0:
        ax.plot(x, np.sin(6 * x))
    elif kind == 1:
        ax.imshow(np.random.default_rng(1).standard_normal((7, 31)), cmap="RdBu_r")
    else:
        ax.bar(range(5), [3, 1, 4, 1, 5])
    ax.set_title(path.stem)
    atomic_savefig(fig, path, dpi=40)
    plt.close(fig)


def _write_csv(path: Path, header: list[str], rows: list[list]) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def _summary() -> dict:
    joints = []
    for j in range(1, N_BLADES + 1):
        film = j in (3, 7, 10, 14, 17)
        joints.append({"joint": j, "source": "film" if film else "k-NN", "pattern_L": f"SP-{j % 10 + 1}",
                       "pattern_R": f"SP-{(j * 3) % 10 + 1}", "area_fraction_L_pct": 50 + j / 3,
                       "area_fraction_R_pct": 60 - j / 7, "reference_area_L_pct": 51.2 if film else None,
                       "reference_area_R_pct": 58.9 if film else None,
                       "beyond_family_pct": None if film else (0.0 if j % 2 else 0.4567),
                       "outside_family": None if film else not j % 2})
    case = {"mean_abs_df_pct": 0.7312345, "mean_mac": 0.8512, "n_modes": 54}
    return {
        "campaign": "academic <lab>", "campaign_dir": "/abs/measurements/academic", "kind": "lab",
        "n_blades": N_BLADES, "grid": [7, 31], "known_joints": [3, 7, 10, 14, 17],
        "generated": "2026-11-23T02:10:00Z", "bladetwin_version": "0.1.0",
        "command": "bladetwin run measurements/academic --out out/academic", "report": "report.html",
        "feature_modes": [2, 7, 10],
        "step1": {"max_abs_eps_pct": 48.4},
        "bias": {"enabled": True, "per_mode_pct": [0.12, -0.4, 1.5], "spread_pct": [0.05, 0.1, 0.3],
                 "joints": [3, 7]},
        "joints": joints,
        "cases": {"A": None, "B": case, "B_no_bias": {**case, "mean_abs_df_pct": 0.91}, "C": None,
                  "baseline": {"A": None, "B": {"mean_abs_df_pct": 1.2, "mean_mac": 0.8, "n_modes": 50}}},
        "paper_table8": {"A": {"mean_abs_df_pct": 0.07, "mean_mac": 0.91},
                         "B": {"mean_abs_df_pct": 0.73, "mean_mac": 0.85},
                         "C": {"mean_abs_df_pct": 0.46, "mean_mac": 0.82}},
        "notes": ["Cases A and C need reference patterns for every joint; this campaign has none: unavailable.",
                  "Joint 12: <script>alert(1)</script> stays text."],
        "timings_s": {"ema": 90.1, "rom": 3.2, "dataset": 30.0, "identify": 5.0, "validation": 300.0,
                      "report": 2.0, "total": 431.0},
        "sections": [
            {"id": "ema", "title": "Experimental modal analysis",
             "text": ["Blade tests give the blade deltas.", "Modes are tracked across blades by MAC."],
             "figures": [{"file": "stabilization_blade.png", "caption": "Stabilization diagram, blade 1."}],
             "tables": [{"file": "blade_deltas.csv", "caption": "Blade deltas (% of the mean eigenvalue).",
                         "heatmap": True}]},
            {"id": "identify", "title": "Identification",
             "text": "A single paragraph given as a string.",
             "figures": [{"file": "figs/patterns.png", "caption": "Synthetic patterns."},
                         {"file": "area_fractions.png", "caption": ""}],
             "tables": [{"file": "joint_frequencies.csv", "caption": "Joint frequencies (Hz)."}]},
            {"id": "empty", "title": "A section with text only", "text": ["Nothing else here."]},
        ],
    }


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    d = tmp_path / "out academic"  # a space in the path: links must still resolve
    (d / "figs").mkdir(parents=True)
    for k, name in enumerate(["stabilization_blade.png", "figs/patterns.png", "area_fractions.png"]):
        _figure(d / name, k)
    rng = np.random.default_rng(0)
    deltas = rng.standard_normal((N_BLADES, N_MODES)) * 1.5
    _write_csv(d / "blade_deltas.csv", ["blade", *(f"mode {m + 1}" for m in range(N_MODES))],
               [[b + 1, *row] for b, row in enumerate(deltas.tolist())])
    _write_csv(d / "joint_frequencies.csv", ["joint", "f2 (Hz)", "f7 (Hz)", "note"],
               [[j, 540.123456 + j, 1992.987654 - j, "film" if j == 3 else ""] for j in range(1, 6)])
    (d / "summary.json").write_text(json.dumps(_summary(), indent=1), encoding="utf-8")
    return d


def _render_cli(folder: Path, capsys) -> tuple[Path, str]:
    assert main(["report", str(folder)]) == 0
    out = capsys.readouterr().out.strip()
    path = Path(out)
    assert path == folder / "report.html" and path.is_file()
    return path, path.read_text(encoding="utf-8")


def _table(page: _Page, cls: str) -> dict:
    found = [t for t in page.tables if cls in t["attrs"].get("class", "").split()]
    assert len(found) == 1, f"expected one table of class {cls}"
    return found[0]


def test_page_is_self_contained_and_links_resolve(folder, capsys):
    path, html = _render_cli(folder, capsys)
    page = _parse(html)

    assert len(page.imgs) == 3
    for img in page.imgs:
        src = img["src"]
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1], validate=True).startswith(b"\x89PNG")
        assert img.get("alt", "").strip()
        assert "max-width:100%" in img.get("style", "").replace(" ", "")

    assert page.hrefs
    for href in page.hrefs:
        if href.startswith("#"):
            assert href[1:] in page.ids, f"dangling anchor {href}"
        elif not href.startswith("http"):
            assert (path.parent / href).is_file(), f"link to a missing file: {href}"
    for target in ["stabilization_blade.png", "figs/patterns.png", "blade_deltas.csv", "joint_frequencies.csv"]:
        assert target in page.hrefs
    for sec in ["ema", "identify", "empty"]:
        assert f"#sec-{sec}" in page.hrefs

    # No network, no script: nothing fetched from elsewhere, and user text is escaped.
    assert "<script" not in html and "http://" not in html and "https://" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "academic &lt;lab&gt;" in html
    assert "overflow-x: auto" in html

    assert page.tables
    for t in page.tables:
        assert t["body"] and any(row for row in t["body"]), f"a table without body rows: {t['attrs']}"


def test_table8_null_cases_show_unavailable(folder, capsys):
    _, html = _render_cli(folder, capsys)
    t8 = _table(_parse(html), "table8")
    labels = [c["text"] for c in t8["head"][1]]
    assert labels[:6] == ["Case A", "Case B", "Case B, no bias correction", "Case C", "Baseline A", "Baseline B"]
    assert labels[6:] == ["Paper A", "Paper B", "Paper C"]
    rows = {r[0]["text"]: [c["text"] for c in r[1:]] for r in t8["body"]}
    assert set(rows) == {"mean |Δf| (%)", "mean MAC", "n modes (paired)"}
    for values in rows.values():
        for k in (0, 3, 4):  # Case A, Case C, baseline A are null
            assert values[k] == "unavailable"
        assert "0" not in values[:6]
    assert rows["mean |Δf| (%)"][1] == "0.73"  # a percentage: 2 decimals along the row
    assert rows["mean MAC"][1] == "0.851"  # 3 significant digits
    assert rows["n modes (paired)"][1] == "54"
    assert rows["mean |Δf| (%)"][6:] == ["0.07", "0.73", "0.46"]
    assert rows["n modes (paired)"][6:] == ["—", "—", "—"]


def test_heatmap_and_tables(folder, capsys):
    _, html = _render_cli(folder, capsys)
    page = _parse(html)
    heat = _table(page, "heatmap")
    _, raw = read_csv_table(folder / "blade_deltas.csv")
    assert len(heat["body"]) == N_BLADES and all(len(r) == N_MODES + 1 for r in heat["body"])
    columns = [format_column([r[k] for r in raw]) for k in range(1, N_MODES + 1)]  # one rule down each column
    for i, (row, raw_row) in enumerate(zip(heat["body"], raw, strict=True)):
        assert row[0]["tag"] == "th" and row[0]["text"] == raw_row[0]  # the blade labels the row, uncoloured
        assert "style" not in row[0]["attrs"]
        for k, (c, text) in enumerate(zip(row[1:], raw_row[1:], strict=True)):
            assert "background:#" in c["attrs"].get("style", "")
            assert c["text"] == columns[k][i] and c["attrs"]["title"] == text  # the exact value in the tooltip
    # A plain table: 3 significant digits on each column's largest value, integers and text kept, no colours.
    plain = [t for t in page.tables if [c["text"] for c in t["head"][0]] == ["joint", "f2 (Hz)", "f7 (Hz)", "note"]]
    assert len(plain) == 1
    body = [[c["text"] for c in r] for r in plain[0]["body"]]
    assert body[0] == ["1", "541", "1992", ""] and body[2] == ["3", "543", "1990", "film"]
    assert not any("style" in c["attrs"] for r in plain[0]["body"] for c in r)
    joints = _table(page, "joints")
    assert len(joints["body"]) == N_BLADES
    assert [c["text"] for c in joints["body"][2]] == ["3", "film", "SP-4", "SP-10", "51.0", "59.6", "51.2", "58.9",
                                                      "—"]
    assert [c["text"] for c in joints["body"][0]][-3:] == ["—", "—", "0.00"]  # joint 1: within the family's reach
    assert [c["text"] for c in joints["body"][1]][-1] == "0.46 ⚠"  # joint 2: flagged


def test_the_roms_control_sits_between_b_and_c_and_its_caption_says_what_it_means(folder, capsys):
    """The ROM table's control row (B_baseline, issue 44) gains one line on its table's caption, and only there."""
    from bladetwin.rom_summary import CASE_HEADER, CONTROL_TEXT, case_rows

    def case(df):
        return {"mean_abs_df_pct": df, "mean_mac": 0.98, "n_modes": 41, "n_reference_modes": 44}

    rom = {"paper": {"cases": {"A": None, "B": case(0.44), "B_baseline": case(0.41), "C": case(0.41)}},
           "updated": {"cases": {"A": None, "B": case(0.02), "B_baseline": case(0.011), "C": case(0.005)}}}
    rows = case_rows(rom)
    assert [r[0] for r in rows] == ["A", "B", "B_baseline", "C"]
    assert rows[2][1:] == [0.41, 0.98, 41, 0.011, 0.98, 41] and rows[0][1:] == [None] * 6
    _write_csv(folder / "rom_cases.csv", CASE_HEADER, [["" if v is None else v for v in r] for r in rows])
    summary = json.loads((folder / "summary.json").read_text())
    summary["sections"].append({"id": "rom_update", "title": "The ROM updated beyond Eq. 19",
                                "tables": [{"file": "rom_cases.csv", "caption": "Cases A, B and C."}]})
    (folder / "summary.json").write_text(json.dumps(summary))
    _, html = _render_cli(folder, capsys)
    assert html.count(CONTROL_TEXT.replace("'", "&#39;")) == 1
    assert "Cases A, B and C. " + CONTROL_TEXT.replace("'", "&#39;") in html
    table = next(t for t in _parse(html).tables if [c["text"] for c in t["head"][0]] == CASE_HEADER)
    assert [r[0]["text"] for r in table["body"]] == ["A", "B", "B_baseline", "C"]


def test_missing_figure_is_one_line_exit_2(folder, capsys):
    (folder / "figs" / "patterns.png").unlink()
    assert main(["report", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "patterns.png" in err[0] and err[0].startswith("bladetwin: error:")
    assert not (folder / "report.html").exists()


def test_missing_summary_is_one_line_exit_2(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "summary.json" in err[0]


def test_bad_json_and_missing_table(folder, capsys):
    summary = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    (folder / "blade_deltas.csv").unlink()
    with pytest.raises(ReportError, match="blade_deltas.csv"):
        render_report(folder)
    (folder / "summary.json").write_text("{not json", encoding="utf-8")
    with pytest.raises(ReportError, match=r"summary\.json: not valid JSON"):
        render_report(folder)
    assert summary["report"] == "report.html"


def test_minimal_summary_and_custom_path(tmp_path):
    """Only a few keys: every optional part is left out or shown unavailable; the page goes where asked."""
    (tmp_path / "empty.csv").write_text("a,b\n", encoding="utf-8")
    sections = [{"id": "x", "title": "Header only", "tables": [{"file": "empty.csv", "caption": "no data"}]}]
    (tmp_path / "summary.json").write_text(json.dumps({"campaign": "bare", "cases": {"B": None},
                                                       "sections": sections}), encoding="utf-8")
    out = render_report(tmp_path, path=tmp_path / "sub" / "page.html")
    assert out == tmp_path / "sub" / "page.html"
    page = _parse(out.read_text(encoding="utf-8"))
    t8 = _table(page, "table8")
    assert all(c["text"] == "unavailable" for r in t8["body"] for c in r[1:])
    assert not page.imgs
    empty = [t for t in page.tables if [c["text"] for c in t["head"][0]] == ["a", "b"]]
    assert len(empty) == 1 and [c["text"] for c in empty[0]["body"][0]] == ["no rows"]
    assert all(t["body"] for t in page.tables)


def test_helpers(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("a,b\n1,2.5\n\n3\n", encoding="utf-8")
    assert read_csv_table(p) == (["a", "b"], [["1", "2.5"], ["3", ""]])
    (tmp_path / "e.csv").write_text("", encoding="utf-8")
    with pytest.raises(ReportError, match="e.csv"):
        read_csv_table(tmp_path / "e.csv")
    assert format_number(None) == "unavailable"
    assert format_number(0.0) == "0"
    assert format_number(1234.5678) == "1235"  # the integer part whole
    assert format_number(" 12 ") == "12"
    assert format_number(float("nan")) == "—"
    assert format_number("SP-3") == "SP-3"
    # the examples: 3 significant digits; a percentage at most 2 decimals; no padding of a given value
    assert [format_number(v) for v in (0.01694, 0.05553, 0.4117, -0.7978)] == ["0.0169", "0.0555", "0.412", "-0.798"]
    assert [format_number(v, percent=True) for v in (0.4117, 0.07704, -0.7978, 0.00213, 12.345)] == \
        ["0.41", "0.08", "-0.80", "0.00", "12.3"]
    assert format_number(0.91) == "0.91" and format_number(0.99962) == "0.9996"  # a MAC keeps what tells it from 1
    assert format_number(2.68e11) == "2.68e+11" and format_number(3.2e-5) == "3.20e-05"
    assert format_column(["195.94", "620.676", "2000.1", ""]) == ["196", "621", "2000", ""]
    assert format_column([0.045, 1.13, 0.2087], percent=True) == ["0.04", "1.13", "0.21"]
    assert format_column(["1", "2"]) == ["1", "2"] and format_column(["-0.43", "1", "nan"]) == ["-0.43", "1.00", "—"]
