r"""The compiled step of :class:`~spm_pin.envs._dynamic.DynamicCore` for :data:`BLOCK`
robots at once, one robot per lane of the CPU's vector instructions.

:func:`~spm_pin.envs._dynamic_kernel.step` takes the robots one after the other;
each physics step of a robot is a few hundred operations in a row that the CPU does
one at a time. Here :data:`BLOCK` robots go through each physics step together, in
loops over the robots whose bodies hold no branch, call or uncertain memory access,
which LLVM compiles to vector instructions (four robots per instruction with AVX2;
:func:`spm_pin._jit.kernels` with ``lanes=True``). Each loop is one pass of the
physics step:

* the cos and sin of the input angles (by their reduction modulo pi/2 and fdlibm's
  polynomials, in lanes too);
* the servo's torque, its envelope, the dynamics' input checks and the proximal axes;
* Newton's warm-started rotation, pass by pass while any robot has not converged
  (its turns' cos and sin from their Taylor series, in lanes too); a robot that has
  converged keeps its rotation;
* the home sign rule, the terms, the solve and the semi-implicit Euler step.

A branch of :func:`~spm_pin.envs._dynamic_kernel._physics_step` is a choice between
two computed values here, so every robot computes both and keeps the one its own
state chooses: the same operations on its own numbers, so the bits of
:func:`~spm_pin.envs._dynamic_kernel._period_one`. A robot that meets what the numpy
loop must take (:func:`~spm_pin.envs._dynamic_kernel.period`) keeps its state from
there on and is handed back, as there. The passes share one scratch array, each
quantity a row of :data:`BLOCK` robots at a constant offset, indexed by unsigned
integers: LLVM then sees that the rows do not overlap (with several arrays, or
signed indices that numba wraps, it must check at run time, and gives up).

:func:`step` takes whole control periods of a block: the command of each robot's
action, the block's period, and each robot's end of period by
:func:`~spm_pin.envs._dynamic_kernel.finish`, as
:func:`~spm_pin.envs._dynamic_kernel.step` does. Semi-implicit Euler without joint
friction only (rk4's stages and friction's tanh are not written in lanes): the
caller takes :func:`~spm_pin.envs._dynamic_kernel.step` for the others.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .. import _jit
from ..dynamics._reduced_kernel import (
    Constants,
    Flat,
    _closure,
    _home_of,
    _newton_step,
    _proximal,
    _row_terms,
    _solve_acceleration,
    _turned,
    flat,
)
from ..dynamics._tuple_kernel import (
    SMALL_ANGLE,
    Mat,
    _angle_cos_sin,
    _cos_sin,
    _first_round,
    _first_suffices,
    _mat_of,
    _mat_vecs,
    _put_mat,
    _quadrant_cos_sin,
    _small_cos_sin,
)
from ._dynamic_kernel import (
    _ANGLE_BOUND,
    _SPEED_BOUND,
    _TORQUE_BOUND,
    Servo,
    Vec,
    _clip_torque,
    _finite_mat,
    _load,
    _servo,
    _within,
    finish,
)
from ._dynamic_kernel import KERNELS as DYNAMIC_KERNELS
from ._kinematic_kernel import Cover, _clip

__all__ = ["BLOCK", "KERNELS", "period", "step"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Robots stepped together (a multiple of the vector width: 4 doubles with AVX2, 8
#: with AVX-512).
BLOCK = 16

# The rows of the scratch array (each BLOCK robots long): input angles, speeds, the
# rotation (by rows), the servos' goals at the period's start, their speeds, the
# torques asked for, cos then sin of the input angles, the proximal axes (by rows),
# the torque, Newton's residual, "still turning" (1.0 or 0.0), "the step is taken"
# (1.0 or 0.0), the turn's angle, its axis, its cos and sin, the steps done (-1.0: a
# lane without a robot), the largest servo load, the speed the torque was applied at.
_TH, _SP, _RR, _GS, _GV, _WT, _CS, _WW = 0, 3, 6, 15, 18, 21, 24, 30
_TAU, _RES, _ACT, _OK, _ANG, _AX, _CN, _SN = 39, 42, 43, 44, 45, 46, 49, 50
_DONE, _LOAD, _TSP = 51, 52, 53
#: Rows of the scratch array.
ROWS = 56


def _u(index: int) -> Any:
    """An index as an unsigned integer: numba then does not wrap negative indices
    (a choice of two addresses that LLVM cannot follow)."""
    return np.uint64(index)


def _ld(S: FloatArray, row: int, i: int) -> float:
    """Robot i's entry of a row."""
    return float(S[_u(row * BLOCK + i)])


def _ld3(S: FloatArray, row: int, i: int) -> Vec:
    """Robot i's entries of three rows from ``row``."""
    return (S[_u(row * BLOCK + i)], S[_u((row + 1) * BLOCK + i)], S[_u((row + 2) * BLOCK + i)])


def _ldm(S: FloatArray, row: int, i: int) -> Mat:
    """Robot i's 3 x 3 matrix, by rows, from ``row``."""
    return (_ld3(S, row, i), _ld3(S, row + 3, i), _ld3(S, row + 6, i))


def _st(S: FloatArray, row: int, i: int, value: float) -> None:
    """Write robot i's entry of a row."""
    S[_u(row * BLOCK + i)] = value


def _st3(S: FloatArray, row: int, i: int, x: Vec) -> None:
    """Write robot i's entries of three rows from ``row``."""
    S[_u(row * BLOCK + i)] = x[0]
    S[_u((row + 1) * BLOCK + i)] = x[1]
    S[_u((row + 2) * BLOCK + i)] = x[2]


def _stm(S: FloatArray, row: int, i: int, m: Mat) -> None:
    """Write robot i's 3 x 3 matrix, by rows, from ``row``."""
    _st3(S, row, i, m[0])
    _st3(S, row + 3, i, m[1])
    _st3(S, row + 6, i, m[2])


def _pick3(take: bool, a: Vec, b: Vec) -> Vec:
    """a if take else b, entry by entry (a choice, not a branch)."""
    return (a[0] if take else b[0], a[1] if take else b[1], a[2] if take else b[2])


@_jit.standalone
def _trig_pass(S: FloatArray, row: int, out: int) -> None:
    """cos then sin of three rows from ``row`` into six rows from ``out``, as
    :func:`~spm_pin.dynamics._tuple_kernel._angle_cos_sin` gives them: its first round
    and kernels in one vectorised loop, then the whole function for the angles that
    need more (rare)."""
    redo = 0
    for i in range(BLOCK):
        for j in range(3):
            angle = _ld(S, row + j, i)
            n, r, w = _first_round(angle)
            c, s = _quadrant_cos_sin(n, r, w)
            _st(S, out + j, i, c)
            _st(S, out + 3 + j, i, s)
            redo += 0 if _first_suffices(angle, r, w) else 1
    if redo == 0:
        return
    for i in range(BLOCK):
        for j in range(3):
            angle = _ld(S, row + j, i)
            n, r, w = _first_round(angle)
            if not _first_suffices(angle, r, w):
                c, s = _angle_cos_sin(angle)
                _st(S, out + j, i, c)
                _st(S, out + 3 + j, i, s)


@_jit.standalone
def _drive_pass(
    S: FloatArray, offset: float, position: bool, servo: Servo, full: float, f: Flat
) -> None:
    """The torque within the envelope, the dynamics' input checks and the proximal
    axes: :func:`~spm_pin.envs._dynamic_kernel._physics_step` up to its rotation."""
    stall, no_load = servo[2], servo[3]
    for i in range(BLOCK):
        th, sp, R = _ld3(S, _TH, i), _ld3(S, _SP, i), _ldm(S, _RR, i)
        goal, speed = _ld3(S, _GS, i), _ld3(S, _GV, i)
        driven = (
            _servo(goal[0], speed[0], offset, th[0], sp[0], servo),
            _servo(goal[1], speed[1], offset, th[1], sp[1], servo),
            _servo(goal[2], speed[2], offset, th[2], sp[2], servo),
        )
        raw = _pick3(position, driven, _ld3(S, _WT, i))
        tau = (
            _clip_torque(raw[0], sp[0], stall, no_load),
            _clip_torque(raw[1], sp[1], stall, no_load),
            _clip_torque(raw[2], sp[2], stall, no_load),
        )
        good = (
            _within(th, _ANGLE_BOUND)
            and _within(sp, _SPEED_BOUND)
            and _within(tau, _TORQUE_BOUND)
            and _finite_mat(R)
            and _ld(S, _DONE, i) == full
        )
        _st(S, _OK, i, 1.0 if good else 0.0)
        _st(S, _ACT, i, 1.0 if good else 0.0)
        _st(S, _RES, i, math.inf)
        _stm(S, _WW, i, _proximal(_ld3(S, _CS, i), _ld3(S, _CS + 3, i), f[0], f[1]))
        _st3(S, _TAU, i, tau)


@_jit.standalone
def _newton_pass(S: FloatArray, cos_a2: float, stop: float, v0: Mat) -> int:
    """One iteration of :func:`~spm_pin.dynamics._reduced_kernel._newton` up to the
    turn's cos and sin, for the robots still turning: the residual, whether they go
    on, the turn's axis and angle. Returns how many go on."""
    going = 0
    for i in range(BLOCK):
        w = _ldm(S, _WW, i)
        v, r, residual = _closure(_ldm(S, _RR, i), w, v0, cos_a2)
        turning = _ld(S, _ACT, i) > 0.5
        _st(S, _RES, i, residual if turning else _ld(S, _RES, i))
        turning = turning and not residual <= stop
        _st(S, _ACT, i, 1.0 if turning else 0.0)
        going += 1 if turning else 0
        axis, angle = _newton_step(w, v, r)
        _st3(S, _AX, i, axis)
        _st(S, _ANG, i, angle if turning else 0.0)
    return going


@_jit.standalone
def _turn_pass(S: FloatArray) -> None:
    """Turn the rotation of each robot still turning about its axis (each column)."""
    for i in range(BLOCK):
        R = _ldm(S, _RR, i)
        turned = _turned(R, _ld3(S, _AX, i), _ld(S, _CN, i), _ld(S, _SN, i))
        if _ld(S, _ACT, i) > 0.5:
            R = turned
        _stm(S, _RR, i, R)


@_jit.standalone
def _euler_pass(
    S: FloatArray, P: FloatArray, step: int, dt: float, servo: Servo, full: float, f: Flat
) -> None:
    """The home sign rule (:func:`~spm_pin.dynamics._reduced_kernel._home_of`, of the
    terms' b and det A), the accelerations (no friction), the semi-implicit Euler step
    and the records; a robot whose step is not taken keeps its state and has its
    steps done set."""
    home_sign, sign_tol, tol = f[16], f[17], f[19]
    stall, no_load = servo[2], servo[3]
    base = (step + 1) * 3 * BLOCK
    for i in range(BLOCK):
        R, w = _ldm(S, _RR, i), _ldm(S, _WW, i)
        residual = _ld(S, _RES, i)
        th, sp, tau = _ld3(S, _TH, i), _ld3(S, _SP, i), _ld3(S, _TAU, i)
        cos, sin = _ld3(S, _CS, i), _ld3(S, _CS + 3, i)
        v = _mat_vecs(R, f[2])
        singular, det, M, c, g, _, _, _, _, _, b = _row_terms(cos, sin, w, v, sp, R, f, True)
        home = _home_of(b, det, home_sign, sign_tol)  # b, det A: as _home_rule's
        settled = math.isfinite(residual) and residual <= tol and home
        acc = _solve_acceleration(M, c, g, (0.0, 0.0, 0.0), tau)
        r = (sp[0] + dt * acc[0], sp[1] + dt * acc[1], sp[2] + dt * acc[2])
        t = (th[0] + dt * r[0], th[1] + dt * r[1], th[2] + dt * r[2])
        taken = _ld(S, _OK, i) > 0.5 and settled and not singular
        value = _load(tau, sp, stall, no_load)
        load = _ld(S, _LOAD, i)
        if taken and not load > value:  # np.maximum(load, value)
            load = value
        _st(S, _LOAD, i, load)
        _st3(S, _TSP, i, _pick3(taken, sp, _ld3(S, _TSP, i)))
        _st3(S, _TH, i, _pick3(taken, t, th))
        _st3(S, _SP, i, _pick3(taken, r, sp))
        P[_u(base + i)] = t[0]
        P[_u(base + BLOCK + i)] = t[1]
        P[_u(base + 2 * BLOCK + i)] = t[2]
        done = _ld(S, _DONE, i)
        _st(S, _DONE, i, float(step) if not taken and done == full else done)


@_jit.standalone
def period(
    S: FloatArray,
    P: FloatArray,
    lanes: int,
    position: bool,
    servo: Servo,
    dt: float,
    substeps: int,
    f: Flat,
) -> None:
    """The physics steps of one control period of a block, semi-implicit Euler,
    without friction, in place.

    Args:
        S: The scratch array (:data:`ROWS` x :data:`BLOCK`), with each robot's input
            angles, speeds, rotation (the warm start), the servos' goals at the
            period's start and their speeds (``"position"``) or the torques asked for
            (``"torque"``); on return its state after the steps it completed (its
            rotation: at the start of the last one), the last step's torque, the speed
            it was applied at, the largest servo load and the steps done (``substeps``
            when all were).
        P: (substeps + 1) x 3 x :data:`BLOCK`: the input angles after each step, from
            step 1 on.
        lanes: The robots in the block (the lanes after them hold a copy of a robot,
            and are not stepped).
        position, servo, dt, substeps: As :func:`~spm_pin.envs._dynamic_kernel.period`.
        f: The reduced dynamics' constants (:func:`~spm_pin.dynamics._reduced_kernel.
            flat`).
    """
    full = float(substeps)
    v0, cos_a2, stop, iterations = f[2], f[13], 0.1 * f[19], f[20]
    for i in range(BLOCK):
        _st(S, _DONE, i, full if i < lanes else -1.0)
        _st(S, _LOAD, i, 0.0)
    for step in range(substeps):
        _trig_pass(S, _TH, _CS)
        _drive_pass(S, step * dt, position, servo, full, f)
        for _ in range(iterations):
            if _newton_pass(S, cos_a2, stop, v0) == 0:
                break
            # the turns' cos and sin as _cos_sin gives them: the series in one
            # vectorised loop, then _cos_sin where the angle is beyond its range (rare)
            for i in range(BLOCK):
                c, s = _small_cos_sin(_ld(S, _ANG, i))
                _st(S, _CN, i, c)
                _st(S, _SN, i, s)
            for i in range(BLOCK):
                angle = _ld(S, _ANG, i)
                if not abs(angle) < SMALL_ANGLE:
                    c, s = _cos_sin(angle)
                    _st(S, _CN, i, c)
                    _st(S, _SN, i, s)
            _turn_pass(S)
        _euler_pass(S, P, step, dt, servo, full, f)


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
    """:func:`~spm_pin.envs._dynamic_kernel.step` (the same arguments and results, bit
    for bit), a block of :data:`BLOCK` robots at a time (:func:`period`). Semi-implicit
    Euler without joint friction only: with rk4 or friction every robot is handed back
    (the caller takes :func:`~spm_pin.envs._dynamic_kernel.step` for those)."""
    f = flat(k)
    if rk4 or f[15] > 0.0:  # not written in lanes: the caller takes step_robots
        handed[:] = True
        return
    max_speed, dv, limit = motion[0], motion[1], flags[0] != 0
    S = np.zeros(ROWS * BLOCK)
    P = np.zeros((substeps + 1) * 3 * BLOCK)
    a = np.empty((BLOCK, 3))
    start_goal = np.empty((BLOCK, 3))
    goal_speed = np.empty((BLOCK, 3))
    # The ends of a block's robots that completed their period, in one call of
    # finish: their rows, actions, goals and state, packed in the lanes' order.
    ended = np.zeros(BLOCK, dtype=np.int64)
    lane = np.zeros(BLOCK, dtype=np.int64)
    a_end = np.empty((BLOCK, 3))
    goal_end = np.empty((BLOCK, 3))
    speed_end = np.empty((BLOCK, 3))
    th = np.empty((BLOCK, 3))
    sp = np.empty((BLOCK, 3))
    rot = np.empty((BLOCK, 3, 3))
    path = np.empty((substeps + 1, BLOCK, 3))
    result = np.empty((BLOCK, out.shape[1]))
    back = np.zeros(BLOCK, dtype=np.bool_)
    n = rows.shape[0]
    for first in range(0, n, BLOCK):
        lanes = min(BLOCK, n - first)
        for i in range(BLOCK):
            m = first + (i if i < lanes else 0)  # a lane without a robot copies one
            r = rows[m]
            for j in range(3):
                aj = _clip(action[m, j], -1.0, 1.0)
                a[i, j] = aj
                command = aj * max_speed
                if limit:
                    command = _clip(command, servo_speed[r, j] - dv, servo_speed[r, j] + dv)
                goal_speed[i, j] = command if position else servo_speed[r, j]
                start_goal[i, j] = servo_goal[r, j]
                _st(S, _WT + j, i, aj * servo[2])
                _st(S, _GS + j, i, servo_goal[r, j])
                _st(S, _GV + j, i, goal_speed[i, j])
                _st(S, _TH + j, i, theta[r, j])
                _st(S, _SP + j, i, speed[r, j])
            _stm(S, _RR, i, _mat_of(R[r]))
        period(S, P, lanes, position, servo, dt, substeps, f)
        c = 0
        for i in range(lanes):
            m = first + i
            r = rows[m]
            if _ld(S, _DONE, i) < substeps:
                handed[m] = True
                continue
            ended[c] = r
            lane[c] = i
            _put_mat(rot[c], _ldm(S, _RR, i))
            for j in range(3):
                a_end[c, j] = a[i, j]
                goal_end[c, j] = start_goal[i, j]
                speed_end[c, j] = goal_speed[i, j]
                th[c, j] = _ld(S, _TH + j, i)
                sp[c, j] = _ld(S, _SP + j, i)
                path[0, c, j] = theta[r, j]
                for q in range(1, substeps + 1):
                    path[q, c, j] = P[_u((3 * q + j) * BLOCK + i)]
            c += 1
        if c == 0:
            continue
        finish(ended[:c], a_end[:c], path[0, :c], th[:c], sp[:c], rot[:c], path[:, :c],
               goal_end[:c], speed_end[:c], theta, speed, R, goal, hold, steps, servo_goal,
               servo_speed, position, substeps, motion, flags, weights, low, high, cover,
               k, result[:c], back[:c], counts)  # fmt: skip
        for e in range(c):
            i = lane[e]
            m = first + i
            r = ended[e]
            handed[m] = back[e]
            if not back[e]:
                for j in range(out.shape[1]):
                    out[m, j] = result[e, j]
                tq, tq_speed = _ld3(S, _TAU, i), _ld3(S, _TSP, i)
                for j in range(3):
                    torque[r, j] = tq[j]
                    torque_speed[r, j] = tq_speed[j]
                servo_load[r] = _ld(S, _LOAD, i)


#: The kernels, callees first: what :func:`spm_pin._jit.kernels` compiles with
#: ``lanes=True``, after the plain family of
#: :data:`~spm_pin.envs._dynamic_kernel.KERNELS`: the physics' callees (every one
#: inlined), not the end of a period (:func:`~spm_pin.envs._dynamic_kernel.finish`,
#: called robot by robot: the plain twin).
KERNELS = (
    *(kernel for kernel in DYNAMIC_KERNELS if kernel is not finish),
    _u,
    _ld,
    _ld3,
    _ldm,
    _st,
    _st3,
    _stm,
    _pick3,
    _trig_pass,
    _drive_pass,
    _newton_pass,
    _turn_pass,
    _euler_pass,
    period,
    step,
)
