"""JobJournal: a stopped study resumes; other settings, strangers' folders, bad entries, pickles refused."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import warnings
from pathlib import Path

import pytest

from rkmpc.experiments.journal import JOURNAL_FORMAT, JobJournal, JournalError
from rkmpc.experiments.parallel import Job, JobOutcome, run_jobs
from rkmpc.experiments.study import run_study

CALLS: list[str] = []


def _square(x: int) -> int:
    CALLS.append(f"square {x}")
    return x * x


def _fail(x: int) -> int:
    CALLS.append(f"fail {x}")
    raise ValueError(f"no {x}")


SETTINGS = {"study": "test", "seed": 0, "ladder": [[4.0, 3.5]]}


def _journal(folder: Path, settings: dict = SETTINGS) -> JobJournal:
    """The journal of ``folder``, opened, its entries read back as :class:`JobOutcome` (as run_study does)."""
    return JobJournal(folder, settings, outcome=JobOutcome).open()


def _jobs(n: int = 3) -> list[Job]:
    return [Job(f"sq-{i}", _square, (i,)) for i in range(n)] + [Job("bad", _fail, (7,))]


def test_a_second_run_takes_finished_jobs_from_the_journal_and_reruns_failed_ones(tmp_path):
    CALLS.clear()
    journal = _journal(tmp_path / "j")
    first = run_jobs(_jobs(), on_error="record", journal=journal)
    assert [o.ok for o in first] == [True, True, True, False] and not any(o.resumed for o in first)
    assert sorted(CALLS) == ["fail 7", "square 0", "square 1", "square 2"]
    CALLS.clear()
    seen = []
    again = _journal(tmp_path / "j", dict(SETTINGS))
    second = run_jobs(_jobs(4), on_error="record", journal=again, progress=lambda o, d, t: seen.append(o))
    assert CALLS == ["square 3", "fail 7"]  # a new job and the failed one, nothing else
    assert [o.value for o in second] == [0, 1, 4, 9, None]  # in job order
    assert [o.resumed for o in second] == [True, True, True, False, False]
    assert [o.index for o in second] == list(range(5))
    assert [o.name for o in seen[:3]] == ["sq-0", "sq-1", "sq-2"]  # resumed ones are reported first
    assert second[1].seconds == first[1].seconds  # the earlier run's wall time is kept


def test_a_run_stopped_midway_keeps_what_finished(tmp_path):
    CALLS.clear()
    journal = _journal(tmp_path / "j")

    def stop_after_two(outcome, done, total):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_jobs(_jobs(4)[:4], journal=journal, progress=stop_after_two)
    assert len(list((tmp_path / "j").glob("*.json"))) == 1 + 2  # journal.json and two entries
    CALLS.clear()
    out = run_jobs(_jobs(4)[:4], journal=journal)
    assert CALLS == ["square 2", "square 3"] and [o.value for o in out] == [0, 1, 4, 9]


def test_the_key_not_the_name_identifies_a_job(tmp_path):
    CALLS.clear()
    journal = _journal(tmp_path / "j")
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
    journal = _journal(tmp_path / "j")
    run_jobs([Job("sq-1", _square, (1,))], journal=journal)
    (entry,) = (p for p in (tmp_path / "j").glob("*.json") if p.name != "journal.json")
    stored = json.loads(entry.read_text())
    assert stored["key"] == "sq-1" and stored["outcome"]["value"] == 1  # plain JSON
    entry.write_bytes(b"not JSON")
    with pytest.raises(JournalError, match=r"journal entry .*\.json \(job 'sq-1'\): unreadable"):
        run_jobs([Job("sq-1", _square, (1,))], journal=journal)
    entry.write_text(json.dumps({"key": "sq-2", "outcome": stored["outcome"]}))
    with pytest.raises(JournalError, match=r"holds job 'sq-2', not 'sq-1'"):
        run_jobs([Job("sq-1", _square, (1,))], journal=journal)


def test_values_go_through_the_study_s_encode_and_decode(tmp_path):
    # A study's value as JSON and back (a tuple is not JSON: the study says how it reads back).
    def encode(value):
        return {"pair": list(value)}

    def decode(data):
        return tuple(data["pair"])

    journal = JobJournal(tmp_path / "j", SETTINGS, encode=encode, decode=decode, outcome=JobOutcome).open()
    run_jobs([Job("pair", divmod, (7, 2))], journal=journal)
    (entry,) = (p for p in (tmp_path / "j").glob("*.json") if p.name != "journal.json")
    assert json.loads(entry.read_text())["outcome"]["value"] == {"pair": [3, 1]}
    (out,) = run_jobs([Job("pair", _fail, (0,))], journal=journal)  # not run: taken from the journal
    assert out.resumed and out.value == (3, 1)


def _square_warning(x: int) -> int:
    warnings.warn(f"kept nominal for {x}", UserWarning, stacklevel=1)
    return x * x


def test_a_job_s_warnings_are_kept_with_its_outcome(tmp_path):
    run_jobs([Job("sq", _square_warning, (3,))], journal=_journal(tmp_path / "j"))
    (out,) = run_jobs([Job("sq", _fail, (3,))], journal=_journal(tmp_path / "j"))
    assert out.resumed and out.value == 9
    assert out.warnings == ("UserWarning: kept nominal for 3",)


class _RunsCode:
    """What a hostile journal entry could hold: unpickling it runs a shell command."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _format_1_journal(folder: Path, marker: Path) -> None:
    """A journal as rkmpc wrote it before JSON entries: format 1, an entry ``<sha>.pkl`` per job."""
    folder.mkdir()
    (folder / "journal.json").write_text(json.dumps({"format": 1, "settings": SETTINGS}))
    entry = folder / f"{hashlib.sha256(b'sq-1').hexdigest()[:32]}.pkl"
    entry.write_bytes(pickle.dumps(_RunsCode(marker)))


def test_the_hostile_pickle_of_these_tests_does_run_code_when_unpickled(tmp_path):
    # Shows that what the next tests refuse to read is a real danger (here, a harmless touch).
    marker = tmp_path / "ran"
    pickle.loads(pickle.dumps(_RunsCode(marker)))  # the point of this test
    assert marker.exists()


def test_a_format_1_journal_of_pickles_is_refused_and_never_unpickled(tmp_path):
    marker = tmp_path / "MARKER"
    _format_1_journal(tmp_path / "old", marker)
    assert JOURNAL_FORMAT == 2
    with pytest.raises(JournalError) as info:
        JobJournal(tmp_path / "old", SETTINGS, outcome=JobOutcome).open()
    message = str(info.value)
    assert str(tmp_path / "old") in message
    assert "older rkmpc as pickles, which are never read" in message
    assert "give another journal folder or delete this one" in message
    assert not marker.exists()


class _TinyStudy:
    """A study of one job, to run a journal through :func:`run_study`."""

    name = "tiny"

    def prepare(self, say):
        pass

    def jobs(self):
        return [Job("sq-1", _square, (1,))]

    def journal_settings(self):
        return SETTINGS

    def encode(self, value):
        return value

    def decode(self, data):
        return data

    def result(self, outcomes, run):
        return [o.value for o in outcomes]


def test_a_study_given_a_format_1_journal_stops_before_running_anything(tmp_path):
    CALLS.clear()
    marker = tmp_path / "MARKER"
    _format_1_journal(tmp_path / "old", marker)
    with pytest.raises(JournalError, match="as pickles, which are never read"):
        run_study(_TinyStudy(), journal=tmp_path / "old")
    assert CALLS == [] and not marker.exists()


def test_a_pickle_dropped_into_a_journal_is_never_read(tmp_path):
    # The entry's old name, a pickle that runs code: the journal reads only <sha>.json entries.
    CALLS.clear()
    journal = _journal(tmp_path / "j")
    marker = tmp_path / "MARKER"
    entry = tmp_path / "j" / f"{hashlib.sha256(b'sq-1').hexdigest()[:32]}.pkl"
    entry.write_bytes(pickle.dumps(_RunsCode(marker)))
    (out,) = run_jobs([Job("sq-1", _square, (1,))], journal=journal)
    assert out.ok and not out.resumed and out.value == 1 and CALLS == ["square 1"]
    assert not marker.exists()
    assert run_study(_TinyStudy(), journal=tmp_path / "j2") == [1]
    assert not marker.exists()


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
