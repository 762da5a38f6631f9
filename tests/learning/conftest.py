"""Fixtures of the CSV-log tests: the shared real logs, and small synthetic logs with known defects."""

from __future__ import annotations

from pathlib import Path

import pytest

from csv_logs import REAL_LOGS, Drive, write_drive


@pytest.fixture(scope="session")
def real_logs() -> Path:
    """``../shared/real/f1tenth-car`` (runs DS2 and DS3), read in place; skipped when absent."""
    if not (REAL_LOGS / "DS2").is_dir() or not (REAL_LOGS / "DS3").is_dir():
        pytest.skip("../shared/real/f1tenth-car (the real car's logs) is not present")
    return REAL_LOGS


@pytest.fixture()
def drive_log(tmp_path):
    """A factory: ``drive_log(Drive(...))`` writes a synthetic log and returns its folder."""
    count = iter(range(1000))

    def make(drive: Drive | None = None) -> Path:
        return write_drive(tmp_path / f"log{next(count)}", drive or Drive())

    return make
