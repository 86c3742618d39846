"""The Gymnasium environments: the API checker, seeds, the batch against single
environments, the guard, and a scripted controller checked by forward kinematics."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import spm_pin as spm  # noqa: E402
from spm_pin.envs import OrientEnv, OrientSettings, OrientVectorEnv, geodesic_angle  # noqa: E402
from spm_pin.errors import InputError  # noqa: E402
from spm_pin.rotations import log_so3  # noqa: E402

#: Tolerances of the comparisons, by what is compared.
TOL = {
    "obs": 1e-6,  # float32 observations; the kinematics of a batch and of one row
    "reward": 1e-9,  # differ in the last bits (4e-16)
    "goal_rad": math.radians(2.0),
}


def _random_actions(rng: np.random.Generator, steps: int, n: int, hold: int = 8) -> Any:
    """Seeded actions (steps, n, 3), each held for ``hold`` steps (so that robots
    travel far enough to meet the boundary of the safe set)."""
    blocks = rng.uniform(-1.0, 1.0, size=(steps // hold + 1, n, 3))
    return np.repeat(blocks, hold, axis=0)[:steps].astype(np.float32)


def test_check_env_passes_and_registered_ids() -> None:
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make("spm_pin/Orient-v0")
    check_env(env.unwrapped)
    assert isinstance(env.unwrapped, OrientEnv)
    vec = gymnasium.make_vec(
        "spm_pin/Orient-v0", num_envs=3, vectorization_mode="vector_entry_point"
    )
    assert isinstance(vec, OrientVectorEnv)
    assert vec.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (3, 21) and vec.observation_space.contains(obs)
    env.close()
    vec.close()


def test_options_are_checked() -> None:
    with pytest.raises(InputError, match="safety"):
        OrientEnv(safety="maybe")
    with pytest.raises(InputError, match="unknown options"):
        OrientEnv(speed=3)
    with pytest.raises(InputError, match="not safe"):
        OrientEnv(goal="fixed", goal_theta=(0.0, 0.0, math.radians(170.0)))
    env = OrientEnv()
    env.reset(seed=0)
    with pytest.raises(InputError, match="action"):
        env.step(np.array([np.nan, 0.0, 0.0]))


def test_determinism_for_a_seed() -> None:
    actions = _random_actions(np.random.default_rng(5), 40, 1)[:, 0]
    runs = []
    for _ in range(2):
        env = OrientEnv(observation_noise=0.01, max_steps=15)
        trace = [env.reset(seed=123)[0]]
        for action in actions:
            obs, reward, terminated, truncated, _ = env.step(action)
            trace.append(np.append(obs, [reward, terminated, truncated]))
            if terminated or truncated:
                trace.append(env.reset()[0])
        runs.append(np.concatenate(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_vector_env_equals_single_envs_across_autoresets() -> None:
    n, steps, seed = 4, 90, 7
    options: dict[str, Any] = {"safety": "terminate", "max_steps": 20, "observation_noise": 0.01}
    vec = OrientVectorEnv(n, **options)
    singles = [OrientEnv(**options) for _ in range(n)]
    obs_v, _ = vec.reset(seed=seed)
    obs_s = np.stack([env.reset(seed=seed + i)[0] for i, env in enumerate(singles)])
    np.testing.assert_allclose(obs_v, obs_s, atol=TOL["obs"])
    ended = np.zeros(n, dtype=bool)
    resets = 0
    for action in _random_actions(np.random.default_rng(1), steps, n):
        obs_v, reward_v, term_v, trunc_v, _ = vec.step(action)
        rows = []
        for i, env in enumerate(singles):  # Gymnasium's NEXT_STEP autoreset by hand
            if ended[i]:
                rows.append((env.reset()[0], 0.0, False, False))
                resets += 1
            else:
                rows.append(env.step(action[i])[:4])
        obs_s = np.stack([r[0] for r in rows])
        np.testing.assert_allclose(obs_v, obs_s, atol=TOL["obs"])
        np.testing.assert_allclose(reward_v, [r[1] for r in rows], atol=TOL["reward"])
        np.testing.assert_array_equal(term_v, [r[2] for r in rows])
        np.testing.assert_array_equal(trunc_v, [r[3] for r in rows])
        ended = term_v | trunc_v
    assert resets >= n  # the comparison went through autoresets


def test_guard_never_refuses_a_state_in_clip_mode() -> None:
    """Seeded random actions pushed against the boundary: every state entered passes
    the servos' guard (an independent checker), speed included."""
    from spm_pin.hardware.guard import SafetyGuard

    n, steps = 12, 80
    env = OrientVectorEnv(n, safety="clip", max_steps=10_000)
    guard = SafetyGuard(limits=env.core.limits)
    env.reset(seed=11)
    period = env.settings.control_period
    clipped = 0
    for action in _random_actions(np.random.default_rng(2), steps, n, hold=20):
        before = env.core.theta.copy()
        _, _, terminated, _, info = env.step(action)
        assert not terminated.any()
        clipped += int(np.sum(info["step_fraction"] < 1.0))
        for i in range(n):
            verdict = guard.check(env.core.theta[i], previous=before[i], period=period)
            assert verdict.safe, verdict.reasons
    assert clipped > 0  # the boundary was met


def test_terminate_mode_stops_before_an_unsafe_state() -> None:
    n = 12
    env = OrientVectorEnv(n, safety="terminate", max_steps=10_000)
    env.reset(seed=3)
    penalty = env.settings.weights.unsafe
    stopped = 0
    for action in _random_actions(np.random.default_rng(4), 80, n, hold=20):
        before = env.core.theta.copy()
        restarting = env._autoreset.copy()
        _, reward, terminated, _, info = env.step(action)
        for i in np.flatnonzero(info["unsafe"] & ~restarting):
            stopped += 1
            assert terminated[i]
            np.testing.assert_array_equal(env.core.theta[i], before[i])  # not entered
            assert reward[i] <= -penalty
            np.testing.assert_array_equal(env.core.speed[i], 0.0)  # stopped
        assert not np.any(info["unsafe"] & ~terminated)
    assert stopped > 0


def _jacobian_policy(env: OrientVectorEnv, gain: float = 4.0) -> Any:
    """Speeds that turn the platform towards the goal: omega = gain log(G R^T),
    theta_dot = J^-1 omega."""
    core = env.core
    relative = core.goal @ np.swapaxes(core.R, -1, -2)
    omega = gain * np.stack([log_so3(r) for r in relative])
    J = spm.jacobian(core.theta, core.design, R=core.R).J
    theta_dot = np.linalg.solve(J, omega[..., None])[..., 0]
    return np.clip(theta_dot / core.limits.max_speed, -1.0, 1.0)


def test_scripted_controller_reaches_held_out_goals() -> None:
    """A Jacobian controller reaches >= 90% of 50 held-out safe goals within 2 deg,
    judged by forward kinematics of the final inputs against that of the goal's."""
    n = 50
    env = OrientVectorEnv(n, max_steps=150)
    env.reset(seed=2024)
    goal_theta = env.core.goal_theta.copy()
    final = np.full((n, 3), np.nan)
    ended = np.zeros(n, dtype=bool)
    for _ in range(env.settings.max_steps):
        _, _, terminated, truncated, _ = env.step(_jacobian_policy(env))
        new = (terminated | truncated) & ~ended
        final[new] = env.core.theta[new]
        ended |= terminated | truncated
        if ended.all():
            break
    assert ended.all()
    reached = spm.forward_kinematics(final).R
    goals = spm.forward_kinematics(goal_theta).R
    error = geodesic_angle(reached, goals)
    assert np.mean(error <= TOL["goal_rad"]) >= 0.9, np.degrees(error).round(2)


def test_reward_and_termination_at_the_goal() -> None:
    """Started at the goal with zero speed: the episode ends after hold_steps with
    the success bonus."""
    env = OrientEnv(start="home", goal="fixed", hold_steps=3)
    obs, info = env.reset(seed=0)
    assert info["orientation_error"] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(obs[:6], obs[6:12], atol=1e-7)  # at the goal
    ends = []
    for _ in range(3):
        _, reward, terminated, truncated, info = env.step(np.zeros(3, dtype=np.float32))
        ends.append((terminated, truncated))
    assert ends == [(False, False), (False, False), (True, False)]
    assert reward == pytest.approx(env.settings.weights.success, abs=1e-9)


def test_rgb_array_frame() -> None:
    pytest.importorskip("matplotlib")
    env = OrientEnv(render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame is not None and frame.dtype == np.uint8 and frame.shape == (320, 320, 3)
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 4  # something is drawn
    vec = OrientVectorEnv(2, render_mode="rgb_array")
    vec.reset(seed=0)
    frames = vec.render()
    assert frames is not None and frames[0].shape == (320, 320, 3)


def test_settings_make_a_safe_fixed_goal() -> None:
    settings = OrientSettings(goal="fixed", goal_theta=(0.1, 0.0, -0.1))
    env = OrientEnv(settings)
    env.reset(seed=1)
    np.testing.assert_allclose(env.core.goal_theta[0], [0.1, 0.0, -0.1])
