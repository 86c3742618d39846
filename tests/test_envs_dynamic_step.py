"""The compiled step of the dynamic environments with a cover
(:func:`spm_pin.envs._dynamic_kernel.step`: the command, the period and its end,
:func:`~spm_pin.envs._dynamic_kernel.finish`) against the numpy path
(``core.fused = False``).

With a saved cover, a whole control period of each robot (the command, the physics
steps, the safety of its end by the cover, the clip's bisection over the physics
steps or the end of the episode, the servos' goals, the rotation, the error, the goal
counter and the reward) runs in one compiled call. The decisions (step fractions,
ends, unsafe steps, the cover's checks asked and settled) are those of the numpy
path; the numbers agree to rounding (the error's sum runs in another order); a row
whose end the safe set must check (outside the certified cells without
``cover_only``) is stepped by numpy, as are robots handed back (period by period,
the compiled physics and end); robots in chunks on threads step as on one; the
kernel run as Python gives the compiled one's bits.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from spm_pin import _jit
from spm_pin.envs import OrientDynamicEnv, OrientDynamicVectorEnv
from spm_pin.envs import _dynamic_kernel as K
from spm_pin.envs._dynamic import THREADED_ROWS

needs_numba = pytest.mark.skipif(not _jit.available(), reason="numba is not installed")

#: The options tried (with the cover; cover_only unless said).
CASES: dict[str, dict[str, Any]] = {
    "position-clip": {"safety": "clip"},
    "position-terminate": {"safety": "terminate"},
    "torque-clip": {"safety": "clip", "actuation": "torque"},
    "rk4-terminate": {"safety": "terminate", "integrator": "rk4"},
    "clip-checked": {"safety": "clip", "cover_only": False},
}
#: The core's state compared after each step.
STATE = ("theta", "speed", "R", "servo_goal", "goal_speed", "torque", "servo_load")


def _actions(seed: int, steps: int, n: int, *, torque: bool) -> np.ndarray:
    """Seeded actions (steps, n, 3), each held for 5 steps (robots build up speed and
    meet the boundary)."""
    rng = np.random.default_rng(seed)
    actions = np.repeat(rng.uniform(-1.0, 1.0, size=(steps // 5 + 1, n, 3)), 5, axis=0)[:steps]
    return 0.2 * actions if torque else actions


def _make(n: int, cover: str, options: dict[str, Any], fused: bool) -> OrientDynamicVectorEnv:
    env = OrientDynamicVectorEnv(n, cover=cover, **{"cover_only": True, "max_steps": 60, **options})
    env.core.fused = fused
    return env


def _count_calls(env: Any) -> list[int]:
    """How many robots each call of the compiled step took (batched calls, and the
    single env's calls of the kernel it gathered its arguments for once)."""
    calls: list[int] = []
    original = env.core._step_call

    def spy(*args: Any) -> Any:
        kernel, arguments = original(*args)

        def counted(*values: Any) -> Any:
            calls.append(int(values[0].size))
            return kernel(*values)

        return counted, arguments

    env.core._step_call = spy
    return calls


@needs_numba
@pytest.mark.parametrize("case", sorted(CASES))
def test_the_compiled_end_decides_as_numpy(env_cover_path: str, case: str) -> None:
    options = CASES[case]
    n, steps = 12, 240
    fused = _make(n, env_cover_path, options, True)
    numpy = _make(n, env_cover_path, options, False)
    calls = _count_calls(fused)
    actions = _actions(7, steps, n, torque=options.get("actuation") == "torque")
    outs = []
    for env in (fused, numpy):
        env.reset(seed=11)
        outs.append([env.step(a) for a in actions])
        outs[-1].append(tuple(np.array(getattr(env.core, name)) for name in STATE))
    fractions, unsafe = [], []
    for step, (x, y) in enumerate(zip(outs[0][:-1], outs[1][:-1], strict=True)):
        np.testing.assert_allclose(x[0], y[0], atol=1e-6, err_msg=f"step {step}")  # float32
        np.testing.assert_allclose(x[1], y[1], rtol=0.0, atol=1e-9, err_msg=f"step {step}")
        np.testing.assert_array_equal(x[2], y[2], err_msg=f"step {step}")
        np.testing.assert_array_equal(x[3], y[3], err_msg=f"step {step}")
        for key in ("step_fraction", "unsafe", "_step_fraction"):
            np.testing.assert_array_equal(x[4][key], y[4][key], err_msg=f"step {step} {key}")
        fractions.append(x[4]["step_fraction"][x[4]["_step_fraction"]])
        unsafe.append(x[4]["unsafe"][x[4]["_unsafe"]])
    for name, u, v in zip(STATE, outs[0][-1], outs[1][-1], strict=True):
        np.testing.assert_allclose(u, v, rtol=0.0, atol=1e-12, err_msg=name)
    np.testing.assert_array_equal(fused.core.hold, numpy.core.hold)
    np.testing.assert_array_equal(fused.core.steps, numpy.core.steps)
    a, b = fused.core.lookup, numpy.core.lookup
    assert a is not None and b is not None
    assert (a.asked, a.settled) == (b.asked, b.settled)
    # The compiled end did the work; the safety was met as the case says.
    stepped = sum(int(np.count_nonzero(x[4]["_step_fraction"])) for x in outs[0][:-1])
    assert sum(calls) == stepped  # every robot stepped went through the compiled step
    if options.get("cover_only", True):
        assert fused.core.handed_rows == 0
    else:  # ends outside the certified cells: the safe set checks them, in numpy
        assert 0 < fused.core.handed_rows < sum(calls)
    if options["safety"] == "clip":
        assert np.any((np.concatenate(fractions) > 0.0) & (np.concatenate(fractions) < 1.0))
    else:
        assert np.any(np.concatenate(unsafe))


@needs_numba
def test_the_python_step_gives_the_compiled_bits(env_cover_path: str) -> None:
    """:func:`~spm_pin.envs._dynamic_kernel.step` run as Python (what numba compiles,
    with its period and end) steps as the compiled one, bit for bit."""
    n, steps = 4, 40
    options = {"safety": "clip"}
    compiled = _make(n, env_cover_path, options, True)
    python = _make(n, env_cover_path, options, True)
    assert python.core.fused_arguments() is not None
    python.core._step_kernel = K.step
    actions = _actions(3, steps, n, torque=False)
    for env in (compiled, python):
        env.reset(seed=5)
    for step, action in enumerate(actions):
        x, y = compiled.step(action), python.step(action)
        for u, v in zip(x[:4], y[:4], strict=True):
            np.testing.assert_array_equal(u, v, err_msg=f"step {step}")
    for name in (*STATE, "hold", "steps"):
        np.testing.assert_array_equal(getattr(compiled.core, name), getattr(python.core, name))


@needs_numba
def test_robots_in_threads_step_as_on_one_thread(env_cover_path: str) -> None:
    """Chunks of robots on two threads: the same bits as one thread."""
    n, steps = 2 * THREADED_ROWS + 17, 12
    envs = [_make(n, env_cover_path, {"safety": "clip"}, True) for _ in range(2)]
    envs[0].core.threads, envs[1].core.threads = 2, 1
    assert envs[0].core.chunks(n) == 2 and envs[1].core.chunks(n) == 1
    actions = _actions(13, steps, n, torque=False)
    for env in envs:
        env.reset(seed=8)
    for action in actions:
        x, y = envs[0].step(action), envs[1].step(action)
        for u, v in zip(x[:4], y[:4], strict=True):
            np.testing.assert_array_equal(u, v)
    for name in (*STATE, "hold", "steps"):
        np.testing.assert_array_equal(getattr(envs[0].core, name), getattr(envs[1].core, name))
    a, b = envs[0].core.lookup, envs[1].core.lookup
    assert a is not None and b is not None and (a.asked, a.settled) == (b.asked, b.settled)


@needs_numba
def test_the_single_env_steps_compiled(env_cover_path: str) -> None:
    """One robot: the compiled step, the same steps as numpy's."""
    envs = [OrientDynamicEnv(cover=env_cover_path, cover_only=True, max_steps=40) for _ in range(2)]
    envs[1].core.fused = False
    calls = _count_calls(envs[0])
    actions = _actions(9, 120, 1, torque=False)[:, 0]
    for env in envs:
        env.reset(seed=21)
    for action in actions:
        x, y = envs[0].step(action), envs[1].step(action)
        np.testing.assert_allclose(x[0], y[0], atol=1e-6)
        assert x[2:4] == y[2:4] and x[4]["step_fraction"] == y[4]["step_fraction"]
        if x[2] or x[3]:
            for env in envs:
                env.reset()
    assert len(calls) == len(actions)


@needs_numba
@pytest.mark.parametrize("case", ["position-clip", "rk4-terminate"])
def test_robots_handed_back_step_period_by_period_as_numpy(env_cover_path: str, case: str) -> None:
    """Every robot handed back by the compiled step: the periods' compiled physics and
    compiled ends (:func:`~spm_pin.envs._dynamic_kernel.finish`) step as numpy."""
    options = CASES[case]
    n, steps = 8, 150
    fused = _make(n, env_cover_path, options, True)
    numpy = _make(n, env_cover_path, options, False)

    def hand_back(rows: Any, action: Any, out: Any, handed: Any, *args: Any) -> None:
        handed[:] = True

    fused.core._call_step = hand_back  # type: ignore[method-assign]
    ends: list[int] = []
    original = fused.core._finish_fused

    def spy(rows: Any, *args: Any) -> Any:
        ends.append(int(rows.size))
        return original(rows, *args)

    fused.core._finish_fused = spy  # type: ignore[method-assign]
    actions = _actions(17, steps, n, torque=False)
    for env in (fused, numpy):
        env.reset(seed=19)
    for step, action in enumerate(actions):
        x, y = fused.step(action), numpy.step(action)
        np.testing.assert_allclose(x[1], y[1], rtol=0.0, atol=1e-9, err_msg=f"step {step}")
        for u, v in zip(x[2:4], y[2:4], strict=True):
            np.testing.assert_array_equal(u, v, err_msg=f"step {step}")
        np.testing.assert_array_equal(x[4]["step_fraction"], y[4]["step_fraction"])
    for name in STATE:
        np.testing.assert_allclose(
            getattr(fused.core, name), getattr(numpy.core, name), rtol=0.0, atol=1e-12
        )
    assert ends and sum(ends) > 0 and fused.core.handed_rows == 0
