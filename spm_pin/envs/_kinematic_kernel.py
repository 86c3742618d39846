r"""One step of :class:`~spm_pin.envs._core.OrientCore`'s robots in one call, with the
safety check answered by a saved cover's certified cells, in a form that numba
compiles (:func:`spm_pin._jit.kernels` of :data:`KERNELS`).

:meth:`OrientCore.step_rows <spm_pin.envs._core.OrientCore.step_rows>` in numpy costs
a few dozen array calls per step plus the safety check; with a cover
(:class:`~spm_pin.envs._safe_lookup.SafeLookup`) most checks are a table lookup, and
what is left is numpy's overhead and the forward kinematics of the batch. Here each
robot's step is taken in floats, the operations of the numpy path in its order:

* the action clipped to [-1, 1], times the speed limit, kept within the acceleration
  limit of the last command;
* the safety check of the step's end: the joint limits, then the cover's certified
  cells (the gaps of :meth:`~spm_pin.planning.SafeSet.gaps_of`, the root cell by
  index, a finer cell by a bit of its root's bitmap, or below the bitmap's depth by
  a binary search in its level's sorted keys, as :meth:`SafeLookup.covered
  <spm_pin.envs._safe_lookup.SafeLookup.covered>`);
* the safety clip's bisection (``"clip"``) or the end of the episode
  (``"terminate"``);
* the platform rotation by Newton's method from the robot's last rotation (the
  reduced dynamics' warm start, :func:`~spm_pin.dynamics._reduced_kernel.
  home_rotation_of`: the closure to 1e-13 and the home sign rule), the orientation
  error, the goal counter, the ends and the reward.

A robot whose step needs what the kernel does not do (a state outside the certified
cells that must be checked, when the cover is not the whole safe set; a rotation the
warm start does not settle) is left untouched and flagged: the numpy path steps it.
The rotation agrees with the numpy path's forward kinematics to about 1e-15 (a
different Newton); everything else is the same arithmetic. Nothing here checks its
arguments: the caller passes C-contiguous arrays of the right types.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .. import _jit
from ..dynamics._reduced_kernel import KERNELS as REDUCED_KERNELS
from ..dynamics._reduced_kernel import home_rotation_of
from ..dynamics._tuple_kernel import Mat, Vec

__all__ = [
    "CELLS",
    "CHECK",
    "GAP12",
    "GAP23",
    "HEADER",
    "KERNELS",
    "LEVELS",
    "ROOTS",
    "ROOT_SIDE",
    "SAFE",
    "TABLE",
    "TABLE_ROW",
    "UNSAFE",
    "WORDS",
    "WORD_BITS",
    "WORD_SHIFT",
    "covered",
    "covered_rows",
    "step",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
#: A cover as one array (:func:`covered`): a single array, so a check inlined into a
#: loop takes and drops one reference, not one per part.
Cover = FloatArray
#: A root cell of :func:`covered`'s index that is covered whole, or that holds no
#: covered cell down to the bitmaps' depth.
ROOT_COVERED = -2
ROOT_EMPTY = -1
#: The cover's header (:func:`covered`): eta_2 - eta_1, eta_3 - eta_2 [deg], the root
#: cells' side [deg], the bitmaps' cells per root side (2**depth), the root cells per
#: side n, where the words start, how many levels are searched and where their table
#: starts. The index follows the header.
HEADER = 8
GAP12, GAP23, ROOT_SIDE, CELLS, ROOTS, WORDS, LEVELS, TABLE = range(HEADER)
#: Bits of a bitmap's word (an integer below 2**32 in a float: exact).
WORD_BITS = 32
#: A bit's word is bit >> WORD_SHIFT.
WORD_SHIFT = WORD_BITS.bit_length() - 1
#: Entries of a searched level in the cover's table: the cells' side, the lattice
#: size, where its keys start and where they end.
TABLE_ROW = 4

#: Verdicts of :func:`_verdict`: outside the joint limits, or (cover only) outside
#: the certified cells.
UNSAFE = 0
#: Within the joint limits and in a certified cell.
SAFE = 1
#: Within the joint limits, outside the certified cells: the safe set decides.
CHECK = 2
#: Radians to degrees, as ``np.degrees``.
_DEGREES = 180.0 / math.pi


def _search(keys: FloatArray, start: int, end: int, key: float) -> bool:
    """Whether ``key`` is among ``keys[start:end]`` (sorted)."""
    low, high = start, end
    while low < high:
        middle = (low + high) // 2
        if keys[middle] < key:
            low = middle + 1
        else:
            high = middle
    return low < end and keys[low] == key


@_jit.inline
def _mod360(x: float) -> float:
    """``x % 360.0`` (Python's, the same bits), without a call to ``fmod`` for x in
    [-360, 360): there ``fmod`` gives x itself, and ``%`` adds 360 below 0 (and
    turns -0.0 into 0.0)."""
    if x >= 0.0 and x < 360.0:
        return x + 0.0  # -0.0 + 0.0 is 0.0
    if x >= -360.0 and x < 0.0:
        return x + 360.0
    return x % 360.0


# covered and _verdict are inlined into the kernels' loops over robots. Each array
# they are given is still referenced and released at each check (two atomic counts),
# so the cover is one array: as seven, the counts took about a tenth of a batched
# kinematic step
@_jit.inline
def covered(t0: float, t1: float, t2: float, cover: Cover) -> bool:
    """Whether the gaps of the input (t0, t1, t2) [rad] lie in a certified cell.

    Args:
        cover: The cover, one float array (integers in it are exact):
            the header (:data:`HEADER` entries, see :data:`GAP12` to :data:`TABLE`);
            the index, per root cell (n x n, row-major) :data:`ROOT_COVERED`,
            :data:`ROOT_EMPTY`, or where its bitmap starts among the words;
            the words, a root's 4**depth bits (its cells at ``depth``, row-major; a
            bit is set where a covered cell of any level down to ``depth`` holds that
            cell), :data:`WORD_BITS` to a word;
            the table, per level deeper than ``depth`` with covered cells: the cells'
            side [deg], the lattice size (keys are i * size + j), and where its
            sorted keys start and end;
            the keys.

    A cell's index at each level is floor(d / a * 2**level), d a gap and a the root
    side: halving a side scales the quotient exactly, so a bitmap's cell lies in the
    cell of each coarser level that its lattice says.
    """
    deg0, deg1, deg2 = t0 * _DEGREES, t1 * _DEGREES, t2 * _DEGREES
    d12 = _mod360(cover[GAP12] - (deg1 - deg0))
    d23 = _mod360(cover[GAP23] - (deg2 - deg1))
    n = int(cover[ROOTS])
    a = d12 / cover[ROOT_SIDE]
    b = d23 / cover[ROOT_SIDE]
    if not (a >= 0.0 and a < n and b >= 0.0 and b < n):  # NaN: outside
        return False
    i, j = int(a), int(b)  # int() of a number >= 0: its floor
    code = int(cover[HEADER + i * n + j])
    if code == ROOT_COVERED:
        return True
    if code >= 0:
        cells_f = cover[CELLS]
        cells = int(cells_f)
        bit = (int(a * cells_f) - i * cells) * cells + (int(b * cells_f) - j * cells)
        word = int(cover[int(cover[WORDS]) + code + (bit >> WORD_SHIFT)])
        if (word >> (bit & (WORD_BITS - 1))) & 1:
            return True
    table = int(cover[TABLE])
    for level in range(int(cover[LEVELS])):
        row = table + TABLE_ROW * level
        side = cover[row]
        key = math.floor(d12 / side) * cover[row + 1] + math.floor(d23 / side)
        if _search(cover, int(cover[row + 2]), int(cover[row + 3]), key):
            return True
    return False


def covered_rows(theta: FloatArray, cover: Cover, out: BoolArray) -> None:
    """:func:`covered` of each input (n, 3) [rad] into ``out`` (n,)."""
    for m in range(theta.shape[0]):
        out[m] = covered(theta[m, 0], theta[m, 1], theta[m, 2], cover)


@_jit.inline
def _verdict(x: Vec, low: FloatArray, high: FloatArray, only: bool, cover: Cover) -> int:
    """:data:`UNSAFE`, :data:`SAFE` or :data:`CHECK` for the input x [rad]."""
    for m in range(3):
        if not (x[m] >= low[m] and x[m] <= high[m]):
            return UNSAFE
    if covered(x[0], x[1], x[2], cover):
        return SAFE
    return UNSAFE if only else CHECK


def _clip(x: float, low: float, high: float) -> float:
    """``np.clip`` of a finite float."""
    return min(max(x, low), high)


def step(
    rows: IntArray,
    action: FloatArray,
    theta: FloatArray,
    speed: FloatArray,
    R: FloatArray,
    goal: FloatArray,
    hold: IntArray,
    steps: IntArray,
    motion: FloatArray,
    flags: IntArray,
    weights: FloatArray,
    low: FloatArray,
    high: FloatArray,
    cover: Cover,
    design: FloatArray,
    solve: FloatArray,
    out: FloatArray,
    handed: BoolArray,
    counts: IntArray,
) -> None:
    """Step ``rows`` of the state arrays in place with the actions (n, 3).

    Args:
        rows: The robots stepped (n,).
        action: Their actions (n, 3), finite.
        theta, speed, R, goal, hold, steps: The core's state of every robot
            (N, 3), (N, 3), (N, 3, 3), (N, 3, 3), (N,), (N,); the rows stepped here
            are written.
        motion: (max speed [rad/s], speed change per period [rad/s], period [s],
            orientation tolerance [rad]).
        flags: (limit the acceleration, clip (else terminate), bisection steps,
            hold steps, cover only).
        weights: (orientation, effort, clip, success, unsafe).
        low, high: The joint limits [rad] (3,).
        cover: The cover's arrays (:func:`covered`).
        design: (9, 3): the rows u, w0, v0 of the design.
        solve: (cos a2, sign of det A at home, sign tolerance, closure tolerance,
            Newton iterations).
        out: (n, 5): reward, orientation error, step fraction, and 1.0 / 0.0 for
            success and unsafe, of the rows stepped.
        handed: (n,) True where the row was not stepped (the numpy path steps it).
        counts: (2,): safety checks asked, and settled by the cover, of the rows
            stepped, added to.
    """
    max_speed, dv, period, tolerance = motion[0], motion[1], motion[2], motion[3]
    limit, clip, iterations = flags[0] != 0, flags[1] != 0, flags[2]
    hold_steps, only = flags[3], flags[4] != 0
    u: Mat = (
        (design[0, 0], design[0, 1], design[0, 2]),
        (design[1, 0], design[1, 1], design[1, 2]),
        (design[2, 0], design[2, 1], design[2, 2]),
    )
    w0: Mat = (
        (design[3, 0], design[3, 1], design[3, 2]),
        (design[4, 0], design[4, 1], design[4, 2]),
        (design[5, 0], design[5, 1], design[5, 2]),
    )
    v0: Mat = (
        (design[6, 0], design[6, 1], design[6, 2]),
        (design[7, 0], design[7, 1], design[7, 2]),
        (design[8, 0], design[8, 1], design[8, 2]),
    )
    for m in range(rows.shape[0]):
        r = rows[m]
        a0 = _clip(action[m, 0], -1.0, 1.0)
        a1 = _clip(action[m, 1], -1.0, 1.0)
        a2 = _clip(action[m, 2], -1.0, 1.0)
        c0, c1, c2 = a0 * max_speed, a1 * max_speed, a2 * max_speed
        if limit:
            c0 = _clip(c0, speed[r, 0] - dv, speed[r, 0] + dv)
            c1 = _clip(c1, speed[r, 1] - dv, speed[r, 1] + dv)
            c2 = _clip(c2, speed[r, 2] - dv, speed[r, 2] + dv)
        t0, t1, t2 = theta[r, 0], theta[r, 1], theta[r, 2]
        s0, s1, s2 = c0 * period, c1 * period, c2 * period
        verdict = _verdict((t0 + s0, t1 + s1, t2 + s2), low, high, only, cover)
        asked, settled = 1, int(verdict == SAFE)
        fraction, unsafe = 1.0, False
        if verdict == UNSAFE:
            fraction = 0.0
            if clip:
                lo, hi = 0.0, 1.0
                for _ in range(iterations):
                    middle = 0.5 * (lo + hi)
                    x = (t0 + middle * s0, t1 + middle * s1, t2 + middle * s2)
                    verdict = _verdict(x, low, high, only, cover)
                    asked += 1
                    settled += int(verdict == SAFE)
                    if verdict == CHECK:
                        break
                    if verdict == SAFE:
                        lo = middle
                    else:
                        hi = middle
                fraction = lo
            else:
                unsafe = True
        if verdict == CHECK:
            handed[m] = True
            continue
        x = (t0 + fraction * s0, t1 + fraction * s1, t2 + fraction * s2)
        start: Mat = (
            (R[r, 0, 0], R[r, 0, 1], R[r, 0, 2]),
            (R[r, 1, 0], R[r, 1, 1], R[r, 1, 2]),
            (R[r, 2, 0], R[r, 2, 1], R[r, 2, 2]),
        )
        ok, rotation = home_rotation_of(
            x, start, u, w0, v0, solve[0], solve[1], solve[2], solve[3], int(solve[4])
        )
        if not ok:
            handed[m] = True
            continue
        counts[0] += asked
        counts[1] += settled
        velocity = (fraction * c0, fraction * c1, fraction * c2)
        _enter(r, m, x, velocity, rotation, (a0, a1, a2), fraction, unsafe, theta, speed, R,
               goal, hold, steps, tolerance, hold_steps, weights, out)  # fmt: skip
        handed[m] = False


def _enter(
    r: int,
    m: int,
    x: Vec,
    velocity: Vec,
    rotation: Mat,
    a: Vec,
    fraction: float,
    unsafe: bool,
    theta: FloatArray,
    speed: FloatArray,
    R: FloatArray,
    goal: FloatArray,
    hold: IntArray,
    steps: IntArray,
    tolerance: float,
    hold_steps: int,
    weights: FloatArray,
    out: FloatArray,
) -> None:
    """Enter robot ``r``'s state after its step, the ``m``-th of the call, as
    :meth:`OrientCore.settle <spm_pin.envs._core.OrientCore.settle>` does: input
    angles x [rad], speeds [rad/s], the rotation; the orientation error, the goal
    counter and the reward of the clipped action a, a ``fraction`` of the step taken
    (``unsafe``: ended by the guard), into ``out[m]`` (see :func:`step`)."""
    total = 0.0
    for i in range(3):
        for j in range(3):
            d = rotation[i][j] - goal[r, i, j]
            total += d * d
    error = 2.0 * math.asin(min(math.sqrt(total) / math.sqrt(8.0), 1.0))
    held = hold[r] + 1 if error <= tolerance else 0
    success = held >= hold_steps
    effort = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]) / 3.0
    reward = (
        -weights[0] * error
        - weights[1] * effort
        - weights[2] * (1.0 - fraction) * (0.0 if unsafe else 1.0)
        + weights[3] * (1.0 if success else 0.0)
        - weights[4] * (1.0 if unsafe else 0.0)
    )
    for i in range(3):
        for j in range(3):
            R[r, i, j] = rotation[i][j]
        theta[r, i] = x[i]
        speed[r, i] = velocity[i]
    hold[r] = held
    steps[r] = steps[r] + 1
    out[m, 0] = reward
    out[m, 1] = error
    out[m, 2] = fraction
    out[m, 3] = 1.0 if success else 0.0
    out[m, 4] = 1.0 if unsafe else 0.0


#: The kernels, callees first: what :func:`spm_pin._jit.kernels` compiles.
KERNELS = (*REDUCED_KERNELS, _search, _mod360, covered, covered_rows, _verdict, _clip, _enter, step)
