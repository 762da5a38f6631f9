"""ModelCache: a model is trained once per spec, stale or broken entries are rebuilt."""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rkmpc.core.io import write_json_atomic
from rkmpc.experiments.cache import CacheWarning, ModelCache, default_cache_dir, spec_key
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
    with pytest.warns(CacheWarning, match="unreadable"):
        model, hit = cache.get_or_build(spec, build)
    assert build.calls == 2 and not hit.hit
    assert KoopmanModel.load(cache.path_for(spec)).A_.shape == model.A_.shape


def test_a_slot_with_a_list_for_json_or_another_model_is_rebuilt_once(tmp_path):
    cache = ModelCache(tmp_path)
    build = _Builder()
    spec = {"name": "kmpc", "seed": 0}
    other = {"name": "residual", "seed": 0}
    cache.get_or_build(spec, build)
    cache.get_or_build(other, build)
    cache.path_for(spec).with_suffix(".json").write_text("[1, 2]")
    with pytest.warns(CacheWarning, match="not a JSON object"):
        _, hit = cache.get_or_build(spec, build)
    assert not hit.hit and build.calls == 3
    _, hit = cache.get_or_build(spec, build)  # replaced: a hit from now on
    assert hit.hit and build.calls == 3
    # The model file of another slot copied into this one is not used.
    shutil.copyfile(cache.path_for(other), cache.path_for(spec))
    with pytest.warns(CacheWarning, match="another kind"):
        _, hit = cache.get_or_build(spec, build)
    assert not hit.hit and build.calls == 4
    assert cache.get_or_build(spec, build)[1].hit


def test_two_processes_asking_for_one_slot_train_it_once(tmp_path):
    # The second waits on the slot's lock while the first trains, then reads the first's model.
    script = f"""
import sys, time
sys.path.insert(0, {str(Path(__file__).parent)!r})
from test_cache import _Builder
from rkmpc.experiments.cache import ModelCache
build = _Builder()
_, hit = ModelCache({str(tmp_path)!r}).get_or_build({{"name": "kmpc"}}, build)
print("hit" if hit.hit else "trained")
"""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    cache = ModelCache(tmp_path)
    lock = cache.path_for({"name": "kmpc"}).with_suffix(".lock")
    tmp_path.mkdir(exist_ok=True)
    with open(lock, "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # as if a first process were training the slot
        second = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, env=env)
        cache_first = _Builder()
        # Store the first process's model while holding the lock (what get_or_build does inside it).
        model, info = cache_first()
        path = cache.path_for({"name": "kmpc"})
        model.save(path, metadata={**model.metadata_, "cache_spec": {"name": "kmpc"}})
        write_json_atomic(path.with_suffix(".json"), {"key": spec_key({"name": "kmpc"}), "info": info})
        fcntl.flock(held, fcntl.LOCK_UN)
    assert second.communicate(timeout=300)[0].strip() == "hit"


def test_default_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("RKMPC_CACHE_DIR", str(tmp_path / "c"))
    assert default_cache_dir() == tmp_path / "c"
    monkeypatch.delenv("RKMPC_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert default_cache_dir() == tmp_path / "x" / "rkmpc"
