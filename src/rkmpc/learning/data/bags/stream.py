"""A ROS 2 bag written message by message, as a recorder receives them (``rkmpc node --record``).

The messages arrive already serialised (CDR, as ROS 2 sends them: ``rclpy.serialization``), each
with its topic and the time to file it under. The bag is a ``ros2 bag`` folder (MCAP or sqlite3)
under its own name from the start, written in closed segments: every :data:`SEGMENT_S` seconds
(of the bag's clock) the segment being written is finished (``NAME_k.mcap`` with its index, as
``ros2 bag record --max-bag-duration`` splits a bag), flushed to the disk and listed in the bag's
``metadata.yaml``, which is replaced whole each time. A recording that dies without closing
(``kill -9``, out of memory, a power cut on the car) thus leaves a bag that reads and imports with
everything up to its last closed segment: at most the last :data:`SEGMENT_S` seconds are lost. Its
``metadata.yaml`` says it did not end (``custom_data``: :data:`RECORDING_KEY` is ``unfinished``;
``closed`` once :meth:`BagStreamWriter.close` ran), which the importer reports. The segment being
written lives in a hidden folder of the bag (:data:`DRAFTS`), never read.

The writing happens in a thread of its own, as ``ros2 bag record`` does: :meth:`BagStreamWriter.write`
only queues the message, so closing a segment (tens of milliseconds; opening an sqlite3 file, over
a hundred) never holds up the node's control loop. An error of that thread (a full disk) is raised
by the next :meth:`~BagStreamWriter.write` or by :meth:`~BagStreamWriter.close`.

``metadata.yaml`` is written as JSON, which is YAML too (every YAML reader of ``ros2 bag`` and
``rosbags`` reads it), because it is rewritten every segment. The connections carry the types'
definitions and RIHS01 hashes from the bags' type store
(:func:`~rkmpc.learning.data.bags.types.typestore`, ``ackermann_msgs`` included), the ones ROS 2
Jazzy and Kilted announce, so ``ros2 bag`` plays the bag to a car's stack.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rkmpc.core.errors import ParameterError
from rkmpc.core.io import atomic_write
from rkmpc.learning.data.bags.types import typestore

__all__ = ["DRAFTS", "RECORDING_KEY", "RECORD_STORAGES", "SEGMENT_S", "BagStreamWriter", "read_metadata"]

#: Storages of a recorded bag: ROS 2 MCAP (the default of ``ros2 bag record``) or sqlite3.
RECORD_STORAGES = ("mcap", "sqlite3")

#: Length of a segment (s of the bag's clock): the most a recording that dies can lose.
SEGMENT_S = 2.0

#: The ``custom_data`` key of a recorded bag's state: ``unfinished`` while recording, ``closed`` after.
RECORDING_KEY = "rkmpc.recording"

#: The hidden folder of a bag in which the segment being recorded is written.
DRAFTS = ".recording"

_NS = 1_000_000_000


def read_metadata(path: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` of a ROS 2 bag folder's ``metadata.yaml``."""
    from ruamel.yaml import YAML  # rosbags' own YAML library (its dependency)

    loaded = YAML(typ="safe").load((path / "metadata.yaml").read_text(encoding="utf-8"))
    info = loaded["rosbag2_bagfile_information"] if isinstance(loaded, dict) else None
    if not isinstance(info, dict):
        raise ValueError("metadata.yaml has no rosbag2_bagfile_information")
    return info


class BagStreamWriter:
    """Write serialised messages to a new ROS 2 bag in closed segments (see the module).

    Parameters
    ----------
    path : str or Path
        The bag folder to make; it must not exist (a bag is never overwritten).
    topics : mapping of str to str
        Message type (``"nav_msgs/msg/Odometry"``) of every topic that will be written.
    storage : str
        ``"mcap"`` or ``"sqlite3"``.
    segment_s : float
        Length of a segment (s of the bag's clock, > 0): the most a recording that dies loses.

    Raises
    ------
    FileExistsError
        When ``path`` exists.
    ParameterError
        For an unknown storage, no topics, a bad segment length or a message type the type store
        does not know.
    ImportError
        When ``rosbags`` is not installed.
    """

    def __init__(
        self,
        path: str | Path,
        topics: Mapping[str, str],
        storage: str = "mcap",
        *,
        segment_s: float = SEGMENT_S,
    ) -> None:
        if storage not in RECORD_STORAGES:
            raise ParameterError(f"bag storage must be one of {list(RECORD_STORAGES)}, got {storage!r}")
        if not topics:
            raise ParameterError("a bag needs at least one topic")
        if not (isinstance(segment_s, int | float) and 0.0 < segment_s < float("inf")):
            raise ParameterError(f"segment_s must be a finite number of seconds > 0, got {segment_s!r}")
        self.path = Path(path)
        if self.path.exists():
            raise FileExistsError(f"{self.path} exists; a bag is never overwritten")
        store = typestore(ros1=False)
        unknown = sorted(kind for kind in topics.values() if kind not in store.types)
        if unknown:
            raise ParameterError(f"message types unknown to the bag's type store: {unknown}")
        self._segments = _Segments(self.path, dict(topics), store, storage, round(segment_s * _NS))
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.path.mkdir()
        # At once, not in the writing thread: a recording killed before its first message was
        # written is still recognised as one (rkmpc.learning.data.bags.read.bag_location).
        (self.path / DRAFTS).mkdir()
        self.storage = storage
        #: Messages given to :meth:`write`, by topic.
        self.counts = dict.fromkeys(topics, 0)
        self._queue: queue.SimpleQueue[tuple[str, int, bytes] | threading.Event | None] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._work, name=f"bag {self.path.name}", daemon=True)
        self._open = True
        self._discard = False
        self._thread.start()

    @property
    def closed(self) -> bool:
        """Whether the bag was closed (or discarded)."""
        return not self._open

    @property
    def segments(self) -> int:
        """Segments closed so far (listed in ``metadata.yaml``)."""
        return len(self._segments.closed)

    def write(self, topic: str, time_ns: int, data: bytes | memoryview) -> None:
        """Queue a serialised message of ``topic``, filed under ``time_ns`` (ns since its clock's epoch)."""
        if not self._open:
            raise ParameterError(f"{self.path}: the bag is closed")
        if topic not in self.counts:
            known = sorted(self.counts)
            raise ParameterError(f"{self.path}: topic {topic!r} was not declared; known: {known}")
        self._segments.raise_failure()
        self._queue.put((topic, int(time_ns), bytes(data)))
        self.counts[topic] += 1

    def wait(self) -> None:
        """Block until every message queued so far is in the segment being written (or in an error)."""
        if not self._open:
            return
        reached = threading.Event()
        self._queue.put(reached)  # the thread sets it when it gets there
        reached.wait()
        self._segments.raise_failure()

    def close(self) -> Path:
        """Write what is queued, finish the last segment and mark the bag closed; returns the path."""
        if not self._open:
            return self.path
        self._open = False
        self._queue.put(None)
        self._thread.join()
        self._segments.raise_failure()
        return self.path

    def discard(self) -> None:
        """Drop what was written: nothing is left of the bag."""
        if not self._open:
            return
        self._open = False
        self._discard = True
        self._queue.put(None)
        self._thread.join()
        shutil.rmtree(self.path, ignore_errors=True)

    def _work(self) -> None:
        """The writing thread: messages into segments until the end (:meth:`close`, :meth:`discard`)."""
        segments = self._segments
        while True:
            item = self._queue.get()
            if item is None:
                break
            if isinstance(item, threading.Event):
                item.set()
            elif segments.failure is None:
                segments.guarded(segments.write, *item)
        if self._discard:
            segments.guarded(segments.abort)
        else:
            segments.guarded(segments.finish)


class _Segments:
    """The segments of one bag, written by its thread (all of ``rosbags``' calls happen there)."""

    def __init__(self, path: Path, topics: dict[str, str], store: Any, storage: str, segment_ns: int) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        self.path = path
        self.topics = topics
        self.store = store
        self.writer_class: Any = Writer
        self.plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        self.segment_ns = segment_ns
        #: What ``metadata.yaml`` says of every closed segment: file, first and last stamp, counts.
        self.closed: list[dict[str, Any]] = []
        self.template: dict[str, Any] | None = None
        self.failure: BaseException | None = None
        self.writer: Any = None
        self.connections: dict[str, Any] = {}
        self.start = self.end = 0
        self.counts: dict[str, int] = {}

    def guarded(self, call: Any, *args: Any) -> None:
        """``call(*args)``, its error kept (:attr:`failure`) for the recorder's next call."""
        try:
            call(*args)
        except Exception as exc:  # kept for the recorder's next call: the thread must go on
            self.failure = exc

    def raise_failure(self) -> None:
        """Raise the error the thread met, if any."""
        if self.failure is not None:
            raise self.failure

    def write(self, topic: str, stamp: int, data: bytes) -> None:
        if self.writer is not None and stamp - self.start >= self.segment_ns:
            self.seal("unfinished")
        if self.writer is None:
            self.begin(stamp)
        self.writer.write(self.connections[topic], stamp, data)
        self.start, self.end = min(self.start, stamp), max(self.end, stamp)
        self.counts[topic] += 1

    def begin(self, stamp: int) -> None:
        name = f"{self.path.name}_{len(self.closed)}"
        writer = self.writer_class(
            self.path / DRAFTS / name, version=self.writer_class.VERSION_LATEST, storage_plugin=self.plugin
        )
        writer.open()
        self.connections = {
            topic: writer.add_connection(topic, kind, typestore=self.store)
            for topic, kind in self.topics.items()
        }
        self.writer, self.start, self.end = writer, stamp, stamp
        self.counts = dict.fromkeys(self.topics, 0)

    def seal(self, state: str) -> None:
        """Close the segment being written, move its file into the bag and list it."""
        writer, self.writer = self.writer, None
        writer.close()
        draft = Path(writer.path)
        if self.template is None:
            self.template = read_metadata(draft)
        (name,) = [p.name for p in draft.iterdir() if p.suffix in (".mcap", ".db3")]
        _flush(draft / name)
        os.replace(draft / name, self.path / name)
        shutil.rmtree(draft, ignore_errors=True)
        self.closed.append({"path": name, "start": self.start, "end": self.end, "counts": dict(self.counts)})
        self.write_metadata(state)

    def finish(self) -> None:
        if self.writer is None and not self.closed:
            self.begin(0)  # a bag without messages: one empty segment, as ros2 bag makes
        if self.writer is not None:
            self.seal("closed")
        shutil.rmtree(self.path / DRAFTS, ignore_errors=True)

    def abort(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None

    def write_metadata(self, state: str) -> None:
        """``metadata.yaml`` of the closed segments, replaced whole and flushed to the disk."""
        assert self.template is not None
        info = _merged(self.template, self.closed)
        info["custom_data"] = {RECORDING_KEY: state}
        text = json.dumps({"rosbag2_bagfile_information": info}, indent=1)
        with atomic_write(self.path / "metadata.yaml", suffix=".yaml.tmp") as handle:
            handle.write(text + "\n")
            handle.flush()
            os.fsync(handle.fileno())


def _flush(path: Path) -> None:
    """Push a finished file's data to the disk (it survives a power cut once listed)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _merged(template: dict[str, Any], closed: list[dict[str, Any]]) -> dict[str, Any]:
    """The bag's ``rosbag2_bagfile_information``: the first segment's, with every closed segment's files."""
    start = min(c["start"] for c in closed)
    end = max(c["end"] for c in closed)
    info = dict(template)
    info.update(
        relative_file_paths=[c["path"] for c in closed],
        files=[
            {
                "path": c["path"],
                "starting_time": {"nanoseconds_since_epoch": c["start"]},
                "duration": {"nanoseconds": c["end"] - c["start"]},
                "message_count": sum(c["counts"].values()),
            }
            for c in closed
        ],
        starting_time={"nanoseconds_since_epoch": start},
        duration={"nanoseconds": end - start},
        message_count=sum(sum(c["counts"].values()) for c in closed),
        topics_with_message_count=[
            {**topic, "message_count": sum(c["counts"][topic["topic_metadata"]["name"]] for c in closed)}
            for topic in template["topics_with_message_count"]
        ],
    )
    return info
