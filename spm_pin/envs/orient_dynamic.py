"""``spm_pin/OrientDynamic-v0``: point the platform at a goal orientation, dynamically.

The task, the goals, the observation (21 numbers), the reward, the ends, the safety
modes and the rendering are those of ``spm_pin/Orient-v0``
(:class:`~spm_pin.envs.OrientEnv`); the robot moves by the reduced closed-loop
dynamics under its servos (:class:`~spm_pin.dynamics.ReducedDynamics`,
:class:`~spm_pin.dynamics.ServoModel`), several physics steps per control period.

**Action** (:class:`~spm_pin.envs.PhysicsSettings`): with ``actuation="position"``
(default), three normalised goal-position speeds in [-1, 1]: each servo's goal
position moves by ``a * max_speed * control_period`` per step and the servos' PD
loops follow it within their torque-speed envelope (a zero action holds the goal);
with ``actuation="torque"``, three motor torques over the stall torque, clipped to the
envelope at the present speed.

**Observation**: as ``spm_pin/Orient-v0``, the speeds being the real input speeds over
``max_speed``, clipped to [-1, 1].

**Safety**: the state at the end of each step passes the guard's static checks. With
``safety="clip"`` an unsafe end (or a state the dynamics cannot step from) stops the
robot at the last safe physics step of the period, speeds zeroed, goal positions set
there; with ``safety="terminate"`` the robot stays at the step's start, stopped, and
the episode ends with the penalty.

**Info** adds ``theta_dot`` [rad/s], ``servo_goal`` [rad], ``torque`` (of the last
physics step) [N m], ``torque_speed`` (the speeds it was applied at) [rad/s] and
``servo_load`` (largest servo load of the step; <= 1 inside the torque-speed envelope).
"""

from __future__ import annotations

from typing import Any

from ._dynamic import DynamicCore, PhysicsSettings, physics_from
from .orient import OrientEnv
from .settings import OrientSettings

__all__ = ["OrientDynamicEnv"]


class OrientDynamicEnv(OrientEnv):
    """Reach and hold a goal orientation with the robot's dynamics (see the module).

    Args:
        settings: The task's options (default :class:`~spm_pin.envs.OrientSettings`).
        render_mode: None, ``"rgb_array"`` or ``"human"``.
        physics: The physics (default :class:`~spm_pin.envs.PhysicsSettings`).
        **options: Fields of :class:`~spm_pin.envs.OrientSettings` or of
            :class:`~spm_pin.envs.PhysicsSettings` that replace those of ``settings``
            and ``physics`` (what ``gymnasium.make("spm_pin/OrientDynamic-v0", ...)``
            passes).

    Attributes:
        settings: The task's options in force.
        physics: The physics in force.
        core: The batched state (one robot).
        single: Its robot's step (:class:`~spm_pin.envs._single.SingleStep`).
    """

    core: DynamicCore

    def __init__(
        self,
        settings: OrientSettings | None = None,
        render_mode: str | None = None,
        physics: PhysicsSettings | None = None,
        **options: Any,
    ) -> None:
        self.physics, rest = physics_from(physics, options)
        super().__init__(settings, render_mode, **rest)

    def _new_core(self) -> DynamicCore:
        return DynamicCore(self.settings, 1, self.physics)
