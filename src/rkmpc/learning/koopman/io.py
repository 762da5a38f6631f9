"""The ``.npz`` file of a Koopman model: layout, writing and validated reading.

One archive holds the matrices ``A, B, C, D, Cx``, the training-state range ``x_min, x_max``, the
training history, the lifting's learned arrays (``lifting.<name>``) and a JSON header ``metadata``
with the format name and version, the sizes and the settings. Format versions:

1. no state range (a model read from it clips nothing);
2. the state range; settings as the flat keyword arguments of the former ``KoopmanModel``;
3. settings as :meth:`KoopmanModel.get_params` (the lifting's own settings nested), no wall-clock budget.

Every problem with a file raises :class:`rkmpc.core.errors.InputFileError` naming the file, the
array or header field, and the problem. Nothing is unpickled.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TypeVar

import numpy as np

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.io import atomic_write
from rkmpc.core.jsonutil import json_default
from rkmpc.core.reading import read_npz
from rkmpc.learning.koopman.lifting import Lifting, MLPLifting, RBFLifting, lifting_from_params
from rkmpc.learning.koopman.settings import TRAINING_THREADS

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "READABLE_VERSIONS", "StoredModel", "read_model", "write_model"]

FORMAT_NAME = "rkmpc-koopman"
FORMAT_VERSION = 3
#: Format versions :func:`read_model` reads.
READABLE_VERSIONS = (1, 2, 3)
#: Lifting kinds a file may name (``"none"``: no dictionary).
LIFTING_KINDS = ("mlp", "rbf", "none")
MATRICES = ("A", "B", "C", "D", "Cx")

#: The flat settings of format versions 1 and 2, and their defaults there.
_FLAT_DEFAULTS: dict[str, Any] = {
    "lifting": "mlp",
    "n_lift": 16,
    "hidden": (64, 64),
    "include_state": True,
    "n_centers": 32,
    "rbf_kind": "thin_plate",
    "epochs": 300,
    "learning_rate": 1e-3,
    "batch_size": 1024,
    "huber_delta": 1.0,
    "rollout_steps": 10,
    "rollout_weight": 0.1,
    "ridge": 1e-6,
    "seed": 0,
    "max_seconds": 60.0,
    "clip_inputs": True,
}


class _Settings(Protocol):
    """What reading a file needs of the model class (:class:`~rkmpc.learning.koopman.model.KoopmanModel`)."""

    lifting: Lifting | None
    include_state: bool

    def validate(self) -> None: ...


class _Fitted(_Settings, Protocol):
    """What writing a file needs of a fitted model."""

    lifting_: Lifting | None
    n_lifted_: int
    nx_: int
    nu_: int
    ny_: int
    output_is_state_: bool
    fit_time_s_: float
    epochs_run_: int
    history_: list[tuple[int, float]]
    x_min_: np.ndarray
    x_max_: np.ndarray

    def get_params(self) -> dict[str, Any]: ...


M = TypeVar("M", bound=_Settings)


@dataclass(frozen=True)
class StoredModel:
    """What a model file holds, validated; :meth:`KoopmanModel.load` assembles the model from it."""

    model: Any
    lifting: Lifting | None
    matrices: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    sizes: tuple[int, int, int, int]
    x_min: np.ndarray
    x_max: np.ndarray
    output_is_state: bool
    history: list[tuple[int, float]]
    fit_time_s: float
    epochs_run: int
    metadata: dict[str, Any]


def model_from_params(cls: Callable[..., M], params: Mapping[str, Any]) -> M:
    """An unfitted ``cls`` from :meth:`KoopmanModel.get_params` output (ParameterError when bad)."""
    if not isinstance(params, Mapping):
        raise ParameterError(f"model settings must be a mapping, got {params!r}")
    unknown = sorted(set(params) - {"lifting", "include_state", "ridge", "clip_inputs"})
    if unknown:
        raise ParameterError(f"unknown model settings {unknown}")
    lifting = lifting_from_params(params.get("lifting"))
    extra = {k: params[k] for k in ("include_state", "ridge", "clip_inputs") if k in params}
    model = cls(lifting, **extra)
    model.validate()
    return model


def _model_from_flat(cls: Callable[..., M], flat: Mapping[str, Any]) -> M:
    """An unfitted ``cls`` from the flat settings of format versions 1 and 2 (turned into today's)."""
    unknown = sorted(set(flat) - set(_FLAT_DEFAULTS))
    if unknown:
        raise ParameterError(f"unknown settings {unknown}")
    p = {**_FLAT_DEFAULTS, **flat}
    training = (
        "epochs",
        "learning_rate",
        "batch_size",
        "huber_delta",
        "rollout_steps",
        "rollout_weight",
        "seed",
    )
    liftings: dict[str, dict[str, Any] | None] = {
        "mlp": {
            "kind": "mlp",
            "n_lift": p["n_lift"],
            "hidden": p["hidden"],
            "training": {name: p[name] for name in training},
        },
        "rbf": {
            "kind": "rbf",
            "n_centers": p["n_centers"],
            "rbf_kind": p["rbf_kind"],
            "seed": p["seed"],
            "method": "kmeans++",
            "width": None,
        },
        "none": None,
    }
    if p["lifting"] not in liftings:
        raise ParameterError(f"lifting must be one of {LIFTING_KINDS}, got {p['lifting']!r}")
    settings = {name: p[name] for name in ("include_state", "ridge", "clip_inputs")}
    return model_from_params(cls, {"lifting": liftings[p["lifting"]], **settings})


def write_model(path: str | Path, model: _Fitted, metadata: Mapping[str, Any] | None) -> None:
    """Write a fitted model in the current format (atomically)."""
    lifting = model.lifting_
    header = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "lifting": "none" if lifting is None else lifting.name,
        "n_lift": 0 if lifting is None else lifting.n_lift,
        "n_lifted": model.n_lifted_,
        "include_state": model.include_state,
        "nx": model.nx_,
        "nu": model.nu_,
        "ny": model.ny_,
        "output_is_state": model.output_is_state_,
        "params": model.get_params(),
        "fit_time_s": model.fit_time_s_,
        "epochs_run": model.epochs_run_,
        "torch_threads": TRAINING_THREADS,
        "user": dict(metadata) if metadata is not None else {},
    }
    arrays: dict[str, np.ndarray] = {name: getattr(model, f"{name}_") for name in MATRICES}
    arrays["history"] = np.array(model.history_, dtype=float).reshape(-1, 2)
    arrays["x_min"] = np.asarray(model.x_min_, dtype=float)
    arrays["x_max"] = np.asarray(model.x_max_, dtype=float)
    if lifting is not None:
        for key, value in lifting.to_arrays().items():
            arrays[f"lifting.{key}"] = value
    arrays["metadata"] = np.array(json.dumps(header, default=json_default))
    with atomic_write(path, "wb") as handle:
        np.savez(handle, allow_pickle=False, **arrays)


def _header(path: Path, arrays: Mapping[str, np.ndarray]) -> tuple[dict[str, Any], int]:
    if "metadata" not in arrays:
        raise InputFileError(path, "no metadata entry: not an rkmpc Koopman model", field="metadata")
    try:
        header = json.loads(str(arrays["metadata"].reshape(())))
    except (ValueError, TypeError) as exc:
        raise InputFileError(path, f"metadata is not valid JSON ({exc})", field="metadata") from None
    if not isinstance(header, dict):
        raise InputFileError(path, "metadata is not a JSON object", field="metadata")
    if header.get("format") != FORMAT_NAME:
        raise InputFileError(
            path, f"format is {header.get('format')!r}, expected {FORMAT_NAME!r}", field="metadata.format"
        )
    version = header.get("format_version")
    if version not in READABLE_VERSIONS:
        readable = ", ".join(map(str, READABLE_VERSIONS))
        raise InputFileError(
            path,
            f"unsupported format version {version!r} (readable: {readable})",
            field="metadata.format_version",
        )
    return header, int(version)


def _sizes(path: Path, header: Mapping[str, Any]) -> dict[str, int]:
    sizes: dict[str, int] = {}
    for key in ("nx", "nu", "ny", "n_lifted", "n_lift"):
        value = header.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise InputFileError(
                path, f"{key} must be a non-negative integer, got {value!r}", field=f"metadata.{key}"
            )
        sizes[key] = value
    return sizes


def _settings(path: Path, cls: Callable[..., M], header: Mapping[str, Any], version: int) -> M:
    kind = header.get("lifting")
    if kind not in LIFTING_KINDS:
        raise InputFileError(path, f"unknown lifting kind {kind!r}", field="metadata.lifting")
    params = header.get("params")
    if not isinstance(params, dict):
        raise InputFileError(path, "params must be a JSON object", field="metadata.params")
    try:
        model = model_from_params(cls, params) if version >= 3 else _model_from_flat(cls, params)
    except (TypeError, ParameterError) as exc:
        raise InputFileError(path, f"bad training parameters: {exc}", field="metadata.params") from None
    stated = "none" if model.lifting is None else model.lifting.name
    if stated != kind:
        raise InputFileError(path, f"lifting {kind!r} but params say {stated!r}", field="metadata.lifting")
    if header.get("include_state") != model.include_state:
        raise InputFileError(path, "include_state disagrees with params", field="metadata.include_state")
    return model


def _matrices(
    path: Path, arrays: Mapping[str, np.ndarray], sizes: Mapping[str, int]
) -> dict[str, np.ndarray]:
    """Matrices: present, 2-D, finite, shapes consistent."""
    mats: dict[str, np.ndarray] = {}
    for name in MATRICES:
        if name not in arrays:
            raise InputFileError(path, f"missing array {name!r}", field=name)
        value = arrays[name]
        if value.ndim != 2 or not np.issubdtype(value.dtype, np.number):
            raise InputFileError(
                path, f"{name} must be a 2-D numeric array, got shape {value.shape}", field=name
            )
        if not np.all(np.isfinite(value)):
            raise InputFileError(path, f"{name} contains NaN or infinite values", field=name)
        mats[name] = value.astype(float)
    nz, nx, nu, ny = sizes["n_lifted"], sizes["nx"], sizes["nu"], sizes["ny"]
    expected = {"A": (nz, nz), "B": (nz, nu), "C": (ny, nz), "D": (ny, nu), "Cx": (nx, nz)}
    if mats["A"].shape[0] != mats["A"].shape[1]:
        raise InputFileError(path, f"A must be square, got {mats['A'].shape}", field="A")
    for name, shape in expected.items():
        if mats[name].shape != shape:
            raise InputFileError(
                path,
                f"{name} has shape {mats[name].shape}, expected {shape} (nz={nz}, nx={nx}, nu={nu}, ny={ny})",
                field=name,
            )
    return mats


def _lifting(
    path: Path, arrays: Mapping[str, np.ndarray], spec: Lifting | None, sizes: Mapping[str, int]
) -> Lifting | None:
    if spec is None:
        return None
    prefix = "lifting."
    sub = {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}
    try:
        if isinstance(spec, MLPLifting):
            fitted: Lifting = MLPLifting.from_arrays(sub, training=spec.training)
        else:
            fitted = RBFLifting.from_arrays(sub, seed=spec.seed)
    except KeyError as exc:
        key = str(exc.args[0]) if exc.args else "?"
        raise InputFileError(path, f"missing lifting array {key!r}", field=prefix + key) from None
    except (ParameterError, ValueError, TypeError, IndexError) as exc:
        raise InputFileError(path, f"invalid lifting arrays: {exc}", field="lifting") from None
    if fitted.nx_ != sizes["nx"] or fitted.n_lift != sizes["n_lift"]:
        raise InputFileError(
            path,
            f"lifting maps {fitted.nx_} -> {fitted.n_lift}, metadata says {sizes['nx']} -> {sizes['n_lift']}",
            field="lifting",
        )
    return fitted


def _state_range(path: Path, arrays: Mapping[str, np.ndarray], key: str, nx: int) -> np.ndarray:
    """The ``x_min`` or ``x_max`` array of a saved model: present, shape (nx,), finite."""
    if key not in arrays:
        raise InputFileError(path, f"missing array {key!r}", field=key)
    value = arrays[key]
    if value.shape != (nx,) or not np.issubdtype(value.dtype, np.number):
        raise InputFileError(
            path, f"{key} must be a numeric array of shape ({nx},), got {value.shape}", field=key
        )
    if not np.all(np.isfinite(value)):
        raise InputFileError(path, f"{key} contains NaN or infinite values", field=key)
    return value.astype(float)


def read_model(path: str | Path, cls: Callable[..., M]) -> StoredModel:
    """Read and validate a model file; ``cls`` is the model class to build (``KoopmanModel``)."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "file not found")
    arrays = read_npz(path)
    header, version = _header(path, arrays)
    sizes = _sizes(path, header)
    model = _settings(path, cls, header, version)
    mats = _matrices(path, arrays, sizes)
    lifting = _lifting(path, arrays, model.lifting, sizes)
    nz, nx = sizes["n_lifted"], sizes["nx"]
    n_state = nx if model.include_state else 0
    n_psi = 0 if lifting is None else lifting.n_lift
    if nz != n_state + n_psi:
        raise InputFileError(
            path,
            f"n_lifted={nz}, but state block ({n_state}) + lifting ({n_psi}) = {n_state + n_psi}",
            field="metadata.n_lifted",
        )
    if version == 1:
        x_min, x_max = np.full(nx, -np.inf), np.full(nx, np.inf)
    else:
        x_min, x_max = (_state_range(path, arrays, key, nx) for key in ("x_min", "x_max"))
        if np.any(x_min > x_max):
            raise InputFileError(path, "x_min exceeds x_max for some feature", field="x_min")
    history = arrays.get("history", np.zeros((0, 2)))
    return StoredModel(
        model=model,
        lifting=lifting,
        matrices=(mats["A"], mats["B"], mats["C"], mats["D"], mats["Cx"]),
        sizes=(nz, nx, sizes["nu"], sizes["ny"]),
        x_min=x_min,
        x_max=x_max,
        output_is_state=bool(header.get("output_is_state", False)),
        history=[(int(e), float(v)) for e, v in np.asarray(history).reshape(-1, 2)],
        fit_time_s=float(header.get("fit_time_s", float("nan"))),
        epochs_run=int(header.get("epochs_run", 0)),
        metadata=dict(header.get("user") or {}),
    )
