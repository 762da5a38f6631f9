"""Settings of the residual MPC (paper Eq. MPC2): what ``rkmpc-paper`` and ``rkmpc`` share, and rkmpc's own.

:class:`ResidualMPCConfig` holds what both residual MPCs read (weights, bounds, solver);
:class:`RKMPCConfig` adds what only ``rkmpc`` reads (the speed-priced steering, the slip drift,
the trust guard, online adaptation). ``rkmpc-paper`` takes a :class:`ResidualMPCConfig` and refuses
an :class:`RKMPCConfig`, so a setting it cannot use is refused where it is given, never ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Self

from rkmpc.control.learned.adaptation import AdaptationConfig
from rkmpc.control.learned.lateral_guard import LateralGuardConfig
from rkmpc.control.learned.oscillation import OscillationConfig
from rkmpc.control.learned.trust import TrustConfig
from rkmpc.control.tracking import check_weights
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_positive_number, require_bool, require_positive_value

__all__ = ["PAPER_RESIDUAL", "RKMPCConfig", "ResidualMPCConfig"]


@dataclass(frozen=True)
class ResidualMPCConfig:
    """Weights and bounds of the residual MPC (paper Eq. MPC2).

    Parameters
    ----------
    position_weight, heading_weight : float
        Tracking weights of the predicted position and heading errors.
    speed_weight : float
        mu: weight of the squared speed correction ``dv^2``.
    steer_weight : float
        epsilon: weight of the squared steering correction ``ddelta^2``.
    max_speed_correction : float
        Bound on ``|dv|`` (m/s).
    max_steer_correction : float
        Bound on ``|ddelta|`` (rad).
    solver : str
        QP backend.
    max_iterations : int
        QP iteration budget; on failure the LMPC's command is applied alone.
    steer_rate_weight : float
        Weight of the squared change of the steering correction from one step to the next
        (the first against the correction applied last), so the correction does not make the
        commanded wheel angle move faster than the LMPC's; 0 for none.
    """

    position_weight: float = 1.0
    heading_weight: float = 1.0
    speed_weight: float = 0.5
    steer_weight: float = 2.0
    max_speed_correction: float = 1.0
    max_steer_correction: float = 0.15
    solver: str = "daqp"
    max_iterations: int = 200
    steer_rate_weight: float = 0.0

    def __post_init__(self) -> None:
        check_weights(
            self, "position_weight", "heading_weight", "speed_weight", "steer_weight", "steer_rate_weight"
        )
        if self.speed_weight <= 0 or self.steer_weight <= 0:
            raise ParameterError("ResidualMPCConfig: speed_weight and steer_weight must be > 0")
        if not (self.max_speed_correction > 0 and self.max_steer_correction > 0):
            raise ParameterError("ResidualMPCConfig: correction bounds must be > 0")

    def scaled(self, length: float, speed: float) -> Self:
        """These settings carried over to a car ``length`` times as long that drives ``speed`` times as fast.

        The cost keeps its balance when every term grows like the squared position error
        (``length**2``): wheel angles on a track of the car's size are alike, so the weight of the
        steering correction grows with ``length**2``; speed errors grow with ``speed``, so the weight
        of the speed correction grows with ``(length / speed)**2``. The speed correction's bound grows
        with ``speed``; the steering bound stays (wheel angles are alike). Position and heading
        weights, solver and iteration budget stay.

        Parameters
        ----------
        length : float
            Ratio (-) of the new car's wheelbase to the one these settings were tuned for, > 0.
        speed : float
            Ratio (-) of the new car's top speed of the speed profile to the old one's, > 0.

        Returns
        -------
        ResidualMPCConfig
            Of the same class; ``self`` itself when both ratios are 1.
        """
        k = require_positive_value(length, "length")
        v = require_positive_value(speed, "speed")
        if k == 1.0 and v == 1.0:
            return self
        changes: dict[str, Any] = {
            "speed_weight": self.speed_weight * (k / v) ** 2,
            "steer_weight": self.steer_weight * k**2,
            "max_speed_correction": self.max_speed_correction * v,
            **self._scaled_own(k, v),
        }
        return replace(self, **changes)

    def _scaled_own(self, length: float, speed: float) -> dict[str, float]:
        """Fields a subclass adds, carried over by :meth:`scaled` (none here)."""
        return {}


@dataclass(frozen=True)
class RKMPCConfig(ResidualMPCConfig):
    """The residual MPC of ``rkmpc``: :class:`ResidualMPCConfig` and what only ``rkmpc`` reads.

    Parameters
    ----------
    lateral_accel_weight : float
        Weight (s^4/m^2) of the squared lateral acceleration a steering correction adds at the
        speed the LMPC plans for that step, ``(v_k**2 / L * ddelta_k)**2`` (0 for
        none). A wheel-angle change moves the car by ``v**2 / L`` times as much at speed ``v``,
        so a fixed ``steer_weight`` that lets the correction act in slow corners lets it
        oscillate on fast straights; this term makes the correction's price grow with ``v**4``.
    slip_drift : bool
        Whether the residual MPC's prediction carries the sideways drift of the measured slip
        angle. The kinematic model moves along its heading whatever its input,
        so neither the LMPC's prediction nor the learned ``U_p`` sees a car that slides: with
        slip angle ``beta`` (rad, velocity direction minus heading) held over the horizon, the
        predicted position moves by ``v_r T beta`` per step across the reference heading. A
        step whose slip angle is not measured (NaN) goes without it, and is counted.
    slip_velocity_limit : float
        Sideways slip velocity ``v_x tan(beta)`` (m/s, > 0; infinite: never) at which the drift is
        gone: held whole up to half of it, then weighted down linearly to nothing at it. A car
        sliding sideways that fast is at the tyres' limit, the start of a spin that steering
        cannot correct, and a drift held there makes the correction steer harder into the
        corner (``docs/pace.md``). The drift moves the prediction by ``v T beta`` a step, so this
        is its own speed; a slow car in a hairpin, whose slip angle is large because its
        geometry makes it so, keeps its drift.
    trust : TrustConfig
        Out-of-distribution guard: how the correction fades toward the LMPC's command when the
        state leaves the model's training range or its predictions go wrong
        (:mod:`rkmpc.control.learned.trust`).
    adaptation : AdaptationConfig
        Online recursive least squares on the output map of the model
        (:mod:`rkmpc.control.learned.adaptation`); off by default.
    lateral_guard : LateralGuardConfig
        The constraint that keeps the corrected plan's predicted lateral deviations within the
        uncorrected plan's largest (:mod:`rkmpc.control.learned.lateral_guard`); off by default.
    oscillation : OscillationConfig
        The damper that raises the steering-rate weight while the correction oscillates
        (:mod:`rkmpc.control.learned.oscillation`); off by default.
    retimed : bool
        Whether the residual QP predicts along the reference retimed to the learned model's
        predicted speeds, with speed acting along the track only and the position error split
        into the lateral deviation and the lag behind the speed profile's schedule
        (:mod:`rkmpc.control.learned.progress`); off: the LMPC's time-indexed linearisation.
    """

    lateral_accel_weight: float = 0.0
    slip_drift: bool = False
    slip_velocity_limit: float = math.inf
    trust: TrustConfig = field(default_factory=TrustConfig)
    adaptation: AdaptationConfig = field(default_factory=AdaptationConfig)
    lateral_guard: LateralGuardConfig = field(default_factory=LateralGuardConfig)
    oscillation: OscillationConfig = field(default_factory=OscillationConfig)
    retimed: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.lateral_guard, LateralGuardConfig):
            raise ParameterError("RKMPCConfig.lateral_guard must be a LateralGuardConfig")
        if not isinstance(self.oscillation, OscillationConfig):
            raise ParameterError("RKMPCConfig.oscillation must be an OscillationConfig")
        check_weights(self, "lateral_accel_weight")
        require_bool(self, "slip_drift", "retimed")
        limit = self.slip_velocity_limit
        if not (limit == math.inf or is_positive_number(limit)):
            raise ParameterError(
                f"RKMPCConfig.slip_velocity_limit must be a positive speed in m/s (inf: never), got {limit!r}"
            )
        if not isinstance(self.trust, TrustConfig) or not isinstance(self.adaptation, AdaptationConfig):
            raise ParameterError("RKMPCConfig.trust and .adaptation must be TrustConfig and AdaptationConfig")

    def slip_drift_weight(self, beta: float, speed: float) -> float:
        """The share of slip angle ``beta`` (rad) the drift holds at ``speed`` (m/s, along the
        heading): 1 while the sideways slip velocity ``|speed tan(beta)|`` is at most half of
        :attr:`slip_velocity_limit`, then down linearly to 0 at it (1 when it is infinite)."""
        if self.slip_velocity_limit == math.inf:
            return 1.0
        sideways = abs(speed * math.tan(beta))
        return min(1.0, max(0.0, 2.0 - 2.0 * sideways / self.slip_velocity_limit))

    def _scaled_own(self, length: float, speed: float) -> dict[str, float]:
        # The lateral acceleration a steering correction adds grows with speed**2 / length.
        return {"lateral_accel_weight": self.lateral_accel_weight * (length / speed) ** 4}


#: The residual MPC of ``rkmpc-paper`` on the 1:10 car: the literal model mispredicts the pose, so
#: only heavily weighted corrections keep it on track.
PAPER_RESIDUAL = ResidualMPCConfig(heading_weight=5.0, speed_weight=5.0, steer_weight=5000.0)
