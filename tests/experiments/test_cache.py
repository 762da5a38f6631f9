"""ModelCache: a model is trained once per spec, stale or broken entries are rebuilt."""

from __future__ import annotations

import numpy as np

from rkmpc.experiments.cache import ModelCache, default_cache_dir, spec_key
from rkmpc.learning.koopman.model import KoopmanModel


def _linear_model(seed: int) -> KoopmanModel:
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(200, 2))
    U = rng.normal(size=(200, 1))
    X_next = X @ np.array([[0.9, 0.1], [0.0, 0.8]]).T + U @ np.array([[0.0, 0.5]])
    return KoopmanModel(None).fit(X, U, X_next)


class _Builder:
    def __init__(self) -> None:
        self.calls = 0

    def __call__(self) -> tuple[KoopmanModel, dict]:
        self.calls += 1
        return _linear_model(self.calls), {"fit_time_s": 0.5, "call": self.calls}


def test_second_lookup_is_a_hit_with_the_stored_info(tmp_path):
    cache = ModelCache(tmp_path)
    build = _Builder()
    spec = {"name": "kmpc", "samples": 1000, "seed": 0}
    first, hit1 = cache.get_or_build(spec, build)
    second, hit2 = cache.get_or_build(dict(spec), build)
    assert build.calls == 1
    assert (hit1.hit, hit2.hit) == (False, True)
    assert hit2.info == {"fit_time_s": 0.5, "call": 1}
    assert hit1.key == hit2.key == spec_key(spec)
    np.testing.assert_array_equal(first.A_, second.A_)
    assert second.metadata_["cache_spec"] == spec
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_a_changed_spec_trains_again(tmp_path):
    cache = ModelCache(tmp_path)
    build = _Builder()
    cache.get_or_build({"name": "kmpc", "seed": 0}, build)
    _, hit = cache.get_or_build({"name": "kmpc", "seed": 1}, build)
    assert build.calls == 2 and not hit.hit
    # Key order does not matter.
    assert spec_key({"a": 1, "b": [1, 2]}) == spec_key({"b": (1, 2), "a": 1})


def test_a_corrupted_entry_is_rebuilt(tmp_path):
    cache = ModelCache(tmp_path)
    build = _Builder()
    spec = {"name": "residual", "data_hash": "abc"}
    cache.get_or_build(spec, build)
    cache.path_for(spec).write_bytes(b"not a model")
    model, hit = cache.get_or_build(spec, build)
    assert build.calls == 2 and not hit.hit
    assert KoopmanModel.load(cache.path_for(spec)).A_.shape == model.A_.shape


def test_default_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("RKMPC_CACHE_DIR", str(tmp_path / "c"))
    assert default_cache_dir() == tmp_path / "c"
    monkeypatch.delenv("RKMPC_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert default_cache_dir() == tmp_path / "x" / "rkmpc"
