"""The scripted baseline of the orientation environments: the inputs read from the
observation against forward kinematics, the success rate on held-out goals, no
unsafe stop, no overshoot, the batch against single robots, a random policy far
behind, and the dynamic environment."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import spm_pin as spm  # noqa: E402
from spm_pin.envs import ScriptedPolicy, evaluate_policy, geodesic_angle  # noqa: E402
from spm_pin.envs.baseline import rotations_of  # noqa: E402
from spm_pin.errors import InputError  # noqa: E402

#: Tolerances and bars, by what is checked.
TOL = {
    "rotation": 1e-9,  # forward kinematics of recovered inputs against the true ones
    "turn": 1e-9,  # recovered inputs differ from the true ones by whole turns
    "float32_rotation": 1e-6,  # a rotation read back from its float32 6-D form
    "overshoot_rad": 1e-9,  # an input passing its goal
    "speed_step": 1e-5,  # a change of commanded speed beyond max_acceleration * dt
    "success": 0.95,  # the bar: >= 95 % of held-out safe goals within 2 deg
    "dynamic_success": 0.8,
    "random_success": 0.2,
}
#: Held-out seeds, used by no other test.
SEED = {"kinematic": 7001, "dynamic": 7101, "random": 7201, "vector": 7301, "decode": 7401}
KINEMATIC = "spm_pin/Orient-v0"
DYNAMIC = "spm_pin/OrientDynamic-v0"


@pytest.fixture(scope="module")
def env() -> Any:
    made = gymnasium.make(KINEMATIC, safety="terminate")
    yield made
    made.close()


def _whole_turns(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(a - b) / 2 pi: whole numbers when a and b differ by whole turns."""
    return np.asarray((a - b) / (2.0 * math.pi))


def test_inputs_from_sin_cos_give_the_true_orientation(env: Any) -> None:
    """Each input is known modulo a turn; FK depends on it only through w_i, so the
    recovered inputs give the true orientation and differ by common whole turns."""
    policy = ScriptedPolicy.for_env(env)
    design = spm.SPMDesign.prototype()
    rng = np.random.default_rng(SEED["decode"])
    safe = policy.safe
    k = rng.integers(env.unwrapped.core.vertices.shape[0], size=16)
    vertices = env.unwrapped.core.vertices[k]
    # Many turns about the axis (the guard allows 200 either way).
    theta = safe.theta_of(vertices[:, 0], vertices[:, 1], rng.uniform(-300.0, 300.0, 16))
    recovered = policy.inputs_of(np.sin(theta), np.cos(theta))
    np.testing.assert_allclose(
        spm.forward_kinematics(recovered, design).R,
        spm.forward_kinematics(theta, design).R,
        atol=TOL["rotation"],
    )
    turns = _whole_turns(theta, recovered)
    np.testing.assert_allclose(turns, np.round(turns), atol=TOL["turn"])
    np.testing.assert_allclose(turns - turns[:, :1], 0.0, atol=TOL["turn"])  # common
    # Not a third of a turn: 120 deg on every input turns the platform.
    shifted = spm.forward_kinematics(theta + 2.0 * math.pi / 3.0, design).R
    assert np.all(geodesic_angle(shifted, spm.forward_kinematics(theta, design).R) > 1.0)
    # The goal's inputs: its orientation, the mean input nearest the reference.
    R = spm.forward_kinematics(theta, design).R
    near = theta + rng.uniform(-3.0, 3.0, (16, 1))
    goal = policy.goal_inputs(rotations_of(np.concatenate([R[:, :, 0], R[:, :, 1]], -1)), near)
    np.testing.assert_allclose(spm.forward_kinematics(goal, design).R, R, atol=TOL["rotation"])
    assert np.all(np.abs(goal.mean(axis=-1) - near.mean(axis=-1)) <= math.pi + 1e-9)


def test_rotations_of_float32_six_d() -> None:
    R = spm.forward_kinematics(np.array([0.3, -0.2, 0.5])).R
    six = np.concatenate([R[:, 0], R[:, 1]]).astype(np.float32)
    back = rotations_of(six)[0]
    np.testing.assert_allclose(back, R, atol=TOL["float32_rotation"])
    np.testing.assert_allclose(back @ back.T, np.eye(3), atol=1e-12)


def test_scripted_policy_reaches_held_out_goals(env: Any) -> None:
    """The bar: >= 95 % of held-out safe goals held within 2 deg, with no
    unsafe stop under ``safety="terminate"``."""
    policy = ScriptedPolicy.for_env(env)
    result = evaluate_policy(env, policy, episodes=40, seed=SEED["kinematic"])
    print({k: v for k, v in result.items() if k != "final_error_deg"})
    assert env.unwrapped.settings.tolerance == pytest.approx(math.radians(2.0))
    assert result["success_rate"] >= TOL["success"], result
    assert result["unsafe_stops"] == 0, result
    assert result["max_final_error_deg"] <= 2.0 or result["success_rate"] < 1.0
    assert policy.replans == 40  # one path per episode: never knocked off it


def test_no_overshoot_and_acceleration_within_limits(env: Any) -> None:
    """Each input approaches its goal from one side only (no overshoot), and the
    policy's own speed changes respect the guard's acceleration."""
    policy = ScriptedPolicy.for_env(env)
    limits = env.unwrapped.settings.the_limits
    dv = limits.max_acceleration * env.unwrapped.settings.control_period / limits.max_speed
    for episode in range(3):
        obs, info = env.reset(seed=SEED["kinematic"] + 100 + episode)
        goal = info["goal_theta"]
        turn = 2.0 * math.pi
        goal = goal - turn * np.round((goal - info["theta"]).mean() / turn)  # shortest
        sign = np.sign(goal - info["theta"])
        previous: Any = np.zeros(3)
        for _ in range(env.unwrapped.settings.max_steps):
            action = policy(obs)
            assert np.all(np.abs(action - previous) <= dv + TOL["speed_step"])
            previous = action
            obs, _, terminated, truncated, info = env.step(action)
            assert np.all(sign * (goal - info["theta"]) >= -TOL["overshoot_rad"])
            if terminated or truncated:
                break
        assert info["success"]


def test_random_policy_does_much_worse(env: Any) -> None:
    space = env.action_space
    space.seed(SEED["random"])
    result = evaluate_policy(env, lambda obs: space.sample(), episodes=20, seed=SEED["random"])
    print({k: v for k, v in result.items() if k != "final_error_deg"})
    assert result["success_rate"] < TOL["random_success"], result


def test_batch_matches_single_robots() -> None:
    """The batched policy on a vector environment acts as one policy per robot on
    single environments seeded alike, and reaches the goals there too."""
    n, steps = 3, 60
    envs = gymnasium.make_vec(KINEMATIC, num_envs=n, vectorization_mode="vector_entry_point")
    singles = [gymnasium.make(KINEMATIC) for _ in range(n)]
    batched = ScriptedPolicy.for_env(envs)
    policies = [ScriptedPolicy.for_env(e) for e in singles]
    obs, _ = envs.reset(seed=SEED["vector"])
    single_obs = [e.reset(seed=SEED["vector"] + i)[0] for i, e in enumerate(singles)]
    for _ in range(steps):
        actions = batched.batch(obs)
        for i in range(n):
            np.testing.assert_allclose(actions[i], policies[i](single_obs[i]), atol=1e-6)
            single_obs[i] = singles[i].step(actions[i])[0]
        obs, *_ = envs.step(actions)
    envs.close()
    for e in singles:
        e.close()


def test_planned_path_is_tracked_through_its_corners(env: Any) -> None:
    """The tracking of a planned polyline (the fallback when the straight line is not
    certified; on the prototype it always is): the robot stops at each corner."""
    policy = ScriptedPolicy.for_env(env)
    corners: list[np.ndarray] = []

    def via_middle(start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        middle = policy.safe.theta_of(120.0, 120.0, 0.5 * (start.mean() + goal.mean()))
        corners.append(middle)
        return np.vstack([start, middle, goal])

    policy._path = via_middle  # type: ignore[method-assign]
    obs, _ = env.reset(seed=SEED["kinematic"] + 200)
    nearest = math.inf
    for _ in range(2 * env.unwrapped.settings.max_steps):
        obs, _, terminated, truncated, info = env.step(policy(obs))
        nearest = min(nearest, float(np.max(np.abs(info["theta"] - corners[0]))))
        if terminated or truncated:
            break
    assert len(corners) == 1
    assert nearest < math.radians(0.1)
    assert info["success"]


def test_dynamic_environment_position_actuation() -> None:
    """On the reduced dynamics under the servos (a few episodes: ~15 ms a step)."""
    dynamic = gymnasium.make(DYNAMIC, safety="terminate")
    policy = ScriptedPolicy.for_env(dynamic)
    result = evaluate_policy(dynamic, policy, episodes=4, seed=SEED["dynamic"])
    dynamic.close()
    print({k: v for k, v in result.items() if k != "final_error_deg"})
    assert result["success_rate"] >= TOL["dynamic_success"], result
    assert result["unsafe_stops"] == 0, result


def test_bad_input() -> None:
    policy = ScriptedPolicy()
    with pytest.raises(InputError, match="observation"):
        policy(np.zeros(5))
    with pytest.raises(InputError, match="observations"):
        policy.batch(np.full((2, 21), np.nan))
    with pytest.raises(InputError, match="brake"):
        ScriptedPolicy(brake=0.0)
    with pytest.raises(InputError, match="env"):
        ScriptedPolicy.for_env(object())
    with pytest.raises(InputError, match="episodes"):
        evaluate_policy(KINEMATIC, policy, episodes=0)
