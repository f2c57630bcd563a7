"""``docs/results.md`` and the README's figures, generated from a run's ``summary.json`` and the benchmarks' JSON.

``make results`` copies the last run's ``summary.json`` into ``docs/results/`` and calls :func:`main`; ``make
bench-results`` refreshes the benchmarks' files there (``bench_*.json``, each by a benchmark's ``--json``). Every
figure in the generated text is a JSON value, rounded by the report's one rule (:mod:`bladetwin.report_cells`:
about 3 significant digits, percentages at most 2 decimals, one number of decimals down a column, or along a row
where a row holds one quantity). In ``docs/results.md`` the row that shows it names its file and key (``source``
column), so a reader (and ``tests/pipeline/test_results_doc.py``) can check it; the README's blocks are the same
rows without that column. Nothing here computes a figure: it only formats."""

from __future__ import annotations

import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from rom.fileio import atomic_path

from .report_cells import format_column, format_number

__all__ = ["Row", "lookup", "table8_rows", "contact_rows", "rom_rows", "performance_rows", "width_rows",
           "response_rows", "render_results", "readme_blocks", "update_readme", "main"]

#: The benchmark files ``make bench-results`` writes, by the name the tables use.
BENCHMARKS = {"run": "bench_run.json", "rom": "bench_rom.json", "ema": "bench_ema.json",
              "ema_families": "bench_ema_families.json", "dataset": "bench_dataset.json",
              "posterior": "bench_posterior.json", "response": "bench_response.json"}
_MISSING = "not measured"


def lookup(doc: dict, key: str):
    """The value at ``key`` in a JSON document: dots between fields, ``[k]`` a list index, ``[f=v]`` the list item
    whose field ``f`` equals ``v`` (e.g. ``results[step=rom_d1b].seconds``); None where it is absent."""
    node = doc
    for part in re.findall(r"[^.\[\]]+|\[[^\]]+\]", key):
        if part.startswith("["):
            inner = part[1:-1]
            if not isinstance(node, list):
                return None
            if "=" in inner:
                f, v = inner.split("=", 1)
                node = next((x for x in node if isinstance(x, dict) and str(x.get(f)) == v), None)
            else:
                k = int(inner)
                node = node[k] if -len(node) <= k < len(node) else None
        else:
            node = node.get(part) if isinstance(node, dict) else None
        if node is None:
            return None
    return node


@dataclass(frozen=True)
class Row:
    """One table row: its label, its figures as printed, where each comes from (``file:key``), and the command
    that measures them (performance rows)."""

    label: str
    cells: tuple[str, ...]
    sources: tuple[str, ...]
    command: str = ""


def _shown(values: list, percent: bool) -> list[str]:
    """``values`` as the README prints them: the report's one rule (:func:`bladetwin.report_cells.format_column`),
    one number of decimals for all of them; "not measured" where a value is absent."""
    texts = format_column(values, percent=percent)
    return [_MISSING if v is None else t for v, t in zip(values, texts, strict=True)]


def _value(docs: dict, f: str, key: str):
    """The JSON value ``f:key``; for ``key`` written ``a / b``, the ratio of two values of ``f``."""
    if " / " in key:
        a, b = (lookup(docs.get(f, {}), k) for k in key.split(" / "))
        return a / b if isinstance(a, (int, float)) and isinstance(b, (int, float)) and b else None
    return lookup(docs.get(f, {}), key)


def _row(label: str, docs: dict, figures: list[tuple[str, str, str]]) -> Row:
    """One row formatted along itself (a row that holds one quantity). ``figures``: (file name, key, kind) of each
    cell, ``kind`` "pct" for a percentage (or percentage points); a key ``a / b`` is the ratio of two keys."""
    values = [_value(docs, f, k) for f, k, _ in figures]
    cells = _shown(values, percent=any(kind == "pct" for _, _, kind in figures))
    return Row(label, tuple(cells), tuple(f"{f}:{k}" for f, k, _ in figures))


def _by_column(rows: list[tuple[str, list[tuple[str, str, str]]]], docs: dict) -> list[Row]:
    """Rows whose columns each hold one quantity, formatted down each column: (label, figures) per row, the
    figures' kinds (see :func:`_row`) those of the columns."""
    values = [[_value(docs, f, k) for f, k, _ in figures] for _, figures in rows]
    width = max((len(v) for v in values), default=0)
    columns = []
    for c in range(width):
        kind = next(fig[c][2] for _, fig in rows if len(fig) > c)
        column = [v[c] if len(v) > c else None for v in values]
        columns.append(_shown(column, percent=kind == "pct"))
    return [Row(label, tuple(columns[c][i] for c in range(len(figures))), tuple(f"{f}:{k}" for f, k, _ in figures))
            for i, (label, figures) in enumerate(rows)]


def _cells(docs: dict, figures: list[tuple[str, str]]) -> tuple[str, ...]:
    """Cells each formatted alone (the performance table: each row mixes seconds, ratios and errors)."""
    return tuple(_MISSING if (v := _value(docs, f, k)) is None else format_number(v) for f, k in figures)


_CASES = (("Case A", "A"), ("Case B", "B"), ("Case B, no bias correction", "B_no_bias"), ("Case C", "C"),
          ("Case A, contact posterior", "posterior.A"), ("Case B, contact posterior", "posterior.B"),
          ("baseline (as Case A)", "baseline.A"), ("baseline (as Case B)", "baseline.B"))


def table8_rows(docs: dict) -> list[Row]:
    """Table 8 of the paper from ``summary.json``: mean |Δf| (%), mean MAC and paired modes per case."""
    rows = []
    for label, key in _CASES:
        figures = [("summary.json", f"cases.{key}.mean_abs_df_pct", "pct"),
                   ("summary.json", f"cases.{key}.mean_mac", "num"), ("summary.json", f"cases.{key}.n_modes", "int")]
        if "." not in key and "_" not in key:
            figures += [("summary.json", f"paper_table8.{key}.mean_abs_df_pct", "pct"),
                        ("summary.json", f"paper_table8.{key}.mean_mac", "num")]
        if _value(docs, "summary.json", f"cases.{key}.mean_abs_df_pct") is not None:
            rows.append((label, figures))
    return _by_column(rows, docs)


_METHOD_FIGURES = (("mean area-fraction error (pp)", "area_error_pp", "pct"),
                   ("mean centroid distance (mm)", "centroid_distance_mm", "num"),
                   ("node agreement", "node_agreement", "num"),
                   ("true area inside the 90 % interval (share of flanks)", "ci90_coverage_area", "num"),
                   ("true centroid inside it (share of flank axes)", "ci90_coverage_centroid", "num"),
                   ("true-pattern feature frequencies inside it (share)", "ci90_coverage_frequency", "num"),
                   ("median 90 % interval width (pp)", "ci90_median_width_pp", "pct"))


def contact_rows(docs: dict) -> list[Row]:
    """The unfilmed joints' contact against the truth (``summary.json`` → ``methods``): the contact posterior, the
    k-NN and the baseline per input (none without a reference: ``methods.baseline`` is then absent)."""
    if lookup(docs.get("summary.json", {}), "methods.baseline") is None:
        return []
    rows = []
    for inp in ("experimental", "numerical"):
        for label, key, spec in _METHOD_FIGURES:
            # intervals are the posterior's alone: the k-NN and the baseline give none
            methods = ("posterior",) if key.startswith("ci90") else ("posterior", "knn")
            figures = [("summary.json", f"methods.{m}.{inp}.{key}", spec) for m in methods]
            if not key.startswith("ci90"):
                figures.append(("summary.json", f"methods.baseline.{key}", spec))
            row = _row(f"{label}, {inp} input", docs, figures)
            if any(c != _MISSING for c in row.cells):
                rows.append(row)
    return rows


def rom_rows(docs: dict) -> list[Row]:
    """Cases A, B, C with the paper's ROM and the updated one (``summary.json`` → ``rom``), side by side."""
    rows = []
    for case in ("A", "B", "B_baseline", "C"):
        label = "Case B, baseline pattern (control)" if case == "B_baseline" else f"Case {case}"
        figures = [("summary.json", f"rom.{kind}.cases.{case}.{key}", spec) for kind in ("paper", "updated")
                   for key, spec in (("mean_abs_df_pct", "pct"), ("mean_mac", "num"), ("n_modes", "int"))]
        if _value(docs, "summary.json", f"rom.updated.cases.{case}.mean_abs_df_pct") is not None:
            rows.append((label, figures))
    return _by_column(rows, docs)


_WIDTHS = (("contact area, flank L", "area L"), ("contact area, flank R", "area R"),
           ("centroid ū (axial), flank L", "centroid u L"), ("centroid v̄ (radial), flank L", "centroid v L"),
           ("centroid ū (axial), flank R", "centroid u R"), ("centroid v̄ (radial), flank R", "centroid v R"))


def width_rows(docs: dict) -> list[Row]:
    """The contact posterior's 90 % interval width over the prior's, per quantity and input (``summary.json`` →
    ``methods.posterior.width_ratio``): how much the disk–one-blade tests narrow it (1: nothing)."""
    rows = [(label, [("summary.json", f"methods.posterior.width_ratio.{inp}.{key}", "num")
                     for inp in ("numerical", "experimental")]) for label, key in _WIDTHS]
    rows = [r for r in rows if any(_value(docs, f, k) is not None for f, k, _ in r[1])]
    return _by_column(rows, docs)


_D1B, _FULL = "results[step=rom_d1b]", "results[step=rom_full_cyclic]"
_CYC, _FE_FULL = "results[step=rom_disk_cyclic]", "results[step=fe_full]"
#: (label, command, file, [(key, format)] of the figure, the reference measured in the same run, their ratio).
_PERFORMANCE = (
    ("`bladetwin run`, bundled campaign, empty store (s); reference: the same run, every stage stored",
     "python benchmarks/run_cold.py", "bench_run.json", ["cold_s", "warm_s", "ratio"]),
    ("disk–one-blade ROM solve, 10 modes (s); reference: FE solve", "python benchmarks/rom.py", "bench_rom.json",
     [f"{_D1B}.median_solve_s", "results[step=fe_d1b].seconds",
      f"{_D1B}.median_solve_s / results[step=fe_d1b].seconds"]),
    ("full ROM, 3N modes, cyclic CB disk, first solve in a fresh process (s); reference: FE solve",
     "python benchmarks/rom.py", "bench_rom.json",
     [f"{_FULL}.seconds", f"{_FE_FULL}.seconds", f"{_FULL}.seconds / {_FE_FULL}.seconds"]),
    ("updated ROM (blades on contact springs, δ + ε): disk–one-blade solve (s); reference: paper's ROM",
     "python benchmarks/rom.py", "bench_rom.json",
     [f"{_D1B}.updated_solve_s", f"{_D1B}.median_solve_s",
      f"{_D1B}.updated_solve_s / {_D1B}.median_solve_s"]),
    ("updated ROM: full assembly, 3N modes, cyclic CB disk, solved again in that process (s); reference: "
     "paper's ROM, likewise", "python benchmarks/rom.py",
     "bench_rom.json", [f"{_FULL}.updated_seconds", f"{_FULL}.paper_repeat_seconds",
                        f"{_FULL}.updated_seconds / {_FULL}.paper_repeat_seconds"]),
    ("full ROM vs FE, 3N modes: max relative frequency error, min MAC", "python benchmarks/rom.py",
     "bench_rom.json", [f"{_FULL}.max_rel_err", f"{_FULL}.min_mac"]),
    ("full ROM peak memory (GB); reference: FE solve", "python benchmarks/rom.py", "bench_rom.json",
     [f"{_FULL}.peak_gb", f"{_FE_FULL}.peak_gb", f"{_FULL}.peak_gb / {_FE_FULL}.peak_gb"]),
    ("cyclic CB disk build, once per disk (s); reference: FE free-disk solve", "python benchmarks/rom.py",
     "bench_rom.json", [f"{_CYC}.seconds", "results[step=fe_disk].seconds",
                        f"{_CYC}.seconds / results[step=fe_disk].seconds"]),
    ("contact posterior of every unfilmed joint, experimental input (s); reference: the k-NN and its refinement",
     "python benchmarks/posterior.py", "bench_posterior.json", ["posterior_s", "knn_s", "ratio"]),
    ("forced response: AF of every EO × 200 posterior samples, families with an interval (`n_families`) (s); "
     "reference: one case by a direct harmonic solve (time per line × lines)", "python benchmarks/response.py",
     "bench_response.json", ["intervals_s", "direct_case_s", "intervals_s / direct_case_s"]),
    ("EMA, LSCF, 54 outputs × 6400 lines, 100 orders (s); reference: sdypy-EMA", "python benchmarks/ema.py",
     "bench_ema.json", ["lscf_s", "sdypy_lscf_s", "lscf_ratio"]),
    ("EMA of the bundled full-assembly test with dense families resolved (s); reference: the ordinary fit",
     "python benchmarks/ema_families.py", "bench_ema_families.json",
     ["families.time_s", "ordinary.time_s", "families.time_s / ordinary.time_s"]),
    ("full-assembly EMA: share of the truth's visible modes with a one-to-one mode within 0.05 %; reference: the "
     "ordinary fit", "python benchmarks/ema_families.py", "bench_ema_families.json",
     ["families.one_to_one_within_0p05pct", "ordinary.one_to_one_within_0p05pct"]),
    ("full-assembly EMA: mean MAC of the paired shapes against the exact shapes; reference: the ordinary fit",
     "python benchmarks/ema_families.py", "bench_ema_families.json",
     ["families.mean_shape_mac", "ordinary.mean_shape_mac"]),
    ("full-assembly EMA: mean shape MAC that the test's noise allows (Cramér–Rao, every other mode known); "
     "reference: the same with the entries below 3 σ zeroed", "python benchmarks/ema_families.py",
     "bench_ema_families.json", ["shape_mac_bound", "shape_mac_bound_zeroed_below_3sd"]),
    ("full-assembly EMA: share of the found modes whose truth lies within ± 2 standard deviations; reference: the "
     "ordinary fit", "python benchmarks/ema_families.py", "bench_ema_families.json",
     ["families.within_2sd", "ordinary.within_2sd"]),
    ("dataset by reanalysis (s); reference: direct solves, extrapolated", "python benchmarks/dataset.py",
     "bench_dataset.json", ["build_s", "direct_s_extrapolated", "build_s / direct_s_extrapolated"]),
    ("dataset, max relative frequency error vs direct solves", "python benchmarks/dataset.py", "bench_dataset.json",
     ["max_rel_err"]),
)


def response_rows(docs: dict) -> list[Row]:
    """The amplification factor against the truth twin's, per ROM (``summary.json`` → ``response``)."""
    keys = (("against_truth.{}.n_cases", "int"), ("against_truth.{}.median_abs_error_pct", "pct"),
            ("against_truth.{}.in_ci90", "num"), ("roms.{}.largest.af", "num"), ("truth.largest.af", "num"))
    rows = [(name, [("summary.json", "response." + k.format(rom), f) for k, f in keys])
            for rom, name in (("updated", "updated ROM"), ("paper", "paper's ROM"))
            if _value(docs, "summary.json", f"response.against_truth.{rom}.n_cases") is not None]
    return _by_column(rows, docs)


def performance_rows(docs: dict) -> list[Row]:
    """One row per benchmark figure: figure, the reference measured in the same run, and their ratio."""
    rows = []
    for label, command, f, keys in _PERFORMANCE:
        cells = _cells(docs, [(f, k) for k in keys])
        rows.append(Row(label, cells + ("",) * (3 - len(cells)), tuple(f"{f}:{k}" for k in keys), command))
    return rows


def _table(header: list[str], rows: list[Row], with_command: bool = False, sources: bool = True) -> list[str]:
    """A Markdown table; ``sources`` adds the ``source`` column (docs/results.md has it, the README does not)."""
    cols = header + ["source"] if sources else header
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        cmd = [f"`{r.command}`"] if with_command else []
        src = [", ".join(f"`{s}`" for s in r.sources)] if sources else []
        lines.append("| " + " | ".join([r.label, *r.cells, *cmd, *src]) + " |")
    return lines


_T8_HEADER = ["Table 8", "mean \\|Δf\\| %", "mean MAC", "paired modes", "paper \\|Δf\\| %", "paper MAC"]
_METHODS_HEADER = ["unfilmed joints vs truth", "contact posterior", "k-NN (refined)", "baseline"]
_PERF_HEADER = ["what", "measured", "reference", "ratio", "command"]
_WIDTH_HEADER = ["posterior 90 % width / prior width", "numerical input", "experimental input"]
_RESPONSE_HEADER = ["AF vs the truth twin's", "(family, EO) cases", "median \\|AF / AF_truth − 1\\| %",
                    "truth inside the 90 % interval", "largest AF", "truth's largest AF"]
_ROM_HEADER = ["vs the full-assembly test", "paper's ROM \\|Δf\\| %", "paper's ROM MAC", "paired",
               "updated ROM \\|Δf\\| %", "updated ROM MAC", "paired"]


def _pad(rows: list[Row], n: int) -> list[Row]:
    return [Row(r.label, r.cells + ("",) * (n - len(r.cells)), r.sources, r.command) for r in rows]


def readme_blocks(docs: dict, sources: bool = False) -> dict[str, str]:
    """The README's blocks by marker name: ``table8``, ``contact``, ``rom``, ``response``, ``performance``;
    ``sources=True`` gives the same blocks with each table's ``source`` column, as ``docs/results.md`` shows them."""
    s = docs.get("summary.json", {})
    run = f"`bladetwin run` on `{s.get('campaign', '?')}`"
    t8 = [f"Figures of {run} (`docs/results/summary.json`; mean over the paired modes), with the paper's ROM. "
          "Cases A and B take the k-NN's answers (the paper's method) unless marked *contact posterior*:", "",
          *_table(_T8_HEADER, _pad(table8_rows(docs), 5), sources=sources)]
    geo = contact_rows(docs)
    contact = ([f"At the unfilmed joints, against the campaign's true patterns ({run}; the numerical input is the "
                "ROM's own d1b frequencies with the true patterns, the experimental input the measured ones):", "",
                *_table(_METHODS_HEADER, _pad(geo, len(_METHODS_HEADER) - 1), sources=sources)] if geo
               else ["No true patterns in this campaign: no contact check."])
    rom = rom_rows(docs)
    answer = "the contact posterior's" if lookup(s, "methods.posterior") is not None else "the k-NN's"
    rom_text = ([f"The paper's ROM (Eq. 19, rigid contact ties) and the updated ROM (in-situ corrections and "
                 f"contact stiffness fitted on the disk–one-blade tests only), {run}, with the run's answer "
                 f"({answer}) at the unfilmed joints:", "",
                 *_table(_ROM_HEADER, rom, sources=sources)]
                if rom else ["The updated ROM did not run (`--rom paper`)."])
    resp = response_rows(docs)
    response = ([f"The mistuning amplification factor (AF) per family and engine order ({run}; `summary.json:"
                 "response`), against the truth twin's own (same force, damping and band rule):", "",
                 *_table(_RESPONSE_HEADER, _pad(resp, len(_RESPONSE_HEADER) - 1), sources=sources)]
                if resp else ["No truth AF in this campaign: no check of the amplification factor."])
    perf = [f"{_machine(docs)}; each figure from the command beside it, with the reference it measures in the "
            "same run.", "", *_table(_PERF_HEADER, performance_rows(docs), with_command=True, sources=sources)]
    return {"table8": "\n".join(t8), "contact": "\n".join(contact), "rom": "\n".join(rom_text),
            "response": "\n".join(response), "performance": "\n".join(perf)}


def _machine(docs: dict) -> str:
    cpus = lookup(docs.get("bench_run.json", {}), "cpu_count")
    return f"{cpus}-core machine, default model" if cpus else "Default model"


def _width_section(docs: dict) -> list[str]:
    rows = width_rows(docs)
    if not rows:
        return []
    return ["## What the disk–one-blade data pin down", "",
            "Each quantity's 90 % interval width under the contact posterior over its width under the prior, median "
            "over the unfilmed joints: 1 means the disk–one-blade tests say nothing about it (docs/identify.md).", "",
            *_table(_WIDTH_HEADER, rows), ""]


def render_results(docs: dict) -> str:
    """The text of ``docs/results.md``."""
    blocks = readme_blocks(docs, sources=True)
    s = docs.get("summary.json", {})
    stages = s.get("stages", {})
    lines = ["# Current results", "",
             "Generated by `make results` from the JSON files in `docs/results/`; do not edit by hand. Each "
             "figure's file and key is in its row's `source` column.", "",
             f"## Table 8 ({s.get('campaign', '?')})", "", blocks["table8"], "",
             "## Contact at the unfilmed joints", "", blocks["contact"], "",
             *_width_section(docs),
             "## The paper's ROM and the updated ROM", "", blocks["rom"], "",
             "## The amplification factor", "", blocks["response"], "",
             "## Performance", "", blocks["performance"], "",
             "## The run these figures come from", "",
             f"- command: `{s.get('command', '?')}`; settings: `{json.dumps(s.get('settings', {}))}`",
             f"- stage nodes computed {stages.get('computed', '?')}, reused from the store "
             f"{stages.get('reused', '?')}; wall time {_shown([lookup(s, 'timings_s.total')], False)[0]} s "
             "(`summary.json:timings_s.total`)"]
    longest = list(stages.get("seconds", {}).items())[:8]
    if longest:
        lines.append("- the longest stage nodes, each node's own seconds (`summary.json:stages.seconds`): "
                     + ", ".join(f"`{name}` {sec:.0f}" for name, sec in longest))
    return "\n".join(lines) + "\n"


_BLOCK = re.compile(r"(<!-- results:(\w+) -->\n)(.*?)(<!-- /results:\2 -->)", re.S)


def update_readme(text: str, blocks: dict[str, str]) -> str:
    """``text`` with each ``<!-- results:NAME -->…<!-- /results:NAME -->`` block replaced by ``blocks[NAME]``."""
    return _BLOCK.sub(lambda m: m.group(1) + blocks.get(m.group(2), m.group(3).rstrip("\n")) + "\n" + m.group(4),
                      text)


def load_docs(folder: Path) -> dict:
    """Every JSON file of ``folder`` by file name; one clear error for a file that is not JSON."""
    docs = {}
    for name in ["summary.json", *BENCHMARKS.values()]:
        path = folder / name
        if path.exists():
            try:
                docs[name] = json.loads(path.read_text())
            except (OSError, ValueError) as exc:
                raise SystemExit(f"error: {path}: not a JSON document ({exc})") from None
    if "summary.json" not in docs:
        raise SystemExit(f"error: {folder / 'summary.json'}: missing (copy a run's summary.json there)")
    return docs


def main(argv: list[str] | None = None) -> int:
    """``python -m bladetwin.results_doc [FOLDER] [--readme README.md]``: write ``docs/results.md``."""
    import argparse

    ap = argparse.ArgumentParser(description="Write docs/results.md (and the README's figures) from JSON files.")
    ap.add_argument("folder", nargs="?", default="docs/results", type=Path)
    ap.add_argument("--out", default="docs/results.md", type=Path)
    ap.add_argument("--readme", default=None, type=Path, help="also update this README's results blocks")
    args = ap.parse_args(argv)
    docs = load_docs(args.folder)
    with atomic_path(args.out) as tmp:
        tmp.write_text(render_results(docs))
    print(f"wrote {args.out}", file=sys.stderr)
    if args.readme:
        text = args.readme.read_text()
        with atomic_path(args.readme) as tmp:
            tmp.write_text(update_readme(text, readme_blocks(docs)))
        print(f"updated {args.readme}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
