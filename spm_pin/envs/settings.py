"""The options of the orientation environments (:class:`OrientSettings`)."""

from __future__ import annotations

import dataclasses
import math
import os

from ..design import SPMDesign
from ..errors import InputError
from ..hardware.config import SafetyLimits
from ..planning import PlanSettings

__all__ = [
    "GOAL_MODES",
    "MAX_CALIBRATION_SPREAD",
    "SAFETY_MODES",
    "START_MODES",
    "CalibrationSpread",
    "OrientSettings",
    "RewardWeights",
]

#: How goals are drawn at each reset.
GOAL_MODES = ("random", "fixed", "curriculum")
#: Where episodes start.
START_MODES = ("random", "home")
#: What an action whose end state is unsafe does.
SAFETY_MODES = ("clip", "terminate")


def _number(value: object, name: str, low: float, high: float, *, open_low: bool = False) -> float:
    """``value`` as a float in [low, high] (or (low, high]); InputError otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{name} must be a number, got {value!r}", argument=name, value=value)
    number = float(value)
    inside = (low < number if open_low else low <= number) and number <= high
    if not inside:  # NaN fails too
        bracket = "(" if open_low else "["
        raise InputError(
            f"{name} must lie in {bracket}{low:g}, {high:g}], got {value!r}",
            argument=name,
            value=value,
        )
    return number


def _count(value: object, name: str, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise InputError(
            f"{name} must be an integer in {low}..{high}, got {value!r}", argument=name, value=value
        )
    return value


def _choice(value: object, name: str, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise InputError(
            f"{name} must be one of {list(allowed)}, got {value!r}", argument=name, value=value
        )
    return str(value)


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """The terms of the reward of one step (each weight >= 0).

    reward = - orientation * e - effort * |a|^2 / 3 - clip * (1 - s)
    + success (on the step that ends the episode at the goal)
    - unsafe (on the step that ends it in ``"terminate"`` safety mode),

    with e the geodesic angle between the platform and the goal [rad], a the
    normalised action and s the fraction of the commanded step that the safety clip
    let through (1 when nothing was clipped).

    Attributes:
        orientation: Per radian of orientation error.
        effort: Per unit of mean squared normalised action.
        clip: Per unit of the step fraction the safety clip took away (the clearance
            term: it teaches to keep off the boundary of the safe set).
        success: Bonus when the goal has been held.
        unsafe: Penalty when an unsafe step ends the episode.
    """

    orientation: float = 1.0
    effort: float = 0.01
    clip: float = 0.5
    success: float = 10.0
    unsafe: float = 10.0

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            _number(getattr(self, field.name), field.name, 0.0, 1e6)


#: The largest standard deviation of a calibration error [rad] (5 deg).
MAX_CALIBRATION_SPREAD = math.radians(5.0)


@dataclasses.dataclass(frozen=True)
class CalibrationSpread:
    """Calibration errors drawn at each reset (domain randomisation for transfer to
    the prototype): the standard deviations [rad] of Gaussian errors of the
    calibration's parameters (:class:`~spm_pin.calibration.CalibrationParameters`),
    each in [0, :data:`MAX_CALIBRATION_SPREAD`]; all 0 (the default) draws none.

    The robot's controller observes the state through the model these errors make
    (believed input = true input + the offset's error; the platform rotation of the
    believed link angles at the believed inputs); the simulated robot, its safety,
    the reward and the ends are the nominal design's (``docs/envs.md``).

    Attributes:
        offsets: The encoder zero offsets' error, each input.
        alpha1: The proximal link angle's error.
        alpha2: The distal link angle's error.
        beta: The error of the platform joint axes' inclination.
    """

    offsets: float = 0.0
    alpha1: float = 0.0
    alpha2: float = 0.0
    beta: float = 0.0

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            name = f"calibration_error.{field.name}"
            object.__setattr__(self, field.name, _number(value, name, 0.0, MAX_CALIBRATION_SPREAD))

    @property
    def active(self) -> bool:
        """Whether any error is drawn (some standard deviation above 0)."""
        return any(getattr(self, field.name) > 0.0 for field in dataclasses.fields(self))


@dataclasses.dataclass(frozen=True)
class OrientSettings:
    """Options of ``spm_pin/Orient-v0`` (every one has a default).

    Attributes:
        design: The SPM (default: the prototype); coaxial designs only (the safe set
            lives in the gap plane).
        limits: The servos' guard limits: speed, acceleration, joint limits,
            clearance margin, singularity margin, dexterity (default
            :class:`~spm_pin.hardware.config.SafetyLimits`).
        control_period: Time of one step [s]; the commanded speeds are held for it.
        max_steps: Steps before an episode is truncated.
        goal: ``"random"``: a goal anywhere in the safe orientation workspace;
            ``"fixed"``: ``goal_theta`` every episode; ``"curriculum"``: a goal within
            ``curriculum_level`` of the start (a fraction of the largest distance in
            the gap plane, and of half a turn about the axis).
        goal_theta: The input angles [rad] whose platform orientation is the goal in
            ``"fixed"`` mode (default: home, the identity).
        curriculum_level: In [0, 1] (``set_curriculum`` changes it later).
        start: ``"random"`` (anywhere in the safe set) or ``"home"``.
        tolerance: Orientation error [rad] that counts as at the goal.
        hold_steps: Consecutive steps at the goal that end the episode.
        safety: ``"clip"``: an unsafe step is shortened to the furthest safe
            fraction (bisection); ``"terminate"``: it is not taken, and the episode
            ends with the penalty ``weights.unsafe``.
        clip_iterations: Bisection steps of the safety clip (the step is known to
            ``2**-clip_iterations`` of its length).
        limit_acceleration: Keep the change of the commanded speed within the
            guard's acceleration limit (a sudden stop by the safety clip can exceed
            it).
        observation_noise: Standard deviation of the Gaussian noise added to the
            observed state (not to the goal); 0 turns it off.
        weights: The reward terms.
        cover: Path of a saved :class:`~spm_pin.planning.SafeCover` of this design's
            safe set with these limits (:meth:`~spm_pin.planning.SafeCover.save` of
            ``SafeCover(safe_set_of(the_design, plan_settings))`` after ``fill``), or
            None. With a cover, a state within the joint limits whose gaps lie in a
            cell the cover certified safe passes the guard's checks without them
            (a table lookup); every other state is checked as without a cover, so
            the environment behaves the same, only faster. A file that is not such a
            cover is refused when the environment is made.
        cover_only: With ``cover``: the certified cells are the environment's safe
            set. A state within the joint limits counts as safe when its gaps lie in
            a certified cell, and as unsafe otherwise, without a check; starts and
            goals are drawn from the safe vertices in certified cells. Conservative
            (every certified cell is safe everywhere) and fast (no collision check
            in a step), at the price of the thin band along the safe set's boundary
            that the cover leaves out (its width shrinks with the cover's level:
            see ``docs/envs.md``). False: the states outside certified cells are
            checked.
        calibration_error: Calibration errors drawn at each reset, which the
            observation sees (:class:`CalibrationSpread`; none by default).
    """

    design: SPMDesign | None = None
    limits: SafetyLimits | None = None
    control_period: float = 0.02
    max_steps: int = 250
    goal: str = "random"
    goal_theta: tuple[float, float, float] = (0.0, 0.0, 0.0)
    curriculum_level: float = 1.0
    start: str = "random"
    tolerance: float = math.radians(2.0)
    hold_steps: int = 5
    safety: str = "clip"
    clip_iterations: int = 8
    limit_acceleration: bool = True
    observation_noise: float = 0.0
    weights: RewardWeights = dataclasses.field(default_factory=RewardWeights)
    cover: str | None = None
    cover_only: bool = False
    calibration_error: CalibrationSpread = dataclasses.field(default_factory=CalibrationSpread)

    def __post_init__(self) -> None:
        if self.design is not None and not isinstance(self.design, SPMDesign):
            raise InputError(
                f"design must be an SPMDesign, got {type(self.design).__name__}",
                argument="design",
                value=self.design,
            )
        if self.limits is not None and not isinstance(self.limits, SafetyLimits):
            raise InputError(
                f"limits must be SafetyLimits, got {type(self.limits).__name__}",
                argument="limits",
                value=self.limits,
            )
        if not isinstance(self.calibration_error, CalibrationSpread):
            raise InputError(
                "calibration_error must be a CalibrationSpread, got "
                f"{type(self.calibration_error).__name__}",
                argument="calibration_error",
                value=self.calibration_error,
            )
        if not isinstance(self.weights, RewardWeights):
            raise InputError(
                f"weights must be RewardWeights, got {type(self.weights).__name__}",
                argument="weights",
                value=self.weights,
            )
        _number(self.control_period, "control_period", 0.0, 1.0, open_low=True)
        _count(self.max_steps, "max_steps", 1, 10**7)
        _choice(self.goal, "goal", GOAL_MODES)
        _choice(self.start, "start", START_MODES)
        _choice(self.safety, "safety", SAFETY_MODES)
        _number(self.curriculum_level, "curriculum_level", 0.0, 1.0)
        _number(self.tolerance, "tolerance", 0.0, math.pi, open_low=True)
        _count(self.hold_steps, "hold_steps", 1, 10**6)
        _count(self.clip_iterations, "clip_iterations", 1, 40)
        _number(self.observation_noise, "observation_noise", 0.0, 1.0)
        goal = self.goal_theta
        if (
            not isinstance(goal, tuple | list)
            or len(goal) != 3
            or not all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                for x in goal
            )
        ):
            raise InputError(
                f"goal_theta must be 3 finite input angles [rad], got {goal!r}",
                argument="goal_theta",
                value=goal,
            )
        object.__setattr__(self, "goal_theta", tuple(float(x) for x in goal))
        if self.cover is not None:
            cover: object = self.cover
            path = os.fspath(cover) if isinstance(cover, str | os.PathLike) else None
            if not isinstance(path, str) or not path:
                raise InputError(
                    f"cover must be None or the path of a saved SafeCover, got {cover!r}",
                    argument="cover",
                    value=cover,
                )
            object.__setattr__(self, "cover", path)
        if not isinstance(self.cover_only, bool):
            raise InputError(
                f"cover_only must be True or False, got {self.cover_only!r}",
                argument="cover_only",
                value=self.cover_only,
            )
        if self.cover_only and self.cover is None:
            raise InputError(
                "cover_only needs a cover (the path of a saved SafeCover)",
                argument="cover_only",
                value=self.cover_only,
            )

    @property
    def the_design(self) -> SPMDesign:
        """The design (the prototype when none was given)."""
        return self.design or SPMDesign.prototype()

    @property
    def the_limits(self) -> SafetyLimits:
        """The guard's limits (the defaults when none were given)."""
        return self.limits or SafetyLimits()

    @property
    def plan_settings(self) -> PlanSettings:
        """The safe set's thresholds: the guard's clearance margin, dexterity and
        singularity margin."""
        limits = self.the_limits
        return PlanSettings(
            margin=limits.collision_margin,
            min_dexterity=limits.min_dexterity,
            min_singularity_margin=limits.min_singularity_margin,
        )
