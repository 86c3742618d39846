"""The fused physics steps of the dynamic environments
(:mod:`spm_pin.envs._dynamic_kernel`) against the numpy loop of
:meth:`~spm_pin.envs._dynamic.DynamicCore.step_rows`.

The kernel repeats the loop's operations in the same order, so the environments
step alike with the kernel and without it (``core.fused = False``: the loop alone),
single and batched, for both actuations, both integrators and both safety modes,
over a few hundred seeded random steps across episode ends; the hand-back to the
loop (a state the dynamics cannot step from at the start of a period or in its
middle, a warm start that the loop settles by forward kinematics) keeps them alike;
the uncompiled kernel gives the compiled one's results; a process with
``SPM_PIN_JIT=0`` (numpy everywhere) gives the same to rounding.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
pytest.importorskip("numba")  # the test extra installs it; without it nothing compiles

import spm_pin as spm  # noqa: E402
from spm_pin import _jit  # noqa: E402
from spm_pin.envs import OrientDynamicEnv, OrientDynamicVectorEnv  # noqa: E402
from spm_pin.envs._dynamic import THREADED_ROWS, DynamicCore  # noqa: E402
from spm_pin.envs._dynamic_kernel import period  # noqa: E402

#: Tolerances of this file, by what is compared.
TOL = {
    "same": 1e-12,  # kernel against loop in one process (the same operations)
    "numpy": 1e-9,  # against a process with SPM_PIN_JIT=0 (numpy dynamics)
    "obs": 1e-6,  # float32 observations of the same (one rounding apart at most)
}
#: The physics and safety options tried.
CASES: dict[str, dict[str, Any]] = {
    "position-clip": {"safety": "clip"},
    "torque-clip": {"safety": "clip", "actuation": "torque"},
    "rk4-terminate": {"safety": "terminate", "integrator": "rk4"},
}
#: The records compared after each step (the core's state besides the returns).
STATE = ("theta", "speed", "R", "torque", "torque_speed", "servo_load", "servo_goal")


def _actions(rng: np.random.Generator, steps: int, n: int, hold: int = 5) -> Any:
    """Seeded actions (steps, n, 3), each held for ``hold`` steps (so robots build up
    speed and meet the boundary)."""
    blocks = rng.uniform(-1.0, 1.0, size=(steps // hold + 1, n, 3))
    return np.repeat(blocks, hold, axis=0)[:steps]


def _spy(core: DynamicCore) -> list[int]:
    """The numbers of physics steps the kernel completed, call by call."""
    calls: list[int] = []
    original = core._fused_steps

    def wrapper(*args: Any) -> int:
        done = original(*args)
        calls.append(done)
        return done

    core._fused_steps = wrapper  # type: ignore[method-assign]
    return calls


def _record(env: Any, out: tuple[Any, ...]) -> np.ndarray:
    """One step's observations, reward, ends, fraction and the core's state, flat."""
    obs, reward, terminated, truncated, info = out
    core = env.core
    parts = [
        np.ravel(obs),
        np.ravel(reward),
        np.ravel(terminated),
        np.ravel(truncated),
        np.ravel(info["step_fraction"]),
        np.ravel(info["unsafe"]),
        *(np.ravel(getattr(core, name)) for name in STATE),
    ]
    return np.concatenate([np.asarray(p, dtype=float) for p in parts])


def _roll(env: Any, seed: int, actions: Any, *, single: bool) -> np.ndarray:
    env.reset(seed=seed)
    rows = []
    for action in actions:
        rows.append(_record(env, env.step(action[0] if single else action)))
    return np.array(rows)


def _pair(make: Any) -> tuple[Any, Any]:
    """(with the kernel, loop only) environments made alike."""
    fused, loop = make(), make()
    loop.core.fused = False
    return fused, loop


def test_kernel_is_compiled_and_switched_off() -> None:
    env = OrientDynamicEnv()
    assert env.core.fused and env.core._period_kernel() is not None
    env.core.fused = False
    assert env.core._period_kernel() is None


@pytest.mark.parametrize("case", sorted(CASES))
def test_vector_env_steps_as_the_loop(case: str) -> None:
    """A batch over 200 seeded random steps, episodes ending and restarting: the same
    observations, rewards, ends and states with the kernel and without it."""
    n, steps = 6, 200
    options = CASES[case]
    fused, loop = _pair(lambda: OrientDynamicVectorEnv(n, max_steps=60, **options))
    calls = _spy(fused.core)
    for seed in (1, 2):
        actions = _actions(np.random.default_rng(seed + 10), steps, n)
        if options.get("actuation") == "torque":
            actions = 0.2 * actions
        mine = _roll(fused, seed, actions, single=False)
        theirs = _roll(loop, seed, actions, single=False)
        np.testing.assert_allclose(mine, theirs, rtol=0.0, atol=TOL["same"])
    assert calls and max(calls) == fused.core.substeps  # the kernel did the work


@pytest.mark.parametrize("case", sorted(CASES))
def test_single_env_steps_as_the_loop(case: str) -> None:
    """One robot over 300 seeded random steps, for several seeds."""
    steps = 300
    options = CASES[case]
    fused, loop = _pair(lambda: OrientDynamicEnv(max_steps=100, **options))
    for seed in (3, 4, 5):
        actions = _actions(np.random.default_rng(seed + 20), steps, 1)
        if options.get("actuation") == "torque":
            actions = 0.2 * actions
        mine = _roll(fused, seed, actions, single=True)
        theirs = _roll(loop, seed, actions, single=True)
        np.testing.assert_allclose(mine, theirs, rtol=0.0, atol=TOL["same"])


def test_the_boundary_is_met_and_stays_alike() -> None:
    """Held full actions drive the robots into the guard: clipped and unsafe steps
    happen, and both paths take them alike."""
    n, steps = 8, 120
    for safety in ("clip", "terminate"):
        fused, loop = _pair(lambda s=safety: OrientDynamicVectorEnv(n, safety=s, max_steps=1000))
        actions = np.sign(_actions(np.random.default_rng(7), steps, n, hold=30))
        mine = _roll(fused, 8, actions, single=False)
        theirs = _roll(loop, 8, actions, single=False)
        np.testing.assert_allclose(mine, theirs, rtol=0.0, atol=TOL["same"])
        fraction = mine[:, 3 * n + 21 * n : 4 * n + 21 * n]
        assert np.any(fraction < 1.0)  # the guard stopped some steps


def _crossing(env: Any, row: int = 0) -> None:
    """Put robot ``row`` just inside the home-mode boundary, moving across it: the
    dynamics cannot go on from the middle of the next period."""
    bad = np.radians([0.0, 100.0, -100.0])  # gaps of 20, 320, 20 deg: unreachable
    line = np.linspace(0.0, 1.0, 2001)[:, None] * bad
    edge = int(np.argmin(spm.forward_kinematics(line).reachable))
    start = line[edge - 40]
    env.core.theta[row] = start
    env.core.R[row] = spm.forward_kinematics(start).R
    distance = float(np.linalg.norm(line[edge] - start))
    env.core.speed[row] = bad / np.linalg.norm(bad) * distance / 0.004


@pytest.mark.parametrize("safety", ["clip", "terminate"])
def test_hand_back_in_the_middle_of_a_period(safety: str) -> None:
    """A robot whose state stops settling in the middle of a period: the kernel hands
    back there and the loop ends the step as it would have alone."""
    made = [OrientDynamicVectorEnv(3, safety=safety, actuation="torque") for _ in range(2)]
    made[1].core.fused = False
    calls = _spy(made[0].core)
    records = []
    for env in made:
        env.reset(seed=5)
        _crossing(env)
        action = np.zeros((3, 3))
        records.append([_record(env, env.step(action)) for _ in range(3)])
    substeps = made[0].core.substeps
    assert 0 < calls[0] < substeps  # handed back in the middle
    np.testing.assert_allclose(records[0], records[1], rtol=0.0, atol=TOL["same"])
    assert records[0][0][3 * 21 + 3 + 0] == (1.0 if safety == "terminate" else 0.0)


def test_hand_back_at_the_start_for_an_unreachable_robot() -> None:
    """A robot without a home-mode assembly: the kernel completes nothing, the loop
    makes that robot unsafe and steps the others as alone."""
    bad = np.radians([0.0, 100.0, -100.0])
    made = [OrientDynamicVectorEnv(3, safety="terminate") for _ in range(2)]
    made[1].core.fused = False
    calls = _spy(made[0].core)
    records = []
    for env in made:
        env.reset(seed=5)
        env.core.theta[1] = bad
        records.append(_record(env, env.step(np.full((3, 3), 0.3))))
    assert calls == [0]
    np.testing.assert_allclose(records[0], records[1], rtol=0.0, atol=TOL["same"])
    assert made[0].core.steps.tolist() == [1, 1, 1]


def test_hand_back_for_a_far_warm_start() -> None:
    """A warm start far from the robot's rotation: the kernel hands back, the loop
    solves it by forward kinematics, and the step goes on alike."""
    made = [OrientDynamicEnv(max_steps=100) for _ in range(2)]
    made[1].core.fused = False
    calls = _spy(made[0].core)
    records = []
    for env in made:
        env.reset(seed=9)
        env.core.R[0] = np.diag([1.0, -1.0, -1.0])  # half a turn off
        rows = [_record(env, env.step(np.array([0.5, -0.2, 0.1])))]
        rows += [_record(env, env.step(np.array([0.1, 0.2, -0.3]))) for _ in range(4)]
        records.append(rows)
    assert calls[0] == 0 and calls[1:] == [made[0].core.substeps] * 4
    np.testing.assert_allclose(records[0], records[1], rtol=0.0, atol=TOL["same"])


@pytest.mark.parametrize("actuation", ["position", "torque"])
def test_threads_step_as_one_thread(actuation: str) -> None:
    """A batch of two chunks stepped by two threads, over steps that meet the guard,
    and a period that a robot of the second chunk cannot finish (the batch is put back
    and stepped in one call): the same bits as one thread."""
    n = 2 * THREADED_ROWS + 37
    made = [OrientDynamicVectorEnv(n, actuation=actuation, max_steps=1000) for _ in range(2)]
    made[0].core.threads, made[1].core.threads = 2, 1
    assert (made[0].core.chunks(n), made[1].core.chunks(n)) == (2, 1)
    assert made[0].core.chunks(2 * THREADED_ROWS - 1) == 1  # a chunk holds 256 rows
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(spm.InputError, match="threads"):
            made[0].core.threads = bad  # type: ignore[assignment]
    assert made[0].core.threads == 2  # a refused value leaves it as it was
    chunked: list[int] = []
    original = made[0].core._threaded_period

    def spy(*args: Any) -> int:
        done = original(*args)
        chunked.append(done)
        return done

    made[0].core._threaded_period = spy  # type: ignore[method-assign]
    scale = 0.2 if actuation == "torque" else 1.0
    actions = scale * np.sign(_actions(np.random.default_rng(17), 12, n, hold=6))
    records = []
    for env in made:
        env.reset(seed=21)
        rows = [_record(env, env.step(action)) for action in actions]
        _crossing(env, row=n - 5)
        rows += [_record(env, env.step(np.zeros((n, 3)))) for _ in range(2)]
        records.append(np.array(rows))
    substeps = made[0].core.substeps
    assert chunked[:12] == [substeps] * 12  # the threads took the whole periods
    assert 0 < chunked[12] < substeps  # ... and handed back in the middle, in one call
    assert np.array_equal(records[0], records[1])
    assert np.any(records[0][:12, 3 * n + 21 * n : 4 * n + 21 * n] < 1.0)  # guard met


def test_uncompiled_kernel_gives_the_compiled_results() -> None:
    """The kernel run as Python (what numba compiles) steps as the compiled one."""
    options = CASES["torque-clip"]
    fused, python = _pair(lambda: OrientDynamicVectorEnv(3, max_steps=30, **options))
    python.core.fused = True
    python.core._fused_kernel = period
    actions = 0.2 * _actions(np.random.default_rng(31), 6, 3)
    mine = _roll(fused, 30, actions, single=False)
    theirs = _roll(python, 30, actions, single=False)
    np.testing.assert_allclose(mine, theirs, rtol=0.0, atol=TOL["same"])


_SCRIPT = """
import json, numpy as np
from spm_pin import _jit
from spm_pin.envs import OrientDynamicEnv, OrientDynamicVectorEnv
assert not _jit.available()
out = []
for n in (0, 4):
    env = OrientDynamicEnv(max_steps=50) if n == 0 else OrientDynamicVectorEnv(n, max_steps=50)
    assert env.core._period_kernel() is None
    env.reset(seed=13)
    rng = np.random.default_rng(17)
    rows = []
    for _ in range(STEPS):
        action = rng.uniform(-1, 1, (max(n, 1), 3))
        obs, reward, terminated, truncated, info = env.step(action[0] if n == 0 else action)
        parts = [obs, reward, terminated, truncated, env.core.theta, env.core.speed]
        rows.append([np.ravel(np.asarray(p, dtype=float)).tolist() for p in parts])
    out.append(rows)
print(json.dumps(out))
"""


def test_steps_alike_in_a_process_without_kernels() -> None:
    """Single and batched, 80 steps across episode ends: the same to rounding as a
    process with ``SPM_PIN_JIT=0`` (numpy dynamics, the loop)."""
    steps = 80
    script = _SCRIPT.replace("STEPS", str(steps))
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env={**os.environ, _jit.ENV_VARIABLE: "0"},
        timeout=900,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    theirs = json.loads(done.stdout)
    for n, expected in zip((0, 4), theirs, strict=True):
        env: Any = (
            OrientDynamicEnv(max_steps=50) if n == 0 else OrientDynamicVectorEnv(n, max_steps=50)
        )
        assert env.core._period_kernel() is not None
        env.reset(seed=13)
        rng = np.random.default_rng(17)
        for step in range(steps):
            action = rng.uniform(-1, 1, (max(n, 1), 3))
            out = env.step(action[0] if n == 0 else action)
            parts = [*out[:4], env.core.theta, env.core.speed]
            for k, part in enumerate(parts):
                tol = TOL["obs"] if k == 0 else TOL["numpy"]
                np.testing.assert_allclose(
                    np.ravel(np.asarray(part, dtype=float)),
                    expected[step][k],
                    rtol=0.0,
                    atol=tol,
                    err_msg=f"n = {n}, step {step}, part {k}",
                )
