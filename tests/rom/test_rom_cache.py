"""On-disk cache of reduced models: round trip, keys that change with every input, no pickle, atomic writes."""

import numpy as np
import pytest

from rom import cache
from rom.contact import ContactPattern
from rom.pattern_io import load_patterns, save_patterns

from . import rom_models


def _same(a, b):
    import dataclasses

    for f in dataclasses.fields(a):
        va, vb = getattr(a, f.name), getattr(b, f.name)
        if isinstance(va, np.ndarray) or isinstance(vb, np.ndarray):
            np.testing.assert_array_equal(va, vb)
        else:
            assert va == vb, f.name


def test_round_trip_keeps_every_field(tmp_path):
    for model in (rom_models.disk_cb(), rom_models.blade()):
        p = cache.save_model(tmp_path / "m.npz", model, key="abc")
        _same(model, cache.load_model(p, "abc"))
    with pytest.raises(ValueError, match="key mismatch"):
        cache.load_model(p, "other")


def test_cached_builds_once_and_reuses(tmp_path):
    calls = []

    def build():
        calls.append(1)
        return rom_models.blade()

    a = cache.cached("blade", "k" * 64, build, tmp_path)
    b = cache.cached("blade", "k" * 64, build, tmp_path)
    assert len(calls) == 1
    _same(a, b)
    assert [p.suffix for p in tmp_path.iterdir()] == [".npz"]  # no temporary files left behind


def test_key_changes_with_every_input():
    bd = rom_models.bladed_disk()
    K, M = bd.blade.K, bd.blade.M
    base = cache.hash_inputs("rubin", K, M, np.arange(5), 50)
    K2 = K.copy()
    K2.data[17] *= 1 + 1e-12
    variants = [
        cache.hash_inputs("rubin", K2, M, np.arange(5), 50),
        cache.hash_inputs("rubin", K, M * 2, np.arange(5), 50),
        cache.hash_inputs("rubin", K, M, np.arange(6), 50),
        cache.hash_inputs("rubin", K, M, np.arange(5), 49),
        cache.hash_inputs("craig_bampton", K, M, np.arange(5), 50),
    ]
    assert len({base, *variants}) == 6
    assert cache.hash_inputs("rubin", K.tocoo(), M, np.arange(5), 50) == base  # format-independent


def test_cached_reducers_hit_the_cache(tmp_path):
    bd = rom_models.bladed_disk(6)
    a = cache.cached_reduce_blade(bd, 10, cache_dir=tmp_path)
    b = cache.cached_reduce_blade(bd, 10, cache_dir=tmp_path)
    c = cache.cached_reduce_blade(bd, 11, cache_dir=tmp_path)
    _same(a, b)
    assert c.m == 11 and len(list(tmp_path.glob("*.npz"))) == 2


def test_object_arrays_are_refused(tmp_path):
    bad = tmp_path / "bad.npz"
    np.savez(bad, __kind__=np.array("RubinModel"), meta=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError):
        cache.load_model(bad)


def test_default_cache_dir_honours_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("BLADETWIN_CACHE", str(tmp_path / "c"))
    assert cache.default_cache_dir() == tmp_path / "c"
    monkeypatch.delenv("BLADETWIN_CACHE")
    assert cache.default_cache_dir().parts[-2:] == (".cache", "bladetwin")


def test_pattern_files_npz_and_text(tmp_path):
    rng = np.random.default_rng(0)
    pats = [ContactPattern.random((3, 7), 0.5, rng) for _ in range(3)]
    p = save_patterns(tmp_path / "p.npz", pats)
    assert load_patterns(p) == pats
    txt = tmp_path / "p.txt"
    L = "\n".join(",".join(str(int(v)) for v in row) for row in pats[0].L)
    R = "\n".join(" ".join(str(int(v)) for v in row) for row in pats[0].R)
    txt.write_text(f"# joint 1\n{L}\n\n{R}\n")
    assert load_patterns(txt) == [pats[0]]
    txt.write_text(L + "\n")
    with pytest.raises(ValueError, match="two grids"):
        load_patterns(txt)
    with pytest.raises(FileNotFoundError):
        load_patterns(tmp_path / "missing.npz")
