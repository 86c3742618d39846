"""Calibration errors drawn at each reset (domain randomisation): the observation is
the state a miscalibrated controller believes, checked by the believed model's own
forward kinematics; the truth (motion, reward, ends, info) is the nominal robot's;
the draws, the seeds, the batch against single environments and the options."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from spm_pin.envs import (  # noqa: E402
    CalibrationSpread,
    OrientDynamicEnv,
    OrientEnv,
    OrientSettings,
    OrientVectorEnv,
)
from spm_pin.envs._core import six_d  # noqa: E402
from spm_pin.errors import InputError  # noqa: E402
from spm_pin.kinematics import forward_kinematics  # noqa: E402

#: A spread a few times the prototype's calibration residuals [rad].
SPREAD = CalibrationSpread(
    offsets=math.radians(1.0),
    alpha1=math.radians(0.5),
    alpha2=math.radians(0.5),
    beta=math.radians(0.5),
)
#: float32 observations against float64 forward kinematics.
OBS_TOL = 1e-6


def _believed(core: Any, row: int) -> tuple[np.ndarray, np.ndarray]:
    """(input angles, rotation) that robot ``row``'s controller believes, by the
    believed design's forward kinematics (an analytic solver, not the env's Newton)."""
    parameters = core.believed.parameters[row]
    theta = core.theta[row] + parameters.offsets
    fk = forward_kinematics(theta, parameters.design(core.design))
    assert bool(fk.reachable)
    return theta, fk.R


def _check_observation(obs: np.ndarray, core: Any, row: int) -> float:
    """The observation of ``row`` is its believed state; returns how far the true
    rotation's 6-D form lies from the observed one."""
    theta, R = _believed(core, row)
    np.testing.assert_allclose(obs[:6], six_d(R), atol=OBS_TOL)
    np.testing.assert_array_equal(obs[6:12], six_d(core.goal[row]).astype(np.float32))
    np.testing.assert_array_equal(obs[12:15], np.sin(theta).astype(np.float32))
    np.testing.assert_array_equal(obs[15:18], np.cos(theta).astype(np.float32))
    return float(np.abs(obs[:6] - six_d(core.R[row])).max())


@pytest.mark.parametrize("maker", [OrientEnv, OrientDynamicEnv])
def test_the_observation_is_the_believed_state(maker: Any) -> None:
    env = maker(calibration_error=SPREAD, max_steps=30)
    rng = np.random.default_rng(4)
    apart = []
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        apart.append(_check_observation(obs, env.unwrapped.core, 0))
        for _ in range(12):
            action = rng.uniform(-1.0, 1.0, 3).astype(np.float32)
            obs, _, terminated, truncated, info = env.step(action)
            apart.append(_check_observation(obs, env.unwrapped.core, 0))
            # the info holds the truth: the true input angles
            np.testing.assert_array_equal(info["theta"], env.unwrapped.core.theta[0])
            if terminated or truncated:
                break
    assert min(apart) > 1e-4  # the believed rotation is not the true one


def test_the_truth_is_the_nominal_robots() -> None:
    """The first episode (drawn before the errors) with and without them: the same
    rewards, ends and info, different observations."""
    actions = np.random.default_rng(9).uniform(-1.0, 1.0, (40, 3)).astype(np.float32)
    plain, drawn = OrientEnv(max_steps=40), OrientEnv(max_steps=40, calibration_error=SPREAD)
    obs_p, info_p = plain.reset(seed=21)
    obs_d, info_d = drawn.reset(seed=21)
    assert not np.array_equal(obs_p, obs_d)
    np.testing.assert_array_equal(info_p["theta"], info_d["theta"])
    for action in actions:
        p, d = plain.step(action), drawn.step(action)
        assert p[1:4] == d[1:4]
        for key in ("theta", "goal_theta", "orientation_error", "step_fraction"):
            np.testing.assert_array_equal(p[4][key], d[4][key])
        if p[2] or p[3]:
            break


def test_errors_are_drawn_per_episode_with_the_spread() -> None:
    n = 1500
    vec = OrientVectorEnv(n, calibration_error=SPREAD)
    vec.reset(seed=3)
    believed = vec.core.believed
    assert believed is not None
    nominal = vec.core.design
    first = believed.offsets.copy()
    errors = np.array(
        [
            [p.alpha1 - nominal.alpha1, p.alpha2 - nominal.alpha2, p.beta - nominal.beta]
            for p in believed.parameters
        ]
    )
    # the sample standard deviations of n draws lie within 10% of the spread
    np.testing.assert_allclose(first.std(axis=0), SPREAD.offsets, rtol=0.1)
    np.testing.assert_allclose(
        errors.std(axis=0), [SPREAD.alpha1, SPREAD.alpha2, SPREAD.beta], rtol=0.1
    )
    assert abs(float(first.mean())) < 4 * SPREAD.offsets / math.sqrt(3 * n)
    assert vec.calibration(5) is believed.parameters[5]
    np.testing.assert_array_equal(vec.calibration(n - 1).offsets, first[n - 1])
    for bad in (-1, n, 1.5, True):
        with pytest.raises(InputError, match="index"):
            vec.calibration(bad)  # type: ignore[arg-type]
    vec.reset(seed=4)  # a new episode: new errors
    assert np.all(believed.offsets != first)
    assert OrientVectorEnv(2).calibration(1) is None
    one = OrientEnv(calibration_error=CalibrationSpread(alpha2=math.radians(0.3)))
    one.reset(seed=0)
    assert one.core.believed is not None
    np.testing.assert_array_equal(one.core.believed.offsets, 0.0)  # only alpha2 drawn
    parameters = one.calibration()
    assert parameters is one.core.believed.parameters[0]
    assert parameters.alpha2 != one.core.design.alpha2
    assert parameters.alpha1 == one.core.design.alpha1


def test_determinism_and_the_batch_against_single_envs() -> None:
    n, seed = 3, 11
    options: dict[str, Any] = {"calibration_error": SPREAD, "max_steps": 12}
    vec = OrientVectorEnv(n, **options)
    singles = [OrientEnv(**options) for _ in range(n)]
    again = OrientEnv(**options)
    obs_v, _ = vec.reset(seed=seed)
    obs_s = np.stack([env.reset(seed=seed + i)[0] for i, env in enumerate(singles)])
    np.testing.assert_allclose(obs_v, obs_s, atol=OBS_TOL)
    np.testing.assert_array_equal(again.reset(seed=seed)[0], obs_s[0])
    ended = np.zeros(n, dtype=bool)
    resets = 0
    for action in np.random.default_rng(2).uniform(-1.0, 1.0, (40, n, 3)).astype(np.float32):
        obs_v, *_, term_v, trunc_v, _ = vec.step(action)
        rows = []
        for i, env in enumerate(singles):  # Gymnasium's NEXT_STEP autoreset by hand
            if ended[i]:
                rows.append(env.reset()[0])
                resets += 1
                if i == 0:
                    np.testing.assert_array_equal(again.reset()[0], rows[-1])
            else:
                rows.append(env.step(action[i])[0])
                if i == 0:
                    np.testing.assert_array_equal(again.step(action[0])[0], rows[-1])
        np.testing.assert_allclose(obs_v, np.stack(rows), atol=OBS_TOL)
        ended = term_v | trunc_v
    assert resets >= n  # the errors were drawn again at autoresets


@pytest.mark.parametrize("env_id", ["spm_pin/Orient-v0", "spm_pin/OrientDynamic-v0"])
def test_check_env_with_calibration_errors(env_id: str) -> None:
    from gymnasium.utils.env_checker import check_env

    env = gymnasium.make(env_id, calibration_error=SPREAD)
    check_env(env.unwrapped)
    assert env.unwrapped.core.believed is not None
    env.close()


def test_the_spread_is_checked() -> None:
    assert not CalibrationSpread().active and SPREAD.active
    assert OrientEnv().core.believed is None  # none drawn by default
    assert OrientEnv().calibration() is None
    for bad in (-0.01, math.nan, math.inf, math.radians(6.0), True, "0.01"):
        with pytest.raises(InputError, match=r"calibration_error\.offsets"):
            CalibrationSpread(offsets=bad)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"calibration_error\.beta"):
        CalibrationSpread(beta=-1.0)
    with pytest.raises(InputError, match="CalibrationSpread"):
        OrientSettings(calibration_error=0.01)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="CalibrationSpread"):
        OrientEnv(calibration_error={"offsets": 0.01})
