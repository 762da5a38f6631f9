"""The identified model: the steering servo, the understeer gradient, the tyres and how well they predict.

:class:`IdentifiedModel` is what :func:`rkmpc.learning.identification.identify`
returns, ``lmpc-id`` drives with and an identified-model file holds
(:mod:`rkmpc.learning.io`). Its ``status`` says whether the model was checked on
held-out data and beat the car's nominal model there (``identified``), did not
and is the nominal model (``nominal``, with the reason), or predates those checks
(``unchecked``: files of versions 1 and 2, models built by hand). The tyres, when they were
identified too (``nmpc-id``'s model, :mod:`rkmpc.learning.tyre_fit`), carry a status of their own.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import KW_ONLY, dataclass

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer, is_real, named_numbers, require_choice
from rkmpc.learning.servo_model import MAX_DELAY, SERVO_STRUCTURES
from rkmpc.learning.tyre_model import IdentifiedTyres
from rkmpc.learning.understeer import UNDERSTEER_RANGE

__all__ = [
    "FIT_SIGNALS",
    "MODEL_STATUSES",
    "RATE_LIMIT_RANGE",
    "SERVO_STRUCTURE_NAMES",
    "TIME_CONSTANT_RANGE",
    "IdentifiedModel",
]

#: Servo structures a model may name: the fitted ones, and ``nominal`` (the car's own lag, kept).
SERVO_STRUCTURE_NAMES: tuple[str, ...] = (*(s.name for s in SERVO_STRUCTURES), "nominal")
#: ``identified``: beat the nominal model on held-out data; ``nominal``: did not, and is the nominal
#: model; ``unchecked``: never checked on held-out data (files of versions 1 and 2, hand-made models).
MODEL_STATUSES = ("identified", "nominal", "unchecked")
#: What the servo was fitted on: the measured wheel angle, or the response of the yaw rate.
FIT_SIGNALS = ("steer_angle", "yaw_rate")
#: Range of servo time constants (s) an identified model may hold: a factor beyond the fits' own
#: search ranges either way, so the nominal lag of any real car fits too. Checked on every model,
#: also one read from a file.
TIME_CONSTANT_RANGE = (1e-3, 2.0)
#: Range of servo rate limits (rad/s) an identified model may hold (the fits search a narrower one).
RATE_LIMIT_RANGE = (0.01, 100.0)

_NAME = "IdentifiedModel"


def _check_range(field: str, value: object, bounds: tuple[float, float], unit: str) -> None:
    low, high = bounds
    if not (is_real(value) and low <= float(value) <= high):  # type: ignore[arg-type]
        raise ParameterError(
            f"{_NAME}.{field} must be a number in [{low:g}, {high:g}] {unit} (plausible for a car), "
            f"got {value!r}"
        )


@dataclass(frozen=True)
class IdentifiedModel:
    """The steering servo and the understeer gradient identified from data, and their held-out quality.

    Parameters
    ----------
    servo_time_constant : float
        First-order time constant of the steering servo (s), > 0.
    understeer_gradient : float
        ``K`` (s^2/m, that is rad per m/s^2): the effective wheelbase grows as
        ``L + K v^2``, so steady cornering needs ``tan(delta) = (L + K v^2) kappa``
        (:func:`~rkmpc.learning.understeer.steady_state_steer`); for small angles, the extra
        wheel angle per unit lateral acceleration.
    servo_fit_r2, understeer_fit_r2 : float
        In-sample coefficients of determination of the final fits, for reference (the
        held-out figures below decide): the servo's one-step wheel-angle changes (measured
        wheel angle) or the yaw rate (fitted on the yaw rate); the wheel angle beyond the
        kinematic one explained by ``K``. NaN (None in JSON) when no such fit was made.
    n_samples : int
        Transitions the servo was fitted on.
    servo_structure : str
        One of :data:`SERVO_STRUCTURE_NAMES`: the structure chosen, or ``nominal`` when the
        car's nominal lag was kept.
    servo_delay : float
        Pure delay of the servo (s), in ``[0, MAX_DELAY]``.
    servo_rate_limit : float or None
        Largest wheel rate (rad/s) when one was fitted; None: the car's nominal rate limit.
    warnings : tuple of str
        What identification could not support and what it did instead, in words.
    status : str, keyword-only
        One of :data:`MODEL_STATUSES`.
    status_reason : str, keyword-only
        Why the model has its status, in words (empty for ``unchecked``).
    fitted_on : str or None, keyword-only
        One of :data:`FIT_SIGNALS`, None when not recorded.
    folds : int, keyword-only
        Time blocks of the cross-validation (0: none).
    heldout_rmse, nominal_rmse : float, keyword-only
        Root-mean-square error (rad/s) of the yaw rate predicted from the commands on the
        held-out blocks, by this model and by the car's nominal model (its servo, ``K = 0``) on
        the same blocks; NaN when not measured.
    heldout_r2 : float, keyword-only
        Share of the variance of the held-out yaw rate this model predicts.
    wheel_heldout_rmse, wheel_nominal_rmse : float, keyword-only
        The same for the wheel angle (rad) run from the commands, when it was measured.
    heldout_candidates : tuple of (str, float), keyword-only
        Every candidate compared and its held-out yaw-rate RMSE (rad/s; of the wheel angle, rad,
        when the servo was fitted on a measured one).
    tyres : IdentifiedTyres or None, keyword-only
        The tyre curves identified from the same data, with their own status and held-out figures;
        None when they were not identified (``lmpc-id``'s model, files of versions 1 to 3).

    Raises
    ------
    ParameterError
        Naming the field, for a value no car has (a hand-edited file): a time constant beyond
        :data:`TIME_CONSTANT_RANGE`, a gradient beyond
        :data:`~rkmpc.learning.understeer.UNDERSTEER_RANGE`, a delay beyond ``[0, MAX_DELAY]``, a
        rate limit beyond :data:`RATE_LIMIT_RANGE`, or an unknown status or signal.
    """

    servo_time_constant: float
    understeer_gradient: float
    servo_fit_r2: float
    understeer_fit_r2: float
    n_samples: int
    servo_structure: str = "lag"
    servo_delay: float = 0.0
    servo_rate_limit: float | None = None
    warnings: tuple[str, ...] = ()
    _: KW_ONLY
    status: str = "unchecked"
    status_reason: str = ""
    fitted_on: str | None = None
    folds: int = 0
    heldout_rmse: float = math.nan
    nominal_rmse: float = math.nan
    heldout_r2: float = math.nan
    wheel_heldout_rmse: float = math.nan
    wheel_nominal_rmse: float = math.nan
    heldout_candidates: tuple[tuple[str, float], ...] = ()
    tyres: IdentifiedTyres | None = None

    def __post_init__(self) -> None:
        _check_range("servo_time_constant", self.servo_time_constant, TIME_CONSTANT_RANGE, "s")
        _check_range("understeer_gradient", self.understeer_gradient, UNDERSTEER_RANGE, "s^2/m")
        for field in (
            "servo_fit_r2",
            "understeer_fit_r2",
            "heldout_rmse",
            "nominal_rmse",
            "heldout_r2",
            "wheel_heldout_rmse",
            "wheel_nominal_rmse",
        ):
            value = getattr(self, field)
            if value is None:  # JSON's null: not measured
                object.__setattr__(self, field, math.nan)
            elif not is_real(value):
                raise ParameterError(f"{_NAME}.{field} must be a number or None, got {value!r}")
        for field in ("n_samples", "folds"):
            if not is_integer(getattr(self, field), 0):
                raise ParameterError(f"{_NAME}.{field} must be an integer >= 0, got {getattr(self, field)!r}")
        require_choice(self, "servo_structure", SERVO_STRUCTURE_NAMES)
        _check_range("servo_delay", self.servo_delay, (0.0, MAX_DELAY), "s")
        if self.servo_rate_limit is not None:
            _check_range("servo_rate_limit", self.servo_rate_limit, RATE_LIMIT_RANGE, "rad/s")
        require_choice(self, "status", MODEL_STATUSES)
        require_choice(self, "fitted_on", (*FIT_SIGNALS, None))
        if not isinstance(self.warnings, (tuple, list)) or not all(isinstance(w, str) for w in self.warnings):
            raise ParameterError(f"{_NAME}.warnings must be a sequence of strings, got {self.warnings!r}")
        object.__setattr__(self, "warnings", tuple(self.warnings))
        if not isinstance(self.status_reason, str):
            raise ParameterError(f"{_NAME}.status_reason must be a string, got {self.status_reason!r}")
        object.__setattr__(
            self, "heldout_candidates", named_numbers(self.heldout_candidates, f"{_NAME}.heldout_candidates")
        )
        if isinstance(self.tyres, Mapping):  # read from JSON
            object.__setattr__(self, "tyres", IdentifiedTyres.from_json(self.tyres))
        if self.tyres is not None and not isinstance(self.tyres, IdentifiedTyres):
            raise ParameterError(f"{_NAME}.tyres must be IdentifiedTyres or None, got {self.tyres!r}")
        nominal = (self.servo_structure, self.servo_delay, self.servo_rate_limit, self.understeer_gradient)
        if self.status == "nominal" and nominal != ("nominal", 0.0, None, 0.0):
            raise ParameterError(
                f"{_NAME}.status is 'nominal' but the model is not the nominal one (servo structure, delay, "
                f"rate limit, understeer gradient {nominal!r}; the nominal model has "
                "('nominal', 0.0, None, 0.0))"
            )

    @property
    def every_warning(self) -> tuple[str, ...]:
        """The identification's warnings, the tyres' after the servo's and understeer's."""
        return (*self.warnings, *(self.tyres.warnings if self.tyres is not None else ()))

    @property
    def error_ratio(self) -> float:
        """Held-out yaw-rate RMSE of this model over the nominal model's (< 1: better); NaN if unmeasured."""
        if not (self.nominal_rmse > 0.0):
            return math.nan
        return self.heldout_rmse / self.nominal_rmse
