"""The dynamic environment's step in vectorised blocks of robots
(:mod:`spm_pin.envs._block_kernel`) against the step robot after robot
(:func:`spm_pin.envs._dynamic_kernel.step`).

The block kernel takes each physics step of :data:`~spm_pin.envs._block_kernel.BLOCK`
robots together, a branch of the robot-after-robot step becoming a choice between
two computed values: each robot does the same operations on its own numbers, so the
results must be the same bits. Checked on whole episodes (ends, resets, hand-backs to
numpy, both actuations and safety modes, a last block only partly filled) and on the
period of a block directly, with robots that stop in the middle of it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from spm_pin import _jit
from spm_pin.dynamics import _tuple_kernel
from spm_pin.envs import OrientDynamicVectorEnv, _block_kernel, _dynamic_kernel
from spm_pin.envs._dynamic import BLOCK_ROWS

needs_numba = pytest.mark.skipif(not _jit.available(), reason="numba is not installed")

BLOCK = _block_kernel.BLOCK
#: Robots of the episode test: two full blocks and a part of one.
ROBOTS = 2 * BLOCK + 5


def _actions(seed: int, steps: int, n: int) -> np.ndarray:
    """Seeded actions (steps, n, 3), each held for 4 steps (robots meet the boundary)."""
    rng = np.random.default_rng(seed)
    held = rng.uniform(-1.0, 1.0, size=(steps // 4 + 1, n, 3)).astype(np.float32)
    return np.repeat(held, 4, axis=0)[:steps]


@needs_numba
@pytest.mark.parametrize(
    ("actuation", "safety", "only"),
    [
        ("position", "clip", False),
        ("position", "terminate", True),
        ("torque", "clip", True),
        ("torque", "terminate", False),
    ],
)
def test_blocks_give_the_bits_of_robot_after_robot(
    env_cover_path: str, actuation: str, safety: str, only: bool
) -> None:
    """Without ``cover_only``, ends outside the certified cells go to numpy (the safe
    set checks them): hand-backs from blocks."""
    options: dict[str, Any] = {
        "cover": env_cover_path,
        "cover_only": only,
        "max_steps": 25,
        "actuation": actuation,
        "safety": safety,
    }
    blocks, robots = (OrientDynamicVectorEnv(ROBOTS, **options) for _ in range(2))
    robots.core.blocks = False
    for env in (blocks, robots):
        env.reset(seed=11)
    ends = 0
    for action in _actions(5, 60, ROBOTS):
        a = blocks.step(action)
        b = robots.step(action)
        for x, y in zip(a[:4], b[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        assert a[4].keys() == b[4].keys()
        for key in a[4]:
            np.testing.assert_array_equal(a[4][key], b[4][key], err_msg=key)
        ends += int(np.sum(a[2] | a[3]))
    assert ends > 0  # episodes ended and were reset
    for name in ("theta", "speed", "R", "servo_goal", "goal_speed", "torque", "servo_load"):
        np.testing.assert_array_equal(
            getattr(blocks.core, name), getattr(robots.core, name), err_msg=name
        )
    assert blocks.core.handed_rows == robots.core.handed_rows
    assert (blocks.core.handed_rows > 0) == (not only)
    a_lookup, b_lookup = blocks.core.lookup, robots.core.lookup
    assert a_lookup is not None and b_lookup is not None
    assert (a_lookup.asked, a_lookup.settled) == (b_lookup.asked, b_lookup.settled)
    assert blocks.core._block_kernel is not None and blocks.core._step_kernel is None
    assert robots.core._block_kernel is None


@needs_numba
def test_few_robots_go_robot_after_robot(env_cover_path: str) -> None:
    env = OrientDynamicVectorEnv(BLOCK_ROWS - 1, cover=env_cover_path, cover_only=True)
    env.reset(seed=2)
    env.step(np.zeros((BLOCK_ROWS - 1, 3), dtype=np.float32))
    assert env.core._step_kernel is not None and env.core._block_kernel is None


def _period_inputs(
    core: Any, lanes: int, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Input angles, speeds, rotations, goals, goal speeds and torques asked for of
    ``lanes`` robots: random reachable states, and in lane 1 one that spins into the
    dynamics' input-angle bound after a few physics steps."""
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-0.4, 0.4, (lanes, 3))
    speed = rng.uniform(-2.0, 2.0, (lanes, 3))
    theta[1] = _dynamic_kernel._ANGLE_BOUND - 0.0035  # all inputs alike: a spin
    speed[1] = 1.0
    R = core.dynamics.rotation(theta)
    goal = theta + rng.uniform(-0.05, 0.05, (lanes, 3))
    goal_speed = rng.uniform(-3.0, 3.0, (lanes, 3))
    goal_speed[1] = 1.0
    goal[1] = theta[1]
    wanted = rng.uniform(-1.0, 1.0, (lanes, 3)) * core.servo.stall_torque
    wanted[1] = 0.5 * core.servo.stall_torque  # the spin goes on
    return theta, speed, R, goal, goal_speed, wanted


@needs_numba
@pytest.mark.parametrize("position", [True, False])
@pytest.mark.parametrize("lanes", [BLOCK, 7])
def test_a_blocks_period_is_each_robots_period(
    env_cover_path: str, position: bool, lanes: int
) -> None:
    """The block's period (with a part-filled block) against each robot's own period:
    the steps done (a robot that crosses the input-angle bound stops there), its
    state, torques, load and path."""
    env = OrientDynamicVectorEnv(1, cover=env_cover_path, cover_only=True)
    core = env.core
    _, servo, dt, substeps, _, k = core._physics_arguments()
    f = _jit.kernels(_dynamic_kernel.KERNELS)["flat"](k)
    period = _jit.kernels(_block_kernel.KERNELS, lanes=True)["period"]
    one = _jit.kernels(_dynamic_kernel.KERNELS)["_period_one"]
    theta, speed, R, goal, goal_speed, wanted = _period_inputs(core, lanes, 8)
    S = np.zeros((_block_kernel.ROWS, BLOCK))
    for row, value in (
        (_block_kernel._TH, theta),
        (_block_kernel._SP, speed),
        (_block_kernel._RR, R.reshape(lanes, 9)),
        (_block_kernel._GS, goal),
        (_block_kernel._GV, goal_speed),
        (_block_kernel._WT, wanted),
    ):
        S[row : row + value.shape[1], :lanes] = value.T
        S[row : row + value.shape[1], lanes:] = value[:1].T  # empty lanes: a copy
    P = np.zeros((substeps + 1, 3, BLOCK))
    period(S.reshape(-1), P.reshape(-1), lanes, position, servo, dt, substeps, f)
    done = S[_block_kernel._DONE]
    assert np.all(done[lanes:] == -1.0)
    assert 0 < done[1] < substeps  # lane 1 stopped in the period
    for i in range(lanes):
        path = np.zeros((substeps + 1, 1, 3))
        steps, t, v, Rm, tq, tq_speed, load = one(
            tuple(theta[i]), tuple(speed[i]), tuple(map(tuple, R[i])), tuple(goal[i]),
            tuple(goal_speed[i]), tuple(wanted[i]), position, servo, dt, substeps, False,
            f, path,
        )  # fmt: skip
        assert done[i] == steps, i
        if steps < substeps:
            continue  # the state of a robot handed back is not used
        np.testing.assert_array_equal(S[_block_kernel._TH : _block_kernel._TH + 3, i], t)
        np.testing.assert_array_equal(S[_block_kernel._SP : _block_kernel._SP + 3, i], v)
        np.testing.assert_array_equal(S[_block_kernel._RR : _block_kernel._RR + 9, i], np.ravel(Rm))
        np.testing.assert_array_equal(S[_block_kernel._TAU : _block_kernel._TAU + 3, i], tq)
        np.testing.assert_array_equal(S[_block_kernel._TSP : _block_kernel._TSP + 3, i], tq_speed)
        assert S[_block_kernel._LOAD, i] == load
        np.testing.assert_array_equal(P[1:, :, i], path[1:, 0, :])


@needs_numba
def test_a_blocks_cos_and_sin_are_each_angles() -> None:
    """The lanes' cos and sin (the first round and kernels vectorised, the angles that
    need more taken one by one) against the row kernels' function: the same bits, with
    angles near multiples of pi/2, beyond the reduction's range, inf and NaN."""
    trig_pass = _jit.kernels(_block_kernel.KERNELS, lanes=True)["_trig_pass"]
    angle_cos_sin = _jit.kernels(_tuple_kernel.KERNELS)["_angle_cos_sin"]
    rng = np.random.default_rng(3)
    special = [np.pi / 2, -3 * np.pi / 2, np.nextafter(1303 * np.pi / 2, 0.0), 1e6, np.inf]
    special += [-np.inf, np.nan, -0.0]
    for angles in (rng.uniform(-2048.0, 2048.0, (3, BLOCK)), rng.uniform(-4.0, 4.0, (3, BLOCK))):
        angles.flat[rng.choice(angles.size, len(special), replace=False)] = special
        S = np.zeros((_block_kernel.ROWS, BLOCK))
        S[_block_kernel._TH : _block_kernel._TH + 3] = angles
        trig_pass(S.reshape(-1), _block_kernel._TH, _block_kernel._CS)
        expected = np.array([[angle_cos_sin(x) for x in row] for row in angles])
        expected = np.concatenate([expected[..., 0], expected[..., 1]])
        got = S[_block_kernel._CS : _block_kernel._CS + 6]
        # the bits, so -0 and NaN too
        np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))
