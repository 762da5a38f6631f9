"""A content-addressed cache of trained models.

Training a model is the slow part of an experiment (the KMPC model needs tens
of thousands of random-excitation samples and up to a minute of training), and
it depends only on what went into it. Each cached model is stored under the
SHA-256 hash of a JSON *spec*: everything that determines the model (data
hash or data-generation settings, training settings, vehicle parameters,
package version). A changed spec gives a new key, so a stale model is never
reused; an unreadable cache file is trained again and replaced.

The cache folder is, in this order: the ``directory`` given, the environment
variable ``RKMPC_CACHE_DIR``, ``$XDG_CACHE_HOME/rkmpc``, ``~/.cache/rkmpc``.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rkmpc.core.errors import InputFileError
from rkmpc.core.io import write_json_atomic
from rkmpc.core.jsonutil import json_default
from rkmpc.learning.koopman.model import KoopmanModel


def default_cache_dir() -> Path:
    """The cache folder used when none is given (see the module docstring)."""
    env = os.environ.get("RKMPC_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "rkmpc"


def spec_key(spec: Mapping[str, Any]) -> str:
    """SHA-256 hex digest of a spec's canonical JSON (sorted keys)."""
    text = json.dumps(spec, sort_keys=True, default=json_default, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class CacheHit:
    """Where a cached model came from.

    Parameters
    ----------
    key : str
        Spec hash.
    path : Path
        Model file.
    hit : bool
        True when the model was read from the cache, False when it was trained now.
    info : dict
        What the builder reported when the model was trained (sample counts,
        training time), stored beside the model and returned on later hits.
    """

    key: str
    path: Path
    hit: bool
    info: dict[str, Any]


class ModelCache:
    """Trained models by spec hash.

    Parameters
    ----------
    directory : str or Path or None
        Cache folder; :func:`default_cache_dir` when None.
    """

    def __init__(self, directory: str | Path | None = None) -> None:
        self.directory = Path(directory) if directory is not None else default_cache_dir()

    def path_for(self, spec: Mapping[str, Any]) -> Path:
        """File the model of ``spec`` is (or would be) stored in."""
        return self.directory / f"{spec['name'] if 'name' in spec else 'model'}-{spec_key(spec)[:20]}.rkm"

    def get_or_build(
        self,
        spec: Mapping[str, Any],
        build: Callable[[], tuple[KoopmanModel, dict[str, Any]]],
    ) -> tuple[KoopmanModel, CacheHit]:
        """The cached model of ``spec``, or ``build()``'s, which is then stored.

        Parameters
        ----------
        spec : mapping
            JSON-serialisable description of everything that determines the
            model; its optional ``name`` prefixes the file name.
        build : callable
            Trains the model; returns ``(model, info)`` with ``info`` a
            JSON-serialisable report kept beside the model.

        Returns
        -------
        model : KoopmanModel
        hit : CacheHit
        """
        key = spec_key(spec)
        path = self.path_for(spec)
        self.directory.mkdir(parents=True, exist_ok=True)
        # One process trains a slot at a time; another asking for it waits, then reads it.
        with open(path.with_suffix(".lock"), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                cached = self._read(spec, key, path)
                if cached is not None:
                    return cached
                model, info = build()
                model.save(path, metadata={**model.metadata_, "cache_spec": dict(spec)})
                write_json_atomic(path.with_suffix(".json"), {"key": key, "spec": dict(spec), "info": info})
                return model, CacheHit(key, path, False, info)
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def _read(self, spec: Mapping[str, Any], key: str, path: Path) -> tuple[KoopmanModel, CacheHit] | None:
        """The model stored for ``key``, or None (with a warning when the slot is unusable)."""
        info_path = path.with_suffix(".json")
        if not (path.exists() and info_path.exists()):
            return None
        try:
            model = KoopmanModel.load(path)
            stored = json.loads(info_path.read_text())
        except (InputFileError, OSError, ValueError) as exc:
            problem = f"unreadable ({exc})"
        else:
            made_for = model.metadata_["cache_spec"] if "cache_spec" in model.metadata_ else None
            if not isinstance(stored, dict) or not isinstance(stored.get("info"), dict):
                problem = "its description is not a JSON object with an info object"
            elif stored.get("key") != key:
                problem = "its description is of another model"
            elif not isinstance(made_for, dict) or spec_key(made_for) != key:
                problem = "it holds a model of another kind or setting"
            else:
                return model, CacheHit(key, path, True, dict(stored["info"]))
        warnings.warn(f"model cache slot {path}: {problem}; training it again", CacheWarning, stacklevel=3)
        return None


class CacheWarning(UserWarning):
    """A model cache slot could not be used and is trained again (it is then replaced)."""
