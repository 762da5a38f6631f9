"""``rkmpc car-loop``: the paper's on-car workflow end to end, on one machine over ROS 2.

Every stage is what a command a team runs with its car does, called here as a function: the ROS
nodes in processes of their own (:func:`rkmpc.ros.node.run_node`, :func:`rkmpc.ros.sim_node.run_sim_node`)
that talk over ROS 2 on this machine only (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, a domain id
of the run's own), with the simulated car in the car's place; the import and the learning in this
process. The car is one :class:`~rkmpc.config.car.CarConfig` (the f1tenth preset, its ``[ros]``
section set for each run), written to ``cars/<run>.json``:

1. **record**: the simulated car drives two laps while the node runs the LMPC and records
   what it saw and sent to ``record/bag`` (MCAP);
2. **import**: the bag (:func:`rkmpc.learning.data.bags.import_bag`, the measured wheel angle of
   ``/rkmpc/steering``) gives ``data/laps.npz``;
3. **learn**: the residual and the identified models (the recipes' settings and the seed, as
   ``rkmpc compare`` learns them: :func:`rkmpc.experiments.training.train_to_file`) give ``models/``;
4. **drive**: the LMPC, ``lmpc-id`` and RKMPC drive a lap each (``runs/<controller>``);
5. **latency**: with an added actuation delay (``sim-node --actuation-delay``), the LMPC and
   RKMPC drive a lap with and without the node's latency compensation (``delay/<run>``);
6. **report**: the paper's Table II of this run and the latencies, printed and written to
   ``table2.json`` and ``table2.md`` (:mod:`rkmpc.ros.workflow_report`).

The clock is lock-step by default (the car waits for each command, so the results do not depend
on how busy the machine is, the project's rule for results); ``clock="realtime"`` runs the car
on the wall clock, as a car would, and the node on its 20 Hz timer. Each process writes its
output to ``logs/``; every process is stopped (Ctrl-C, then killed after a grace period) when
the workflow ends, fails or is interrupted.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.config.ros import LatencySettings
from rkmpc.core.errors import RkmpcError
from rkmpc.core.io import check_output_folder, write_json_atomic
from rkmpc.ros.config import NodeTask
from rkmpc.ros.processes import child_process, node_process, sim_node_process
from rkmpc.ros.sim_config import SimNodeConfig
from rkmpc.ros.workflow_config import WorkflowConfig
from rkmpc.ros.workflow_report import build_report, write_report

__all__ = ["MARKER", "STEERING_TOPIC", "WorkflowConfig", "WorkflowError", "prepare_folder", "run_workflow"]

#: The file that marks a folder as a ``car-loop`` output (``--force`` replaces only such folders).
MARKER = "car_loop.json"
#: The topic of the wheel angle the simulated car measures (``std_msgs/msg/Float64``, rad).
STEERING_TOPIC = "/rkmpc/steering"
#: Wall-clock seconds a process may take to stop after Ctrl-C before it is killed.
_GRACE_S = 30.0


class WorkflowError(RkmpcError):
    """A stage of the workflow failed (names the stage and the log to read)."""


@dataclass
class _Run:
    """Processes started by the workflow, their environment and where their output goes."""

    config: WorkflowConfig
    out: Path
    env: dict[str, str]
    say: Callable[[str], None]
    car: CarConfig
    processes: list[tuple[Any, Path]] = field(default_factory=list)
    commands: list[str] = field(default_factory=list)

    def start(self, name: str, target: Callable[..., int], args: tuple[Any, ...], what: str) -> Any:
        """Start ``target(*args)`` in a process of its own (spawned: nothing of this one is inherited)."""
        log = self.out / "logs" / f"{name}.log"
        # Made here, not only in the child: a stage stopped before its process got going (another
        # failed first) still has its (empty) log, which errors and users read.
        log.touch()
        self.commands.append(what)
        process = multiprocessing.get_context("spawn").Process(
            target=child_process, args=(name, target, args, str(log), self.env), name=name
        )
        process.start()
        self.processes.append((process, log))
        return process

    def log_of(self, process: Any) -> Path:
        return next(log for p, log in self.processes if p is process)

    def stop(self, process: Any) -> int:
        """Ctrl-C (SIGINT), then SIGTERM, then SIGKILL, each after a grace period; the exit status."""
        for stop, grace in ((signal.SIGINT, _GRACE_S), (signal.SIGTERM, 5.0), (signal.SIGKILL, None)):
            if process.exitcode is not None or process.pid is None:
                break
            try:
                os.kill(process.pid, stop)
            except ProcessLookupError:
                break
            process.join(grace)
        process.join()
        return int(process.exitcode)

    def stop_all(self) -> None:
        for process, _ in reversed(self.processes):
            self.stop(process)


def prepare_folder(out: Path, force: bool) -> None:
    """Make ``out`` an empty folder; an earlier ``car-loop`` output only with ``force``."""
    # The car files name the models by absolute path: the workflow writes in ``out`` itself, not
    # in a temporary folder renamed at the end (:func:`rkmpc.core.io.output_folder`).
    if check_output_folder(out, force=force, markers=(MARKER,)):
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)


def run_workflow(config: WorkflowConfig, say: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the whole workflow (module docstring); returns the report written to ``table2.json``.

    Raises
    ------
    WorkflowError
        When a stage fails (a process exits with an error, the recording laps are not completed,
        the output folder is in use), naming the stage and its log.
    """
    tell = say if say is not None else (lambda _msg: None)
    out = Path(config.out).expanduser().resolve()  # the car files name the models by absolute path
    prepare_folder(out, config.force)
    for sub in ("logs", "cars", "models", "data"):
        (out / sub).mkdir()
    write_json_atomic(out / MARKER, {"config": asdict(config), "state": "running"})
    car = load_preset("f1tenth").with_sensors(config.sensors)
    run = _Run(config, out, _environment(config, out), tell, car)
    tell(f"ROS_DOMAIN_ID={run.env['ROS_DOMAIN_ID']}, discovery on this machine only, {config.clock} clock")
    try:
        report = _stages(run)
    finally:
        run.stop_all()
    write_json_atomic(out / MARKER, {"config": asdict(config), "state": "done", "commands": run.commands})
    return report


def _stages(run: _Run) -> dict[str, Any]:
    config, out, tell = run.config, run.out, run.say
    tell(f"1/5 recording {config.record_laps} LMPC laps to {out / 'record' / 'bag'}")
    record = _drive(
        run, "record", out / "record", "lmpc", laps=config.record_laps, bag=out / "record" / "bag"
    )
    if record["sim"]["outcome"] != "completed":
        raise WorkflowError(f"the recording laps were not completed: {record['sim']['outcome']}")
    tell("2/5 importing the bag")
    imported = _import(run)
    models: dict[str, dict[str, str]] = {}
    tell("3/5 learning the residual model and identifying the car")
    for kind, name in (("residual", "residual.npz"), ("identified", "identified.json")):
        path = out / "models" / name
        models[kind] = {"file": str(path), "report": _learn(run, kind, path)}
    table: dict[str, dict[str, Any]] = {}
    for controller in config.controllers:
        tell(f"4/5 driving {controller} for a lap")
        table[controller] = _drive(
            run, controller, out / "runs" / controller, controller, laps=1, models=models
        )
    delayed: dict[str, dict[str, Any]] = {}
    if config.delay > 0.0:
        for controller in config.delay_controllers:
            for compensate in (False, True):
                label = f"{controller}{'+comp' if compensate else ''}"
                tell(f"5/5 {config.delay * 1e3:g} ms added actuation delay: {label}")
                delayed[label] = _drive(
                    run,
                    f"delay-{label}",
                    out / "delay" / label,
                    controller,
                    laps=1,
                    models=models,
                    delay=config.delay,
                    compensate=compensate,
                )
    report = build_report(
        config=asdict(config),
        record=record,
        imported=imported.strip(),
        models=models,
        table=table,
        delayed=delayed,
        commands=run.commands,
    )
    write_report(out, report)
    return report


def _environment(config: WorkflowConfig, out: Path) -> dict[str, str]:
    """The processes' environment: this rkmpc first on the path, localhost-only ROS 2, its own domain."""
    env = dict(os.environ)
    source = str(Path(__file__).resolve().parents[2])  # the folder this rkmpc package is in
    env["PYTHONPATH"] = os.pathsep.join([source, *filter(None, [env.get("PYTHONPATH")])])
    domain = config.domain_id if config.domain_id is not None else 1 + os.getpid() % 101
    env.update(
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_LOG_DIR=str(out / "logs" / "ros"),
    )
    return env


def _import(run: _Run) -> str:
    """The recorded bag as ``data/laps.npz`` (``rkmpc collect --from-bag``); its summary line."""
    from rkmpc.learning.data.bags import BagImportConfig, import_bag

    bag, data = run.out / "record" / "bag", run.out / "data" / "laps.npz"
    topic = f" --steer-topic {STEERING_TOPIC}" if run.car.sensors.measures_steer_angle else ""
    # The simulated car stamps its odometry when it sends it: the pose is the localiser's latency older.
    latency = run.car.sensors.pose_latency
    run.commands.append(f"rkmpc collect --from-bag {bag}{topic} --pose-latency {latency:g} --out {data}")
    steer = STEERING_TOPIC if run.car.sensors.measures_steer_angle else None
    imported = import_bag(bag, run.car.vehicle, BagImportConfig(steer_topic=steer, pose_latency=latency))
    imported.save(data)
    episodes = len(set(imported.episode.tolist()))
    return f"{len(imported)} transitions in {episodes} episode(s) from {bag} -> {data}"


def _learn(run: _Run, kind: str, path: Path) -> str:
    """The ``kind`` model of the imported laps (``rkmpc train --kind KIND``); what it printed."""
    from rkmpc.experiments.training import train_to_file
    from rkmpc.learning.contract import Provenance
    from rkmpc.learning.data.dataset import TransitionDataset

    data = run.out / "data" / "laps.npz"
    run.commands.append(f"rkmpc train --data {data} --kind {kind} --seed {run.config.seed} --out {path}")
    car = run.car
    made_for = Provenance(vehicle=car.preset, dt=car.ros.period, wheelbase=car.vehicle.wheelbase)
    lines = train_to_file(
        TransitionDataset.load(data),
        made_for,
        car.vehicle,
        kind,
        path,
        seed=run.config.seed,
        source=str(data),
    )
    return "\n".join(lines)


def _car_of(run: _Run, name: str, compensate: bool, delay: float) -> CarConfig:
    """The car of one run (its ``[ros]`` section), written to ``cars/<name>.json``."""
    ros = run.car.ros
    ros = replace(
        ros,
        trigger="odometry" if run.config.clock == "lockstep" else "timer",
        topics=replace(ros.topics, steering=STEERING_TOPIC if run.car.sensors.measures_steer_angle else None),
        odometry=replace(ros.odometry, lateral_velocity=run.car.sensors.measures_slip_angle),
        latency=LatencySettings(compensate=True, actuation=delay) if compensate else ros.latency,
    )
    car = replace(run.car, ros=ros)
    write_json_atomic(run.out / "cars" / f"{name}.json", car.to_json())
    return car


def _drive(
    run: _Run,
    name: str,
    folder: Path,
    controller: str,
    *,
    laps: int,
    models: dict[str, dict[str, str]] | None = None,
    bag: Path | None = None,
    delay: float = 0.0,
    compensate: bool = False,
) -> dict[str, Any]:
    """``sim-node`` and ``node`` for ``laps`` laps, their files in ``folder``; the two summaries."""
    from rkmpc.learning.recipes import recipe_for

    config = run.config
    car = _car_of(run, name, compensate, delay)
    recipe = recipe_for(controller)
    model = None if recipe is None else (models or {})[recipe.kind]["file"]
    task = NodeTask(track=config.track, controller=controller, model=model)
    bag_text = "" if bag is None else f" --record {bag}"
    node = run.start(
        f"{name}-node",
        node_process,
        (car, task, str(folder / "node"), None if bag is None else str(bag)),
        f"rkmpc node --config cars/{name}.json --track {config.track} --controller {controller}"
        + ("" if model is None else f" --model {model}")
        + bag_text,
    )
    bound = config.timeout
    sim_config = SimNodeConfig(
        car=car,
        track=config.track,
        clock=config.clock,
        laps=laps,
        steering_topic=STEERING_TOPIC if car.sensors.measures_steer_angle else "",
        seed=config.seed,
        actuation_delay=delay,
        startup_timeout=bound,
        answer_timeout=bound,
    )
    sim = run.start(
        f"{name}-sim",
        sim_node_process,
        (sim_config, str(folder / "sim")),
        f"rkmpc sim-node --track {config.track} --clock {config.clock} --laps {laps} "
        f"--sensors {car.sensors.name} --seed {config.seed} --actuation-delay {delay}",
    )
    deadline = time.monotonic() + config.timeout
    while sim.exitcode is None:
        if node.exitcode is not None:
            raise WorkflowError(f"{name}: rkmpc node ended early: {_tail(run.log_of(node).read_text())}")
        if time.monotonic() > deadline:
            raise WorkflowError(
                f"{name}: the lap took longer than {config.timeout:g} s; see {run.log_of(sim)}"
            )
        sim.join(0.2)
    if sim.exitcode != 0 and not (folder / "sim" / "summary.json").is_file():
        # The car failed without a lap to report (a bad track, say; a lap that ends off the track
        # exits 1 too, with its summary): its log says why. The node, stopped now, may not yet
        # have got as far as its own error.
        run.stop(node)
        raise WorkflowError(
            f"{name}: rkmpc sim-node failed (exit {sim.exitcode}): {_tail(run.log_of(sim).read_text())}"
        )
    node_code = run.stop(node)
    if node_code != 0:
        raise WorkflowError(
            f"{name}: rkmpc node failed (exit {node_code}): {_tail(run.log_of(node).read_text())}"
        )
    summaries: dict[str, Any] = {}
    for key, path in (
        ("sim", folder / "sim" / "summary.json"),
        ("node", folder / "node" / "node_summary.json"),
    ):
        if not path.is_file():
            process = sim if key == "sim" else node
            raise WorkflowError(f"{name}: no {path.name}: {_tail(run.log_of(process).read_text())}")
        summaries[key] = json.loads(path.read_text())
    summaries["controller"] = controller
    summaries["actuation_delay"] = delay
    summaries["compensate"] = compensate
    return summaries


def _tail(text: str, lines: int = 5) -> str:
    return " | ".join(line.strip() for line in text.strip().splitlines()[-lines:])
