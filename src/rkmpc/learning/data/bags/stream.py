"""A ROS 2 bag written message by message, as a recorder receives them (``rkmpc node --record``).

The messages arrive already serialised (CDR, as ROS 2 sends them: ``rclpy.serialization``), each
with its topic and the time to file it under. The bag is a ``ros2 bag`` folder (MCAP or sqlite3)
written under a hidden temporary name beside its final one and renamed into place by
:meth:`BagStreamWriter.close`; a run that dies before leaves no half bag under the final name.
The connections carry the types' definitions and RIHS01 hashes from the bags' type store
(:func:`~rkmpc.learning.data.bags.types.typestore`, ``ackermann_msgs`` included), the ones ROS 2
Jazzy and Kilted announce, so ``ros2 bag`` plays the bag to a car's stack.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rkmpc.core.errors import ParameterError
from rkmpc.learning.data.bags.types import typestore

__all__ = ["RECORD_STORAGES", "BagStreamWriter"]

#: Storages of a recorded bag: ROS 2 MCAP (the default of ``ros2 bag record``) or sqlite3.
RECORD_STORAGES = ("mcap", "sqlite3")


class BagStreamWriter:
    """Write serialised messages to a new ROS 2 bag; rename it into place when closed.

    Parameters
    ----------
    path : str or Path
        The bag folder to make; it must not exist (a bag is never overwritten).
    topics : mapping of str to str
        Message type (``"nav_msgs/msg/Odometry"``) of every topic that will be written.
    storage : str
        ``"mcap"`` or ``"sqlite3"``.

    Raises
    ------
    FileExistsError
        When ``path`` exists.
    ParameterError
        For an unknown storage, no topics, or a message type the type store does not know.
    ImportError
        When ``rosbags`` is not installed.
    """

    def __init__(self, path: str | Path, topics: Mapping[str, str], storage: str = "mcap") -> None:
        if storage not in RECORD_STORAGES:
            raise ParameterError(f"bag storage must be one of {list(RECORD_STORAGES)}, got {storage!r}")
        if not topics:
            raise ParameterError("a bag needs at least one topic")
        self.path = Path(path)
        if self.path.exists():
            raise FileExistsError(f"{self.path} exists; a bag is never overwritten")
        store = typestore(ros1=False)
        unknown = sorted(kind for kind in topics.values() if kind not in store.types)
        if unknown:
            raise ParameterError(f"message types unknown to the bag's type store: {unknown}")
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(dir=self.path.parent, prefix=f".{self.path.name}."))
        self._draft = self._tmp / self.path.name
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        self._writer: Any = Writer(self._draft, version=Writer.VERSION_LATEST, storage_plugin=plugin)
        try:
            self._writer.open()
            self._connections = {
                topic: self._writer.add_connection(topic, kind, typestore=store)
                for topic, kind in topics.items()
            }
        except BaseException:
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise
        self.storage = storage
        #: Messages written, by topic.
        self.counts = dict.fromkeys(topics, 0)
        self._open = True

    @property
    def closed(self) -> bool:
        """Whether the bag was closed (or discarded)."""
        return not self._open

    def write(self, topic: str, time_ns: int, data: bytes | memoryview) -> None:
        """File a serialised message of ``topic`` under ``time_ns`` (ns since the epoch of its clock)."""
        if not self._open:
            raise ParameterError(f"{self.path}: the bag is closed")
        if topic not in self._connections:
            known = sorted(self.counts)
            raise ParameterError(f"{self.path}: topic {topic!r} was not declared; known: {known}")
        self._writer.write(self._connections[topic], int(time_ns), bytes(data))
        self.counts[topic] += 1

    def close(self) -> Path:
        """Finish the bag (its ``metadata.yaml``) and move it to its final name; returns the path."""
        if not self._open:
            return self.path
        self._open = False
        try:
            self._writer.close()
            self._draft.rename(self.path)
        finally:
            shutil.rmtree(self._tmp, ignore_errors=True)
        return self.path

    def discard(self) -> None:
        """Drop what was written: nothing is left under the final name or the temporary one."""
        if not self._open:
            return
        self._open = False
        try:
            self._writer.close()
        finally:
            shutil.rmtree(self._tmp, ignore_errors=True)
