"""Speed moves the car along the track, steering across it: the residual QP on a retimed reference.

The LMPC predicts deviations from a *time-indexed* reference: point ``k`` of the horizon is where
the speed profile puts the car ``k T`` seconds from now (:meth:`rkmpc.track.reference.Reference.horizon`).
Its model assumes the car drives the speeds it plans, so its prediction stays on that schedule.
The learned model of ``rkmpc`` knows better: a car whose speed loop cannot follow the profile out
of a hairpin drives the effective speeds ``U_p`` below the plan. Linearised along the time-indexed
reference, a speed deficit turns the car less per second than the reference turns, and the
prediction reads it as a lateral deviation toward the outside of the corner (half a metre over a
1.5 s horizon on a 1:10 car leaving a hairpin at 2 m/s against a profile of 3 m/s). The residual
QP then adds steering toward the inside, although the car, re-projected onto the path at every
step, is only late, not off the line; it cuts the corner.

:class:`ProgressSplit` keeps the two apart:

* the horizon is retimed: point ``k`` is the path point at the distance the car covers at the
  learned model's predicted speeds of the LMPC's plan, ``s_k = s_0 + T sum_{j<k} max(U_p,v,j, 0)``
  (:meth:`~rkmpc.track.reference.Reference.along`), and the kinematic model is linearised along it
  at those speeds; there a speed change moves the car along the track only (the speed columns of
  ``Gamma`` are zero), the steering across it;
* the cost's position error per step is split, in the frame of the retimed point, into the
  lateral deviation (from the retimed prediction) and the along-track lag against the speed
  profile's schedule, ``T sum_{j<=k} (U_p,v,j - v_r,j)``, linear in the speed correction: the
  lag still asks for the speed the profile wants, but can no longer be paid for with steering.

The weights stay those of the position (both parts) and heading; with the car on schedule
(``U_p,v = v_r``) the split is a rotation of the same position error.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from rkmpc.control.linear.problem import KinematicMPCProblem, Prediction
    from rkmpc.track.reference import Reference

__all__ = ["ProgressSplit", "linearisation"]


def linearisation(
    pred: Prediction, effective: np.ndarray, split: ProgressSplit | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``Phi, Gamma``, headings of points 1..N and reference inputs the residual QP predicts along.

    The LMPC's own time-indexed linearisation when ``split`` is None, else ``split``'s retimed one
    (:meth:`ProgressSplit.linearise`, whose arguments and returns these are).
    """
    if split is None:
        n = len(pred.u_ref)
        return pred.Phi, pred.Gamma, pred.reference.theta[1 : n + 1], pred.u_ref.ravel()
    return split.linearise(pred, effective)


class ProgressSplit:
    """The residual QP's linearisation and cost rows on a reference retimed to the predicted speeds.

    Parameters
    ----------
    reference : Reference
        The path and speed profile the LMPC tracks.
    problem : KinematicMPCProblem
        The LMPC's condensed kinematic problem (its horizon ``N`` and period ``T``).
    """

    def __init__(self, reference: Reference, problem: KinematicMPCProblem) -> None:
        self.reference = reference
        self.problem = problem
        n = problem.n
        self.horizon = n
        self.dt = problem.config.dt
        # Row k sums the steps 0..k: the distance (over T) after input k.
        self._cumulative = np.tril(np.ones((n, n))) * self.dt

    def linearise(
        self, pred: Prediction, effective: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The kinematic model linearised along the reference retimed to ``effective``'s speeds.

        Parameters
        ----------
        pred : Prediction
            The LMPC's prediction of this step (its reference horizon starts at the car).
        effective : numpy.ndarray
            The learned model's effective inputs ``U_p`` of the LMPC's plan, ``[v, delta]`` per
            step (m/s, rad), shape (2N,).

        Returns
        -------
        Phi, Gamma : numpy.ndarray
            Condensed prediction along the retimed reference, shapes (3N, 3) and (3N, 2N); the
            speed columns of ``Gamma`` are zero.
        theta : numpy.ndarray
            Headings (rad) of the retimed points 1..N, shape (N,).
        u_ref : numpy.ndarray
            The inputs of the retimed reference, ``[v, delta]`` per step, shape (2N,).
        """
        n = self.horizon
        speeds = np.maximum(effective[0::2], 0.0)
        ref = self.reference.along(float(pred.reference.s[0]), np.cumsum(speeds * self.dt))
        Phi, Gamma = self.problem.prediction_matrices(ref.theta[:n], speeds, ref.delta[:n])
        Gamma.reshape(n, 3, 2 * n)[:, :, 0::2] = 0.0
        u_ref = np.empty(2 * n)
        u_ref[0::2] = speeds
        u_ref[1::2] = ref.delta[:n]
        return Phi, Gamma, ref.theta[1 : n + 1], u_ref

    def rows(
        self,
        pred: Prediction,
        effective: np.ndarray,
        sensitivity: np.ndarray,
        e0: np.ndarray,
        GM: np.ndarray,
        theta: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The cost's deviations ``E + M dU``, per step ``[along-track lag, lateral, heading]``.

        Parameters
        ----------
        pred : Prediction
            The LMPC's prediction (its reference speeds are the schedule).
        effective : numpy.ndarray
            ``U_p`` of the LMPC's plan, shape (2N,).
        sensitivity : numpy.ndarray
            ``dU_p / dU`` over the horizon, shape (2N, 2N).
        e0, GM : numpy.ndarray
            Deviations ``[x, y, theta]`` from the retimed reference and their sensitivity to the
            correction, shapes (3N,) and (3N, 2N).
        theta : numpy.ndarray
            Headings of the retimed points 1..N, shape (N,).

        Returns
        -------
        E, M : numpy.ndarray
            Shapes (3N,) and (3N, 2N): the lag (m, positive ahead of the schedule), the lateral
            deviation (m, positive to the left) and the heading deviation (rad) of each step.
        """
        n = self.horizon
        c, s = np.cos(theta), np.sin(theta)
        E = np.empty(3 * n)
        M = np.empty((3 * n, 2 * n))
        E[0::3] = self._cumulative @ (effective[0::2] - pred.u_ref[:, 0])
        M[0::3] = self._cumulative @ sensitivity[0::2]
        E[1::3] = c * e0[1::3] - s * e0[0::3]
        M[1::3] = c[:, None] * GM[1::3] - s[:, None] * GM[0::3]
        E[2::3] = e0[2::3]
        M[2::3] = GM[2::3]
        return E, M
