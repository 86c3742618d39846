"""Gymnasium environments of coaxial SPMs (the ``rl`` extra: ``pip install spm-pin[rl]``).

Importing this package registers, with Gymnasium:

* ``spm_pin/Orient-v0``: reach and hold a goal orientation with input-speed
  commands, kinematically, under the servos' guard (:class:`OrientEnv`); its native
  vector environment :class:`OrientVectorEnv` steps N robots as numpy batches
  (``gymnasium.make_vec("spm_pin/Orient-v0", num_envs=N,
  vectorization_mode="vector_entry_point")``).
* ``spm_pin/OrientDynamic-v0``: the same task on the robot's reduced dynamics under
  its servos, position or torque actuation (:class:`OrientDynamicEnv`, physics
  :class:`PhysicsSettings`); its native vector environment
  :class:`OrientDynamicVectorEnv`.

Options: :class:`OrientSettings` (design, servo limits, goal sampling, safety mode,
reward weights :class:`RewardWeights`, observation noise, calibration errors drawn at
each reset :class:`CalibrationSpread`), passed as keyword
arguments to ``gymnasium.make`` (with the fields of :class:`PhysicsSettings` for the
dynamic environment).

A scripted baseline, :class:`ScriptedPolicy` (inverse kinematics, a certified path and
a braking profile, from the observation alone), and :func:`evaluate_policy`, which
measures any policy's success rate.
"""

from __future__ import annotations

import gymnasium

from ._core import OBSERVATION_SIZE, geodesic_angle
from ._dynamic import ACTUATIONS, PhysicsSettings
from ._render import FRAME_PIXELS
from .baseline import ScriptedPolicy, evaluate_policy
from .orient import RENDER_MODES, OrientEnv
from .orient_dynamic import OrientDynamicEnv
from .settings import (
    GOAL_MODES,
    SAFETY_MODES,
    START_MODES,
    CalibrationSpread,
    OrientSettings,
    RewardWeights,
)
from .vector import OrientVectorEnv
from .vector_dynamic import OrientDynamicVectorEnv

__all__ = [
    "ACTUATIONS",
    "ENV_IDS",
    "FRAME_PIXELS",
    "GOAL_MODES",
    "OBSERVATION_SIZE",
    "RENDER_MODES",
    "SAFETY_MODES",
    "START_MODES",
    "CalibrationSpread",
    "OrientDynamicEnv",
    "OrientDynamicVectorEnv",
    "OrientEnv",
    "OrientSettings",
    "OrientVectorEnv",
    "PhysicsSettings",
    "RewardWeights",
    "ScriptedPolicy",
    "evaluate_policy",
    "geodesic_angle",
]

#: The registered environment ids.
ENV_IDS = ("spm_pin/Orient-v0", "spm_pin/OrientDynamic-v0")

if "spm_pin/Orient-v0" not in gymnasium.registry:
    gymnasium.register(
        "spm_pin/Orient-v0",
        entry_point="spm_pin.envs.orient:OrientEnv",
        vector_entry_point="spm_pin.envs.vector:OrientVectorEnv",
    )

if "spm_pin/OrientDynamic-v0" not in gymnasium.registry:
    gymnasium.register(
        "spm_pin/OrientDynamic-v0",
        entry_point="spm_pin.envs.orient_dynamic:OrientDynamicEnv",
        vector_entry_point="spm_pin.envs.vector_dynamic:OrientDynamicVectorEnv",
    )
