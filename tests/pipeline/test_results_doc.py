"""docs/results.md and the README's figures against the JSON files they are generated from (docs/results/)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from bladetwin.results_doc import (
    load_docs,
    lookup,
    readme_blocks,
    render_results,
    table8_rows,
    update_readme,
    width_rows,
)

from .number_rule import check_column, is_percent_header

REPO = Path(__file__).resolve().parents[2]
FOLDER = REPO / "docs" / "results"


def _resolve(docs: dict, source: str):
    """The test's own reading of a ``file:key`` source (``a / b`` a ratio), independent of the renderer."""
    name, key = source.split(":", 1)
    if " / " in key:
        a, b = (_resolve(docs, f"{name}:{k}") for k in key.split(" / "))
        return None if a is None or b is None else a / b
    node = docs.get(name)
    for part in key.replace("[", ".[").split("."):
        if node is None or not part:
            continue
        m = re.fullmatch(r"\[(\w+)=([\w.-]+)\]", part)
        if m:
            node = next((x for x in node if str(x.get(m[1])) == m[2]), None)
        else:
            node = node.get(part) if isinstance(node, dict) else None
    return node


def _rows(text: str):
    """(cells, sources) of every table row that names its sources."""
    for line in text.splitlines():
        if not line.startswith("| ") or "`" not in line.rsplit("|", 2)[-2]:
            continue
        cols = [c.strip() for c in line.strip("|").split("|")]
        sources = re.findall(r"`([^`]+)`", cols[-1])
        if all(":" in s for s in sources):
            yield cols[1:1 + len(sources)], sources


def _check_figures(text: str, docs: dict) -> int:
    n = 0
    for cells, sources in _rows(text):
        for cell, source in zip(cells, sources, strict=True):
            value = _resolve(docs, source)
            if value is None:
                assert cell == "not measured", (source, cell)
                continue
            printed = float(cell)
            decimals = len(cell.split("e")[0].split(".")[1]) if "." in cell.split("e")[0] else 0
            exp = int(cell.split("e")[1]) if "e" in cell else 0
            # the printed figure is the JSON value rounded to its last printed digit
            assert abs(printed - value) <= 0.5 * 10.0 ** (exp - decimals) * (1 + 1e-9), (source, cell, value)
            n += 1
    return n


def test_every_figure_in_results_md_equals_its_json():
    docs = load_docs(FOLDER)
    text = (REPO / "docs" / "results.md").read_text()
    assert _check_figures(text, docs) >= 20  # Table 8, the contact check and the performance table
    for row in table8_rows(docs):  # the doc holds the run's Table 8, not another run's
        assert f"| {row.label} | {' | '.join(row.cells)} |" in text


def _tables(text: str):
    """Each Markdown table of ``text``: (header, body rows), the ``source`` and ``command`` columns left out."""
    lines = text.splitlines() + [""]
    start = None
    for i, line in enumerate(lines):
        if line.startswith("|") and start is None:
            start = i
        elif not line.startswith("|") and start is not None:
            rows = [[c.strip() for c in x.strip().strip("|").split(" | ")] for x in lines[start:i]]
            keep = [k for k, h in enumerate(rows[0]) if h not in ("source", "command")]
            yield [rows[0][k] for k in keep], [[r[k] for k in keep] for r in rows[2:]]
            start = None


def test_the_readme_and_results_md_follow_the_one_formatting_rule():
    """About 3 significant digits, percentages at most 2 decimals, one number of decimals down a column (along
    a row where each row holds one quantity: the contact check); the performance table's cells each alone."""
    docs = load_docs(FOLDER)
    n = 0
    blocks = re.findall(r"<!-- results:\w+ -->\n(.*?)<!-- /results", (REPO / "README.md").read_text(), re.S)
    for doc in (*blocks, (REPO / "docs" / "results.md").read_text()):
        for header, body in _tables(doc):
            if header[0] == "what":  # performance: each cell a quantity of its own
                n += sum(check_column([c], where=f"{r[0]}") for r in body for c in r[1:])
            elif header[0] == "unfilmed joints vs truth":  # each row one quantity
                n += sum(check_column(r[1:], percent="(pp)" in r[0], where=r[0]) for r in body)
            else:
                for k, h in enumerate(header[1:], start=1):
                    n += check_column([r[k] for r in body], percent=is_percent_header(h), where=h)
    assert n >= 100
    # the examples: four or five significant digits no more
    t8 = {r.label: r.cells for r in table8_rows(docs)}
    assert all(len(c.split(".")[-1]) <= 2 for c in (t8["Case A"][0], t8["Case B"][0]))


def _without_source(line: str) -> str:
    """A docs/results.md table line less its last (``source``) column."""
    return line[:-len("---|")] if line.startswith("|---") else line.rsplit(" | ", 1)[0] + " |"


def test_results_md_and_readme_are_regenerated_from_the_json():
    docs = load_docs(FOLDER)
    assert (REPO / "docs" / "results.md").read_text() == render_results(docs), "run `make results`"
    readme = (REPO / "README.md").read_text()
    assert readme == update_readme(readme, readme_blocks(docs)), "run `make results`"


def test_readme_tables_are_results_md_rows_without_the_source_column():
    # every README figure is a row of docs/results.md (whose figures the test above checks against the JSON)
    results = (REPO / "docs" / "results.md").read_text().splitlines()
    checked = {_without_source(line) for line in results if line.startswith("|")}
    blocks = re.findall(r"<!-- results:(\w+) -->\n(.*?)<!-- /results:\1 -->", (REPO / "README.md").read_text(), re.S)
    assert [name for name, _ in blocks] == ["table8", "contact", "rom", "response", "performance"]
    rows = [line for _, text in blocks for line in text.splitlines() if line.startswith("|")]
    assert len(rows) >= 40  # Table 8, the contact check, the ROM, AF and performance tables
    assert not [line for line in rows if line not in checked]
    assert "source" not in "".join(rows) and not [line for line in rows if "summary.json:" in line]


def test_sources_only_where_asked():
    docs = load_docs(FOLDER)
    plain, sourced = readme_blocks(docs), readme_blocks(docs, sources=True)
    assert plain.keys() == sourced.keys()
    for name in plain:
        a, b = plain[name].splitlines(), sourced[name].splitlines()
        assert len(a) == len(b)
        assert [_without_source(x) if x.startswith("|") else x for x in b] == a, name
        assert _check_figures(plain[name], docs) == 0 and (_check_figures(sourced[name], docs) > 0) == ("|" in b[-1])


def test_missing_benchmarks_and_blocks():
    docs = {"summary.json": {"campaign": "c", "cases": {"A": {"mean_abs_df_pct": 0.1234, "mean_mac": 0.9,
                                                              "n_modes": 7}}}}
    text = render_results(docs)
    assert "| Case A | 0.12 | 0.9 | 7 | not measured | not measured |" in text
    assert "Case B" not in text and "No true patterns" in text
    assert _check_figures(text, docs) == 3
    readme = "a\n<!-- results:table8 -->\nold\n<!-- /results:table8 -->\n<!-- results:other -->\nkeep\n" \
             "<!-- /results:other -->\n"
    out = update_readme(readme, readme_blocks(docs))
    assert "old" not in out and "| Case A | 0.12 |" in out and "keep" in out


def test_width_rows():
    ratios = {"area L": 0.6, "area R": 0.7, "centroid u L": 0.9}
    docs = {"summary.json": {"campaign": "c", "methods": {"posterior": {"width_ratio": {"numerical": ratios}}}}}
    rows = width_rows(docs)
    assert [r.label for r in rows] == ["contact area, flank L", "contact area, flank R", "centroid ū (axial), flank L"]
    assert rows[0].cells == ("0.6", "not measured")  # one decimal down the column: 0.6, 0.7, 0.9 as given
    assert rows[0].sources[0] == "summary.json:methods.posterior.width_ratio.numerical.area L"
    text = render_results(docs)
    assert "## What the disk–one-blade data pin down" in text and _check_figures(text, docs) == 3
    assert "pin down" not in render_results({"summary.json": {"campaign": "c"}})


def test_lookup():
    doc = {"results": [{"step": "a", "s": 1.0}, {"step": "b", "s": {"x": [3, 4]}}]}
    assert lookup(doc, "results[step=b].s.x[1]") == 4
    assert lookup(doc, "results[0].s") == 1.0
    assert lookup(doc, "results[step=c].s") is None and lookup(doc, "nope.x") is None


def test_a_damaged_json_is_refused_in_one_line(tmp_path):
    (tmp_path / "summary.json").write_text("{not json")
    with pytest.raises(SystemExit, match="summary.json: not a JSON document"):
        load_docs(tmp_path)
    (tmp_path / "summary.json").write_text(json.dumps({"campaign": "x"}))
    (tmp_path / "bench_rom.json").write_text("")
    with pytest.raises(SystemExit, match="bench_rom.json"):
        load_docs(tmp_path)
