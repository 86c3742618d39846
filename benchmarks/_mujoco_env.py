"""The peer of the dynamic environment: the orientation task as a Gymnasium environment
built the usual way on MuJoCo (``benchmarks/bench_envs.py`` times it).

:class:`MujocoOrientEnv` loads the exported MJCF (``urdf/spm.xml``: the tree and the two
loop-closing welds), adds one position actuator per input joint with the servo's PD
gains and stall torque (``kp``, ``kv``, ``forcerange``), and steps it as Gymnasium's
MuJoCo environments do: the action sets ``data.ctrl`` once per control period and
``mj_step(model, data, nstep=frame_skip)`` runs the physics steps in C, at the same
physics step as ``spm_pin/OrientDynamic-v0`` (1 ms, semi-implicit Euler, MuJoCo's
default weld stiffness).

The task is ``spm_pin/OrientDynamic-v0``'s with position actuation: three normalised
goal-position speeds in [-1, 1] (times ``max_speed``, kept within the guard's
acceleration of the last ones), the same 21 observed numbers (the platform rotation and
the goal in 6-D form, sin and cos of the inputs, the speeds over ``max_speed``), the
same orientation reward and ends. What it leaves out, as such environments do: the
guard's safety checks (joint limits, assembly mode, singularity margin, clearance) and
the torque-speed envelope (the torque is clipped to the stall torque only); the
episodes start at home (a random closed start needs the loop-closure solver), the
goals come from a bank given to the constructor.

MuJoCo is imported when the environment is built (the ``sim`` extra).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

__all__ = ["MJCF", "MujocoOrientEnv", "weld_residual"]

FloatArray = npt.NDArray[np.float64]
ObsArray = npt.NDArray[np.float32]

#: The committed MJCF of the prototype.
MJCF = Path(__file__).resolve().parent.parent / "urdf" / "spm.xml"
#: The bodies that the welds hold onto the platform.
WELDED_BODIES = ("platform_leg2", "platform_leg3")


def _six_d(R: FloatArray) -> FloatArray:
    """The first two columns of R (3, 3), column after column (6,)."""
    six: FloatArray = np.concatenate([R[:, 0], R[:, 1]])
    return six


def _angle(R: FloatArray, G: FloatArray) -> float:
    """Geodesic angle [rad] between two rotations (3, 3)."""
    norm = float(np.sqrt(np.sum((R - G) ** 2)))
    return 2.0 * math.asin(min(norm / math.sqrt(8.0), 1.0))


def weld_residual(model: Any, data: Any) -> float:
    """Largest angle [rad] between the platform and the bodies welded onto it (the
    closure error of MuJoCo's soft welds; 0 for a closed loop)."""
    platform = data.xmat[model.body("platform").id].reshape(3, 3)
    return max(
        _angle(data.xmat[model.body(name).id].reshape(3, 3), platform) for name in WELDED_BODIES
    )


class MujocoOrientEnv(gymnasium.Env[ObsArray, ObsArray]):
    """The orientation task on MuJoCo (see the module).

    Args:
        goals: Goal rotations (m, 3, 3); each reset draws one.
        mjcf: The MJCF file (default: the committed prototype's).
        control_period: Time of one step [s].
        physics_dt: MuJoCo's time step [s].
        kp, kv: The servo's position [N m/rad] and speed [N m s/rad] gains.
        stall_torque: Largest actuator torque [N m].
        max_speed: Goal-position speed of an action of 1 [rad/s].
        max_acceleration: Largest change of that speed [rad/s^2].
        max_steps: Steps before an episode is truncated.
        tolerance: Orientation error that counts as at the goal [rad].
        hold_steps: Steps at the goal that end the episode.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012

    def __init__(
        self,
        goals: FloatArray,
        *,
        mjcf: Path = MJCF,
        control_period: float = 0.02,
        physics_dt: float = 1e-3,
        kp: float = 20.0,
        kv: float = 0.5,
        stall_torque: float = 7.3,
        max_speed: float = math.radians(90.0),
        max_acceleration: float = math.radians(360.0),
        max_steps: int = 250,
        tolerance: float = math.radians(2.0),
        hold_steps: int = 5,
    ) -> None:
        import mujoco

        spec = mujoco.MjSpec.from_file(str(mjcf))
        for i in (1, 2, 3):
            actuator = spec.add_actuator()
            actuator.name = f"servo_{i}"
            actuator.target = f"u_{i}"
            actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
            actuator.set_to_position(kp=kp, kv=kv)
            actuator.forcelimited = True
            actuator.forcerange = [-stall_torque, stall_torque]
        self.model = spec.compile()
        self.model.opt.timestep = physics_dt
        self.data = mujoco.MjData(self.model)
        self._mj_step = mujoco.mj_step
        self._mj_reset = mujoco.mj_resetData
        self._mj_forward = mujoco.mj_forward
        self.frame_skip = max(1, round(control_period / physics_dt))
        self.control_period = control_period
        joints = [self.model.joint(f"u_{i}") for i in (1, 2, 3)]
        self._qpos = np.array([int(j.qposadr[0]) for j in joints])
        self._qvel = np.array([int(j.dofadr[0]) for j in joints])
        self._platform = int(self.model.body("platform").id)
        self.goals = np.asarray(goals, dtype=float).reshape(-1, 3, 3)
        self.max_speed = float(max_speed)
        self._dv = float(max_acceleration) * control_period
        self.max_steps = int(max_steps)
        self.tolerance = float(tolerance)
        self.hold_steps = int(hold_steps)
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(21,), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.goal = np.eye(3)
        self.target = np.zeros(3)
        self.command = np.zeros(3)
        self.steps = 0
        self.hold = 0

    def _rotation(self) -> FloatArray:
        R: FloatArray = self.data.xmat[self._platform].reshape(3, 3)
        return R

    def _observe(self) -> ObsArray:
        theta = self.data.qpos[self._qpos]
        speed = np.clip(self.data.qvel[self._qvel] / self.max_speed, -1.0, 1.0)
        parts = [_six_d(self._rotation()), _six_d(self.goal), np.sin(theta), np.cos(theta), speed]
        return np.concatenate(parts).astype(np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[ObsArray, dict[str, Any]]:
        """Home, at rest, and a goal drawn from the bank."""
        super().reset(seed=seed, options=options)
        self._mj_reset(self.model, self.data)
        self._mj_forward(self.model, self.data)
        self.goal = self.goals[int(self.np_random.integers(self.goals.shape[0]))]
        self.target = self.data.qpos[self._qpos].copy()
        self.command = np.zeros(3)
        self.data.ctrl[:] = self.target
        self.steps = self.hold = 0
        return self._observe(), {"orientation_error": _angle(self._rotation(), self.goal)}

    def step(self, action: ObsArray) -> tuple[ObsArray, float, bool, bool, dict[str, Any]]:
        """One control period: the goal positions move at ``action * max_speed``."""
        a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)
        self.command = np.clip(a * self.max_speed, self.command - self._dv, self.command + self._dv)
        self.target = self.target + self.command * self.control_period
        self.data.ctrl[:] = self.target
        self._mj_step(self.model, self.data, nstep=self.frame_skip)
        error = _angle(self._rotation(), self.goal)
        self.hold = self.hold + 1 if error <= self.tolerance else 0
        self.steps += 1
        terminated = self.hold >= self.hold_steps
        truncated = self.steps >= self.max_steps and not terminated
        reward = -error - 0.01 * float(np.mean(a**2)) + 10.0 * terminated
        info = {"orientation_error": error, "success": terminated}
        return self._observe(), reward, terminated, truncated, info

    def closure_residual(self) -> float:
        """The welds' closure error now [rad] (see :func:`weld_residual`)."""
        return weld_residual(self.model, self.data)
