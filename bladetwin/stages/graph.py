"""The pipeline as data: named nodes with declared inputs and one output each (design §2.1).

A :class:`Node` wraps a plain function. Its inputs are the names of other nodes' outputs (or of the run's
*sources*, values given to the runner), its parameters are keyword arguments fixed when the graph is built.
A :class:`Pipeline` is an ordered collection of nodes; it can be listed, cut to the nodes a target needs, and
merged with another campaign's pipeline.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = ["Node", "Pipeline"]


@dataclass(frozen=True, eq=False)
class Node:
    """One stage: ``output = func(**{name: value of inputs[name]}, **params)``.

    Attributes
    ----------
    name : str
        The output's name, unique in a pipeline (e.g. ``"ema/blade_01"``); a campaign's are declared in
        :mod:`~bladetwin.stages.names`.
    func : callable
        A module-level function (worker processes import it by name). It computes and returns; it never
        draws or writes files.
    inputs : mapping str → str
        Argument name → the name of the node (or source) whose output it receives.
    params : mapping
        Fixed keyword arguments; they enter the node's key.
    version : int
        Bump when ``func`` changes its result for the same inputs (a new key: old entries are not read).
    where : ``"worker"`` or ``"parent"``
        Long numerical work runs on a worker process; quick steps (and those that need a Dask client)
        run in the parent.
    stored : bool
        Keep the output in the store under its key; otherwise it is recomputed whenever a run needs it.
    content_key : bool
        The output's key is the hash of the value itself, not of the inputs' keys: nodes downstream of it
        are then found in the store whenever their inputs are equal, however they were reached.
    label : str
        What progress messages call it.
    """

    name: str
    func: Callable
    inputs: Mapping[str, str] = field(default_factory=dict)
    params: Mapping[str, object] = field(default_factory=dict)
    version: int = 1
    where: str = "worker"
    stored: bool = True
    content_key: bool = False
    label: str = ""

    def __post_init__(self) -> None:
        if self.where not in ("worker", "parent"):
            raise ValueError(f"node {self.name}: where = {self.where!r}, expected 'worker' or 'parent'")
        object.__setattr__(self, "inputs", MappingProxyType(dict(self.inputs)))
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))

    @property
    def func_id(self) -> str:
        return f"{self.func.__module__}.{self.func.__qualname__}"


class Pipeline:
    """Nodes by output name, in the order they were added (which must respect their dependencies)."""

    def __init__(self, nodes: Iterable[Node] = ()) -> None:
        self._nodes: dict[str, Node] = {}
        for n in nodes:
            self.add(n)

    def add(self, node: Node) -> Node:
        if node.name in self._nodes:
            raise ValueError(f"two nodes named {node.name!r}")
        self._nodes[node.name] = node
        return node

    def __contains__(self, name: str) -> bool:
        return name in self._nodes

    def __getitem__(self, name: str) -> Node:
        return self._nodes[name]

    def __iter__(self):
        return iter(self._nodes.values())

    def __len__(self) -> int:
        return len(self._nodes)

    def names(self) -> list[str]:
        return list(self._nodes)

    def needed_for(self, targets: Iterable[str], sources: Iterable[str] = ()) -> list[Node]:
        """The nodes the targets depend on (themselves included), in dependency order."""
        sources, need, stack = set(sources), set(), list(targets)
        while stack:
            name = stack.pop()
            if name in need or name in sources:
                continue
            if name not in self._nodes:
                raise KeyError(f"no node or source named {name!r}")
            need.add(name)
            stack.extend(self._nodes[name].inputs.values())
        return [n for n in self._nodes.values() if n.name in need]

    def chain_lengths(self, names: Iterable[str]) -> dict[str, int]:
        """Each of ``names``: the most nodes on a chain from it to the end of the pipeline within ``names``
        (itself counted).

        The runner starts the ready node with the longest chain first, so that the longest chains (the
        critical path, counted in nodes: a cold run has no durations to weigh them by) never wait.
        """
        names = set(names)
        below: dict[str, list[str]] = {n: [] for n in names}
        for n in self._nodes.values():
            if n.name in names:
                for src in n.inputs.values():
                    if src in below:
                        below[src].append(n.name)
        length: dict[str, int] = {}
        for name in reversed([n for n in self._nodes if n in names]):  # consumers come after their inputs
            length[name] = 1 + max((length[c] for c in below[name]), default=0)
        return length

    def consumers(self) -> dict[str, list[str]]:
        """Output name → the nodes that take it as an input."""
        out: dict[str, list[str]] = {n: [] for n in self._nodes}
        for n in self._nodes.values():
            for src in n.inputs.values():
                out.setdefault(src, []).append(n.name)
        return out

    def prefixed(self, prefix: str, shared: Mapping[str, str] = MappingProxyType({})) -> Pipeline:
        """A copy with every name under ``prefix/`` (several campaigns in one run); ``shared`` keeps names."""
        def rename(x: str) -> str:
            return shared.get(x, f"{prefix}/{x}")

        return Pipeline(Node(rename(n.name), n.func, {k: rename(v) for k, v in n.inputs.items()}, n.params,
                             n.version, n.where, n.stored, n.content_key, n.label or n.name)
                        for n in self._nodes.values())
