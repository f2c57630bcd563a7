"""The runner: executes a :class:`~bladetwin.stages.graph.Pipeline` by its dependencies (design §2.1, §8.17).

Nodes whose output is in the store are not run. The others run as soon as their inputs exist: ``where="worker"``
nodes on a :class:`concurrent.futures.ProcessPoolExecutor` (one BLAS thread each, so ``workers`` nodes share the
cores), ``where="parent"`` ones here. Among ready nodes the one with the longest chain of nodes after it goes
first (:meth:`~bladetwin.stages.graph.Pipeline.chain_lengths`).

Forking after MKL (design §8.17): once a process has run MKL's OpenMP team (a threaded Pardiso phase), a child
forked from it that enters one waits forever. The pool therefore forks at the start of :meth:`Runner.run`,
before any node runs, and parent nodes never factorize: the reductions and solves are all worker nodes. The
run's sources (the FE model, the campaign) are handed to the workers through the fork, not pickled.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass

from ..user_warnings import emit, recording, unique
from .graph import Node, Pipeline
from .store import Store, content_key, node_key

__all__ = ["Source", "Runner", "Results", "RunStats"]

_MISSING = object()
#: Values the workers inherit through the fork, by key (set just before the pool forks).
_INHERITED: dict[str, object] = {}
#: A worker's loaded store entries, by path: a model is read once per worker, not once per node.
_LOADED: dict[str, object] = {}
_SINGLE_THREAD = False


@dataclass(frozen=True, eq=False)
class Source:
    """A value given to a run, with the key nodes downstream hash (``None``: hash its content)."""

    value: object
    key: str | None = None


@dataclass
class _State:
    key: str | None = None
    status: str = "pending"  # pending → running → done; or stored (found in the store)
    value: object = _MISSING


@dataclass(frozen=True)
class RunStats:
    """What a run did: nodes computed (by name) and nodes found in the store."""

    computed: tuple[str, ...]
    reused: tuple[str, ...]


def _init_worker(single: bool) -> None:
    global _SINGLE_THREAD
    _SINGLE_THREAD = single
    _LOADED.clear()  # a worker reads the entries of its own run only
    # Ctrl-C is the parent's to handle: it stops the workers itself, so they print no traceback of their own.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()


def _die_with_parent() -> None:
    """On Linux, a worker whose parent is killed (SIGKILL: no chance to stop it) is killed too, not orphaned."""
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # 1: PR_SET_PDEATHSIG


def _stop(pool: ProcessPoolExecutor, others: set[int]) -> None:
    """Stop the workers now (an error or Ctrl-C in this process): no node is left to finish its job.

    ``others`` are the process ids of this process's children from before the pool: they are not its workers.
    The store stays consistent: every entry is written to a temporary file and renamed, so a killed node
    leaves nothing behind, and a rerun computes it again.
    """
    # concurrent.futures has no public call that stops running workers (shutdown() would wait for the running
    # nodes: minutes); its workers are multiprocessing children, which multiprocessing lists.
    for proc in multiprocessing.active_children():
        if proc.pid not in others:
            proc.terminate()
    pool.shutdown(wait=False, cancel_futures=True)


def _resolve(spec: tuple):
    kind, ref = spec
    if kind == "v":
        return ref
    if kind == "i":
        return _INHERITED[ref]
    if ref not in _LOADED:
        from .codec import load

        _LOADED[ref] = load(ref)
    return _LOADED[ref]


def _work(func: Callable, args: dict, params: dict, path: str) -> tuple[float, list[str]]:
    """A worker node: resolve its inputs, compute, store the output with the warnings it raised; returns the
    seconds it computed and those warnings."""
    from threadpoolctl import threadpool_limits

    from .codec import save

    kwargs = {k: _resolve(s) for k, s in args.items()}
    t = time.perf_counter()
    with threadpool_limits(1 if _SINGLE_THREAD else None), recording() as texts:
        value = func(**kwargs, **params)
    seconds = time.perf_counter() - t
    found = unique(texts)
    save(path, value, found)
    return seconds, found


class Results(Mapping):
    """The run's outputs by name; stored ones are read on first access."""

    def __init__(self, runner: Runner, names: Iterable[str]) -> None:
        self._runner, self._names = runner, list(names)

    def __getitem__(self, name: str):
        return self._runner.value(name)

    def __iter__(self):
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def key(self, name: str) -> str:
        return self._runner.state[name].key


class Runner:
    """Runs pipelines against a :class:`Store`.

    Parameters
    ----------
    store : Store
    workers : int
        Worker processes; with 1 (or without ``fork``) every node runs in this process.
    say : callable
        Progress messages.
    """

    def __init__(self, store: Store, workers: int = 2, say: Callable[[str], None] = lambda m: None) -> None:
        self.store, self.workers, self.say = store, int(workers), say
        self.state: dict[str, _State] = {}
        self.fillers: set[str] = set()
        self._filling = False
        #: Problems with the store itself (an unreadable entry, recomputed), for the user.
        self.warnings: list[str] = []
        #: The user warnings each node raised when it was computed (now, or when its stored entry was).
        self.node_warnings: dict[str, list[str]] = {}
        self._emitted: set[str] = set()
        self.computed: list[str] = []
        self.reused: list[str] = []
        #: Seconds each computed node took (in its process).
        self.seconds: dict[str, float] = {}
        self._finished_keys: set[tuple[str, str]] = set()
        self._running_keys: set[tuple[str, str]] = set()

    # ---------------------------------------------------------------------------------------------- values
    def value(self, name: str):
        s = self.state[name]
        if s.value is _MISSING:
            if s.status not in ("done", "stored"):
                raise KeyError(f"{name}: not computed")
            s.value = self.store.load(self.pipeline[name].func_id, s.key)
        return s.value

    def _spec(self, name: str) -> tuple:
        if name in self.sources:
            return ("i", self.state[name].key)
        node = self.pipeline[name]
        if node.stored:  # by path, even if loaded here: a worker reads a model once, it is never pickled per node
            return ("s", str(self.store.path(node.func_id, self.state[name].key)))
        return ("v", self.value(name))

    # ---------------------------------------------------------------------------------------------- keys
    def _assign_keys(self, nodes: list[Node]) -> None:
        for n in nodes:
            s = self.state[n.name]
            if s.status == "pending" and n.stored and (n.func_id, s.key) in self._finished_keys:
                s.status = "stored"  # a twin node (another campaign's) computed it in this run
                self.reused.append(n.name)
                self._warned(n.name, self.store.warnings(n.func_id, s.key))
            if s.key is not None or n.content_key:
                continue
            keys = {a: self.state[src].key for a, src in n.inputs.items()}
            if any(k is None for k in keys.values()):
                continue
            s.key = node_key(n.func_id, n.version, dict(n.params), keys)
            if s.status == "pending" and n.stored and self.store.has(n.func_id, s.key):
                problem = self.store.check(n.func_id, s.key)
                if problem is None:
                    s.status = "stored"
                    self.reused.append(n.name)
                    self._warned(n.name, self.store.warnings(n.func_id, s.key))
                else:
                    self.warnings.append(problem)
                    emit(problem)

    def _demanded(self, name: str, memo: dict) -> bool:
        if name not in memo:
            memo[name] = False  # no cycles in a pipeline; guards the recursion all the same
            s = self.state[name]
            wanted = name in self.targets or (self._filling and name in self.fillers)
            memo[name] = s.status == "pending" and (wanted or any(
                self.state[c].status == "pending"
                and ((self.state[c].key is None and not self.pipeline[c].content_key) or self._demanded(c, memo))
                for c in self.consumers.get(name, ())))
        return memo[name]

    def _available(self, name: str) -> bool:
        return self.state[name].status in ("done", "stored")

    # ---------------------------------------------------------------------------------------------- running
    def _finish(self, node: Node, value=_MISSING, seconds: float = 0.0) -> None:
        s = self.state[node.name]
        s.status = "done"
        self.seconds[node.name] = seconds
        self._finished_keys.add((node.func_id, s.key))
        self._running_keys.discard((node.func_id, s.key))
        if value is not _MISSING:
            s.value = value
        if node.content_key:
            s.key = content_key(s.value)
        self.computed.append(node.name)

    def _warned(self, name: str, texts: list[str]) -> None:
        """Keep a node's warnings and print each the first time this run meets it."""
        self.node_warnings[name] = list(texts)
        self.emit(texts)

    def emit(self, texts: Iterable[str]) -> list[str]:
        """Print each warning the first time this runner meets it (one line on stderr); returns ``texts``."""
        texts = list(texts)
        for text in texts:
            if text not in self._emitted:
                self._emitted.add(text)
                emit(text)
        return texts

    def warnings_of(self, prefix: str = "") -> list[str]:
        """The store's problems, then the warnings of the nodes named ``prefix…``, in pipeline order, once each."""
        names = [n for n in self.pipeline.names() if n.startswith(prefix) and n in self.node_warnings]
        return unique([*self.warnings, *(t for n in names for t in self.node_warnings[n])])

    def _run_here(self, node: Node) -> None:
        kwargs = {a: self.value(src) for a, src in node.inputs.items()}
        t = time.perf_counter()
        with recording() as texts:
            value = node.func(**kwargs, **node.params)
        seconds = time.perf_counter() - t
        if node.stored:
            self.store.save(node.func_id, self.state[node.name].key, value, unique(texts))
        self._warned(node.name, unique(texts))
        self._finish(node, value, seconds)
        if node.where == "worker":
            self.say(f"  {node.label or node.name} ({seconds:.1f} s)")

    def _submit(self, pool: ProcessPoolExecutor, node: Node) -> Future:
        args = {a: self._spec(src) for a, src in node.inputs.items()}
        path = str(self.store.path(node.func_id, self.state[node.name].key))
        self.state[node.name].status = "running"
        self._running_keys.add((node.func_id, self.state[node.name].key))
        return pool.submit(_work, node.func, args, dict(node.params), path)

    def run(self, pipeline: Pipeline, targets: Iterable[str], sources: Mapping[str, Source],
            fillers: Iterable[str] = ()) -> Results:
        """Compute ``targets`` (and what they need), reusing the store; returns every needed output.

        ``fillers`` only fill idle workers while the targets are computed: a ready filler starts after every other
        ready node, and none starts once the targets are done (those left are computed by a later run). Why:
        ``bladetwin run`` fits the disk–one-blade tests beside the calibration, which the whole run waits for;
        ranked as equals (chains of one node each), the bundled campaign's 18 fits went first and the
        calibration started 9 s late, after the last of them.
        """
        self.pipeline, self.targets, self.fillers = pipeline, set(targets), set(fillers) - set(targets)
        self.sources = dict(sources)
        nodes = pipeline.needed_for(self.targets | self.fillers, self.sources)
        needed = {n.name for n in nodes}
        self.chain = pipeline.chain_lengths(needed)
        self.chain.update({n: 0 for n in self.fillers if not self._feeds(n, needed - self.fillers)})
        self.consumers = {k: [c for c in v if c in needed] for k, v in pipeline.consumers().items()}
        for name, src in self.sources.items():
            key = src.key if src.key is not None else content_key(src.value)
            self.state[name] = _State(key, "done", src.value)
        for n in nodes:
            self.state.setdefault(n.name, _State())
        others = {proc.pid for proc in multiprocessing.active_children()}
        pool = self._pool()
        try:
            self._loop(nodes, pool)
        except BaseException:
            if pool is not None:
                _stop(pool, others)
            raise
        else:
            if pool is not None:
                pool.shutdown(wait=True)
        finally:
            _INHERITED.clear()
        return Results(self, [n.name for n in nodes] + list(self.sources))

    def _feeds(self, name: str, others: set[str]) -> bool:
        """Whether a node of ``others`` takes ``name`` as an input (then it is no mere filler)."""
        return any(name in self.pipeline[o].inputs.values() for o in others)

    def _pool(self) -> ProcessPoolExecutor | None:
        if self.workers < 2 or "fork" not in multiprocessing.get_all_start_methods():
            return None
        _INHERITED.clear()  # this run's sources only, whatever a run before it left
        _INHERITED.update({self.state[n].key: s.value for n, s in self.sources.items()})
        return ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("fork"),
                                   initializer=_init_worker, initargs=(True,))

    def _loop(self, nodes: list[Node], pool: ProcessPoolExecutor | None) -> None:
        running: dict[Future, Node] = {}
        t0 = time.perf_counter()
        while True:
            self._assign_keys(nodes)
            self._filling = bool(self.fillers) and not all(self._available(t) for t in self.targets)
            memo: dict = {}
            # a node whose twin (same function and key) is running waits for it, then reads its entry
            ready = sorted((n for n in nodes if self._demanded(n.name, memo)
                            and (n.func_id, self.state[n.name].key) not in self._running_keys
                            and all(self._available(src) for src in n.inputs.values())),
                           key=lambda n: -self.chain[n.name])
            here = [n for n in ready if n.where == "parent" or pool is None]
            if here:
                self._run_here(here[0])  # then look again: its output may make others stored or ready
                continue
            for n in ready:
                if len(running) >= self.workers:
                    break
                if (n.func_id, self.state[n.name].key) not in self._running_keys:  # a twin just went out
                    running[self._submit(pool, n)] = n
            if not running:
                missing = [t for t in self.targets if not self._available(t)]
                if missing:
                    raise RuntimeError(f"pipeline stalled before {missing}")
                return
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for fut in done:
                node = running.pop(fut)
                seconds, texts = fut.result()  # a node's own error surfaces here
                self._warned(node.name, texts)
                self._finish(node, seconds=seconds)
                self.say(f"  {node.label or node.name} ({time.perf_counter() - t0:.1f} s)")
