"""The safety guard: no goal reaches the servos unless the model says it is safe.

A goal theta (input angles [rad]) passes when

1. it is 3 finite numbers inside the joint limits,
2. the home assembly mode exists there (``spm.forward_kinematics(theta).reachable``),
3. its distance to singularity is large enough
   (``spm.jacobian(theta).singularity_margin >= min_singularity_margin`` and
   ``dexterity >= min_dexterity``),
4. no two links collide, with margin (``robot.collisions(theta, margin=m)`` empty),

and, for a stream of goals sent every ``period`` seconds, when the commanded motion
keeps |theta_k - theta_{k-1}| / period <= max_speed and
|theta_k - 2 theta_{k-1} + theta_{k-2}| / period^2 <= max_acceleration. Goals that are
not evenly spaced in time (h_k = t_k - t_{k-1}) are checked with the speeds of their
intervals: |v_k - v_{k-1}| / ((h_k + h_{k-1}) / 2) <= max_acceleration with
v_k = (theta_k - theta_{k-1}) / h_k (the same number when h_k = h_{k-1}).

A path (trajectory) is checked whole before its first command: every sample, and
between samples further than ``path_resolution`` apart, linearly interpolated
samples (what the servos sweep through).

The static checks (1-4) of a goal are cached, so a loop that sends pre-checked
samples (or holds a goal) pays for them once.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError, SPMError, UnsafeCommandError
from ..kinematics import forward_kinematics, jacobian
from ._fast import FastStatic
from .config import SafetyLimits

if TYPE_CHECKING:
    from ..model.robot import SPMRobot

__all__ = ["PathVerdict", "SafetyGuard", "Verdict"]

FloatArray = npt.NDArray[np.float64]
LinkPair = tuple[str, str]
#: Relative slack of the speed and acceleration checks (rounding of sampled paths).
_RATE_SLACK = 1e-9


@dataclasses.dataclass(frozen=True)
class Verdict:
    """The guard's answer for one goal.

    Attributes:
        theta: The goal [rad], (3,).
        safe: Every check passed.
        reasons: Why not, one sentence per failed check (empty when safe).
        reachable: The home assembly mode exists.
        singularity_margin: Distance to singularity in [0, 1] (NaN if unreachable).
        dexterity: 1/kappa(J) in [0, 1] (NaN if unreachable).
        collisions: Colliding link pairs (with margin).
        R: The platform rotation (3, 3) of the home assembly mode, as
            ``forward_kinematics(theta).R`` gives it bit for bit; None where
            unreachable.
    """

    theta: FloatArray
    safe: bool
    reasons: tuple[str, ...]
    reachable: bool
    singularity_margin: float
    dexterity: float
    collisions: tuple[LinkPair, ...]
    R: FloatArray | None = None

    def require(self) -> Verdict:
        """Return self when safe; else raise UnsafeCommandError with the reasons."""
        if not self.safe:
            where = np.degrees(self.theta).round(3).tolist()
            raise UnsafeCommandError(
                f"goal theta = {where} deg refused, nothing was sent: " + "; ".join(self.reasons),
                reasons=self.reasons,
                goal=self.theta,
            )
        return self


@dataclasses.dataclass(frozen=True)
class PathVerdict:
    """The guard's answer for a whole path.

    Attributes:
        safe: Every sample (and every interpolated sample) passed.
        checked: Number of samples checked (interpolated ones included).
        index: Index (in the given path) of the first unsafe sample, or None.
        verdict: The verdict of the first unsafe sample, or None.
        reasons: Why the path is unsafe (empty when safe).
    """

    safe: bool
    checked: int
    index: int | None
    verdict: Verdict | None
    reasons: tuple[str, ...]

    def require(self) -> PathVerdict:
        """Return self when safe; else raise UnsafeCommandError (nothing was sent)."""
        if not self.safe:
            goal = None if self.verdict is None else self.verdict.theta
            raise UnsafeCommandError(
                f"path refused at sample {self.index}, nothing was sent: "
                + "; ".join(self.reasons),
                reasons=self.reasons,
                goal=goal,
                index=self.index,
            )
        return self


def _as_theta(theta: npt.ArrayLike, name: str = "theta") -> FloatArray:
    try:
        values = np.array(theta, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"{name} must be 3 angles [rad], got {theta!r}", argument=name, value=theta
        ) from None
    if values.shape != (3,):
        raise InputError(
            f"{name} must have shape (3,) [rad], got shape {values.shape}",
            argument=name,
            value=theta,
        )
    return values


class SafetyGuard:
    """Checks goals against the model before they may be sent.

    Args:
        robot: The robot model (its ``collisions`` method checks the links);
            default ``spm.build_robot(design)``.
        limits: The limits (default :class:`SafetyLimits`).
        cache_size: Static verdicts kept (by exact goal).

    Attributes:
        design: The design of the robot.
        limits: As given.
        stats: Counters: static checks computed, cache hits, refusals.
    """

    def __init__(
        self,
        robot: SPMRobot | None = None,
        limits: SafetyLimits | None = None,
        *,
        cache_size: int = 8192,
    ) -> None:
        if robot is None:
            from ..collision import build_robot

            robot = build_robot()
        if not callable(getattr(robot, "collisions", None)):
            raise InputError(
                "robot must be an SPMRobot with a collisions(theta, margin=...) method",
                argument="robot",
                value=robot,
            )
        self.robot = robot
        self.design: SPMDesign = robot.design
        self.limits = limits or SafetyLimits()
        self._cache: collections.OrderedDict[bytes, Verdict] = collections.OrderedDict()
        self._cache_size = int(cache_size)
        self.stats = collections.Counter[str]()
        self._fast = FastStatic.of(robot, self.limits)

    def __repr__(self) -> str:
        return f"SafetyGuard(design={self.design.name!r}, limits={self.limits!r})"

    # ---------------------------------------------------------------- static
    def _limit_reasons(self, theta: FloatArray) -> list[str]:
        limits = self.limits
        reasons = []
        values = theta.tolist()
        # A non-finite sum (NaN, or inf - inf) or a huge one: look at each value.
        if not math.isfinite(sum(values)) and not all(math.isfinite(x) for x in values):
            return [f"theta {values} is not finite"]
        for i in range(3):
            low, high = limits.theta_min[i], limits.theta_max[i]
            if not low <= values[i] <= high:
                reasons.append(
                    f"theta_{i + 1} = {math.degrees(values[i]):.3f} deg is outside the joint "
                    f"limits [{math.degrees(low):.1f}, {math.degrees(high):.1f}] deg"
                )
        return reasons

    def _static_batch(self, thetas: FloatArray) -> list[Verdict]:
        """Static verdicts of many goals (n, 3), cached ones reused."""
        verdicts: list[Verdict | None] = []
        todo: list[int] = []
        for k, theta in enumerate(thetas):
            key = theta.tobytes()
            cached = self._cache.get(key)
            if cached is not None:
                self._cache.move_to_end(key)
                self.stats["cache_hits"] += 1
            else:
                todo.append(k)
            verdicts.append(cached)
        if todo:
            for k, verdict in zip(todo, self._compute(thetas[todo]), strict=True):
                verdicts[k] = verdict
                self._remember(verdict)
        return [v for v in verdicts if v is not None]

    def _static_one(self, theta: FloatArray) -> Verdict:
        """The static verdict of one goal (3,): cached, else the fast path."""
        key = theta.tobytes()
        cached = self._cache.get(key)
        if cached is not None:
            self._cache.move_to_end(key)
            self.stats["cache_hits"] += 1
            return cached
        verdict = self.static_verdict(theta)
        self._remember(verdict)
        return verdict

    def cached_verdict(self, theta: FloatArray) -> Verdict | None:
        """The static verdict of a goal (3,) [rad] already checked and still in the
        cache, or None (no checks run, nothing counted)."""
        return self._cache.get(np.asarray(theta, dtype=float).tobytes())

    def static_verdict(self, theta: FloatArray) -> Verdict:
        """The static checks (1-4) of one goal (3,) [rad], uncached, on the fast path.

        The same verdict as the batch checks give, bit for bit (the measures and the
        collision check from the single-input code of :mod:`._fast`); goals that are
        not finite take the batch path.
        """
        if self._fast is None or not math.isfinite(sum(theta.tolist())):
            return self._compute(theta[None])[0]
        self.stats["computed"] += 1
        reasons = self._limit_reasons(theta)
        reachable, margin, dexterity, rotation, q = self._fast.static(theta.tolist())

        fast = self._fast

        def collide() -> tuple[LinkPair, ...]:  # called only where reachable
            try:
                if q is not None:
                    return fast.collisions_at(q)
                return fast.collisions(theta.tolist(), rotation)
            except SPMError as exc:  # as in _collisions
                return (("model", f"error: {exc}"),)

        R = None if rotation is None else np.array(rotation, dtype=float)
        return self._verdict(theta, reasons, True, reachable, margin, dexterity, collide, R)

    def _remember(self, verdict: Verdict) -> None:
        self._cache[verdict.theta.tobytes()] = verdict
        while len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)

    def _compute(self, thetas: FloatArray) -> list[Verdict]:
        n = thetas.shape[0]
        self.stats["computed"] += n
        finite = np.all(np.isfinite(thetas), axis=-1)
        safe_theta = np.where(finite[:, None], thetas, 0.0)
        fk = forward_kinematics(safe_theta, self.design)
        reachable = fk.reachable & finite
        margin = np.full(n, math.nan)
        dexterity = np.full(n, math.nan)
        if np.any(reachable):
            jac = jacobian(safe_theta[reachable], self.design, R=fk.R[reachable])
            margin[reachable] = jac.singularity_margin
            dexterity[reachable] = jac.dexterity
        verdicts = []
        for k in range(n):
            theta = thetas[k].copy()
            verdicts.append(
                self._verdict(
                    theta,
                    self._limit_reasons(theta),
                    bool(finite[k]),
                    bool(reachable[k]),
                    float(margin[k]),
                    float(dexterity[k]),
                    functools.partial(self._collisions, theta),
                    fk.R[k].copy() if reachable[k] else None,
                )
            )
        return verdicts

    def _verdict(
        self,
        theta: FloatArray,
        reasons: list[str],
        finite: bool,
        reachable: bool,
        margin: float,
        dexterity: float,
        collide: Callable[[], tuple[LinkPair, ...]],
        R: FloatArray | None = None,
    ) -> Verdict:
        """The verdict from the limit reasons and the measures; ``collide`` runs the
        collision check (only where the goal is reachable); ``R``: the home-mode
        rotation there."""
        limits = self.limits
        pairs: tuple[LinkPair, ...] = ()
        if not reachable:
            if finite:
                reasons.append("no home-mode assembly exists there (unreachable)")
        else:
            if not margin >= limits.min_singularity_margin:
                reasons.append(
                    f"too close to a singularity: margin {margin:.4f} < "
                    f"{limits.min_singularity_margin:g}"
                )
            if not dexterity >= limits.min_dexterity:
                reasons.append(f"dexterity {dexterity:.4f} < {limits.min_dexterity:g}")
            pairs = collide()
            if pairs:
                names = ", ".join(f"{a}-{b}" for a, b in pairs)
                reasons.append(
                    f"links collide (margin {limits.collision_margin * 1e3:g} mm): {names}"
                )
        return Verdict(
            theta=theta,
            safe=not reasons,
            reasons=tuple(reasons),
            reachable=reachable,
            singularity_margin=margin,
            dexterity=dexterity,
            collisions=pairs,
            R=R if reachable else None,
        )

    def _collisions(self, theta: FloatArray) -> tuple[LinkPair, ...]:
        try:
            pairs = self.robot.collisions(theta, margin=self.limits.collision_margin)
        except SPMError as exc:  # e.g. a configuration that does not close
            return (("model", f"error: {exc}"),)
        return tuple((str(a), str(b)) for a, b in pairs)

    # ---------------------------------------------------------------- public
    def check(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
        previous_period: float | None = None,
    ) -> Verdict:
        """Check one goal, and the step to it from the previous commands.

        Args:
            theta: The goal [rad], (3,).
            previous: The last goal sent [rad] (speed check).
            before_previous: The goal sent before it [rad] (acceleration check).
            period: Time between ``previous`` and this goal [s] (needed for the
                speed and acceleration checks).
            previous_period: Time between ``before_previous`` and ``previous`` [s]
                (default: ``period``, goals evenly spaced in time).

        Returns:
            The verdict (``verdict.require()`` raises when unsafe).
        """
        goal = _as_theta(theta)
        verdict = self._static_one(goal)
        rate_reasons: list[str] = []
        if previous is not None and period is not None:
            rate_reasons = self._rate_reasons(
                goal,
                _as_theta(previous, "previous"),
                None if before_previous is None else _as_theta(before_previous, "before_previous"),
                period,
                previous_period,
            )
        if rate_reasons:
            verdict = dataclasses.replace(
                verdict, safe=False, reasons=verdict.reasons + tuple(rate_reasons)
            )
        if not verdict.safe:
            self.stats["refused"] += 1
        return verdict

    def _rate_reasons(
        self,
        goal: FloatArray,
        previous: FloatArray,
        before: FloatArray | None,
        period: float,
        previous_period: float | None = None,
    ) -> list[str]:
        for name, value in (("period", period), ("previous_period", previous_period)):
            if value is not None and not (value > 0 and math.isfinite(value)):
                raise InputError(
                    f"{name} must be a finite number > 0 s, got {value!r}",
                    argument=name,
                    value=value,
                )
        limits = self.limits
        reasons = []
        speed = float(np.max(np.abs(goal - previous))) / period
        if speed > limits.max_speed * (1 + _RATE_SLACK):
            reasons.append(
                f"joint speed {math.degrees(speed):.1f} deg/s > "
                f"{math.degrees(limits.max_speed):.1f} deg/s"
            )
        if before is not None:
            if previous_period is None or previous_period == period:
                accel = float(np.max(np.abs(goal - 2 * previous + before))) / period**2
            else:  # unevenly spaced: the change of the speeds of the two intervals
                change = (goal - previous) / period - (previous - before) / previous_period
                accel = float(np.max(np.abs(change))) / (0.5 * (period + previous_period))
            if accel > limits.max_acceleration * (1 + _RATE_SLACK):
                reasons.append(
                    f"joint acceleration {math.degrees(accel):.1f} deg/s^2 > "
                    f"{math.degrees(limits.max_acceleration):.1f} deg/s^2"
                )
        return reasons

    def check_path(
        self,
        path: npt.ArrayLike,
        *,
        period: float | None = None,
        start: npt.ArrayLike | None = None,
    ) -> PathVerdict:
        """Check a whole path before its first command.

        Args:
            path: Goals [rad], (n, 3), to be sent in order.
            period: Time between goals [s]; with it, speed and acceleration are
                checked (from ``start`` at rest, when given).
            start: Where the servos are (or were last commanded) [rad], (3,).

        Returns:
            The verdict; ``.require()`` raises UnsafeCommandError when unsafe.
        """
        try:
            goals = np.array(path, dtype=float)
        except (TypeError, ValueError):
            raise InputError(
                f"path must be angles [rad] of shape (n, 3), got {path!r}",
                argument="path",
                value=path,
            ) from None
        if goals.ndim != 2 or goals.shape[1] != 3 or goals.shape[0] == 0:
            raise InputError(
                f"path must have shape (n, 3) with n >= 1, got {goals.shape}",
                argument="path",
                value=path,
            )
        sequence = goals if start is None else np.vstack([_as_theta(start, "start"), goals])
        offset = 0 if start is None else 1
        # Interpolate where samples are further apart than the resolution.
        samples = [sequence[:1]]
        owner = [0]
        for k in range(1, sequence.shape[0]):
            step = float(np.max(np.abs(sequence[k] - sequence[k - 1])))
            parts = (
                max(1, math.ceil(step / self.limits.path_resolution)) if math.isfinite(step) else 1
            )
            fractions = np.arange(1, parts + 1)[:, None] / parts
            samples.append(sequence[k - 1] + fractions * (sequence[k] - sequence[k - 1]))
            owner += [k] * parts
        every = np.vstack(samples)
        verdicts = self._static_batch(every)
        for verdict, k in zip(verdicts, owner, strict=True):
            if not verdict.safe:
                self.stats["refused"] += 1
                index = max(k - offset, 0)
                between = "" if np.array_equal(verdict.theta, sequence[k]) else " (between samples)"
                return PathVerdict(
                    False,
                    len(every),
                    index,
                    verdict,
                    (f"sample {index}{between}: " + "; ".join(verdict.reasons),),
                )
        if period is not None:
            # From rest at start (when given), to rest at the last sample.
            rest = [] if start is None else [sequence[0], sequence[0]]
            padded = np.vstack([*rest, goals, goals[-1:]])
            shift = len(rest)
            for k in range(max(shift, 1), padded.shape[0]):
                before = padded[k - 2] if k >= 2 else None
                reasons = self._rate_reasons(padded[k], padded[k - 1], before, period)
                if reasons:
                    self.stats["refused"] += 1
                    index = min(k - shift, goals.shape[0] - 1)
                    verdict = self._static_batch(goals[index][None])[0]
                    return PathVerdict(
                        False,
                        len(every),
                        index,
                        dataclasses.replace(verdict, safe=False, reasons=tuple(reasons)),
                        (f"sample {index}: " + "; ".join(reasons),),
                    )
        return PathVerdict(True, len(every), None, None, ())
