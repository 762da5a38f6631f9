"""Issue 13's probe, replayed: every case of "What to fix" and the probe's graceful ones, in one place.

The cases are in the table of ``probe_cases`` (``benchmarks/probe_table.py`` prints it as markdown).
Each must end as its row expects: a clear error naming what is wrong, a graceful fall-back, or the
right result; never a traceback, a hang or a silently wrong result.
"""

from __future__ import annotations

import pytest
from probe_cases import OUTCOMES, Case, Probe, all_cases

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
