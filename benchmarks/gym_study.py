"""rkmpc against the LMPC in the real F1TENTH gym v1.0.0, learned from two LMPC laps driven there.

For each track the script puts the track into the gym (:func:`rkmpc.envs.f1tenth_gym.gym_map`),
makes the gym's environment with its own observation (default ``original``: pose, speed, yaw rate;
no wheel angle, no lateral velocity) and drives, through the documented adapter
(:func:`rkmpc.envs.adapter.run_episode`), controllers built for the car that declares the gym's
sensors (:func:`rkmpc.envs.f1tenth_gym.gym_car`, :func:`rkmpc.sim.build.build_controller`: the
state estimator stands in front of every controller where the gym does not measure a field):

1. the LMPC drives ``--data-laps`` laps from a standing start; :meth:`Episode.dataset` is the data
   set, its unmeasured fields NaN;
2. each learned controller's model is learned from it (:func:`rkmpc.experiments.training.estimated_for`:
   the wheel angle and slip of a Koopman model's data are the state estimator's smoothed ones, the
   wheel angle propagated through the servo the data show; :func:`rkmpc.learning.learn.learn`);
3. every controller drives ``--run-laps`` laps from a standing start; the LAST lap is measured from
   the gym's true state at every 0.01 s step (``info`` of :class:`~rkmpc.envs.f1tenth_gym.TrackProgress`).

Everything is seeded (``--seed``: the training; the gym is deterministic) and capped by epochs, not
time. It writes ``OUT/gym_study.json`` (settings, versions, every run's figures and status counts)
and ``OUT/gym_study.md`` (the table), and keeps the data sets and models in ``OUT/<track>/``
(``--reuse DIR`` reads those of an earlier study in DIR made with the same data and learning
settings instead of collecting and learning again: to compare driving settings on the same models).

Run: ``OMP_NUM_THREADS=1 python benchmarks/gym_study.py --tracks builtin,Monza,Silverstone
--controllers lmpc,lmpc-id,rkmpc --out runs/gym-study``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.analysis.tables import markdown
from rkmpc.config.loader import load_preset
from rkmpc.control.learned.residual_config import RKMPCConfig
from rkmpc.control.learned.trust import TrustConfig
from rkmpc.core.errors import ParameterError
from rkmpc.core.io import write_json_atomic, write_text_atomic
from rkmpc.core.versions import versions
from rkmpc.envs.adapter import Episode, run_episode
from rkmpc.envs.f1tenth_gym import (
    GYM_ESTIMATOR,
    TrackProgress,
    gym_car,
    gym_map,
    gym_policy,
    make_gym_env,
    start_pose,
)
from rkmpc.estimation.labels import estimate_dataset
from rkmpc.estimation.steering import SteeringModel
from rkmpc.experiments.studies.common import track_label
from rkmpc.experiments.training import estimated_for
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.io import load_model
from rkmpc.learning.learn import learn, save_learned
from rkmpc.learning.recipes import KoopmanLearner, Recipe, recipe_for
from rkmpc.sim.build import build_controller
from rkmpc.sim.scenario import Scenario

#: The shared data beside the repository (``../shared``); ``--shared`` gives another folder.
SHARED = Path(__file__).resolve().parents[1].parent / "shared"
#: Steering models the learned data may be estimated with: the servo the data show (the default of
#: ``estimated_for``) or the car's nominal one.
STEERING = ("data", "nominal")
#: The state estimator's tuning: the gym's exact measurements (``GYM_ESTIMATOR``) or the car's own.
ESTIMATORS = ("gym", "car")


@dataclass(frozen=True, kw_only=True)
class GymStudySettings:
    """What the study does (see the module notes); every field is recorded in the JSON file."""

    tracks: tuple[str, ...]
    controllers: tuple[str, ...]
    seed: int = 0
    epochs: int | None = None
    data_laps: int = 2
    run_laps: int = 2
    observation: str = "original"
    steering: str = "data"
    estimator: str = "gym"
    rkmpc: RKMPCConfig = field(default_factory=lambda: load_preset("f1tenth").controllers.rkmpc)

    def __post_init__(self) -> None:
        if "lmpc" not in self.controllers:
            raise ParameterError(
                f"GymStudySettings.controllers must include lmpc (the baseline), got {self.controllers}"
            )
        if self.data_laps < 1 or self.run_laps < 1:
            raise ParameterError(
                "GymStudySettings: data_laps and run_laps must be >= 1, "
                f"got {self.data_laps}, {self.run_laps}"
            )
        if self.estimator not in ESTIMATORS:
            raise ParameterError(
                f"GymStudySettings.estimator must be one of {ESTIMATORS}, got {self.estimator!r}"
            )
        if self.steering not in STEERING:
            raise ParameterError(
                f"GymStudySettings.steering must be one of {STEERING}, got {self.steering!r}"
            )

    def learning_key(self, track: str) -> str:
        """A short hash of what shapes a track's data and models (the files of ``--reuse``)."""
        spec = {
            "track": track,
            "seed": self.seed,
            "epochs": self.epochs,
            "data_laps": self.data_laps,
            "observation": self.observation,
            "steering": self.steering,
            "estimator": self.estimator,
        }
        return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:10]

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def _track_spec(name: str, shared: Path) -> str:
    """A track name as the study takes it: ``builtin``, a shared track's name or a CSV file."""
    if name == "builtin" or Path(name).suffix:
        return name
    return str(shared / "tracks" / "centerlines" / f"{name}.csv")


def _with_rkmpc(scenario: Scenario, config: RKMPCConfig) -> Scenario:
    car = scenario.car
    return replace(scenario, car=replace(car, controllers=replace(car.controllers, rkmpc=config)))


def _drive(
    env: TrackProgress, scenario: Scenario, controller: Any, laps: int
) -> tuple[Episode, list[dict[str, float]]]:
    """Drive ``laps`` laps from a standing start at the reference's first point; every step's info."""
    steps: list[dict[str, float]] = []

    def keep(info: Any) -> None:
        steps.append({k: float(info[k]) for k in ("time", "progress_laps", "lateral_error", "heading_error")})

    env.max_laps = laps
    # A lap of the slowest car takes well under four times the reference's lap time.
    limit = int(4 * laps * scenario.reference.lap_time / 0.01) + 1000
    episode = run_episode(
        env,
        gym_policy(controller, env),
        options={"poses": start_pose(scenario.reference.path)},
        max_steps=limit,
        on_step=keep,
    )
    return episode, steps


def _metrics(episode: Episode, steps: list[dict[str, float]], laps: int) -> dict[str, Any]:
    """The figures of the last of ``laps`` laps (the gym's true state at every step)."""
    progress = np.array([s["progress_laps"] for s in steps])
    rows = (progress >= laps - 1) & (progress < laps)
    lateral = np.abs([s["lateral_error"] for s in steps])[rows]
    heading = np.abs([s["heading_error"] for s in steps])[rows]
    log = episode.log
    stepped = np.isfinite(np.asarray(log["status"], dtype=float))
    times = np.asarray(log["t"])[stepped]
    lap_start = float(np.array([s["time"] for s in steps])[rows][0]) if rows.any() else math.inf
    commands = np.asarray(log["cmd_steer"])[stepped][times >= lap_start]
    laps_done = episode.info.get("completed_lap_times", [])
    completed = len(laps_done) >= laps
    return {
        "completed": completed,
        "outcome": episode.info.get("outcome"),
        "progress_laps": float(episode.info.get("progress_laps", math.nan)),
        "lap_time_s": float(laps_done[laps - 1]) if completed else None,
        "lateral_error_mean_m": float(lateral.mean()) if lateral.size else None,
        "lateral_error_max_m": float(lateral.max()) if lateral.size else None,
        "heading_error_mean_rad": float(heading.mean()) if heading.size else None,
        "command_rate_mean_rad_s": float(np.mean(np.abs(np.diff(commands)))) / episode.control_period
        if commands.size > 1
        else None,
        "status_counts": dict(sorted(episode.status_counts.items())),
        "guard_steps": int(episode.status_counts.get("guard", 0)),
        "fallback_steps": int(episode.fallback_count),
        "control_steps": int(episode.control_steps),
        "unmeasured": list(episode.unmeasured),
    }


def _learned_data(
    recipe: Recipe, data: TransitionDataset, scenario: Scenario, steering: str
) -> TransitionDataset:
    """The data the recipe learns from (``estimated_for``, or estimated with the nominal servo)."""
    if steering == "data" or not isinstance(recipe.learner, KoopmanLearner):
        return estimated_for(recipe, data, scenario.vehicle, scenario.car.estimator)
    config = replace(scenario.car.estimator, control_period=data.dt)
    return estimate_dataset(
        data, scenario.vehicle, steering=SteeringModel.nominal(scenario.vehicle), config=config
    )


def _models(
    settings: GymStudySettings, scenario: Scenario, env: TrackProgress, folder: Path, reuse: Path | None
) -> tuple[dict[str, object], dict[str, Any]]:
    """The LMPC's data set of the track and every learned controller's model (read from ``reuse``)."""
    earlier = None if reuse is None else reuse / folder.name
    record: dict[str, Any] = {}
    if earlier is not None and (earlier / "lmpc_laps.npz").is_file():
        data = TransitionDataset.load(earlier / "lmpc_laps.npz")
        record["data"] = {"reused": str(earlier / "lmpc_laps.npz"), "transitions": len(data)}
    else:
        data_file = folder / "lmpc_laps.npz"
        episode, steps = _drive(env, scenario, build_controller("lmpc", scenario), settings.data_laps)
        meta = {"controller": "lmpc", "laps": settings.data_laps, "track": scenario.track.name}
        data = episode.dataset(metadata=meta, made_with=scenario.provenance())
        data.save(data_file)
        record["data"] = {"transitions": len(data), **_metrics(episode, steps, settings.data_laps)}
    models: dict[str, object] = {}
    for name in settings.controllers:
        recipe = recipe_for(name)
        if recipe is None:
            continue
        file = f"{name}.{'json' if recipe.kind == 'identified' else 'npz'}"
        if earlier is not None and (earlier / file).is_file():
            models[name] = load_model(earlier / file, recipe.kind)
            record[name] = {"reused": str(earlier / file)}
            continue
        path = folder / file
        learned = learn(
            recipe,
            _learned_data(recipe, data, scenario, settings.steering),
            made_for=replace(scenario.provenance(), scale=None),
            vehicle=scenario.vehicle,
            seed=settings.seed,
            epochs=settings.epochs,
        )
        save_learned(learned, path)
        models[name] = learned.model
        record[name] = {"warnings": list(learned.warnings)}
    return models, record


def run_track(
    settings: GymStudySettings, track: str, out: Path, *, shared: Path, reuse: Path | None
) -> dict[str, Any]:
    """Collect, learn and drive every controller on one track; its record."""
    estimator = GYM_ESTIMATOR if settings.estimator == "gym" else None
    car = gym_car(observation=settings.observation, estimator=estimator)
    scenario = _with_rkmpc(Scenario.from_car(car, _track_spec(track, shared)), settings.rkmpc)
    folder = out / f"{track_label(track)}-{settings.learning_key(track)}"
    folder.mkdir(parents=True, exist_ok=True)
    map_dir = gym_map(scenario.track, out / "maps", reference=scenario.reference)
    env = make_gym_env(scenario, map_dir, observation=settings.observation)
    models, learned = _models(settings, scenario, env, folder, reuse)
    runs: dict[str, Any] = {}
    for name in settings.controllers:
        controller = build_controller(name, scenario, models.get(name))
        episode, steps = _drive(env, scenario, controller, settings.run_laps)
        runs[name] = {
            "controller_class": type(controller).__name__,
            **_metrics(episode, steps, settings.run_laps),
            "diagnostics": {k: float(v) for k, v in controller.diagnostics().items()},
        }
        print(f"{track} {name}: {_line(runs[name])}", flush=True)
    return {"track": scenario.track.name, "sensors": car.sensors.name, "learning": learned, "runs": runs}


def _line(run: dict[str, Any]) -> str:
    if not run["completed"]:
        return f"{run['outcome']} at {run['progress_laps']:.2f} laps"
    return (
        f"lateral {run['lateral_error_mean_m']:.4f} mean {run['lateral_error_max_m']:.4f} max, heading "
        f"{run['heading_error_mean_rad']:.4f}, statuses {run['status_counts']}"
    )


def _pct(value: float | None, base: float | None) -> str:
    return "-" if value is None or base is None or base == 0 else f"{100.0 * (value - base) / base:+.0f} %"


def _cell(value: float | None, spec: str = ".4f") -> str:
    return "-" if value is None else format(value, spec)


def table(tracks: list[dict[str, Any]]) -> str:
    """The Markdown table of the study: per track and controller, the figures and the change vs LMPC."""
    header = [
        "track",
        "controller",
        "lap",
        "lateral mean (m)",
        "vs LMPC",
        "lateral max (m)",
        "vs LMPC",
        "heading mean (rad)",
        "vs LMPC",
        "cmd rate (rad/s)",
        "guard",
        "steps",
    ]
    rows = []
    for entry in tracks:
        base = entry["runs"]["lmpc"]
        for name, run in entry["runs"].items():
            rows.append(
                [
                    entry["track"],
                    name,
                    "yes" if run["completed"] else f"no ({run['outcome']})",
                    _cell(run["lateral_error_mean_m"]),
                    _pct(run["lateral_error_mean_m"], base["lateral_error_mean_m"]),
                    _cell(run["lateral_error_max_m"]),
                    _pct(run["lateral_error_max_m"], base["lateral_error_max_m"]),
                    _cell(run["heading_error_mean_rad"]),
                    _pct(run["heading_error_mean_rad"], base["heading_error_mean_rad"]),
                    _cell(run["command_rate_mean_rad_s"], ".3f"),
                    str(run["guard_steps"]),
                    str(run["control_steps"]),
                ]
            )
    return markdown(header, rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tracks",
        default="builtin,Monza,Silverstone",
        help="comma-separated: builtin, shared track names (read at scale 0.1) or CSV files",
    )
    parser.add_argument("--controllers", default="lmpc,lmpc-id,rkmpc", help="comma-separated; lmpc first")
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument("--epochs", type=int, default=None, help="training epochs (default: the recipe's)")
    parser.add_argument("--data-laps", type=int, default=2, help="LMPC laps of data")
    parser.add_argument("--run-laps", type=int, default=2, help="laps driven; the last is measured")
    parser.add_argument("--observation", default="original", help="the gym's observation type")
    parser.add_argument(
        "--steering",
        choices=STEERING,
        default="data",
        help="servo the learned data's wheel angle is estimated with",
    )
    parser.add_argument(
        "--estimator",
        choices=ESTIMATORS,
        default="gym",
        help="state estimator tuning: the gym's or the car's",
    )
    parser.add_argument(
        "--slip-drift",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="rkmpc: RKMPCConfig.slip_drift (default: the f1tenth preset's)",
    )
    parser.add_argument("--steer-rate-weight", type=float, default=None, help="rkmpc: RKMPCConfig field")
    parser.add_argument("--lateral-accel-weight", type=float, default=None, help="rkmpc: RKMPCConfig field")
    parser.add_argument("--no-trust", action="store_true", help="rkmpc: the trust guard off")
    parser.add_argument("--shared", type=Path, default=SHARED, help="the shared data folder (its tracks)")
    parser.add_argument(
        "--reuse", type=Path, default=None, help="an earlier study's folder: its data sets and models"
    )
    args = parser.parse_args()
    # rkmpc as the f1tenth preset tunes it (tuned once, on the project's own plant); flags change it.
    config = load_preset("f1tenth").controllers.rkmpc
    changes: dict[str, Any] = {}
    if args.slip_drift is not None:
        changes["slip_drift"] = args.slip_drift
    if args.steer_rate_weight is not None:
        changes["steer_rate_weight"] = args.steer_rate_weight
    if args.lateral_accel_weight is not None:
        changes["lateral_accel_weight"] = args.lateral_accel_weight
    if args.no_trust:
        changes["trust"] = TrustConfig(enabled=False)
    settings = GymStudySettings(
        tracks=tuple(args.tracks.split(",")),
        controllers=tuple(args.controllers.split(",")),
        seed=args.seed,
        epochs=args.epochs,
        data_laps=args.data_laps,
        run_laps=args.run_laps,
        observation=args.observation,
        steering=args.steering,
        estimator=args.estimator,
        rkmpc=replace(config, **changes),
    )
    args.out.mkdir(parents=True, exist_ok=True)
    tracks = [
        run_track(settings, track, args.out, shared=args.shared, reuse=args.reuse)
        for track in settings.tracks
    ]
    text = table(tracks)
    write_json_atomic(
        args.out / "gym_study.json",
        {"settings": settings.to_json(), "versions": versions(), "tracks": tracks},
    )
    write_text_atomic(args.out / "gym_study.md", text + "\n")
    print(text)


if __name__ == "__main__":
    main()
