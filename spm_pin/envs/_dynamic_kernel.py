r"""The physics steps of one control period of :class:`~spm_pin.envs._dynamic.DynamicCore`
for N robots in one call, in a form that numba compiles (:func:`spm_pin._jit.kernels`
of :data:`KERNELS`).

:meth:`DynamicCore.step_rows <spm_pin.envs._dynamic.DynamicCore.step_rows>` runs
``substeps`` physics steps per control period; in numpy each one costs a few dozen
array calls on the surviving robots, nearly all of the time for one robot. Its loop
body is repeated here row by row in Python floats, the same operations in the same
order (so the compiled kernel gives the numpy loop's bits):

* the servo: ``"position"``: the goal moves at the goal speed through the period,
  ``goal = goal_start + goal_speed (k dt)``, and the PD loop gives
  ``kp (goal - theta) + kd (goal_speed - theta_dot)``; ``"torque"``: the wanted torque;
* the torque-speed envelope at the present speed
  (:meth:`~spm_pin.dynamics.ServoModel.torque_limits`) and the clip to it;
* the reduced-dynamics step of :mod:`spm_pin.dynamics._reduced_kernel` (rotation warm
  started from the last one, then Euler or rk4), as
  :meth:`~spm_pin.dynamics.ReducedDynamics.step` takes it;
* the records: the path of input angles, the torque and the speed it was applied
  at, the largest servo load (:meth:`~spm_pin.dynamics.ServoModel.utilisation`).

:func:`period` stops before the first physics step in which any robot meets what the
numpy loop treats specially (an input the dynamics' checks refuse: too large, NaN or
inf; a rotation the warm start does not settle, which the numpy path solves by
forward kinematics; a singularity) and returns how many steps it completed: the
numpy loop goes on from there with the state it left, so the results, the errors and
the ends are those of the numpy loop. A step of one row (:func:`_advance_row`)
depends on no other row, so the caller may run the period on chunks of rows in
threads (:func:`period` releases the GIL).

With a cover, :func:`finish` ends a period that every row completed: the end's
safety by the cover's certified cells, the clip's bisection over the physics steps
(or the end of the episode), the servos' goals, the rotation, the reward and the
ends, as the numpy path after its loop; a row it cannot end (a state the safe set
must check, a rotation not settled) is handed back to numpy. :func:`step` takes whole
control periods robot after robot: the command of the action, :func:`period` of the
robot alone and :func:`finish` (a robot's data stay in the cache through its
period); a robot it cannot step is left untouched for the numpy path. Nothing here
checks its arguments: the caller passes C-contiguous arrays of the right types.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .. import _jit
from .._checks import ANGLE_LIMIT
from ..dynamics._checks import LIMITS
from ..dynamics._reduced_kernel import (
    KERNELS as REDUCED_KERNELS,
)
from ..dynamics._reduced_kernel import (
    STATUS_OK,
    Constants,
    Flat,
    _home_of,
    _newton,
    _proximal,
    _row_step,
    _trig,
    flat,
    home_rotation_of,
)
from ..dynamics._tuple_kernel import Mat, _mat_of, _put_mat, _vec_of
from ._kinematic_kernel import (
    CHECK,
    SAFE,
    UNSAFE,
    Cover,
    _clip,
    _enter,
    _mod360,
    _search,
    _verdict,
    covered,
)

__all__ = ["KERNELS", "finish", "period", "step"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
Vec = tuple[float, float, float]
#: The servo's (kp [N m/rad], kd [N m s/rad], stall torque [N m], no-load speed [rad/s]).
Servo = tuple[float, float, float, float]

#: The bounds of :meth:`~spm_pin.dynamics.ReducedDynamics.step`'s input checks: input
#: angles [rad], speeds [rad/s], torques [N m] (a row beyond them is refused there).
_ANGLE_BOUND = float(ANGLE_LIMIT)
_SPEED_BOUND = float(LIMITS["[rad/s]"])
_TORQUE_BOUND = float(LIMITS["[N m]"])


def _within(x: Vec, bound: float) -> bool:
    """Every |x_j| <= bound (False for NaN), as the dynamics' ``max |x| <= bound``."""
    return abs(x[0]) <= bound and abs(x[1]) <= bound and abs(x[2]) <= bound


def _clip_torque(raw: float, speed: float, stall: float, no_load: float) -> float:
    """``raw`` clipped to the torque-speed envelope at ``speed``: the formula of
    :meth:`~spm_pin.dynamics.ServoModel.torque_limits`, then ``np.clip`` (NaN stays
    NaN, as there)."""
    slope = speed / no_load
    lower = -stall * (1.0 + slope)
    if lower < -stall:  # np.maximum(-stall, lower)
        lower = -stall
    upper = stall * (1.0 - slope)
    if upper > stall:  # np.minimum(stall, upper)
        upper = stall
    value = raw
    if value < lower:
        value = lower
    if value > upper:
        value = upper
    return value


def _servo(
    goal_start: float, goal_speed: float, offset: float, theta: float, speed: float, servo: Servo
) -> float:
    """The PD loop's torque [N m] before the envelope: kp (goal - theta) +
    kd (goal_speed - speed), the goal ``goal_start + goal_speed offset``."""
    goal = goal_start + goal_speed * offset
    return servo[0] * (goal - theta) + servo[1] * (goal_speed - speed)


def _load(tau: Vec, speed: Vec, stall: float, no_load: float) -> float:
    """Largest utilisation max(|tau / stall + speed / no_load|, |tau / stall|) of the
    three servos."""
    largest = 0.0
    for j in range(3):
        t = tau[j] / stall
        duty = t + speed[j] / no_load
        value = abs(duty)
        if not value > abs(t):
            value = abs(t)
        if j == 0 or value > largest:
            largest = value
    return largest


def _finite_mat(R: Mat) -> bool:
    """Every entry finite (the dynamics' check of the warm start)."""
    return _within(R[0], math.inf) and _within(R[1], math.inf) and _within(R[2], math.inf)


@_jit.inline
def _physics_step(
    th: Vec,
    sp: Vec,
    R: Mat,
    goal_start: Vec,
    goal_speed: Vec,
    wanted: Vec,
    offset: float,
    position: bool,
    servo: Servo,
    dt: float,
    rk4: bool,
    f: Flat,
) -> tuple[bool, Vec, Vec, Mat, Vec]:
    """One physics step of one robot at input angles th, speeds sp, warm start R:
    (taken, th', sp', the rotation at th, the torque); not taken where the numpy loop
    must take it."""
    stall, no_load = servo[2], servo[3]
    if position:
        raw = (
            _servo(goal_start[0], goal_speed[0], offset, th[0], sp[0], servo),
            _servo(goal_start[1], goal_speed[1], offset, th[1], sp[1], servo),
            _servo(goal_start[2], goal_speed[2], offset, th[2], sp[2], servo),
        )
    else:
        raw = wanted
    tau = (
        _clip_torque(raw[0], sp[0], stall, no_load),
        _clip_torque(raw[1], sp[1], stall, no_load),
        _clip_torque(raw[2], sp[2], stall, no_load),
    )
    if not (
        _within(th, _ANGLE_BOUND)
        and _within(sp, _SPEED_BOUND)
        and _within(tau, _TORQUE_BOUND)
        and _finite_mat(R)
    ):
        return False, th, sp, R, tau
    cos, sin = _trig(th)
    w = _proximal(cos, sin, f[0], f[1])
    # the warm start settles where Newton's residual is within the tolerance and the
    # home sign rule holds (:func:`_home_rotation`); the rule is taken from the
    # step's own terms at the rotation (the same numbers, computed once)
    rotation, residual, v = _newton(R, w, f[2], f[13], 0.1 * f[19], int(f[20]))
    if not (math.isfinite(residual) and residual <= f[19]):
        return False, th, sp, R, tau
    status, t, r, _, b, det = _row_step(th, cos, sin, w, v, sp, tau, rotation, dt, rk4, f)
    if not _home_of(b, det, f[16], f[17]) or status != STATUS_OK:
        return False, th, sp, R, tau
    return True, t, r, rotation, tau


@_jit.inline
def _advance_row(
    row: int,
    offset: float,
    theta: FloatArray,
    speed: FloatArray,
    R: FloatArray,
    goal_start: FloatArray,
    goal_speed: FloatArray,
    wanted: FloatArray,
    position: bool,
    servo: Servo,
    dt: float,
    rk4: bool,
    f: Flat,
    theta_next: FloatArray,
    speed_next: FloatArray,
    R_next: FloatArray,
    tau_next: FloatArray,
) -> bool:
    """One physics step of ``row`` into the ``*_next`` arrays; False (nothing written)
    where the numpy loop must take it."""
    zero = (0.0, 0.0, 0.0)
    if position:
        drive = (_vec_of(goal_start[row]), _vec_of(goal_speed[row]), zero)
    else:
        drive = (zero, zero, _vec_of(wanted[row]))
    taken, t, r, rotation, tau = _physics_step(
        _vec_of(theta[row]), _vec_of(speed[row]), _mat_of(R[row]), drive[0], drive[1],
        drive[2], offset, position, servo, dt, rk4, f,
    )  # fmt: skip
    if not taken:
        return False
    _put_mat(R_next[row], rotation)
    for j in range(3):
        theta_next[row, j] = t[j]
        speed_next[row, j] = r[j]
        tau_next[row, j] = tau[j]
    return True


@_jit.inline
def _commit_row(
    row: int,
    step: int,
    servo: Servo,
    theta: FloatArray,
    speed: FloatArray,
    R: FloatArray,
    theta_next: FloatArray,
    speed_next: FloatArray,
    R_next: FloatArray,
    tau_next: FloatArray,
    path: FloatArray,
    torque: FloatArray,
    torque_speed: FloatArray,
    load: FloatArray,
) -> None:
    """Take the step of ``row`` from the ``*_next`` arrays, and its records."""
    sp = _vec_of(speed[row])
    tau = _vec_of(tau_next[row])
    value = _load(tau, sp, servo[2], servo[3])
    if not load[row] > value:  # np.maximum(load, value)
        load[row] = value
    for j in range(3):
        torque[row, j] = tau[j]
        torque_speed[row, j] = sp[j]
        theta[row, j] = theta_next[row, j]
        speed[row, j] = speed_next[row, j]
        path[step + 1, row, j] = theta_next[row, j]
        for m in range(3):
            R[row, j, m] = R_next[row, j, m]


@_jit.nogil
def period(
    theta: FloatArray,
    speed: FloatArray,
    R: FloatArray,
    goal_start: FloatArray,
    goal_speed: FloatArray,
    wanted: FloatArray,
    position: bool,
    servo: Servo,
    dt: float,
    substeps: int,
    rk4: bool,
    k: Constants,
    path: FloatArray,
    torque: FloatArray,
    torque_speed: FloatArray,
    load: FloatArray,
) -> int:
    """The physics steps of one control period of rows (N, 3), in place.

    Args:
        theta, speed: Input angles [rad] and speeds [rad/s] (N, 3), stepped in place.
        R: Platform rotations (N, 3, 3): the warm starts, replaced by each step's.
        goal_start, goal_speed: The servos' goal positions at the period's start
            [rad] and their speeds [rad/s] (``"position"``).
        wanted: The torques asked for [N m] (``"torque"``).
        position: ``"position"`` actuation (else ``"torque"``).
        servo: (kp, kd, stall torque, no-load speed).
        dt: The physics step [s].
        substeps: Physics steps in the period.
        rk4: rk4 (else semi-implicit Euler).
        k: The reduced dynamics' constants.
        path: (substeps + 1, N, 3): the input angles after each step, written from
            row 1 on.
        torque, torque_speed: The last step's torques [N m] and the speeds they were
            applied at [rad/s] (N, 3), in place.
        load: The largest servo load so far (N,), in place.

    Returns:
        The number of physics steps completed for every row (``substeps`` when all
        were; fewer when a step met what the numpy loop must take, which it then
        takes from the state left here).
    """
    n = theta.shape[0]
    theta_next = np.empty((n, 3))
    speed_next = np.empty((n, 3))
    R_next = np.empty((n, 3, 3))
    tau_next = np.empty((n, 3))
    f = flat(k)
    for step in range(substeps):
        offset = step * dt
        for row in range(n):
            if not _advance_row(
                row, offset, theta, speed, R, goal_start, goal_speed, wanted, position,
                servo, dt, rk4, f, theta_next, speed_next, R_next, tau_next,
            ):  # fmt: skip
                return step
        for row in range(n):
            _commit_row(
                row, step, servo, theta, speed, R, theta_next, speed_next, R_next,
                tau_next, path, torque, torque_speed, load,
            )  # fmt: skip
    return substeps


def _period_one(
    theta: Vec,
    speed: Vec,
    R: Mat,
    goal_start: Vec,
    goal_speed: Vec,
    wanted: Vec,
    position: bool,
    servo: Servo,
    dt: float,
    substeps: int,
    rk4: bool,
    f: Flat,
    path: FloatArray,
) -> tuple[int, Vec, Vec, Mat, Vec, Vec, float]:
    """:func:`period` of one robot, its state held in floats rather than arrays: (the
    steps completed, theta, speed, R, the last step's torque and the speed it was
    applied at, the largest servo load); the input angles after each step into
    ``path`` (substeps + 1, 1, 3) from row 1 on. The same operations as
    :func:`period`'s; the state returned is meaningful only when every step was
    completed (``f``: the constants as :func:`~spm_pin.dynamics._reduced_kernel.flat`
    gives them)."""
    torque = torque_speed = (0.0, 0.0, 0.0)
    load = 0.0
    for step in range(substeps):
        taken, t, r, rotation, tau = _physics_step(
            theta, speed, R, goal_start, goal_speed, wanted, step * dt, position, servo,
            dt, rk4, f,
        )  # fmt: skip
        if not taken:
            return step, theta, speed, R, torque, torque_speed, load
        value = _load(tau, speed, servo[2], servo[3])
        if not load > value:  # np.maximum(load, value)
            load = value
        torque, torque_speed = tau, speed
        theta, speed, R = t, r, rotation
        for j in range(3):
            path[step + 1, 0, j] = t[j]
    return substeps, theta, speed, R, torque, torque_speed, load


@_jit.nogil
def finish(
    rows: IntArray,
    action: FloatArray,
    start: FloatArray,
    end: FloatArray,
    velocity: FloatArray,
    reference: FloatArray,
    path: FloatArray,
    goal_start: FloatArray,
    goal_speed: FloatArray,
    theta: FloatArray,
    speed: FloatArray,
    R: FloatArray,
    goal: FloatArray,
    hold: IntArray,
    steps: IntArray,
    servo_goal: FloatArray,
    servo_speed: FloatArray,
    position: bool,
    substeps: int,
    motion: FloatArray,
    flags: IntArray,
    weights: FloatArray,
    low: FloatArray,
    high: FloatArray,
    cover: Cover,
    k: Constants,
    out: FloatArray,
    handed: BoolArray,
    counts: IntArray,
) -> None:
    """The end of a control period whose physics steps every row completed, for the
    ``rows`` of a core with a cover, in place: what
    :meth:`DynamicCore.step_rows <spm_pin.envs._dynamic.DynamicCore.step_rows>` does
    in numpy after its loop, the same operations in the same order.

    The end state's safety by the cover (:func:`~spm_pin.envs._kinematic_kernel.
    _verdict`); for an unsafe end, ``"clip"``: the bisection over the period's physics
    steps for the last safe one, speeds zeroed; ``"terminate"``: the start, stopped;
    the servos' goals (``"position"``: moved on through the period, or held where the
    robot stopped; ``"torque"``: where it stands); the rotation by Newton's method from
    the period's last one (:meth:`~spm_pin.dynamics.ReducedDynamics.rotation`'s warm
    start); the error, the goal counter and the reward
    (:func:`~spm_pin.envs._kinematic_kernel._enter`).

    A row whose end needs what the kernel does not do (a state outside the certified
    cells that the safe set must check; a rotation the warm start does not settle) is
    left untouched and flagged in ``handed``: the numpy path ends it.

    Args:
        rows: The robots stepped (n,), indices into the core's arrays.
        action: Their clipped actions (n, 3).
        start, end, velocity: Their input angles at the period's start and end [rad]
            and their speeds at its end [rad/s] (n, 3).
        reference: Their rotations at the period's end (n, 3, 3).
        path: (substeps + 1, n, 3): the input angles after each physics step.
        goal_start, goal_speed: The servos' goals at the period's start [rad] and
            their commanded speeds [rad/s] (n, 3).
        theta, speed, R, goal, hold, steps, servo_goal, servo_speed: The core's state
            of every robot (N, ...); the rows ended here are written.
        position: ``"position"`` actuation (else ``"torque"``).
        substeps: Physics steps in the period.
        motion, flags, weights, low, high, cover: As
            :func:`~spm_pin.envs._kinematic_kernel.step` takes them.
        k: The reduced dynamics' constants.
        out, handed, counts: As :func:`~spm_pin.envs._kinematic_kernel.step`.
    """
    period_s, tolerance = motion[2], motion[3]
    clip, hold_steps, only = flags[1] != 0, flags[3], flags[4] != 0
    u, w0, v0 = _mat_of(k[0]), _mat_of(k[1]), _mat_of(k[2])
    for m in range(rows.shape[0]):
        r = rows[m]
        handed[m] = True
        x = _vec_of(end[m])
        verdict = _verdict(x, low, high, only, cover)
        asked, settled = 1, int(verdict == SAFE)
        if verdict == CHECK:
            continue
        bad = verdict == UNSAFE
        fraction, unsafe = 1.0, False
        v = _vec_of(velocity[m])
        if bad:
            v = (0.0, 0.0, 0.0)
            if clip:  # the last safe physics step (the start is safe)
                low_step, high_step = 0, substeps
                while high_step - low_step > 1:
                    middle = (low_step + high_step) // 2
                    verdict = _verdict(_vec_of(path[middle, m]), low, high, only, cover)
                    asked += 1
                    settled += int(verdict == SAFE)
                    if verdict == CHECK:
                        break
                    if verdict == SAFE:
                        low_step = middle
                    else:
                        high_step = middle
                if verdict == CHECK:
                    continue
                x = _vec_of(path[low_step, m])
                fraction = low_step / substeps
            else:
                x = _vec_of(start[m])
                fraction, unsafe = 0.0, True
        settled_rotation, rotation = home_rotation_of(
            x, _mat_of(reference[m]), u, w0, v0, k[13], k[16], k[17], k[19], int(k[20])
        )
        if not settled_rotation:
            continue
        counts[0] += asked
        counts[1] += settled
        for j in range(3):
            if not position:
                servo_goal[r, j] = x[j]
            elif bad:  # the stop holds the servos where they stand
                servo_goal[r, j] = x[j]
                servo_speed[r, j] = 0.0
            else:
                servo_goal[r, j] = goal_start[m, j] + goal_speed[m, j] * period_s
                servo_speed[r, j] = goal_speed[m, j]
        _enter(r, m, x, v, rotation, _vec_of(action[m]), fraction, unsafe, theta, speed, R,
               goal, hold, steps, tolerance, hold_steps, weights, out)  # fmt: skip
        handed[m] = False


@_jit.nogil
def step(
    rows: IntArray,
    action: FloatArray,
    theta: FloatArray,
    speed: FloatArray,
    R: FloatArray,
    servo_goal: FloatArray,
    servo_speed: FloatArray,
    torque: FloatArray,
    torque_speed: FloatArray,
    servo_load: FloatArray,
    goal: FloatArray,
    hold: IntArray,
    steps: IntArray,
    position: bool,
    servo: Servo,
    dt: float,
    substeps: int,
    rk4: bool,
    k: Constants,
    motion: FloatArray,
    flags: IntArray,
    weights: FloatArray,
    low: FloatArray,
    high: FloatArray,
    cover: Cover,
    out: FloatArray,
    handed: BoolArray,
    counts: IntArray,
) -> None:
    """Whole control periods of ``rows`` with a cover, one robot after the other, in
    place: the command of the action (the servos' goal speed within the acceleration
    limit, or the torque asked for), :func:`period` of the robot alone (held in
    floats, :func:`_period_one`), then :func:`finish`; what :meth:`DynamicCore.step_rows
    <spm_pin.envs._dynamic.DynamicCore.step_rows>` does in numpy, the same operations
    in the same order (a robot's period does not depend on the others).

    A robot whose period or end needs the numpy path (see :func:`period` and
    :func:`finish`) is left untouched and flagged in ``handed``: the numpy path steps
    it from the start of its period.

    Args:
        rows: The robots stepped (n,), indices into the core's arrays.
        action: Their actions (n, 3), finite.
        theta, speed, R, servo_goal, servo_speed, torque, torque_speed, servo_load,
            goal, hold, steps: The core's state of every robot (N, ...); the rows
            stepped here are written.
        position, servo, dt, substeps, rk4, k: As :func:`period` takes them.
        motion, flags, weights, low, high, cover, out, handed, counts: As
            :func:`~spm_pin.envs._kinematic_kernel.step` takes them.
    """
    max_speed, dv, limit = motion[0], motion[1], flags[0] != 0
    # One robot's period: the arrays of a batch of one, reused robot after robot, as
    # views of one buffer (one allocation per call)
    buffer = np.empty((substeps + 10, 3))
    a, th, sp, start_goal = buffer[0:1], buffer[1:2], buffer[2:3], buffer[3:4]
    goal_speed, wanted = buffer[4:5], buffer[5:6]
    rot, path = buffer[6:9].reshape((1, 3, 3)), buffer[9:].reshape((substeps + 1, 1, 3))
    f = flat(k)
    for m in range(rows.shape[0]):
        r = rows[m]
        for j in range(3):
            aj = _clip(action[m, j], -1.0, 1.0)
            a[0, j] = aj
            wanted[0, j] = aj * servo[2]
            command = aj * max_speed
            if limit:
                command = _clip(command, servo_speed[r, j] - dv, servo_speed[r, j] + dv)
            goal_speed[0, j] = command if position else servo_speed[r, j]
            start_goal[0, j] = servo_goal[r, j]
            path[0, 0, j] = theta[r, j]
        done, t, v, Rm, tq, tq_speed, most = _period_one(
            _vec_of(theta[r]), _vec_of(speed[r]), _mat_of(R[r]), _vec_of(start_goal[0]),
            _vec_of(goal_speed[0]), _vec_of(wanted[0]), position, servo, dt, substeps, rk4, f,
            path,
        )  # fmt: skip
        if done < substeps:
            handed[m] = True
            continue
        _put_mat(rot[0], Rm)
        for j in range(3):
            th[0, j] = t[j]
            sp[0, j] = v[j]
        finish(rows[m : m + 1], a, path[0], th, sp, rot, path, start_goal, goal_speed, theta,
               speed, R, goal, hold, steps, servo_goal, servo_speed, position, substeps, motion,
               flags, weights, low, high, cover, k, out[m : m + 1], handed[m : m + 1],
               counts)  # fmt: skip
        if not handed[m]:
            for j in range(3):
                torque[r, j] = tq[j]
                torque_speed[r, j] = tq_speed[j]
            servo_load[r] = most


#: The kernels, callees first: what :func:`spm_pin._jit.kernels` compiles.
KERNELS = (
    *REDUCED_KERNELS,
    _within,
    _finite_mat,
    _clip_torque,
    _servo,
    _load,
    _physics_step,
    _advance_row,
    _commit_row,
    period,
    _period_one,
    _search,
    _mod360,
    covered,
    _verdict,
    _enter,
    finish,
    _clip,
    step,
)
