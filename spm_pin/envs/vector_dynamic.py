"""N copies of ``spm_pin/OrientDynamic-v0`` stepped as numpy batches
(:class:`OrientDynamicVectorEnv`).

One :class:`~spm_pin.envs._dynamic.DynamicCore` holds every robot: the reduced
dynamics, the servos, the safety checks and the rewards of all N run as array
operations. Seeding, autoreset (Gymnasium's ``NEXT_STEP``) and the info masks are
those of :class:`~spm_pin.envs.OrientVectorEnv`, so N single environments seeded
``seed + i`` give the same observations, rewards and ends, step for step.
"""

from __future__ import annotations

from typing import Any

import numpy.typing as npt

from ._dynamic import DynamicCore, PhysicsSettings, physics_from
from .settings import OrientSettings
from .vector import BoolArray, FloatArray, ObsArray, OrientVectorEnv

__all__ = ["OrientDynamicVectorEnv"]


class OrientDynamicVectorEnv(OrientVectorEnv):
    """``num_envs`` dynamic orientation environments in one batch (see the module).

    Args:
        num_envs: Number of sub-environments (>= 1).
        settings: The task's options (default :class:`~spm_pin.envs.OrientSettings`).
        render_mode: None, ``"rgb_array"`` or ``"human"`` (both show sub-environment 0).
        physics: The physics (default :class:`~spm_pin.envs.PhysicsSettings`).
        **options: Fields of :class:`~spm_pin.envs.OrientSettings` or of
            :class:`~spm_pin.envs.PhysicsSettings`.

    Attributes:
        settings: The task's options in force.
        physics: The physics in force.
        core: The batched state of all robots.
    """

    core: DynamicCore

    def __init__(
        self,
        num_envs: int = 1,
        settings: OrientSettings | None = None,
        render_mode: str | None = None,
        physics: PhysicsSettings | None = None,
        **options: Any,
    ) -> None:
        self.physics, rest = physics_from(physics, options)
        super().__init__(num_envs, settings, render_mode, **rest)

    def _new_core(self) -> DynamicCore:
        return DynamicCore(self.settings, self.num_envs, self.physics)

    def step(
        self, actions: npt.ArrayLike
    ) -> tuple[ObsArray, FloatArray, BoolArray, BoolArray, dict[str, Any]]:
        """One control period for every sub-environment (actions (num_envs, 3)); those
        whose episode ended at the last step are reset instead (their info entries
        masked out)."""
        stepped = ~self._autoreset
        obs, reward, terminated, truncated, info = super().step(actions)
        for key, value in self.core.extra_info(self._all).items():
            info[key] = value
            info[f"_{key}"] = stepped.copy()
        return obs, reward, terminated, truncated, info
