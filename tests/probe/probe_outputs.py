"""Probe cases: interruption and outputs (Ctrl-C, folders written whole, the model cache, file modes)."""

from __future__ import annotations

import fcntl
import os
import signal
import stat
from typing import Any
from unittest import mock

from probe_cases import CLEAR_ERROR, CORRECT, GRACEFUL, Evidence, Probe, case, caught_warnings, cli_error

GROUP = "interruption and outputs"
SIGINT_TEST = "tests/cli/test_outputs.py::test_sigint_during_an_nmpc_run_ends_it_with_nothing_written"


@case(
    "out.ctrl_c_one_line",
    GROUP,
    "Ctrl-C: one line 'interrupted', exit status 130, no traceback",
    GRACEFUL,
    see_also=(SIGINT_TEST,),
)
def ctrl_c_one_line(probe: Probe) -> Evidence:
    # The real SIGINT to a running `rkmpc run --controller nmpc` is the subprocess test named above.
    def interrupted(_: Any) -> int:
        raise KeyboardInterrupt

    with mock.patch("rkmpc.cli._cmd_tracks", interrupted):
        run = probe.cli("tracks")
    assert run.code == 130 and run.err == "rkmpc: interrupted\n", (run.code, run.err)
    return Evidence(GRACEFUL, f"exit {run.code}: {run.err.strip()}")


@case(
    "out.ctrl_c_in_solver",
    GROUP,
    "a Ctrl-C that a C solver (IPOPT) swallowed still ends the run",
    GRACEFUL,
    see_also=(SIGINT_TEST,),
)
def ctrl_c_in_solver(_: Probe) -> Evidence:
    from probe_cases import controller, observations

    from rkmpc.core.errors import raise_if_interrupted
    from rkmpc.core.interrupt import interruptible

    pp = controller("pp")
    obs = observations()[0]
    ended = False
    with interruptible():
        try:  # what CasADi does with a KeyboardInterrupt raised in its callbacks: swallows it
            os.kill(os.getpid(), signal.SIGINT)
        except KeyboardInterrupt:
            pass
        try:
            pp.step(obs)
        except KeyboardInterrupt:
            ended = True
    assert ended, "the swallowed Ctrl-C was lost"
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("returned a result with an exception set") from exc
    except SystemError as error:
        try:
            raise_if_interrupted(error)
        except KeyboardInterrupt:
            pass
        else:
            raise AssertionError("a solver error caused by Ctrl-C was not raised again") from None
    return Evidence(
        GRACEFUL, "pending SIGINT raised at the next step; SystemError(KeyboardInterrupt) re-raised"
    )


@case(
    "out.no_folder_before_validation",
    GROUP,
    "a failed run (missing track file) creates no output folder",
    CLEAR_ERROR,
)
def no_folder_before_validation(probe: Probe) -> Evidence:
    out = probe.path("deep") / "out"
    args = ["run", "--controller", "pp", "--track", str(probe.path("none.csv")), "--out", str(out)]
    evidence = cli_error(probe, args, "none.csv")
    assert not probe.path("deep").exists()
    return evidence


@case(
    "out.second_compare_refused",
    GROUP,
    "a second compare into the same --out is refused without --force, the first run left whole",
    CLEAR_ERROR,
)
def second_compare_refused(probe: Probe) -> Evidence:
    from rkmpc.core.io import output_folder, write_text_atomic

    out = probe.path("cmp")
    with output_folder(out, force=False, markers=("results.json",)) as work:  # a first comparison
        write_text_atomic(work / "results.json", "{}")
        write_text_atomic(work / "log_lmpc.csv", "t\n")
    args = ["compare", "--controllers", "pp,lmpc", "--track", "oval", "--out", str(out)]
    evidence = cli_error(probe, args, "--force")
    assert sorted(p.name for p in out.iterdir()) == ["log_lmpc.csv", "results.json"]
    with output_folder(out, force=True, markers=("results.json",)) as work:  # --force: replaced whole
        write_text_atomic(work / "results.json", "{}")
    assert [p.name for p in out.iterdir()] == ["results.json"]
    return evidence


@case(
    "out.train_into_folder",
    GROUP,
    "train --out <existing folder> fails before training (before reading the data even)",
    CLEAR_ERROR,
)
def train_into_folder(probe: Probe) -> Evidence:
    args = ["train", "--data", str(probe.path("none.npz")), "--kind", "residual", "--out", str(probe.tmp)]
    return cli_error(probe, args, "is a folder")


class _Builder:
    """Fits a small linear model (no lifting) per call and counts the calls."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self) -> tuple[Any, dict[str, Any]]:
        import numpy as np

        from rkmpc.learning.koopman.model import KoopmanModel

        self.calls += 1
        rng = np.random.default_rng(self.calls)
        X, U = rng.normal(size=(100, 2)), rng.normal(size=(100, 1))
        return KoopmanModel(None).fit(X, U, 0.9 * X + 0.1 * U), {"call": self.calls}


def _rebuilt(probe: Probe, spoil: Any, needle: str) -> Evidence:
    from rkmpc.experiments.cache import CacheWarning, ModelCache

    cache = ModelCache(probe.path("cache"))
    build = _Builder()
    spec, other = {"name": "kmpc", "seed": 0}, {"name": "residual", "seed": 0}
    cache.get_or_build(spec, build)
    cache.get_or_build(other, build)
    spoil(cache, spec, other)
    with caught_warnings() as seen:
        _, hit = cache.get_or_build(spec, build)
    said = [str(w.message) for w in seen if issubclass(w.category, CacheWarning)]
    assert not hit.hit and build.calls == 3 and said and needle in said[0], (hit, build.calls, said)
    assert cache.get_or_build(spec, build)[1].hit and build.calls == 3  # replaced: a hit from now on
    return Evidence(GRACEFUL, said[0])


@case(
    "out.cache_slot_json_list",
    GROUP,
    "a cache slot whose JSON is a list: rebuilt once with a warning",
    GRACEFUL,
)
def cache_slot_json_list(probe: Probe) -> Evidence:
    def spoil(cache: Any, spec: dict[str, Any], _: dict[str, Any]) -> None:
        cache.path_for(spec).with_suffix(".json").write_text("[1, 2]")

    return _rebuilt(probe, spoil, "not a JSON object")


@case(
    "out.cache_slot_other_kind",
    GROUP,
    "a cache slot holding a model of another kind: rebuilt once with a warning",
    GRACEFUL,
)
def cache_slot_other_kind(probe: Probe) -> Evidence:
    import shutil

    def spoil(cache: Any, spec: dict[str, Any], other: dict[str, Any]) -> None:
        shutil.copyfile(cache.path_for(other), cache.path_for(spec))

    return _rebuilt(probe, spoil, "another kind")


@case(
    "out.cache_slot_locked",
    GROUP,
    "a slot being trained is locked: a second process waits instead of training it too",
    CORRECT,
    see_also=("tests/experiments/test_cache.py::test_two_processes_asking_for_one_slot_train_it_once",),
)
def cache_slot_locked(probe: Probe) -> Evidence:
    from rkmpc.experiments.cache import ModelCache

    cache = ModelCache(probe.path("cache"))
    spec = {"name": "kmpc"}
    inner = _Builder()
    held: list[bool] = []

    def build() -> tuple[Any, dict[str, Any]]:
        with open(cache.path_for(spec).with_suffix(".lock"), "a") as other:  # as another process would
            try:
                fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                held.append(True)
            else:
                fcntl.flock(other, fcntl.LOCK_UN)
                held.append(False)
        return inner()

    cache.get_or_build(spec, build)
    assert held == [True], held
    return Evidence(CORRECT, "the slot's .lock is held (flock) while it is trained")


@case(
    "out.file_modes",
    GROUP,
    "a run's files are all 0644 and its folder 0755 under umask 022 (results were 0600)",
    CORRECT,
)
def file_modes(probe: Probe) -> Evidence:
    out = probe.path("run")
    old = os.umask(0o022)
    try:
        run = probe.cli("run", "--controller", "pp", "--track", "oval", "--out", str(out))
    finally:
        os.umask(old)
    assert run.code == 0, run.err[-500:]
    modes = {p.name: oct(stat.S_IMODE(p.stat().st_mode)) for p in out.iterdir()}
    assert set(modes.values()) == {"0o644"}, modes
    assert stat.S_IMODE(out.stat().st_mode) == 0o755
    return Evidence(CORRECT, f"folder 0755, {len(modes)} files 0644 ({', '.join(sorted(modes)[:3])}, ...)")
