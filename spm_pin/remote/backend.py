"""Twin backends: what the server drives, without any web code.

A backend holds the robot's state and moves it, one goal at a time, after the safety
guard (:class:`~spm_pin.hardware.guard.SafetyGuard`, the same one that guards the
servos) has accepted the goal. :class:`TwinBackend` is the protocol every backend
follows and :class:`GuardedTwin` what they share (the model, the guard, the report of
a goal); :class:`~spm_pin.remote.kinematic.KinematicBackend` is the model alone.

Every public method of a backend takes its lock: Pinocchio's data (and the guard's
cache) are not safe to share between threads, and the server runs requests in a
thread pool.

A goal is judged by the guard (joint limits, home assembly mode, singularity margin,
dexterity, collisions with the guard's margin) and, besides, by a collision check in
whichever assembly mode exists there (:func:`~spm_pin.collision.check_input`): where
the home assembly mode does not exist, the report still names the links that collide
in the real assembly mode nearest to it, as the published study showed at
theta = [60, 90, 220] deg.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from .._checks import as_rotation
from ..design import SPMDesign
from ..errors import InputError, UnreachableError, UnsafeCommandError
from ..kinematics import forward_kinematics, inverse_kinematics, jacobian
from ..kinematics._common import mode_label

if TYPE_CHECKING:
    from ..hardware.config import SafetyLimits
    from ..hardware.guard import SafetyGuard, Verdict
    from ..model.robot import SPMRobot

__all__ = [
    "CHECK_NAMES",
    "RATE_CHECK_NAMES",
    "CheckOutcome",
    "CollisionState",
    "GoalRefusedError",
    "GoalReport",
    "GuardedTwin",
    "PairState",
    "TwinBackend",
    "TwinState",
]

FloatArray = npt.NDArray[np.float64]
LinkPair = tuple[str, str]

#: The checks a goal passes, in the order they are reported.
CHECK_NAMES = ("joint_limits", "reachable", "singularity", "dexterity", "collision")

#: The checks of a streamed goal against the goals commanded before it (reported
#: only when they were evaluated, i.e. with a period).
RATE_CHECK_NAMES = ("speed", "acceleration")

#: Words of the guard's reasons -> the check they belong to (first match wins).
_REASON_WORDS = (
    ("joint speed", "speed"),
    ("joint acceleration", "acceleration"),
    ("joint limits", "joint_limits"),
    ("not finite", "joint_limits"),
    ("unreachable", "reachable"),
    ("singularity", "singularity"),
    ("dexterity", "dexterity"),
    ("collide", "collision"),
)


@dataclasses.dataclass(frozen=True)
class CheckOutcome:
    """One check of a goal.

    Attributes:
        name: One of :data:`CHECK_NAMES` (or ``"other"`` for a reason of the guard
            that none of them covers).
        passed: The goal passes it; None where it could not be evaluated (the
            singularity and dexterity of an input without a home-mode assembly).
        reason: Why not (None when passed).
    """

    name: str
    passed: bool | None
    reason: str | None


class GoalRefusedError(UnsafeCommandError):
    """A goal that the server refused; nothing moved.

    Attributes:
        report: The verdict on the goal, every check with its outcome.
    """

    def __init__(self, message: str, report: GoalReport) -> None:
        super().__init__(message, reasons=report.reasons, goal=report.theta)
        self.report = report


@dataclasses.dataclass(frozen=True)
class GoalReport:
    """The verdict on one goal, as the server reports it.

    Attributes:
        theta: The goal [rad], (3,).
        safe: The guard accepts it and no links collide in any existing assembly mode.
        reasons: Why not, one sentence per failed check (empty when safe).
        checks: Every check of :data:`CHECK_NAMES` with its outcome.
        reachable: The home assembly mode exists.
        singularity_margin: Distance to singularity in [0, 1] (NaN if unreachable).
        dexterity: 1/kappa(J) in [0, 1] (NaN if unreachable).
        pairs: Colliding link pairs: the guard's (with its margin) and those of the
            assembly mode checked by :func:`~spm_pin.collision.check_input`.
        assembly: The assembly mode the collisions were checked in (``"+++/-"``
            style), or None when no real assembly exists.
        min_distance: Smallest distance between two checked links [m] (negative on
            overlap); ``inf`` (``null`` on the wire) when the goal was refused for
            its speed or acceleration alone: its static checks passed and the exact
            distances (milliseconds) are not computed, so that a stream of such
            refusals is answered as fast as it comes.
        collision_margin: The guard's collision margin [m].
    """

    theta: FloatArray
    safe: bool
    reasons: tuple[str, ...]
    checks: tuple[CheckOutcome, ...]
    reachable: bool
    singularity_margin: float
    dexterity: float
    pairs: tuple[LinkPair, ...]
    assembly: str | None
    min_distance: float
    collision_margin: float

    @property
    def failed(self) -> tuple[CheckOutcome, ...]:
        """The checks that failed."""
        return tuple(check for check in self.checks if check.passed is False)

    def require(self) -> GoalReport:
        """Return self when safe; else raise GoalRefusedError (an UnsafeCommandError)."""
        if not self.safe:
            where = np.degrees(self.theta).round(6).tolist()
            raise GoalRefusedError(
                f"goal theta = {where} deg refused, nothing moved: " + "; ".join(self.reasons),
                self,
            )
        return self


@dataclasses.dataclass(frozen=True)
class PairState:
    """One checked link pair at the current state.

    Attributes:
        pair: The two link names.
        colliding: The links overlap (no margin).
        distance: Their distance [m] (negative: depth of overlap).
    """

    pair: LinkPair
    colliding: bool
    distance: float


@dataclasses.dataclass(frozen=True)
class CollisionState:
    """Every checked link pair at one state.

    Attributes:
        theta: The input angles [rad], (3,).
        pairs: Each checked link pair, in the order of
            :data:`~spm_pin.collision.LINK_PAIRS`.
    """

    theta: FloatArray
    pairs: tuple[PairState, ...]

    @property
    def collision(self) -> bool:
        """Some pair collides."""
        return any(pair.colliding for pair in self.pairs)


@dataclasses.dataclass(frozen=True)
class TwinState:
    """The twin's state.

    Attributes:
        theta: Input angles [rad], (3,).
        R: Platform rotation (3, 3), or None without a home-mode assembly.
        reachable: The home assembly mode exists.
        pairs: Colliding link pairs (no margin).
        min_distance: Smallest distance between two checked links [m].
        dexterity: 1/kappa(J) in [0, 1] (NaN if unreachable).
        singularity_margin: Distance to singularity in [0, 1] (NaN if unreachable).
        assembly: Assembly-mode label such as ``"+++/-"`` (None if unreachable).
        backend: The backend's name (``"kinematic"``, ``"dynamic"``, ``"servos"``).
        time: Server time when the state was read [s since the epoch].
        moving: A motion is in progress (never for the kinematic twin).
        stops: How many times the twin was stopped (:meth:`TwinBackend.stop`).
        theta_dot: Input speeds [rad/s], (3,) (None for the kinematic twin).
        goal: The goal the twin is heading for now [rad], (3,) (None for the
            kinematic twin, which is always at its goal).
        fault: Why the twin stopped by itself (a failed simulation step, a servo
            fault), or None.
        torque: The actuators hold their goal (False after a stop of the servo
            twin: torque off).
    """

    theta: FloatArray
    R: FloatArray | None
    reachable: bool
    pairs: tuple[LinkPair, ...]
    min_distance: float
    dexterity: float
    singularity_margin: float
    assembly: str | None
    backend: str
    time: float
    moving: bool = False
    stops: int = 0
    theta_dot: FloatArray | None = None
    goal: FloatArray | None = None
    fault: str | None = None
    torque: bool = True


class TwinBackend(Protocol):
    """What the server needs of a twin (the kinematic model now; the simulated
    dynamics and the servos follow the same protocol).

    Every method is safe to call from several threads.
    """

    name: str
    design: SPMDesign
    guard: SafetyGuard

    def state(self) -> TwinState:
        """The current state."""
        ...

    def joints(self) -> FloatArray:
        """The current input angles [rad], (3,)."""
        ...

    def check(self, theta: npt.ArrayLike) -> GoalReport:
        """The verdict on a goal [rad], without moving."""
        ...

    def move(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
        previous_period: float | None = None,
    ) -> TwinState:
        """Move to a goal [rad] if it is safe; raise GoalRefusedError (nothing
        moves) if not. With ``previous`` and ``period`` (a stream of goals), the
        guard's speed check applies too, with ``before_previous`` its acceleration
        check (``previous_period``: the time between the two previous goals, when
        not ``period``)."""
        ...

    def solve(self, R: npt.ArrayLike) -> FloatArray:
        """Input angles [rad] that put the platform at rotation R (home working mode);
        raise UnreachableError if there are none."""
        ...

    def collisions(self) -> CollisionState:
        """Every checked link pair at the current state."""
        ...

    def stop(self, reason: str | None = None) -> TwinState:
        """Halt any motion in progress (the servos' torque goes off); return the
        state. ``reason`` says why (kept for the log)."""
        ...


def _theta(theta: npt.ArrayLike) -> FloatArray:
    try:
        values = np.array(theta, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"theta must be 3 angles [rad], got {theta!r}", argument="theta", value=theta
        ) from None
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise InputError(
            f"theta must be 3 finite angles [rad], got {values.tolist()}",
            argument="theta",
            value=theta,
        )
    return values


def _goal_arguments(
    theta: npt.ArrayLike,
    previous: npt.ArrayLike | None,
    before_previous: npt.ArrayLike | None,
) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
    """A goal and the two goals before it (streams), each checked: (goal, previous,
    before_previous) [rad].

    Raises:
        InputError: one of them is not 3 finite numbers.
    """
    goal = _theta(theta)
    last = None if previous is None else _theta(previous)
    before = None if before_previous is None else _theta(before_previous)
    return goal, last, before


def _check_of(reason: str) -> str:
    """The check a reason of the guard belongs to (``"other"`` if none)."""
    for words, name in _REASON_WORDS:
        if words in reason:
            return name
    return "other"


class GuardedTwin:
    """What every twin shares: the robot, the guard, the verdict on goals, the
    derived state of input angles, inverse kinematics and collisions.

    Subclasses say where the input angles are (:meth:`joints`) and how they move
    (``move``, ``stop``, ``state``). Model queries take ``self._lock``: Pinocchio's
    data and the guard's cache are not safe to share between threads.

    Args:
        robot: The robot with its collision checker (default
            ``spm.build_robot(design)``).
        design: The SPM (default: the prototype); ignored when ``robot`` is given.
        limits: The guard's limits (default
            :class:`~spm_pin.hardware.config.SafetyLimits`).
    """

    name = "twin"

    def __init__(
        self,
        design: SPMDesign | None = None,
        *,
        robot: SPMRobot | None = None,
        limits: SafetyLimits | None = None,
    ) -> None:
        from ..collision import build_robot
        from ..hardware.guard import SafetyGuard

        if robot is None:
            robot = build_robot(design or SPMDesign.prototype())
        self.robot: SPMRobot = robot
        self.design: SPMDesign = robot.design
        self.guard: SafetyGuard = SafetyGuard(robot, limits)
        self._lock = threading.Lock()
        self.stops = 0
        self.last_stop_reason: str | None = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}(design={self.design.name!r})"

    def joints(self) -> FloatArray:
        """The current input angles [rad], (3,)."""
        raise NotImplementedError

    # ---------------------------------------------------------------- private
    def _report(
        self,
        theta: FloatArray,
        previous: FloatArray | None = None,
        before_previous: FloatArray | None = None,
        period: float | None = None,
        verdict: Verdict | None = None,
        previous_period: float | None = None,
    ) -> GoalReport:
        from ..collision import check_input

        if verdict is None:
            verdict = self.guard.check(
                theta,
                previous=previous,
                before_previous=before_previous,
                period=period,
                previous_period=previous_period,
            )
        limits = self.guard.limits
        rate_only = bool(verdict.reasons) and all(
            _check_of(reason) in RATE_CHECK_NAMES for reason in verdict.reasons
        )
        home = self._home_label()
        found: tuple[LinkPair, ...]
        mode: str | None
        if rate_only and home is not None:
            # The static checks passed: the home mode exists with no pair within the
            # margin, as check_input finds it; the distances are not computed.
            found, mode, min_distance = (), home, math.inf
        else:
            report = check_input(
                theta, self.robot, margin=limits.collision_margin, distances=not rate_only
            )
            found, mode, min_distance = report.pairs, report.mode, report.min_distance
        pairs = list(verdict.collisions)
        pairs += [pair for pair in found if pair not in pairs]
        reasons = list(verdict.reasons)
        if found and not verdict.collisions:
            names = ", ".join(f"{a}-{b}" for a, b in found)
            where = "no real assembly" if mode is None else f"assembly mode {mode}"
            reasons.append(
                f"links collide (margin {limits.collision_margin * 1e3:g} mm, {where}): {names}"
            )
        checked: tuple[str, ...] = CHECK_NAMES
        if previous is not None and period is not None:
            checked += RATE_CHECK_NAMES[: 1 if before_previous is None else 2]
        grouped: dict[str, list[str]] = {
            name: [] for name in (*checked, *RATE_CHECK_NAMES, "other")
        }
        for reason in reasons:
            grouped[_check_of(reason)].append(reason)
        checks = []
        for name in checked if not grouped["other"] else (*checked, "other"):
            passed: bool | None = not grouped[name]
            if passed and not verdict.reachable and name in ("singularity", "dexterity"):
                passed = None
            checks.append(CheckOutcome(name, passed, "; ".join(grouped[name]) or None))
        return GoalReport(
            theta=theta.copy(),
            safe=verdict.safe and not found,
            reasons=tuple(reasons),
            checks=tuple(checks),
            reachable=verdict.reachable,
            singularity_margin=verdict.singularity_margin,
            dexterity=verdict.dexterity,
            pairs=tuple(pairs),
            assembly=mode,
            min_distance=min_distance,
            collision_margin=limits.collision_margin,
        )

    def _home_label(self) -> str | None:
        """The home assembly mode's label (``"+++/+"`` style) that a safe verdict of
        the guard settles, or None when its limits do not settle it (a negative
        collision margin, or no singularity margin to keep b_ii and det A from 0)."""
        limits = self.guard.limits
        if limits.collision_margin < 0 or not limits.min_singularity_margin > 0:
            return None
        return "+++/+" if float(self.design.home_det_a) > 0 else "+++/-"

    def _compute_state(self, theta: FloatArray, min_distance: float | None = None) -> TwinState:
        """The state at input angles [rad]; ``min_distance`` [m] when already known
        (else the exact distances are computed: the costly part)."""
        from ..collision import check_input

        if min_distance is not None:
            fast = self._accepted_state(theta, min_distance)
            if fast is not None:
                return fast
        fk = forward_kinematics(theta, self.design)
        reachable = bool(fk.reachable)
        R: FloatArray | None = None
        dexterity = margin = math.nan
        label: str | None = None
        if reachable:
            R = np.array(fk.R, dtype=float)
            jac = jacobian(theta[None], self.design, R=R[None])
            dexterity = float(jac.dexterity[0])
            margin = float(jac.singularity_margin[0])
            label = mode_label(jac.b[0]) + ("/+" if float(jac.det_a[0]) > 0 else "/-")
        report = check_input(theta, self.robot, distances=min_distance is None)
        return TwinState(
            theta=theta.copy(),
            R=R,
            reachable=reachable,
            pairs=report.pairs,
            min_distance=report.min_distance if min_distance is None else min_distance,
            dexterity=dexterity,
            singularity_margin=margin,
            assembly=label,
            backend=self.name,
            time=time.time(),
        )

    def _accepted_state(self, theta: FloatArray, min_distance: float) -> TwinState | None:
        """The state at a goal the guard has accepted (its safe verdict still cached),
        from that verdict (its measures and its rotation): the values of the
        batch path bit for bit at a fraction of its cost (what a state pushed at
        1 kHz while goals stream in needs). None for any other input.

        A safe verdict (collision margin >= 0) means the home mode exists there with
        no colliding pair, and its singularity margin (a positive threshold) keeps
        every b_ii and det A away from zero, so the assembly label is the home mode's.
        """
        label = self._home_label()
        if label is None:
            return None  # the verdict would not settle the pairs or the label
        verdict = self.guard.cached_verdict(theta)
        if verdict is None or not verdict.safe or verdict.R is None:
            return None
        return TwinState(
            theta=theta.copy(),
            R=verdict.R.copy(),
            reachable=True,
            pairs=(),
            min_distance=min_distance,
            dexterity=verdict.dexterity,
            singularity_margin=verdict.singularity_margin,
            assembly=label,
            backend=self.name,
            time=time.time(),
        )

    def _accept(
        self,
        goal: FloatArray,
        last: FloatArray | None = None,
        before: FloatArray | None = None,
        period: float | None = None,
        previous_period: float | None = None,
    ) -> None:
        """Raise GoalRefusedError unless the goal is safe (call with the lock held).

        An accepted goal is decided by the guard alone: a safe verdict means the home
        assembly mode exists and no two links come nearer than the margin there, which
        is the collision check of :func:`~spm_pin.collision.check_input` in that mode
        (tested: the two agree). Only a refused goal pays for the full report (it
        names the pairs, in the nearest real assembly mode when the home one does not
        exist).
        """
        verdict = self.guard.check(
            goal,
            previous=last,
            before_previous=before,
            period=period,
            previous_period=previous_period,
        )
        if not verdict.safe:
            self._report(goal, last, before, period, verdict, previous_period).require()

    # ---------------------------------------------------------------- shared public
    def check(self, theta: npt.ArrayLike) -> GoalReport:
        """The verdict on a goal [rad], (3,), without moving.

        Raises:
            InputError: not 3 finite numbers.
        """
        goal = _theta(theta)
        with self._lock:
            return self._report(goal)

    def solve(self, R: npt.ArrayLike) -> FloatArray:
        """Input angles [rad] for platform rotation R, home working mode (as ``spm ik``).

        Raises:
            InputError: R is not a rotation matrix.
            UnreachableError: some leg cannot close; the message names them.
        """
        rotation = as_rotation(R, "R")
        with self._lock:
            ik = inverse_kinematics(rotation[None], self.design)
        legs = [int(i) + 1 for i in np.flatnonzero(~np.asarray(ik.leg_reachable[0]))]
        if legs:
            raise UnreachableError(
                f"the orientation is out of reach of design {self.design.name!r}: "
                f"leg(s) {legs} cannot close (no input angle puts w_i at alpha2 from v_i)",
                leg=legs[0] if len(legs) == 1 else None,
                value=rotation,
            )
        return np.array(ik.theta[0], dtype=float)

    def collisions(self) -> CollisionState:
        """Every checked link pair at the current state (no margin)."""
        from ..collision import check_input

        theta = self.joints()
        with self._lock:
            report = check_input(theta, self.robot)
        pairs = tuple(
            PairState(pair, pair in report.pairs, float(distance))
            for pair, distance in report.distances.items()
        )
        return CollisionState(theta, pairs)
