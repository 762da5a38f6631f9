"""The workflow's processes: a function run in a spawned process of its own, its output to a log.

:func:`child_process` is what :class:`multiprocessing.Process` runs: a session of its own (a Ctrl-C at
the terminal reaches the workflow, which stops its processes in order), the process's output to a
log file, the workflow's environment (its ROS domain), then the function, whose return value is the
exit status. :func:`node_process` and :func:`sim_node_process` are the two ROS nodes as such functions.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rkmpc.config.car import CarConfig
from rkmpc.core.errors import RkmpcError
from rkmpc.ros.config import NodeTask
from rkmpc.ros.sim_config import SimNodeConfig

__all__ = ["child_process", "node_process", "sim_node_process"]


def child_process(
    name: str, target: Callable[..., int], args: tuple[Any, ...], log: str, env: dict[str, str]
) -> None:
    """A workflow process: its own session, its output to ``log``, its environment, then ``target``."""
    os.setsid()  # a Ctrl-C at the terminal reaches the workflow, which stops its processes in order
    sink = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(sink, 1)
    os.dup2(sink, 2)
    sys.stdout = open(1, "w", buffering=1, closefd=False)
    sys.stderr = open(2, "w", buffering=1, closefd=False)
    os.environ.clear()
    os.environ.update(env)
    try:
        code = target(*args)
    except (RkmpcError, ValueError, OSError) as exc:
        print(f"rkmpc {name}: error: {exc}", file=sys.stderr)
        code = 2
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def node_process(car: CarConfig, task: NodeTask, out: str, bag: str | None) -> int:
    from rkmpc.ros.node import run_node

    return run_node(car, task, out=Path(out), record=None if bag is None else Path(bag))


def sim_node_process(config: SimNodeConfig, out: str) -> int:
    from rkmpc.ros.sim_node import run_sim_node

    return run_sim_node(config, out=Path(out))
