"""The dynamic Gymnasium environment ``spm_pin/OrientDynamic-v0``: the API checker,
seeds, the batch against single environments, the guard (checked independently),
the servos' torque-speed envelope, holding still, and bad input."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import spm_pin as spm  # noqa: E402
from spm_pin.dynamics import XM540_W150  # noqa: E402
from spm_pin.envs import (  # noqa: E402
    ENV_IDS,
    OrientDynamicEnv,
    OrientDynamicVectorEnv,
    PhysicsSettings,
)
from spm_pin.errors import InputError  # noqa: E402

#: Tolerances of the comparisons, by what is compared.
TOL = {
    "state": 1e-12,  # float64 states and rewards of a batch row and of one robot
    "obs": 1e-6,  # float32 observations of the same
    "hold_rad": 2e-3,  # drift of a robot holding still under gravity (g / kp ~ 1e-3)
    "hold_speed": 1e-3,  # its speed [rad/s] at the end
    "envelope": 1e-9,  # torques against the servo's torque-speed envelope [N m]
}


def _random_actions(rng: np.random.Generator, steps: int, n: int, hold: int = 8) -> Any:
    """Seeded actions (steps, n, 3), each held for ``hold`` steps."""
    blocks = rng.uniform(-1.0, 1.0, size=(steps // hold + 1, n, 3))
    return np.repeat(blocks, hold, axis=0)[:steps].astype(np.float32)


def test_check_env_passes_and_registered_ids() -> None:
    from gymnasium.utils.env_checker import check_env

    assert "spm_pin/OrientDynamic-v0" in ENV_IDS
    env = gymnasium.make("spm_pin/OrientDynamic-v0", max_steps=20)
    check_env(env.unwrapped, skip_render_check=True)
    assert isinstance(env.unwrapped, OrientDynamicEnv)
    vec = gymnasium.make_vec(
        "spm_pin/OrientDynamic-v0", num_envs=3, vectorization_mode="vector_entry_point"
    )
    assert isinstance(vec, OrientDynamicVectorEnv)
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (3, 21) and vec.observation_space.contains(obs)
    obs, *_, info = vec.step(np.zeros((3, 3), dtype=np.float32))
    assert vec.observation_space.contains(obs)
    assert info["torque"].shape == (3, 3) and info["_torque"].all()
    env.close()
    vec.close()


def test_options_and_actions_are_checked() -> None:
    with pytest.raises(InputError, match="actuation"):
        OrientDynamicEnv(actuation="velocity")
    with pytest.raises(InputError, match="physics_dt"):
        OrientDynamicEnv(physics_dt=0.0)
    with pytest.raises(InputError, match="unknown options"):
        OrientDynamicEnv(speed=3)
    with pytest.raises(InputError, match="physics"):
        OrientDynamicEnv(physics="fast")  # type: ignore[arg-type]
    env = OrientDynamicEnv(physics=PhysicsSettings(physics_dt=4e-3))
    assert env.core.substeps == 5 and env.core.dt == pytest.approx(4e-3)
    env.reset(seed=0)
    for bad in (np.array([np.nan, 0.0, 0.0]), np.zeros(2), np.zeros((1, 3)), "left"):
        with pytest.raises(InputError, match="action"):
            env.step(bad)
    vec = OrientDynamicVectorEnv(2)
    vec.reset(seed=0)
    with pytest.raises(InputError, match="action"):
        vec.step(np.zeros(3))
    with pytest.raises(InputError, match="action"):
        vec.step(np.array([[0.0, np.inf, 0.0], [0.0, 0.0, 0.0]]))


def test_determinism_for_a_seed() -> None:
    actions = _random_actions(np.random.default_rng(5), 30, 1)[:, 0]
    runs = []
    for _ in range(2):
        env = OrientDynamicEnv(observation_noise=0.01, max_steps=12)
        trace = [env.reset(seed=123)[0]]
        for action in actions:
            obs, reward, terminated, truncated, info = env.step(action)
            trace.append(np.concatenate([obs, [reward, terminated, truncated], info["torque"]]))
            if terminated or truncated:
                trace.append(env.reset()[0])
        runs.append(np.concatenate(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize("actuation", ["position", "torque"])
def test_vector_env_equals_single_envs_across_autoresets(actuation: str) -> None:
    n, seed = 3, 7
    steps, max_steps = (40, 12) if actuation == "position" else (16, 5)
    options: dict[str, Any] = {
        "safety": "terminate",
        "max_steps": max_steps,
        "observation_noise": 0.01,
        "actuation": actuation,
    }
    vec = OrientDynamicVectorEnv(n, **options)
    singles = [OrientDynamicEnv(**options) for _ in range(n)]
    obs_v, _ = vec.reset(seed=seed)
    obs_s = np.stack([env.reset(seed=seed + i)[0] for i, env in enumerate(singles)])
    np.testing.assert_allclose(obs_v, obs_s, atol=TOL["obs"])
    ended = np.zeros(n, dtype=bool)
    resets = 0
    scale = 0.02 if actuation == "torque" else 1.0  # full stall torque is violent
    for action in scale * _random_actions(np.random.default_rng(1), steps, n):
        obs_v, reward_v, term_v, trunc_v, _ = vec.step(action)
        rows = []
        for i, env in enumerate(singles):  # Gymnasium's NEXT_STEP autoreset by hand
            if ended[i]:
                rows.append((env.reset()[0], 0.0, False, False))
                resets += 1
            else:
                rows.append(env.step(action[i])[:4])
        np.testing.assert_allclose(obs_v, np.stack([r[0] for r in rows]), atol=TOL["obs"])
        np.testing.assert_allclose(reward_v, [r[1] for r in rows], rtol=0, atol=TOL["state"])
        np.testing.assert_array_equal(term_v, [r[2] for r in rows])
        np.testing.assert_array_equal(trunc_v, [r[3] for r in rows])
        for i, env in enumerate(singles):
            np.testing.assert_allclose(
                vec.core.theta[i], env.core.theta[0], rtol=0, atol=TOL["state"]
            )
            np.testing.assert_allclose(
                vec.core.speed[i], env.core.speed[0], rtol=0, atol=TOL["state"]
            )
        ended = term_v | trunc_v
    assert resets >= n  # the comparison went through autoresets


@pytest.mark.parametrize("actuation", ["torque", "position"])
def test_guard_never_refuses_an_observed_state_in_clip_mode(actuation: str) -> None:
    """Seeded random actions pushed against the boundary: every state entered passes
    the servos' guard (an independent checker, on the returned input angles)."""
    from spm_pin.hardware.guard import SafetyGuard

    n, steps = 6, 40
    env = OrientDynamicVectorEnv(n, safety="clip", max_steps=10_000, actuation=actuation)
    guard = SafetyGuard(limits=env.core.limits)
    env.reset(seed=11)
    rng = np.random.default_rng(2)
    scale = 0.05 if actuation == "torque" else 1.0
    clipped = 0
    for action in scale * _random_actions(rng, steps, n, hold=20):
        obs, _, terminated, _, info = env.step(action)
        assert not terminated.any()
        clipped += int(np.sum(info["step_fraction"] < 1.0))
        theta = env.core.theta
        np.testing.assert_allclose(obs[:, 12:15], np.sin(theta), atol=TOL["obs"])
        for i in range(n):
            verdict = guard.check(theta[i])
            assert verdict.safe, verdict.reasons
        stopped = info["step_fraction"] < 1.0
        np.testing.assert_array_equal(info["theta_dot"][stopped], 0.0)
    assert clipped > 0  # the boundary was met


def test_terminate_mode_ends_before_an_unsafe_state() -> None:
    n = 6
    env = OrientDynamicVectorEnv(n, safety="terminate", max_steps=10_000, actuation="torque")
    env.reset(seed=3)
    penalty = env.settings.weights.unsafe
    stopped = 0
    for action in 0.05 * _random_actions(np.random.default_rng(4), 40, n, hold=20):
        before = env.core.theta.copy()
        restarting = env._autoreset.copy()
        _, reward, terminated, _, info = env.step(action)
        for i in np.flatnonzero(info["unsafe"] & ~restarting):
            stopped += 1
            assert terminated[i] and reward[i] <= -penalty
            np.testing.assert_array_equal(env.core.theta[i], before[i])  # not entered
            np.testing.assert_array_equal(env.core.speed[i], 0.0)  # stopped
        assert not np.any(info["unsafe"] & ~terminated)
    assert stopped > 0


def test_a_row_the_dynamics_cannot_step_is_unsafe_not_an_error() -> None:
    """A robot put where no home-mode assembly exists makes ReducedDynamics raise:
    the step treats that row as unsafe and the others step as alone."""
    bad_theta = np.radians([0.0, 100.0, -100.0])  # gaps of 20, 320, 20 deg
    assert not spm.forward_kinematics(bad_theta).reachable
    vec = OrientDynamicVectorEnv(3, safety="terminate")
    single = OrientDynamicEnv(safety="terminate")
    vec.reset(seed=5)
    single.reset(seed=5)
    vec.core.theta[1] = bad_theta
    action = np.full((3, 3), 0.3, dtype=np.float32)
    _, reward, terminated, _, info = vec.step(action)
    assert terminated[1] and info["unsafe"][1]
    assert not info["unsafe"][0] and not info["unsafe"][2]
    _, reward0, *_ = single.step(action[0])
    np.testing.assert_allclose(vec.core.theta[0], single.core.theta[0], atol=TOL["state"])
    assert reward[0] == pytest.approx(reward0, abs=TOL["state"])
    clip = OrientDynamicVectorEnv(2, safety="clip")
    clip.reset(seed=5)
    clip.core.theta[0] = bad_theta
    _, _, terminated, _, info = clip.step(np.zeros((2, 3), dtype=np.float32))
    assert not terminated.any() and info["step_fraction"][0] == 0.0
    np.testing.assert_array_equal(clip.core.theta[0], bad_theta)  # stopped where it was
    assert info["step_fraction"][1] == 1.0


def test_zero_action_holds_the_robot_under_gravity() -> None:
    """Position actuation, zero action: the servos hold a safe start within g / kp."""
    env = OrientDynamicVectorEnv(4, max_steps=10_000)
    env.reset(seed=21)
    start = env.core.theta.copy()
    holding = env.core.dynamics.holding_torques(start)
    assert np.abs(holding).max() > 1e-3  # gravity does pull there
    for _ in range(25):
        _, _, _, _, info = env.step(np.zeros((4, 3), dtype=np.float32))
    assert np.all(info["step_fraction"] == 1.0)
    np.testing.assert_allclose(env.core.theta, start, atol=TOL["hold_rad"])
    np.testing.assert_allclose(info["theta_dot"], 0.0, atol=TOL["hold_speed"])
    np.testing.assert_allclose(info["servo_goal"], start, atol=1e-15)


def test_torques_stay_inside_the_servo_envelope() -> None:
    """Full-scale random torque actions: every applied torque lies inside the
    XM540's torque-speed envelope at the speed it was applied (ServoModel's own
    limits), and the servo load never exceeds 1."""
    n = 6
    env = OrientDynamicVectorEnv(n, actuation="torque", max_steps=10_000)
    env.reset(seed=8)
    saturated = 0
    for action in _random_actions(np.random.default_rng(9), 25, n, hold=5):
        _, _, _, _, info = env.step(action)
        lower, upper = XM540_W150.torque_limits(info["torque_speed"])
        assert np.all(info["torque"] >= lower - TOL["envelope"])
        assert np.all(info["torque"] <= upper + TOL["envelope"])
        assert np.all(info["servo_load"] <= 1.0 + TOL["envelope"])
        assert np.all(np.abs(info["torque"]) <= XM540_W150.stall_torque + TOL["envelope"])
        saturated += int(np.sum(info["servo_load"] > 1.0 - 1e-9))
    assert saturated > 0  # the envelope was reached


def test_position_actuation_follows_the_commanded_speed() -> None:
    """A steady goal speed: the servos track it (the loop's feedforward)."""
    env = OrientDynamicEnv(start="home", goal="fixed", goal_theta=(0.3, 0.3, 0.3))
    env.reset(seed=0)
    for _ in range(12):
        _, _, _, _, info = env.step(np.full(3, 0.5, dtype=np.float32))
    speed = 0.5 * env.core.limits.max_speed
    np.testing.assert_allclose(info["theta_dot"], speed, rtol=1e-2)
    assert math.isclose(float(np.ptp(info["theta"])), 0.0, abs_tol=1e-6)  # a pure turn


def test_the_platform_rotation_is_that_of_forward_kinematics() -> None:
    """The rotation a step enters comes from Newton's method warm started at the
    physics steps' rotations: it equals forward kinematics of the state entered, also
    for robots the safety clip stopped part-way."""
    env = OrientDynamicVectorEnv(16, max_steps=10_000)
    env.reset(seed=4)
    rng = np.random.default_rng(8)
    clipped = 0
    for _ in range(60):
        _, _, _, _, info = env.step(rng.uniform(-1.0, 1.0, size=(16, 3)).astype(np.float32))
        clipped += int(np.sum(info["step_fraction"] < 1.0))
        fk = spm.forward_kinematics(env.core.theta, env.core.design)
        assert fk.reachable.all()
        np.testing.assert_allclose(env.core.R, fk.R, atol=1e-12)
    assert clipped > 0


def test_a_steps_extra_info_is_the_vector_envs_row_and_a_copy() -> None:
    from spm_pin.envs._dynamic import EXTRA_INFO

    vec = OrientDynamicVectorEnv(2, max_steps=50)
    single = OrientDynamicEnv(max_steps=50)
    vec.reset(seed=3)
    single.reset(seed=3)  # sub-environment 0 of the vector env
    action = np.array([0.4, -0.2, 0.1], dtype=np.float32)
    info_v = vec.step(np.stack([action, -action]))[4]
    info = single.step(action)[4]
    rows = np.array([0])
    assert tuple(single.core.extra_info(0)) == tuple(single.core.extra_info(rows)) == EXTRA_INFO
    for key in EXTRA_INFO:
        np.testing.assert_array_equal(info[key], info_v[key][0], err_msg=key)
    assert info["theta_dot"].shape == (3,) and isinstance(info["servo_load"], float)
    before = info["theta_dot"].copy()
    single.core.speed[0] += 1.0  # the info keeps the step's values, not a view
    np.testing.assert_array_equal(info["theta_dot"], before)
    assert np.any(before != 0.0)


def test_each_environment_builds_its_core_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """An environment builds one core of its own kind (a cover is loaded by each core
    built): the dynamic ones do not build a kinematic core first and replace it."""
    from spm_pin.envs import OrientEnv, OrientVectorEnv, _core

    built: list[str] = []
    real = _core.OrientCore.__init__

    def counted(self: Any, *args: Any, **kwargs: Any) -> None:
        built.append(type(self).__name__)
        real(self, *args, **kwargs)

    monkeypatch.setattr(_core.OrientCore, "__init__", counted)
    for make, kind in (
        (OrientEnv, "OrientCore"),
        (OrientDynamicEnv, "DynamicCore"),
        (lambda: OrientVectorEnv(3), "OrientCore"),
        (lambda: OrientDynamicVectorEnv(3), "DynamicCore"),
    ):
        built.clear()
        env: Any = make()
        assert built == [kind]
        assert type(env.core).__name__ == kind
        single = getattr(env, "single", None)
        assert single is None or single.core is env.core  # the robot stepped is the core's
