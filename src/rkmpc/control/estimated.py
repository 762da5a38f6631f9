"""Any controller driven from estimated states: the raw measurements go through a state estimator first.

:class:`EstimatedController` wraps a controller and a
:class:`~rkmpc.estimation.filter.StateEstimator`. Each step turns the raw observation (a pose from
the localiser, a wheel speed, a gyro rate, no wheel angle) into the estimate, steps the inner
controller with it and tells the estimator, at the next step, the command that was sent. It is a
:class:`~rkmpc.control.base.Controller` like any other: it never raises and never answers a
non-finite command, and its fall-backs are the inner controller's (which checks the estimate as it
would check a measurement).
"""

from __future__ import annotations

import logging
import math

from rkmpc.control.base import Controller
from rkmpc.core.errors import ParameterError, raise_if_interrupted
from rkmpc.core.observation import Command, Observation
from rkmpc.estimation.filter import StateEstimator

__all__ = ["EstimatedController"]

_LOG = logging.getLogger(__name__)


class EstimatedController(Controller):
    """``controller`` stepped with the estimates of ``estimator`` instead of the raw observations.

    Parameters
    ----------
    controller : Controller
        The inner controller; it checks the estimate (required fields, its admissible errors).
    estimator : StateEstimator
        Its ``config.control_period`` must be the controller's period (the wheel-angle model
        steps with it).

    Raises
    ------
    ParameterError
        When the periods differ.

    Attributes
    ----------
    estimate : Observation or None
        The estimate of the last step (None before the first).
    """

    def __init__(self, controller: Controller, estimator: StateEstimator) -> None:
        period = estimator.config.control_period
        if controller.dt is not None and not math.isclose(controller.dt, period, rel_tol=1e-9):
            raise ParameterError(
                f"EstimatedController: {controller.name!r} plans with a period of {controller.dt!r} s, "
                f"the estimator's control_period is {period!r} s"
            )
        super().__init__()
        self.inner = controller
        self.estimator = estimator
        self.name = controller.name
        self.dt = controller.dt
        self.estimate: Observation | None = None

    def _reset(self) -> None:
        self.inner.reset()
        self.estimator.reset()
        self.estimate = None

    def _refusal(self, observation: Observation) -> tuple[str, str] | None:
        # The raw observation may lack anything (a pose not yet there, a speed the car does not
        # measure): the estimator takes what is finite, the inner controller checks the estimate.
        return None

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        try:
            estimate = self.estimator.update(observation, self._last_command)
        except Exception as exc:  # the estimator's failure must not end the run: start it afresh
            raise_if_interrupted(exc)
            _LOG.debug("%s: the estimator raised; reset", self.name, exc_info=True)
            self.estimator.reset()
            raise
        self.estimate = estimate
        command = self.inner.step(estimate)
        info = self.inner.info
        return command, info.status, info.message

    def diagnostics(self) -> dict[str, float]:
        """The inner controller's diagnostics and the estimator's counts (``estimator_*``)."""
        return {**self.inner.diagnostics(), **self.estimator.diagnostics().as_dict()}
