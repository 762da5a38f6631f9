"""The probes of issues 13 and 27, replayed: every case they found, and the graceful ones, in one place.

The cases are in the table of ``probe_cases`` (``benchmarks/probe_table.py`` prints it as markdown).
Each must end as its row expects: a clear error naming what is wrong, a graceful fall-back, or the
right result; never a traceback, a hang or a silently wrong result.
"""

from __future__ import annotations

import pytest
from probe_cases import OUTCOMES, PROBLEMS, Case, Probe, all_cases

CASES = all_cases()


def _param(c: Case) -> object:
    marks = []
    if c.slow:
        marks.append(pytest.mark.slow)
    if c.xfail is not None:
        marks.append(pytest.mark.xfail(strict=True, reason=c.xfail))
    return pytest.param(c, id=c.id, marks=marks)


@pytest.mark.parametrize("probe_case", [_param(c) for c in CASES])
def test_probe_case(probe_case: Case, tmp_path, capsys) -> None:
    evidence = probe_case.run(Probe(tmp_path, capsys.readouterr))
    assert evidence.outcome == probe_case.expected, evidence
    assert evidence.message.strip()
    assert "Traceback" not in evidence.message


def test_the_table_is_complete_and_stable() -> None:
    ids = [c.id for c in CASES]
    assert len(ids) == len(set(ids))
    assert len(CASES) >= 45
    assert {c.expected for c in CASES} <= set(OUTCOMES)
    assert all(c.description and c.group for c in CASES)


def test_issue_27s_cases_cover_every_kind_of_problem_it_found() -> None:
    issue27 = [c for c in CASES if c.problem is not None]
    assert len(issue27) >= 30
    assert {c.problem for c in issue27} == set(PROBLEMS)
    assert all("(issue 27)" in c.group for c in issue27)
    # None is left as a known failure.
    assert [c.id for c in CASES if c.xfail is not None] == []
