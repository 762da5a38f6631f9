"""Model files by kind: load the model a controller needs, checking its kind and features."""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path
from typing import Any

from rkmpc.core.errors import InputFileError
from rkmpc.core.io import write_json_atomic
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.reading import check_regular_file
from rkmpc.learning.identified_model import IdentifiedModel
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.recipes import IdentificationLearner, recipe_of_kind

_IDENTIFIED_FORMAT = "rkmpc-identified"
#: Version 2 added the servo structure, delay, rate limit and the identification warnings; version 3
#: the status (``identified`` or ``nominal``, with the reason) and the held-out quality; version 4 the
#: identified tyres (``null`` when they were not identified).
_IDENTIFIED_VERSION = 4
#: The fields of version 1 files; the others take their defaults (a lag without delay or rate limit).
_VERSION_1_FIELDS = (
    "servo_time_constant",
    "understeer_gradient",
    "servo_fit_r2",
    "understeer_fit_r2",
    "n_samples",
)
#: The fields of version 2 files; the version 3 ones take their defaults (status ``unchecked``).
_VERSION_2_FIELDS = (*_VERSION_1_FIELDS, "servo_structure", "servo_delay", "servo_rate_limit", "warnings")
#: Fields added by version 4 (version 3 files have every other field; their models have no tyres).
_VERSION_4_FIELDS = ("tyres",)


def _fields_of(version: int) -> list[str]:
    if version == 1:
        return list(_VERSION_1_FIELDS)
    if version == 2:
        return list(_VERSION_2_FIELDS)
    every = [f.name for f in fields(IdentifiedModel)]
    return every if version == _IDENTIFIED_VERSION else [n for n in every if n not in _VERSION_4_FIELDS]


def save_identified(model: IdentifiedModel, path: str | Path, metadata: dict[str, Any] | None = None) -> None:
    """Write an identified model as JSON, format version 4 (temporary file, then renamed)."""
    write_json_atomic(
        path,
        {
            "format": _IDENTIFIED_FORMAT,
            "version": _IDENTIFIED_VERSION,
            "model": to_json_ready(model),
            "metadata": metadata or {},
        },
    )


def load_identified(path: str | Path) -> IdentifiedModel:
    """Read a model written by :func:`save_identified` (versions 1 to 4); clear errors for bad files.

    The file's metadata (with the contract of what the model was made with) is kept on the model
    as ``metadata_``, as :class:`~rkmpc.learning.koopman.model.KoopmanModel` keeps its own.

    Versions 1 and 2 predate the held-out checks: their models load with status ``unchecked``;
    versions 1 to 3 predate the tyres: their models have none.
    """
    path = Path(path)
    check_regular_file(path)
    try:
        payload = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputFileError(path, "file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputFileError(path, f"not an identified-model JSON file: {exc}") from None
    if not isinstance(payload, dict) or payload.get("format") != _IDENTIFIED_FORMAT:
        raise InputFileError(path, f"not an {_IDENTIFIED_FORMAT} file", field="format")
    version = payload.get("version")
    if version not in (1, 2, 3, _IDENTIFIED_VERSION) or isinstance(version, bool):
        raise InputFileError(
            path,
            f"unknown version {version!r}; this rkmpc reads versions 1 to {_IDENTIFIED_VERSION}",
            field="version",
        )
    data = payload["model"] if isinstance(payload.get("model"), dict) else None
    names = _fields_of(version)
    if data is None or sorted(data) != sorted(names):
        raise InputFileError(path, f"expected the fields {names} (version {version})", field="model")
    try:
        model = IdentifiedModel(**data)
    except (TypeError, ValueError) as exc:
        raise InputFileError(path, str(exc), field="model") from None
    metadata = payload.get("metadata")
    # What the model was made with (its contract: car, plant, period, wheelbase, scale), kept as a
    # Koopman model keeps it (``metadata_``), so that a model file is checked against the car it
    # drives (rkmpc.sim.build.check_model) whatever its kind.
    object.__setattr__(model, "metadata_", dict(metadata) if isinstance(metadata, dict) else {})
    return model


def load_model(path: str | Path, kind: str) -> IdentifiedModel | KoopmanModel:
    """The model of ``kind`` (a recipe's: ``identified``, ``residual``, ``paper``, ``koopman``) at ``path``.

    A Koopman model must say it is of that kind and, when it records its state features, they must
    be the recipe's (:mod:`rkmpc.learning.features`): a model is never fed other inputs than it was
    trained on.
    """
    recipe = recipe_of_kind(kind)
    identified = isinstance(recipe.learner, IdentificationLearner)
    check_regular_file(path)
    _refuse_other_format(Path(path), kind, identified=identified)
    if isinstance(recipe.learner, IdentificationLearner):
        loaded = load_identified(path)
        if recipe.learner.tyres and loaded.tyres is None:
            raise InputFileError(
                path,
                "holds an identified model without tyres (from `rkmpc train --kind identified`, or a file "
                f"of version 3 or older); {recipe.controller} needs one from `rkmpc train --kind {kind}`",
                field="tyres",
            )
        return loaded
    model = KoopmanModel.load(path)
    found = model.metadata_.get("kind")
    if found != kind:
        raise InputFileError(
            path, f"holds a {found!r} model, this controller needs a {kind!r} one", field="kind"
        )
    if recipe.state is not None and model.nx_ != recipe.state.size:
        raise InputFileError(
            path,
            f"the model takes {model.nx_} state features, the {kind!r} recipe feeds {recipe.state.size} "
            f"({recipe.state.describe()}); retrain it with this version",
            field="features",
        )
    features = model.metadata_.get("features")
    if isinstance(features, list) and recipe.state is not None and tuple(features) != recipe.state.names:
        raise InputFileError(
            path,
            f"the model was trained on the features {features}, "
            f"the {kind!r} recipe feeds {list(recipe.state.names)}",
            field="features",
        )
    return model


def _refuse_other_format(path: Path, kind: str, *, identified: bool) -> None:
    """A model file of the other format (JSON for an archive, or the reverse): say which it is."""
    try:
        with path.open("rb") as handle:
            head = handle.read(64).lstrip()
    except OSError:
        return  # the loader names what is wrong with the file
    is_archive, is_json = head.startswith(b"PK"), head.startswith(b"{")
    if identified and is_archive:
        raise InputFileError(
            path,
            "holds a learned (Koopman) model archive, from `rkmpc train --kind residual|paper|koopman`; "
            "lmpc-id needs an identified model, a JSON file from `rkmpc train --kind identified`",
        )
    if not identified and is_json:
        raise InputFileError(
            path,
            f"holds a JSON file (an identified model, for lmpc-id?); this controller needs a {kind!r} "
            f"model archive from `rkmpc train --kind {kind}`",
        )


def load_any_model(path: str | Path) -> IdentifiedModel | KoopmanModel:
    """The model at ``path``, whatever its kind: an identified model (JSON) or a Koopman model (archive)
    of the kind its file records, checked as :func:`load_model` checks it."""
    path = Path(path)
    check_regular_file(path)
    try:
        with path.open("rb") as handle:
            head = handle.read(64).lstrip()
    except OSError:
        head = b""  # the loader names what is wrong with the file
    if head.startswith(b"{"):
        return load_identified(path)
    kind = KoopmanModel.load(path).metadata_.get("kind")
    if not isinstance(kind, str):
        raise InputFileError(path, "the model file does not say its kind", field="kind")
    return load_model(path, kind)
