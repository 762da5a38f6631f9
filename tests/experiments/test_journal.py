"""JobJournal: a stopped study resumes; other settings, strangers' folders and bad entries are refused."""

from __future__ import annotations

import json

import pytest

from rkmpc.experiments.journal import JobJournal, JournalError
from rkmpc.experiments.parallel import Job, run_jobs

CALLS: list[str] = []


def _square(x: int) -> int:
    CALLS.append(f"square {x}")
    return x * x


def _fail(x: int) -> int:
    CALLS.append(f"fail {x}")
    raise ValueError(f"no {x}")


SETTINGS = {"study": "test", "seed": 0, "ladder": [[4.0, 3.5]]}


def _jobs(n: int = 3) -> list[Job]:
    return [Job(f"sq-{i}", _square, (i,)) for i in range(n)] + [Job("bad", _fail, (7,))]


def test_a_second_run_takes_finished_jobs_from_the_journal_and_reruns_failed_ones(tmp_path):
    CALLS.clear()
    journal = JobJournal(tmp_path / "j", SETTINGS).open()
    first = run_jobs(_jobs(), on_error="record", journal=journal)
    assert [o.ok for o in first] == [True, True, True, False] and not any(o.resumed for o in first)
    assert sorted(CALLS) == ["fail 7", "square 0", "square 1", "square 2"]
    CALLS.clear()
    seen = []
    again = JobJournal(tmp_path / "j", dict(SETTINGS)).open()
    second = run_jobs(_jobs(4), on_error="record", journal=again, progress=lambda o, d, t: seen.append(o))
    assert CALLS == ["square 3", "fail 7"]  # a new job and the failed one, nothing else
    assert [o.value for o in second] == [0, 1, 4, 9, None]  # in job order
    assert [o.resumed for o in second] == [True, True, True, False, False]
    assert [o.index for o in second] == list(range(5))
    assert [o.name for o in seen[:3]] == ["sq-0", "sq-1", "sq-2"]  # resumed ones are reported first
    assert second[1].seconds == first[1].seconds  # the earlier run's wall time is kept


def test_a_run_stopped_midway_keeps_what_finished(tmp_path):
    CALLS.clear()
    journal = JobJournal(tmp_path / "j", SETTINGS).open()

    def stop_after_two(outcome, done, total):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_jobs(_jobs(4)[:4], journal=journal, progress=stop_after_two)
    assert len(list((tmp_path / "j").glob("*.pkl"))) == 2
    CALLS.clear()
    out = run_jobs(_jobs(4)[:4], journal=journal)
    assert CALLS == ["square 2", "square 3"] and [o.value for o in out] == [0, 1, 4, 9]


def test_the_key_not_the_name_identifies_a_job(tmp_path):
    CALLS.clear()
    journal = JobJournal(tmp_path / "j", SETTINGS).open()
    run_jobs([Job("Austin lmpc", _square, (2,), key="/a/Austin.csv lmpc")], journal=journal)
    out = run_jobs([Job("Austin lmpc", _square, (3,), key="/b/Austin.csv lmpc")], journal=journal)
    assert CALLS == ["square 2", "square 3"] and out[0].value == 9 and not out[0].resumed


def test_other_settings_are_refused_naming_what_differs(tmp_path):
    JobJournal(tmp_path / "j", SETTINGS).open()
    with pytest.raises(JournalError, match=r"other settings \(differing: ladder, seed\)"):
        JobJournal(tmp_path / "j", {**SETTINGS, "seed": 1, "ladder": [[5.0, 4.0]]}).open()


def test_a_folder_the_journal_did_not_write_is_refused(tmp_path):
    stranger = tmp_path / "stranger"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    with pytest.raises(JournalError, match=r"not empty and holds no journal\.json"):
        JobJournal(stranger, SETTINGS).open()
    (tmp_path / "file").write_text("x")
    with pytest.raises(JournalError, match="is a file"):
        JobJournal(tmp_path / "file", SETTINGS).open()
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "journal.json").write_text(json.dumps({"format": 99, "settings": SETTINGS}))
    with pytest.raises(JournalError, match="format 99"):
        JobJournal(bad, SETTINGS).open()


def test_an_unreadable_entry_is_a_clear_error(tmp_path):
    journal = JobJournal(tmp_path / "j", SETTINGS).open()
    run_jobs([Job("sq-1", _square, (1,))], journal=journal)
    (entry,) = (tmp_path / "j").glob("*.pkl")
    entry.write_bytes(b"not a pickle")
    with pytest.raises(JournalError, match=r"journal entry .*\.pkl \(job 'sq-1'\): unreadable"):
        run_jobs([Job("sq-1", _square, (1,))], journal=journal)


def test_track_files_are_keyed_by_their_absolute_path(tmp_path, monkeypatch):
    from rkmpc.experiments.studies.common import track_key

    monkeypatch.chdir(tmp_path)
    (tmp_path / "t").mkdir()
    assert track_key("t/../t/Oval.csv") == str(tmp_path / "t" / "Oval.csv")
    assert track_key("builtin") == "builtin"


def test_job_keys_must_be_unique():
    from rkmpc.core.errors import ParameterError

    jobs = [Job("a", _square, (1,), key="k"), Job("b", _square, (2,), key="k")]
    with pytest.raises(ParameterError, match=r"job keys must be unique, repeated: \['k'\]"):
        run_jobs(jobs)
