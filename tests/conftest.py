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


@pytest.fixture(scope="session")
def builtin_lap(builtin_scenario):
    """One LMPC lap of the built-in track as a data set (with its contract)."""
    from rkmpc.sim.collect import collect

    return collect(builtin_scenario, laps=1)


@pytest.fixture(scope="session")
def small_paper_model(builtin_scenario, builtin_lap):
    """An ``rkmpc-paper`` model in seconds: one LMPC lap of the built-in track, no lifting network.

    The literal reading's lifted linear model on the local pose (``z = [x, y, theta]``), fitted by
    least squares only: small, but a real model of the data that drives the residual MPC.
    """
    from rkmpc.learning.data.augmentation import AugmentConfig
    from rkmpc.learning.koopman.model import KoopmanModel
    from rkmpc.learning.pipeline import TrainConfig, train_model

    sc = builtin_scenario
    config = TrainConfig(kind="paper", augment=AugmentConfig(ratio=0.2), model=KoopmanModel(None))
    model, _ = train_model(builtin_lap, sc.vehicle.wheelbase, config, vehicle=sc.vehicle_name)
    return model


def figure_eight_points(n: int = 240) -> object:
    """A figure-8 centre line at 1:10 (``x = 15 sin t, y = 6 sin 2t``, about 83 m a lap).

    It crosses itself at the origin at 77 degrees, the two passes 41 m apart along the lap (a
    bridge); ``s = 0`` (``t = pi / 4``) is 29 m before the first pass, away from the crossing.
    """
    import numpy as np

    t = np.pi / 4 + np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([15.0 * np.sin(t), 6.0 * np.sin(2 * t)])


@pytest.fixture(scope="session")
def figure_eight_csv(tmp_path_factory) -> Path:
    """The figure-8 of :func:`figure_eight_points` as a TUM centre-line file, 2.4 m wide."""
    import numpy as np

    xy = figure_eight_points()
    rows = np.column_stack([xy, np.full(len(xy), 1.2), np.full(len(xy), 1.2)])
    path = tmp_path_factory.mktemp("figure8") / "figure8.csv"
    np.savetxt(path, rows, delimiter=",", header="x_m,y_m,w_tr_right_m,w_tr_left_m", fmt="%.6f")
    return path
