"""Identified tyres: the lateral force curve of each axle, and how well it predicts held-out data.

:class:`AxleCurve` is one axle's lateral force per unit vertical load (the friction
coefficient folded in: data cannot tell grip from the peak factor), linear in the slip
angle or the simplified magic formula. :class:`IdentifiedTyres` is what
:func:`rkmpc.learning.tyre_fit.identify_tyres` returns and an identified model
(:class:`~rkmpc.learning.identified_model.IdentifiedModel`, field ``tyres``) holds: the
structure chosen on held-out blocks, both curves, the status (``identified``, or
``nominal`` with the reason when no candidate predicted clearly better than the car's
nominal tyres) and the held-out figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer, is_real, named_numbers, require_choice
from rkmpc.vehicle.params import PacejkaParams, VehicleParams
from rkmpc.vehicle.tyres import LinearTyre, PacejkaTyre, TyreModel

__all__ = [
    "CURVE_KINDS",
    "MAX_PEAK_FACTOR",
    "MAX_STIFFNESS",
    "SERVO_SOURCES",
    "TYRE_SIGNALS",
    "TYRE_STATUSES",
    "TYRE_STRUCTURES",
    "WHEEL_SOURCES",
    "AxleCurve",
    "IdentifiedTyres",
    "nominal_curves",
]

#: Curve kinds and their parameters: ``linear`` (stiffness, 1/rad), ``pacejka`` (B, C, D, E).
CURVE_KINDS: dict[str, tuple[str, ...]] = {"linear": ("stiffness",), "pacejka": ("B", "C", "D", "E")}
#: Candidate structures (:mod:`rkmpc.learning.tyre_fit` describes each).
TYRE_STRUCTURES = ("nominal", "grip", "ratio", "linear", "pacejka")
#: ``identified``: beat the nominal tyres on held-out data; ``nominal``: did not, and is them.
TYRE_STATUSES = ("identified", "nominal")
#: What the curves were fitted on: yaw rate and side slip one step ahead, or the yaw rate alone.
TYRE_SIGNALS = ("slip_angle", "yaw_rate")
#: Where the wheel angle of the fit came from: measured, or run from the commands through the servo.
WHEEL_SOURCES = ("measured", "commands")
#: The servo a wheel run from the commands goes through: the identified one, its lag without its
#: delay, or the car's nominal one.
SERVO_SOURCES = ("identified", "lag", "nominal")
#: Largest plausible peak factor D (friction included) and stiffness per unit load (1/rad).
MAX_PEAK_FACTOR, MAX_STIFFNESS = 5.0, 100.0

_NAME = "IdentifiedTyres"


@dataclass(frozen=True, kw_only=True)
class AxleCurve:
    """Lateral force of one axle per unit vertical load, friction included, against the slip angle.

    Parameters
    ----------
    kind : str
        ``linear``: ``Fy / Fz = c alpha``; ``pacejka``:
        ``Fy / Fz = D sin(C atan(B alpha - E (B alpha - atan(B alpha))))``.
    parameters : tuple of float
        ``(c,)`` (1/rad), or ``(B, C, D, E)`` (1/rad, -, -, -), as :data:`CURVE_KINDS` names them.

    Raises
    ------
    ParameterError
        For an unknown kind, a wrong number of parameters, or a value no tyre has.
    """

    kind: str
    parameters: tuple[float, ...]

    def __post_init__(self) -> None:
        require_choice(self, "kind", CURVE_KINDS)
        names = CURVE_KINDS[self.kind]
        values = self.parameters
        if (
            not isinstance(values, (tuple, list))
            or len(values) != len(names)
            or not all(map(is_real, values))
        ):
            raise ParameterError(
                f"AxleCurve.parameters of a {self.kind} curve must be numbers {names}, got {values!r}"
            )
        values = tuple(float(v) for v in values)
        object.__setattr__(self, "parameters", values)
        if not all(math.isfinite(v) for v in values) or not all(v > 0 for v in values[:3]):
            raise ParameterError(f"AxleCurve.parameters must be finite, {names[:3]} > 0, got {values!r}")
        peak_factor = values[2] if self.kind == "pacejka" else 0.0
        if not 0.0 < self.stiffness <= MAX_STIFFNESS or peak_factor > MAX_PEAK_FACTOR:
            raise ParameterError(
                f"AxleCurve: stiffness {self.stiffness:.4g} 1/rad and peak factor D {peak_factor:.4g} "
                f"must be in (0, {MAX_STIFFNESS:g}] and at most {MAX_PEAK_FACTOR:g} (plausible for a tyre)"
            )

    @classmethod
    def linear(cls, stiffness: float) -> AxleCurve:
        """``Fy / Fz = stiffness * alpha`` (stiffness in 1/rad)."""
        return cls(kind="linear", parameters=(stiffness,))

    @classmethod
    def pacejka(cls, b: float, c: float, d: float, e: float = 0.0) -> AxleCurve:
        """The (simplified when ``e = 0``) magic formula per unit load."""
        return cls(kind="pacejka", parameters=(b, c, d, e))

    @property
    def stiffness(self) -> float:
        """Initial slope ``d(Fy / Fz) / d alpha`` (1/rad): ``c``, or ``B C D``."""
        p = self.parameters
        return p[0] if self.kind == "linear" else p[0] * p[1] * p[2]

    @property
    def peak(self) -> float:
        """Largest force per unit load over slip angles up to 90 degrees (``inf`` for a linear curve)."""
        if self.kind == "linear":
            return math.inf
        alpha = np.linspace(0.0, 0.5 * math.pi, 721)
        return float(np.max(self.force_per_load(alpha)))

    def force_per_load(self, alpha: np.ndarray) -> np.ndarray:
        """``Fy / Fz`` (-) at the slip angles ``alpha`` (rad), same shape."""
        alpha = np.asarray(alpha, dtype=float)
        if self.kind == "linear":
            return self.parameters[0] * alpha
        b, c, d, e = self.parameters
        ba = b * alpha
        return d * np.sin(c * np.arctan(ba - e * (ba - np.arctan(ba))))

    def tyre(self, mu: float) -> TyreModel:
        """The tyre model of a car whose force law multiplies by its friction ``mu``: this curve / ``mu``."""
        if self.kind == "linear":
            return LinearTyre(self.parameters[0] / mu)
        b, c, d, e = self.parameters
        return PacejkaTyre(PacejkaParams(B=b, C=c, D=d / mu, E=e))

    def describe(self) -> str:
        """One phrase: the kind, its parameters and the stiffness."""
        if self.kind == "linear":
            return f"linear {self.stiffness:.3f}/rad"
        b, c, d, e = self.parameters
        tail = f", E {e:.3f}" if e else ""
        return f"Pacejka B {b:.3f}, C {c:.3f}, D {d:.3f}{tail} (stiffness {self.stiffness:.3f}/rad)"


def nominal_curves(vehicle: VehicleParams) -> tuple[AxleCurve, AxleCurve]:
    """The car's nominal tyres as curves per unit load (its ``mu`` folded into ``D``)."""
    out = []
    for p in (vehicle.tyre_front, vehicle.tyre_rear):
        out.append(AxleCurve.pacejka(p.B, p.C, p.D * vehicle.mu, p.E))
    return out[0], out[1]


def _curve(field: str, value: object) -> AxleCurve:
    if isinstance(value, AxleCurve):
        return value
    if isinstance(value, Mapping) and set(value) == {"kind", "parameters"}:
        return AxleCurve(kind=value["kind"], parameters=tuple(value["parameters"] or ()))
    raise ParameterError(f"{_NAME}.{field} must be an AxleCurve or {{kind, parameters}}, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class IdentifiedTyres:
    """Tyre curves identified from laps, and how well they predict the lateral dynamics held out.

    Parameters
    ----------
    structure : str
        One of :data:`TYRE_STRUCTURES`: the candidate chosen (``nominal`` when none beat the car's
        nominal tyres).
    front, rear : AxleCurve
        The curves of the axles (the nominal ones when ``status`` is ``nominal``).
    status : str
        One of :data:`TYRE_STATUSES`.
    status_reason : str
        Why, in words.
    fitted_on : str
        One of :data:`TYRE_SIGNALS`.
    wheel : str
        One of :data:`WHEEL_SOURCES`: the wheel angle the fit used, which a controller must use too.
    servo : str
        One of :data:`SERVO_SOURCES`: the servo that wheel was run through from the commands (chosen
        on held-out blocks when the identified servo was fitted on the yaw rate and holds the
        chassis's lag; else the identified one).
    n_samples, folds : int
        Transitions the final fit used; time blocks of the cross-validation (0: none).
    heldout_score, nominal_score : float
        Held-out prediction error of the chosen curves and of the nominal ones on the same blocks, each
        channel divided by the spread of its one-step change (:mod:`rkmpc.learning.tyre_fit`); NaN when
        not measured.
    yaw_rate_rmse, nominal_yaw_rate_rmse : float
        Held-out yaw-rate RMSE (rad/s) of the prediction, chosen and nominal curves.
    lateral_velocity_rmse, nominal_lateral_velocity_rmse : float
        The same for the lateral velocity (m/s); NaN when the side slip was not measured.
    slip_reach : tuple of float
        Largest slip angle (rad) of the front and the rear axle in the data fitted (98th percentile):
        how far into the curves the data reach.
    candidates : tuple of (str, float)
        Every candidate compared and its held-out score.
    warnings : tuple of str
        What the data could not support, in words.
    """

    structure: str
    front: AxleCurve
    rear: AxleCurve
    status: str
    status_reason: str
    fitted_on: str
    wheel: str
    servo: str
    n_samples: int
    folds: int
    heldout_score: float = math.nan
    nominal_score: float = math.nan
    yaw_rate_rmse: float = math.nan
    nominal_yaw_rate_rmse: float = math.nan
    lateral_velocity_rmse: float = math.nan
    nominal_lateral_velocity_rmse: float = math.nan
    slip_reach: tuple[float, float] = (math.nan, math.nan)
    candidates: tuple[tuple[str, float], ...] = ()
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "front", _curve("front", self.front))
        object.__setattr__(self, "rear", _curve("rear", self.rear))
        for field, choices in (
            ("structure", TYRE_STRUCTURES),
            ("status", TYRE_STATUSES),
            ("fitted_on", TYRE_SIGNALS),
            ("wheel", WHEEL_SOURCES),
            ("servo", SERVO_SOURCES),
        ):
            require_choice(self, field, choices)
        if (self.status == "nominal") != (self.structure == "nominal"):
            raise ParameterError(
                f"{_NAME}: status {self.status!r} with structure {self.structure!r} "
                "(nominal goes with nominal)"
            )
        for field in ("n_samples", "folds"):
            if not is_integer(getattr(self, field), 0):
                raise ParameterError(f"{_NAME}.{field} must be an integer >= 0, got {getattr(self, field)!r}")
        for f in fields(self):
            if f.type == "float":
                value = getattr(self, f.name)
                if value is None:  # JSON's null: not measured
                    object.__setattr__(self, f.name, math.nan)
                elif not is_real(value):
                    raise ParameterError(f"{_NAME}.{f.name} must be a number or None, got {value!r}")
        reach = self.slip_reach
        if not isinstance(reach, (tuple, list)) or len(reach) != 2:
            raise ParameterError(f"{_NAME}.slip_reach must be two numbers (rad), got {reach!r}")
        object.__setattr__(self, "slip_reach", tuple(math.nan if v is None else float(v) for v in reach))
        if not isinstance(self.status_reason, str):
            raise ParameterError(f"{_NAME}.status_reason must be a string, got {self.status_reason!r}")
        if not isinstance(self.warnings, (tuple, list)) or not all(isinstance(w, str) for w in self.warnings):
            raise ParameterError(f"{_NAME}.warnings must be a sequence of strings, got {self.warnings!r}")
        object.__setattr__(self, "warnings", tuple(self.warnings))
        object.__setattr__(self, "candidates", named_numbers(self.candidates, f"{_NAME}.candidates"))

    @classmethod
    def from_json(cls, value: Mapping[str, Any]) -> IdentifiedTyres:
        """From the dictionary a model file holds (:func:`rkmpc.core.jsonutil.to_json_ready` of one)."""
        names = {f.name for f in fields(cls)}
        if not isinstance(value, Mapping) or set(value) != names:
            raise ParameterError(f"{_NAME}: expected the fields {sorted(names)}, got {value!r}")
        return cls(**value)

    @property
    def error_ratio(self) -> float:
        """Held-out score over the nominal tyres' (< 1: better); NaN when not measured."""
        return self.heldout_score / self.nominal_score if self.nominal_score > 0 else math.nan

    def understeer_gradient(self, gravity: float = 9.81) -> float:
        """``K = (1 / c_f - 1 / c_r) / g`` (s^2/m) the curves' initial stiffnesses imply (static loads)."""
        return (1.0 / self.front.stiffness - 1.0 / self.rear.stiffness) / gravity

    def tyres(self, mu: float) -> tuple[TyreModel, TyreModel]:
        """Front and rear tyre models of a car with friction ``mu`` (:meth:`AxleCurve.tyre`)."""
        return self.front.tyre(mu), self.rear.tyre(mu)
