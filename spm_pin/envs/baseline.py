"""A scripted baseline for the orientation environments (:class:`ScriptedPolicy`,
:func:`evaluate_policy`).

:class:`ScriptedPolicy` is not learned: it is the controller a robotics engineer
would write, the bar a learned policy has to clear. It reads the observation alone
(the environment's settings give it the design, the servo limits and the safe set;
it never reads the robot's hidden state):

1. **The inputs from sin and cos.** ``atan2`` gives each input angle modulo a whole
   turn. The forward kinematics depend on each input only through the direction of
   its proximal link w_i, a function of (cos theta_i, sin theta_i), so the wrapped
   angles give the very same platform orientation. The gaps between neighbouring
   proximal links, D12 and D23 in (0, 360) deg, come out exactly (modulo 360 deg);
   the mean input is known up to whole turns, which turn the mechanism onto itself.
   (Not up to a third of a turn: adding 120 deg to all three inputs turns the
   platform by 120 deg.) The policy keeps the mean input continuous from step to
   step.
2. **The goal's inputs.** The goal rotation (its 6-D form, orthonormalised) is solved
   by :func:`~spm_pin.kinematics.inverse_kinematics` in the home working mode; its
   gaps are kept and its mean input shifted by whole turns to lie nearest the present
   one (the platform spins endlessly: the shortest way round).
3. **The path.** The straight line in input space (a straight line in the gap plane,
   the mean input moving in proportion) when :meth:`~spm_pin.planning.SafeSet.certify`
   proves it safe as a continuous motion; otherwise the certified polyline of
   :func:`~spm_pin.planning.plan` (planned once per episode), whose corners the
   policy stops at. Planned again when the goal changes or the robot is found off its
   path (a new episode, a stop by the guard).
4. **The speeds.** Along the present segment, with r the largest remaining input
   distance [rad] and d the segment's direction scaled to largest component 1, the
   command is ``v = d * min(max_speed, v_prev + a dt, v_brake(r), r / dt)`` with
   ``v_brake(r) = a dt (sqrt(1/4 + 2 r / (a dt^2)) - 1/2)``: the speed from which
   slowing by ``a dt`` per control period dt covers exactly r (a = ``brake`` times
   the guard's acceleration). It reaches the goal at rest, without overshoot, with
   every speed change within the acceleration limit, on the certified path (the three
   inputs in proportion). The normalised action is ``v / max_speed``.

:func:`evaluate_policy` runs any policy (a callable from observation to action) for a
number of seeded episodes and reports its success rate, episode lengths, final
errors and unsafe stops.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gymnasium
import numpy as np
import numpy.typing as npt

from ..errors import InputError, PlanningError, SPMError
from ..kinematics import inverse_kinematics
from ..planning import SafeSet, plan, safe_set_of
from ._core import OBSERVATION_SIZE
from .settings import OrientSettings

__all__ = ["ScriptedPolicy", "evaluate_policy"]

FloatArray = npt.NDArray[np.float64]
ObsArray = npt.NDArray[np.float32]

#: Distance [rad] from its path beyond which the robot is planned for again.
OFF_PATH_RAD = math.radians(1.0)
#: Remaining distance [rad] at which a corner of a planned path counts as reached.
CORNER_RAD = math.radians(0.05)


def rotations_of(six: npt.ArrayLike) -> FloatArray:
    """Rotations (n, 3, 3) of their 6-D forms (n, 6) (the first two columns),
    orthonormalised by Gram-Schmidt (the observation is float32)."""
    x = np.asarray(six, dtype=float).reshape(-1, 6)
    a, b = x[:, :3], x[:, 3:]
    c1 = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b - np.sum(c1 * b, axis=-1, keepdims=True) * c1
    c2 = b / np.linalg.norm(b, axis=-1, keepdims=True)
    c3 = np.cross(c1, c2)
    rotations: FloatArray = np.stack([c1, c2, c3], axis=-1)
    return rotations


class ScriptedPolicy:
    """The scripted controller of the orientation environments (see the module).

    Call it with one observation (21,) for one action (3,), or use :meth:`batch` with
    observations (n, 21) of a vector environment for actions (n, 3); it keeps, per
    robot, its path and last command between calls.

    Args:
        settings: The environment's options (design, the guard's limits, control
            period); default :class:`~spm_pin.envs.OrientSettings`.
        safe: The safe set that certifies paths (default: the one of the settings,
            built once per process and shared with the environments).
        planner: Plan around the unsafe parts of the gap plane when the straight line
            is not certified; False always goes straight.
        brake: The fraction of the guard's acceleration the braking profile plans
            with, in (0, 1] (a margin for the rounding of speeds).

    Attributes:
        settings: The options in force.
        safe: The safe set.
        replans: Paths computed so far (one per episode when all goes well).
        planned: Those of them that needed the planner (the straight line was not
            certified).
    """

    def __init__(
        self,
        settings: OrientSettings | None = None,
        *,
        safe: SafeSet | None = None,
        planner: bool = True,
        brake: float = 0.9,
    ) -> None:
        if settings is not None and not isinstance(settings, OrientSettings):
            raise InputError(
                f"settings must be OrientSettings, got {type(settings).__name__}",
                argument="settings",
                value=settings,
            )
        if isinstance(brake, bool) or not isinstance(brake, int | float) or not 0 < brake <= 1:
            raise InputError(f"brake must lie in (0, 1], got {brake!r}", argument="brake")
        self.settings = settings or OrientSettings()
        self.safe = safe or safe_set_of(self.settings.the_design, self.settings.plan_settings)
        self.planner = bool(planner)
        limits = self.settings.the_limits
        self._max_speed = float(limits.max_speed)
        self._dv = float(limits.max_acceleration) * self.settings.control_period
        self._brake_dv = brake * self._dv
        self._dt = float(self.settings.control_period)
        self.replans = 0
        self.planned = 0
        self._n = 0
        self.reset()

    @classmethod
    def for_env(cls, env: Any, **kwargs: Any) -> ScriptedPolicy:
        """The policy for an environment (single or vector, wrapped or not): its
        settings and safe set (configuration only, no state)."""
        inner = getattr(env, "unwrapped", env)
        settings = getattr(inner, "settings", None)
        core = getattr(inner, "core", None)
        if not isinstance(settings, OrientSettings) or core is None:
            raise InputError(
                f"env must be an spm_pin orientation environment, got {type(inner).__name__}",
                argument="env",
                value=env,
            )
        return cls(settings, safe=core.safe_set, **kwargs)

    # ---------------------------------------------------------------- state
    def reset(self, rows: npt.ArrayLike | None = None) -> None:
        """Forget the paths of ``rows`` (default: all): they are planned afresh at
        the next call (a new goal or a robot off its path is detected anyway)."""
        if rows is None:
            self._paths: list[FloatArray | None] = [None] * self._n
            return
        for i in np.atleast_1d(np.asarray(rows, dtype=np.intp)):
            self._paths[int(i)] = None

    def _resize(self, n: int) -> None:
        self._n = n
        self._paths = [None] * n
        self._goal_key = np.full((n, 6), np.nan)
        self._index = np.ones(n, dtype=np.intp)
        self._theta = np.zeros((n, 3))
        self._command = np.zeros((n, 3))

    # ---------------------------------------------------------------- decoding
    def inputs_of(self, sin: npt.ArrayLike, cos: npt.ArrayLike) -> FloatArray:
        """Input angles (n, 3) [rad] with these sines and cosines, consistent with
        their gaps (theta_1 in (-pi, pi], the others such that D12, D23 are those of
        the wrapped angles): the platform orientation of the true angles, which
        differ by whole turns of all three inputs at most."""
        wrapped = np.arctan2(np.asarray(sin, dtype=float), np.asarray(cos, dtype=float))
        wrapped = wrapped.reshape(-1, 3)
        d12, d23, _ = self.safe.gaps_of(wrapped)
        base = self.safe.theta_of(d12, d23, 0.0)
        theta: FloatArray = base + (wrapped[:, :1] - base[:, :1])
        return theta

    def goal_inputs(self, goal: FloatArray, near: FloatArray) -> FloatArray:
        """Input angles (n, 3) [rad] of goal rotations (n, 3, 3) in the home working
        mode, turned by whole turns to lie nearest ``near`` (n, 3) in mean."""
        ik = inverse_kinematics(goal, self.safe.design, mode=0)
        wrapped = np.asarray(ik.theta, dtype=float).reshape(-1, 3)
        if not np.all(np.isfinite(wrapped)):
            raise PlanningError(
                "a goal orientation is out of reach of the home working mode",
                reasons=("goal out of reach",),
                check="goal",
            )
        theta = self.inputs_of(np.sin(wrapped), np.cos(wrapped))
        turn = 2.0 * math.pi
        shift = turn * np.round((near.mean(axis=-1) - theta.mean(axis=-1)) / turn)
        result: FloatArray = theta + shift[:, None]
        return result

    def _path(self, start: FloatArray, goal: FloatArray) -> FloatArray:
        """The waypoints (m, 3) from start to goal (see the module)."""
        self.replans += 1
        straight = np.vstack([start, goal])
        if not self.planner or self.safe.certify(straight)[0]:
            return straight
        try:
            path = plan(start, goal, safe=self.safe).theta
        except SPMError:  # no certified path: go straight, the guard stops what fails
            return straight
        self.planned += 1
        waypoints: FloatArray = np.asarray(path, dtype=float)
        return waypoints

    # ---------------------------------------------------------------- control
    def batch(self, observations: npt.ArrayLike) -> ObsArray:
        """Actions (n, 3) in [-1, 1], float32, for observations (n, 21) of robots
        0..n-1 (a vector environment's rows; each keeps its own path)."""
        obs = np.asarray(observations, dtype=float)
        if obs.ndim != 2 or obs.shape[1] != OBSERVATION_SIZE or not np.all(np.isfinite(obs)):
            raise InputError(
                f"observations must be finite, of shape (n, {OBSERVATION_SIZE}), got "
                f"shape {obs.shape}",
                argument="observations",
                value=observations,
            )
        n = obs.shape[0]
        if n != self._n:
            self._resize(n)
        rec = self.inputs_of(obs[:, 12:15], obs[:, 15:18])
        turn = 2.0 * math.pi
        # The same whole turn as the last step's (the mean moves little in a step).
        shift = turn * np.round((self._theta.mean(axis=-1) - rec.mean(axis=-1)) / turn)
        theta = rec + shift[:, None]
        goal_key = obs[:, 6:12]
        fresh = np.array([p is None for p in self._paths]) | np.any(
            goal_key != self._goal_key, axis=-1
        )
        fresh |= self._off_path(theta)
        rows = np.flatnonzero(fresh)
        if rows.size:
            theta[rows] = rec[rows]
            goals = self.goal_inputs(rotations_of(goal_key[rows]), rec[rows])
            for k, i in enumerate(rows):
                self._paths[int(i)] = self._path(rec[i], goals[k])
            self._index[rows] = 1
            self._goal_key[rows] = goal_key[rows]
            self._command[rows] = obs[rows, 18:21] * self._max_speed
        command = self._speeds(theta)
        self._theta = theta
        self._command = command
        action: ObsArray = np.clip(command / self._max_speed, -1.0, 1.0).astype(np.float32)
        return action

    def __call__(self, observation: npt.ArrayLike) -> ObsArray:
        """The action (3,) in [-1, 1], float32, for one observation (21,)."""
        obs = np.asarray(observation)
        if obs.shape != (OBSERVATION_SIZE,):
            raise InputError(
                f"observation must have shape ({OBSERVATION_SIZE},), got {obs.shape}",
                argument="observation",
                value=observation,
            )
        action: ObsArray = self.batch(obs[None])[0]
        return action

    def _segments(self) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
        """(start, end (n, 3) of each robot's present segment, is it the last)."""
        start = np.zeros((self._n, 3))
        end = np.zeros((self._n, 3))
        last = np.ones(self._n, dtype=bool)
        for i, path in enumerate(self._paths):
            if path is None:
                continue
            k = int(self._index[i])
            start[i], end[i] = path[k - 1], path[k]
            last[i] = k == path.shape[0] - 1
        return start, end, last

    def _off_path(self, theta: FloatArray) -> npt.NDArray[np.bool_]:
        """Robots farther than :data:`OFF_PATH_RAD` from their present segment."""
        start, end, _ = self._segments()
        seg = end - start
        length2 = np.sum(seg * seg, axis=-1)
        t = np.clip(np.sum((theta - start) * seg, axis=-1) / np.maximum(length2, 1e-300), 0, 1)
        distance = np.linalg.norm(theta - start - t[:, None] * seg, axis=-1)
        off: npt.NDArray[np.bool_] = distance > OFF_PATH_RAD
        return off

    def _speeds(self, theta: FloatArray) -> FloatArray:
        """The commanded speeds (n, 3) [rad/s] along each robot's path (see the module)."""
        for i, path in enumerate(self._paths):  # pass the corners reached
            assert path is not None  # planned above for every row
            while (
                self._index[i] < path.shape[0] - 1
                and np.max(np.abs(path[self._index[i]] - theta[i])) < CORNER_RAD
            ):
                self._index[i] += 1
        _, target, _ = self._segments()
        error = target - theta
        r = np.max(np.abs(error), axis=-1)
        direction = error / np.maximum(r, 1e-300)[:, None]
        previous = np.sum(self._command * direction, axis=-1) / np.maximum(
            np.sum(direction * direction, axis=-1), 1e-300
        )
        dv, dt = self._brake_dv, self._dt
        brake = dv * (np.sqrt(0.25 + 2.0 * r / (dv * dt)) - 0.5)
        speed = np.minimum.reduce(
            [np.full_like(r, self._max_speed), np.maximum(previous, 0.0) + self._dv, brake, r / dt]
        )
        command = direction * np.maximum(speed, 0.0)[:, None]
        limited: FloatArray = np.clip(command, self._command - self._dv, self._command + self._dv)
        return limited


def evaluate_policy(
    env_or_id: gymnasium.Env[Any, Any] | str,
    policy: Callable[[Any], Any],
    *,
    episodes: int = 20,
    seed: int | None = 0,
    **options: Any,
) -> dict[str, Any]:
    """Run ``policy`` for ``episodes`` episodes and measure it.

    Args:
        env_or_id: A single environment, or a registered id made with ``options``
            (and closed afterwards).
        policy: Observation -> action; its ``reset()``, if any, is called at the
            start of every episode.
        episodes: Number of episodes (>= 1).
        seed: Seed of the first reset (the later ones go on with the environment's
            generator); None draws fresh episodes.
        **options: Keyword arguments of ``gymnasium.make`` (with an id only).

    Returns:
        ``episodes``; ``success_rate``: the fraction of episodes that ended at the
        goal held within the tolerance (terminated by success, not by an unsafe
        step); ``successes``; ``unsafe_stops``: episodes ended by an unsafe step;
        ``truncated``: episodes cut at ``max_steps``; ``mean_length``: steps per
        episode; ``mean_final_error_deg`` and ``max_final_error_deg``: the orientation
        error at the end [deg]; ``final_error_deg``: each episode's.
    """
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise InputError(f"episodes must be an integer >= 1, got {episodes!r}", argument="episodes")
    own = isinstance(env_or_id, str)
    if own:
        env: gymnasium.Env[Any, Any] = gymnasium.make(str(env_or_id), **options)
    elif options:
        raise InputError(
            f"options {sorted(options)} apply to an environment id only",
            argument="options",
            value=sorted(options),
        )
    else:
        env = env_or_id  # type: ignore[assignment]
    lengths: list[int] = []
    errors: list[float] = []
    successes = unsafe = truncations = 0
    reset_policy = getattr(policy, "reset", None)
    try:
        for episode in range(episodes):
            obs, info = env.reset(seed=seed if episode == 0 else None)
            if callable(reset_policy):
                reset_policy()
            steps = 0
            while True:
                obs, _, terminated, truncated, info = env.step(policy(obs))
                steps += 1
                if terminated or truncated:
                    break
            successes += bool(info.get("success", False))
            unsafe += bool(info.get("unsafe", False))
            truncations += bool(truncated and not terminated)
            lengths.append(steps)
            errors.append(math.degrees(float(info["orientation_error"])))
    finally:
        if own:
            env.close()
    return {
        "episodes": episodes,
        "success_rate": successes / episodes,
        "successes": successes,
        "unsafe_stops": unsafe,
        "truncated": truncations,
        "mean_length": float(np.mean(lengths)),
        "mean_final_error_deg": float(np.mean(errors)),
        "max_final_error_deg": float(np.max(errors)),
        "final_error_deg": errors,
    }
