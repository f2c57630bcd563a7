"""The house's static limits (docs/design.md §6, §8.43), read from the source tree.

* no module over 500 lines, none over 400 in ``bladetwin/``;
* no function over 80 lines in ``ema``, ``rom``, ``identify``, ``lab`` or ``bladetwin``;
* no private name (leading underscore) imported from another module of the packages;
* no import cycle between the packages' modules, counting imports inside functions too (an import moved into a
  function hides a cycle from Python, not from a reader).
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("ema", "rom", "identify", "lab", "bladetwin")
MODULE_LINES = 500
BLADETWIN_MODULE_LINES = 400
FUNCTION_LINES = 80


def _modules() -> dict[str, Path]:
    """Dotted module name → file, for every module of the packages."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((REPO / pkg).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = path
    return out


MODULES = _modules()
TREES = {name: ast.parse(path.read_text(encoding="utf-8")) for name, path in MODULES.items()}


def _imports(name: str) -> list[tuple[str, str | None, int]]:
    """(imported module, imported name or None, line) of every import in module ``name``, absolute."""
    is_pkg = MODULES[name].name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    out = []
    for node in ast.walk(TREES[name]):
        if isinstance(node, ast.Import):
            out += [(a.name, None, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if node.level:
                mod = ".".join(base[: len(base) - node.level + 1] + ([mod] if mod else []))
            for a in node.names:
                sub = f"{mod}.{a.name}"
                out.append((sub, None, node.lineno) if sub in MODULES else (mod, a.name, node.lineno))
    return [(m, n, line) for m, n, line in out if m.split(".")[0] in PACKAGES]


def test_modules_are_short():
    long = {n: p.read_text(encoding="utf-8").count("\n") for n, p in MODULES.items()}
    over = {n: k for n, k in long.items()
            if k > (BLADETWIN_MODULE_LINES if n.startswith("bladetwin") else MODULE_LINES)}
    assert not over, f"modules over {MODULE_LINES} lines ({BLADETWIN_MODULE_LINES} in bladetwin/): {over}"


def test_functions_are_short():
    over = {}
    for name, tree in TREES.items():
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = node.end_lineno - node.lineno + 1
                if n > FUNCTION_LINES:
                    over[f"{name}.{node.name}"] = n
    assert not over, f"functions over {FUNCTION_LINES} lines: {over}"


def test_no_private_name_is_imported_across_modules():
    found = [f"{name}:{line} imports {mod}.{what}" for name in MODULES for mod, what, line in _imports(name)
             if what is not None and what.startswith("_") and not what.startswith("__") and mod != name]
    assert not found, "private names imported across modules: " + "; ".join(found)


def test_no_import_cycle():
    graph = {name: {m if m in MODULES else m.rsplit(".", 1)[0] for m, _, _ in _imports(name)} - {name}
             for name in MODULES}
    graph = {k: {m for m in v if m in MODULES and not k.startswith(m + ".")} for k, v in graph.items()}
    # a package's __init__ importing its own submodules is how a package exports; only module cycles count
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(n: str) -> None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph[n]):
            if state.get(m) == 1:
                cycles.append(stack[stack.index(m):] + [m])
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n)
    cycles = [c for c in cycles if not any(MODULES[m].name == "__init__.py" for m in c)]
    assert not cycles, "import cycles: " + "; ".join(" → ".join(c) for c in cycles[:5])
