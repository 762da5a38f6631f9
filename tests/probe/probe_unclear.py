"""Issue 27's probe: tracebacks and unclear messages (a backend not installed, an environment flag of
the wrong type, a file name not in UTF-8, two runs into one folder, a special file as a model,
options that were ignored or unbounded, workers left behind by a killed study)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from unittest import mock

import numpy as np
from probe_cases import CLEAR_ERROR, CORRECT, GRACEFUL, Evidence, Probe, case, cli_error, raises

TRACEBACKS = "tracebacks (issue 27)"
UNCLEAR = "unclear (issue 27)"
SRC = Path(__file__).resolve().parents[2] / "src"


@case(
    "tb.backend_not_installed",
    TRACEBACKS,
    "--backend ray / dask without the package: one line before any work, not a traceback",
    CLEAR_ERROR,
    problem="traceback",
)
def backend_not_installed(probe: Probe) -> Evidence:
    import importlib.util

    args = ["study", "tracks", "--tracks", "oval", "--controllers", "pp", "--out", str(probe.path("o"))]
    real = importlib.util.find_spec

    def without(name: str, *rest: object) -> object:
        return None if name in ("ray", "dask", "distributed") else real(name, *rest)  # type: ignore[arg-type]

    with (
        mock.patch("rkmpc.experiments.backends.importlib.util.find_spec", without),
        mock.patch("rkmpc.experiments.studies.tracks.TracksStudy.prepare") as prepare,
    ):
        cli_error(
            probe,
            [*args, "--backend", "dask", "--address", "tcp://127.0.0.1:1"],
            "needs dask and distributed",
        )
        evidence = cli_error(probe, [*args, "--backend", "ray"], "backend 'ray' needs ray", "rkmpc[cluster]")
    assert not prepare.called  # said before the shared models are trained
    return evidence


@case(
    "tb.env_noise_true",
    TRACEBACKS,
    "F1TenthEnvConfig(noise=True) (reset raised AttributeError): refused, a NoiseStd is needed",
    CLEAR_ERROR,
    problem="traceback",
)
def env_noise_true(_: Probe) -> Evidence:
    from rkmpc.envs.f1tenth import F1TenthEnvConfig

    return raises(lambda: F1TenthEnvConfig(noise=True), "noise")  # type: ignore[arg-type]


@case(
    "tb.track_name_not_utf8",
    TRACEBACKS,
    "a track file whose name is not valid UTF-8: the run completes, the name shown as escapes",
    CORRECT,
    problem="traceback",
    see_also=("tests/cli/test_file_names.py",),
)
def track_name_not_utf8(probe: Probe) -> Evidence:
    t = np.linspace(0.0, 2 * np.pi, 80, endpoint=False)
    track = probe.tmp / os.fsdecode(b"ov\xe9al.csv")
    rows = "\n".join(f"{20 * np.cos(a):.6f},{12 * np.sin(a):.6f},2,2" for a in t)
    track.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + rows + "\n")
    out = probe.path("o")
    run = probe.cli("run", "--controller", "pp", "--track", str(track), "--scale", "1", "--out", str(out))
    assert run.code == 0 and "Traceback" not in run.err, run.err[-1500:]
    assert (out / "plot.png").is_file() and "ov\\xe9al (scale 1, f1tenth)" in run.out
    return Evidence(CORRECT, "completed; shown as 'ov\\xe9al (scale 1, f1tenth)' in the table and the plot")


@case(
    "unclear.same_out_at_once",
    UNCLEAR,
    "a second `rkmpc run` into an --out another run is writing: refused at once, not after its lap",
    CLEAR_ERROR,
    problem="unclear",
    see_also=("tests/cli/test_outputs.py::test_a_second_run_into_a_folder_being_written_is_refused_at_once",),
)
def same_out_at_once(probe: Probe) -> Evidence:
    out = probe.path("o")
    script = (
        "import sys\nfrom rkmpc.core.io import claim_output\n"
        f"with claim_output({str(out)!r}):\n    print('held', flush=True)\n    sys.stdin.read()\n"
    )
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    first = subprocess.Popen(
        [sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
    )
    try:
        assert first.stdout is not None and first.stdout.readline() == "held\n"
        with mock.patch("rkmpc.experiments.compare.compare") as drive:
            evidence = cli_error(
                probe,
                ["run", "--controller", "lmpc", "--out", str(out)],
                f"{out} is being written by another rkmpc process now (process {first.pid})",
            )
        assert not drive.called  # refused before the lap
    finally:
        first.kill()  # as kill -9: the claim goes with its process
        first.wait(timeout=60)
    run = probe.cli("run", "--controller", "pp", "--track", "oval", "--out", str(out))
    assert run.code == 0 and [p.name for p in probe.tmp.iterdir()] == ["o"], run.err[-500:]
    return evidence


@case(
    "unclear.model_special_file",
    UNCLEAR,
    "--model naming /dev/null, a folder or a FIFO: says what it is (was 'file not found'; a FIFO blocked)",
    CLEAR_ERROR,
    problem="unclear",
)
def model_special_file(probe: Probe) -> Evidence:
    fifo = probe.path("model.rkm")
    os.mkfifo(fifo)
    args = ["run", "--controller", "rkmpc", "--out", str(probe.path("o")), "--model"]
    cli_error(probe, [*args, "/dev/null"], "/dev/null: a character device, not a regular file")
    cli_error(probe, [*args, str(probe.tmp)], "a folder, not a regular file")
    return cli_error(probe, [*args, str(fifo)], "model.rkm: a FIFO (named pipe), not a regular file")


@case(
    "unclear.address_without_backend",
    UNCLEAR,
    "--address without --backend (ignored: the study ran locally): refused",
    CLEAR_ERROR,
    problem="unclear",
)
def address_without_backend(probe: Probe) -> Evidence:
    args = [
        "study",
        "tracks",
        "--controllers",
        "pp",
        "--address",
        "tcp://10.0.0.1:8786",
        "--out",
        str(probe.path("o")),
    ]
    return cli_error(probe, args, "address", "--backend")


@case(
    "unclear.pace_steps_huge",
    UNCLEAR,
    "study pace --steps 1000000 (an 85 MB JSON): refused at once naming the bound",
    CLEAR_ERROR,
    problem="unclear",
)
def pace_steps_huge(probe: Probe) -> Evidence:
    args = ["study", "pace", "--steps", "1000000", "--out", str(probe.path("o"))]
    return cli_error(probe, args, "steps", "59", "1000000")


@case(
    "unclear.workers_outlive_study",
    UNCLEAR,
    "kill -9 of a study's process: its loky workers end within seconds (stayed for minutes)",
    GRACEFUL,
    slow=True,
    problem="unclear",
    see_also=("tests/experiments/test_worker_parent.py",),
)
def workers_outlive_study(probe: Probe) -> Evidence:
    import signal
    import time

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
    from test_worker_parent import HANG, alive, children

    command = [sys.executable, "-m", "rkmpc.cli", "study", "tracks", "--tracks", "builtin,oval"]
    command += ["--controllers", "nmpc-dynamic", "--jobs", "2", "--out", str(probe.path("out"))]
    env = {**os.environ, "PYTHONPATH": str(SRC), "RKMPC_CACHE_DIR": str(probe.path("cache"))}
    study = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + HANG
        while len(children(study.pid)) < 4:  # two workers and loky's two resource trackers
            assert study.poll() is None and time.monotonic() < deadline, "no workers started"
            time.sleep(0.2)
        time.sleep(2.0)
        helpers = children(study.pid)
        study.kill()
        study.wait(timeout=60)
        deadline = time.monotonic() + 15.0
        while any(alive(pid) for pid in helpers) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = [pid for pid in helpers if alive(pid)]
    finally:
        if study.poll() is None:
            study.kill()
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert not left, left
    return Evidence(GRACEFUL, f"{len(helpers)} child processes of the killed study, none left after it")
