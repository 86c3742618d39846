"""Gymnasium environments of coaxial SPMs (the ``rl`` extra: ``pip install spm-pin[rl]``).

Importing this package registers, with Gymnasium:

* ``spm_pin/Orient-v0``: reach and hold a goal orientation with input-speed
  commands, kinematically, under the servos' guard (:class:`OrientEnv`); its native
  vector environment :class:`OrientVectorEnv` steps N robots as numpy batches
  (``gymnasium.make_vec("spm_pin/Orient-v0", num_envs=N,
  vectorization_mode="vector_entry_point")``).

Options: :class:`OrientSettings` (design, servo limits, goal sampling, safety mode,
reward weights :class:`RewardWeights`, observation noise), passed as keyword
arguments to ``gymnasium.make``.
"""

from __future__ import annotations

import gymnasium

from ._core import OBSERVATION_SIZE, geodesic_angle
from ._render import FRAME_PIXELS
from .orient import RENDER_MODES, OrientEnv
from .settings import GOAL_MODES, SAFETY_MODES, START_MODES, OrientSettings, RewardWeights
from .vector import OrientVectorEnv

__all__ = [
    "ENV_IDS",
    "FRAME_PIXELS",
    "GOAL_MODES",
    "OBSERVATION_SIZE",
    "RENDER_MODES",
    "SAFETY_MODES",
    "START_MODES",
    "OrientEnv",
    "OrientSettings",
    "OrientVectorEnv",
    "RewardWeights",
    "geodesic_angle",
]

#: The registered environment ids.
ENV_IDS = ("spm_pin/Orient-v0",)

if "spm_pin/Orient-v0" not in gymnasium.registry:
    gymnasium.register(
        "spm_pin/Orient-v0",
        entry_point="spm_pin.envs.orient:OrientEnv",
        vector_entry_point="spm_pin.envs.vector:OrientVectorEnv",
    )
