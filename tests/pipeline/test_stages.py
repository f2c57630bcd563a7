"""The stage graph's machinery (bladetwin.stages): codec, store, runner, against direct computation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from bladetwin.stages import Node, Pipeline, Runner, Source, Store, codec
from rom.contact import ContactPattern

CALLS: list[str] = []


def add(a, b, *, shift=0.0):
    CALLS.append("add")
    return np.asarray(a) + np.asarray(b) + shift


def double(x):
    CALLS.append("double")
    return 2 * np.asarray(x)


def total(x):
    CALLS.append("total")
    return float(np.sum(x))


def _pipeline(shift: float = 0.0) -> Pipeline:
    return Pipeline([Node("s", add, {"a": "a", "b": "b"}, {"shift": shift}, where="parent"),
                     Node("d", double, {"x": "s"}),
                     Node("t", total, {"x": "d"}, where="parent")])


def _sources(a=(1.0, 2.0), b=(3.0, 4.0)) -> dict:
    return {"a": Source(np.array(a)), "b": Source(np.array(b))}


def test_codec_round_trips_dataclasses_sparse_and_keyed_maps(tmp_path):
    pat = ContactPattern(np.eye(3, 7, dtype=bool), np.ones((3, 7), bool))
    value = {1: [pat, (2, "x")], "K": sp.random(6, 6, density=0.3, random_state=1, format="csr"),
             "z": np.array([1 + 2j]), "none": None, "f": 1.5}
    back = codec.load(codec.save(tmp_path / "v.npz", value))
    assert np.array_equal(back[1][0].L, pat.L) and np.array_equal(back[1][0].R, pat.R)
    assert back[1][1] == (2, "x") and back["none"] is None and back["f"] == 1.5
    assert (back["K"] != value["K"]).nnz == 0 and back["z"][0] == 1 + 2j


def test_codec_refuses_foreign_types_and_names_a_damaged_file(tmp_path):
    @dataclasses.dataclass
    class Foreign:
        x: int

    with pytest.raises(codec.CodecError, match="not a type"):
        codec.save(tmp_path / "f.npz", Foreign(1))
    path = codec.save(tmp_path / "ok.npz", {"a": np.arange(1000.0)})
    path.write_bytes(path.read_bytes()[:200])
    with pytest.raises(codec.CodecError, match=str(path)):
        codec.load(path)


@pytest.mark.parametrize("workers", [1, 2])
def test_runner_computes_by_dependencies_and_reuses_the_store(tmp_path, workers):
    store = Store(tmp_path)
    CALLS.clear()
    res = Runner(store, workers).run(_pipeline(), ["t"], _sources())
    assert res["t"] == 2 * (1 + 3 + 2 + 4)  # the direct computation
    again = Runner(store, workers)
    res2 = again.run(_pipeline(), ["t"], _sources())
    assert res2["t"] == res["t"] and again.computed == [] and set(again.reused) == {"s", "d", "t"}


def test_a_changed_parameter_recomputes_exactly_what_depends_on_it(tmp_path):
    store = Store(tmp_path)
    Runner(store, 1).run(_pipeline(), ["t"], _sources())
    r = Runner(store, 1)
    assert r.run(_pipeline(shift=1.0), ["t"], _sources())["t"] == 2 * (1 + 3 + 2 + 4 + 2)
    assert r.computed == ["s", "d", "t"]
    r = Runner(store, 1)
    r.run(_pipeline(), ["d"], _sources())
    assert r.computed == [] and r.reused == ["s", "d"]  # a target needs nothing beyond it


def test_content_keyed_nodes_share_what_follows_them(tmp_path):
    def pipe():
        return Pipeline([Node("s", add, {"a": "a", "b": "b"}, where="parent", stored=False, content_key=True),
                         Node("d", double, {"x": "s"})])
    store = Store(tmp_path)
    Runner(store, 1).run(pipe(), ["d"], _sources())
    r = Runner(store, 1)  # other inputs, the same sum: the node after it is found in the store
    assert np.array_equal(r.run(pipe(), ["d"], _sources((2.0, 1.0), (2.0, 5.0)))["d"], [8.0, 12.0])
    assert r.computed == ["s"] and r.reused == ["d"]


def test_a_damaged_entry_is_recomputed_with_a_warning(tmp_path):
    store = Store(tmp_path)
    Runner(store, 1).run(_pipeline(), ["t"], _sources())
    entry = next((tmp_path / "nodes" / "double").glob("*.npz"))
    entry.write_bytes(b"")
    r = Runner(store, 1)
    assert r.run(_pipeline(), ["d"], _sources())["d"].tolist() == [8.0, 12.0]
    assert r.computed == ["d"] and any(str(entry) in w for w in r.warnings)


def test_fillers_wait_for_every_other_ready_node_and_none_starts_once_the_targets_are_done(tmp_path):
    """A filler (``Runner.run(fillers=...)``) goes after every other ready node, a filler that a target needs is
    computed as any input, and with one worker (nothing idle) no filler runs at all."""
    def pipe():
        return Pipeline([*_pipeline(), Node("f", double, {"x": "b"}), Node("g", total, {"x": "b"})])
    CALLS.clear()
    r = Runner(Store(tmp_path), 1)
    assert r.run(pipe(), ["t"], _sources(), fillers=["f", "g"])["t"] == 20.0
    assert CALLS == ["add", "double", "total"] and r.computed == ["s", "d", "t"]
    r = Runner(Store(tmp_path), 1)
    r.run(pipe(), ["t"], _sources(), fillers=["d", "f"])  # "d" feeds the target: needed, not a filler
    assert r.computed == [] and set(r.reused) == {"s", "d", "t"}


def test_a_filler_takes_a_worker_that_the_targets_leave_idle(tmp_path):
    """Two workers, one ready target node: the ready filler starts beside it, and both are computed."""
    pipe = Pipeline([*_pipeline(), Node("f", double, {"x": "b"})])
    r = Runner(Store(tmp_path), 2)
    r.run(pipe, ["t"], _sources(), fillers=["f"])
    assert set(r.computed) == {"s", "d", "t", "f"} and r.computed.index("s") == 0
    assert np.array_equal(r.value("f"), [6.0, 8.0])


def halve_with_warning(x):
    import warnings

    warnings.warn("halved:\n  on purpose", UserWarning, stacklevel=1)
    return 0.5 * np.asarray(x)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_stages_warnings_are_kept_with_its_entry_and_reported_when_reused(tmp_path, capfd, workers):
    """A warning raised while a stage computes (here or on a worker) is printed once as one line, and comes back
    from the store with the entry: a rerun that reuses the stage reports the same warnings."""
    def pipe():
        return Pipeline([Node("s", add, {"a": "a", "b": "b"}, where="parent"),
                         Node("h", halve_with_warning, {"x": "s"}), Node("d", double, {"x": "h"})])
    store = Store(tmp_path)
    first = Runner(store, workers)
    first.run(pipe(), ["d"], _sources())
    err = capfd.readouterr().err
    assert err.count("bladetwin: warning: halved: on purpose\n") == 1 and "UserWarning" not in err
    again = Runner(store, workers)
    again.run(pipe(), ["d"], _sources())
    assert again.computed == [] and again.warnings_of() == first.warnings_of() == ["halved: on purpose"]
    assert "halved: on purpose" in capfd.readouterr().err


def test_a_pipeline_is_data_that_can_be_listed_and_cut():
    p = _pipeline()
    assert p.names() == ["s", "d", "t"]
    assert [n.name for n in p.needed_for(["d"], sources=["a", "b"])] == ["s", "d"]
    q = p.prefixed("c1")
    assert q.names() == ["c1/s", "c1/d", "c1/t"] and dict(q["c1/d"].inputs) == {"x": "c1/s"}
    with pytest.raises(ValueError, match="two nodes"):
        Pipeline([Node("s", add), Node("s", add)])
