"""KoopmanModel: training, prediction, reproducibility, storage and its error reporting."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.learning.koopman.io import FORMAT_NAME
from rkmpc.learning.koopman.lifting import MLPLifting, MLPTraining, RBFLifting
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.koopman.windows import consecutive_windows

DATA = Path(__file__).resolve().parents[1] / "data"

DT = 0.05


def _duffing_step(x: np.ndarray, u: float) -> np.ndarray:
    """One RK4 step of the forced double-well Duffing oscillator x'' = x - x^3 - 0.5 x' + u."""

    def f(s: np.ndarray) -> np.ndarray:
        return np.array([s[1], s[0] - s[0] ** 3 - 0.5 * s[1] + u])

    k1 = f(x)
    k2 = f(x + DT / 2 * k1)
    k3 = f(x + DT / 2 * k2)
    k4 = f(x + DT * k3)
    return x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def _duffing_data(n_traj: int, steps: int, seed: int):
    """Trajectories stacked in order, so that X_next[k] == X[k+1] within a trajectory."""
    rng = np.random.default_rng(seed)
    X, U, Xn = [], [], []
    for _ in range(n_traj):
        x = rng.uniform(-2.0, 2.0, size=2)
        for _ in range(steps):
            u = rng.uniform(-1.0, 1.0, size=1)
            xn = _duffing_step(x, float(u[0]))
            X.append(x)
            U.append(u)
            Xn.append(xn)
            x = xn
    return np.array(X), np.array(U), np.array(Xn)


@pytest.fixture(scope="module")
def data():
    return _duffing_data(60, 50, seed=0)  # 3000 samples


@pytest.fixture(scope="module")
def held_out():
    X, U, Xn = _duffing_data(30, 50, seed=1)
    windows = consecutive_windows(X, U, Xn, 10)
    assert windows is not None
    return windows


def _mlp(epochs: int, batch_size: int, seed: int = 0, n_lift: int = 16, **model: object) -> KoopmanModel:
    training = MLPTraining(epochs=epochs, batch_size=batch_size, seed=seed)
    return KoopmanModel(MLPLifting(n_lift=n_lift, training=training), **model)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def trained(data):
    X, U, Xn = data
    epochs_seen: list[tuple[int, float]] = []
    model = _mlp(epochs=30, batch_size=256, seed=0).fit(
        X, U, Xn, on_epoch=lambda e, loss: epochs_seen.append((e, loss))
    )
    return model, epochs_seen


# ---------------------------------------------------------------- training


@pytest.mark.slow
def test_training_reduces_the_loss_and_reports_progress(trained):
    model, seen = trained
    assert isinstance(model.lifting_, MLPLifting)
    assert model.n_lifted_ == 2 + 16
    assert [e for e, _ in model.history_] == list(range(31))
    assert seen == model.history_
    assert model.history_[-1][1] < 0.2 * model.history_[0][1]
    assert model.epochs_run_ == 30
    assert model.fit_time_s_ > 0


@pytest.mark.slow
def test_learned_lifting_beats_the_linear_model_over_ten_steps(data, held_out, trained):
    X, U, Xn = data
    Xw, Uw = held_out
    model, _ = trained
    linear = KoopmanModel(None).fit(X, U, Xn)
    err_mlp = model.multi_step_error(Xw, Uw)
    err_lin = linear.multi_step_error(Xw, Uw)
    assert err_mlp.shape == err_lin.shape == (10,)
    # Measured: 0.017 vs 0.26 at step 10 (untrained random features: 0.13; the double well is far
    # from linear), so the bound checks the training, not just the extra features.
    assert err_mlp[-1] < 0.2 * err_lin[-1]
    assert err_mlp.mean() < 0.2 * err_lin.mean()


def test_same_seed_same_model_other_seed_other_model(data):
    X, U, Xn = data
    a = _mlp(3, 512, seed=7).fit(X, U, Xn)
    b = _mlp(3, 512, seed=7).fit(X, U, Xn)
    c = _mlp(3, 512, seed=8).fit(X, U, Xn)
    np.testing.assert_allclose(a.A_, b.A_, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.B_, b.B_, rtol=0, atol=1e-12)
    assert a.history_ == b.history_
    assert np.max(np.abs(a.A_ - c.A_)) > 1e-6


def test_training_leaves_torch_settings_as_it_found_them(data):
    import torch

    X, U, Xn = data
    threads = torch.get_num_threads()
    deterministic = torch.are_deterministic_algorithms_enabled()
    torch.manual_seed(99)
    expected = torch.rand(2)
    torch.manual_seed(99)
    _mlp(1, 1024).fit(X, U, Xn)
    assert torch.equal(torch.rand(2), expected)
    assert torch.get_num_threads() == threads
    assert torch.are_deterministic_algorithms_enabled() == deterministic


def test_training_uses_one_thread_whatever_the_machine_and_says_so(tmp_path, data):
    """A fixed thread count (1) makes models identical everywhere; the model file records it."""
    import torch

    X, U, Xn = data
    seen = []
    before = torch.get_num_threads()
    model = _mlp(2, 512).fit(X, U, Xn, on_epoch=lambda *_: seen.append(torch.get_num_threads()))
    assert set(seen) == {1} and torch.get_num_threads() == before
    model.save(tmp_path / "m.npz")
    header = json.loads(str(np.load(tmp_path / "m.npz")["metadata"]))
    assert header["torch_threads"] == 1


def test_training_runs_exactly_its_epochs(data):
    """No wall-clock budget: the epoch count alone ends training, whatever the machine's load."""
    X, U, Xn = data
    model = _mlp(4, 512).fit(X, U, Xn)
    assert model.epochs_run_ == 4 and [e for e, _ in model.history_] == [0, 1, 2, 3, 4]
    assert not hasattr(MLPTraining(), "max_seconds")


def test_output_targets_and_no_state_block(data):
    X, U, Xn = data
    Y = np.column_stack([X[:, 0] ** 2, X[:, 1] + 0.5 * U[:, 0]])
    model = _mlp(3, 512, n_lift=12, include_state=False).fit(X, U, Xn, Y=Y)
    assert model.n_lifted_ == 12
    assert model.A_.shape == (12, 12) and model.B_.shape == (12, 1)
    assert model.C_.shape == (2, 12) and model.D_.shape == (2, 1) and model.Cx_.shape == (2, 12)
    assert not model.output_is_state_ and model.ny_ == 2
    Uh = U[:5]
    Yh = model.predict(X[0], Uh)
    assert Yh.shape == (5, 2)
    # predict is the documented recursion.
    z = model.lift(X[0])
    for k in range(5):
        np.testing.assert_allclose(Yh[k], model.output(z, Uh[k]), rtol=1e-12, atol=1e-12)
        z = model.step(z, Uh[k])


def test_linear_output_is_exact_with_the_state_in_z(data):
    X, U, Xn = data
    Y = X @ np.array([[1.0, -2.0], [0.5, 0.0]]).T + U @ np.array([[0.3], [-1.0]]).T
    model = KoopmanModel(RBFLifting(n_centers=10), ridge=0.0).fit(X, U, Xn, Y=Y)
    np.testing.assert_allclose(model.output(model.lift(X), U), Y, rtol=0, atol=1e-6)


@pytest.mark.slow
def test_lift_shapes_and_state_prediction(trained, data):
    model, _ = trained
    X, U, _ = data
    Z = model.lift(X[:10])
    assert Z.shape == (10, 18)
    np.testing.assert_array_equal(Z[:, :2], X[:10])
    np.testing.assert_allclose(model.lift(X[3]), Z[3], rtol=0, atol=1e-12)
    states = model.predict_states(X[0], U[:8])
    assert states.shape == (9, 2)
    np.testing.assert_array_equal(states[0], X[0])
    np.testing.assert_allclose(model.predict(X[0], U[:8]), states[:-1], rtol=0, atol=1e-12)


def test_rbf_model_needs_no_training(data):
    X, U, Xn = data
    model = KoopmanModel(RBFLifting(n_centers=20)).fit(X, U, Xn)
    assert model.history_ == [] and model.n_lifted_ == 22


def test_bad_parameters_and_data(data):
    X, U, Xn = data
    with pytest.raises(ParameterError, match="lifting"):
        KoopmanModel("poly").fit(X, U, Xn)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="include_state"):
        KoopmanModel(None, include_state=False).fit(X, U, Xn)
    with pytest.raises(ParameterError, match="n_lift"):
        KoopmanModel(MLPLifting(n_lift=0)).fit(X, U, Xn)
    with pytest.raises(ParameterError, match="ridge"):
        KoopmanModel(None, ridge=-1.0).fit(X, U, Xn)
    with pytest.raises(ParameterError, match="epochs"):
        MLPTraining(epochs=0)
    with pytest.raises(ParameterError, match="X_next"):
        KoopmanModel(None).fit(X, U, Xn[:, :1])
    with pytest.raises(ParameterError, match="windows"):
        KoopmanModel(None).fit(X, U, Xn, windows=(np.zeros((4, 3, 2)), np.zeros((4, 3, 1))))
    with pytest.raises(RuntimeError, match="not fitted"):
        KoopmanModel(None).predict(X[0], U[:3])


def test_fit_leaves_the_given_lifting_unfitted(data):
    """The model fits a copy of its lifting: one lifting object can set up many models."""
    X, U, Xn = data
    lifting = RBFLifting(n_centers=5)
    model = KoopmanModel(lifting).fit(X, U, Xn)
    assert model.lifting_ is not lifting and not hasattr(lifting, "centers_")
    assert KoopmanModel.from_params(model.get_params()).get_params() == model.get_params()


def test_consecutive_windows_respect_trajectory_breaks():
    X, U, Xn = _duffing_data(3, 12, seed=5)
    Xw, Uw = consecutive_windows(X, U, Xn, 10)
    assert Xw.shape == (3 * 3, 11, 2) and Uw.shape == (9, 10, 1)
    for xs, us in zip(Xw, Uw, strict=True):
        for k in range(10):
            np.testing.assert_allclose(xs[k + 1], _duffing_step(xs[k], float(us[k, 0])), rtol=0, atol=1e-12)
    assert consecutive_windows(X, U, Xn, 13) is None


# ---------------------------------------------------------------- storage


@pytest.mark.parametrize("kind", [pytest.param("mlp", marks=pytest.mark.slow), "rbf", "none"])
def test_save_load_round_trip(tmp_path, data, trained, kind):
    X, U, Xn = data
    lifting = RBFLifting() if kind == "rbf" else None
    model = trained[0] if kind == "mlp" else KoopmanModel(lifting).fit(X, U, Xn)
    path = tmp_path / "sub" / "model.npz"
    model.save(path, metadata={"data_hash": "abc123", "rkmpc_version": "0.1.0"})
    assert [p.name for p in path.parent.iterdir()] == ["model.npz"]  # no temporary left behind
    again = KoopmanModel.load(path)
    for name in ("A_", "B_", "C_", "D_", "Cx_"):
        np.testing.assert_array_equal(getattr(again, name), getattr(model, name))
    np.testing.assert_array_equal(again.predict(X[5], U[:12]), model.predict(X[5], U[:12]))
    np.testing.assert_array_equal(again.lift(X[:50]), model.lift(X[:50]))
    assert again.get_params() == model.get_params()
    assert again.metadata_ == {"data_hash": "abc123", "rkmpc_version": "0.1.0"}
    assert again.history_ == model.history_
    assert again.fit_time_s_ == model.fit_time_s_
    assert (again.nx_, again.nu_, again.ny_) == (2, 1, 2)


@pytest.fixture
def saved(tmp_path, data):
    X, U, Xn = data
    path = tmp_path / "model.npz"
    KoopmanModel(RBFLifting(n_centers=8)).fit(X, U, Xn).save(path)
    return path


def _rewrite(src, dst, change):
    with np.load(src) as loaded:
        arrays = {k: loaded[k] for k in loaded.files}
    meta = json.loads(str(arrays["metadata"]))
    arrays, meta = change(arrays, meta)
    arrays["metadata"] = np.array(json.dumps(meta))
    np.savez(dst, **arrays)
    return dst


def _expect_error(path, match, field=None):
    with pytest.raises(InputFileError, match=match) as info:
        KoopmanModel.load(path)
    assert str(path) in str(info.value)
    assert info.value.path == path
    if field is not None:
        assert info.value.field == field


def test_load_missing_file(tmp_path):
    _expect_error(tmp_path / "nope.npz", "not found")


def test_load_garbage_empty_and_truncated(tmp_path, saved):
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(np.random.default_rng(0).bytes(4000))
    _expect_error(garbage, "npz")
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    _expect_error(empty, "npz")
    raw = saved.read_bytes()
    for cut in (len(raw) // 3, len(raw) - 30):
        truncated = tmp_path / f"cut{cut}.npz"
        truncated.write_bytes(raw[:cut])
        _expect_error(truncated, "npz")
    for pos in (200, len(raw) // 2):  # overwritten bytes inside the archive: caught by the zip checksums
        damaged = bytearray(raw)
        damaged[pos : pos + 8] = b"\xff" * 8
        flipped = tmp_path / f"flip{pos}.npz"
        flipped.write_bytes(bytes(damaged))
        _expect_error(flipped, "npz")
    single = tmp_path / "single.npz"
    with single.open("wb") as handle:
        np.save(handle, np.eye(3))
    _expect_error(single, "npy")


def test_load_wrong_format_and_version(tmp_path, saved):
    def other_format(arrays, meta):
        meta["format"] = "something-else"
        return arrays, meta

    def future_version(arrays, meta):
        meta["format_version"] = 99
        return arrays, meta

    _expect_error(_rewrite(saved, tmp_path / "f.npz", other_format), FORMAT_NAME, "metadata.format")
    _expect_error(_rewrite(saved, tmp_path / "v.npz", future_version), "version", "metadata.format_version")

    def no_metadata(arrays, meta):
        return arrays, meta

    path = _rewrite(saved, tmp_path / "m.npz", no_metadata)
    with np.load(path) as loaded:
        arrays = {k: loaded[k] for k in loaded.files if k != "metadata"}
    np.savez(path, **arrays)
    _expect_error(path, "metadata", "metadata")


def test_load_missing_arrays(tmp_path, saved):
    def drop(name):
        def change(arrays, meta):
            del arrays[name]
            return arrays, meta

        return change

    _expect_error(_rewrite(saved, tmp_path / "b.npz", drop("B")), "missing array 'B'", "B")
    _expect_error(
        _rewrite(saved, tmp_path / "c.npz", drop("lifting.centers")), "lifting array", "lifting.centers"
    )


def test_load_inconsistent_shapes(tmp_path, saved):
    def not_square(arrays, meta):
        arrays["A"] = arrays["A"][:, :-1]
        return arrays, meta

    def b_rows(arrays, meta):
        arrays["B"] = arrays["B"][:-1]
        return arrays, meta

    def sizes(arrays, meta):
        meta["nx"] = 5
        return arrays, meta

    def nan(arrays, meta):
        arrays["C"] = arrays["C"] * np.nan
        return arrays, meta

    _expect_error(_rewrite(saved, tmp_path / "a.npz", not_square), "square", "A")
    _expect_error(_rewrite(saved, tmp_path / "b.npz", b_rows), "shape", "B")
    _expect_error(_rewrite(saved, tmp_path / "n.npz", sizes), "shape", "Cx")
    _expect_error(_rewrite(saved, tmp_path / "c.npz", nan), "NaN", "C")


# ---------------------------------------------------------------- training range


def test_lift_clips_states_into_the_training_range(data):
    X, U, Xn = data
    model = KoopmanModel(RBFLifting(n_centers=16)).fit(X, U, Xn)
    np.testing.assert_array_equal(model.x_min_, np.minimum(X.min(0), Xn.min(0)))
    np.testing.assert_array_equal(model.x_max_, np.maximum(X.max(0), Xn.max(0)))
    inside = X[:5]
    np.testing.assert_array_equal(model.lift(inside), model._lift(inside))  # unchanged inside the range
    outside = np.array([model.x_max_ + np.array([3.0, 0.0]), model.x_min_ - np.array([0.0, 5.0])])
    edge = np.array([[model.x_max_[0], model.x_max_[1]], [model.x_min_[0], model.x_min_[1]]])
    np.testing.assert_array_equal(model.lift(outside), model._lift(edge))
    free = KoopmanModel(RBFLifting(n_centers=16), clip_inputs=False).fit(X, U, Xn)
    assert not np.allclose(free.lift(outside), free._lift(edge))
    with pytest.raises(ParameterError, match="clip_inputs"):
        KoopmanModel(None, clip_inputs=1).fit(X, U, Xn)  # type: ignore[arg-type]


def test_range_is_saved_and_version_1_files_clip_nothing(tmp_path, saved):
    model = KoopmanModel.load(saved)
    assert np.all(np.isfinite(model.x_min_)) and np.all(model.x_min_ < model.x_max_)

    def version_1(arrays, meta):
        del arrays["x_min"], arrays["x_max"]
        meta["format_version"] = 1
        lifting = meta["params"]["lifting"]
        meta["params"] = {
            "lifting": "rbf",
            "n_centers": lifting["n_centers"],
            "rbf_kind": lifting["rbf_kind"],
        }
        return arrays, meta

    old = KoopmanModel.load(_rewrite(saved, tmp_path / "v1.npz", version_1))
    far = model.x_max_ + 10.0
    np.testing.assert_array_equal(old.lift(far), old._lift(far))
    assert not np.allclose(model.lift(far), model._lift(far))

    def drop_range(arrays, meta):
        del arrays["x_max"]
        return arrays, meta

    def bad_range(arrays, meta):
        arrays["x_min"] = arrays["x_max"] + 1.0
        return arrays, meta

    _expect_error(_rewrite(saved, tmp_path / "r.npz", drop_range), "missing array 'x_max'", "x_max")
    _expect_error(_rewrite(saved, tmp_path / "s.npz", bad_range), "exceeds", "x_min")


@pytest.mark.parametrize("kind", ["rbf", "mlp"])
def test_version_2_files_of_the_former_layout_load_and_predict_alike(kind):
    """Files written before the redesign (flat settings, format 2) give the same numbers today."""
    expected = np.load(DATA / "koopman_v2_expected.npz")
    model = KoopmanModel.load(DATA / f"koopman_v2_{kind}.npz")
    assert model.lifting is not None and model.lifting.name == kind
    np.testing.assert_array_equal(model.lift(expected["probe"]), expected[f"{kind}_lift"])
    np.testing.assert_array_equal(
        model.predict(expected["probe"][0], expected["inputs"]), expected[f"{kind}_predict"]
    )
    assert model.metadata_["kind"] == "test"


def test_saved_files_are_readable_by_the_team(tmp_path, data):
    X, U, Xn = data
    path = tmp_path / "model.npz"
    KoopmanModel(None).fit(X, U, Xn).save(path)
    assert (
        path.stat().st_mode & 0o044 == 0o044
    )  # group and others may read (umask 022), unlike mkstemp's 0600
