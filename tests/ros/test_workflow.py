"""``rkmpc car-loop``: the output folder, the report, a failure stops every process; (slow) the whole run.

The whole run records two LMPC laps over ROS 2, trains the residual model with the recipe's own
settings and drives three controllers, so it is in the slow tier; it runs in lock-step, so what
it asserts does not depend on how busy the machine is.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rkmpc.core.errors import OutputError, ParameterError
from rkmpc.ros.workflow import MARKER, WorkflowConfig, WorkflowError, prepare_folder
from rkmpc.ros.workflow_report import TABLE_KEYS, build_report, markdown_report

SRC = Path(__file__).resolve().parents[2] / "src"


def test_an_output_folder_is_not_reused_without_force(tmp_path):
    out = tmp_path / "loop"
    prepare_folder(out, force=False)  # a new folder
    prepare_folder(out, force=False)  # an empty one
    (out / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="pass --force"):
        prepare_folder(out, force=False)
    # --force replaces only the output of an earlier car-loop.
    with pytest.raises(OutputError, match=f"not an rkmpc output \\(no {MARKER}\\)"):
        prepare_folder(out, force=True)
    assert (out / "notes.txt").read_text() == "mine"
    (out / MARKER).write_text("{}")
    prepare_folder(out, force=True)
    assert list(out.iterdir()) == []


def test_the_settings_are_checked():
    with pytest.raises(ParameterError, match="clock"):
        WorkflowConfig(out="x", clock="wall")
    with pytest.raises(ParameterError, match="residual and identified"):
        WorkflowConfig(out="x", controllers=("lmpc", "kmpc"))
    with pytest.raises(ParameterError, match="domain_id"):
        WorkflowConfig(out="x", domain_id=300)


def _run(lateral: float, heading: float, *, completed: bool = True) -> dict:
    metrics = {
        "completed": completed,
        "progress": 1.0 if completed else 0.4,
        "lap_time_s": 27.5 if completed else None,
        "lateral_error_mean_m": lateral,
        "lateral_error_max_m": 3 * lateral,
        "heading_error_mean_rad": heading,
        "steer_rate_mean_rad_s": 0.2,
        "steps": 550,
    }
    stats = {"median": 1.0, "p99": 2.0, "max": 3.0}
    return {
        "sim": {
            "outcome": "completed" if completed else "off_track",
            "metrics": metrics,
            "round_trip_ms_median": 4.0,
            "round_trip_ms_p99": 9.0,
        },
        "node": {
            "solve_time_ms": {"median": 0.8, "p99": 1.5, "max": 2.0},
            "odometry_to_command_ms": stats,
            "fallbacks": 0,
            "by_state": {"running": 550, "shutdown": 1},
        },
        "actuation_delay": 0.0,
        "compensate": False,
    }


def test_the_report_is_table_two_with_rkmpc_against_the_lmpc():
    table = {"lmpc": _run(0.04, 0.03), "lmpc-id": _run(0.03, 0.02), "rkmpc": _run(0.02, 0.025)}
    delayed = {"lmpc": _run(0.3, 0.2, completed=False), "lmpc+comp": _run(0.06, 0.04)}
    report = build_report(
        config={"clock": "lockstep", "track": "builtin", "delay": 0.05},
        record=_run(0.04, 0.03),
        imported="1099 transitions in 1 episode(s)",
        models={"residual": {"file": "m.npz", "report": "residual model: ...\nheld-out ..."}},
        table=table,
        delayed=delayed,
        commands=["rkmpc node --config lmpc.yaml"],
    )
    rows = report["table2"]
    assert list(rows) == ["lmpc", "lmpc-id", "rkmpc"]
    assert all(rows[name][key] is not None for name in rows for key in TABLE_KEYS)
    # Lock-step: the latency is the round trip the simulated car waited for.
    assert rows["lmpc"]["latency_ms_median"] == 4.0 and rows["lmpc"]["step_ms_p99"] == 1.5
    comparison = report["rkmpc_vs_lmpc"]
    assert comparison["lateral_change_pct"] == pytest.approx(-50.0)
    assert comparison["heading_change_pct"] == pytest.approx(100 * (0.025 - 0.03) / 0.03)
    assert comparison["rkmpc_beats_lmpc"]
    text = markdown_report(report)
    assert "RKMPC beats the LMPC" in text and "| rkmpc | yes | 0.0200 | 0.0250 |" in text
    assert "| lmpc | no (off_track, 40 %) |" in text  # the delay run that left the track
    json.dumps(report)  # JSON-ready
    # Real time: the latency is the odometry's age at the node.
    realtime = build_report(
        config={"clock": "realtime", "track": "builtin", "delay": 0.0},
        record=_run(0.04, 0.03),
        imported="",
        models={},
        table={"lmpc": _run(0.04, 0.03), "rkmpc": _run(0.05, 0.02)},
        delayed={},
        commands=[],
    )
    assert realtime["table2"]["lmpc"]["latency_ms_median"] == 1.0
    assert not realtime["rkmpc_vs_lmpc"]["rkmpc_beats_lmpc"]


def _car_loop(args: list[str], timeout: float) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), *filter(None, [env.get("PYTHONPATH")])])
    return subprocess.run(
        [sys.executable, "-m", "rkmpc.cli", "car-loop", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")
def test_a_failing_stage_names_itself_and_leaves_no_process(tmp_path, monkeypatch):
    pytest.importorskip("rclpy", reason="ROS 2 is not installed (make ros)", exc_type=ImportError)
    from rkmpc.ros import workflow

    started: list = []
    start = workflow._Run.start

    def recorded(self, *args, **kwargs):  # every process the workflow starts (spawned, not forked)
        process = start(self, *args, **kwargs)
        started.append(process)
        return process

    monkeypatch.setattr(workflow._Run, "start", recorded)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    track = str(tmp_path / "no-such-track.csv")
    config = WorkflowConfig(out=str(tmp_path / "loop"), track=track, timeout=300)
    # Both the node and the car read the track; whichever fails first is reported, with its log.
    with pytest.raises(WorkflowError, match=r"^record: rkmpc (sim-)?node") as info:
        workflow.run_workflow(config)
    assert "no-such-track.csv" in str(info.value)
    assert len(started) == 2 and all(p.exitcode is not None for p in started)  # the node and the car
    assert not any(p.is_alive() for p in started)
    assert (tmp_path / "loop" / "logs" / "record-node.log").is_file()


@pytest.mark.slow
def test_the_whole_workflow_gives_table_two(tmp_path):
    out = tmp_path / "loop"
    done = _car_loop(["--out", str(out), "--delay-study", "0"], timeout=3 * 3600)
    assert done.returncode == 0, done.stdout + done.stderr
    report = json.loads((out / "table2.json").read_text())
    rows = report["table2"]
    assert list(rows) == ["lmpc", "lmpc-id", "rkmpc"]
    for name, row in rows.items():
        assert row["completed"], (name, row)
        assert all(row[key] is not None for key in TABLE_KEYS), (name, row)
    assert report["rkmpc_vs_lmpc"] is not None and report["delay"] == {}
    text = (out / "table2.md").read_text()
    assert all(f"| {name} | yes |" in text for name in rows)
    # The bag it trained from, the models, and the refusal to reuse the folder.
    assert (out / "record" / "bag" / "metadata.yaml").is_file()
    assert (out / "models" / "residual.npz").is_file() and (out / "models" / "identified.json").is_file()
    again = _car_loop(["--out", str(out)], timeout=600)
    assert again.returncode == 2 and "--force" in again.stderr


@pytest.mark.slow  # several seconds: the slow tier (make test-slow, run by CI)
@pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")
def test_ctrl_c_stops_every_process_and_the_node_closes_its_bag(tmp_path):
    pytest.importorskip("rclpy", reason="ROS 2 is not installed (make ros)", exc_type=ImportError)
    import signal
    import time

    out = tmp_path / "loop"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), *filter(None, [env.get("PYTHONPATH")])])
    loop = subprocess.Popen(
        [sys.executable, "-m", "rkmpc.cli", "car-loop", "--out", str(out)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        deadline = time.monotonic() + 300
        # Until the node records: its bag's segment being written is there (the laps take longer).
        while not (out / "record" / "bag" / ".recording").is_dir():
            assert loop.poll() is None and time.monotonic() < deadline, "the recording never started"
            time.sleep(0.05)
        loop.send_signal(signal.SIGINT)
        text, _ = loop.communicate(timeout=120)
    finally:
        if loop.poll() is None:
            loop.kill()
    assert loop.returncode == 130 and "interrupted" in text, text
    # The node stopped with a final stop and closed its bag: complete, under its own name.
    from rkmpc.learning.data.bags.stream import RECORDING_KEY, read_metadata

    assert read_metadata(out / "record" / "bag")["custom_data"] == {RECORDING_KEY: "closed"}
    assert not (out / "record" / "bag" / ".recording").exists()
    alive = [p for p in Path("/proc").glob("[0-9]*") if _cmdline(p).find(str(out)) >= 0]
    assert alive == []


def _cmdline(process: Path) -> str:
    try:
        return (process / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""
