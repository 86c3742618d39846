"""The compiled step of the kinematic environments (spm_pin.envs._kinematic_kernel).

With a saved cover the robots of :class:`~spm_pin.envs._core.OrientCore` step in one
compiled call: the compiled kernel gives the Python kernel's bits; the decisions
(step fractions, ends) are those of the numpy path and the numbers agree to rounding
(the rotation comes from another Newton); a row the kernel cannot settle is stepped
by numpy. With ``cover_only`` the certified cells are the safe set: every state
entered lies in a certified cell and passes the safe set's checks and the servos'
guard, and starts and goals are drawn in certified cells.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from spm_pin import _jit
from spm_pin.envs import OrientSettings, OrientVectorEnv
from spm_pin.envs import _kinematic_kernel as K
from spm_pin.envs._safe_lookup import SafeLookup
from spm_pin.errors import InputError
from spm_pin.planning import safe_set_of

needs_numba = pytest.mark.skipif(not _jit.available(), reason="numba is not installed")


def _actions(seed: int, steps: int, num: int, hold: int = 1) -> np.ndarray:
    """Seeded actions (steps, num, 3), each held for ``hold`` steps (to push robots
    against the boundary)."""
    rng = np.random.default_rng(seed)
    drawn = rng.uniform(-1.0, 1.0, size=(math.ceil(steps / hold), num, 3))
    return np.repeat(drawn, hold, axis=0)[:steps].astype(np.float32)


def _run(env: OrientVectorEnv, actions: np.ndarray, seed: int) -> list[tuple[Any, ...]]:
    obs, _ = env.reset(seed=seed)
    record: list[tuple[Any, ...]] = [(obs,)]
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        record.append((obs, reward, terminated, truncated, info["step_fraction"]))
    return record


def _env(num: int, cover: str, fused: bool = True, **options: Any) -> OrientVectorEnv:
    env = OrientVectorEnv(num, cover=cover, **options)
    env.core.fused = fused
    return env


@needs_numba
@pytest.mark.parametrize(("safety", "only"), [("clip", True), ("terminate", True), ("clip", False)])
def test_the_compiled_kernel_gives_the_python_kernels_bits(
    env_cover_path: str, safety: str, only: bool
) -> None:
    options = {"safety": safety, "cover_only": only, "max_steps": 60}
    actions = _actions(3, 90, 8, hold=10)
    compiled = _env(8, env_cover_path, **options)
    plain = _env(8, env_cover_path, **options)
    assert plain.core.fused_arguments() is not None  # builds the arguments
    plain.core._kernel = K.step  # the Python function itself
    a, b = _run(compiled, actions, 4), _run(plain, actions, 4)
    for step, (x, y) in enumerate(zip(a, b, strict=True)):
        for u, v in zip(x, y, strict=True):
            np.testing.assert_array_equal(u, v, err_msg=f"step {step}")
    for name in ("theta", "speed", "R", "hold", "steps"):
        np.testing.assert_array_equal(getattr(compiled.core, name), getattr(plain.core, name))
    assert compiled.core.handed_rows == plain.core.handed_rows


@needs_numba
@pytest.mark.parametrize("safety", ["clip", "terminate"])
def test_the_compiled_step_decides_as_numpy(env_cover_path: str, safety: str) -> None:
    """cover_only: the same step fractions and ends as the numpy path, the same
    observations and rewards to rounding, the same states to 1e-12."""
    options = {"safety": safety, "cover_only": True, "max_steps": 80, "goal": "curriculum"}
    actions = _actions(5, 200, 24, hold=15)
    fused = _env(24, env_cover_path, **options)
    numpy = _env(24, env_cover_path, fused=False, **options)
    a, b = _run(fused, actions, 9), _run(numpy, actions, 9)
    fractions = []
    for step, (x, y) in enumerate(zip(a, b, strict=True)):
        np.testing.assert_allclose(x[0], y[0], atol=1e-6, err_msg=f"step {step}")
        if step:
            np.testing.assert_allclose(x[1], y[1], atol=1e-6, err_msg=f"step {step}")
            for u, v in zip(x[2:], y[2:], strict=True):
                np.testing.assert_array_equal(u, v, err_msg=f"step {step}")
            fractions.append(x[4])
    np.testing.assert_allclose(fused.core.theta, numpy.core.theta, atol=1e-12)
    np.testing.assert_allclose(fused.core.R, numpy.core.R, atol=1e-12)
    assert fused.core.handed_rows == 0  # every row stepped by the kernel
    ends = np.concatenate([np.asarray(r[2]) | np.asarray(r[3]) for r in a[1:]])
    assert np.any(ends)  # episodes ended and were reset
    if safety == "clip":
        assert np.any(np.concatenate(fractions) < 1.0)  # the clip was met


@needs_numba
def test_a_row_the_warm_start_does_not_settle_is_stepped_by_numpy(env_cover_path: str) -> None:
    actions = _actions(1, 3, 6)
    envs = [_env(6, env_cover_path, fused=fused, cover_only=True) for fused in (True, False)]
    for env in envs:
        env.reset(seed=2)
        env.core.R[0] = 0.0  # no warm start: Newton cannot move from it
    steps = [[env.step(a) for a in actions] for env in envs]
    assert envs[0].core.handed_rows == 1  # row 0, at its first step only
    for x, y in zip(*steps, strict=True):
        np.testing.assert_array_equal(x[0][0], y[0][0])  # row 0: numpy's own step
        np.testing.assert_allclose(x[0], y[0], atol=1e-6)
    np.testing.assert_array_equal(envs[0].core.theta[0], envs[1].core.theta[0])


@pytest.mark.parametrize("fused", [True, False])
def test_with_cover_only_every_state_is_certified_and_passes_the_guard(
    env_cover_path: str, fused: bool
) -> None:
    """Random actions held against the boundary: each state entered lies in a
    certified cell (a fresh lookup), passes the safe set's checks and the servos'
    guard (independent checkers), speed included."""
    from spm_pin.hardware.guard import SafetyGuard

    n, steps = 16, 120
    env = _env(n, env_cover_path, fused=fused, cover_only=True, max_steps=10_000)
    safe = safe_set_of(env.settings.the_design, env.settings.plan_settings)
    lookup = SafeLookup.from_file(safe, env_cover_path)
    guard = SafetyGuard(limits=env.core.limits)
    period = env.settings.control_period
    env.reset(seed=12)
    states, clipped = [env.core.theta.copy()], 0
    for action in _actions(6, steps, n, hold=25):
        before = env.core.theta.copy()
        _, _, terminated, _, info = env.step(action)
        assert not terminated.any()
        clipped += int(np.sum(info["step_fraction"] < 1.0))
        states.append(env.core.theta.copy())
        for i in range(0, n, 4):
            verdict = guard.check(env.core.theta[i], previous=before[i], period=period)
            assert verdict.safe, verdict.reasons
    theta = np.concatenate(states)
    assert lookup.covered(theta).all()
    assert safe.evaluate(theta).safe.all()
    assert clipped > 0  # the boundary of the cells was met


def test_with_cover_only_starts_and_goals_lie_in_certified_cells(env_cover_path: str) -> None:
    env = OrientVectorEnv(64, cover=env_cover_path, cover_only=True)
    safe = safe_set_of(env.settings.the_design, env.settings.plan_settings)
    lookup = SafeLookup.from_file(safe, env_cover_path)
    plain = OrientVectorEnv(64)
    assert 0 < env.core.vertices.shape[0] < plain.core.vertices.shape[0]
    for seed in range(3):
        env.reset(seed=seed)
        assert lookup.covered(env.core.theta).all()
        assert lookup.covered(env.core.goal_theta).all()


def test_cover_only_settings_are_checked(env_cover_path: str) -> None:
    with pytest.raises(InputError, match="cover_only needs a cover"):
        OrientSettings(cover_only=True)
    with pytest.raises(InputError, match="cover_only must be True or False"):
        OrientSettings(cover=env_cover_path, cover_only="yes")  # type: ignore[arg-type]
    # A safe goal outside the certified cells (next to the boundary) is refused.
    env = OrientVectorEnv(1, cover=env_cover_path)
    safe = env.core.safe_set
    lookup = env.core.lookup
    assert lookup is not None
    rng = np.random.default_rng(0)
    theta = rng.uniform(-math.pi, math.pi, size=(20_000, 3))
    candidates = theta[safe.evaluate(theta).safe & ~lookup.covered(theta)]
    assert candidates.shape[0] > 0
    goal = tuple(float(x) for x in candidates[0])
    OrientVectorEnv(1, cover=env_cover_path, goal="fixed", goal_theta=goal)  # checked: fine
    with pytest.raises(InputError, match="not in a cell the cover certified"):
        OrientVectorEnv(1, cover=env_cover_path, cover_only=True, goal="fixed", goal_theta=goal)


def test_cover_only_refuses_a_home_start_or_a_cover_without_cells(
    env_cover_path: str, tmp_path: Any
) -> None:
    from spm_pin.hardware.config import SafetyLimits
    from spm_pin.planning import SafeCover

    env = OrientVectorEnv(2, cover=env_cover_path, cover_only=True, start="home")
    env.reset(seed=0)
    np.testing.assert_array_equal(env.core.theta, 0.0)  # home lies in a certified cell
    beyond = SafetyLimits(theta_min=(0.1, -3.0, -3.0), theta_max=(3.0, 3.0, 3.0))
    with pytest.raises(
        InputError, match="start 'home' is beyond the joint limits or not in a cell"
    ):
        OrientVectorEnv(1, cover=env_cover_path, cover_only=True, start="home", limits=beyond)
    settings = OrientSettings()
    empty = tmp_path / "empty.npz"
    SafeCover(safe_set_of(settings.the_design, settings.plan_settings)).save(empty)
    with pytest.raises(InputError, match="in the cells the cover certified"):
        OrientVectorEnv(1, cover=str(empty), cover_only=True)


@needs_numba
def test_compiled_observations_are_numpys() -> None:
    """The compiled observations (no noise) equal numpy's, float32 bit for bit, at
    random states (speeds beyond the limit clipped); with noise numpy draws them."""
    from spm_pin.envs import _observe_kernel

    env = OrientVectorEnv(64)
    env.reset(seed=4)
    rng = np.random.default_rng(6)
    core = env.core
    core.theta[:] = rng.uniform(-7.0, 7.0, size=core.theta.shape)
    core.speed[:] = rng.uniform(-2.0, 2.0, size=core.speed.shape) * core.limits.max_speed
    rows = np.array([5, 0, 63, 17, 5])
    compiled = core.observe(rows, [])
    assert core._observe is not None  # the compiled path ran
    core.fused = False
    numpy = core.observe(rows, [])
    assert compiled.dtype == numpy.dtype == np.float32
    np.testing.assert_array_equal(compiled, numpy)
    assert np.any(np.abs(numpy[:, 18:]) == 1.0)  # some speeds were clipped
    python = np.empty_like(compiled)
    _observe_kernel.observe_rows(
        rows, core.R, core.goal, core.theta, core.speed, core.limits.max_speed, python
    )
    np.testing.assert_array_equal(python, compiled)


@needs_numba
def test_the_gaps_modulo_is_pythons_bit_for_bit() -> None:
    """The cover's gaps modulo 360 without ``fmod`` in [-360, 360) (``_mod360``):
    Python's ``%`` bit for bit, compiled and Python, at random, at the range's edges
    and beyond it, for -0.0 (which ``%`` turns into 0.0), inf and NaN."""
    table = _jit.kernels(K.KERNELS)
    rng = np.random.default_rng(8)
    edges = [-360.0, 360.0, 0.0, -0.0, 1e-300, -1e-300, -1e-20, 720.0, -720.0, 1e6, -1e6]
    edges += [np.nextafter(x, t) for x in (-360.0, 360.0, 0.0) for t in (-math.inf, math.inf)]
    values = np.concatenate([rng.uniform(-400.0, 400.0, 4000), rng.uniform(-1e4, 1e4, 1000), edges])
    for x in values.tolist():
        expected = x % 360.0
        for got in (table["_mod360"](x), K._mod360(x)):
            assert got == expected and math.copysign(1.0, got) == math.copysign(1.0, expected), x
    assert table["_mod360"](-0.0) == 0.0 and math.copysign(1.0, table["_mod360"](-0.0)) == 1.0
    for x in (math.inf, -math.inf, math.nan):
        assert math.isnan(table["_mod360"](x)) and math.isnan(x % 360.0)
