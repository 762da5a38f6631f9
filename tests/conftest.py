"""Shared fixtures: the shared track folder and small scenarios."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_TRACKS = Path(__file__).resolve().parents[1].parent / "shared" / "tracks"


@pytest.fixture(autouse=True)
def _private_model_cache(tmp_path_factory, monkeypatch):
    """Trained models go to a temporary cache, never the user's."""
    monkeypatch.setenv("RKMPC_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "model-cache"))


@pytest.fixture(scope="session")
def shared_tracks() -> Path:
    """The TUM tracks beside the repository; skips the test when absent."""
    if not (SHARED_TRACKS / "centerlines").is_dir():
        pytest.skip("../shared/tracks is not present")
    return SHARED_TRACKS


@pytest.fixture(scope="session")
def builtin_scenario():
    """The built-in track with the f1tenth car."""
    from rkmpc.sim.scenario import load_scenario

    return load_scenario("builtin")
