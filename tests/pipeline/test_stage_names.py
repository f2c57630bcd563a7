"""Every stage name has one owner: ``bladetwin.stages.names`` (issue 45).

The graph's nodes and sources are named in the catalog only; whatever adds, wires or reads them spells them
through it. :func:`spelled_names` finds the names spelled as string literals anywhere else in ``bladetwin/``, by
this rule (docstrings are never looked at):

- **Family names** (``ema/…``, ``full/…``, ``refine/…``…: a prefix of the graph's names that contain a ``/``):
  any string constant, or constant part of an f-string, that starts with a family's prefix. Such a string
  names nodes and nothing else.
- **Plain names** (``dataset``, ``baseline``, ``campaign``…) are also ordinary words: a dict key, an argument's
  name, a ``summary.json`` key or a case name may equal one. A constant equal to a plain name counts only where
  it is used as a node's name:

  * the name of a ``Node(...)`` (first argument or ``name=``);
  * a dict literal's value (or a branch of a conditional value) in a module that builds nodes (calls ``Node``):
    the input mappings and the tables of names wired into them. Dict *keys* are argument names;
  * a lookup on the runner's results: the index of ``res[…]``, ``results[…]``, ``sources[…]`` or ``src[…]``
    or of a call's result (``runner.run(…)[…]``), the left side of ``… in res``, the first argument of
    ``res.get(…)``, and the first argument of any ``.value(…)`` or ``.key(…)`` (the runner's own lookups);
  * an operand of ``+`` or a constant part of an f-string (a name built with a campaign's prefix);
  * an element of a list, tuple or set literal whose elements are all names or family prefixes, given to a call
    or as a dict literal's value (the targets of a run, the groups of ``STAGE_GROUPS``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from bladetwin.campaign import read_campaign
from bladetwin.stages import names
from bladetwin.stages.campaign_graph import RunOptions, campaign_pipeline, campaign_sources
from bladetwin.stages.runner import Source

REPO = Path(__file__).resolve().parents[2]
CATALOG = REPO / "bladetwin" / "stages" / "names.py"
#: The variables that hold the runner's results or a run's sources, by the package's convention.
RESULTS = {"res", "results", "sources", "src"}
#: Option sets whose graphs, together, have every node a run can have.
OPTIONS = ({}, {"method": "knn"}, {"method": "posterior", "rom": "paper", "calibrate": False})


def graph_names(campaign_dir: Path = REPO / "measurements" / "academic") -> set[str]:
    """Every node and source name of the campaign's graphs (:data:`OPTIONS`)."""
    campaign = read_campaign(campaign_dir)
    found: set[str] = set()
    for kw in OPTIONS:
        opts = RunOptions(**kw)
        found |= set(campaign_pipeline(campaign, opts).names())
        found |= set(campaign_sources(campaign, Source(None, "model"), None, opts))
    return found


def _is_results(node: ast.AST) -> bool:
    return isinstance(node, ast.Call) or (isinstance(node, ast.Name) and node.id in RESULTS)


def _is_node_call(node: ast.AST) -> bool:
    return isinstance(node, ast.Call) and (getattr(node.func, "id", None) == "Node"
                                           or getattr(node.func, "attr", None) == "Node")


class _Scan:
    """One module's string literals that name nodes (the module docstring's rule)."""

    def __init__(self, tree: ast.Module, plain: set[str], families: tuple[str, ...]) -> None:
        self.plain, self.families = plain, families
        self.parent = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
        self.builds_nodes = any(_is_node_call(n) for n in ast.walk(tree))
        self.docs = {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr)}
        self.hits = [(n.lineno, n.value) for n in ast.walk(tree) if isinstance(n, ast.Constant)
                     and isinstance(n.value, str) and id(n) not in self.docs and self._names_a_node(n)]

    def _is_name(self, node: ast.AST) -> bool:
        return isinstance(node, ast.Constant) and isinstance(node.value, str) and (
            node.value in self.plain or node.value.startswith(self.families))

    def _names_a_node(self, const: ast.Constant) -> bool:
        if const.value.startswith(self.families):
            return True
        return const.value in self.plain and self._used_as_name(const)

    def _used_as_name(self, const: ast.Constant) -> bool:
        up = self.parent.get(const)
        if isinstance(up, ast.keyword):
            return up.arg == "name" and _is_node_call(self.parent.get(up))
        if isinstance(up, ast.Call):
            method = getattr(up.func, "attr", None)
            first = bool(up.args) and up.args[0] is const
            return first and (_is_node_call(up) or method in ("value", "key")
                              or (method == "get" and _is_results(up.func.value)))
        if isinstance(up, ast.Subscript):
            return up.slice is const and _is_results(up.value)
        if isinstance(up, ast.Compare):
            return up.left is const and isinstance(up.ops[0], ast.In | ast.NotIn) and _is_results(up.comparators[0])
        if isinstance(up, ast.BinOp | ast.JoinedStr):
            return isinstance(up, ast.JoinedStr) or isinstance(up.op, ast.Add)
        if isinstance(up, ast.List | ast.Tuple | ast.Set):
            return all(map(self._is_name, up.elts)) and (isinstance(self.parent.get(up), ast.Call)
                                                         or self._dict_value(up, anywhere=True))
        return self._dict_value(const)

    def _dict_value(self, node: ast.AST, anywhere: bool = False) -> bool:
        up = self.parent.get(node)
        while isinstance(up, ast.IfExp) and node is not up.test:
            node, up = up, self.parent.get(up)
        return (self.builds_nodes or anywhere) and isinstance(up, ast.Dict) and any(v is node for v in up.values)


def spelled_names(root: Path, graph: set[str]) -> dict[str, list[tuple[int, str]]]:
    """Module (relative to ``root``'s parent) → (line, literal) of each node name spelled outside the catalog."""
    plain = {n for n in graph if "/" not in n}
    families = tuple(sorted({n.split("/", 1)[0] + "/" for n in graph if "/" in n}))
    out = {}
    for path in sorted(root.rglob("*.py")):
        if path.name == CATALOG.name and path.parent.name == "stages":
            continue
        hits = _Scan(ast.parse(path.read_text(encoding="utf-8")), plain, families).hits
        if hits:
            out[str(path.relative_to(root.parent))] = sorted(hits)
    return out


@pytest.fixture(scope="module")
def graph() -> set[str]:
    return graph_names()


def test_no_node_name_is_spelled_outside_the_catalog(graph):
    found = spelled_names(REPO / "bladetwin", graph)
    assert not found, "node names spelled as literals (use bladetwin.stages.names): " + "; ".join(
        f"{path}: " + ", ".join(f"{line}: {value!r}" for line, value in hits) for path, hits in found.items())


def test_the_catalog_declares_every_name_of_the_graph(graph):
    declared = {v for k, v in vars(names).items() if k.isupper() and isinstance(v, str)}
    assert {n for n in graph if "/" in n} and {n.split("/", 1)[0] + "/" for n in graph if "/" in n} == \
        set(names.FAMILIES)
    assert not {n for n in graph if not n.startswith(names.FAMILIES)} - declared


def test_the_rule_finds_a_literal_lookup_and_spares_ordinary_words(tmp_path, graph):
    pkg = tmp_path / "bladetwin"
    pkg.mkdir()
    (pkg / "reader.py").write_text(
        '"""A reader: ``res["dataset"]`` in a docstring is not code."""\n'
        'def read(res, cases, n):\n'
        '    """``full/identified``."""\n'
        '    summary = {"dataset": res["dataset"], "baseline": cases["baseline"]}\n'
        '    return summary, res[f"ema/blade_{n:02d}"], "calibration" in res, ("A", "baseline")\n',
        encoding="utf-8")
    assert spelled_names(pkg, graph) == {"bladetwin/reader.py": [(4, "dataset"), (5, "calibration"),
                                                                 (5, "ema/blade_")]}


def test_the_parsers_read_back_what_the_catalog_builds():
    assert names.per_joint(names.refine("experimental_no_bias", 7), names.REFINE) == ("experimental_no_bias", 7)
    assert names.per_joint(names.posterior_joint("numerical", 12), names.POSTERIOR) == ("numerical", 12)
    assert names.per_joint(names.posterior_part(0), names.POSTERIOR) is None
    assert names.per_joint(names.POSTERIOR_PRIOR, names.POSTERIOR) is None
    assert names.answer_of(names.posterior_patterns("numerical")) == (True, "numerical")
    assert names.answer_of(names.patterns("experimental")) == (False, "experimental")
    assert names.answer_of(names.REFERENCE) is None
    assert names.members({names.full("a"): 1, names.DATASET: 2, names.full("b"): 3}, names.FULL) == {"a": 1, "b": 3}
