"""N copies of ``spm_pin/Orient-v0`` stepped as numpy batches (:class:`OrientVectorEnv`).

One :class:`~spm_pin.envs._core.OrientCore` holds every robot: forward kinematics,
the safety checks and the rewards of all N run as array operations, not N Python
environments. Sub-environment i draws its episodes from its own generator, seeded
like the single environment (``reset(seed=s)`` seeds sub-environment i with
``s + i``, as Gymnasium's own vector environments do), so N single environments
seeded alike give the same observations, rewards and ends, step for step.

Autoreset follows Gymnasium's default ``NEXT_STEP`` mode: a sub-environment whose
episode ended (terminated or truncated) at one step is reset at the next call of
:meth:`~OrientVectorEnv.step`, whose action for it is ignored; that step returns
its first observation of the new episode, reward 0 and neither end flag.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..calibration import CalibrationParameters
from ..errors import InputError
from ._actions import check_actions
from ._core import OrientCore
from ._render import HumanView, draw_frame
from .orient import (
    RENDER_MODES,
    action_space,
    check_render_mode,
    observation_space,
    settings_from,
)
from .settings import OrientSettings

__all__ = ["OrientVectorEnv"]

ObsArray = npt.NDArray[np.float32]
FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


class OrientVectorEnv(VectorEnv[ObsArray, npt.NDArray[np.float32], npt.NDArray[Any]]):
    """``num_envs`` orientation environments in one batch (see the module).

    Args:
        num_envs: Number of sub-environments (>= 1).
        settings: The options (default :class:`OrientSettings`).
        render_mode: None, ``"rgb_array"`` or ``"human"`` (both show sub-environment 0).
        **options: Fields of :class:`OrientSettings` that replace those of
            ``settings``.

    Attributes:
        settings: The options in force.
        core: The batched state of all robots.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": list(RENDER_MODES),
        "render_fps": 50,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        settings: OrientSettings | None = None,
        render_mode: str | None = None,
        **options: Any,
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise InputError(
                f"num_envs must be an integer >= 1, got {num_envs!r}",
                argument="num_envs",
                value=num_envs,
            )
        self.settings = settings_from(settings, options)
        self.render_mode = check_render_mode(render_mode)
        self.num_envs = num_envs
        self.core = self._new_core()
        self.single_observation_space = observation_space()
        self.single_action_space = action_space()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.settings.control_period)}
        self._rngs: list[np.random.Generator] = [
            seeding.np_random(None)[0] for _ in range(num_envs)
        ]
        self._all = np.arange(num_envs, dtype=np.intp)
        self._autoreset = np.zeros(num_envs, dtype=bool)
        self._view: HumanView | None = None

    def _new_core(self) -> OrientCore:
        """The batched state of the ``num_envs`` robots (built once, in ``__init__``; a
        subclass with another core overrides this)."""
        return OrientCore(self.settings, self.num_envs)

    @property
    def sub_generators(self) -> tuple[np.random.Generator, ...]:
        """Each sub-environment's random generator."""
        return tuple(self._rngs)

    def set_curriculum(self, level: float) -> None:
        """The curriculum level in [0, 1] for the next resets (``goal="curriculum"``)."""
        checked = dataclasses.replace(self.settings, curriculum_level=level)
        self.core.level = checked.curriculum_level

    def calibration(self, index: int) -> CalibrationParameters | None:
        """The calibration parameters that robot ``index``'s observations are
        computed with in its episode (drawn at its reset with ``calibration_error``),
        or None without calibration errors."""
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise InputError(f"index must be an integer, got {index!r}", argument="index")
        if not 0 <= index < self.num_envs:
            raise InputError(
                f"index must lie in 0..{self.num_envs - 1}, got {index}",
                argument="index",
                value=index,
            )
        believed = self.core.believed
        return None if believed is None else believed.parameters[int(index)]

    def _seeds(self, seed: int | list[int | None] | None) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, int):
            return [seed + i for i in range(self.num_envs)]
        seeds: list[int | None] = list(seed)
        if len(seeds) != self.num_envs:
            raise InputError(
                f"seed must be None, an int or {self.num_envs} seeds, got {len(seeds)}",
                argument="seed",
                value=seed,
            )
        return seeds

    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[ObsArray, dict[str, Any]]:
        """Start new episodes in every sub-environment (or in those of
        ``options["reset_mask"]``, a boolean array (num_envs,))."""
        seeds = self._seeds(seed)
        mask = np.ones(self.num_envs, dtype=bool)
        if options is not None and "reset_mask" in options:
            mask = np.asarray(options["reset_mask"])
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_:
                raise InputError(
                    f"options['reset_mask'] must be a boolean array of shape "
                    f"({self.num_envs},), got {mask!r}",
                    argument="reset_mask",
                    value=mask,
                )
        rows = np.flatnonzero(mask)
        for i in rows:
            if seeds[i] is not None:  # else the generator goes on, as in Env.reset
                self._rngs[i] = seeding.np_random(seeds[i])[0]
        if seeds[0] is not None:
            self._np_random, self._np_random_seed = seeding.np_random(seeds[0])
        self.core.reset_rows(rows, self._rngs)
        self._autoreset[rows] = False
        obs = self.core.observe(self._all, self._rngs)
        error = self.core.error(self._all)
        return obs, self._info(error, mask)

    def _info(self, error: FloatArray, mask: BoolArray) -> dict[str, Any]:
        return {
            "orientation_error": error,
            "_orientation_error": mask.copy(),
        }

    def step(
        self, actions: npt.ArrayLike
    ) -> tuple[ObsArray, FloatArray, BoolArray, BoolArray, dict[str, Any]]:
        """One control period for every sub-environment (actions (num_envs, 3)); those
        whose episode ended at the last step are reset instead."""
        values = check_actions(actions, (self.num_envs, 3))
        n = self.num_envs
        reward = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        fraction = np.ones(n)
        success = np.zeros(n, dtype=bool)
        unsafe = np.zeros(n, dtype=bool)
        error = np.zeros(n)
        restart = np.flatnonzero(self._autoreset)
        active = np.flatnonzero(~self._autoreset)
        # The order of the draws matches the single environment's: the reset rows
        # draw their episode, every row its observation noise after the step.
        self.core.reset_rows(restart, self._rngs)
        if active.size:
            result = self.core.step_rows(active, values[active])
            reward[active] = result.reward
            terminated[active] = result.terminated
            truncated[active] = result.truncated
            fraction[active] = result.fraction
            success[active] = result.success
            unsafe[active] = result.unsafe
            error[active] = result.error
        error[restart] = self.core.error(restart)
        obs = self.core.observe(self._all, self._rngs)
        self._autoreset = terminated | truncated
        stepped = ~np.isin(self._all, restart)
        info = self._info(error, np.ones(n, dtype=bool))
        info.update(
            step_fraction=fraction,
            _step_fraction=stepped,
            success=success,
            _success=stepped,
            unsafe=unsafe,
            _unsafe=stepped,
        )
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info

    def render(self) -> tuple[npt.NDArray[np.uint8], ...] | None:
        """Sub-environment 0: its picture (``rgb_array``, a tuple of one frame) or the
        meshcat scene (``human``)."""
        from ..kinematics import forward_kinematics

        core = self.core
        if self.render_mode == "rgb_array":
            fk = forward_kinematics(core.theta[0], core.design)
            goal_v = (core.goal[0] @ core.design.v0.T).T
            return (draw_frame((core.design.u, fk.w, fk.v, goal_v)),)
        if self.render_mode == "human":
            if self._view is None:
                self._view = HumanView(core.design)
            self._view.show(core.theta[0])
        return None

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the meshcat server of ``human`` rendering, if one runs."""
        if self._view is not None:
            self._view.close()
            self._view = None
