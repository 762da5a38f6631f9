"""JSON conversion: one place that turns rkmpc's values into plain JSON types."""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["json_default", "to_json_ready"]


def to_json_ready(obj: Any) -> Any:
    """Plain JSON types, recursively.

    Objects with a ``to_json()`` method give its result; dataclasses become
    dicts; numpy scalars and arrays become numbers and lists; paths become
    strings; tuples and sets become lists; NaN and infinities become None;
    anything else becomes its ``repr``.
    """
    to_json = getattr(obj, "to_json", None)
    if callable(to_json) and not isinstance(obj, type):
        return to_json_ready(to_json())
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_json_ready({f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)})
    if isinstance(obj, Mapping):
        return {str(k): to_json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [to_json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_json_ready(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, numbers.Integral):
        return int(obj)
    if isinstance(obj, numbers.Real):
        f = float(obj)
        return f if math.isfinite(f) else None
    if obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    return repr(obj)


def json_default(value: Any) -> Any:
    """``default=`` hook of :func:`json.dump` for numpy values, paths and tuples.

    Unlike :func:`to_json_ready` it keeps non-finite floats (``json.dump``
    writes them as ``NaN``) and refuses unknown objects with :class:`TypeError`.
    """
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"cannot write {type(value).__name__} as JSON")
