"""Probe cases: results that must not depend on the machine, silent wrong learning, resource abuse."""

from __future__ import annotations

import io
import json
import time
import zipfile
from pathlib import Path

import numpy as np
from probe_cases import (
    CLEAR_ERROR,
    CORRECT,
    Evidence,
    Probe,
    case,
    caught_warnings,
    cli_error,
    ellipse,
    lap,
    models,
    raises,
    scenario,
    write_centerline,
)

MACHINE = "results independent of the machine"
LEARNING = "silent wrong learning"
RESOURCES = "resource abuse"
DT = 0.05
WHEELBASE = 0.307


def _drive(n: int = 400, weave: float = 0.3, yaw0: float = 0.4) -> np.ndarray:
    """Observations of a kinematic car weaving at 2-4 m/s, shape (n + 1, 7)."""
    t = DT * np.arange(n + 1)
    speed = 3.0 + np.sin(t / 3.0)
    steer = weave * np.sin(t / 1.3)
    yaw_rate = speed * np.tan(steer) / WHEELBASE
    yaw = yaw0 + np.concatenate([[0.0], np.cumsum(yaw_rate[:-1] * DT)])
    x = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.cos(yaw[:-1]) * DT)])
    y = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.sin(yaw[:-1]) * DT)])
    return np.column_stack([x, y, yaw, speed, yaw_rate, np.zeros(n + 1), steer])


def _data(obs: np.ndarray, next_obs: np.ndarray | None = None) -> object:
    from rkmpc.learning.data.dataset import TransitionDataset

    return TransitionDataset(
        obs=obs[:-1],
        command=np.column_stack([obs[:-1, 3], obs[:-1, 6]]),
        next_obs=obs[1:] if next_obs is None else next_obs,
        dt=DT,
        episode=np.zeros(len(obs) - 1, dtype=int),
    )


def _learnable(data: object) -> None:
    from rkmpc.learning.data.plausibility import check_learnable

    check_learnable(data, WHEELBASE, "laps.npz")  # type: ignore[arg-type]


# ------------------------------------------------------------------ machine independence


@case(
    "machine.no_time_caps",
    MACHINE,
    "no wall-clock budget: nmpc-dynamic has no max_cpu_time, training no max_seconds",
    CORRECT,
)
def no_time_caps(_: Probe) -> Evidence:
    from dataclasses import fields

    from probe_cases import controller

    from rkmpc.control.nonlinear.nmpc import NMPCConfig
    from rkmpc.learning.koopman.model import KoopmanModel
    from rkmpc.learning.koopman.settings import MLPTraining

    assert NMPCConfig().max_cpu_time is None
    assert controller("nmpc-dynamic").config.max_cpu_time is None
    assert "max_seconds" not in KoopmanModel(None).get_params()
    budgets = [f.name for f in fields(MLPTraining)]
    assert not [name for name in budgets if "time" in name or "seconds" in name], budgets
    return Evidence(CORRECT, f"nmpc-dynamic max_cpu_time None; training budgets {budgets[:1]} (counts)")


@case(
    "machine.one_training_thread",
    MACHINE,
    "training uses one torch thread whatever the machine, recorded in the model file",
    CORRECT,
)
def one_training_thread(probe: Probe) -> Evidence:
    import torch

    from rkmpc.learning.koopman.lifting import MLPLifting
    from rkmpc.learning.koopman.model import KoopmanModel
    from rkmpc.learning.koopman.settings import MLPTraining

    rng = np.random.default_rng(0)
    X, U = rng.normal(size=(300, 2)), rng.normal(size=(300, 1))
    Xn = 0.9 * X + 0.1 * U
    seen: list[int] = []
    before = torch.get_num_threads()
    lifting = MLPLifting(n_lift=4, training=MLPTraining(epochs=2, batch_size=100))
    model = KoopmanModel(lifting).fit(X, U, Xn, on_epoch=lambda *_: seen.append(torch.get_num_threads()))
    assert set(seen) == {1} and torch.get_num_threads() == before, (seen, before)
    path = probe.path("m.rkm")
    model.save(path)
    with np.load(path, allow_pickle=False) as archive:
        header = json.loads(str(archive["metadata"]))
    assert header["torch_threads"] == 1, header
    return Evidence(CORRECT, f"threads during training {sorted(set(seen))}; file: torch_threads = 1")


# ------------------------------------------------------------------ silent wrong learning


@case("learn.stood_still", LEARNING, "training on a car that stood still", CLEAR_ERROR)
def stood_still(_: Probe) -> Evidence:
    from rkmpc.learning.pipeline import TrainConfig, train_model

    obs = _drive()
    obs[:, 0:2] = obs[0, 0:2]
    obs[:, 3] = 0.0
    data = _data(obs)
    with caught_warnings():  # a data set without a contract: warned about, then refused
        return raises(
            lambda: train_model(data, WHEELBASE, TrainConfig(kind="residual"), source="laps.npz"),  # type: ignore[arg-type]
            "laps.npz",
            "stood still",
        )


@case("learn.shuffled", LEARNING, "next observations shuffled against the observations", CLEAR_ERROR)
def shuffled(_: Probe) -> Evidence:
    obs = _drive()
    mixed = obs[1:][np.random.default_rng(2).permutation(len(obs) - 1)]
    return raises(lambda: _learnable(_data(obs, mixed)), "laps.npz [next_obs]", "shuffled")


@case("learn.yaw_degrees", LEARNING, "yaw in degrees, all under 100 (passes a magnitude check)", CLEAR_ERROR)
def yaw_degrees(_: Probe) -> Evidence:
    obs = _drive(n=200, weave=0.05, yaw0=-0.4)
    _learnable(_data(obs))  # in radians: fine
    obs[:, 2] = np.degrees(obs[:, 2])
    assert np.abs(obs[:, 2]).max() < 100.0
    return raises(lambda: _learnable(_data(obs)), "laps.npz [obs.yaw]", "degrees")


@case(
    "learn.identify_25_samples",
    LEARNING,
    "identification from 25 noisy samples: a plausible servo (was 1.4e7 s, R2 -0.017)",
    CORRECT,
)
def identify_25_samples(_: Probe) -> Evidence:
    from dataclasses import replace

    from rkmpc.learning.identification import TIME_CONSTANT_RANGE, identify
    from rkmpc.learning.servo_fit import SERVO_MIN_R2

    data = lap()
    n = 25
    noise = 0.02 * np.random.default_rng(7).standard_normal((n, 2))
    obs, next_obs = data.obs[:n].copy(), data.next_obs[:n].copy()
    obs[:, 6] += noise[:, 0]
    next_obs[:, 6] += noise[:, 1]
    small = replace(data, obs=obs, next_obs=next_obs, command=data.command[:n], episode=data.episode[:n])
    with caught_warnings() as seen:
        model = identify(small, scenario().vehicle)
    tau = model.servo_time_constant
    assert TIME_CONSTANT_RANGE[0] <= tau <= 1.0, tau
    if model.servo_structure == "nominal":  # too little to fit: the nominal servo, said so
        assert tau == scenario().vehicle.steering.time_constant
        said = [str(w.message) for w in seen if "servo" in str(w.message)]
        assert said, [str(w.message) for w in seen]
        return Evidence(CORRECT, f"nominal servo kept (tau {tau:g} s), warned: {said[0]}")
    assert model.servo_fit_r2 >= SERVO_MIN_R2, model.servo_fit_r2
    return Evidence(CORRECT, f"servo {model.servo_structure}: tau {tau:.3g} s, R2 {model.servo_fit_r2:.2f}")


def _edited_identified(probe: Probe, gradient: float) -> Evidence:
    from rkmpc.learning.io import load_model, save_identified

    path = probe.path("lmpc-id.json")
    save_identified(models()["lmpc-id"], path)
    load_model(path, "identified")  # as written: fine
    payload = json.loads(path.read_text())
    payload["model"]["understeer_gradient"] = gradient
    path.write_text(json.dumps(payload))
    return raises(lambda: load_model(path, "identified"), "lmpc-id.json [model]", "understeer_gradient")


@case("learn.identified_k_negative", LEARNING, "a hand-edited identified model with K = -5", CLEAR_ERROR)
def identified_k_negative(probe: Probe) -> Evidence:
    return _edited_identified(probe, -5.0)


@case("learn.identified_k_huge", LEARNING, "a hand-edited identified model with K = 1e6", CLEAR_ERROR)
def identified_k_huge(probe: Probe) -> Evidence:
    return _edited_identified(probe, 1e6)


@case(
    "learn.raceline_off_track",
    LEARNING,
    "a race line 500 m from the track (was lateral error 0.000)",
    CLEAR_ERROR,
)
def raceline_off_track(probe: Probe) -> Evidence:
    center = write_centerline(probe.path("ring.csv"), ellipse(100.0, 60.0), width=5.0)
    race = probe.path("race.csv")
    race.write_text("# x_m,y_m\n" + "\n".join(f"{x},{y}" for x, y in ellipse(95.0, 55.0, dx=500.0)) + "\n")
    out = probe.path("out")
    args = ["run", "--controller", "pp", "--track", str(center), "--raceline", str(race), "--out", str(out)]
    evidence = cli_error(probe, args, "race.csv", "leaves the track")
    assert not out.exists()
    return evidence


#: A thin hairpin loop: its polyline does not cross itself, the spline through it does.
HAIRPIN = [(0, 0), (4, 0), (8, 0), (8.6, 0), (8.6, 0.3), (8, 0.3), (4, 0.3), (0, 0.3), (-0.6, 0.3), (-0.6, 0)]


@case(
    "learn.spline_crossing",
    LEARNING,
    "a centre line whose spline crosses itself though its polyline does not",
    CLEAR_ERROR,
)
def spline_crossing(probe: Probe) -> Evidence:
    from rkmpc.track.loaders import find_self_intersection, load_centerline

    points = np.asarray(HAIRPIN, dtype=float)
    assert find_self_intersection(points) is None
    path = write_centerline(probe.path("hairpin.csv"), points, width=0.05)
    return raises(lambda: load_centerline(path), "hairpin.csv")


# ------------------------------------------------------------------ resource abuse


def _npy_header(shape: tuple[int, ...]) -> bytes:
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return header.getvalue()


@case(
    "resource.npz_declares_huge_arrays",
    RESOURCES,
    "a small .npz declaring 7.8 GiB arrays, given to train",
    CLEAR_ERROR,
)
def npz_declares_huge(probe: Probe) -> Evidence:
    bomb = probe.path("bomb.npz")
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("obs.npy", _npy_header((2**30 // 7 * 7, 7))[:200] + bytes(64))
    size = bomb.stat().st_size
    assert size < 10_000
    out = probe.path("m.rkm")
    evidence = cli_error(
        probe, ["train", "--data", str(bomb), "--kind", "residual", "--out", str(out)], "bomb.npz"
    )
    assert "declares arrays" in evidence.message and "limit" in evidence.message
    assert not out.exists()
    return evidence


@case(
    "resource.model_file_expands",
    RESOURCES,
    "a 2.4 MB model file unpacking to 520 MiB: refused from its headers at once",
    CLEAR_ERROR,
)
def model_file_expands(probe: Probe) -> Evidence:
    from rkmpc.learning.koopman.model import KoopmanModel

    path = probe.path("big.rkm")
    mib = 520
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
        with archive.open("A_.npy", "w", force_zip64=True) as member:
            member.write(_npy_header((mib * 2**20 // 8,)))
            chunk = bytes(8 * 2**20)
            for _ in range(mib // 8):
                member.write(chunk)
    assert path.stat().st_size < 4 * 2**20
    start = time.perf_counter()
    evidence = raises(lambda: KoopmanModel.load(path), "big.rkm", "limit of 512 MiB")
    assert time.perf_counter() - start < 5.0
    return evidence


def _oval(probe: Probe, factor: float) -> Path:
    return write_centerline(probe.path("oval.csv"), factor * ellipse(10.0, 6.0, n=60), width=1.0)


@case("resource.scale_1e6", RESOURCES, "--scale 1e6 (ran for ~5e11 s with no output)", CLEAR_ERROR)
def scale_1e6(probe: Probe) -> Evidence:
    track = _oval(probe, 1.0)
    args = [
        "run",
        "--controller",
        "pp",
        "--track",
        str(track),
        "--scale",
        "1e6",
        "--out",
        str(probe.path("o")),
    ]
    return cli_error(probe, args, "oval.csv", "more than 100 km")


@case("resource.coordinates_1e9", RESOURCES, "track coordinates x 1e9", CLEAR_ERROR)
def coordinates_1e9(probe: Probe) -> Evidence:
    track = _oval(probe, 1e9)
    args = ["run", "--controller", "pp", "--track", str(track), "--out", str(probe.path("o"))]
    return cli_error(probe, args, "oval.csv", "more than 100 km")


@case("resource.time_limit_bounded", RESOURCES, "an endless time limit for a run", CLEAR_ERROR)
def time_limit_bounded(_: Probe) -> Evidence:
    from rkmpc.sim.closed_loop import SimConfig

    return raises(lambda: SimConfig(max_time=float("inf")), "max_time must be finite")
