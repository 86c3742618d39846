"""``spm_pin/Orient-v0``: point the platform at a goal orientation, kinematically.

**Action**: three normalised input-speed commands in [-1, 1]; times the guard's
``max_speed`` they are the speeds [rad/s] of the input shafts, held for one control
period (with ``limit_acceleration``, first kept within the guard's acceleration of the
previous speeds).

**Safety**: the end of every step is checked with the static checks of the servos'
guard (joint limits, home assembly mode, singularity margin, dexterity, clearance
margin, through :meth:`~spm_pin.planning.SafeSet.evaluate`). An unsafe step is
shortened to its furthest safe fraction (``safety="clip"``, bisection) or not taken,
ending the episode with a penalty (``safety="terminate"``). No state the environment
enters is refused by the guard.

**Observation** (21 numbers, float32, each in [-1, 1]): the platform rotation R in
its continuous 6-D form (its first two columns: no jump anywhere, unlike Euler angles
or a quaternion with w >= 0, whose sign flips where w = 0), the goal in the same form,
sin and cos of the three input angles (the platform turns endlessly about the axis),
and the input speeds divided by ``max_speed``.

**Reward**, **termination** and **truncation**: see
:class:`~spm_pin.envs.settings.RewardWeights` and
:class:`~spm_pin.envs.settings.OrientSettings`: at the goal (within ``tolerance``)
for ``hold_steps`` steps ends the episode; ``max_steps`` truncates it.

**Rendering**: ``"rgb_array"`` draws the unit vectors u, w_i, v_i of the legs on the
sphere with matplotlib (the goal's platform axes dashed); ``"human"`` shows the robot
in meshcat (:class:`~spm_pin.viz.Visualizer`, started at the first render).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from ..calibration import CalibrationParameters
from ..errors import InputError
from ._core import _ROW, OBSERVATION_SIZE, OrientCore
from ._render import HumanView, draw_frame
from ._single import SingleStep
from .settings import OrientSettings

__all__ = ["RENDER_MODES", "OrientEnv", "settings_from"]

ObsArray = npt.NDArray[np.float32]
#: The render modes of both environments.
RENDER_MODES = ("rgb_array", "human")


def settings_from(settings: OrientSettings | None, options: dict[str, Any]) -> OrientSettings:
    """``settings`` (default :class:`OrientSettings`) with ``options`` (its field names,
    as ``gymnasium.make`` passes keyword arguments) replaced."""
    base = settings or OrientSettings()
    if settings is not None and not isinstance(settings, OrientSettings):
        raise InputError(
            f"settings must be OrientSettings, got {type(settings).__name__}",
            argument="settings",
            value=settings,
        )
    names = {f.name for f in dataclasses.fields(OrientSettings)}
    unknown = sorted(set(options) - names)
    if unknown:
        raise InputError(
            f"unknown options {unknown}; known: {sorted(names)}", argument="options", value=unknown
        )
    return dataclasses.replace(base, **options) if options else base


def check_render_mode(render_mode: str | None) -> str | None:
    """``render_mode`` when it is None or one of :data:`RENDER_MODES`."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise InputError(
            f"render_mode must be None or one of {list(RENDER_MODES)}, got {render_mode!r}",
            argument="render_mode",
            value=render_mode,
        )
    return render_mode


def observation_space() -> spaces.Box:
    """The observation space of one robot (21 numbers in [-1, 1])."""
    return spaces.Box(-1.0, 1.0, shape=(OBSERVATION_SIZE,), dtype=np.float32)


def action_space() -> spaces.Box:
    """The action space of one robot (3 normalised speeds in [-1, 1])."""
    return spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)


class OrientEnv(gymnasium.Env[ObsArray, npt.NDArray[np.float32]]):
    """Reach and hold a goal orientation (see the module).

    Args:
        settings: The options (default :class:`OrientSettings`).
        render_mode: None, ``"rgb_array"`` or ``"human"``.
        **options: Fields of :class:`OrientSettings` that replace those of
            ``settings`` (what ``gymnasium.make("spm_pin/Orient-v0", ...)`` passes).

    Attributes:
        settings: The options in force.
        core: The batched state (one robot).
        single: Its robot's step (:class:`~spm_pin.envs._single.SingleStep`).
    """

    metadata: dict[str, Any] = {"render_modes": list(RENDER_MODES), "render_fps": 50}  # noqa: RUF012

    def __init__(
        self,
        settings: OrientSettings | None = None,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        self.settings = settings_from(settings, options)
        self.render_mode = check_render_mode(render_mode)
        self.core = self._new_core()
        #: Robot 0 of ``core``, stepped as this environment's robot.
        self.single = SingleStep(self.core)
        # Box's own type parameter is wider than the arrays it holds.
        self.observation_space = observation_space()  # type: ignore[assignment]
        self.action_space = action_space()  # type: ignore[assignment]
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.settings.control_period)}
        self._view: HumanView | None = None

    def _new_core(self) -> OrientCore:
        """The batched state of this environment's one robot (built once, in
        ``__init__``; a subclass with another core overrides this)."""
        return OrientCore(self.settings, 1)

    def set_curriculum(self, level: float) -> None:
        """The curriculum level in [0, 1] for the next resets (``goal="curriculum"``)."""
        checked = dataclasses.replace(self.settings, curriculum_level=level)
        self.core.level = checked.curriculum_level

    def calibration(self) -> CalibrationParameters | None:
        """The calibration parameters this episode's observations are computed with
        (drawn at the reset with ``calibration_error``), or None without calibration
        errors."""
        believed = self.core.believed
        return None if believed is None else believed.parameters[0]

    def _info(self, error: float) -> dict[str, Any]:
        return {
            "orientation_error": error,
            "theta": self.core.theta[0].copy(),
            "goal_theta": self.core.goal_theta[0].copy(),
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[ObsArray, dict[str, Any]]:
        """Start an episode: a safe start and a goal drawn from the env's generator."""
        super().reset(seed=seed, options=options)
        rngs = [self.np_random]
        self.core.reset_rows(_ROW, rngs)
        obs = self.core.observe(_ROW, rngs)[0]
        if self.render_mode == "human":
            self.render()
        return obs, self._info(float(self.core.error(_ROW)[0]))

    def step(self, action: npt.ArrayLike) -> tuple[ObsArray, float, bool, bool, dict[str, Any]]:
        """One control period with the normalised action (3,) in [-1, 1] (see the
        module); the info: ``orientation_error`` [rad], ``step_fraction``, ``success``,
        ``unsafe`` and the core's :data:`~spm_pin.envs._core.OrientCore.RECORD` entries
        (``theta``, ``goal_theta`` and what the dynamic environment adds)."""
        rng = self._np_random  # the property's check, once
        out = self.single.step(action, self.np_random if rng is None else rng)
        if self.render_mode == "human":
            self.render()
        return out

    def render(self) -> npt.NDArray[np.uint8] | None:
        """The picture of the robot (``rgb_array``) or the meshcat scene (``human``)."""
        if self.render_mode == "rgb_array":
            return draw_frame(self.design_axes())
        if self.render_mode == "human":
            if self._view is None:
                self._view = HumanView(self.core.design)
            self._view.show(self.core.theta[0])
        return None

    def design_axes(self) -> tuple[npt.NDArray[np.float64], ...]:
        """(u, w, v, goal v) of the robot: unit vectors, rows per leg, (3, 3) each."""
        from ..kinematics import forward_kinematics

        fk = forward_kinematics(self.core.theta[0], self.core.design)
        goal_v = self.core.goal[0] @ self.core.design.v0.T
        return (self.core.design.u, fk.w, fk.v, goal_v.T)

    def close(self) -> None:
        """Stop the meshcat server of ``human`` rendering, if one runs."""
        if self._view is not None:
            self._view.close()
            self._view = None
