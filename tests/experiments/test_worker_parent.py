"""Local workers end with the process that started them (a study killed with ``kill -9``)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from rkmpc.experiments.backends import PARENT_POLL_S, watch_parent

SRC = Path(__file__).resolve().parents[2] / "src"
#: Upper bound of any wait (s): a hang fails the test instead of stalling CI; never what is measured.
HANG = 300.0


def children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
            found.append(int(entry.name))
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def test_a_process_does_not_watch_itself():
    before = {t.name for t in threading.enumerate()}
    watch_parent(os.getpid())  # jobs run in the calling process: nothing to watch
    assert {t.name for t in threading.enumerate()} == before


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
def test_kill_9_of_a_study_leaves_no_worker_running(tmp_path):
    """``rkmpc study tracks --jobs 2`` killed while both workers drive: they and loky's helpers end."""
    command = [sys.executable, "-m", "rkmpc.cli", "study", "tracks", "--tracks", "builtin,oval"]
    command += ["--controllers", "nmpc-dynamic", "--jobs", "2", "--out", str(tmp_path / "out")]
    env = {**os.environ, "PYTHONPATH": str(SRC), "RKMPC_CACHE_DIR": str(tmp_path / "cache")}
    study = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + HANG
        workers: list[int] = []
        while len(workers) < 2:  # both loky workers started (and running a job: nmpc-dynamic takes minutes)
            assert study.poll() is None and time.monotonic() < deadline, "no workers started"
            time.sleep(0.2)
            workers = [pid for pid in children(study.pid) if b"popen_loky" in _cmdline(pid)]
        time.sleep(2.0)  # the jobs handed to them
        helpers = children(study.pid)
        study.send_signal(signal.SIGKILL)
        study.wait(timeout=60)
        deadline = time.monotonic() + 30 * PARENT_POLL_S
        while any(alive(pid) for pid in helpers) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = [pid for pid in helpers if alive(pid)]
    finally:
        if study.poll() is None:
            study.kill()
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert set(workers) <= set(helpers) and not left, f"still running after the study: {left}"
