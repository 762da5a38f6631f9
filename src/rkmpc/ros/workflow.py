"""``rkmpc car-loop``: the paper's on-car workflow end to end, on one machine over ROS 2.

Every stage is a command a team runs with its car, started here as processes that talk over
ROS 2 on this machine only (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, a domain id of the
run's own), with ``rkmpc sim-node`` in the car's place:

1. **record**: ``rkmpc sim-node`` drives two laps while ``rkmpc node`` runs the LMPC and records
   what it saw and sent (``--record``) to ``record/bag`` (MCAP);
2. **import**: ``rkmpc collect --from-bag record/bag --steer-topic /rkmpc/steering`` gives
   ``data/laps.npz``;
3. **train**: ``rkmpc train --kind residual`` and ``--kind identified`` (the recipes' settings
   and seed 0, as ``rkmpc compare`` learns them) give ``models/``;
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
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from rkmpc.core.errors import ParameterError, RkmpcError
from rkmpc.core.io import check_output_folder, write_json_atomic
from rkmpc.ros.sim_config import CLOCKS
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


@dataclass(frozen=True)
class WorkflowConfig:
    """What ``rkmpc car-loop`` runs (SI units).

    Parameters
    ----------
    out : str
        The output folder (must not exist or be empty, unless ``force``).
    clock : str
        ``"lockstep"`` (default) or ``"realtime"`` (:data:`rkmpc.ros.sim_config.CLOCKS`).
    track : str
        Built-in track name or TUM centre-line CSV.
    record_laps : int
        LMPC laps recorded for training (the paper's two).
    controllers : tuple of str
        Controllers of Table II, driven a lap each.
    delay : float
        Added actuation delay (s) of the latency-compensation runs; 0 skips them.
    delay_controllers : tuple of str
        Controllers driven with the added delay, with and without compensation.
    seed : int
        Seed of the simulated car and of the training.
    domain_id : int or None
        ``ROS_DOMAIN_ID`` of the run (0-101); None picks one from the process id.
    force : bool
        Replace an earlier ``car-loop`` output folder.
    timeout : float
        Wall-clock bound (s) of each process: a guard against a hang, never a measure.
    """

    out: str
    clock: str = "lockstep"
    track: str = "builtin"
    record_laps: int = 2
    controllers: tuple[str, ...] = ("lmpc", "lmpc-id", "rkmpc")
    delay: float = 0.05
    delay_controllers: tuple[str, ...] = ("lmpc", "rkmpc")
    seed: int = 0
    domain_id: int | None = None
    force: bool = False
    timeout: float = 3600.0

    def __post_init__(self) -> None:
        from rkmpc.learning.recipes import recipe_for

        if self.clock not in CLOCKS:
            raise ParameterError(f"clock must be one of {list(CLOCKS)}, got {self.clock!r}")
        if self.record_laps < 1:
            raise ParameterError(f"record_laps must be >= 1, got {self.record_laps}")
        if not (self.delay >= 0.0 and self.timeout > 0.0):
            raise ParameterError("delay must be >= 0 and timeout > 0")
        if self.domain_id is not None and not 0 <= self.domain_id <= 101:
            raise ParameterError(f"domain_id must be in 0-101, got {self.domain_id}")
        learned = {r.controller: r.kind for name in self.controllers if (r := recipe_for(name)) is not None}
        learned.update(
            {r.controller: r.kind for name in self.delay_controllers if (r := recipe_for(name)) is not None}
        )
        unsupported = sorted(name for name, kind in learned.items() if kind not in ("residual", "identified"))
        if unsupported:
            raise ParameterError(
                f"the workflow trains residual and identified models only, not for {unsupported}"
            )


@dataclass
class _Run:
    """Processes started by the workflow, their environment and where their output goes."""

    config: WorkflowConfig
    out: Path
    env: dict[str, str]
    say: Callable[[str], None]
    processes: list[tuple[subprocess.Popen[bytes], Path]] = field(default_factory=list)
    commands: list[str] = field(default_factory=list)

    def start(self, name: str, args: list[str]) -> subprocess.Popen[bytes]:
        log = self.out / "logs" / f"{name}.log"
        self.commands.append("rkmpc " + " ".join(args))
        with log.open("wb") as sink:
            # A session of its own: a Ctrl-C at the terminal reaches the workflow, which stops its
            # processes in order (the node then closes its bag).
            process = subprocess.Popen(
                [sys.executable, "-m", "rkmpc.cli", *args],
                env=self.env,
                stdout=sink,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        self.processes.append((process, log))
        return process

    def log_of(self, process: subprocess.Popen[bytes]) -> Path:
        return next(log for p, log in self.processes if p is process)

    def run(self, name: str, args: list[str]) -> str:
        """Run a command to its end; its output, or a :class:`WorkflowError`."""
        process = self.start(name, args)
        try:
            code = process.wait(timeout=self.config.timeout)
        except subprocess.TimeoutExpired:
            log = self.log_of(process)
            raise WorkflowError(f"{name}: no end within {self.config.timeout:g} s; see {log}") from None
        text = self.log_of(process).read_text(errors="replace")
        if code != 0:
            raise WorkflowError(f"{name} failed (exit {code}): {_tail(text)} (log: {self.log_of(process)})")
        return text

    def stop(self, process: subprocess.Popen[bytes]) -> int:
        """Ctrl-C (SIGINT), then SIGTERM, then SIGKILL, each after a grace period; the exit status."""
        for stop, grace in ((signal.SIGINT, _GRACE_S), (signal.SIGTERM, 5.0), (signal.SIGKILL, None)):
            if process.poll() is not None:
                break
            process.send_signal(stop)
            try:
                process.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                continue
        return int(process.returncode)

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
    run = _Run(config, out, _environment(config, out), tell)
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
    data = out / "data" / "laps.npz"
    bag = str(out / "record" / "bag")
    imported = run.run(
        "collect", ["collect", "--from-bag", bag, "--steer-topic", STEERING_TOPIC, "--out", str(data)]
    )
    models: dict[str, dict[str, str]] = {}
    tell("3/5 training the residual model and identifying the car")
    for kind, name in (("residual", "residual.npz"), ("identified", "identified.json")):
        path = out / "models" / name
        text = run.run(
            f"train-{kind}",
            ["train", "--data", str(data), "--kind", kind, "--seed", str(config.seed), "--out", str(path)],
        )
        models[kind] = {"file": str(path), "report": text.strip()}
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


def _car_file(
    run: _Run, name: str, controller: str, models: dict[str, dict[str, str]], delay: float, compensate: bool
) -> Path:
    """The node's YAML file of a run (JSON values are YAML)."""
    from rkmpc.learning.recipes import recipe_for

    settings: dict[str, Any] = {
        "track": run.config.track,
        "controller": controller,
        "trigger": "odometry" if run.config.clock == "lockstep" else "timer",
        "topics": {"steering": STEERING_TOPIC},
    }
    recipe = recipe_for(controller)
    if recipe is not None:
        settings["model"] = models[recipe.kind]["file"]
    if compensate:
        settings["latency"] = {"compensate": True, "actuation": delay}
    path = run.out / "cars" / f"{name}.yaml"
    path.write_text("".join(f"{key}: {json.dumps(value)}\n" for key, value in settings.items()))
    return path


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
    config = run.config
    car = _car_file(run, name, controller, models or {}, delay, compensate)
    node_args = ["node", "--config", str(car), "--out", str(folder / "node")]
    node = run.start(f"{name}-node", node_args + ([] if bag is None else ["--record", str(bag)]))
    bound = str(config.timeout)
    sim_args = ["sim-node", "--track", config.track, "--clock", config.clock, "--laps", str(laps)]
    sim_args += [
        "--steering-topic",
        STEERING_TOPIC,
        "--seed",
        str(config.seed),
        "--actuation-delay",
        str(delay),
    ]
    sim_args += ["--startup-timeout", bound, "--answer-timeout", bound, "--out", str(folder / "sim")]
    sim = run.start(f"{name}-sim", sim_args)
    deadline = time.monotonic() + config.timeout
    while sim.poll() is None:
        if node.poll() is not None:
            raise WorkflowError(f"{name}: rkmpc node ended early: {_tail(run.log_of(node).read_text())}")
        if time.monotonic() > deadline:
            raise WorkflowError(
                f"{name}: the lap took longer than {config.timeout:g} s; see {run.log_of(sim)}"
            )
        time.sleep(0.2)
    if sim.returncode != 0 and not (folder / "sim" / "summary.json").is_file():
        # The car failed without a lap to report (a bad track, say; a lap that ends off the track
        # exits 1 too, with its summary): its log says why. The node, stopped now, may not yet
        # have got as far as its own error.
        run.stop(node)
        raise WorkflowError(
            f"{name}: rkmpc sim-node failed (exit {sim.returncode}): {_tail(run.log_of(sim).read_text())}"
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
