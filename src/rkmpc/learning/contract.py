"""What a data set or a model was made with, and the check that it is used with the same.

A model learned at one control period or on one car answers for that period and that car: data
recorded at ``dt = 0.01 s`` and used at ``0.05 s`` gives nine times the prediction error, a model of
the full-size car driven on the 1:10 car six to eight times. :class:`Provenance` records the car
(its preset name and wheelbase), the control period, the track scale and the range of every state
feature a data set (:class:`rkmpc.learning.data.dataset.TransitionDataset`, in its metadata) or a
model (:class:`rkmpc.learning.koopman.model.KoopmanModel`, in ``metadata_``) was made with, under
the key :data:`CONTRACT_KEY`.

:meth:`Provenance.check` compares it with the conditions of a run (or of a training) and refuses a
mismatch with a :class:`~rkmpc.core.errors.ContractError` naming the file, the field and both
values, unless the caller asks for it explicitly (``allow_mismatch=True``, ``--allow-mismatch`` on
the command line): then it warns (:class:`~rkmpc.core.errors.ContractWarning`) and returns the
warnings for the caller to record. A field either side does not know (``None``: random-excitation data
has no track, a controller does not know the track) is not checked; a file written before
contracts still loads, and checking it warns once that its fields are not checked.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from rkmpc.core.errors import ContractError, ContractWarning, ParameterError
from rkmpc.core.validation import is_positive_number

__all__ = ["CHECKED_FIELDS", "CONTRACT_KEY", "Provenance", "contract_of"]

#: Metadata key under which data sets and models store their :class:`Provenance`.
CONTRACT_KEY = "contract"
#: The fields :meth:`Provenance.check` compares, with their units for messages.
CHECKED_FIELDS = {"vehicle": "", "plant": "", "dt": " s", "wheelbase": " m", "scale": ""}
#: Relative tolerance of the numeric comparisons (a period read back from JSON is the same period).
_RTOL = 1e-6


def _optional_positive(obj: object, name: str) -> None:
    value = getattr(obj, name)
    if value is None:
        return
    if not is_positive_number(value):
        raise ParameterError(f"{type(obj).__name__}.{name} must be None or finite and > 0, got {value!r}")
    object.__setattr__(obj, name, float(value))


def _floats(values: Sequence[Any], what: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ParameterError(f"Provenance.{what} must be numbers, got {values!r}") from None
    if not all(math.isfinite(v) for v in out):
        raise ParameterError(f"Provenance.{what} must be finite, got {values!r}")
    return out


@dataclass(frozen=True)
class Provenance:
    """The car, period, track scale and state ranges a data set or a model was made with.

    Every field may be None (not known): a file written before contracts, or a side of a check
    that does not know it.

    Parameters
    ----------
    vehicle : str or None
        Vehicle preset name (``"f1tenth"``, ``"fullsize"``).
    plant : str or None
        The car that was driven: the preset's own plant (``"f1tenth"``) or a zoo car
        (``"gym"``, ``"random-3"``); None when not known (a real car's log).
    dt : float or None
        Control period (s), > 0.
    wheelbase : float or None
        Wheelbase of the car (m), > 0.
    scale : float or None
        Scale the track file was loaded at (1.0 for the built-in tracks, made at 1:10); None for
        data and models that do not depend on a track (random excitation).
    features : tuple of str
        Names of the state features whose range follows.
    state_min, state_max : tuple of float
        Smallest and largest value of each feature in the data (SI units of the feature), finite,
        ``state_min <= state_max``.
    recorded : bool
        False for a file written before contracts (:func:`contract_of`): checking it warns once
        that what it does not record is not checked. Not part of the JSON.

    Raises
    ------
    ParameterError
        Naming the field, when a value is invalid.
    """

    vehicle: str | None = None
    plant: str | None = None
    dt: float | None = None
    wheelbase: float | None = None
    scale: float | None = None
    features: tuple[str, ...] = ()
    state_min: tuple[float, ...] = ()
    state_max: tuple[float, ...] = ()
    recorded: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.recorded, bool):
            raise ParameterError(f"Provenance.recorded must be a bool, got {self.recorded!r}")
        for name in ("vehicle", "plant"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, str) and value):
                raise ParameterError(f"Provenance.{name} must be None or a non-empty string, got {value!r}")
        for name in ("dt", "wheelbase", "scale"):
            _optional_positive(self, name)
        if isinstance(self.features, str) or not all(isinstance(n, str) for n in self.features):
            raise ParameterError(f"Provenance.features must be names, got {self.features!r}")
        object.__setattr__(self, "features", tuple(self.features))
        low, high = _floats(self.state_min, "state_min"), _floats(self.state_max, "state_max")
        if not len(low) == len(high) == len(self.features):
            raise ParameterError(
                f"Provenance: {len(self.features)} features, {len(low)} minima and {len(high)} maxima"
            )
        if any(lo > hi for lo, hi in zip(low, high, strict=True)):
            raise ParameterError("Provenance.state_min exceeds state_max for some feature")
        object.__setattr__(self, "state_min", low)
        object.__setattr__(self, "state_max", high)

    # ------------------------------------------------------------------ building

    def with_ranges(self, features: Sequence[str], values: np.ndarray) -> Provenance:
        """The same provenance with the range of each column of ``values`` (shape (M, len(features))).

        Columns without a finite value (a quantity that was not measured) are left out.
        """
        values = np.asarray(values, dtype=float).reshape(-1, len(features))
        finite = np.isfinite(values)
        keep = [j for j in range(len(features)) if finite[:, j].any()]
        low = [float(np.min(values[finite[:, j], j])) for j in keep]
        high = [float(np.max(values[finite[:, j], j])) for j in keep]
        return replace(
            self, features=tuple(features[j] for j in keep), state_min=tuple(low), state_max=tuple(high)
        )

    def merged(self, other: Provenance) -> Provenance:
        """What two data sets joined together were made with: fields they agree on, ranges joined.

        A field the two disagree on (two track scales) becomes unknown; the ranges of the features
        both record are joined.
        """
        same = {
            name: getattr(self, name)
            for name in CHECKED_FIELDS
            if _equal(getattr(self, name), getattr(other, name))
        }
        mine = dict(zip(self.features, zip(self.state_min, self.state_max, strict=True), strict=True))
        theirs = dict(zip(other.features, zip(other.state_min, other.state_max, strict=True), strict=True))
        names = tuple(n for n in self.features if n in theirs)
        low = tuple(min(mine[n][0], theirs[n][0]) for n in names)
        high = tuple(max(mine[n][1], theirs[n][1]) for n in names)
        return Provenance(**same, features=names, state_min=low, state_max=high)

    # ------------------------------------------------------------------ JSON

    def to_json(self) -> dict[str, Any]:
        """Plain JSON types (tuples as lists)."""
        return {
            "vehicle": self.vehicle,
            "plant": self.plant,
            "dt": self.dt,
            "wheelbase": self.wheelbase,
            "scale": self.scale,
            "features": list(self.features),
            "state_min": list(self.state_min),
            "state_max": list(self.state_max),
        }

    @classmethod
    def from_json(cls, data: Any) -> Provenance:
        """A provenance from :meth:`to_json` output; ParameterError naming the problem when invalid."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"a contract must be a JSON object, got {data!r}")
        names = {f.name for f in fields(cls)} - {"recorded"}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ParameterError(f"unknown contract fields {unknown}")
        known = {name: data[name] for name in names if name in data}
        for name in ("features", "state_min", "state_max"):
            if name in known:
                if not isinstance(known[name], list):
                    raise ParameterError(f"contract field {name!r} must be a list, got {known[name]!r}")
                known[name] = tuple(known[name])
        return cls(**known)

    # ------------------------------------------------------------------ the check

    def unknown(self) -> tuple[str, ...]:
        """The checked fields this provenance does not know."""
        return tuple(name for name in CHECKED_FIELDS if getattr(self, name) is None)

    def mismatches(self, against: Provenance, source: str, made: str = "made") -> tuple[str, ...]:
        """One sentence per checked field both sides know and disagree on (see :meth:`check`)."""
        out = []
        for name, unit in CHECKED_FIELDS.items():
            mine, theirs = getattr(self, name), getattr(against, name)
            if mine is None or theirs is None or _equal(mine, theirs):
                continue
            was, uses = f"{_show(mine)}{unit}", f"{_show(theirs)}{unit}"
            out.append(f"{source} was {made} with {name} = {was}; this run uses {name} = {uses}")
        return tuple(out)

    def check(
        self, against: Provenance, *, source: str, made: str = "made", allow_mismatch: bool = False
    ) -> tuple[str, ...]:
        """Refuse to use what this provenance describes under the conditions ``against``.

        Parameters
        ----------
        against : Provenance
            The conditions of the run or the training (None fields are not checked).
        source : str
            What is checked, for messages (the file name, ``"the data set"``).
        made : str
            How it was made, for messages (``"trained"``, ``"recorded"``).
        allow_mismatch : bool
            Use it anyway: each mismatch becomes a :class:`~rkmpc.core.errors.ContractWarning`.

        Returns
        -------
        tuple of str
            The warnings issued (allowed mismatches, fields ``source`` does not record), for the
            caller to record beside its results; empty when everything matches.

        Raises
        ------
        ContractError
            On a mismatch, unless ``allow_mismatch``; the message names the file, every field that
            differs and both values.
        """
        problems = self.mismatches(against, source, made)
        if problems and not allow_mismatch:
            raise ContractError(source, "; ".join(problems), mismatch=True)
        issued = [f"{problem} (allowed)" for problem in problems]
        missing = [name for name in self.unknown() if getattr(against, name) is not None]
        if missing and not self.recorded:
            issued.append(f"{source} was made before contracts: its {', '.join(missing)} not checked")
        for message in issued:
            warnings.warn(message, ContractWarning, stacklevel=2)
        return tuple(issued)


def contract_of(metadata: Mapping[str, Any], *, dt: float | None = None) -> Provenance:
    """The :class:`Provenance` stored in a metadata dict, or an unknown one (with ``dt`` when given).

    Raises
    ------
    ParameterError
        When the stored contract is invalid.
    """
    if CONTRACT_KEY not in metadata:
        return Provenance(dt=dt, recorded=False)
    return Provenance.from_json(metadata[CONTRACT_KEY])


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, str) or isinstance(b, str) or a is None or b is None:
        return bool(a == b)
    return math.isclose(float(a), float(b), rel_tol=_RTOL, abs_tol=0.0)


def _show(value: Any) -> str:
    return repr(value) if isinstance(value, str) else f"{value:g}"
