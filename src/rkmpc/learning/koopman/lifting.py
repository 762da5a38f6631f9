"""Lifting functions psi: R^nx -> R^n_lift, the dictionaries of a Koopman model.

Each lifting is an estimator in the style of scikit-learn and pykoop: ``__init__`` only stores its
settings, ``fit`` learns from data and returns ``self``, learned attributes end in ``_``, and a
fitted lifting maps states of shape (n_samples, nx) to features of shape (n_samples, n_lift) (or one
state of shape (nx,) to (n_lift,)) in plain numpy, so using a model needs no torch.

* :class:`~rkmpc.learning.koopman.mlp.MLPLifting` -- a network (standardisation, two ReLU hidden layers,
  linear output) trained with the paper's loss (:mod:`rkmpc.learning.koopman.training`, PyTorch) as set
  by :class:`~rkmpc.learning.koopman.settings.MLPTraining`;
* :class:`~rkmpc.learning.koopman.rbf.RBFLifting` -- a fixed radial-basis dictionary in the spirit of
  Korda & Mezic (2018).

``to_arrays()`` / ``from_arrays()`` convert a fitted lifting to and from flat named arrays for storage;
``get_params()`` gives its settings as plain JSON types. This module is the common entry point: it
names the union :data:`Lifting`, rebuilds a lifting from its settings (:func:`lifting_from_params`,
:func:`clone`) and re-exports the liftings and their helpers.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rkmpc.core.errors import ParameterError
from rkmpc.learning.koopman.common import standardisation
from rkmpc.learning.koopman.mlp import MLPLifting
from rkmpc.learning.koopman.rbf import RBF_KINDS, RBFLifting
from rkmpc.learning.koopman.settings import MLPTraining

__all__ = [
    "RBF_KINDS",
    "Lifting",
    "MLPLifting",
    "MLPTraining",
    "RBFLifting",
    "clone",
    "lifting_from_params",
    "standardisation",
]


#: A lifting of a :class:`~rkmpc.learning.koopman.model.KoopmanModel` (None: no dictionary, ``z = x``).
Lifting = MLPLifting | RBFLifting


def lifting_from_params(params: Mapping[str, Any] | None) -> Lifting | None:
    """An unfitted lifting from :meth:`get_params` output (None for none); ParameterError when bad."""
    if params is None:
        return None
    if not isinstance(params, Mapping):
        raise ParameterError(f"lifting settings must be a mapping or None, got {params!r}")
    kind = params.get("kind")
    try:
        if kind == MLPLifting.name:
            training = MLPTraining(**dict(params["training"]))
            lifting: Lifting = MLPLifting(int(params["n_lift"]), tuple(params["hidden"]), training)
        elif kind == RBFLifting.name:
            lifting = RBFLifting(
                n_centers=params["n_centers"],
                kind=params["rbf_kind"],
                seed=params["seed"],
                method=params["method"],
                width=params["width"],
            )
        else:
            raise ParameterError(
                f"unknown lifting kind {kind!r}; known: {MLPLifting.name!r}, {RBFLifting.name!r}"
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f"bad {kind!r} lifting settings {dict(params)!r}: {exc}") from None
    lifting.validate()
    return lifting


def clone(lifting: Lifting | None) -> Lifting | None:
    """An unfitted copy of ``lifting`` with the same settings (None stays None)."""
    return lifting_from_params(None if lifting is None else lifting.get_params())
