"""``rkmpc node --record``: what the node saw and sent, as a ROS 2 bag (MCAP by default).

A :class:`BagRecorder` is a recorder of :meth:`rkmpc.ros.node.ControllerNode.add_recorder`: it
receives every odometry the node took in, every measured wheel angle (where the car has a
steering topic) and every drive command it published, serialises each as ROS 2 does
(``rclpy.serialization``, CDR) and writes it to a bag (:class:`~rkmpc.learning.data.bags.BagStreamWriter`:
in closed segments of 2 s, so a node killed with ``kill -9`` leaves a bag of all but its last
seconds). The bag imports with ``rkmpc collect
--from-bag`` (``--steer-topic`` for the wheel angle) and plays with ``ros2 bag play``.

The time each message is filed under (the bag's receive time) is the node's clock:

* ``trigger: timer`` (a car): the wall clock when the message came in or went out, the clock the
  car's stamps are on.
* ``trigger: odometry`` (lock-step with ``rkmpc sim-node``): the simulated car's clock, as
  ``ros2 bag record --use-sim-time`` would file it: odometry and commands under their header
  stamps (an answer carries its odometry's stamp), and a wheel angle, which has no header, under
  the stamp of the odometry its answer carries: the node answers an odometry only once the angle
  sent with it is in, whichever of the two arrived first (two topics keep no order between them),
  and the car sends nothing new before the answer. Only the last angle before an answer is kept.
"""

from __future__ import annotations

import datetime
from pathlib import Path
from typing import Any

from rclpy.serialization import serialize_message

from rkmpc.config.ros import RosSettings
from rkmpc.learning.data.bags.stream import BagStreamWriter
from rkmpc.learning.data.bags.types import ACKERMANN_DRIVE_STAMPED, FLOAT64, ODOMETRY

__all__ = ["BagRecorder", "bag_path"]

_NS = 1_000_000_000


def bag_path(template: str, now: datetime.datetime | None = None) -> Path:
    """The bag's folder: ``template`` with ``{time}`` replaced by ``now`` (``%Y%m%d-%H%M%S``)."""
    moment = now if now is not None else datetime.datetime.now()
    return Path(template.replace("{time}", moment.strftime("%Y%m%d-%H%M%S")))


class BagRecorder:
    """Record the node's messages to a new bag.

    Parameters
    ----------
    path : str or Path
        The bag folder; it must not exist.
    config : RosSettings
        The node's topics (the steering topic is recorded when set), trigger (the clock of the
        bag, see the module) and the bag's storage (``record.storage``).

    Raises
    ------
    FileExistsError
        When ``path`` exists.
    """

    def __init__(self, path: str | Path, config: RosSettings) -> None:
        topics = config.topics
        kinds = {topics.odometry: ODOMETRY, topics.drive: ACKERMANN_DRIVE_STAMPED}
        if topics.steering is not None:
            kinds[topics.steering] = FLOAT64
        self.writer = BagStreamWriter(path, kinds, config.record.storage)
        self.path = self.writer.path
        self._odometry = topics.odometry
        self._drive = topics.drive
        self._steering = topics.steering
        self._last_odometry: int | None = None
        self._sim_clock = config.trigger == "odometry"
        self._steer_waiting: bytes | None = None

    @property
    def counts(self) -> dict[str, int]:
        """Messages written so far, by topic."""
        return dict(self.writer.counts)

    def __call__(self, topic: str, msg: Any, time_ns: int) -> None:
        """Record one message of ``topic``, received or sent at ``time_ns`` (wall clock, ns)."""
        data = serialize_message(msg)
        if not self._sim_clock:
            self.writer.write(topic, time_ns, data)
            return
        if topic == self._steering:
            self._steer_waiting = data
            return
        stamp = int(msg.header.stamp.sec) * _NS + int(msg.header.stamp.nanosec)
        if topic == self._odometry:
            self._last_odometry = stamp
        elif (
            topic == self._drive
            and self._steering is not None
            and self._steer_waiting is not None
            and stamp == self._last_odometry
        ):
            # The answer to the newest odometry: the angle the node answered it with goes with it.
            self.writer.write(self._steering, stamp, self._steer_waiting)
            self._steer_waiting = None
        self.writer.write(topic, stamp, data)

    def close(self) -> Path:
        """Finish the bag and move it into place; returns its path."""
        return self.writer.close()
