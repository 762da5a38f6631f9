"""run_study (rkmpc.experiments.study): any Study run one way: shared work, jobs, journal, typed result."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.experiments.journal import JournalError
from rkmpc.experiments.parallel import Job
from rkmpc.experiments.study import Parallel, StudyRun, run_study

CALLS: list[str] = []


def _cube(x: int) -> tuple[int, int]:
    CALLS.append(f"cube {x}")
    if x == 2:
        warnings.warn("two is even", UserWarning, stacklevel=1)
    if x < 0:
        raise ValueError(f"no {x}")
    return (x, x**3)


@dataclass(frozen=True)
class _Result:
    values: list[Any]
    errors: list[str | None]
    run: StudyRun

    def to_json(self) -> dict[str, Any]:
        return {"values": self.values}

    def to_markdown(self) -> str:
        return ""

    def figure(self) -> None:
        return None


@dataclass
class _Cubes:
    """A study of cubes: its values are tuples, which its journal stores as lists and reads back."""

    numbers: tuple[int, ...]
    seed: int = 0
    prepared: list[str] = field(default_factory=list)
    name = "cubes"

    def prepare(self, say):
        self.prepared.append("shared work")
        say("preparing")

    def jobs(self):
        return [Job(f"cube {n}", _cube, (n,)) for n in self.numbers]

    def journal_settings(self):
        return {"seed": self.seed}

    def encode(self, value):
        return list(value)

    def decode(self, data):
        return tuple(data)

    def result(self, outcomes, run):
        return _Result([o.value for o in outcomes], [o.error for o in outcomes], run)


def test_the_shared_work_then_the_jobs_then_the_typed_result():
    CALLS.clear()
    said: list[str] = []
    seen: list[tuple[str, int, int]] = []
    study = _Cubes((1, 2, -3))
    result = run_study(
        study, say=said.append, progress=lambda o, done, total: seen.append((o.name, done, total))
    )
    assert study.prepared == ["shared work"] and said[0] == "preparing"
    assert "3 jobs on 1 loky workers" in said
    assert result.values == [(1, 1), (2, 8), None]  # a failing job is recorded, the others go on
    assert result.errors[2] == "ValueError: no -3"
    assert sorted(s[0] for s in seen) == ["cube -3", "cube 1", "cube 2"] and {s[2] for s in seen} == {3}
    assert result.run.parallel == Parallel() and result.run.wall_s >= 0.0
    assert {"python", "numpy", "rkmpc"} <= set(result.run.versions)
    assert result.run.to_json()["parallel"] == {"n_jobs": 1, "backend": "loky", "address": None}
    # What a job warned is kept with the run, by job, not printed by it.
    assert result.run.warnings == {"cube 2": ("UserWarning: two is even",)}
    assert result.run.to_json()["warnings"] == {"cube 2": ["UserWarning: two is even"]}


def test_a_journal_resumes_a_study_and_refuses_other_settings(tmp_path):
    CALLS.clear()
    first = run_study(_Cubes((1, 2, -3)), journal=tmp_path / "j")
    assert sorted(CALLS) == ["cube -3", "cube 1", "cube 2"]
    CALLS.clear()
    again = run_study(_Cubes((1, 2, -3, 4)), journal=tmp_path / "j")
    assert CALLS == ["cube -3", "cube 4"]  # the failed job and the new one
    assert again.values[:2] == first.values[:2] == [(1, 1), (2, 8)]  # decoded: tuples again
    with pytest.raises(JournalError, match=r"other settings \(differing: settings\.seed\)"):
        run_study(_Cubes((1,), seed=1), journal=tmp_path / "j")


def test_where_the_jobs_run_is_checked():
    assert Parallel(n_jobs=-1).n_jobs == -1
    for bad in (
        {"n_jobs": 0},
        {"n_jobs": -2},
        {"n_jobs": 1.5},
        {"backend": "spark"},
        {"address": "tcp://localhost:8786"},
    ):
        with pytest.raises(ParameterError):
            Parallel(**bad)
    assert Parallel(backend="dask", address="tcp://localhost:8786").address == "tcp://localhost:8786"


def _full_disk(path, payload):
    """What ``write_json_atomic`` does on a full disk."""
    raise OSError(28, "No space left on device", str(path))


@pytest.mark.parametrize("fails", ["entries", "header"])
def test_a_journal_on_a_full_disk_loses_no_result_and_says_so_once(tmp_path, monkeypatch, fails):
    import rkmpc.experiments.journal as journal_module

    CALLS.clear()
    folder = tmp_path / "j"
    if fails == "entries":  # the journal was made, then the disk filled up
        run_study(_Cubes(()), journal=folder)
    monkeypatch.setattr(journal_module, "write_json_atomic", _full_disk)
    said: list[str] = []
    result = run_study(_Cubes((1, 2, -3)), journal=folder, say=said.append)
    assert result.values == [(1, 1), (2, 8), None]  # every job ran, every result kept
    told = [line for line in said if "journal" in line]
    assert len(told) == 2, said  # the first failure, then the count at the end
    assert str(folder) in told[0] and "No space left on device" in told[0] and "goes on" in told[0]
    assert "2 of 3 finished jobs not kept" in told[1]
    assert sorted(p.name for p in folder.glob("*.json")) == ([] if fails == "header" else ["journal.json"])
