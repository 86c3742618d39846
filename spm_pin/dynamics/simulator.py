"""Time stepping of the closed loop: :class:`Simulator` and its :class:`SimulationResult`.

A simulator holds its state in a :class:`~spm_pin.dynamics._kernel.SimState` and
advances it with the bound closures of a :class:`~spm_pin.dynamics._kernel.Kernel`
(see :mod:`spm_pin.dynamics` for the integrators and the projection). A run samples
the motion every ``record_every`` steps.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from .._checks import check_count
from ..errors import InputError
from ..model.robot import SPMRobot
from ._checks import positive, vector
from ._constants import DEFAULT_DT, INTEGRATORS, SINGULAR_RCOND, FloatArray
from ._kernel import Kernel, SimState, singular
from .closed_loop import ClosedLoopDynamics, _dynamics
from .servo import XM540_W150, ServoCheck, ServoModel, check_servo

__all__ = ["Controller", "SimulationResult", "Simulator"]


@dataclasses.dataclass(frozen=True)
class SimulationResult:
    """A simulated motion, sampled every ``record_every`` steps.

    Attributes:
        time: Sample times [s], (N,).
        theta: Input angles [rad], (N, 3).
        theta_dot: Input speeds [rad/s], (N, 3).
        theta_ddot: Input accelerations [rad/s^2] at the samples, (N, 3).
        torque: Actuator torques applied from each sample on [N m], (N, 3).
        q: Joint configurations, (N, 9).
        kinetic: Kinetic energy [J], (N,) (armature included).
        potential: Potential energy [J], (N,).
        actuator_work: Work done by the actuators since the start [J], (N,).
        friction_loss: Energy dissipated by joint friction since the start [J], (N,).
        closure_residual: Closure residual at each sample [rad], (N,).
        max_closure_residual: Largest closure residual over every step [rad].
        steps: Number of time steps.
        dt: Time step [s].
        integrator: Integrator name.
    """

    time: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray
    torque: FloatArray
    q: FloatArray
    kinetic: FloatArray
    potential: FloatArray
    actuator_work: FloatArray
    friction_loss: FloatArray
    closure_residual: FloatArray
    max_closure_residual: float
    steps: int
    dt: float
    integrator: str

    @property
    def energy(self) -> FloatArray:
        """Mechanical energy kinetic + potential [J], (N,)."""
        result: FloatArray = self.kinetic + self.potential
        return result

    @property
    def energy_error(self) -> FloatArray:
        """Energy balance error E - E_0 - W_actuators + D_friction [J], (N,): zero for an
        exact integration."""
        result: FloatArray = self.energy - self.energy[0] - self.actuator_work + self.friction_loss
        return result

    def check_servo(self, servo: ServoModel = XM540_W150) -> ServoCheck:
        """The recorded torques and speeds against a servo's envelope."""
        return check_servo(self.torque, self.theta_dot, servo, time=self.time)


#: A controller: ``controller(t, theta, theta_dot)`` -> actuator torques [N m], (3,).
Controller = Callable[[float, FloatArray, FloatArray], Any]


class Simulator:
    """Time stepping of the closed loop with projection (see :mod:`spm_pin.dynamics`).

    The state is (q, theta_dot) with q closed; each step integrates, projects the
    passive joints back onto the loops (Newton, theta held) and rebuilds the joint
    velocities from theta_dot, so both the positions and the velocities satisfy the
    closures after every step.

    Args:
        dynamics: A :class:`ClosedLoopDynamics` (gravity, friction, armature), or an
            SPMRobot / None for the defaults.
        dt: Time step [s] (default 1 ms).
        integrator: ``"rk4"`` (default, accurate) or ``"euler"`` (semi-implicit, fast).
        state: Initial theta (3,) [rad] or closed q (9,) (default home).
        theta_dot: Initial input speeds [rad/s] (default 0).

    Raises:
        InputError: non-positive or non-finite dt, unknown integrator, bad state.

    Example:
        >>> import spm_pin as spm
        >>> sim = spm.Simulator(dt=1e-3, state=[0.1, 0.0, 0.0])
        >>> result = sim.run(0.05)
        >>> bool(result.max_closure_residual <= spm.dynamics.DRIFT_TOL)
        True
    """

    def __init__(
        self,
        dynamics: ClosedLoopDynamics | SPMRobot | None = None,
        *,
        dt: float = DEFAULT_DT,
        integrator: str = "rk4",
        state: npt.ArrayLike | None = None,
        theta_dot: npt.ArrayLike | None = None,
    ) -> None:
        self.dynamics = _dynamics(dynamics)
        self.dt = positive(dt, "dt", "[s]")
        if integrator not in INTEGRATORS:
            raise InputError(
                f"integrator must be one of {list(INTEGRATORS)}, got {integrator!r}",
                argument="integrator",
                value=integrator,
            )
        self.integrator = integrator
        self._state = SimState(
            q=np.zeros(self.dynamics.model.nq),
            theta_dot=np.zeros(3),
            S=np.zeros((0, 0)),
            time=0.0,
            steps=0,
            work=0.0,
            loss=0.0,
            r2=0.0,
            max_r2=0.0,
            rcond=1.0,
        )
        self._kernel = Kernel(self.dynamics, self.dt, self.integrator, self._state)
        self.reset(state, theta_dot)

    def __repr__(self) -> str:
        return (
            f"Simulator(dt={self.dt:g}, integrator={self.integrator!r}, t={self._state.time:.6g}, "
            f"theta={self.theta.round(6).tolist()})"
        )

    # ------------------------------------------------------------------ state
    def reset(
        self,
        state: npt.ArrayLike | None = None,
        theta_dot: npt.ArrayLike | None = None,
        *,
        time: float = 0.0,
    ) -> None:
        """Put the robot at a state and clear the counters.

        Args:
            state: theta (3,) [rad] (home assembly mode) or a closed q (9,) (default
                home).
            theta_dot: Input speeds [rad/s] (default 0).
            time: Clock [s].

        Raises:
            InputError: bad state, speeds or time.
            SingularityError: the state is a parallel (type II) singularity.
        """
        q = self.dynamics.configuration(np.zeros(3) if state is None else state)
        rate = np.zeros(3) if theta_dot is None else vector(theta_dot, 3, "theta_dot", "[rad/s]")
        if isinstance(time, bool) or not isinstance(time, (int, float, np.integer, np.floating)):
            raise InputError(f"time must be a number [s], got {time!r}", argument="time")
        clock = float(time)
        if not math.isfinite(clock):
            raise InputError(f"time must be finite [s], got {time!r}", argument="time")
        kernel, current = self._kernel, self._state
        J, r2, _, _ = kernel.project(q)
        rcond = kernel.lu.rcond()
        if rcond < SINGULAR_RCOND:
            singular(current, q, rcond, self.dynamics.actuated_idx)
        current.rcond = rcond
        current.q = q
        current.theta_dot = rate
        current.S = kernel.tangent(J)
        current.time = clock
        current.steps = 0
        current.work = 0.0
        current.loss = 0.0
        current.r2 = r2
        current.max_r2 = r2
        kernel.forget()

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return self._state.time

    @property
    def q(self) -> FloatArray:
        """Closed joint configuration (9,) (a copy)."""
        result: FloatArray = self._state.q.copy()
        return result

    @property
    def theta(self) -> FloatArray:
        """Input angles [rad] (3,)."""
        result: FloatArray = self._state.q.take(self.dynamics.actuated_idx)
        return result

    @property
    def theta_dot(self) -> FloatArray:
        """Input speeds [rad/s] (3,)."""
        result: FloatArray = self._state.theta_dot.copy()
        return result

    @property
    def v(self) -> FloatArray:
        """Joint velocities [rad/s] (9,), J v = 0."""
        result: FloatArray = self._state.S.dot(self._state.theta_dot)
        return result

    @property
    def closure_residual(self) -> float:
        """Closure residual of the present state [rad] (Euclidean norm of the welds)."""
        return math.sqrt(self._state.r2)

    @property
    def max_closure_residual(self) -> float:
        """Largest closure residual since the last reset [rad]."""
        return math.sqrt(self._state.max_r2)

    @property
    def steps(self) -> int:
        """Steps taken since the last reset."""
        return self._state.steps

    def energy(self) -> tuple[float, float]:
        """(kinetic, potential) energy at the present state [J]."""
        return self._kernel.energy(self._state.q, self.v)

    # ------------------------------------------------------------------ steps
    def step(self, torque: npt.ArrayLike | None = None) -> FloatArray:
        """Advance one time step with actuator torques [N m] (3,) held over it (default 0).

        Returns:
            The input accelerations at the state the step started from [rad/s^2], (3,).

        Raises:
            InputError: torque of a wrong shape, NaN or inf.
            SingularityError: the motion reached a parallel (type II) singularity.
            ConvergenceError: the loops could not be closed (never silently).
        """
        tau = np.zeros(3) if torque is None else vector(torque, 3, "torque", "[N m]")
        return self._kernel.step(tau)

    # -------------------------------------------------------------------- run
    def run(
        self,
        duration: float,
        controller: Controller | npt.ArrayLike | None = None,
        *,
        record_every: int = 1,
    ) -> SimulationResult:
        """Simulate for ``duration`` seconds and return the sampled motion.

        Args:
            duration: Simulated time [s] (rounded to whole steps, at least one).
            controller: The actuator torques: None (zero: a passive motion), a constant
                (3,) [N m], or a callable ``controller(t, theta, theta_dot) -> (3,)``
                evaluated at the start of every step and held over it (e.g. a
                :class:`ServoController`).
            record_every: Record every k-th step (the first and last state always).

        Returns:
            :class:`SimulationResult`.

        Raises:
            InputError: bad duration, record_every, constant torque or controller
                output (NaN, inf, wrong shape: reported with the time).
            SingularityError: the motion reached a parallel (type II) singularity.
        """
        length = positive(duration, "duration", "[s]")
        check_count(record_every, "record_every", 1)
        steps = max(1, round(length / self.dt))
        call: Controller | None = None
        constant = np.zeros(3)
        if callable(controller):
            call = controller
        elif controller is not None:
            constant = vector(controller, 3, "controller", "[N m] (a constant torque)")
        recorder = _Recorder(self, steps // record_every + 2)
        step = self._kernel.step
        idx = self.dynamics.actuated_idx
        state = self._state

        def torque_now() -> FloatArray:
            if call is None:
                return constant
            value: FloatArray = call(state.time, state.q.take(idx), state.theta_dot.copy())
            if (
                type(value) is not np.ndarray
                or value.shape != (3,)
                or value.dtype != np.float64
                or not math.isfinite(float(value.dot(value)))
            ):
                value = vector(value, 3, "controller output", f"[N m] (at t = {state.time:.6g} s)")
            return value

        for k in range(steps):
            tau = torque_now()
            if k % record_every == 0:
                row = recorder.add(tau)
                recorder.theta_ddot[row] = step(tau)
            else:
                step(tau)
        tau = torque_now()
        row = recorder.add(tau)
        v = state.S.dot(state.theta_dot)
        recorder.theta_ddot[row] = self._kernel.accelerate(state.q, v, tau)[0].take(idx)
        return recorder.result()


class _Recorder:
    """Preallocated sample arrays of a run."""

    def __init__(self, sim: Simulator, n: int) -> None:
        self.sim = sim
        self.state = sim._state
        self.energy = sim._kernel.energy
        self.n = 0
        self.time = np.zeros(n)
        self.theta_dot = np.zeros((n, 3))
        self.theta_ddot = np.zeros((n, 3))
        self.torque = np.zeros((n, 3))
        self.q = np.zeros((n, 9))
        self.kinetic = np.zeros(n)
        self.potential = np.zeros(n)
        self.work = np.zeros(n)
        self.loss = np.zeros(n)
        self.residual = np.zeros(n)

    def add(self, tau: FloatArray) -> int:
        """Record the simulator's present state (the kinematics are evaluated there)."""
        state = self.state
        k = self.n
        q = state.q
        v = state.S.dot(state.theta_dot)
        self.time[k] = state.time
        self.theta_dot[k] = state.theta_dot
        self.torque[k] = tau
        self.q[k] = q
        self.kinetic[k], self.potential[k] = self.energy(q, v)
        self.work[k] = state.work
        self.loss[k] = state.loss
        self.residual[k] = math.sqrt(state.r2)
        self.n += 1
        return k

    def result(self) -> SimulationResult:
        sim = self.sim
        n = self.n
        idx = sim.dynamics.actuated_idx
        return SimulationResult(
            time=self.time[:n].copy(),
            theta=self.q[:n][:, idx].copy(),
            theta_dot=self.theta_dot[:n].copy(),
            theta_ddot=self.theta_ddot[:n].copy(),
            torque=self.torque[:n].copy(),
            q=self.q[:n].copy(),
            kinetic=self.kinetic[:n].copy(),
            potential=self.potential[:n].copy(),
            actuator_work=self.work[:n].copy(),
            friction_loss=self.loss[:n].copy(),
            closure_residual=self.residual[:n].copy(),
            max_closure_residual=sim.max_closure_residual,
            steps=self.state.steps,
            dt=sim.dt,
            integrator=sim.integrator,
        )
