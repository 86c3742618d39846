"""The batched dynamic core of ``spm_pin/OrientDynamic-v0`` (:class:`DynamicCore`).

It is an :class:`~spm_pin.envs._core.OrientCore` (the same goals, safety checks,
reward, observation and episode counters) whose robots move by the reduced dynamics
(:class:`~spm_pin.dynamics.ReducedDynamics`) under the servos' torques instead of
following the commanded speeds exactly. The state of N robots is their input angles
and speeds (N, 3) each (no passive joint is integrated, so the loops cannot drift),
stepped as numpy batches in ``substeps`` physics steps per control period.

**Actuation** (:class:`PhysicsSettings`):

* ``"position"`` (default): the action is the speed of each servo's goal position,
  ``a * max_speed`` (first kept within the guard's acceleration of the last one when
  ``limit_acceleration`` is set, as the commanded speeds of ``spm_pin/Orient-v0``
  are): the goal moves at that speed through the control period (the servo's
  profile), and the servo's PD position loop,
  ``kp (goal - theta) + kd (goal speed - theta_dot)``, follows it with its torque
  clipped to the torque-speed envelope at every physics step
  (:class:`~spm_pin.dynamics.ServoModel`). A zero action holds the goal. (The inputs
  may turn 200 times either way, so absolute goals cannot be normalised to [-1, 1].)
* ``"torque"``: the action times the servo's stall torque is the motor torque, clipped
  to the torque-speed envelope at the present speed at every physics step.

**Safety**: the state at the end of each control period passes the guard's static
checks (:meth:`~spm_pin.envs._core.OrientCore.safe`). When it does not, or when the
dynamics cannot go on (a state without a home-mode assembly, a parallel singularity),
``safety="clip"`` stops the robot at the last safe physics step of the period (found
by bisection over the steps, each candidate checked), its speeds zeroed and its goal
position set there, as the guard's stop would; ``safety="terminate"`` keeps the state
of the period's start (speeds zeroed) and ends the episode with the penalty.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import itertools
import math
import os
import threading
from typing import Any

import numpy as np

from .. import _jit
from ..dynamics import XM540_W150, ReducedDynamics, ServoModel
from ..errors import InputError, SPMError
from . import _block_kernel, _dynamic_kernel
from ._core import BoolArray, FloatArray, IntArray, OrientCore, StepResult
from .settings import OrientSettings, _choice, _number

__all__ = ["ACTUATIONS", "INTEGRATORS", "DynamicCore", "PhysicsSettings", "physics_from"]

#: What an action of the dynamic environment commands.
ACTUATIONS = ("position", "torque")
#: The integrators of :meth:`~spm_pin.dynamics.ReducedDynamics.step`.
INTEGRATORS = ("euler", "rk4")
#: What :meth:`DynamicCore.extra_info` adds to a step's info, as
#: :attr:`OrientCore.RECORD <spm_pin.envs._core.OrientCore.RECORD>` gives it: (info
#: key, state attribute, size).
_EXTRA = (
    ("theta_dot", "speed", 3),
    ("servo_goal", "servo_goal", 3),
    ("torque", "torque", 3),
    ("torque_speed", "torque_speed", 3),
    ("servo_load", "servo_load", 0),
)
#: The keys :meth:`DynamicCore.extra_info` adds to a step's info.
EXTRA_INFO = tuple(key for key, _, _ in _EXTRA)
#: Fewest rows in a chunk of a period shared among threads (below, handing the work
#: to a thread costs more than it saves).
THREADED_ROWS = 256
#: Fewest robots the compiled step takes in vectorised blocks
#: (:mod:`~spm_pin.envs._block_kernel`); fewer go robot after robot (a block of
#: :data:`~spm_pin.envs._block_kernel.BLOCK` lanes costs about what four robots do
#: one after the other).
BLOCK_ROWS = 4

_pool_lock = threading.Lock()
_the_pool: concurrent.futures.ThreadPoolExecutor | None = None


def _cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _pool() -> concurrent.futures.ThreadPoolExecutor:
    """The threads that step the chunks of a period (made on first use)."""
    global _the_pool
    with _pool_lock:
        if _the_pool is None:
            _the_pool = concurrent.futures.ThreadPoolExecutor(
                max_workers=max(2, _cores()), thread_name_prefix="spm-pin-physics"
            )
        return _the_pool


@dataclasses.dataclass(frozen=True)
class PhysicsSettings:
    """The physics of ``spm_pin/OrientDynamic-v0`` (every one has a default).

    Attributes:
        actuation: ``"position"``: the action moves the servos' goal positions;
            ``"torque"``: the action is the motor torque over the stall torque.
        servo: The servos' model: PD gains and torque-speed envelope (default
            :data:`~spm_pin.dynamics.XM540_W150`).
        physics_dt: Largest physics step [s]; the control period is cut into
            ``ceil(control_period / physics_dt)`` equal steps. Default: 1 ms for
            ``"position"``, 0.25 ms for ``"torque"``: at the envelope the motor's
            back-EMF damps like ``stall_torque / no_load_speed`` (1.3 N m s/rad for the
            XM540) on inputs of a few 1e-4 kg m^2 without armature, which the explicit
            step resolves only below about 0.5 ms.
        integrator: ``"euler"`` (semi-implicit) or ``"rk4"``.
        armature: Reflected rotor inertia of each actuator [kg m^2] (>= 0).
    """

    actuation: str = "position"
    servo: ServoModel | None = None
    physics_dt: float | None = None
    integrator: str = "euler"
    armature: float = 0.0

    def __post_init__(self) -> None:
        _choice(self.actuation, "actuation", ACTUATIONS)
        _choice(self.integrator, "integrator", INTEGRATORS)
        if self.servo is not None and not isinstance(self.servo, ServoModel):
            raise InputError(
                f"servo must be a ServoModel, got {type(self.servo).__name__}",
                argument="servo",
                value=self.servo,
            )
        if self.physics_dt is not None:
            _number(self.physics_dt, "physics_dt", 0.0, 0.1, open_low=True)
        _number(self.armature, "armature", 0.0, 10.0)

    @property
    def the_servo(self) -> ServoModel:
        """The servo model (the XM540-W150 when none was given)."""
        return self.servo or XM540_W150

    @property
    def the_physics_dt(self) -> float:
        """The largest physics step [s] (the actuation's default when none was given)."""
        if self.physics_dt is not None:
            return float(self.physics_dt)
        return 1e-3 if self.actuation == "position" else 2.5e-4


#: The option names of :class:`PhysicsSettings`.
PHYSICS_FIELDS = frozenset(f.name for f in dataclasses.fields(PhysicsSettings))


def physics_from(
    physics: PhysicsSettings | None, options: dict[str, Any]
) -> tuple[PhysicsSettings, dict[str, Any]]:
    """(``physics`` with the :class:`PhysicsSettings` fields of ``options`` replaced,
    the other options)."""
    if physics is not None and not isinstance(physics, PhysicsSettings):
        raise InputError(
            f"physics must be PhysicsSettings, got {type(physics).__name__}",
            argument="physics",
            value=physics,
        )
    mine = {k: v for k, v in options.items() if k in PHYSICS_FIELDS}
    rest = {k: v for k, v in options.items() if k not in PHYSICS_FIELDS}
    base = physics or PhysicsSettings()
    return (dataclasses.replace(base, **mine) if mine else base), rest


@dataclasses.dataclass(frozen=True)
class _Period:
    """A control period's physics of n rows, for its end (:meth:`DynamicCore._finish`):
    the clipped actions, the input angles at its start and end, the end speeds and
    rotations, the path (substeps + 1, n, 3), the last step each row reached and the
    rows the dynamics could not step, the servos' goals at the start and their speeds.
    """

    a: FloatArray
    start: FloatArray
    theta: FloatArray
    speed: FloatArray
    R: FloatArray
    path: FloatArray
    last: IntArray
    failed: BoolArray
    goal_start: FloatArray
    goal_speed: FloatArray

    def subset(self, back: IntArray) -> _Period:
        """The period of the rows ``back`` (indices into its rows)."""
        return _Period(
            self.a[back],
            self.start[back],
            self.theta[back],
            self.speed[back],
            self.R[back],
            self.path[:, back],
            self.last[back],
            self.failed[back],
            self.goal_start[back],
            self.goal_speed[back],
        )


class DynamicCore(OrientCore):
    """N robots moved by the reduced dynamics under their servos (see the module).

    Args:
        settings: The options shared with ``spm_pin/Orient-v0``.
        num: Number of robots.
        physics: The physics.

    Attributes:
        speed: The input speeds [rad/s], (N, 3) (the real ones, not commands).
        servo_goal: The servos' goal positions [rad], (N, 3).
        torque: The motor torques of the last physics step [N m], (N, 3).
        torque_speed: The input speeds [rad/s] at which ``torque`` was applied.
        servo_load: The largest load (:meth:`~spm_pin.dynamics.ServoModel.utilisation`,
            1 on the envelope) over the last control period, (N,).
        fused: Whether the physics steps of a period run in one compiled call
            (:mod:`~spm_pin.envs._dynamic_kernel`; the same results as the numpy loop,
            which takes over where the call stops); set False for the loop alone.
    """

    STEP_KERNELS = _dynamic_kernel.KERNELS
    SINGLE = "DYNAMIC"
    RECORD = (*OrientCore.RECORD, *_EXTRA)

    def __init__(self, settings: OrientSettings, num: int, physics: PhysicsSettings) -> None:
        super().__init__(settings, num)
        self.physics = physics
        self.servo = physics.the_servo
        self.dynamics = ReducedDynamics(self.design, armature=physics.armature)
        #: Physics steps per control period.
        self.substeps = max(1, math.ceil(settings.control_period / physics.the_physics_dt - 1e-9))
        #: The physics step [s].
        self.dt = settings.control_period / self.substeps
        self.servo_goal = np.zeros((num, 3))
        self.goal_speed = np.zeros((num, 3))
        self.torque = np.zeros((num, 3))
        self.torque_speed = np.zeros((num, 3))
        self.servo_load = np.zeros(num)
        #: The compiled period where numba is installed, not switched off
        #: (``SPM_PIN_JIT=0``) and the dynamics run compiled; False: the loop alone.
        self.fused = True
        self._threads: int | None = None
        self._fused_kernel: Any = None
        self._finish_kernel: Any = None
        self._step_kernel: Any = None
        self._block_kernel: Any = None
        #: Whether the compiled step takes :data:`BLOCK_ROWS` robots or more in
        #: vectorised blocks (:mod:`~spm_pin.envs._block_kernel`; the same bits as
        #: robot after robot, which False asks for).
        self.blocks = True
        self._physics_args: tuple[Any, ...] | None = None

    @property
    def threads(self) -> int | None:
        """Threads that share a compiled period of at least 2 :data:`THREADED_ROWS`
        rows, in contiguous chunks (the kernel releases the GIL; the results are one
        thread's, bit for bit); None (the default): one per core this process may use.

        Raises:
            InputError: on setting anything but None or a positive int.
        """
        return self._threads

    @threads.setter
    def threads(self, value: int | None) -> None:
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int) or value < 1
        ):
            raise InputError(
                f"threads must be None or a positive int, got {value!r}",
                argument="threads",
                value=value,
            )
        self._threads = value

    def chunks(self, rows: int) -> int:
        """Into how many chunks (threads) a compiled period of ``rows`` rows is cut:
        at most :attr:`threads`, each of at least :data:`THREADED_ROWS` rows; 1: one
        call."""
        if rows < 2 * THREADED_ROWS:  # one chunk (and no system call to count cores)
            return 1
        return max(1, min(self._threads or _cores(), rows // THREADED_ROWS))

    def reset_rows(self, rows: IntArray, rngs: list[np.random.Generator]) -> None:
        """Start new episodes in ``rows`` at rest, each servo's goal where it stands."""
        super().reset_rows(rows, rngs)
        self.servo_goal[rows] = self.theta[rows]
        self.goal_speed[rows] = 0.0
        self.torque[rows] = 0.0
        self.torque_speed[rows] = 0.0
        self.servo_load[rows] = 0.0

    # ---------------------------------------------------------------- servos
    def _envelope(self, speed: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(lower, upper) torques [N m] the servos can give at ``speed``, the formula of
        :meth:`~spm_pin.dynamics.ServoModel.torque_limits` without its input checks."""
        stall = self.servo.stall_torque
        slope = speed / self.servo.no_load_speed
        return np.maximum(-stall, -stall * (1.0 + slope)), np.minimum(stall, stall * (1.0 - slope))

    def _load(self, torque: FloatArray, speed: FloatArray) -> FloatArray:
        """Largest :meth:`~spm_pin.dynamics.ServoModel.utilisation` of the three servos."""
        tau = torque / self.servo.stall_torque
        duty = tau + speed / self.servo.no_load_speed
        load: FloatArray = np.maximum(np.abs(duty), np.abs(tau)).max(axis=-1)
        return load

    # ---------------------------------------------------------------- physics
    def _advance(
        self, theta: FloatArray, speed: FloatArray, torque: FloatArray, R: FloatArray
    ) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray]:
        """One physics step of checked rows: (stepped, theta, speed, R). Rows where the
        dynamics raise (no home-mode assembly, a singularity) are found by halving the
        batch and come back unstepped with ``stepped`` False."""
        n = theta.shape[0]
        try:
            out = self.dynamics.step(
                theta, speed, torque, self.dt, integrator=self.physics.integrator, reference=R
            )
        except SPMError:
            if n == 1:
                return np.zeros(1, dtype=bool), theta, speed, R
            half = n // 2
            first = self._advance(theta[:half], speed[:half], torque[:half], R[:half])
            second = self._advance(theta[half:], speed[half:], torque[half:], R[half:])
            ok, th, sp, rot = (np.concatenate(pair) for pair in zip(first, second, strict=True))
            return ok, th, sp, rot
        return np.ones(n, dtype=bool), out.theta, out.theta_dot, out.R

    def _period_kernel(self) -> Any:
        """The compiled :func:`~spm_pin.envs._dynamic_kernel.period`, or None."""
        if not self.fused or self.dynamics._kernels() is None:
            return None
        kernel = self._fused_kernel
        if kernel is None:
            if not _jit.available():
                self.fused = False
                return None
            kernel = self._fused_kernel = _jit.kernels(_dynamic_kernel.KERNELS)["period"]
        return kernel

    def _fused_steps(
        self,
        state: tuple[FloatArray, FloatArray, FloatArray],
        drive: tuple[FloatArray, FloatArray, FloatArray],
        records: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    ) -> int:
        """The physics steps of the period that :func:`~spm_pin.envs._dynamic_kernel.
        period` completes for all rows, in place on ``state`` (theta, speed, R) and
        ``records`` (path, torque, torque_speed, load) under the ``drive`` (goal_start,
        goal_speed, wanted); 0 without the kernel (or for arrays it does not take)."""
        kernel = self._period_kernel()
        arrays = (*state, *drive, *records)
        if kernel is None or not all(
            x.dtype == np.float64 and x.flags.c_contiguous for x in arrays
        ):
            return 0
        chunks = self.chunks(state[0].shape[0])
        if chunks == 1:
            return self._call_period(kernel, state, drive, records)
        return self._threaded_period(kernel, state, drive, records, chunks)

    def _threaded_period(
        self,
        kernel: Any,
        state: tuple[FloatArray, FloatArray, FloatArray],
        drive: tuple[FloatArray, FloatArray, FloatArray],
        records: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
        chunks: int,
    ) -> int:
        """:meth:`_fused_steps` on ``chunks`` contiguous chunks of rows at once, in
        threads. The kernel stops a chunk before the first step that a row of it cannot
        take; should a chunk stop early, the state is put back and the whole batch
        runs in one call, so that every row stops at the same step, as in one call."""
        path, kept = records[0], records[1:]
        saved = [x.copy() for x in (*state, *kept)]
        bounds = np.linspace(0, state[0].shape[0], chunks + 1).astype(int)
        parts: list[tuple[Any, Any, Any]] = []
        for a, b in itertools.pairwise(bounds.tolist()):
            part_path = np.empty((path.shape[0], b - a, 3))
            parts.append(
                (
                    tuple(x[a:b] for x in state),
                    tuple(x[a:b] for x in drive),
                    (part_path, *(x[a:b] for x in kept)),
                )
            )
        futures = [_pool().submit(self._call_period, kernel, *part) for part in parts]
        done = [future.result() for future in futures]
        if min(done) == self.substeps:
            for (a, b), part in zip(itertools.pairwise(bounds.tolist()), parts, strict=True):
                path[1:, a:b] = part[2][0][1:]
            return self.substeps
        for x, y in zip((*state, *kept), saved, strict=True):
            x[...] = y
        return self._call_period(kernel, state, drive, records)

    def _call_period(
        self,
        kernel: Any,
        state: tuple[FloatArray, FloatArray, FloatArray],
        drive: tuple[FloatArray, FloatArray, FloatArray],
        records: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    ) -> int:
        """``kernel`` (a period) called on the state, the drive and the records."""
        done: int = kernel(*state, *drive, *self._physics_arguments(), *records)
        return done

    def _compiled_step(self) -> tuple[Any, ...] | None:
        """:meth:`fused_arguments` where the compiled step applies (the compiled period
        too), else None."""
        arguments = self.fused_arguments()
        if arguments is None or self._period_kernel() is None:
            return None
        return arguments

    def _hand_back(self, rows: IntArray, action: FloatArray) -> StepResult:
        """Step ``rows`` that the compiled step handed back, period by period (the
        rows whose end numpy makes are counted in ``handed_rows`` there)."""
        return self._step_periods(rows, action)

    def _physics_arguments(self) -> tuple[Any, ...]:
        """What the compiled period and step take of the physics, which does not
        change (made once): ``"position"`` actuation, the servo (kp, kd, stall torque,
        no-load speed), the physics step, the steps per period, rk4, the reduced
        dynamics' constants."""
        if self._physics_args is None:
            servo = self.servo
            self._physics_args = (
                self.physics.actuation == "position",
                (
                    float(servo.kp),
                    float(servo.kd),
                    float(servo.stall_torque),
                    float(servo.no_load_speed),
                ),
                float(self.dt),
                int(self.substeps),
                self.physics.integrator == "rk4",
                self.dynamics._constants(),
            )
        return self._physics_args

    def _last_safe(self, path: FloatArray, rows: IntArray, high: IntArray) -> IntArray:
        """For each of ``rows`` (indices into the path's robots): the last physics step
        k < high[i] whose state path[k, i] passed the safety checks, by bisection
        (state 0, the start, is safe; state high[i] is not)."""
        low = np.zeros(rows.size, dtype=np.intp)
        high = high.copy()
        while True:
            open_ = np.flatnonzero(high - low > 1)
            if open_.size == 0:
                return low
            middle = (low[open_] + high[open_]) // 2
            ok = self.safe(path[middle, rows[open_]])
            low[open_] = np.where(ok, middle, low[open_])
            high[open_] = np.where(ok, high[open_], middle)

    def _step_plain(self, rows: IntArray, action: FloatArray) -> StepResult:
        """:meth:`step_rows` without the compiled step: :meth:`_step_periods`."""
        return self._step_periods(rows, action)

    def _kernel_counts(
        self,
        rows: IntArray,
        action: FloatArray,
        out: FloatArray,
        handed: BoolArray,
        arguments: tuple[Any, ...],
    ) -> IntArray:
        """Whole control periods of ``rows``, robot by robot, by the compiled
        :func:`~spm_pin.envs._dynamic_kernel.step`: in contiguous chunks of robots on
        threads (the kernel releases the GIL) where :meth:`chunks` says so; the
        cover's checks asked and settled (2,)."""
        n = rows.size
        chunks = self.chunks(n)
        if chunks == 1:
            return super()._kernel_counts(rows, action, out, handed, arguments)
        bounds = np.linspace(0, n, chunks + 1).astype(int).tolist()
        parts = np.zeros((chunks, 2), dtype=np.int64)
        futures = [
            _pool().submit(
                self._call_step, rows[a:b], action[a:b], out[a:b], handed[a:b], part, arguments
            )
            for part, (a, b) in zip(parts, itertools.pairwise(bounds), strict=True)
        ]
        for future in futures:
            future.result()
        counts: IntArray = parts.sum(axis=0)
        return counts

    def _in_blocks(self, n: int) -> bool:
        """Whether the compiled step takes ``n`` robots in blocks: :attr:`blocks`, at
        least :data:`BLOCK_ROWS` robots, semi-implicit Euler and no joint friction
        (what :func:`~spm_pin.envs._block_kernel.step` is written for)."""
        return (
            self.blocks
            and n >= BLOCK_ROWS
            and self.physics.integrator == "euler"
            and self.dynamics.friction is None
        )

    def _step_call(
        self,
        rows: IntArray,
        action: FloatArray,
        out: FloatArray,
        handed: BoolArray,
        counts: IntArray,
        arguments: tuple[Any, ...],
    ) -> tuple[Any, tuple[Any, ...]]:
        """(the compiled step of ``rows``, its arguments):
        :func:`~spm_pin.envs._block_kernel.step` (robots in blocks, vectorised) where
        :meth:`_in_blocks`, else :func:`~spm_pin.envs._dynamic_kernel.step` (the same
        bits)."""
        if self._in_blocks(rows.size):
            if self._block_kernel is None:
                _jit.kernels(_dynamic_kernel.KERNELS)  # the plain twins it calls
                self._block_kernel = _jit.kernels(_block_kernel.KERNELS, lanes=True)["step"]
            kernel = self._block_kernel
        else:
            if self._step_kernel is None:
                self._step_kernel = _jit.kernels(_dynamic_kernel.KERNELS)["step"]
            kernel = self._step_kernel
        motion, flags, weights, low, high, cover = arguments[:6]
        args = (
            rows,
            action,
            self.theta,
            self.speed,
            self.R,
            self.servo_goal,
            self.goal_speed,
            self.torque,
            self.torque_speed,
            self.servo_load,
            self.goal,
            self.hold,
            self.steps,
            *self._physics_arguments(),
            motion,
            flags,
            weights,
            low,
            high,
            cover,
            out,
            handed,
            counts,
        )
        return kernel, args

    def _step_periods(self, rows: IntArray, action: FloatArray) -> StepResult:
        """:meth:`step_rows` period by period: the physics steps of every row (compiled
        where they can, :meth:`_fused_steps`), then the period's end (compiled with a
        cover, :meth:`_finish_fused`; else :meth:`_finish`)."""
        servo = self.servo
        n = rows.size
        a = np.clip(action, -1.0, 1.0)
        position = self.physics.actuation == "position"
        goal_speed = self.goal_speed[rows]
        goal_start = self.servo_goal[rows]
        wanted = a * servo.stall_torque
        if position:
            goal_speed = self.command(a, goal_speed)
        start = self.theta[rows]
        theta = start.copy()
        speed = self.speed[rows].copy()
        R = self.R[rows].copy()
        path = np.empty((self.substeps + 1, n, 3))
        path[0] = start
        last = np.full(n, self.substeps, dtype=np.intp)  # the last state reached
        failed = np.zeros(n, dtype=bool)
        torque = self.torque[rows].copy()
        torque_speed = self.torque_speed[rows].copy()
        load = np.zeros(n)
        alive = np.arange(n)
        # The compiled period goes as far as every row steps as in the loop below;
        # the loop takes the rest (none, usually) from the state it leaves.
        done = self._fused_steps(
            (theta, speed, R),
            (goal_start, goal_speed, np.asarray(wanted)),
            (path, torque, torque_speed, load),
        )
        for k in range(done, self.substeps):
            th, sp = theta[alive], speed[alive]
            lower, upper = self._envelope(sp)
            if position:  # the goal moves at goal_speed through the period
                goal = goal_start[alive] + goal_speed[alive] * (k * self.dt)
                raw = servo.kp * (goal - th) + servo.kd * (goal_speed[alive] - sp)
            else:
                raw = wanted[alive]
            tau = np.clip(raw, lower, upper)
            ok, th, sp, rot = self._advance(th, sp, tau, R[alive])
            if not np.all(ok):
                lost = alive[~ok]
                failed[lost] = True
                last[lost] = k  # the dynamics could not go on from path[k]
                alive, th, sp, rot, tau = alive[ok], th[ok], sp[ok], rot[ok], tau[ok]
            torque[alive] = tau
            torque_speed[alive] = speed[alive]
            load[alive] = np.maximum(load[alive], self._load(tau, speed[alive]))
            theta[alive] = th
            speed[alive] = sp
            R[alive] = rot
            path[k + 1, alive] = th
            if alive.size == 0:
                break
        self.torque[rows] = torque
        self.torque_speed[rows] = torque_speed
        self.servo_load[rows] = load
        period = _Period(a, start, theta, speed, R, path, last, failed, goal_start, goal_speed)
        arguments = self.fused_arguments()
        if arguments is not None and (done == self.substeps or not failed.any()):
            return self._finish_fused(rows, period, arguments)
        return self._finish(rows, period)

    def _finish_fused(self, rows: IntArray, p: _Period, arguments: tuple[Any, ...]) -> StepResult:
        """:meth:`_finish` by the compiled :func:`~spm_pin.envs._dynamic_kernel.finish`
        (a period every row completed, a cover), the rows it hands back by numpy."""
        if self._finish_kernel is None:
            self._finish_kernel = _jit.kernels(_dynamic_kernel.KERNELS)["finish"]
        n = rows.size
        out = np.empty((n, 5))
        handed = np.zeros(n, dtype=bool)
        counts = np.zeros(2, dtype=np.int64)
        motion, flags, weights, low, high, cover = arguments[:6]
        physics = self._physics_arguments()
        c = np.ascontiguousarray
        self._finish_kernel(
            c(rows, dtype=np.int64),
            *(c(x, dtype=np.float64) for x in (p.a, p.start, p.theta, p.speed, p.R, p.path)),
            *(c(x, dtype=np.float64) for x in (p.goal_start, p.goal_speed)),
            self.theta,
            self.speed,
            self.R,
            self.goal,
            self.hold,
            self.steps,
            self.servo_goal,
            self.goal_speed,
            physics[0],  # "position" actuation
            physics[3],  # substeps
            motion,
            flags,
            weights,
            low,
            high,
            cover,
            physics[5],  # the reduced dynamics' constants
            out,
            handed,
            counts,
        )
        return self.kernel_result(
            rows, out, handed, counts, lambda back: self._finish(rows[back], p.subset(back))
        )

    def _finish(self, rows: IntArray, p: _Period) -> StepResult:
        """The end of a period of ``rows`` in numpy: the end state's safety (the clip's
        bisection over the physics steps, or the end of the episode), the servos'
        goals and :meth:`settle`."""
        s = self.settings
        n = rows.size
        theta, speed, goal_speed = p.theta, p.speed, p.goal_speed  # the period's own: ended here
        safe = ~p.failed
        safe[safe] = self.safe(theta[safe])
        fraction = np.ones(n)
        unsafe = np.zeros(n, dtype=bool)
        bad = np.flatnonzero(~safe)
        if bad.size:
            if s.safety == "clip":
                stop = self._last_safe(p.path, bad, p.last[bad])
                theta[bad] = p.path[stop, bad]
                fraction[bad] = stop / self.substeps
            else:
                theta[bad] = p.start[bad]
                fraction[bad] = 0.0
                unsafe[bad] = True
            speed[bad] = 0.0
        if self.physics.actuation == "position":
            goal = p.goal_start + goal_speed * s.control_period
            goal[bad] = theta[bad]  # the stop holds the servos where they stand
            goal_speed[bad] = 0.0
            self.servo_goal[rows] = goal
            self.goal_speed[rows] = goal_speed
        else:
            self.servo_goal[rows] = theta
        return self.settle(rows, p.a, theta, speed, fraction, unsafe, reference=p.R)

    def rotations(
        self, rows: IntArray, theta: FloatArray, reference: FloatArray | None = None
    ) -> FloatArray:
        """:meth:`OrientCore.rotations`, by the reduced dynamics' warm start from
        ``reference`` (the rotations of the physics steps, near theta) where given:
        Newton's method from there (compiled with the dynamics), forward kinematics for
        the rows it does not settle."""
        if reference is None:
            return super().rotations(rows, theta)
        try:
            return self.dynamics.rotation(theta, reference=reference)
        except SPMError:  # a row without a home-mode assembly: it keeps its rotation
            return super().rotations(rows, theta)

    def extra_info(self, rows: IntArray | int) -> dict[str, Any]:
        """What the dynamic environments add to a step's info, per row (an index
        array: arrays of those rows; one row's int: its values): the real input
        speeds ``theta_dot`` [rad/s], the servos' goal positions ``servo_goal`` [rad],
        the motor torques of the last physics step ``torque`` [N m] and the speeds
        ``torque_speed`` [rad/s] they were applied at, and the largest ``servo_load``
        of the period (<= 1 inside the torque-speed envelope). Copies, never views."""
        if isinstance(rows, np.ndarray):  # indexing by an array copies
            return {key: getattr(self, name)[rows] for key, name, _ in _EXTRA}
        return {key: getattr(self, name)[rows].copy() for key, name, _ in _EXTRA}
