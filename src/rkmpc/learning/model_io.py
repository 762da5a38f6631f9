"""Load the model a controller needs, checking that it is of the right kind."""

from __future__ import annotations

import json
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

from rkmpc.errors import InputFileError
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.sim.log import write_json_atomic

_IDENTIFIED_FORMAT = "rkmpc-identified"


def save_identified(model: IdentifiedModel, path: str | Path, metadata: dict[str, Any] | None = None) -> None:
    """Write an identified model as JSON (temporary file, then renamed)."""
    write_json_atomic(
        path, {"format": _IDENTIFIED_FORMAT, "version": 1, "model": asdict(model), "metadata": metadata or {}}
    )


def load_identified(path: str | Path) -> IdentifiedModel:
    """Read a model written by :func:`save_identified`; clear errors for bad files."""
    path = Path(path)
    try:
        payload = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputFileError(path, "file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputFileError(path, f"not an identified-model JSON file: {exc}") from None
    if not isinstance(payload, dict) or payload.get("format") != _IDENTIFIED_FORMAT:
        raise InputFileError(path, f"not an {_IDENTIFIED_FORMAT} file", field="format")
    data = payload["model"] if isinstance(payload.get("model"), dict) else None
    names = [f.name for f in fields(IdentifiedModel)]
    if data is None or sorted(data) != sorted(names):
        raise InputFileError(path, f"expected the fields {names}", field="model")
    try:
        return IdentifiedModel(**data)
    except (TypeError, ValueError) as exc:
        raise InputFileError(path, str(exc), field="model") from None


def load_model(path: str | Path, kind: str) -> Any:
    """The model of ``kind`` (``identified``, ``residual``, ``paper``, ``koopman``) stored at ``path``."""
    if kind == "identified":
        return load_identified(path)
    from rkmpc.learning.koopman import KoopmanModel

    model = KoopmanModel.load(path)
    found = model.metadata_.get("kind")
    if found != kind:
        raise InputFileError(
            path, f"holds a {found!r} model, this controller needs a {kind!r} one", field="kind"
        )
    return model
