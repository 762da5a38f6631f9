"""Tracks: arc-length paths, track loaders, built-in tracks, speed profiles and references."""

from rkmpc.core.angles import wrap_angle
from rkmpc.track.builtin import BUILTIN_DESCRIPTIONS, builtin_track, list_builtin_tracks
from rkmpc.track.crossings import Crossing
from rkmpc.track.loaders import find_self_intersection, load_centerline, load_raceline, load_track
from rkmpc.track.path import Path, PathSamples, Projection
from rkmpc.track.reference import Reference, ReferenceHorizon
from rkmpc.track.speed_profile import SpeedLimits, SpeedProfile, speed_profile
from rkmpc.track.track import Track

__all__ = [
    "BUILTIN_DESCRIPTIONS",
    "Crossing",
    "Path",
    "PathSamples",
    "Projection",
    "Reference",
    "ReferenceHorizon",
    "SpeedLimits",
    "SpeedProfile",
    "Track",
    "builtin_track",
    "find_self_intersection",
    "list_builtin_tracks",
    "load_centerline",
    "load_raceline",
    "load_track",
    "speed_profile",
    "wrap_angle",
]
