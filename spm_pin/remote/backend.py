"""Twin backends: what the server drives, without any web code.

A backend holds the robot's state and moves it, one goal at a time, after the safety
guard (:class:`~spm_pin.hardware.guard.SafetyGuard`, the same one that guards the
servos) has accepted the goal. :class:`TwinBackend` is the protocol every backend
follows; :class:`KinematicBackend` is the model alone: a twin whose input angles
jump to each accepted goal.

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
    "KinematicBackend",
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

#: While goals stream in (``command``), the kinematic twin's exact smallest link
#: distance is computed again at most this often [s] (it costs ~15 ms).
DISTANCE_INTERVAL = 0.1

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
            overlap).
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
    ) -> TwinState:
        """Move to a goal [rad] if it is safe; raise GoalRefusedError (nothing
        moves) if not. With ``previous`` and ``period`` (a stream of goals), the
        guard's speed check applies too, with ``before_previous`` its acceleration
        check."""
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
    ) -> GoalReport:
        from ..collision import check_input

        if verdict is None:
            verdict = self.guard.check(
                theta, previous=previous, before_previous=before_previous, period=period
            )
        limits = self.guard.limits
        report = check_input(theta, self.robot, margin=limits.collision_margin)
        pairs = list(verdict.collisions)
        pairs += [pair for pair in report.pairs if pair not in pairs]
        reasons = list(verdict.reasons)
        if report.pairs and not verdict.collisions:
            names = ", ".join(f"{a}-{b}" for a, b in report.pairs)
            where = "no real assembly" if report.mode is None else f"assembly mode {report.mode}"
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
            safe=verdict.safe and not report.pairs,
            reasons=tuple(reasons),
            checks=tuple(checks),
            reachable=verdict.reachable,
            singularity_margin=verdict.singularity_margin,
            dexterity=verdict.dexterity,
            pairs=tuple(pairs),
            assembly=report.mode,
            min_distance=report.min_distance,
            collision_margin=limits.collision_margin,
        )

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
        from that verdict and the single-input forward kinematics: the values of the
        batch path bit for bit at a fraction of its cost (what a state pushed at
        1 kHz while goals stream in needs). None for any other input.

        A safe verdict (collision margin >= 0) means the home mode exists there with
        no colliding pair, and its singularity margin (a positive threshold) keeps
        every b_ii and det A away from zero, so the assembly label is the home mode's.
        """
        from ..kinematics import _scalar

        limits = self.guard.limits
        if limits.collision_margin < 0 or not limits.min_singularity_margin > 0:
            return None  # the verdict would not settle the pairs or the label
        verdict = self.guard.cached_verdict(theta)
        if verdict is None or not verdict.safe:
            return None
        rows = _scalar.fk_home(theta.tolist(), _scalar.constants(self.design))
        if rows is None:  # pragma: no cover - a safe verdict is reachable
            return None
        return TwinState(
            theta=theta.copy(),
            R=np.array(rows, dtype=float),
            reachable=True,
            pairs=(),
            min_distance=min_distance,
            dexterity=verdict.dexterity,
            singularity_margin=verdict.singularity_margin,
            assembly="+++/+" if float(self.design.home_det_a) > 0 else "+++/-",
            backend=self.name,
            time=time.time(),
        )

    def _accept(
        self,
        goal: FloatArray,
        last: FloatArray | None = None,
        before: FloatArray | None = None,
        period: float | None = None,
    ) -> None:
        """Raise GoalRefusedError unless the goal is safe (call with the lock held).

        An accepted goal is decided by the guard alone: a safe verdict means the home
        assembly mode exists and no two links come nearer than the margin there, which
        is the collision check of :func:`~spm_pin.collision.check_input` in that mode
        (tested: the two agree). Only a refused goal pays for the full report (it
        names the pairs, in the nearest real assembly mode when the home one does not
        exist).
        """
        verdict = self.guard.check(goal, previous=last, before_previous=before, period=period)
        if not verdict.safe:
            self._report(goal, last, before, period, verdict).require()

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


class KinematicBackend(GuardedTwin):
    """The model alone: a twin whose input angles jump to each accepted goal.

    Its state is computed when it is read, not when a goal is accepted, and kept
    until the next goal: a stream of goals (:meth:`command`) pays for the guard's
    checks only, and the exact smallest link distance (``min_distance``, the costly
    part) is computed with the distance of the nearest pair of the previous state
    as a cap, which prunes the other pairs early and gives the same minimum. While
    goals stream in, it is computed again at most every :data:`DISTANCE_INTERVAL`
    seconds (in between, a read gives the last one computed); after :meth:`move` it
    is always exact.

    Args:
        design: The SPM (default: the prototype); ignored when ``robot`` is given.
        robot: The robot with its collision checker (default
            ``spm.build_robot(design)``).
        limits: The guard's limits (default
            :class:`~spm_pin.hardware.config.SafetyLimits`).
        theta: The starting input angles [rad] (default: home, [0, 0, 0]); must be
            safe.

    Attributes:
        name: ``"kinematic"``.
        design: The design of the robot.
        robot: The robot model.
        guard: The safety guard every goal passes.
    """

    name = "kinematic"

    def __init__(
        self,
        design: SPMDesign | None = None,
        *,
        robot: SPMRobot | None = None,
        limits: SafetyLimits | None = None,
        theta: npt.ArrayLike | None = None,
    ) -> None:
        super().__init__(design, robot=robot, limits=limits)
        start: FloatArray = np.zeros(3) if theta is None else _theta(theta)
        report = self._report(start).require()
        self._theta: FloatArray = start
        self._state: TwinState | None = self._compute_state(start, report.min_distance)
        # The exact distances: a robot of their own (built at the first read after
        # a goal) and the link pair nearest at the last read, whose distance caps
        # the search of the next minimum.
        self._distance_lock = threading.Lock()
        self._streaming = False  # the last goal came by command() (a stream)
        self._last_distance: tuple[float, float] | None = None  # (monotonic time, m)
        self._distance_robot: SPMRobot | None = None
        self._nearest: LinkPair | None = None

    def _min_distance(self, theta: FloatArray) -> float:
        """The exact smallest link distance at an accepted goal [m] (home assembly
        mode, every checked pair, as :func:`~spm_pin.collision.check_input`).

        Computed on a robot of its own (under its own lock), so that the twin's lock
        is not held meanwhile and goals keep being accepted. The distance of the pair
        nearest last time bounds the minimum from above; with it as the cap, the
        other pairs stop as soon as they cannot be nearer.
        """
        from ..collision import build_robot
        from ..collision.checker import checker_of

        with self._distance_lock:
            if self._distance_robot is None:
                self._distance_robot = build_robot(self.design)
            robot = self._distance_robot
            checker = checker_of(robot)
            q = robot.configuration(theta)
            nearest = self._nearest
            if nearest is not None:
                cap = checker.distances(q, pairs=[nearest])[nearest]
                if math.isfinite(cap) and cap > 0.0:
                    return float(checker.clearances(q[None], include_fixed=True, cap=cap)[0])
            distances = checker.distances(q)
            self._nearest = min(distances, key=distances.__getitem__)
            return float(distances[self._nearest])

    def state(self) -> TwinState:
        """The current state (its ``time`` is now); computed at the first read after
        a goal, then kept until the next.

        The exact distances are computed without the twin's lock: a goal accepted
        meanwhile is not held up, and this read answers the state at the goal it
        started from (its own ``theta``, every value exact there).
        """
        with self._lock:
            theta = self._theta
        return self._state_at(theta)

    def _state_at(self, theta: FloatArray) -> TwinState:
        """The state at ``theta``, an accepted goal (the current one, or one that a
        later goal has replaced meanwhile); kept when it is still the current one."""
        with self._lock:
            if self._state is not None and self._theta is theta:
                return dataclasses.replace(self._state, time=time.time(), stops=self.stops)
        now = time.monotonic()
        recent = self._last_distance
        if self._streaming and recent is not None and now - recent[0] < DISTANCE_INTERVAL:
            min_distance = recent[1]  # goals streaming in: at most DISTANCE_INTERVAL old
        else:
            min_distance = self._min_distance(theta)
            self._last_distance = (time.monotonic(), min_distance)  # its age counts from now
        with self._lock:
            state = self._compute_state(theta, min_distance)
            if self._theta is theta:
                self._state = state
            return dataclasses.replace(state, time=time.time(), stops=self.stops)

    def joints(self) -> FloatArray:
        """The current input angles [rad], (3,)."""
        with self._lock:
            theta: FloatArray = self._theta.copy()
        return theta

    def command(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
    ) -> None:
        """Jump to a goal [rad], (3,), if it is safe, without reading the state back
        (what a streamed goal needs; :meth:`move` answers the state too).

        Arguments and errors as :meth:`move`.
        """
        self._command(theta, previous, before_previous, period, streamed=True)

    def command_quick(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
    ) -> bool:
        """:meth:`command` without the report of a refusal: True when the goal was
        safe and taken, False when the guard refused it (nothing moved). Costs the
        guard's checks alone (a fraction of a millisecond), so a server may call it
        on its event loop and leave only refusals, whose report costs milliseconds,
        to :meth:`command` in a worker thread.

        Raises:
            InputError: as :meth:`move`.
        """
        goal, last, before = _goal_arguments(theta, previous, before_previous)
        with self._lock:
            verdict = self.guard.check(goal, previous=last, before_previous=before, period=period)
            if not verdict.safe:
                return False
            self._theta = goal
            self._state = None
            self._streaming = True
        return True

    def _command(
        self,
        theta: npt.ArrayLike,
        previous: npt.ArrayLike | None,
        before_previous: npt.ArrayLike | None,
        period: float | None,
        *,
        streamed: bool = False,
    ) -> FloatArray:
        goal, last, before = _goal_arguments(theta, previous, before_previous)
        with self._lock:
            self._accept(goal, last, before, period)
            self._theta = goal
            self._state = None
            self._streaming = streamed
        return goal

    def move(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
    ) -> TwinState:
        """Jump to a goal [rad], (3,), if it is safe.

        Args:
            theta: The goal [rad], (3,).
            previous: For a stream of goals: the goal commanded before [rad]; with
                ``period`` the guard checks the speed |theta - previous| / period.
            before_previous: The goal commanded before ``previous`` [rad]; the
                guard then checks the acceleration too.
            period: Time since ``previous`` was commanded [s].

        Returns:
            The state at the goal.

        Raises:
            InputError: not 3 finite numbers.
            GoalRefusedError: the goal is unsafe (an UnsafeCommandError; its
                ``report`` says why); the state is unchanged.
        """
        return self._state_at(self._command(theta, previous, before_previous, period))

    def stop(self, reason: str | None = None) -> TwinState:
        """Nothing is ever in motion in the kinematic twin: it holds still, counts
        the stop (``stops``, ``last_stop_reason``) and answers the state."""
        with self._lock:
            self.stops += 1
            self.last_stop_reason = reason
        return self.state()
