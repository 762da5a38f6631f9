"""A damper for the correction's limit cycle: the residual QP's steering-rate weight, raised once it rings.

The residual MPC of ``rkmpc`` reads the measured wheel angle through its learned model. On a car
whose servo rings (an under-damped second-order servo, the zoo's ``overshoot``), a model learned
from two smooth LMPC laps can close a loop through that feature which the data never excited: the
correction and the servo swing against each other at the servo's own frequency, on a straight as
much as in a corner. The trust guard does not see it (the model keeps predicting the swinging
features well) and a fixed steering-rate weight that stops it costs every healthy run accuracy.

:class:`OscillationDamper` watches, over the last ``window_steps`` control steps, the mean change
per step of the steering correction the car received, ``r_c = mean |dU_k - dU_{k-1}|``, and of the
LMPC's own steering command, ``r_b = mean |U_k - U_{k-1}|``. The correction oscillates when

``r_c > max(rate_ratio * r_b, rate_floor * max_rate * dt)``

(it moves faster than the baseline it corrects, and faster than a share of the servo's rate
limit, which a quantised servo's chatter stays under) on ``persist_steps`` steps in a row: a ring
keeps swinging for many seconds, while the bursts measured on healthy runs (a ring that dies by
itself, the correction through a late and jumpy localiser) lasted under three. From the next step
on, the residual QP
weighs the change of the steering correction from step to step with ``damping_weight`` more (the
term of ``ResidualMPCConfig.steer_rate_weight``): by default for the rest of the run, since a loop
that rang once rings again (released 5 s after it stopped, the ring came back 27 times in a lap;
a weight light enough to leave healthy runs alone from the first step does not stop a ring
already swinging: ``docs/method.md``); with ``hold_steps`` for that many steps after the last step
that found it. Steps damped and the times the damping switched on are counted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer, require_bool, require_nonnegative, require_positive

__all__ = ["OscillationConfig", "OscillationDamper"]

#: Steps held when ``hold_steps`` is 0: longer than any run (``rkmpc.sim.closed_loop.MAX_STEPS``).
_FOREVER = 10**12


@dataclass(frozen=True)
class OscillationConfig:
    """Settings of :class:`OscillationDamper`.

    Parameters
    ----------
    enabled : bool
        Whether the damper watches (off: it never acts).
    window_steps : int
        Control steps (>= 2) over which the two rates are averaged.
    rate_ratio : float
        How many times as fast as the LMPC's command (> 0) the correction may move.
    rate_floor : float
        Share (in (0, 1]) of the car's steering rate limit below which the correction's rate is
        never taken for an oscillation.
    damping_weight : float
        Steering-rate weight (>= 0, the unit of ``steer_rate_weight``) added while damping.
    persist_steps : int
        Consecutive steps (>= 1) the correction must oscillate before the damping switches on.
    hold_steps : int
        Steps (>= 0) damped after each step that found an oscillation; 0: until the controller
        is reset (the rest of the run).
    """

    enabled: bool = False
    window_steps: int = 20
    rate_ratio: float = 2.0
    rate_floor: float = 0.2
    damping_weight: float = 100.0
    persist_steps: int = 100
    hold_steps: int = 0

    def __post_init__(self) -> None:
        require_bool(self, "enabled")
        for name, low in (("window_steps", 2), ("persist_steps", 1), ("hold_steps", 0)):
            value = getattr(self, name)
            if not is_integer(value, low):
                raise ParameterError(f"OscillationConfig.{name} must be an integer >= {low}, got {value!r}")
        require_positive(self, "rate_ratio", "rate_floor")
        require_nonnegative(self, "damping_weight")
        if self.rate_floor > 1.0:
            raise ParameterError(f"OscillationConfig.rate_floor must be in (0, 1], got {self.rate_floor!r}")


class OscillationDamper:
    """Watches the steering correction and the baseline command; damps the correction while it oscillates.

    Parameters
    ----------
    config : OscillationConfig
        Thresholds and damping.
    max_rate : float
        The car's steering rate limit (rad/s).
    dt : float
        Control period (s).
    """

    def __init__(self, config: OscillationConfig, max_rate: float, dt: float) -> None:
        self.config = config
        self._floor = config.rate_floor * max_rate * dt
        self._changes = np.zeros((config.window_steps, 2))  # |change| of correction, of baseline
        self.reset()

    def reset(self) -> None:
        """Forget the history and the counts."""
        self._changes[:] = 0.0
        self._filled = 0
        self._next = 0
        self._last: tuple[float, float] | None = None
        self._hold = 0
        self._run = 0
        #: Steps on which the residual QP was damped.
        self.steps = 0
        #: Times the damping switched on (from off).
        self.onsets = 0

    @property
    def weight(self) -> float:
        """The steering-rate weight to add to the residual QP at this step (0 when not damping)."""
        return self.config.damping_weight if self._hold > 0 else 0.0

    def observe(self, baseline: float, correction: float) -> None:
        """Record the step just sent: the LMPC's steering command and the correction added (rad)."""
        if not self.config.enabled:
            return
        if self._hold > 0:
            self.steps += 1
            self._hold -= 1
        if self._last is not None:
            self._changes[self._next] = (abs(correction - self._last[1]), abs(baseline - self._last[0]))
            self._next = (self._next + 1) % len(self._changes)
            self._filled = min(self._filled + 1, len(self._changes))
        self._last = (baseline, correction)
        if self._filled < len(self._changes):
            return
        moved, base = self._changes.mean(axis=0)
        self._run = self._run + 1 if moved > max(self.config.rate_ratio * base, self._floor) else 0
        if self._run >= self.config.persist_steps:
            if self._hold == 0:
                self.onsets += 1
            self._hold = self.config.hold_steps or _FOREVER
