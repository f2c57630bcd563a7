"""The report as a lab reads it (issue 48): the first screen answers its three questions, numbers follow one rule,
long tables fold under the figure that shows them, no table is wider than the page, and it prints.

A fake output folder with everything the first screen reads (both ROMs, the control, the posterior's intervals,
long and wide tables) is rendered, and so is the bundled campaign's where ``out/academic`` exists. The widths are
measured in headless Chromium where it is installed.
"""

from __future__ import annotations

import csv
import html
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from bladetwin.index_page import render_index  # noqa: E402
from bladetwin.methods import FREQUENCY_HEADER, POSTERIOR_HEADER  # noqa: E402
from bladetwin.report import render_report  # noqa: E402
from bladetwin.report_answer import HEADLINE_CHARS, rom_choice, trust_paragraphs  # noqa: E402
from bladetwin.rom_summary import CASE_HEADER  # noqa: E402
from bladetwin.run_figures import plot_posterior_frequencies  # noqa: E402
from bladetwin.util import atomic_savefig  # noqa: E402

from .number_rule import check_column, is_percent_header  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
ACADEMIC = REPO / "out" / "academic"
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FOLD = 20  # about 20 rows: longer tables are folded
N_BLADES, FILMED = 18, (3, 7, 10, 14, 17)


# ----------------------------------------------------------------------------------------------- the page


class _Page(HTMLParser):
    """Tables (their class, head and body cells, whether a <details> holds them), details' summaries, text."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: list[dict] = []
        self.details: list[dict] = []
        self.text: list[str] = []
        self._open_details: list[dict] = []
        self._table: dict | None = None
        self._cell: list[str] | None = None
        self._section: str | None = None
        self._summary: dict | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "details":
            d = {"class": a.get("class", ""), "summary": "", "parent": self._open_details[-1]
                 if self._open_details else None}
            self.details.append(d)
            self._open_details.append(d)
        elif tag == "summary" and self._open_details:
            self._summary = self._open_details[-1]
        elif tag == "table":
            self._table = {"class": a.get("class", ""), "head": [], "body": [], "folded": bool(self._open_details),
                           "label": a.get("aria-labelledby") or a.get("aria-label") or ""}
            self.tables.append(self._table)
        elif tag in ("thead", "tbody") and self._table is not None:
            self._section = tag
        elif tag == "tr" and self._table is not None:
            self._table["body" if self._section == "tbody" else "head"].append([])
        elif tag in ("td", "th") and self._table is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "details" and self._open_details:
            self._open_details.pop()
        elif tag == "summary":
            self._summary = None
        elif tag in ("td", "th") and self._cell is not None and self._table is not None:
            rows = self._table["body" if self._section == "tbody" else "head"]
            rows[-1].append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "table":
            self._table, self._section = None, None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)
        if self._summary is not None:
            self._summary["summary"] += data


def _parse(text: str) -> _Page:
    page = _Page()
    page.feed(text)
    page.close()
    return page


def _check_numbers(page: _Page) -> int:
    """The formatting rule on every table: down each column, or along each row where a row holds one quantity."""
    n = 0
    for t in page.tables:
        where = t["label"] or t["class"]
        if "by-row" in t["class"].split():
            for row in t["body"]:
                n += check_column(row[1:], percent=is_percent_header(row[0]), where=f"{where}: {row[0]}")
            continue
        header = t["head"][-1] if t["head"] else []
        width = max((len(r) for r in t["body"]), default=0)
        for k in range(width):
            name = header[k] if len(t["head"]) == 1 and k < len(header) else ""
            n += check_column([r[k] for r in t["body"] if k < len(r)], percent=is_percent_header(name),
                              where=f"{where}: column {name or k}")
    return n


def _check_folding(page: _Page) -> None:
    for t in page.tables:
        assert t["folded"] or len(t["body"]) <= FOLD, f"{t['label']}: {len(t['body'])} rows shown unfolded"


# ------------------------------------------------------------------------------------------ the fixture


def _png(path: Path, rows: int = 1) -> None:
    fig, ax = plt.subplots(figsize=(6, 1 + rows * 0.3))
    ax.imshow(np.random.default_rng(0).random((rows, 31)), aspect="auto")
    atomic_savefig(fig, path, dpi=40)
    plt.close(fig)


def _csv(path: Path, header: list[str], rows: list[list]) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def _case(df: float, mac: float, n: int, ref: int = 47) -> dict:
    return {"mean_abs_df_pct": df, "mean_mac": mac, "n_modes": n, "n_reference_modes": ref}


def _summary() -> dict:
    unfilmed = [j for j in range(1, N_BLADES + 1) if j not in FILMED]
    joints = [{"joint": j, "source": "film" if j in FILMED else "posterior", "pattern_L": "posterior",
               "pattern_R": "posterior", "area_fraction_L_pct": 60 + j / 7, "area_fraction_R_pct": 55 - j / 3,
               "reference_area_L_pct": 58.123 + j, "reference_area_R_pct": 61.456 - j,
               "beyond_family_pct": None if j in FILMED else 0.01694 * j,
               "outside_family": None if j in FILMED else j in (4, 11)} for j in range(1, N_BLADES + 1)]
    ratio = {"area L": 0.7559, "area R": 0.65, "centroid u L": 0.9099, "centroid v L": 0.924,
             "centroid u R": 0.9474, "centroid v R": 0.7422}
    long_note = ("Films read as scanned, image rows along the grid's rows: their flank's cells are square in the "
                 "image, so a scan rotated by 90° cannot be told from the imprint: joint_03_L.png, joint_03_R.png.")
    return {
        "campaign": "layout", "kind": "virtual", "n_blades": N_BLADES, "grid": [7, 31], "known_joints": list(FILMED),
        "generated": "2026-11-27T00:00:00Z", "command": "bladetwin run", "report": "report.html",
        "feature_modes": [2, 4, 10], "step1": {"max_abs_eps_pct": 48.98},
        "bias": {"enabled": True, "per_mode_pct": [0.07704, -0.7978, 0.00213], "spread_pct": [0.05553, 0.1, 0.3],
                 "joints": list(FILMED)},
        "joints": joints,
        "cases": {"A": _case(0.02766, 0.9565, 56, 56), "B": _case(1.1792, 0.6265, 35),
                  "B_no_bias": _case(1.1385, 0.6275, 34), "C": _case(1.1803, 0.6352, 35),
                  "baseline": {"A": _case(0.04179, 0.8597, 56, 56), "B": _case(1.1842, 0.6145, 35)},
                  "posterior": {"A": _case(0.04524, 0.9646, 56, 56), "B": _case(1.1335, 0.6165, 34)}},
        "paper_table8": {"A": {"mean_abs_df_pct": 0.07, "mean_mac": 0.91},
                         "B": {"mean_abs_df_pct": 0.73, "mean_mac": 0.85},
                         "C": {"mean_abs_df_pct": 0.46, "mean_mac": 0.82}},
        "rom": {"paper": {"cases": {"A": _case(0.04524, 0.9646, 56, 56), "B": _case(1.1335, 0.6165, 34),
                                    "B_baseline": _case(1.1842, 0.6145, 35), "C": _case(1.1803, 0.6352, 35)}},
                "updated": {"cases": {"A": _case(0.05139, 0.9772, 55, 55), "B": _case(0.20872, 0.94761, 39),
                                      "B_baseline": _case(0.19958, 0.9414, 40), "C": _case(0.2016, 0.9403, 40)}}},
        "methods": {"posterior": {"experimental": {"area_error_pp": 13.559, "ci90_coverage_area": 0.8846,
                                                   "ci90_median_width_pp": 43.548},
                                  "width_ratio": {"experimental": ratio}},
                    "baseline": {"area_error_pp": 15.402}},
        "notes": [long_note, "A short note."],
        "warnings": ["blade 4, free mode 5 (4328.5 Hz): the disk–one-blade test puts it +17.8 % (eigenvalue) from "
                     "the free test's Eq. 19 value, beyond ±10 %: check that the blade and disk–one-blade files "
                     "belong to blade 4"],
        "timings_s": {"ema": 146.71, "rom": 174.6, "report": 0.4, "total": 573.3},
        "files": {"rom_modes_uff": "identified_rom_modes.uff"},
        "sections": [
            {"id": "ema", "title": "Experimental modal analysis", "text": "EMA.",
             "figures": [{"file": "stabilization.png", "caption": "Stabilization."}],
             "tables": [{"file": "ema_quality.csv", "caption": "EMA of every test (38 rows, no figure)."},
                        {"file": "blade_deltas.csv", "caption": "Blade deltas (%).", "heatmap": True},
                        {"file": "d1b_validation.csv", "caption": "Fourteen columns with long names."}]},
            {"id": "posterior", "title": "Contact posterior", "text": ["What the data pin down."],
             "figures": [{"file": "contact_probability.png", "caption": "Posterior probability of contact."},
                         {"file": "posterior_frequencies.png", "caption": "Frequencies against the test."}],
             "tables": [{"file": "posterior_contact.csv", "caption": "The posterior per joint."},
                        {"file": "posterior_frequencies.csv", "caption": "Every tracked frequency.",
                         "figure": "posterior_frequencies.png"}]},
            {"id": "rom_update", "title": "The ROM updated beyond Eq. 19",
             "tables": [{"file": "rom_cases.csv", "caption": "Cases A, B and C."}]},
        ],
        "_unfilmed": unfilmed,
    }


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    d = tmp_path / "out"
    d.mkdir()
    s = _summary()
    unfilmed = s.pop("_unfilmed")
    rng = np.random.default_rng(1)
    _png(d / "stabilization.png")
    _png(d / "contact_probability.png", rows=len(unfilmed))
    freq = []
    for j in unfilmed:
        for m in range(1, 11):
            y = 200.0 * m + j
            lo, hi = sorted(y * (1 + rng.normal(0, 1e-3, 2)))
            f = 0.5 * (lo + hi)
            freq.append([j, m, y, f, lo, hi, 100 * (f / y - 1)])
    fig = plot_posterior_frequencies(np.array(freq))
    atomic_savefig(fig, d / "posterior_frequencies.png", dpi=40)
    _csv(d / "posterior_frequencies.csv", FREQUENCY_HEADER, freq)
    post = [[j, *(rng.uniform(0, 100, 8)), *(rng.normal(0, 1, 12))] for j in unfilmed]
    _csv(d / "posterior_contact.csv", POSTERIOR_HEADER, post)
    _csv(d / "ema_quality.csv", ["test", "type", "modes", "fit quality min", "fit quality mean"],
         [[f"blade_{k:02d}", "blade", 8, 0.998865 + k * 1e-5, 0.999079] for k in range(38)])
    _csv(d / "blade_deltas.csv", ["blade", *(f"mode {m}" for m in range(1, 8))],
         [[b, *(rng.normal(0, 1.5, 7))] for b in range(1, N_BLADES + 1)])
    names = [f"{kind} mode {m} (Hz)" for kind in ("measured", "identified", "reference-pattern ROM",
                                                 "numerical-input ROM") for m in (2, 4, 10)]
    _csv(d / "d1b_validation.csv", ["joint", "source", *names],
         [[j, "k-NN + refinement", *(rng.uniform(600, 3500, 12))] for j in range(1, N_BLADES + 1)])
    rom = s["rom"]
    _csv(d / "rom_cases.csv", CASE_HEADER,
         [[k, *(rom[kind]["cases"][k][f] for kind in ("paper", "updated")
                for f in ("mean_abs_df_pct", "mean_mac", "n_modes"))] for k in ("A", "B", "B_baseline", "C")])
    (d / "identified_rom_modes.uff").write_text("    -1\n", encoding="utf-8")
    (d / "summary.json").write_text(json.dumps(s, indent=1), encoding="utf-8")
    return d


# ---------------------------------------------------------------------------------------------- the tests


def test_the_first_screen_answers_the_three_questions_in_order(folder):
    page = render_report(folder).read_text(encoding="utf-8")
    text = html.unescape(re.sub(r"<[^>]+>", " ", page))
    order = ["1. The contact of every unfilmed joint", "The answer.", "2. The ROM to take away",
             "3. How far to trust them", "Contact.", "ROM.", "Warnings (1)", "Notes (2)", "Full-assembly validation"]
    at = [text.index(s) for s in order]
    assert at == sorted(at), order
    # the contact maps lead the page once, not again in their section (which points to them)
    assert page.count("data:image/png;base64,") == 3
    assert 'href="#fig-2">at the top</a>' in page
    p = _parse(page)
    rom = next(t for t in p.tables if "rom" in t["class"].split())
    assert rom["body"] == [["updated ROM (exported)", "0.21", "0.948", "39 of 47"],
                           ["paper's ROM", "1.13", "0.617", "34 of 47"]]
    assert 'href="identified_rom_modes.uff"' in page
    contact, rom_text = (" ".join(p.split()) for _, p in trust_paragraphs(json.loads(
        (folder / "summary.json").read_text())))
    for figure in ("43.5 pp", "0.65–0.76", "0.74–0.95", "88 % of the flanks", "13.6 pp", "15.4 pp", "Joints 4, 11"):
        assert figure in contact and figure in text, figure
    for figure in ("0.21 %", "MAC 0.948", "39 of 47", "0.20 %, 0.941", "improves the MAC only", "0.20 %, 0.940"):
        assert figure in rom_text and figure in text, figure
    # notes and warnings folded, each under a one-line headline; a note that fits its headline is not folded
    folded = [d for d in p.details if d["class"] in ("note", "warning")]
    assert len(folded) == 2 and all(len(d["summary"].strip()) <= HEADLINE_CHARS + 2 for d in folded)
    assert folded[0]["summary"].strip().startswith("blade 4, free mode 5 (4328.5 Hz)")
    assert '<p class="note whole">A short note.</p>' in page


def test_the_trust_paragraphs_are_generated_from_the_summary(folder):
    s = json.loads((folder / "summary.json").read_text())
    upd = s["rom"]["updated"]["cases"]
    upd["B_baseline"] = _case(0.5, 0.9, 38)  # the identified contact beats the control on both figures
    assert "improves both figures" in trust_paragraphs(s)[1][1]
    upd["B_baseline"] = _case(0.1, 0.99, 41)
    assert "does not improve the match" in trust_paragraphs(s)[1][1]
    del s["rom"]  # `--rom paper`: the paper's ROM is taken away, with the posterior's Case B
    assert trust_paragraphs(s)[1][1].startswith("The paper's ROM matches the full-assembly test to 1.13 %")
    s["methods"] = {}  # the k-NN only, no truth: no interval, said so
    s["kind"] = "lab"
    contact = trust_paragraphs(s)[0][1]
    assert "no interval" in contact and "intervals are the measure" in contact


def test_the_rom_to_take_away_names_the_joints_where_it_took_a_posterior_draw(folder):
    """Where the ROM update replaced a joint's answer (design §8.84), the first screen says so by joint."""
    s = json.loads((folder / "summary.json").read_text())
    params = s["rom"]["updated"].setdefault("parameters", {})
    params["replaced_joints"] = [{"joint": 4, "area_pct": [8.0, 17.0]}]
    assert "(joint 4: the posterior draw its disk–one-blade test bears out" in rom_choice(s)["text"]
    params["replaced_joints"] = []
    assert "posterior draw" not in rom_choice(s)["text"]


def _check_page(page: Path) -> int:
    p = _parse(page.read_text(encoding="utf-8"))
    _check_folding(p)
    return _check_numbers(p)


def test_every_table_follows_the_number_rule_and_long_tables_are_folded(folder, tmp_path):
    report = render_report(folder)
    assert _check_page(report) > 500
    p = _parse(report.read_text(encoding="utf-8"))
    # the posterior's wide table: each value with its interval, 21 CSV columns → 9
    post = next(t for t in p.tables if t["head"] and t["head"][0][0] == "joint" and len(t["head"][0]) == 9)
    assert re.fullmatch(r"\d+\.\d \[\d+\.\d, \d+\.\d\]", post["body"][0][1])
    # the 130-row table is folded, right under the figure that shows it; the 38-row one alone
    text = report.read_text(encoding="utf-8")
    under = r"posterior_frequencies\.png</a>\)</span></figcaption>\s*</figure>\s*<details class=\"table\""
    assert re.search(under, text)
    numbers = [int(n) for n in re.findall(r"<strong>Table (\d+)\.</strong>", text)]
    assert numbers == list(range(1, len(numbers) + 1))  # numbered as they read, a folded one under its figure
    long = [t for t in p.tables if len(t["body"]) > FOLD]
    assert len(long) == 2 and all(t["folded"] for t in long)
    # the index page of two campaigns
    other = tmp_path / "second"
    shutil.copytree(folder, other)
    s = json.loads((other / "summary.json").read_text())
    s["campaign"] = "second"
    (other / "summary.json").write_text(json.dumps(s))
    index = render_index(tmp_path, [folder, other])
    assert _check_page(index) > 50
    assert "<td>1.18</td><td>0.626</td>" in index.read_text(encoding="utf-8")


@pytest.mark.skipif(not (ACADEMIC / "summary.json").is_file(), reason="out/academic not written (run `make run`)")
def test_the_bundled_campaigns_report_follows_the_rule(tmp_path):
    report = render_report(ACADEMIC, path=tmp_path / "academic" / "report.html")
    assert _check_page(report) > 1000


# ------------------------------------------------------------------------------- widths, in a browser


_MEASURE = """<script>
document.querySelectorAll('details').forEach(d => d.open = true);
const out = [];
document.querySelectorAll('table').forEach(t => {
  const box = t.parentElement.getBoundingClientRect(), r = t.getBoundingClientRect();
  out.push({label: t.getAttribute('aria-labelledby') || t.getAttribute('aria-label') || t.className,
            width: r.width, right: r.right, box: box.width});
});
const pre = document.createElement('pre');
pre.id = 'measured';
pre.textContent = JSON.stringify({viewport: document.documentElement.clientWidth, tables: out});
document.body.appendChild(pre);
</script>"""


def _widths(page: Path, width: int, tmp_path: Path, *, print_css: bool = False) -> dict:
    """Every table's width in headless Chromium at ``width`` px, its folds open (``print_css``: the print
    stylesheet applied on screen, so that the page width is the printed one)."""
    text = page.read_text(encoding="utf-8")
    if print_css:
        text = text.replace("@media print {", "@media all {")
    probe = tmp_path / f"probe_{page.stem}_{width}.html"
    probe.write_text(text.replace("</body>", _MEASURE + "</body>"), encoding="utf-8")
    out = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", f"--window-size={width},1000",
                          "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="measured">(.*?)</pre>', out.stdout, re.S)
    assert m, f"Chromium gave no measurement: {out.stderr[-500:]}"
    return json.loads(html.unescape(m.group(1)))


def _assert_fit(measured: dict, where: str) -> None:
    assert measured["tables"], where
    for t in measured["tables"]:
        assert t["width"] <= t["box"] + 1 and t["right"] <= measured["viewport"] + 1, (where, t)


def _pages(folder: Path, tmp_path: Path) -> list[Path]:
    pages = [render_report(folder)]
    if (ACADEMIC / "summary.json").is_file():
        pages.append(render_report(ACADEMIC, path=tmp_path / "academic" / "report.html"))
    other = tmp_path / "second"
    shutil.copytree(folder, other)
    pages.append(render_index(tmp_path, [folder, other]))
    return pages


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed: the widths need a browser to lay out")
def test_no_table_is_wider_than_the_page_at_1400_px(folder, tmp_path):
    for page in _pages(folder, tmp_path):
        _assert_fit(_widths(page, 1400, tmp_path), f"{page} at 1400 px")


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed: printing needs a browser")
def test_the_report_prints_without_cut_tables(folder, tmp_path):
    """The print stylesheet: every table within an A4 page's width (186 mm ≈ 703 px), folds open; a PDF comes out."""
    report = render_report(folder)
    text = report.read_text(encoding="utf-8")
    css = text[text.index("@media print {"):text.index("</style>")]
    for rule in ("break-inside: avoid", "details::details-content", "thead { display: table-header-group; }",
                 "max-width: none"):
        assert rule in css, rule
    _assert_fit(_widths(report, 703, tmp_path, print_css=True), "printed on A4")
    pdf = tmp_path / "report.pdf"
    subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-pdf-header-footer",
                    f"--print-to-pdf={pdf}", report.as_uri()], capture_output=True, timeout=120, check=True)
    data = pdf.read_bytes()
    assert data.startswith(b"%PDF") and len(re.findall(rb"/Type\s*/Page\b", data)) >= 2


def test_an_answer_outside_its_interval_is_drawn_where_it_lies():
    """The posterior's answer (its pattern) may lie outside the interval of its samples' frequencies: the figure
    draws the bar from the interval's bounds and the dot at the answer, instead of refusing (a re-seated joint's
    run raised "'yerr' must not contain negative values")."""
    rows = np.array([[2, 1, 100.0, 100.5, 99.8, 100.2, 0.5], [2, 2, 200.0, 199.0, 199.5, 200.5, -0.5]])
    fig = plot_posterior_frequencies(rows)
    ax = fig.axes[0]
    bar = ax.collections[0].get_segments()[0]
    np.testing.assert_allclose(bar[:, 1], [100 * (99.8 / 100 - 1), 100 * (100.2 / 100 - 1)])
    np.testing.assert_allclose(ax.lines[-1].get_ydata(), [0.5])
