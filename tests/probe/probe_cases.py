"""The case table of the probes (issues 13 and 27): every bad input, fault and newcomer's stumble, replayed.

A case is a small function ``case(probe) -> Evidence`` registered with :func:`case` under a stable
id, a one-line description and the outcome it must have:

``clear_error``
    an error of the project's types (:class:`~rkmpc.core.errors.RkmpcError`), or the CLI's exit
    status 2 with one ``rkmpc: error:`` line (argparse's ``SystemExit`` for options), whose message
    names the file, field or option at fault; never a traceback.
``graceful``
    a fall-back with a counted status, a warning, or a refusal with a message; the work goes on.
``correct``
    the result is right.

The case asserts what identifies the problem (raising ``AssertionError`` otherwise) and returns the
:class:`Evidence` it saw: the outcome class it observed and the message. The test module
(``test_probe.py``) and ``benchmarks/probe_table.py`` both run :func:`all_cases`, so the list is
written once. Cases import the project lazily, so the table is cheap to build.

A case of issue 27's probe also says what its problem was when the probe found it (``problem``:
one of :data:`PROBLEMS`, ``lost`` a recording or results lost, ``hang`` no end, ``silent`` a wrong
result with nothing said, ``traceback``, ``unclear`` an unclear or late message, ``friction`` a
newcomer's stumble): a case that fails again counts as that problem in the table's summary, a case
that passes as its expected outcome. A case that could hang runs :func:`within` a guard (a bound
against a hang, never what is measured).
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import io
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

CLEAR_ERROR = "clear_error"
GRACEFUL = "graceful"
CORRECT = "correct"
OUTCOMES = (CLEAR_ERROR, GRACEFUL, CORRECT)
#: What a case of issue 27 was when the probe found it (see the module).
PROBLEMS = ("lost", "hang", "silent", "traceback", "unclear", "friction")


class Hang(AssertionError):
    """A case ran past its guard (:func:`within`)."""


@dataclass(frozen=True)
class Evidence:
    """What a case saw: the outcome class and the message (or result) that shows it."""

    outcome: str
    message: str


@dataclass
class Run:
    """One in-process ``rkmpc`` command: exit status and what it printed."""

    code: int
    out: str
    err: str


@dataclass
class Probe:
    """What a case may use: a private folder and the in-process command line.

    ``readouterr`` is pytest's ``capsys.readouterr``; without it (the benchmark script) the
    output is captured with :func:`contextlib.redirect_stdout` and ``redirect_stderr``.
    """

    tmp: Path
    readouterr: Callable[[], Any] | None = None

    def cli(self, *argv: str) -> Run:
        """``rkmpc ARGV`` in this process (``rkmpc.cli.main``); argparse's ``SystemExit`` is a status."""
        from rkmpc.cli import main

        def call() -> int:
            try:
                return main(list(argv))
            except SystemExit as exc:
                return exc.code if isinstance(exc.code, int) else 1

        if self.readouterr is not None:
            self.readouterr()
            code = call()
            captured = self.readouterr()
            return Run(code, captured.out, captured.err)
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = call()
        return Run(code, out.getvalue(), err.getvalue())

    def path(self, name: str) -> Path:
        """A file or folder name in the private folder (not created)."""
        return self.tmp / name


@dataclass(frozen=True)
class Case:
    """One row of the table."""

    id: str
    group: str
    description: str
    expected: str
    run: Callable[[Probe], Evidence]
    slow: bool = False
    xfail: str | None = None
    see_also: tuple[str, ...] = field(default=())
    problem: str | None = None


_CASES: dict[str, Case] = {}


def case(
    case_id: str,
    group: str,
    description: str,
    expected: str,
    *,
    slow: bool = False,
    xfail: str | None = None,
    see_also: Sequence[str] = (),
    problem: str | None = None,
) -> Callable[[Callable[[Probe], Evidence]], Callable[[Probe], Evidence]]:
    """Register the decorated function as the case ``case_id``."""
    assert expected in OUTCOMES, expected
    assert problem is None or problem in PROBLEMS, problem

    def register(fn: Callable[[Probe], Evidence]) -> Callable[[Probe], Evidence]:
        assert case_id not in _CASES, f"duplicate case id {case_id}"
        _CASES[case_id] = Case(
            case_id, group, description, expected, fn, slow, xfail, tuple(see_also), problem
        )
        return fn

    return register


def all_cases() -> list[Case]:
    """Every case, in the order of the issue."""
    modules = ("probe_controllers", "probe_learning", "probe_outputs", "probe_messages")
    issue27 = ("probe_lost", "probe_hangs", "probe_silent", "probe_unclear", "probe_friction")
    for module in (*modules, *issue27):
        importlib.import_module(module)  # registers its cases
    return list(_CASES.values())


# ------------------------------------------------------------------ evidence helpers


def _one_line(text: str) -> str:
    return " ".join(text.split())


def raises(
    call: Callable[[], object], *needles: str, types: tuple[type[BaseException], ...] = ()
) -> Evidence:
    """``call()`` raises one of the project's errors (or ``types``) whose message has every needle."""
    from rkmpc.core.errors import RkmpcError

    expected: tuple[type[BaseException], ...] = (RkmpcError, *types)
    try:
        call()
    except expected as exc:
        message = str(exc)
    else:
        raise AssertionError("no error raised")
    for needle in needles:
        assert needle in message, f"{needle!r} not in {message!r}"
    return Evidence(CLEAR_ERROR, _one_line(message))


def cli_error(probe: Probe, argv: Sequence[str], *needles: str) -> Evidence:
    """``rkmpc ARGV`` ends with status 2 and a message (no traceback) that has every needle."""
    run = probe.cli(*argv)
    assert run.code == 2, (run.code, run.err[-500:])
    assert "Traceback" not in run.err, run.err[-2000:]
    lines = [line for line in run.err.splitlines() if "error:" in line]
    assert lines, run.err[-500:]
    for needle in needles:
        assert needle in run.err, f"{needle!r} not in {run.err[-500:]!r}"
    return Evidence(CLEAR_ERROR, _one_line(lines[-1]))


@contextlib.contextmanager
def within(seconds: float, what: str) -> Iterator[None]:
    """Raise :class:`Hang` when the block runs past ``seconds`` (a guard against a hang; main thread)."""
    import signal

    def alarm(*_: object) -> None:
        raise Hang(f"{what}: still running after {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


def warned(seen: Sequence[warnings.WarningMessage], category: type[Warning], *needles: str) -> str:
    """The one warning of ``category`` among ``seen`` (from :func:`caught_warnings`), with every needle."""
    said = [str(w.message) for w in seen if issubclass(w.category, category)]
    assert len(said) == 1, [str(w.message) for w in seen]
    for needle in needles:
        assert needle in said[0], f"{needle!r} not in {said[0]!r}"
    return _one_line(said[0])


@contextlib.contextmanager
def caught_warnings() -> Iterator[list[warnings.WarningMessage]]:
    """Every warning raised in the block, recorded (none printed)."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        yield seen


# ------------------------------------------------------------------ shared, built once


@functools.cache
def scenario() -> Any:
    """The built-in track with the f1tenth car."""
    from rkmpc.sim.scenario import load_scenario

    return load_scenario("builtin")


@functools.cache
def lap() -> Any:
    """One LMPC lap of the built-in track as a data set (about a second)."""
    from rkmpc.sim.collect import collect

    return collect(scenario(), laps=1)


@functools.cache
def models() -> dict[str, Any]:
    """A model of every learned controller from :func:`lap`, least squares only (a second)."""
    from rkmpc.learning.data.augmentation import AugmentConfig
    from rkmpc.learning.identification import identify
    from rkmpc.learning.koopman.model import KoopmanModel
    from rkmpc.learning.pipeline import TrainConfig, train_model

    sc = scenario()

    def fit(kind: str) -> Any:
        config = TrainConfig(kind=kind, augment=AugmentConfig(ratio=0.1), model=KoopmanModel(None))
        return train_model(lap(), sc.vehicle.wheelbase, config, vehicle=sc.vehicle_name)[0]

    return {
        "lmpc-id": identify(lap(), sc.vehicle),
        "rkmpc": fit("residual"),
        "kmpc": fit("koopman"),
        "rkmpc-paper": fit("paper"),
    }


def identified_model(probe: Probe) -> Any:
    """An identified model of :func:`lap` as ``rkmpc train --kind identified`` writes it (with a contract)."""
    from rkmpc.experiments.training import train_to_file
    from rkmpc.learning.contract import Provenance
    from rkmpc.learning.io import load_model

    sc = scenario()
    path = probe.path("lmpc-id.json")
    made_for = Provenance(vehicle=sc.vehicle_name, dt=sc.dt, wheelbase=sc.vehicle.wheelbase)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train_to_file(lap(), made_for, sc.vehicle, "identified", path)
    return load_model(path, "identified")


@functools.cache
def observations() -> tuple[Any, ...]:
    """Half a second of observations of the car driven by the LMPC."""
    from rkmpc.control import Observation, make_controller
    from rkmpc.sim.closed_loop import SimConfig, simulate
    from rkmpc.vehicle.registry import make_plant

    sc = scenario()
    ctrl = make_controller("lmpc", sc.reference, sc.vehicle)
    log = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, SimConfig(max_time=0.5)).log
    names = ("x", "y", "yaw", "speed", "yaw_rate", "slip_angle", "steer_angle")
    return tuple(Observation(**{f: float(log[f][i]) for f in names}) for i in range(len(log["t"])))


def controller(name: str, **options: Any) -> Any:
    """A reset controller of the built-in scenario (with its model when it needs one)."""
    from rkmpc.control import make_controller

    sc = scenario()
    if name in models():
        options.setdefault("model", models()[name])
    ctrl = make_controller(name, sc.reference, sc.vehicle, **options)
    ctrl.reset()
    return ctrl


def write_centerline(path: Path, xy: Any, width: float = 1.0) -> Path:
    """A TUM centre-line CSV of the points ``xy`` with both widths ``width``."""
    rows = "\n".join(f"{x:.9g},{y:.9g},{width:g},{width:g}" for x, y in xy)
    path.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + rows + "\n")
    return path


def ellipse(a: float = 100.0, b: float = 60.0, n: int = 80, dx: float = 0.0) -> Any:
    """Points of an ellipse (m), counter-clockwise, centred at ``(dx, 0)``."""
    import numpy as np

    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([dx + a * np.cos(t), b * np.sin(t)])
