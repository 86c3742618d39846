"""The single environments' step (``SingleStep``): robot 0 alone through the
compiled kernel with buffers made once and its result read as Python numbers.

It must be the vector environment's step of one robot: the same observations,
rewards, ends, info and counters of the cover's checks, for the kinematic and the
dynamic environment; a robot the kernel hands back is stepped by numpy as in
``step_rows``; without the compiled step (``fused`` off) it is ``step_rows`` itself.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from spm_pin import _jit
from spm_pin.envs import OrientDynamicEnv, OrientDynamicVectorEnv, OrientEnv, OrientVectorEnv
from spm_pin.errors import InputError

needs_numba = pytest.mark.skipif(not _jit.available(), reason="numba is not installed")

KINDS = ("kinematic", "dynamic")


def _pair(kind: str, cover: str, **options: Any) -> tuple[Any, Any]:
    """A single env and a vector env of one robot, with the same options."""
    options = {"cover": cover, "cover_only": True, "max_steps": 30, **options}
    if kind == "kinematic":
        return OrientEnv(**options), OrientVectorEnv(1, **options)
    return OrientDynamicEnv(**options), OrientDynamicVectorEnv(1, **options)


def _actions(seed: int, steps: int) -> np.ndarray:
    """Seeded actions (steps, 3), each held for 4 steps (the robot meets the boundary)."""
    rng = np.random.default_rng(seed)
    return np.repeat(rng.uniform(-1.0, 1.0, size=(steps // 4 + 1, 3)), 4, axis=0)[:steps]


def _same_step(single: Any, vector: Any, action: np.ndarray) -> bool:
    """Step both with ``action``; assert the same outcome; True at an episode's end."""
    obs, reward, terminated, truncated, info = single.step(action)
    v_obs, v_reward, v_terminated, v_truncated, v_info = vector.step(action[None])
    np.testing.assert_array_equal(obs, v_obs[0])
    assert type(reward) is float and reward == float(v_reward[0])
    assert type(terminated) is bool and terminated == bool(v_terminated[0])
    assert type(truncated) is bool and truncated == bool(v_truncated[0])
    for key, value in info.items():
        if key in v_info:  # the vector env's ends reset: compare what it kept
            np.testing.assert_array_equal(value, v_info[key][0], err_msg=key)
    return terminated or truncated


@needs_numba
@pytest.mark.parametrize("only", [True, False], ids=["cover_only", "cover"])
@pytest.mark.parametrize("kind", KINDS)
def test_the_single_step_is_the_vector_step_of_one_robot(
    env_cover_path: str, kind: str, only: bool
) -> None:
    """Step for step, the single env gives what the vector env gives its one robot,
    its state is the same, and the cover's checks are counted alike; the single env
    takes its whole step in one compiled call, and with the cover alone (not
    ``cover_only``) the robot leaves the certified cells, so that call hands it
    back to numpy at some steps."""
    single, vector = _pair(kind, env_cover_path, safety="clip", cover_only=only)
    single.reset(seed=7)
    vector.reset(seed=7)
    np.testing.assert_array_equal(single.core.theta, vector.core.theta)
    ends = 0
    for action in _actions(3, 150):
        if _same_step(single, vector, action):
            ends += 1
            single.reset(seed=7 + ends)
            vector.reset(seed=7 + ends)
        for name in ("theta", "speed", "R", "goal", "hold", "steps"):
            np.testing.assert_array_equal(getattr(single.core, name), getattr(vector.core, name))
    a, b = single.core.lookup, vector.core.lookup
    assert a.asked > 0 and (a.asked, a.settled) == (b.asked, b.settled)
    assert single.single._whole is not None and ends > 0
    assert single.core.handed_rows == vector.core.handed_rows
    assert (single.core.handed_rows > 0) == (not only)


@needs_numba
@pytest.mark.parametrize("kind", KINDS)
def test_a_robot_handed_back_is_stepped_by_numpy(env_cover_path: str, kind: str) -> None:
    """The kernel hands robot 0 back at every step: the step is the numpy path's (the
    same as with ``fused`` off), and the kinematic core counts each hand-back."""
    fused, _ = _pair(kind, env_cover_path, safety="terminate")
    numpy, _ = _pair(kind, env_cover_path, safety="terminate")
    numpy.core.fused = False
    calls: list[int] = []

    def hand_back(rows: Any, action: Any, out: Any, handed: Any, *args: Any) -> None:
        calls.append(int(rows.size))
        handed[:] = True

    fused.core._step_call = lambda rows, action, out, handed, *rest: (
        hand_back,
        (rows, action, out, handed),
    )
    fused.reset(seed=11)
    numpy.reset(seed=11)
    steps = 0
    for action in _actions(5, 80):
        x, y = fused.step(action), numpy.step(action)
        steps += 1
        np.testing.assert_allclose(x[0], y[0], rtol=0.0, atol=1e-6)
        assert x[1:4] == pytest.approx(y[1:4], rel=0.0, abs=1e-9)
        assert x[4]["step_fraction"] == y[4]["step_fraction"]
        if x[2] or x[3]:
            fused.reset()
            numpy.reset()
    assert calls == [1] * steps
    if kind == "kinematic":
        assert fused.core.handed_rows == steps


@needs_numba
def test_without_the_compiled_step_it_is_step_rows(env_cover_path: str) -> None:
    """``fused`` off: ``SingleStep.step_one`` is ``step_rows`` of row 0 (no buffers made)."""
    single, vector = _pair("dynamic", env_cover_path)
    for env in (single, vector):
        env.core.fused = False
        env.reset(seed=2)
    for action in _actions(8, 40):
        if _same_step(single, vector, action):
            break
    assert single.single._one is None


@needs_numba
@pytest.mark.parametrize("kind", KINDS)
def test_bad_actions_are_refused_and_leave_the_state(env_cover_path: str, kind: str) -> None:
    """Through the compiled single step: a wrong shape, a value that is not finite or
    not a number is an InputError before anything moves; a list, a float32 and a
    float64 array of the same numbers step alike."""
    envs = [_pair(kind, env_cover_path)[0] for _ in range(3)]
    for env in envs:
        env.reset(seed=4)
        env.step(np.zeros(3, dtype=np.float32))  # the compiled call is made
    env = envs[0]
    assert env.single._one is not None
    names = ("theta", "speed", "R", "hold", "steps")
    before = [getattr(env.core, name).copy() for name in names]
    bad_actions = (
        np.array([np.nan, 0.0, 0.0], dtype=np.float32),
        np.array([0.0, np.inf, 0.0]),
        np.array([0.0, 0.0, -np.inf]),
        np.zeros(2, dtype=np.float32),
        np.zeros((1, 3), dtype=np.float32),
        [0.0, float("nan"), 0.0],
        "left",
    )
    for bad in bad_actions:
        with pytest.raises(InputError, match="action"):
            env.step(bad)
        for name, value in zip(names, before, strict=True):
            np.testing.assert_array_equal(getattr(env.core, name), value, err_msg=name)
    same = [0.25, -0.5, 0.75]
    steps = [
        envs[0].step(same),
        envs[1].step(np.array(same, dtype=np.float32)),
        envs[2].step(np.array(same)),
    ]
    for other in steps[1:]:
        np.testing.assert_array_equal(other[0], steps[0][0])
        assert other[1:4] == steps[0][1:4]
    assert steps[0][4]["orientation_error"] == steps[2][4]["orientation_error"]


@needs_numba
@pytest.mark.parametrize("kind", KINDS)
def test_a_steps_observation_and_info_are_fresh_copies(env_cover_path: str, kind: str) -> None:
    """The observation and the info's arrays of a step are the state after it, and
    neither the next step nor a change of the state alters them; the compiled record
    and the numpy path (``fused`` off) give the same keys and numbers."""
    env = _pair(kind, env_cover_path)[0]
    plain = _pair(kind, env_cover_path)[0]
    plain.core.fused = False
    env.reset(seed=6)
    plain.reset(seed=6)
    rng = np.random.default_rng(1)
    kept = []
    for _ in range(6):
        action = rng.uniform(-1.0, 1.0, size=3).astype(np.float32)
        obs, _, _, _, info = env.step(action)
        p_obs, _, _, _, p_info = plain.step(action)
        assert env.single._record is not None and plain.single._record is None
        assert list(info) == list(p_info)
        np.testing.assert_allclose(obs, p_obs, rtol=0.0, atol=1e-6)
        for key, value in info.items():
            np.testing.assert_allclose(value, p_info[key], rtol=0.0, atol=1e-9, err_msg=key)
        for key, name, _ in env.core.RECORD:
            np.testing.assert_array_equal(info[key], getattr(env.core, name)[0], err_msg=key)
        kept.append((obs, info, obs.copy(), {key: np.copy(value) for key, value in info.items()}))
    env.core.theta[0] += 0.1
    env.core.goal_theta[0] += 0.1
    for obs, info, obs_then, info_then in kept:
        np.testing.assert_array_equal(obs, obs_then)
        for key, value in info_then.items():
            np.testing.assert_array_equal(info[key], value, err_msg=key)
    assert kept[0][0] is not kept[1][0] and kept[0][1]["theta"] is not kept[1][1]["theta"]
