"""State estimation for a car that measures what a real one does: pose, wheel speed, gyro, no wheel angle.

* :mod:`~rkmpc.estimation.steering`: the wheel angle from the commands sent, through a servo model.
* :mod:`~rkmpc.estimation.filter`: an extended Kalman filter for the controllers' observation.
* :mod:`~rkmpc.estimation.smoother`: its Rauch-Tung-Striebel smoother over a recorded sequence and
  over a transition data set, for training labels.
"""

from rkmpc.estimation.config import EstimatorConfig
from rkmpc.estimation.diagnostics import EstimatorDiagnostics
from rkmpc.estimation.filter import StateEstimator
from rkmpc.estimation.steering import SteeringModel, WheelAnglePropagator, wheel_angles

__all__ = [
    "EstimatorConfig",
    "EstimatorDiagnostics",
    "StateEstimator",
    "SteeringModel",
    "WheelAnglePropagator",
    "wheel_angles",
]
