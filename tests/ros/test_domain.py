"""The loop tests' ROS domain ids: two pytest workers never share one."""

from __future__ import annotations

from ros_domain import ros_domain_id


def test_two_workers_draw_their_domain_ids_from_disjoint_shares(monkeypatch):
    names = ["loop", "loop_sensors", "hash_probe", "probe.lost"]
    drawn: dict[str, set[int]] = {}
    monkeypatch.setenv("PYTEST_XDIST_WORKER_COUNT", "2")
    for worker in ("gw0", "gw1"):
        monkeypatch.setenv("PYTEST_XDIST_WORKER", worker)
        drawn[worker] = {ros_domain_id(name) for name in names}
    assert drawn["gw0"].isdisjoint(drawn["gw1"])
    assert all(1 <= i <= 200 for ids in drawn.values() for i in ids)
    monkeypatch.delenv("PYTEST_XDIST_WORKER")
    monkeypatch.delenv("PYTEST_XDIST_WORKER_COUNT")
    assert 1 <= ros_domain_id("loop") <= 200  # one process, no workers: the whole range
