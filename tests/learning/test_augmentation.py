import math

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.learning.data.augmentation import (
    AugmentConfig,
    local_frame_windows,
    to_local_frame,
    valid_origins,
)
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.vehicle.kinematic import kinematic_step

WHEELBASE = 0.307
DT = 0.05


def wrap(a):
    return math.pi - (math.pi - a) % (2 * math.pi)


def trajectory(n, seed=0, start=(0.0, 0.0, 0.0), steer=None, episode_lengths=None):
    """Kinematic trajectory under random inputs; yaw stored wrapped to (-pi, pi]."""
    rng = np.random.default_rng(seed)
    speeds = rng.uniform(0.5, 4.0, n)
    steers = rng.uniform(-0.3, 0.3, n) if steer is None else np.full(n, steer)
    state = np.array(start, dtype=float)
    obs = np.full((n, 7), np.nan)
    next_obs = np.full((n, 7), np.nan)
    for k in range(n):
        new = kinematic_step(state, (speeds[k], steers[k]), WHEELBASE, DT)
        obs[k, :4] = (state[0], state[1], wrap(state[2]), speeds[k])
        obs[k, 4] = k  # a frame-independent column, to check it is carried through
        next_obs[k, :4] = (new[0], new[1], wrap(new[2]), speeds[k])
        next_obs[k, 4] = k + 1
        state = new
    if episode_lengths is None:
        episode = np.zeros(n, dtype=np.int64)
    else:
        episode = np.repeat(np.arange(len(episode_lengths)), episode_lengths)
    return TransitionDataset(obs, np.stack([speeds, steers], axis=1), next_obs, DT, episode)


def test_to_local_frame_basic():
    origin = np.array([1.0, 2.0, math.pi / 2])
    poses = np.array([[1.0, 2.0, math.pi / 2], [1.0, 3.0, math.pi], [0.0, 2.0, -math.pi / 2 + 0.1]])
    local = to_local_frame(poses, origin)
    np.testing.assert_allclose(local[0], [0.0, 0.0, 0.0], atol=1e-15)
    # One metre ahead along the origin heading.
    np.testing.assert_allclose(local[1], [1.0, 0.0, math.pi / 2], atol=1e-12)
    # One metre to the origin's right (-y), heading wrapped into (-pi, pi].
    np.testing.assert_allclose(local[2], [0.0, 1.0, wrap(-math.pi + 0.1)], atol=1e-12)
    assert np.all(local[:, 2] > -math.pi) and np.all(local[:, 2] <= math.pi)
    # Exactly opposite headings map to +pi.
    assert to_local_frame(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, math.pi]))[2] == pytest.approx(
        math.pi
    )


def test_counts_follow_the_ratio():
    data = trajectory(300)
    cfg = AugmentConfig(ratio=0.3, n_points=35, seed=4)
    windows = local_frame_windows(data, cfg)
    valid = len(data) - 35 + 1
    assert windows.n_windows == round(0.3 * valid)
    assert windows.augmented_count == windows.n_windows * 35
    assert windows.raw_count == 300
    assert windows.obs.shape == (windows.n_windows, 35, 7)
    assert windows.command.shape == (windows.n_windows, 35, 2)
    assert windows.next_obs.shape == (windows.n_windows, 35, 7)
    assert len(np.unique(windows.origin_index)) == windows.n_windows
    assert np.all(np.diff(windows.origin_index) > 0)
    # A tiny ratio still gives one window.
    assert local_frame_windows(data, AugmentConfig(ratio=1e-6, n_points=35)).n_windows == 1
    # ratio 1 uses every valid origin.
    assert local_frame_windows(data, AugmentConfig(ratio=1.0, n_points=35)).n_windows == valid


def test_windows_are_in_the_frame_of_their_first_pose():
    data = trajectory(200, seed=3)
    windows = local_frame_windows(data, AugmentConfig(ratio=0.5, n_points=20, seed=1))
    np.testing.assert_array_equal(windows.obs[:, 0, :3], 0.0)
    idx = windows.indices
    # Frame-independent columns and commands are unchanged.
    np.testing.assert_array_equal(windows.obs[..., 3:], data.obs[idx, 3:])
    np.testing.assert_array_equal(windows.next_obs[..., 3:], data.next_obs[idx, 3:])
    np.testing.assert_array_equal(windows.command, data.command[idx])
    # Rigid motion: distances between consecutive points and from obs to next_obs are preserved.
    local_d = np.linalg.norm(np.diff(windows.obs[..., :2], axis=1), axis=-1)
    global_d = np.linalg.norm(np.diff(data.obs[idx, :2], axis=1), axis=-1)
    np.testing.assert_allclose(local_d, global_d, atol=1e-12)
    step_local = np.linalg.norm(windows.next_obs[..., :2] - windows.obs[..., :2], axis=-1)
    step_global = np.linalg.norm(data.next_obs[idx, :2] - data.obs[idx, :2], axis=-1)
    np.testing.assert_allclose(step_local, step_global, atol=1e-12)
    # Consecutive in time inside a window: next_obs of one step is obs of the next.
    np.testing.assert_allclose(windows.next_obs[:, :-1, :3], windows.obs[:, 1:, :3], atol=1e-12)
    # The window's origin heading is the first pose's: going straight ahead moves along +x.
    m = 0
    first_step = windows.next_obs[m, 0]
    v, d = data.command[windows.origin_index[m]]
    np.testing.assert_allclose(first_step[:3], kinematic_step((0, 0, 0), (v, d), WHEELBASE, DT), atol=1e-12)


def test_window_crossing_the_yaw_boundary_is_continuous():
    # A steady left turn starting just below +pi: the stored (wrapped) yaw jumps to -pi.
    data = trajectory(60, start=(5.0, 5.0, math.pi - 0.2), steer=0.3)
    assert np.any(np.abs(np.diff(data.obs[:, 2])) > math.pi)
    windows = local_frame_windows(data, AugmentConfig(ratio=1.0, n_points=40))
    yaw = windows.obs[..., 2]
    assert np.all(np.diff(yaw, axis=1) > 0) and np.all(np.diff(yaw, axis=1) < 0.5)
    np.testing.assert_allclose(windows.next_obs[:, :-1, 2], yaw[:, 1:], atol=1e-12)
    # Some window turns by more than 90 degrees; still no wrap.
    assert np.max(yaw) > math.pi / 2


def test_seeded_and_reproducible():
    data = trajectory(250)
    a = local_frame_windows(data, AugmentConfig(ratio=0.2, n_points=10, seed=7))
    b = local_frame_windows(data, AugmentConfig(ratio=0.2, n_points=10, seed=7))
    c = local_frame_windows(data, AugmentConfig(ratio=0.2, n_points=10, seed=8))
    np.testing.assert_array_equal(a.origin_index, b.origin_index)
    np.testing.assert_array_equal(a.obs, b.obs)
    assert not np.array_equal(a.origin_index, c.origin_index)


def test_windows_never_cross_episodes():
    data = trajectory(120, episode_lengths=[50, 12, 58])
    origins = valid_origins(data, 20)
    # The 12-transition episode cannot hold a window; the others give 31 and 39 origins.
    assert len(origins) == 31 + 39
    windows = local_frame_windows(data, AugmentConfig(ratio=1.0, n_points=20))
    ep = data.episode[windows.indices]
    assert np.all(ep == ep[:, :1])
    assert not np.any(ep == 1)
    with pytest.raises(ParameterError, match="n_points"):
        local_frame_windows(data, AugmentConfig(n_points=59))


def test_flatten():
    data = trajectory(80)
    windows = local_frame_windows(data, AugmentConfig(ratio=0.5, n_points=5))
    obs, command, next_obs = windows.flatten()
    assert obs.shape == (windows.augmented_count, 7)
    assert command.shape == (windows.augmented_count, 2)
    np.testing.assert_array_equal(next_obs.reshape(windows.next_obs.shape), windows.next_obs)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"ratio": 0.0}, "ratio"),
        ({"ratio": 1.5}, "ratio"),
        ({"ratio": math.nan}, "ratio"),
        ({"n_points": 0}, "n_points"),
        ({"n_points": 3.5}, "n_points"),
        ({"seed": -1}, "seed"),
    ],
)
def test_config_validation(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        AugmentConfig(**kwargs)
