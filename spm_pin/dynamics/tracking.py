"""How well the servos follow a stream of goals: :func:`track_goals`.

The goals are what a sync loop sends to the servos, one per period, each held until
the next (a zero-order hold, as on the bus). The closed-loop dynamics with the
servos' model (:class:`~spm_pin.dynamics.ServoController`: PD position loop and
torque-speed envelope) are simulated through them, and the tracking error is the
distance of the input angles from the goal in force at each sample.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..model.robot import SPMRobot
from ._checks import positive
from ._constants import FloatArray
from .closed_loop import ClosedLoopDynamics
from .servo import XM540_W150, ServoModel
from .simulator import Simulator
from .trajectory import ServoController

__all__ = ["TrackingResult", "track_goals"]


@dataclasses.dataclass(frozen=True)
class TrackingResult:
    """A simulated response to a stream of goals.

    Attributes:
        time: Sample times [s], (n,): the end of each period, then of the settling.
        goal: The goal in force over the period that ends at each sample [rad], (n, 3).
        theta: Input angles at the samples [rad], (n, 3).
        theta_dot: Input speeds at the samples [rad/s], (n, 3).
        error: Largest |theta_i - goal_i| at each sample [rad], (n,).
        max_error: Largest error while the goals stream [rad] (the lag).
        final_error: Error at the end of the settling [rad].
        rms_error: Root mean square of the error while the goals stream [rad].
    """

    time: FloatArray
    goal: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    error: FloatArray
    max_error: float
    final_error: float
    rms_error: float


def track_goals(
    goals: npt.ArrayLike,
    period: float,
    *,
    start: npt.ArrayLike | None = None,
    dynamics: ClosedLoopDynamics | SPMRobot | None = None,
    servo: ServoModel = XM540_W150,
    dt: float = 1e-3,
    integrator: str = "rk4",
    settle: float = 0.5,
) -> TrackingResult:
    """Simulate the servos following ``goals`` (n, 3) [rad], one per ``period`` [s].

    Args:
        goals: The goals sent, in order [rad], (n, 3).
        period: Time between goals [s]; a whole number of time steps ``dt``.
        start: Where the robot is at rest at first [rad] (default: the first goal).
        dynamics: The closed-loop dynamics (default: the prototype's, upright).
        servo: The servos' model.
        dt: Simulation step [s].
        integrator: ``"rk4"`` or ``"euler"``.
        settle: Time after the last goal, holding it [s] (>= 0).

    Returns:
        The response, sampled at the end of every period.

    Raises:
        InputError: malformed goals, a period that is not a whole number of steps,
            a bad servo or settling time.
        SingularityError: the motion reached a parallel singularity.
    """
    try:
        array = np.array(goals, dtype=float)
    except (TypeError, ValueError):
        array = np.empty(0)
    if array.ndim != 2 or array.shape[1:] != (3,) or array.shape[0] < 1:
        raise InputError(
            f"goals must have shape (n, 3) [rad], got {np.shape(goals)!r}", argument="goals"
        )
    if not np.all(np.isfinite(array)):
        raise InputError("goals must be finite [rad]", argument="goals")
    step = positive(dt, "dt", "[s]")
    length = positive(period, "period", "[s]")
    per = round(length / step)
    if per < 1 or not math.isclose(per * step, length, rel_tol=1e-9):
        raise InputError(
            f"period ({period} s) must be a whole number of time steps dt ({dt} s)",
            argument="period",
            value=period,
        )
    if not isinstance(servo, ServoModel):
        raise InputError(f"servo must be a ServoModel, got {servo!r}", argument="servo")
    hold = positive(settle, "settle", "[s]", allow_zero=True)
    sim = Simulator(
        dynamics,
        dt=step,
        integrator=integrator,
        state=array[0] if start is None else start,
    )
    extra = math.ceil(hold / length - 1e-9)
    schedule = np.vstack([array, np.repeat(array[-1:], extra, axis=0)])
    n = schedule.shape[0]
    theta = np.empty((n, 3))
    speed = np.empty((n, 3))
    for k, goal in enumerate(schedule):
        controller = ServoController(servo, goal)
        for _ in range(per):
            sim.step(controller(sim.time, sim.theta, sim.theta_dot))
        theta[k] = sim.theta
        speed[k] = sim.theta_dot
    error = np.max(np.abs(theta - schedule), axis=1)
    streaming = error[: array.shape[0]]
    return TrackingResult(
        time=np.arange(1, n + 1) * length,
        goal=schedule,
        theta=theta,
        theta_dot=speed,
        error=error,
        max_error=float(streaming.max()),
        final_error=float(error[-1]),
        rms_error=float(np.sqrt(np.mean(streaming**2))),
    )
