"""The compiled kernels of the control loop give the Python kernels' bits.

:func:`spm_pin._jit.kernels` compiles the single-input float code with numba (extra
``fast``). Each compiled kernel is compared with the Python kernel it is compiled
from, and both with the batch functions, on seeded random inputs of a coaxial and a
general design (reachable, unreachable, multi-turn and near-singular inputs).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import spm_pin as spm
from spm_pin import _jit
from spm_pin.collision import _configuration
from spm_pin.errors import InputError
from spm_pin.hardware import SafetyGuard
from spm_pin.kinematics import _fk_single, _scalar
from spm_pin.kinematics._common import rotation_about
from spm_pin.kinematics.fk import turned
from spm_pin.kinematics.jacobian import SINGULAR_TOL

pytest.importorskip("numba")  # the test extra installs it; without it nothing compiles

#: Sizes of the random samples and their seed.
N = 1500
SEED = 20281
DESIGNS = ("prototype", "agile_eye")


def _same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def _inputs(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    wide = rng.uniform(-1.4, 1.4, (n, 3))
    turns = rng.uniform(-1.0, 1.0, (n // 10, 3)) + 2 * np.pi * rng.integers(-2, 3, (n // 10, 1))
    edge = np.zeros((n // 10, 3))
    edge[:, 0] = rng.choice([-1.0, 1.0], n // 10) * np.radians(rng.uniform(100.0, 110.0, n // 10))
    return np.vstack([wide, turns, edge])


@pytest.fixture(scope="module")
def compiled() -> dict[str, dict[str, object]]:
    return {
        "fk": _jit.kernels(_fk_single.KERNELS),
        "measures": _jit.kernels(_scalar.KERNELS),
        "closed": _jit.kernels(_configuration.KERNELS),
    }


def test_kernels_are_compiled(compiled: dict[str, dict[str, object]]) -> None:
    assert _jit.available()
    for group in compiled.values():
        for name, kernel in group.items():
            assert type(kernel).__name__ == "CPUDispatcher", name
    # The Python functions themselves are left as they are.
    assert type(_fk_single.home_rotation).__name__ == "function"
    assert _jit.kernels(_fk_single.KERNELS) is compiled["fk"]  # compiled once


@pytest.mark.parametrize("name", DESIGNS)
def test_forward_kinematics_measures_and_configuration_bit_for_bit(
    name: str, compiled: dict[str, dict[str, object]]
) -> None:
    design = spm.SPMDesign.preset(name)
    robot = spm.build_robot(design)
    k = _scalar.constants(design)
    legs = _configuration.leg_axes(design)
    thetas = _inputs(N, SEED)
    batch = spm.forward_kinematics(thetas, design)
    counts = {"reachable": 0, "singular": 0}
    for i, theta in enumerate(thetas):
        values = theta.tolist()
        fast = _scalar.fk_home(values, k, compiled["fk"])
        plain = _scalar.fk_home(values, k)
        one = spm.forward_kinematics(theta, design)  # the batch function, one input
        assert fast == plain, theta
        assert (fast is not None) == bool(one.reachable) == bool(batch.reachable[i]), theta
        if fast is None:
            continue
        counts["reachable"] += 1
        assert np.array_equal(np.array(fast), one.R), theta
        # The vectorised solve of many inputs runs Newton in its own order of
        # operations: the same root to rounding.
        assert np.allclose(np.array(fast), batch.R[i], rtol=0.0, atol=1e-13), theta
        measured = _scalar.measures(
            values, fast, k, SINGULAR_TOL, compiled["measures"]["jacobian_parts"]
        )
        jac = spm.jacobian(theta[None], design, R=one.R[None])
        assert measured == _scalar.measures(values, fast, k, SINGULAR_TOL)
        assert _same(measured[0], float(jac.singularity_margin[0])), theta
        assert _same(measured[1], float(jac.dexterity[0])), theta
        counts["singular"] += measured[1] == 0.0
        q = _configuration.rotation_configuration(
            values,
            fast,
            legs,
            compiled["closed"]["closed_angles"],
        )
        assert np.array_equal(q, _configuration.rotation_configuration(values, fast, legs))
        assert np.allclose(q, robot.configuration(theta), rtol=0.0, atol=1e-12), theta
    assert N // 3 < counts["reachable"] < len(thetas), counts


def test_turned_is_the_matrix_product_and_the_float_rows_its_bits() -> None:
    rng = np.random.default_rng(SEED + 1)
    axis = spm.SPMDesign.prototype().u[0]
    angles = rng.uniform(-7.0, 7.0, 400)
    R = spm.forward_kinematics(rng.uniform(-0.8, 0.8, (400, 3))).R
    R = R[np.all(np.isfinite(R), axis=(1, 2))]
    turn = rotation_about(axis, angles[: len(R)])
    both = turned(turn, R)
    assert np.allclose(both, turn @ R, rtol=0.0, atol=1e-15)
    outer = tuple(tuple(row) for row in np.outer(axis, axis).tolist())
    compiled = _jit.kernels(_fk_single.KERNELS)["turned_rows"]
    for k in range(len(R)):
        c, s = float(np.cos(angles[k])), float(np.sin(angles[k]))
        rows = tuple(tuple(row) for row in R[k].tolist())
        plain = _fk_single.turned_rows(c, s, tuple(axis.tolist()), outer, rows)
        assert np.array_equal(np.array(plain), both[k]), k
        assert compiled(c, s, tuple(axis.tolist()), outer, rows) == plain


def test_guard_verdicts_alike_with_and_without_compiled_kernels() -> None:
    """The guard in a process with ``SPM_PIN_JIT=0`` (Python kernels) gives the
    verdicts of the guard here (compiled kernels), digit for digit."""
    goals = _inputs(200, SEED + 2)
    script = (
        "import sys, json, numpy as np\n"
        "from spm_pin.hardware import SafetyGuard\n"
        "from spm_pin import _jit\n"
        "assert not _jit.available()\n"
        "guard = SafetyGuard()\n"
        "out = []\n"
        "for goal in json.load(sys.stdin):\n"
        "    v = guard.static_verdict(np.array(goal))\n"
        "    out.append([v.safe, list(v.reasons), repr(v.singularity_margin), "
        "repr(v.dexterity), [list(p) for p in v.collisions]])\n"
        "print(json.dumps(out))\n"
    )
    import json

    env = {**os.environ, _jit.ENV_VARIABLE: "0"}
    done = subprocess.run(
        [sys.executable, "-c", script],
        input=json.dumps(goals.tolist()),
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    theirs = json.loads(done.stdout)
    guard = SafetyGuard()
    assert guard._fast is not None
    mine = []
    for goal in goals:
        v = guard.static_verdict(goal)
        mine.append(
            [
                v.safe,
                list(v.reasons),
                repr(v.singularity_margin),
                repr(v.dexterity),
                [list(p) for p in v.collisions],
            ]
        )
    assert mine == theirs
    assert any(not row[0] for row in mine) and any(row[0] for row in mine)


def test_switched_off_gives_the_python_functions(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(_jit.ENV_VARIABLE, "0")
    assert not _jit.available()
    functions = (_fk_single._cross, _fk_single._dot)  # a key not compiled before
    plain = _jit.kernels(functions)
    assert plain == {"_cross": _fk_single._cross, "_dot": _fk_single._dot}


@pytest.mark.parametrize("scale", [1e-8, 2e-7, 4.9e-7, 5.1e-7, 1e-6, 3e-6])
def test_one_rotation_checked_as_the_array_check(scale: float) -> None:
    """The float check of one rotation only accepts what the array check accepts,
    and leaves the rest to it (same messages)."""
    rng = np.random.default_rng(SEED + 3)
    base = spm.forward_kinematics(np.radians([10.0, 20.0, 35.0])).R
    for _ in range(50):
        R = base + scale * rng.uniform(-1.0, 1.0, (3, 3))
        stacked_ok = True
        try:
            spm.inverse_kinematics(R[None])  # the array check of a stack of one
        except InputError:
            stacked_ok = False
        try:
            spm.inverse_kinematics(R)
            single_ok = True
        except InputError:
            single_ok = False
        assert single_ok == stacked_ok, R
    for bad in (np.full((3, 3), math.nan), -base, np.diag([1.0, 1.0, math.inf])):
        with pytest.raises(InputError):
            spm.inverse_kinematics(bad)


@pytest.mark.parametrize("name", DESIGNS)
def test_inverse_kinematics_of_one_rotation_bit_for_bit(name: str) -> None:
    design = spm.SPMDesign.preset(name)
    k = _scalar.constants(design)
    compiled = _jit.kernels(_scalar.KERNELS)["ik_parts"]
    rotations = spm.forward_kinematics(_inputs(N, SEED + 4), design).R
    rotations = rotations[np.all(np.isfinite(rotations), axis=(1, 2))]
    # And uniformly random rotations, many of which some leg cannot reach.
    quaternions = np.random.default_rng(SEED + 5).normal(size=(300, 4))
    w, x, y, z = (quaternions / np.linalg.norm(quaternions, axis=1, keepdims=True)).T
    anywhere = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )
    rotations = np.vstack([rotations, anywhere])
    batch = spm.inverse_kinematics(rotations, design)
    closed = 0
    for i, R in enumerate(rotations):
        rows = tuple(tuple(row) for row in R.tolist())
        fast = _scalar.ik_home(rows, k, compiled)
        plain = _scalar.ik_home(rows, k)
        assert fast.leg_reachable == plain.leg_reachable == tuple(batch.leg_reachable[i]), i
        assert np.array_equal(fast.theta, plain.theta, equal_nan=True), i
        assert np.array_equal(fast.b, plain.b, equal_nan=True), i
        if all(fast.leg_reachable):
            closed += 1
            assert np.array_equal(fast.theta, batch.theta[i]), i
    # Every leg of the Agile Eye (90 degree links) closes at any rotation.
    assert closed > 0 and (closed < len(rotations) or name == "agile_eye")


def test_the_guards_one_call_a_cycle_equals_its_parts() -> None:
    """``FastStatic.static`` (one compiled kernel: rotation, Jacobian parts, closed
    angles) gives what the separate kernels give, and the closed q the collision
    check would build."""
    guard = SafetyGuard()
    fast = guard._fast
    assert fast is not None
    legs = _configuration.leg_axes(guard.design)
    reachable = 0
    for theta in _inputs(600, SEED + 6):
        values = theta.tolist()
        ok, margin, dexterity, rotation, q = fast.static(values)
        assert (ok, margin, dexterity, rotation) == fast.measures(values) or (
            math.isnan(margin) and not ok
        ), theta
        if q is None:  # unreachable, or not settled by the float solve (batch decides)
            continue
        reachable += 1
        assert np.array_equal(q, _configuration.rotation_configuration(values, rotation, legs))
        assert fast.collisions_at(q) == fast.collisions(values, rotation)
    assert 0 < reachable < 600 + 120


_CACHE_RUNNER = """
import sys
sys.path.insert(0, sys.argv[1])
import caller, callee
from spm_pin import _jit
g = _jit.kernels((callee.f, caller.g))["g"]
print(g(1.0), sum(g.stats.cache_hits.values()))
"""


def test_the_cache_on_disk_follows_callees_in_other_files(tmp_path: os.PathLike[str]) -> None:
    """A kernel cached on disk is compiled again when a function it calls, or a
    constant it names, changes in another file (numba stamps its cache with the
    kernel's own file alone); unchanged, the next process loads it from the cache."""
    from pathlib import Path

    root = Path(tmp_path)
    callee, caller, runner = root / "callee.py", root / "caller.py", root / "run.py"
    caller.write_text("from callee import SCALE, f\n\n\ndef g(x):\n    return f(x) * SCALE\n")
    runner.write_text(_CACHE_RUNNER)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(root / "cache")}
    env.pop(_jit.ENV_VARIABLE, None)
    runs = [0]

    def run(offset: float, scale: float) -> tuple[float, int]:
        """g(1.0) = (1 + offset) * scale in a new process, and its cache hits."""
        callee.write_text(f"SCALE = {scale!r}\n\n\ndef f(x):\n    return x + {offset!r}\n")
        runs[0] += 1
        stamp = callee.stat().st_mtime_ns + 10**9 * runs[0]  # a new stamp every time
        os.utime(callee, ns=(stamp, stamp))
        done = subprocess.run(
            [sys.executable, str(runner), str(root)],
            capture_output=True,
            text=True,
            timeout=300,
            env=env,
            check=True,
        )
        value, hits = done.stdout.split()
        return float(value), int(hits)

    assert run(1.0, 2.0) == (4.0, 0)  # compiled, cached
    assert run(1.0, 2.0) == (4.0, 1)  # unchanged: from the cache
    assert run(2.0, 2.0)[0] == 6.0  # the callee changed
    assert run(2.0, 3.0)[0] == 9.0  # a constant the caller names changed
    assert run(2.0, 3.0) == (9.0, 1)


def _quotient(a: float, b: float) -> float:
    """a / b."""
    return a / b


def _half_quotient(a: float, b: float) -> float:
    """a / (2 b), through :func:`_quotient`."""
    return 0.5 * _quotient(a, b)


def _divide(a: float, b: float) -> float:
    """a / b (compiled in the plain family only)."""
    return a / b


def _half_divided(a: float, b: float) -> float:
    """a / (2 b), through :func:`_divide`."""
    return 0.5 * _divide(a, b)


def test_the_lanes_family_divides_as_numpy_and_falls_back_to_plain_twins() -> None:
    """``lanes=True``: the same bits, a division by zero gives inf (numpy's error
    model, no exception branch) in the function and its inlined callees; a callee the
    family does not list is the plain twin, which raises as Python does."""
    plain = _jit.kernels((_quotient, _half_quotient))
    lanes = _jit.kernels((_quotient, _half_quotient), lanes=True)
    assert lanes["_quotient"] is not plain["_quotient"]
    assert _jit.ready((_quotient, _half_quotient), lanes=True) is lanes
    for a, b in ((1.0, 3.0), (-2.5, 7.1), (1e-300, 3e10)):
        assert lanes["_half_quotient"](a, b) == plain["_half_quotient"](a, b) == 0.5 * (a / b)
    with pytest.raises(ZeroDivisionError):
        plain["_half_quotient"](1.0, 0.0)
    assert lanes["_quotient"](1.0, 0.0) == math.inf
    assert lanes["_half_quotient"](-1.0, 0.0) == -math.inf
    _jit.kernels((_divide,))
    mixed = _jit.kernels((_half_divided,), lanes=True)
    assert mixed["_half_divided"](1.0, 4.0) == 0.125
    with pytest.raises(ZeroDivisionError):
        mixed["_half_divided"](1.0, 0.0)


def _scaled_sum(x: np.ndarray, scale: float, out: np.ndarray) -> None:
    """out[i] = scale * sum of row i (a kernel that writes its arguments)."""
    for i in range(x.shape[0]):
        out[i] = scale * (x[i, 0] + x[i, 1])


def test_the_entry_point_is_the_kernel_without_dispatch() -> None:
    """``entry``: the compiled machine code for the arguments' types (compiled on
    demand, not the dispatcher), the same results; a Python function is itself."""
    kernel = _jit.kernels((_scaled_sum,))["_scaled_sum"]
    x = np.arange(6.0).reshape(3, 2)
    out, expected = np.zeros(3), np.zeros(3)
    point = _jit.entry(kernel, (x, 2.5, out))  # before any call: compiled here
    assert point is not kernel and callable(point)
    point(x, 2.5, out)
    kernel(x, 2.5, expected)
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(out, 2.5 * x.sum(axis=1))
    assert _jit.entry(kernel, (x, 2.5, out)) is point  # the one overload
    assert _jit.entry(_scaled_sum, (x, 2.5, out)) is _scaled_sum


@_jit.standalone
def _quotients(a: np.ndarray, b: float, out: np.ndarray) -> None:
    """out[i] = a[i] / b through :func:`_quotient` (a pass: compiled on its own)."""
    for i in range(a.shape[0]):
        out[i] = _quotient(a[i], b)


def test_a_standalone_pass_is_not_inlined_in_the_lanes_family() -> None:
    """``standalone``: in the lanes family the pass keeps its own compiled body (its
    callees are still inlined into it), with numpy's division; the plain family is
    unchanged."""
    lanes = _jit.kernels((_quotient, _quotients), lanes=True)
    plain = _jit.kernels((_quotient, _quotients))
    assert lanes["_quotients"].targetoptions["inline"] == "never"  # type: ignore[attr-defined]
    assert lanes["_quotient"].targetoptions["inline"] == "always"  # type: ignore[attr-defined]
    a = np.array([1.0, -3.0, 0.0])
    out, expected = np.empty(3), np.empty(3)
    lanes["_quotients"](a, 4.0, out)
    plain["_quotients"](a, 4.0, expected)
    np.testing.assert_array_equal(out, a / 4.0)
    np.testing.assert_array_equal(out, expected)
    lanes["_quotients"](a, 0.0, out)  # numpy's error model: no exception
    assert out[0] == math.inf and out[1] == -math.inf and math.isnan(out[2])
    with pytest.raises(ZeroDivisionError):
        plain["_quotients"](a, 0.0, expected)


def test_each_kernel_tuple_lists_its_callees_before_their_callers() -> None:
    """A family compiles a tuple's functions in order, each calling the compiled twins
    of the functions compiled before it: a callee missing from the tuple is compiled
    only if another tuple came first in the process (an inlined callee then fails to
    type). So each tuple holds every kernel its functions call, callees first; the
    blocks' tuple (compiled after the dynamic one) may call the dynamic one's. The
    modules are every module of the package whose source defines ``KERNELS = (``."""
    import importlib
    from pathlib import Path

    package = Path(spm.__file__).parent
    names = sorted(
        "spm_pin." + ".".join(path.relative_to(package).with_suffix("").parts)
        for path in package.rglob("*.py")
        if "\nKERNELS = (" in path.read_text(encoding="utf-8")
    )
    known = {"spm_pin.envs._dynamic_kernel", "spm_pin.envs._block_kernel"}
    assert known <= set(names) and "spm_pin.kinematics._scalar" in names
    assert "spm_pin.envs._believed_kernel" in names and len(names) >= 11
    tuples = {name: importlib.import_module(name).KERNELS for name in names}
    every = {id(function) for functions in tuples.values() for function in functions}
    earlier = {"spm_pin.envs._block_kernel": tuples["spm_pin.envs._dynamic_kernel"]}
    checked = 0
    for name, functions in tuples.items():
        before = {id(function) for function in earlier.get(name, ())}
        for function in functions:
            for called in function.__code__.co_names:
                value = function.__globals__.get(called)
                if value is not None and id(value) in every:
                    assert id(value) in before, f"{name}: {function.__name__} calls {called}"
                    checked += 1
            before.add(id(function))
    assert checked > 100
