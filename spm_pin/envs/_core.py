"""The batched kinematic core that both orientation environments step.

One :class:`OrientCore` holds N robots as arrays: input angles theta (N, 3) [rad],
commanded speeds (N, 3) [rad/s], platform rotations (N, 3, 3), goals (N, 3, 3), the
counters of each episode. The single environment is a core of one robot, the vector
environment a core of N, so both run the same arithmetic. Each robot draws its
episodes (start, goal, observation noise) from its own random generator, in the same
order in both.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from .. import _jit
from ..dynamics.reduced import _NEWTON_ITERATIONS, REDUCED_CLOSURE_TOL
from ..errors import InputError
from ..kinematics import forward_kinematics
from ..kinematics.fk import _SIGN_TOL
from ..planning import SafeSet, safe_set_of
from . import _kinematic_kernel, _observe_kernel
from ._calibration_error import BelievedModels
from ._safe_lookup import SafeLookup
from .settings import OrientSettings

__all__ = ["OBSERVATION_SIZE", "OrientCore", "StepOne", "StepResult", "geodesic_angle"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.intp]

#: The rows of a single environment's robot.
_ROW = np.array([0], dtype=np.intp)

#: Platform rotation (6), goal (6), sin and cos of the inputs (6), speeds (3).
OBSERVATION_SIZE = 21
#: Observed entries that carry noise: all but the goal's six.
_NOISY = np.r_[0:6, 12:21]


def geodesic_angle(R: FloatArray, G: FloatArray) -> FloatArray:
    """The angle [rad] of the rotation between R and G, (..., 3, 3) each:
    2 arcsin(|R - G|_F / sqrt(8)) (well conditioned near 0, unlike the arccos of the
    trace)."""
    norm = np.sqrt(np.sum((R - G) ** 2, axis=(-2, -1)))
    angle: FloatArray = 2.0 * np.arcsin(np.minimum(norm / math.sqrt(8.0), 1.0))
    return angle


def six_d(R: FloatArray) -> FloatArray:
    """The continuous 6-D form of rotations (..., 3, 3): the first two columns,
    column after column, (..., 6)."""
    cols: FloatArray = np.concatenate([R[..., :, 0], R[..., :, 1]], axis=-1)
    return cols


@dataclasses.dataclass(frozen=True)
class StepResult:
    """What one step of the rows that stepped gives.

    Attributes:
        reward: (n,).
        terminated: (n,) at the goal for ``hold_steps``, or stopped by an unsafe step.
        truncated: (n,) ``max_steps`` reached.
        error: (n,) orientation error after the step [rad].
        fraction: (n,) fraction of the commanded step that was taken.
        success: (n,) the goal was held.
        unsafe: (n,) an unsafe step ended the episode.
    """

    reward: FloatArray
    terminated: BoolArray
    truncated: BoolArray
    error: FloatArray
    fraction: FloatArray
    success: BoolArray
    unsafe: BoolArray


class StepOne(NamedTuple):
    """What one step of a single robot gives (:class:`StepResult`'s fields, as
    Python numbers)."""

    reward: float
    terminated: bool
    truncated: bool
    error: float
    fraction: float
    success: bool
    unsafe: bool

    @classmethod
    def of(cls, result: StepResult) -> StepOne:
        """Row 0 of ``result``."""
        return cls(
            float(result.reward[0]),
            bool(result.terminated[0]),
            bool(result.truncated[0]),
            float(result.error[0]),
            float(result.fraction[0]),
            bool(result.success[0]),
            bool(result.unsafe[0]),
        )


class OrientCore:
    """N kinematic robots stepped as numpy batches (see the module).

    Args:
        settings: The options.
        num: Number of robots.
    """

    #: The kernels of the compiled step (:meth:`_step_call`'s ``step``), and the name
    #: of the whole single step's family in :mod:`~spm_pin.envs._single_kernel`.
    STEP_KERNELS: tuple[Callable[..., Any], ...] = _kinematic_kernel.KERNELS
    SINGLE = "KINEMATIC"
    #: What a single environment's step adds to its info from the state of robot 0,
    #: in order: (info key, state attribute, size: 3 for an array (3,), 0 for a
    #: number) (:class:`~spm_pin.envs._single.SingleStep`).
    RECORD: tuple[tuple[str, str, int], ...] = (
        ("theta", "theta", 3),
        ("goal_theta", "goal_theta", 3),
    )

    def __init__(self, settings: OrientSettings, num: int) -> None:
        self.settings = settings
        self.design = settings.the_design
        self.limits = settings.the_limits
        self.safe_set: SafeSet = safe_set_of(self.design, settings.plan_settings)
        #: The certified cells of ``settings.cover`` (None without one).
        self.lookup: SafeLookup | None = None
        if settings.cover is not None:
            self.lookup = SafeLookup.from_file(self.safe_set, settings.cover)
        #: The cover's certified cells are the safe set (``settings.cover_only``).
        self.only = settings.cover_only
        #: Step with the compiled kernel (:mod:`~spm_pin.envs._kinematic_kernel`) where
        #: there is a cover and numba; False: always the numpy path.
        self.fused = True
        #: Rows the compiled kernel handed back to numpy so far.
        self.handed_rows = 0
        self._kernel: Any = None
        self._kernel_args: tuple[Any, ...] = ()
        self._observe: Any = None
        index = np.argwhere(self.safe_set.safe)
        #: The safe vertices of the gap plane (D12, D23 [deg]), (m, 2).
        self.vertices: FloatArray = np.stack(
            [self.safe_set.d12[index[:, 0]], self.safe_set.d23[index[:, 1]]], axis=-1
        )
        if self.only:
            self.vertices = self.vertices[self._in_cells(self.vertices)]
            if settings.start == "home" and not self.safe(np.zeros((1, 3)))[0]:
                raise InputError(
                    "start 'home' is beyond the joint limits or not in a cell the cover "
                    "certified (cover_only): fill the cover to a finer level, or start "
                    "at random",
                    argument="start",
                    value=settings.start,
                )
        if self.vertices.shape[0] == 0:
            raise InputError(
                f"design {self.design.name!r} has no safe state with these limits"
                + (" in the cells the cover certified (cover_only)" if self.only else ""),
                argument="limits",
                value=self.limits,
            )
        #: The diagonal of the safe vertices' bounding box [deg] (the curriculum's scale).
        self.max_gap_distance = float(np.hypot(*np.ptp(self.vertices, axis=0)))
        self.num = num
        self.level = settings.curriculum_level
        self.theta = np.zeros((num, 3))
        self.speed = np.zeros((num, 3))
        self.R = np.tile(np.eye(3), (num, 1, 1))
        self.goal = np.tile(np.eye(3), (num, 1, 1))
        self.goal_theta = np.zeros((num, 3))
        self.hold = np.zeros(num, dtype=np.intp)
        self.steps = np.zeros(num, dtype=np.intp)
        #: The models the robots' controllers believe (``calibration_error``), or None.
        self.believed: BelievedModels | None = None
        if settings.calibration_error.active:
            self.believed = BelievedModels(self.design, num, settings.calibration_error)
        fixed = np.asarray(settings.goal_theta, dtype=float)
        self._fixed_goal = fixed
        if settings.goal == "fixed":
            verdict = self.safe_set.evaluate(fixed[None])
            if not verdict.safe[0]:
                raise InputError(
                    f"goal_theta {np.degrees(fixed).round(3).tolist()} deg is not safe: "
                    + verdict.reason(0, self.safe_set.settings),
                    argument="goal_theta",
                    value=settings.goal_theta,
                )
            if self.only and not self.safe(fixed[None])[0]:
                raise InputError(
                    f"goal_theta {np.degrees(fixed).round(3).tolist()} deg is safe, but "
                    "not in a cell the cover certified (cover_only): fill the cover "
                    "to a finer level, or choose a goal further from the boundary",
                    argument="goal_theta",
                    value=settings.goal_theta,
                )

    def _in_cells(self, gaps: FloatArray) -> BoolArray:
        """Which gap-plane points (m, 2) [deg] lie inside certified cells: the four
        cells about each (a point on a cell's side counts as in the cell below it,
        so a turn about the axis, which moves the gaps by rounding, must not take it
        to the cell beyond)."""
        assert self.lookup is not None
        asked, settled = self.lookup.asked, self.lookup.settled
        inside = np.ones(gaps.shape[0], dtype=bool)
        for a in (-1e-6, 1e-6):
            for b in (-1e-6, 1e-6):
                theta = self.safe_set.theta_of(gaps[:, 0] + a, gaps[:, 1] + b, 0.0)
                inside &= self.lookup.covered(theta)
        self.lookup.asked, self.lookup.settled = asked, settled
        return inside

    # ---------------------------------------------------------------- episodes
    def _draw(self, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """(start, goal input angles) of one episode, drawn from ``rng``."""
        s = self.settings
        vertices = self.vertices
        if s.start == "home":
            start = np.zeros(3)
        else:
            k = int(rng.integers(vertices.shape[0]))
            start = self.safe_set.theta_of(
                vertices[k, 0], vertices[k, 1], rng.uniform(-math.pi, math.pi)
            )
        if s.goal == "fixed":
            return start, self._fixed_goal.copy()
        d12, d23, yaw = self.safe_set.gaps_of(start)
        if s.goal == "curriculum":
            distance = np.hypot(vertices[:, 0] - d12, vertices[:, 1] - d23)
            near = np.flatnonzero(distance <= self.level * self.max_gap_distance + 1e-9)
            if near.size == 0:  # the start lies off the grid: its nearest vertex
                near = np.array([int(np.argmin(distance))])
            k = int(near[rng.integers(near.size)])
            turn = self.level * rng.uniform(-math.pi, math.pi)
            goal = self.safe_set.theta_of(vertices[k, 0], vertices[k, 1], float(yaw) + turn)
        else:
            k = int(rng.integers(vertices.shape[0]))
            goal = self.safe_set.theta_of(
                vertices[k, 0], vertices[k, 1], rng.uniform(-math.pi, math.pi)
            )
        return start, goal

    def reset_rows(self, rows: IntArray, rngs: list[np.random.Generator]) -> None:
        """Start a new episode in each of ``rows``, drawn from its own generator."""
        if rows.size == 0:
            return
        drawn = [self._draw(rngs[int(i)]) for i in rows]
        start = np.stack([a for a, _ in drawn])
        goal = np.stack([b for _, b in drawn])
        both = forward_kinematics(np.concatenate([start, goal]), self.design)
        n = rows.size
        self.theta[rows] = start
        self.speed[rows] = 0.0
        self.R[rows] = both.R[:n]
        self.goal[rows] = both.R[n:]
        self.goal_theta[rows] = goal
        self.hold[rows] = 0
        self.steps[rows] = 0
        if self.believed is not None:  # after the start and the goal, robot by robot
            self.believed.draw(rows, rngs)

    # ---------------------------------------------------------------- safety
    def safe(self, theta: FloatArray) -> BoolArray:
        """The guard's static checks at input angles (n, 3): joint limits, then the
        safe set's checks (home assembly, singularity margin, dexterity, clearance).
        With a cover (``settings.cover``), the states within the joint limits whose
        gaps lie in a certified cell pass without the safe set's checks; the rest
        are checked."""
        low = np.asarray(self.limits.theta_min)
        high = np.asarray(self.limits.theta_max)
        ok = np.all((theta >= low) & (theta <= high), axis=-1)
        result = np.zeros(theta.shape[0], dtype=bool)
        rows = np.flatnonzero(ok)
        if rows.size and self.lookup is not None:
            certified = self.lookup.covered(theta[rows])
            result[rows[certified]] = True
            rows = rows[~certified]
            if self.only:
                return result
        if rows.size:
            result[rows] = self.safe_set.evaluate(theta[rows]).safe
        return result

    def _furthest_safe(self, theta: FloatArray, step: FloatArray) -> FloatArray:
        """Largest fraction s (bisection) with theta + s step safe, (n,); 0 when
        even the shortest tried step is unsafe."""
        low = np.zeros(theta.shape[0])
        high = np.ones(theta.shape[0])
        for _ in range(self.settings.clip_iterations):
            middle = 0.5 * (low + high)
            ok = self.safe(theta + middle[:, None] * step)
            low = np.where(ok, middle, low)
            high = np.where(ok, high, middle)
        return low

    # ---------------------------------------------------------------- stepping
    def command(self, a: FloatArray, previous: FloatArray) -> FloatArray:
        """Commanded speeds [rad/s] of normalised actions ``a`` (n, 3) in [-1, 1]: times
        ``max_speed``, with ``limit_acceleration`` kept within the guard's acceleration
        of the ``previous`` command (n, 3) over one control period."""
        command = a * self.limits.max_speed
        if self.settings.limit_acceleration:
            dv = self.limits.max_acceleration * self.settings.control_period
            command = np.clip(command, previous - dv, previous + dv)
        return command

    def step_rows(self, rows: IntArray, action: FloatArray) -> StepResult:
        """Step ``rows`` with normalised actions (n, 3) in [-1, 1]: by the compiled
        kernel where it can (a cover, numba; :meth:`_kernel_counts`), the robots it
        hands back by :meth:`_hand_back`; else by :meth:`_step_plain`."""
        arguments = self._compiled_step()
        if arguments is None or rows.size == 0:
            return self._step_plain(rows, action)
        n = rows.size
        out = np.empty((n, 5))
        handed = np.zeros(n, dtype=bool)
        counts = self._kernel_counts(
            np.ascontiguousarray(rows, dtype=np.int64),
            np.ascontiguousarray(action, dtype=np.float64),
            out,
            handed,
            arguments,
        )
        return self.kernel_result(
            rows,
            out,
            handed,
            counts,
            lambda back: self._hand_back(rows[back], action[back]),
            count=False,
        )

    def _step_plain(self, rows: IntArray, action: FloatArray) -> StepResult:
        """:meth:`step_rows` without the compiled step: numpy."""
        return self._step_numpy(rows, action)

    def record_sources(self) -> tuple[FloatArray, ...]:
        """The arrays (N, k) of :data:`RECORD`'s entries, in its order (views)."""
        return tuple(getattr(self, name).reshape(self.num, -1) for _, name, _ in self.RECORD)

    def _kernel_counts(
        self,
        rows: IntArray,
        action: FloatArray,
        out: FloatArray,
        handed: BoolArray,
        arguments: tuple[Any, ...],
    ) -> IntArray:
        """:meth:`_call_step` of ``rows`` in one call; the cover's checks asked and
        settled (2,)."""
        counts = np.zeros(2, dtype=np.int64)
        self._call_step(rows, action, out, handed, counts, arguments)
        return counts

    def _call_step(
        self,
        rows: IntArray,
        action: FloatArray,
        out: FloatArray,
        handed: BoolArray,
        counts: IntArray,
        arguments: tuple[Any, ...],
    ) -> None:
        """The compiled step of ``rows`` (:meth:`_step_call`)."""
        kernel, args = self._step_call(rows, action, out, handed, counts, arguments)
        kernel(*args)

    def _step_call(
        self,
        rows: IntArray,
        action: FloatArray,
        out: FloatArray,
        handed: BoolArray,
        counts: IntArray,
        arguments: tuple[Any, ...],
    ) -> tuple[Any, tuple[Any, ...]]:
        """(the compiled :func:`~spm_pin.envs._kinematic_kernel.step`, its arguments
        for ``rows``)."""
        if self._kernel is None:
            self._kernel = _jit.kernels(_kinematic_kernel.KERNELS)["step"]
        args = (
            rows,
            action,
            self.theta,
            self.speed,
            self.R,
            self.goal,
            self.hold,
            self.steps,
            *arguments,
            out,
            handed,
            counts,
        )
        return self._kernel, args

    def _compiled_step(self) -> tuple[Any, ...] | None:
        """:meth:`fused_arguments` where :meth:`_call_step` applies, else None."""
        return self.fused_arguments()

    def _hand_back(self, rows: IntArray, action: FloatArray) -> StepResult:
        """Step ``rows`` that the compiled step handed back, by numpy (counted in
        ``handed_rows``)."""
        self.handed_rows += int(rows.size)
        return self._step_numpy(rows, action)

    def kernel_result(
        self,
        rows: IntArray,
        out: FloatArray,
        handed: BoolArray,
        counts: IntArray,
        rest: Callable[[IntArray], StepResult],
        *,
        count: bool = True,
    ) -> StepResult:
        """The step's result from a compiled kernel's ``out`` (n, 5) (reward, error,
        fraction, success, unsafe) and ``counts`` (the cover's checks asked and
        settled), with ``rest(back)`` stepping the rows it ``handed`` back (indices
        into ``rows``) by numpy; ``count``: add those rows to ``handed_rows``."""
        assert self.lookup is not None
        self.lookup.asked += int(counts[0])
        self.lookup.settled += int(counts[1])
        success = out[:, 3] != 0.0
        unsafe = out[:, 4] != 0.0
        terminated = success | unsafe
        truncated = (self.steps[rows] >= self.settings.max_steps) & ~terminated
        result = StepResult(out[:, 0], terminated, truncated, out[:, 1], out[:, 2], success, unsafe)
        if not handed.any():
            return result
        back = np.flatnonzero(handed)
        if count:
            self.handed_rows += int(back.size)
        numpy_rows = rest(back)
        for field in dataclasses.fields(StepResult):
            getattr(result, field.name)[back] = getattr(numpy_rows, field.name)
        return result

    def fused_arguments(self) -> tuple[Any, ...] | None:
        """The compiled step's arguments that do not change (motion, flags, weights,
        the joint limits, the cover's arrays, the design's rows, the rotation's
        constants: see :func:`~spm_pin.envs._kinematic_kernel.step`), made on first
        use; None where no compiled step applies (no cover, no numba, ``fused`` off,
        or state arrays it does not take)."""
        if not self.fused or self.lookup is None:
            return None
        if not self._kernel_args:
            if not _jit.available() or self.hold.dtype != np.int64:
                self.fused = False
                return None
            s, limits, design = self.settings, self.limits, self.design
            w = s.weights
            motion = np.array(
                [
                    limits.max_speed,
                    limits.max_acceleration * s.control_period,
                    s.control_period,
                    s.tolerance,
                ]
            )
            flags = np.array(
                [
                    int(s.limit_acceleration),
                    int(s.safety == "clip"),
                    s.clip_iterations,
                    s.hold_steps,
                    int(self.only),
                ],
                dtype=np.int64,
            )
            weights = np.array([w.orientation, w.effort, w.clip, w.success, w.unsafe])
            low = np.array(limits.theta_min, dtype=float).reshape(3)
            high = np.array(limits.theta_max, dtype=float).reshape(3)
            rows = np.concatenate([design.u, design.w0, design.v0]).astype(float)
            solve = np.array(
                [
                    math.cos(design.alpha2),
                    float(np.sign(design.home_det_a)),
                    float(_SIGN_TOL),
                    REDUCED_CLOSURE_TOL,  # the reduced dynamics' warm start, as it is
                    float(_NEWTON_ITERATIONS),
                ]
            )
            self._kernel_args = (
                motion,
                flags,
                weights,
                low,
                high,
                self.lookup.arrays(),
                np.ascontiguousarray(rows),
                solve,
            )
        return self._kernel_args

    def _step_numpy(self, rows: IntArray, action: FloatArray) -> StepResult:
        """:meth:`step_rows` in numpy."""
        s = self.settings
        a = np.clip(action, -1.0, 1.0)
        command = self.command(a, self.speed[rows])
        theta = self.theta[rows]
        step = command * s.control_period
        ok = self.safe(theta + step)
        fraction = ok.astype(float)
        unsafe = np.zeros(rows.size, dtype=bool)
        bad = np.flatnonzero(~ok)
        if bad.size:
            if s.safety == "clip":
                fraction[bad] = self._furthest_safe(theta[bad], step[bad])
            else:
                unsafe[bad] = True
        new_theta = theta + fraction[:, None] * step
        new_speed = fraction[:, None] * command
        return self.settle(rows, a, new_theta, new_speed, fraction, unsafe)

    def settle(
        self,
        rows: IntArray,
        a: FloatArray,
        theta: FloatArray,
        speed: FloatArray,
        fraction: FloatArray,
        unsafe: BoolArray,
        reference: FloatArray | None = None,
    ) -> StepResult:
        """Enter the (safe) state theta, speed (n, 3) in ``rows`` after a step with the
        clipped actions ``a``: the platform rotation (:meth:`rotations`, warm started
        from ``reference`` (n, 3, 3) where given), the reward, the goal counter and the
        ends (``fraction`` of the step taken, ``unsafe`` rows ended by the guard)."""
        s = self.settings
        w = s.weights
        R = self.rotations(rows, theta, reference)
        error = geodesic_angle(R, self.goal[rows])
        hold = np.where(error <= s.tolerance, self.hold[rows] + 1, 0)
        success = hold >= s.hold_steps
        steps = self.steps[rows] + 1
        terminated = success | unsafe
        truncated = (steps >= s.max_steps) & ~terminated
        reward = (
            -w.orientation * error
            - w.effort * np.mean(a**2, axis=-1)
            - w.clip * (1.0 - fraction) * (~unsafe)
            + w.success * success
            - w.unsafe * unsafe
        )
        self.theta[rows] = theta
        self.speed[rows] = speed
        self.R[rows] = R
        self.hold[rows] = hold
        self.steps[rows] = steps
        return StepResult(reward, terminated, truncated, error, fraction, success, unsafe)

    def rotations(
        self, rows: IntArray, theta: FloatArray, reference: FloatArray | None = None
    ) -> FloatArray:
        """The home-mode platform rotations (n, 3, 3) at the input angles theta (n, 3)
        of ``rows`` (a row keeps its rotation where the home mode does not assemble):
        forward kinematics (``reference`` is not used here; the dynamic core starts
        Newton's method there)."""
        fk = forward_kinematics(theta, self.design)
        R: FloatArray = np.where(fk.reachable[:, None, None], fk.R, self.R[rows])
        return R

    def error(self, rows: IntArray) -> FloatArray:
        """Orientation error of ``rows`` [rad]."""
        return geodesic_angle(self.R[rows], self.goal[rows])

    def observe(self, rows: IntArray, rngs: list[np.random.Generator]) -> npt.NDArray[np.float32]:
        """Observations of ``rows`` (n, 21), float32, with noise drawn from each row's
        own generator when ``observation_noise`` > 0, and the platform rotation and
        input angles that the robots' controllers believe with ``calibration_error``
        (:class:`~spm_pin.envs._calibration_error.BelievedModels`); without either,
        by the compiled :func:`~spm_pin.envs._observe_kernel.observe_rows` where numba
        is installed and ``fused`` is on: the same numbers."""
        sigma = self.settings.observation_noise
        plain = sigma == 0.0 and self.believed is None
        if plain and self.fused and (self._observe is not None or _jit.available()):
            out = np.empty((rows.size, OBSERVATION_SIZE), dtype=np.float32)
            args = (
                np.ascontiguousarray(rows, dtype=np.int64),
                self.R,
                self.goal,
                self.theta,
                self.speed,
                float(self.limits.max_speed),
                out,
            )
            if self._observe is None:  # the same types every call: no dispatch
                kernel = _jit.kernels(_observe_kernel.KERNELS)["observe_rows"]
                self._observe = _jit.entry(kernel, args)
            self._observe(*args)
            return out
        theta, R = self.theta[rows], self.R[rows]
        if self.believed is not None:
            theta, R = self.believed.observed(rows, theta, R)
        obs = np.concatenate(
            [
                six_d(R),
                six_d(self.goal[rows]),
                np.sin(theta),
                np.cos(theta),
                np.clip(self.speed[rows] / self.limits.max_speed, -1.0, 1.0),
            ],
            axis=-1,
        )
        if sigma > 0.0:
            noise = np.stack([rngs[int(i)].normal(0.0, sigma, _NOISY.size) for i in rows])
            obs[:, _NOISY] = np.clip(obs[:, _NOISY] + noise, -1.0, 1.0)
        return obs.astype(np.float32)
