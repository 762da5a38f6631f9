import math
import zipfile

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.experiments.runs import run_controller
from rkmpc.learning.data.dataset import FORMAT_VERSION, TransitionDataset
from rkmpc.sim.collect import collect
from rkmpc.sim.log import StepLog
from rkmpc.sim.run import RunSpec

DT = 0.05


def small_dataset(n=30, seed=0, dt=DT, episodes=None, metadata=None):
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(n, 7))
    obs[:, 3] = rng.uniform(0.5, 3.0, n)
    obs[:, 6] = np.nan  # wheel angle not measured
    next_obs = obs + 0.01
    command = np.stack([rng.uniform(0.5, 3.0, n), rng.uniform(-0.4, 0.4, n)], axis=1)
    episode = np.zeros(n, dtype=np.int64) if episodes is None else np.asarray(episodes)
    return TransitionDataset(obs, command, next_obs, dt, episode, metadata or {"dt": dt, "source": "test"})


@pytest.fixture(scope="module")
def lmpc_run(builtin_scenario):
    result, _ = run_controller(builtin_scenario, RunSpec("lmpc"))
    return result


# ---------------------------------------------------------------- construction


def test_construction_converts_and_freezes():
    data = small_dataset()
    assert len(data) == 30
    assert data.obs.dtype == np.float64 and data.episode.dtype == np.int64
    assert data.poses().shape == (30, 3) and data.next_poses().shape == (30, 3)
    np.testing.assert_array_equal(data.poses(), data.obs[:, :3])
    with pytest.raises(ValueError, match="read-only"):
        data.obs[0, 0] = 1.0
    ints = TransitionDataset(
        np.zeros((2, 7), dtype=int), np.zeros((2, 2), dtype=int), np.zeros((2, 7)), 1, np.zeros(2, dtype=int)
    )
    assert ints.obs.dtype == np.float64 and ints.dt == 1.0


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"obs": np.zeros((30, 6))}, r"obs: shape \(30, 6\)"),
        ({"command": np.zeros((29, 2))}, "command: 29 rows"),
        ({"next_obs": np.zeros((30, 7), dtype=complex)}, "next_obs: must hold real numbers"),
        ({"dt": 0.0}, "dt: must be finite and > 0"),
        ({"dt": math.nan}, "dt"),
        ({"episode": np.r_[np.zeros(20), np.ones(5), np.zeros(5)].astype(int)}, "episode: must not decrease"),
        ({"episode": np.zeros(31, dtype=int)}, "episode: shape"),
        ({"metadata": {"dt": 0.1}}, "the metadata says 0.1"),
        ({"metadata": {"bad": object()}}, "metadata: not JSON-able"),
    ],
)
def test_construction_validation(change, match):
    data = small_dataset()
    kwargs = {
        "obs": data.obs,
        "command": data.command,
        "next_obs": data.next_obs,
        "dt": data.dt,
        "episode": data.episode,
        "metadata": data.metadata,
    }
    kwargs.update(change)
    with pytest.raises(ParameterError, match=match):
        TransitionDataset(**kwargs)


def test_required_columns_must_be_finite_optional_may_be_nan():
    data = small_dataset()
    for col, name in ((0, "obs.x"), (2, "obs.yaw"), (3, "obs.speed")):
        obs = data.obs.copy()
        obs[4, col] = np.nan
        with pytest.raises(ParameterError, match=rf"{name}: 1 non-finite value\(s\), first at row 4"):
            TransitionDataset(obs, data.command, data.next_obs, DT, data.episode)
    obs = data.obs.copy()
    obs[:, 4:] = np.nan
    TransitionDataset(obs, data.command, data.next_obs, DT, data.episode)
    obs = data.obs.copy()
    obs[3, 3] = -0.1
    with pytest.raises(ParameterError, match=r"obs\.speed: negative speed"):
        TransitionDataset(obs, data.command, data.next_obs, DT, data.episode)
    command = data.command.copy()
    command[0, 1] = np.inf
    with pytest.raises(ParameterError, match=r"command\.steer"):
        TransitionDataset(data.obs, command, data.next_obs, DT, data.episode)


def test_content_hash_depends_on_data_not_metadata():
    a = small_dataset(metadata={"note": "a"})
    b = small_dataset(metadata={"note": "b"})
    c = small_dataset(seed=1)
    d = small_dataset(dt=0.02, metadata={"dt": 0.02})
    assert a.content_hash() == b.content_hash()
    assert len(a.content_hash()) == 64
    assert a.content_hash() != c.content_hash()
    assert a.content_hash() != d.content_hash()


def test_concatenate_renumbers_episodes():
    a = small_dataset(10, episodes=[3] * 4 + [7] * 6)
    b = small_dataset(5, seed=2, episodes=[0] * 5)
    joined = TransitionDataset.concatenate([a, b, a])
    assert len(joined) == 25
    np.testing.assert_array_equal(joined.episode, [0] * 4 + [1] * 6 + [2] * 5 + [3] * 4 + [4] * 6)
    np.testing.assert_array_equal(joined.obs[10:15], b.obs)
    assert len(joined.metadata["parts"]) == 3
    with pytest.raises(ParameterError, match="dt"):
        TransitionDataset.concatenate([a, small_dataset(dt=0.1, metadata={"dt": 0.1})])
    with pytest.raises(ParameterError, match="no data sets"):
        TransitionDataset.concatenate([])


# ---------------------------------------------------------------- files


def test_save_load_round_trip(tmp_path):
    data = small_dataset(
        episodes=[0] * 10 + [1] * 20, metadata={"dt": DT, "vehicle": "f1tenth", "n": np.int64(3)}
    )
    path = tmp_path / "sub" / "data.npz"
    data.save(path)
    assert [p.name for p in path.parent.iterdir()] == ["data.npz"]  # no temporary file left behind
    back = TransitionDataset.load(path)
    for name in ("obs", "command", "next_obs", "episode"):
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name))
    assert back.dt == data.dt
    assert back.metadata == {"dt": DT, "vehicle": "f1tenth", "n": 3}
    assert back.content_hash() == data.content_hash()


def write_npz(path, **arrays):
    with path.open("wb") as handle:
        np.savez(handle, **arrays)


def good_arrays(data):
    return {
        "obs": data.obs,
        "command": data.command,
        "next_obs": data.next_obs,
        "episode": data.episode,
        "dt": np.float64(data.dt),
        "metadata": np.str_('{"dt": 0.05}'),
        "format": np.int64(FORMAT_VERSION),
    }


def test_load_missing_file(tmp_path):
    path = tmp_path / "nope.npz"
    with pytest.raises(InputFileError, match="file not found") as info:
        TransitionDataset.load(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("edit", "field", "match"),
    [
        (lambda a: a.update(obs=a["obs"][:, :5]), "obs", r"shape \(30, 5\), expected \(N, 7\)"),
        (lambda a: a.pop("next_obs"), "next_obs", "missing array 'next_obs'"),
        (lambda a: a["obs"].__setitem__((7, 0), np.nan), "obs.x", "non-finite"),
        (lambda a: a["command"].__setitem__((2, 1), 20.0), "command.steer", "looks like degrees"),
        (lambda a: a["obs"].__setitem__((2, 6), -25.0), "obs.steer_angle", "looks like degrees"),
        (lambda a: a["next_obs"].__setitem__((2, 2), 170.0), "next_obs.yaw", "looks like degrees"),
        (lambda a: a["obs"].__setitem__((0, 3), -1.0), "obs.speed", "negative speed"),
        (lambda a: a.update(dt=np.float64(0.1)), "dt", "metadata says 0.05"),
        (lambda a: a.update(format=np.int64(99)), "format", "unknown format version 99"),
        (lambda a: a.pop("format"), "format", "not a transition data set"),
        (lambda a: a.update(metadata=np.str_("{oops")), "metadata", "invalid JSON"),
    ],
)
def test_load_reports_bad_content(tmp_path, edit, field, match):
    arrays = {k: np.array(v) for k, v in good_arrays(small_dataset()).items()}
    edit(arrays)
    path = tmp_path / "bad.npz"
    write_npz(path, **arrays)
    with pytest.raises(InputFileError, match=match) as info:
        TransitionDataset.load(path)
    assert info.value.field == field
    assert info.value.path == path
    assert str(path) in str(info.value)


def test_load_garbage_and_truncated_files(tmp_path):
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"\x00\x01 this is not a zip archive" * 10)
    with pytest.raises(InputFileError, match=r"not a readable \.npz") as info:
        TransitionDataset.load(garbage)
    assert str(garbage) in str(info.value)

    good = tmp_path / "good.npz"
    small_dataset(200).save(good)
    raw = good.read_bytes()
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(InputFileError, match="corrupted or truncated") as info:
        TransitionDataset.load(truncated)
    assert str(truncated) in str(info.value)

    # Corrupt bytes in the middle of a compressed member (the zip directory still reads).
    corrupted = tmp_path / "corrupted.npz"
    with zipfile.ZipFile(good) as archive:
        info_obs = archive.getinfo("obs.npy")
    data = bytearray(raw)
    start = info_obs.header_offset + 30 + len(info_obs.filename) + 20
    data[start : start + 200] = b"\xff" * 200
    corrupted.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match="corrupted or truncated") as info:
        TransitionDataset.load(corrupted)
    assert str(corrupted) in str(info.value)


def test_load_a_folder(tmp_path):
    with pytest.raises(InputFileError, match="not a file"):
        TransitionDataset.load(tmp_path)


# ---------------------------------------------------------------- from logs and collection


def test_from_log_of_a_simulated_run(lmpc_run, builtin_scenario):
    log = lmpc_run.log
    data = TransitionDataset.from_log(log, metadata={"track": "builtin"})
    assert lmpc_run.completed
    # Every row but the last makes a transition (the completed run logs a command on every row).
    assert len(data) == len(log) - 1
    assert data.dt == pytest.approx(builtin_scenario.dt)
    np.testing.assert_array_equal(data.episode, 0)
    np.testing.assert_array_equal(data.obs[1:], data.next_obs[:-1])
    np.testing.assert_array_equal(data.command[:, 0], log["cmd_speed"][:-1])
    assert data.metadata["outcome"] == "completed"
    assert data.metadata["controller"] == "lmpc"
    assert data.metadata["track"] == "builtin"
    assert data.metadata["source"] == "log"


def test_from_log_splits_episodes_at_holes_and_drops_missing_commands():
    from rkmpc.sim.closed_loop import log_columns

    log = StepLog(log_columns(("x", "y")))
    cols = log.columns
    for k in range(10):
        row = np.zeros(len(cols))
        row[cols.index("t")] = k * DT
        row[cols.index("x")] = k * 0.1
        row[cols.index("speed")] = 2.0
        row[cols.index("cmd_speed")] = 2.0
        if k in (4, 9):
            row[cols.index("cmd_speed")] = np.nan  # e.g. the off-track row
        log.append(row)
    data = TransitionDataset.from_log(log)
    assert len(data) == 8
    np.testing.assert_array_equal(data.episode, [0, 0, 0, 0, 1, 1, 1, 1])
    np.testing.assert_allclose(data.obs[:, 0], [0.0, 0.1, 0.2, 0.3, 0.5, 0.6, 0.7, 0.8])
    np.testing.assert_allclose(data.next_obs[:, 0], data.obs[:, 0] + 0.1)
    assert data.dt == pytest.approx(DT)

    bare = StepLog(["x", "y"])
    with pytest.raises(ParameterError, match="lacks the columns"):
        TransitionDataset.from_log(bare)


def test_from_log_leaves_out_a_spun_car_sliding_backwards():
    from rkmpc.sim.closed_loop import log_columns

    log = StepLog(log_columns(("x", "y")))
    cols = log.columns
    for k in range(8):
        row = np.zeros(len(cols))
        row[cols.index("t")] = k * DT
        row[cols.index("x")] = k * 0.1
        row[cols.index("speed")] = -0.3 if k >= 5 else 2.0  # spun at row 5
        row[cols.index("cmd_speed")] = 2.0
        log.append(row)
    data = TransitionDataset.from_log(log)
    assert len(data) == 4 and np.all(data.next_obs[:, 3] >= 0.0)


def test_collect_two_laps(builtin_scenario, tmp_path):
    data = collect(builtin_scenario, laps=2, seed=3)
    meta = data.metadata
    assert meta["completed"] is True and meta["outcome"] == "completed"
    assert meta["vehicle"] == "f1tenth" and meta["track"] == builtin_scenario.track.name
    assert meta["laps"] == 2 and meta["seed"] == 3 and meta["controller"] == "lmpc"
    assert meta["dt"] == builtin_scenario.dt and meta["scale"] == builtin_scenario.track.scale
    assert meta["rkmpc_version"] and meta["versions"]["rkmpc"] == meta["rkmpc_version"]
    assert len(meta["lap_times"]) == 2
    # About two lap times' worth of 50 ms steps.
    expected = sum(meta["lap_times"]) / builtin_scenario.dt
    assert abs(len(data) - expected) <= 2
    np.testing.assert_array_equal(data.episode, 0)
    path = tmp_path / "collected.npz"
    data.save(path)
    assert TransitionDataset.load(path).content_hash() == data.content_hash()
