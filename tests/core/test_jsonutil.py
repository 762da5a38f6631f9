"""One JSON conversion for the whole package."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from rkmpc.core.jsonutil import json_default, to_json_ready


def test_to_json_ready_makes_strict_json():
    out = to_json_ready({"a": np.float64("nan"), "b": np.arange(3), "c": (1, np.int64(2)), 3: np.bool_(True)})
    assert out == {"a": None, "b": [0, 1, 2], "c": [1, 2], "3": True}
    json.dumps(out, allow_nan=False)


@dataclass(frozen=True)
class _Point:
    x: float
    where: Path


class _Typed:
    def to_json(self) -> dict:
        return {"kind": "typed", "value": np.float32(1.5)}


def test_dataclasses_paths_and_to_json_objects():
    assert to_json_ready(_Point(np.float64(2.0), Path("/tmp/a"))) == {"x": 2.0, "where": "/tmp/a"}
    assert to_json_ready([_Typed()]) == [{"kind": "typed", "value": 1.5}]
    assert to_json_ready(object()).startswith("<object")


def test_json_default_keeps_nan_and_refuses_unknown_objects():
    assert json.dumps({"v": np.float64("nan")}, default=json_default) == '{"v": NaN}'
    assert json.dumps({"p": Path("x"), "t": (1, 2)}, default=json_default) == '{"p": "x", "t": [1, 2]}'
    with pytest.raises(TypeError, match="cannot write"):
        json.dumps({"o": object()}, default=json_default)
