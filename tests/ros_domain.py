"""The ROS 2 domain id of one test's processes: its own, and never one another pytest worker picks.

``make test`` runs two pytest workers (pytest-xdist); each takes its own half of the ids 1-200, so
two ROS tests running at once never share a domain (and never hear each other's topics).
"""

from __future__ import annotations

import os

#: The ids the tests use: 1-200 (ROS 2 allows 0-232 on Linux; 0 is the default every other program uses).
_IDS = 200


def ros_domain_id(name: str) -> int:
    """A domain id for the test ``name`` in this process, inside this pytest worker's share of the ids."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    worker = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw"))
    share = _IDS // workers
    return 1 + worker * share + (os.getpid() * 31 + sum(map(ord, name))) % share
