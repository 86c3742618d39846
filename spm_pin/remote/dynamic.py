"""The simulated twin: the closed-loop dynamics running in real time (``spm serve
--sim dynamic``).

:class:`DynamicBackend` steps a :class:`~spm_pin.dynamics.Simulator` (the closed loop
with projection, ``dt`` = 1 ms by default) so that its clock keeps up with the wall
clock, with the three servos modelled by
:class:`~spm_pin.dynamics.ServoController` (the XM540-W150's PD position loop and
torque-speed envelope by default). Every ``period`` the loop gives the servos the
next goal of the path (see :mod:`spm_pin.remote._motion`): the twin takes the time a
real robot would, lags behind its goals as the servos would, and answers its
present input angles, speeds and goal.

A stop holds the twin where it is (the servos' goal becomes their present position).
A failed step (a parallel singularity, loops that cannot close) ends the motion: the
twin keeps its last state, reports the fault in its state and takes no more goals.
"""

from __future__ import annotations

import math
import time

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..dynamics import ClosedLoopDynamics, ServoController, ServoModel, Simulator
from ..dynamics.servo import XM540_W150
from ..errors import InputError
from ..hardware.config import SafetyLimits
from ..model.robot import SPMRobot
from ._motion import MotionTwin
from .backend import _theta

__all__ = ["DEFAULT_PERIOD", "MAX_STEPS_PER_CYCLE", "DynamicBackend"]

FloatArray = npt.NDArray[np.float64]

#: Seconds between goals given to the simulated servos (100 Hz, as the servo loop).
DEFAULT_PERIOD = 0.01
#: Most simulation steps taken in one loop cycle (whole periods): a loop that falls
#: further behind the wall clock lets simulated time run slower instead of catching up.
MAX_STEPS_PER_CYCLE = 100


class DynamicBackend(MotionTwin):
    """The closed-loop simulator as a twin, in real time (see the module).

    Args:
        design: The SPM (default: the prototype); ignored when ``robot`` or
            ``dynamics`` is given.
        robot: The robot with its collision checker (default
            ``spm.build_robot(design)``).
        limits: The guard's limits.
        theta: The starting input angles [rad] (default home); must be safe.
        dynamics: The closed-loop dynamics to simulate (gravity, friction, armature;
            default ``ClosedLoopDynamics(robot)``).
        servo: The servos' model (default the XM540-W150).
        dt: Simulation time step [s].
        integrator: ``"rk4"`` (default) or ``"euler"``.
        period: Seconds between goals given to the servos.
        distance_interval: See :class:`~spm_pin.remote._motion.MotionTwin`.

    Attributes:
        name: ``"dynamic"``.
        simulator: The simulator (read it only through the twin's methods while the
            twin runs).
        servo: The servos' model.
        slow_cycles: Cycles where the simulation could not keep up with the wall
            clock (simulated time then runs slower).

    Use it as a context manager, or call :meth:`close`, to end its thread.
    """

    name = "dynamic"

    def __init__(
        self,
        design: SPMDesign | None = None,
        *,
        robot: SPMRobot | None = None,
        limits: SafetyLimits | None = None,
        theta: npt.ArrayLike | None = None,
        dynamics: ClosedLoopDynamics | None = None,
        servo: ServoModel = XM540_W150,
        dt: float = 1e-3,
        integrator: str = "rk4",
        period: float = DEFAULT_PERIOD,
        distance_interval: float = 0.1,
    ) -> None:
        if robot is None and dynamics is not None:
            robot = dynamics.robot
        super().__init__(
            design,
            robot=robot,
            limits=limits,
            period=period,
            distance_interval=distance_interval,
        )
        if not isinstance(servo, ServoModel):
            raise InputError(
                f"servo must be a ServoModel, got {type(servo).__name__}",
                argument="servo",
                value=servo,
            )
        start: FloatArray = np.zeros(3) if theta is None else _theta(theta)
        self._report(start).require()
        self.servo = servo
        self.simulator = Simulator(
            dynamics if dynamics is not None else self.robot,
            dt=dt,
            integrator=integrator,
            state=start,
        )
        self._steps_per_period = round(self.period / self.simulator.dt)
        if self._steps_per_period < 1 or not math.isclose(
            self._steps_per_period * self.simulator.dt, self.period, rel_tol=1e-9
        ):
            raise InputError(
                f"period ({period} s) must be a whole number of time steps dt ({dt} s)",
                argument="period",
                value=period,
            )
        self.slow_cycles = 0
        self._controller = ServoController(servo, start)
        self._controller_goal = start.copy()
        self._epoch: float | None = None  # wall time of simulated time 0
        self._theta = self.simulator.theta
        self._goal = start.copy()
        self._start_loop()

    def _cycle(self) -> None:
        """Advance the simulation to the wall clock, one goal per simulated period.

        The goals of a path are given to the servos by simulated time, not by loop
        cycles: a loop that runs late and catches up still hands each goal to the
        servos for one whole period of simulated time (handing them over per cycle
        would run the goals ahead of the robot, and the servos would race after them).
        """
        sim = self.simulator
        now = time.perf_counter()
        if self._epoch is None:
            self._epoch = now - sim.time
        periods = math.floor((now - self._epoch - sim.time) / self.period + 1e-9)
        limit = max(1, MAX_STEPS_PER_CYCLE // self._steps_per_period)
        if periods > limit:  # too far behind: simulated time runs slower instead
            self.slow_cycles += 1
            self._epoch += (periods - limit) * self.period
            periods = limit
        for _ in range(max(periods, 0)):
            with self._motion:
                if self._path:
                    self._goal = self._path.popleft()
                goal = self._goal
            theta, theta_dot = self._advance(goal)
            with self._motion:
                self._theta, self._theta_dot = theta, theta_dot

    def _advance(self, goal: FloatArray) -> tuple[FloatArray, FloatArray]:
        """One period of simulated time with the servos holding ``goal``."""
        sim = self.simulator
        if not np.array_equal(goal, self._controller_goal):
            self._controller = ServoController(self.servo, goal)
            self._controller_goal = goal.copy()
        controller = self._controller
        for _ in range(self._steps_per_period):
            sim.step(controller(sim.time, sim.theta, sim.theta_dot))
        return sim.theta, sim.theta_dot
