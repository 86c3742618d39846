"""The compiled reduced dynamics (:mod:`spm_pin.dynamics._reduced_kernel`) against the
numpy path of :class:`~spm_pin.dynamics.ReducedDynamics`.

The kernels repeat the numpy equations row by row (sums in another order), so the two
agree to rounding: terms, rotations and time steps are compared on seeded random
states of the prototype, one robot and a batch, with and without friction; the
fallback to forward kinematics, the singularity check and the errors are the numpy
path's; the dynamic environment steps alike in a process with ``SPM_PIN_JIT=0``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from typing import Any

import numpy as np
import pytest

import spm_pin as spm
from spm_pin import _jit
from spm_pin import dynamics as D
from spm_pin._checks import ANGLE_LIMIT
from spm_pin.dynamics import _reduced_kernel, _tuple_kernel
from spm_pin.dynamics import reduced as reduced_module
from spm_pin.kinematics.fk import satisfies_home_rule

pytest.importorskip("numba")  # the test extra installs it; without it nothing compiles

SEED = 4242
#: Tolerances of this file: relative to the largest entry of the numpy result (the
#: unit-scale R, J and S: absolute).
TOL = {
    "terms": 1e-12,  # M, c, g, friction
    "unit": 1e-12,  # R, J, S, theta, theta_dot after a step
    "acceleration": 1e-12,  # theta_ddot
    "env": 1e-9,  # the dynamic env's state after a few steps, [rad] and [rad/s]
}
KINDS = ("upright", "loaded")


def _pair(kind: str) -> tuple[D.ReducedDynamics, D.ReducedDynamics]:
    """(compiled, numpy) reduced dynamics of the prototype."""
    options: dict[str, Any] = {}
    if kind == "loaded":
        options = {
            "gravity": (3.0, -2.0, -9.0),
            "friction": D.JointFriction(
                viscous=np.linspace(0.001, 0.009, 9),
                coulomb=np.full(9, 0.002),
                smoothing_speed=0.5,
            ),
            "armature": [0.002, 0.003, 0.004],
        }
    fast = D.ReducedDynamics(**options)
    slow = D.ReducedDynamics(compiled=False, **options)
    assert fast._kernels() is not None and slow._kernels() is None
    return fast, slow


def _states(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n reachable home-mode states away from singularities, speeds and torques."""
    rng = np.random.default_rng(seed)
    theta = np.empty((0, 3))
    while theta.shape[0] < n:
        more = rng.uniform(-0.6, 0.6, (2 * n, 3))
        theta = np.vstack([theta, more[spm.jacobian(more).singularity_margin > 0.2]])
    theta = theta[:n]
    return theta, rng.normal(size=(n, 3)) * 2.0, rng.normal(size=(n, 3)) * 0.05


def _close(actual: np.ndarray, expected: np.ndarray, tol: float, *, relative: bool) -> None:
    scale = max(float(np.abs(expected).max()), 1e-300) if relative else 1.0
    np.testing.assert_allclose(actual, expected, rtol=0.0, atol=tol * scale)


def test_kernels_are_compiled_and_switched_off_by_the_argument() -> None:
    fast, slow = _pair("upright")
    table = fast._kernels()
    assert table is not None
    for name in ("rotations", "terms", "accelerations", "step"):
        assert type(table[name]).__name__ == "CPUDispatcher", name
    assert table is _jit.kernels(_reduced_kernel.KERNELS)  # compiled once
    assert slow._kernels() is None


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_compiled_steps_are_the_python_kernels_bits(kind: str, integrator: str) -> None:
    # The hot callees are inlined into the compiled kernels (_jit.inline): the same
    # operations, so the Python kernels' bits.
    for name in ("_home_rotation", "_row_terms", "_row_acceleration", "_row_step"):
        assert getattr(getattr(_reduced_kernel, name), _jit._INLINE, False), name
    fast, _ = _pair(kind)
    table = fast._kernels()
    assert table is not None
    k = fast._constants()
    theta, theta_dot, tau = _states(12, SEED + 7)
    reference = fast.rotation(theta + 0.01)
    outputs = []
    for step in (table["step"], _reduced_kernel.step):
        out = [np.empty((12, 3)), np.empty((12, 3)), np.empty((12, 3)), np.empty((12, 3, 3))]
        status = step(theta, theta_dot, tau, reference, 1e-3, integrator == "rk4", k, *out)
        assert status == _reduced_kernel.STATUS_OK
        acc, det = np.empty((12, 3)), np.empty(12)
        singular = (
            table["accelerations"] if step is table["step"] else _reduced_kernel.accelerations
        )(theta, theta_dot, tau, out[3], k, acc, det)
        assert not singular.any()
        outputs.append([*out, acc, det])
    for a, b in zip(*outputs, strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("n", [1, 64])
def test_terms_and_rotations_equal_the_numpy_path(kind: str, n: int) -> None:
    fast, slow = _pair(kind)
    theta, theta_dot, _ = _states(n, SEED + n)
    moved = theta + 0.02 * theta_dot
    reference = slow.rotation(theta)
    R = slow.rotation(moved, reference)
    _close(fast.rotation(moved, reference), R, TOL["unit"], relative=False)
    a = fast.terms(moved, theta_dot, reference=reference)
    b = slow.terms(moved, theta_dot, reference=reference)
    for name in ("M", "c", "g", "friction"):
        expected = getattr(b, name)
        if kind == "upright" and name == "friction":
            assert not np.any(getattr(a, name)) and not np.any(expected)
            continue
        _close(getattr(a, name), expected, TOL["terms"], relative=True)
    for name in ("R", "J", "S"):
        _close(getattr(a, name), getattr(b, name), TOL["unit"], relative=False)
    _close(fast.mass_matrix(moved), slow.mass_matrix(moved), TOL["terms"], relative=True)
    _close(fast.holding_torques(moved), slow.holding_torques(moved), TOL["terms"], relative=True)
    for x, y in zip(fast.energy(moved, theta_dot), slow.energy(moved, theta_dot), strict=True):
        _close(x, y, TOL["terms"], relative=True)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("n", [1, 64])
@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_steps_equal_the_numpy_path(kind: str, n: int, integrator: str) -> None:
    fast, slow = _pair(kind)
    theta, theta_dot, torque = _states(n, SEED + 7 * n)
    R = slow.rotation(theta)
    states = {"fast": (theta, theta_dot, R), "slow": (theta, theta_dot, R)}
    for _ in range(20):  # a control period of the env, warm-started each step
        out = {}
        for key, dynamics in (("fast", fast), ("slow", slow)):
            th, rate, rot = states[key]
            out[key] = dynamics.step(th, rate, torque, 1e-3, integrator=integrator, reference=rot)
            states[key] = (out[key].theta, out[key].theta_dot, out[key].R)
        a, b = out["fast"], out["slow"]
        for name in ("theta", "theta_dot", "R"):
            _close(getattr(a, name), getattr(b, name), TOL["unit"], relative=False)
        _close(a.theta_ddot, b.theta_ddot, TOL["acceleration"], relative=True)
    # One robot as (3,): the shapes of the numpy path.
    one_fast = fast.step(theta[0], theta_dot[0], torque[0], 1e-3, integrator=integrator)
    one_slow = slow.step(theta[0], theta_dot[0], torque[0], 1e-3, integrator=integrator)
    assert one_fast.theta.shape == one_slow.theta.shape == (3,)
    assert one_fast.R.shape == (3, 3)
    _close(one_fast.theta_ddot, one_slow.theta_ddot, TOL["acceleration"], relative=True)
    _close(
        fast.forward(theta, theta_dot, torque),
        slow.forward(theta, theta_dot, torque),
        TOL["acceleration"],
        relative=True,
    )


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_a_far_reference_falls_back_to_forward_kinematics(
    integrator: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A warm start far from the solution (the platform upside down) does not settle
    in the home mode: those rows, and only those, are solved by forward kinematics,
    in the compiled path as in the numpy path."""
    fast, slow = _pair("upright")
    theta, theta_dot, torque = _states(64, SEED + 1)
    R = slow.rotation(theta)
    far = R.copy()
    rows = np.arange(0, 64, 5)
    far[rows] = np.diag([1.0, -1.0, -1.0]) @ R[rows]
    solved: list[int] = []
    real = reduced_module.forward_kinematics

    def counting(angles: np.ndarray, design: spm.SPMDesign) -> Any:
        solved.append(angles.shape[0])
        return real(angles, design)

    monkeypatch.setattr(reduced_module, "forward_kinematics", counting)
    _close(fast.rotation(theta, far), R, TOL["unit"], relative=False)
    assert solved == [rows.size]
    _close(slow.rotation(theta, far), R, TOL["unit"], relative=False)
    assert solved == [rows.size, rows.size]
    a = fast.step(theta, theta_dot, torque, 1e-3, integrator=integrator, reference=far)
    b = slow.step(theta, theta_dot, torque, 1e-3, integrator=integrator, reference=far)
    assert len(solved) > 2  # the compiled step left the batch to the Python path
    for name in ("theta", "theta_dot", "R"):
        _close(getattr(a, name), getattr(b, name), TOL["unit"], relative=False)
    _close(a.theta_ddot, b.theta_ddot, TOL["acceleration"], relative=True)


def test_errors_are_the_numpy_paths() -> None:
    fast, slow = _pair("upright")
    theta = np.zeros((5, 3))
    theta[[1, 3]] = np.radians([0.0, 170.0, 0.0])  # a gap of -50 deg: no assembly
    R = slow.rotation(np.zeros((5, 3)))
    messages = []
    for dynamics in (fast, slow):
        with pytest.raises(spm.UnreachableError, match=r"rows \[1, 3\]") as caught:
            dynamics.step(theta, np.zeros((5, 3)), None, 1e-3, reference=R)
        messages.append(str(caught.value))
    assert messages[0] == messages[1]


def test_singular_rows_are_refused_alike(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the singularity threshold raised past every state, both paths refuse the
    same rows with the same message (the threshold is read when the kernels'
    constants are built, so it is raised first)."""
    monkeypatch.setattr(reduced_module, "_SINGULAR_DET", 10.0)
    fast, slow = _pair("upright")
    theta, theta_dot, torque = _states(4, SEED + 2)
    R = slow.rotation(theta)
    for call in (
        lambda d: d.forward(theta, theta_dot, torque, reference=R),
        lambda d: d.step(theta, theta_dot, torque, 1e-3, reference=R),
        lambda d: d.terms(theta, theta_dot, reference=R),
    ):
        messages = []
        for dynamics in (fast, slow):
            with pytest.raises(spm.SingularityError, match=r"rows \[0, 1, 2, 3\]") as caught:
                call(dynamics)
            messages.append(str(caught.value))
        assert messages[0] == messages[1]


def test_dynamic_env_steps_alike_without_the_kernels() -> None:
    """``spm_pin/OrientDynamic-v0`` in a process with ``SPM_PIN_JIT=0`` (numpy) gives
    the states of the env here (compiled kernels) to rounding."""
    script = (
        "import json, numpy as np\n"
        "from spm_pin import _jit\n"
        "from spm_pin.envs import OrientDynamicEnv\n"
        "assert not _jit.available()\n"
        "env = OrientDynamicEnv(max_steps=10**6)\n"
        "env.reset(seed=3)\n"
        "rng = np.random.default_rng(5)\n"
        "out = []\n"
        "for _ in range(6):\n"
        "    obs, reward, *_ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))\n"
        "    out.append(env.unwrapped.core.theta[0].tolist() + "
        "env.unwrapped.core.speed[0].tolist() + [float(reward)])\n"
        "assert env.unwrapped.core.dynamics._kernels() is None\n"
        "print(json.dumps(out))\n"
    )
    env_vars = {**os.environ, _jit.ENV_VARIABLE: "0"}
    done = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=env_vars,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    theirs = np.array(json.loads(done.stdout))
    from spm_pin.envs import OrientDynamicEnv

    env = OrientDynamicEnv(max_steps=10**6)
    env.reset(seed=3)
    rng = np.random.default_rng(5)
    mine = []
    for _ in range(6):
        _, reward, *_ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
        core = env.unwrapped.core  # type: ignore[attr-defined]
        mine.append([*core.theta[0].tolist(), *core.speed[0].tolist(), float(reward)])
    assert env.unwrapped.core.dynamics._kernels() is not None  # type: ignore[attr-defined]
    np.testing.assert_allclose(np.array(mine), theirs, rtol=0.0, atol=TOL["env"])


def test_changed_gravity_armature_and_friction_are_seen() -> None:
    """The compiled path follows changes of gravity, armature and friction made after
    construction, in place or by replacement, as the numpy path does."""
    fast, slow = _pair("loaded")
    theta, theta_dot, _ = _states(8, SEED + 3)
    fast.terms(theta, theta_dot)  # builds the kernels' constants
    for dynamics in (fast, slow):
        dynamics.gravity[:] = (0.5, 1.0, 9.0)
        dynamics.armature[:] = (0.01, 0.0, 0.02)
        assert dynamics.friction is not None
        dynamics.friction.coulomb[:4] = 0.0
    a, b = fast.terms(theta, theta_dot), slow.terms(theta, theta_dot)
    for name in ("M", "g", "friction"):
        _close(getattr(a, name), getattr(b, name), TOL["terms"], relative=True)
    for dynamics in (fast, slow):
        dynamics.gravity = np.array([0.0, -9.81, 0.0])
        dynamics.friction = None
    a, b = fast.terms(theta, theta_dot), slow.terms(theta, theta_dot)
    _close(a.g, b.g, TOL["terms"], relative=True)
    assert not np.any(a.friction) and not np.any(b.friction)


def test_the_home_rule_from_the_terms_is_the_rule_of_every_assembly_mode() -> None:
    """The physics step reads the home sign rule from its terms (b and det A of
    ``_row_terms``, ``_home_of``) instead of computing it again (``_home_rule``): over
    every assembly mode of seeded states (forward_kinematics_all), both give numpy's
    ``satisfies_home_rule`` of numpy's b and det A, and the terms' b and det A are
    the rule's own numbers, bit for bit."""
    fast, _ = _pair("upright")
    table = _jit.kernels(_reduced_kernel.KERNELS)
    design = fast.design
    f = table["flat"](fast._constants())
    home_sign, sign_tol = f[16], f[17]
    theta, rate, _ = _states(12, SEED + 7)
    modes = spm.forward_kinematics_all(theta, design)
    seen = set()
    for n in range(theta.shape[0]):
        cos, sin = table["_trig"](tuple(theta[n]))
        w = table["_proximal"](cos, sin, f[0], f[1])
        for slot in np.flatnonzero(modes.valid[n]):
            R = tuple(tuple(row) for row in modes.R[n, slot])
            v = table["_mat_vecs"](R, f[2])
            out = table["_row_terms"](cos, sin, w, v, tuple(rate[n]), R, f, True)
            det, b = out[1], out[10]
            truth = bool(
                satisfies_home_rule(modes.b[n, slot], np.asarray(modes.det_a[n, slot]), design)
            )
            rule = table["_home_rule"](R, w, f[0], f[2], home_sign, sign_tol)
            assert table["_home_of"](b, det, home_sign, sign_tol) == rule == truth
            np.testing.assert_allclose(b, modes.b[n, slot], rtol=0.0, atol=1e-12)
            seen.add(truth)
    assert seen == {True, False}


def test_the_turns_cos_and_sin_are_libms_to_one_unit_in_the_last_place() -> None:
    # Newton's turns take cos and sin from their Taylor series below SMALL_ANGLE and
    # from fdlibm's kernels below pi/4 (no libm call: the blocks' lanes vectorise, and
    # a kinematic step's turns of a few hundredths of a radian cost half as much);
    # libm is the truth, compiled and Python alike, and from pi/4 on _cos_sin is
    # libm's, bit for bit.
    small, quarter = _tuple_kernel.SMALL_ANGLE, math.pi / 4.0
    table = _jit.kernels(_tuple_kernel.KERNELS)
    rng = np.random.default_rng(SEED)
    signs = rng.choice([-1.0, 1.0], 4000)
    inside = np.concatenate(
        [
            rng.uniform(-small, small, 2000),
            10.0 ** rng.uniform(-20, -2, 2000) * signs[:2000],
            [0.0, -0.0, np.nextafter(small, 0.0), -np.nextafter(small, 0.0), 1e-300],
            rng.uniform(small, quarter, 2000) * signs[2000:],
            [small, -small, 0.05, 0.5, np.nextafter(quarter, 0.0), -np.nextafter(quarter, 0.0)],
        ]
    )
    outside = rng.uniform(-10, 10, 400)
    outside = np.concatenate(
        [[quarter, -quarter, 3.0, -2.0, 1e3], outside[abs(outside) >= quarter]]
    )
    for x in inside:
        c, s = table["_cos_sin"](float(x))
        assert (c, s) == _tuple_kernel._cos_sin(float(x))  # the Python twin's bits
        assert abs(c - math.cos(x)) <= np.spacing(math.cos(x)), x
        assert abs(s - math.sin(x)) <= np.spacing(abs(math.sin(x))), x
    for x in outside:
        assert table["_cos_sin"](float(x)) == (math.cos(x), math.sin(x)), x
    c, s = table["_cos_sin"](math.nan)
    assert math.isnan(c) and math.isnan(s)


def test_the_input_angles_cos_and_sin_are_libms_to_one_unit_in_the_last_place() -> None:
    # The input angles' cos and sin by fdlibm's reduction and kernels (no libm call,
    # so the blocks' lanes vectorise): at random, near multiples of pi/2 (where the
    # first round cancels and the last rounds are needed), in the band where one
    # round stops sufficing, at the range's edges; compiled and Python alike. Beyond
    # the range, inf and NaN: libm's, bit for bit.
    table = _jit.kernels(_tuple_kernel.KERNELS)
    angle_cos_sin = table["_angle_cos_sin"]
    limit = _tuple_kernel.ANGLE_RANGE
    rng = np.random.default_rng(SEED)
    multiples = rng.integers(1, 2**18, 1500) * rng.choice([-1.0, 1.0], 1500) * (np.pi / 2)
    band = multiples * (1.0 + rng.choice([-1.0, 1.0], 1500) * 2.0 ** -rng.uniform(8.0, 40.0, 1500))
    inside = np.concatenate(
        [
            rng.uniform(-ANGLE_LIMIT, ANGLE_LIMIT, 2000),
            rng.uniform(-4.0, 4.0, 2000),
            rng.uniform(-limit, limit, 1000),
            10.0 ** rng.uniform(-300, 0, 500) * rng.choice([-1.0, 1.0], 500),
            multiples,
            np.nextafter(multiples, 0.0),
            multiples + 7 * np.spacing(multiples),
            band,
            [0.0, -0.0, np.nextafter(limit, 0.0), -np.nextafter(limit, 0.0), 1e-300],
        ]
    )
    first = [table["_first_suffices"](x, *table["_first_round"](x)[1:]) for x in map(float, inside)]
    assert 1000 < first.count(False) < len(inside) - 5000  # both paths are taken
    for x in map(float, inside):
        c, s = angle_cos_sin(x)
        assert (c, s) == _tuple_kernel._angle_cos_sin(x)  # the Python twin's bits
        assert abs(c - math.cos(x)) <= np.spacing(abs(math.cos(x))), x
        assert abs(s - math.sin(x)) <= np.spacing(abs(math.sin(x))), x
    assert math.copysign(1.0, angle_cos_sin(-0.0)[1]) == -1.0  # sin(-0) = -0
    for x in (limit, -limit, 1e6, -3e8, 1e300):
        assert angle_cos_sin(x) == (math.cos(x), math.sin(x)), x
    for x in (math.inf, -math.inf, math.nan):
        assert all(math.isnan(value) for value in angle_cos_sin(x))
