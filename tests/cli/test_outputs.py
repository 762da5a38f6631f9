"""Outputs and interruption: folders appear whole or not at all, Ctrl-C ends a run in one line."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from rkmpc.cli import main
from rkmpc.core.errors import OutputError, raise_if_interrupted
from rkmpc.core.interrupt import interruptible
from rkmpc.core.io import check_output_file, output_folder, write_text_atomic

SRC = Path(__file__).resolve().parents[2] / "src"
MARKERS = ("results.json",)


def test_an_output_folder_appears_only_when_the_work_succeeds(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with output_folder(out, force=False, markers=MARKERS) as work:
        assert not out.exists() and work.parent == out.parent
        write_text_atomic(work / "results.json", "{}")
    assert (out / "results.json").read_text() == "{}"
    assert [p.name for p in out.parent.iterdir()] == ["out"]  # no temporary folder left


def test_a_failed_run_leaves_nothing_not_even_the_parents_it_made(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with pytest.raises(KeyboardInterrupt), output_folder(out, force=False, markers=MARKERS) as work:
        write_text_atomic(work / "log.csv", "t\n")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_a_used_folder_is_refused_and_replaced_whole_with_force(tmp_path):
    out = tmp_path / "out"
    out.mkdir()  # an empty folder is used as it is
    with output_folder(out, force=False, markers=MARKERS) as work:
        write_text_atomic(work / "results.json", "1")
        write_text_atomic(work / "log_old.csv", "old")
    with pytest.raises(OutputError, match="pass --force"):
        with output_folder(out, force=False, markers=MARKERS):
            pass
    with output_folder(out, force=True, markers=MARKERS) as work:
        write_text_atomic(work / "results.json", "2")
    assert sorted(p.name for p in out.iterdir()) == ["results.json"]  # the old log is gone
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    # --force never deletes a folder rkmpc did not write.
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="not an rkmpc output"):
        with output_folder(mine, force=True, markers=MARKERS):
            pass
    assert (mine / "notes.txt").read_text() == "mine"


def test_an_output_file_is_checked_before_the_work(tmp_path):
    with pytest.raises(OutputError, match="is a folder"):
        check_output_file(tmp_path)
    (tmp_path / "file").write_text("")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output_file(tmp_path / "file" / "model.npz")
    check_output_file(tmp_path / "new" / "model.npz")
    assert not (tmp_path / "new").exists()


def _full_disk(**_kwargs):
    """A temporary file on a full disk: ``/dev/full`` refuses every write with ENOSPC."""
    return open("/dev/full", "wb")


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_train_onto_a_full_disk_or_an_unwritable_path_fails_before_training(tmp_path, capsys, monkeypatch):
    data = tmp_path / "none.npz"  # never read: the output is checked first
    out = tmp_path / "models" / "m.rkm"
    with monkeypatch.context() as patch:
        patch.setattr("rkmpc.core.io.tempfile.NamedTemporaryFile", _full_disk)
        code = main(["train", "--data", str(data), "--kind", "residual", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and f"cannot write {out}: No space left on device" in err, err
    assert str(tmp_path) in err and "none.npz" not in err
    assert list(tmp_path.iterdir()) == []  # neither the folder nor a test file is left
    # /proc takes no new files, whoever asks (root included, which passes any permission check).
    code = main(["train", "--data", str(data), "--kind", "residual", "--out", "/proc/m.rkm"])
    err = capsys.readouterr().err
    assert code == 2 and "cannot write /proc/m.rkm" in err, err


def _hold(out: Path) -> subprocess.Popen:
    """Another process holding the output ``out`` (as a run writing it would) until its stdin closes."""
    script = (
        "import sys\nfrom rkmpc.core.io import claim_output\n"
        f"with claim_output({str(out)!r}):\n    print('held', flush=True)\n    sys.stdin.read()\n"
    )
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    holder = subprocess.Popen(
        [sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
    )
    assert holder.stdout is not None and holder.stdout.readline() == "held\n"
    return holder


def test_a_second_run_into_a_folder_being_written_is_refused_at_once(tmp_path, capsys):
    out = tmp_path / "o"
    holder = _hold(out)
    try:
        args = ["run", "--controller", "pp", "--track", "oval", "--out", str(out)]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert f"{out} is being written by another rkmpc process now (process {holder.pid})" in err
        assert "driving" not in err  # refused before the lap
        assert [p.name for p in tmp_path.iterdir()] == [".o.lock"]
    finally:
        holder.kill()  # as kill -9: the claim goes with its process
        holder.wait(timeout=60)
    assert main(args) == 0
    assert [p.name for p in tmp_path.iterdir()] == ["o"]  # no lock file left behind


def test_train_into_a_folder_fails_before_training(tmp_path, capsys):
    # The data file does not even exist: the output is checked first.
    code = main(["train", "--data", str(tmp_path / "none.npz"), "--kind", "residual", "--out", str(tmp_path)])
    assert code == 2
    assert "is a folder" in capsys.readouterr().err


def test_a_second_run_into_the_same_folder_is_refused_or_replaced_with_force(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["run", "--controller", "pp", "--track", "oval", "--out", str(out)]
    old = os.umask(0o022)
    try:
        assert main(args) == 0
        assert stat.S_IMODE(out.stat().st_mode) == 0o755
        assert {stat.S_IMODE(p.stat().st_mode) for p in out.iterdir()} == {0o644}
        (out / "log_stale.csv").write_text("from an earlier run")
        assert main(args) == 2
        assert "--force" in capsys.readouterr().err
        assert main([*args, "--force"]) == 0
    finally:
        os.umask(old)
    assert not (out / "log_stale.csv").exists()
    assert json.loads((out / "metrics.json").read_text())["completed"] is True
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_a_failed_run_creates_no_folder(tmp_path, capsys):
    out = tmp_path / "deep" / "out"
    assert main(["run", "--controller", "pp", "--track", str(tmp_path / "none.csv"), "--out", str(out)]) == 2
    assert "none.csv" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_is_one_line_and_exit_status_130(monkeypatch, capsys):
    def interrupted(_args):
        raise KeyboardInterrupt

    monkeypatch.setattr("rkmpc.cli._cmd_tracks", interrupted)
    assert main(["tracks"]) == 130
    assert capsys.readouterr().err == "rkmpc: interrupted\n"


def test_a_ctrl_c_that_a_solver_swallowed_still_ends_the_run(builtin_scenario):
    from rkmpc.control.registry import make_controller
    from rkmpc.core.observation import Observation

    controller = make_controller("pp", builtin_scenario.reference, builtin_scenario.vehicle)
    p = builtin_scenario.reference.path.position(1.0)
    yaw = float(builtin_scenario.reference.path.heading(1.0))
    obs = Observation(x=float(p[0]), y=float(p[1]), yaw=yaw, speed=1.0)
    with interruptible():
        try:  # what CasADi does with a KeyboardInterrupt raised in its callbacks
            os.kill(os.getpid(), signal.SIGINT)
        except KeyboardInterrupt:
            pass
        with pytest.raises(KeyboardInterrupt):
            controller.step(obs)
    controller.step(obs)  # outside the block, nothing is pending


def test_a_ctrl_c_turned_into_a_solver_error_is_raised_again():
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("returned a result with an exception set") from exc
    except SystemError as error:
        with pytest.raises(KeyboardInterrupt):
            raise_if_interrupted(error)
    raise_if_interrupted(RuntimeError("a plain solver error"))


@pytest.mark.slow  # several seconds: the slow tier (make test-slow, run by CI)
def test_sigint_during_an_nmpc_run_ends_it_with_nothing_written(tmp_path):
    out = tmp_path / "out"
    command = [sys.executable, "-m", "rkmpc.cli", "run", "--controller", "nmpc", "--track", "oval"]
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    process = subprocess.Popen(
        [*command, "--laps", "20", "--out", str(out)], stderr=subprocess.PIPE, text=True, env=env
    )
    assert process.stderr is not None
    for line in process.stderr:
        if "driving nmpc" in line:
            break
    process.send_signal(signal.SIGINT)
    rest = process.stderr.read()
    assert process.wait(timeout=600) == 130
    assert rest.strip().splitlines()[-1] == "rkmpc: interrupted"
    assert "Traceback" not in rest
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["run", "--controller", "lmpc", "--track", "builtin", "--laps", "0"],
            "argument --laps: must be an integer >= 1, got 0",
        ),
        (
            ["collect", "--track", "builtin", "--seed", "-5"],
            "argument --seed: must be an integer >= 0, got -5",
        ),
        (
            ["train", "--data", "x.npz", "--kind", "residual", "--epochs", "many"],
            "argument --epochs: must be an integer >= 1",
        ),
    ],
)
def test_bad_counts_name_their_option(args, message, tmp_path, capsys):
    from rkmpc.cli import main

    with pytest.raises(SystemExit) as info:
        main([*args, "--out", str(tmp_path / "out")])
    assert info.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_help_shows_defaults_and_the_version(capsys):
    from importlib.metadata import version

    from rkmpc.cli import main

    with pytest.raises(SystemExit):
        main(["compare", "-h"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: 2)" in text and "(default: 50000)" in text  # --data-laps, --kmpc-samples
    assert "(default: None)" not in text and "(default: False)" not in text
    with pytest.raises(SystemExit):
        main(["collect", "-h"])
    assert "output data set file (.npz)" in " ".join(capsys.readouterr().out.split())
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0 and capsys.readouterr().out.strip() == f"rkmpc {version('rkmpc')}"
