"""The step logs a comparison writes (``log_<controller>.csv`` with its ``.meta.json``), lap by lap.

Shared by the benchmark scripts that read a comparison's folder (``rkmpc compare --out F``).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from rkmpc.sim.log import StepLog


def first_laps(
    folder: Path, controllers: tuple[str, ...]
) -> Iterator[tuple[str, StepLog, np.ndarray | None]]:
    """For each controller with a log in ``folder``: its name, its log and the mask of its first lap.

    The mask selects the steps with ``t`` up to the first lap time; it is None when no lap was
    completed. Controllers without a log are passed over.
    """
    for name in controllers:
        path = folder / f"log_{name}.csv"
        if not path.exists():
            continue
        meta = json.loads(Path(f"{path}.meta.json").read_text())
        log = StepLog.from_csv(path)
        yield name, log, (log["t"] <= meta["lap_times"][0]) if meta["lap_times"] else None
