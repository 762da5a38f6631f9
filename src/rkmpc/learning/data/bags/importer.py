"""A bag recorded on a car (or by the ROS nodes) as the project's transition data set."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from rkmpc.core.errors import BagError
from rkmpc.learning.data.bags.config import BagImportConfig
from rkmpc.learning.data.bags.imported import imported_dataset
from rkmpc.learning.data.bags.read import BagStreams, Stream, read_streams
from rkmpc.learning.data.bags.resample import Samples, Transitions, resample, transitions
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.window import TimeWindow
from rkmpc.vehicle.params import VehicleParams

__all__ = ["import_bag", "streams_to_dataset"]


def import_bag(
    path: str | Path,
    vehicle: VehicleParams,
    config: BagImportConfig | None = None,
    *,
    scale: float | None = None,
) -> TransitionDataset:
    """Read a ROS 1 ``.bag``, ROS 2 sqlite3 or MCAP bag as transitions on the control period.

    The odometry (``nav_msgs/msg/Odometry``) is resampled every ``config.dt`` and each command
    (``ackermann_msgs/msg/AckermannDriveStamped``) held until the next; an odometry gap starts a
    new episode (:mod:`rkmpc.learning.data.bags.resample` says how).

    Parameters
    ----------
    path : str or Path
        A ``.bag`` file (ROS 1) or a ROS 2 bag folder (sqlite3 or MCAP, with its ``metadata.yaml``).
    vehicle : VehicleParams
        The car that was driven: its name and wheelbase go into the contract, its ``lr`` (m)
        moves rear-axle odometry to the centre of gravity.
    config : BagImportConfig, optional
        Topics, frames, time base and resampling; defaults to ``BagImportConfig()`` (the F1TENTH
        simulator's topics, odometry at the centre of gravity, header stamps, 50 ms).
    scale : float or None
        Scale of the track the car drove (for the contract); None when not known.

    Returns
    -------
    TransitionDataset
        With metadata ``source = "bag"``, the bag's path and storage, the topics and frames, the
        import's settings, the message counts, the first sample's stamp (s) and the contract
        (car, period, wheelbase, scale, state ranges).

    Raises
    ------
    BagError
        Naming the bag, the topic or field and the problem: a missing file or no bag, a missing
        topic (listing the bag's topics), a wrong message type, stamps that go backwards or repeat,
        non-finite values, too few transitions after resampling.
    ImportError
        When ``rosbags`` is not installed.
    """
    cfg = config if config is not None else BagImportConfig()
    streams = read_streams(path, cfg)
    return streams_to_dataset(streams, vehicle, cfg, scale=scale)


def streams_to_dataset(
    streams: BagStreams, vehicle: VehicleParams, config: BagImportConfig, *, scale: float | None = None
) -> TransitionDataset:
    """The transitions of streams read from a bag (:func:`import_bag` after reading)."""
    if config.window is not None:
        streams = _windowed(streams, config.window)
    samples = resample(
        streams.odom,
        streams.drive,
        streams.steer,
        dt=config.dt,
        gap=config.gap,
        tolerance=config.tolerance,
        lr=vehicle.lr if config.odom_frame == "rear-axle" else 0.0,
        min_slip_speed=config.min_slip_speed,
        lateral_velocity=config.lateral_velocity,
        yaw_rate=config.yaw_rate,
    )
    found = transitions(samples)
    if len(found) < config.min_samples:
        raise BagError(streams.path, _too_little(streams, samples, found, config), config.odom_topic)
    source = {
        "source": "bag",
        "bag": str(streams.path),
        "bag_storage": streams.storage,
        "recording": "unfinished" if streams.unfinished else "complete",
        "frames": {"frame_id": streams.frames[0], "child_frame_id": streams.frames[1]},
        **config.describe(),
        "messages": {
            "odom": len(streams.odom),
            "drive": len(streams.drive),
            "steer": None if streams.steer is None else len(streams.steer),
        },
        "start_stamp": float(found.stamps[0]) / 1e9,
    }
    return imported_dataset(found, source, dt=config.dt, vehicle=vehicle, scale=scale, packages=["rosbags"])


def _windowed(streams: BagStreams, window: TimeWindow) -> BagStreams:
    """The odometry and steer messages inside ``window``; BagError when no odometry is left.

    The window counts from the first message of the topics read. The commands are all kept: the
    grid starts at the first, as without a window, and a command sent before the window holds
    into it.
    """
    every = [s for s in (streams.odom, streams.drive, streams.steer) if s is not None]
    origin = min(int(s.stamps[0]) for s in every)
    span = (max(int(s.stamps[-1]) for s in every) - origin) / 1e9
    inside = window.mask(streams.odom.stamps, origin)
    if not np.any(inside):
        raise BagError(
            streams.path,
            f"the window {window.text()} holds no message of the topic; the bag's topics span "
            f"0 to {span:.2f} s from its first message (stamp {origin / 1e9:.3f} s)",
            streams.odom.topic,
        )
    steer = streams.steer
    if steer is not None:
        keep = window.mask(steer.stamps, origin)
        steer = (
            Stream(steer.topic, steer.stamps[keep], steer.values[keep], steer.fields)
            if np.any(keep)
            else None
        )
    odom = Stream(
        streams.odom.topic, streams.odom.stamps[inside], streams.odom.values[inside], streams.odom.fields
    )
    return replace(streams, odom=odom, steer=steer)


def _too_little(streams: BagStreams, samples: Samples, found: Transitions, config: BagImportConfig) -> str:
    """Why the bag gave too few transitions, with the counts along the way."""
    odom = streams.odom.stamps
    period = float(np.median(np.diff(odom))) / 1e9 if len(odom) > 1 else float("nan")
    before = int(np.sum(odom < streams.drive.stamps[0]))
    return (
        f"too little data: {len(found)} transitions after resampling at dt = {config.dt:g} s, "
        f"need at least {config.min_samples} ({len(odom)} odometry messages, one every {period:.3g} s "
        f"(median), {before} of them before the first command; {len(streams.drive)} commands; "
        f"{len(samples)} samples inside odometry stretches without a gap over {config.gap:g} s, "
        f"{int(np.sum(samples.usable))} of them with a fresh command and a speed >= 0)"
    )
