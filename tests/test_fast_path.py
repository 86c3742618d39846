"""The single-input fast paths give the batch functions' answers, bit for bit.

Inverse kinematics of one rotation, forward kinematics and the Jacobian measures of
one input (:mod:`spm_pin.kinematics._scalar`), the guard's static verdict of one goal
and the servo units of one goal, each against the vectorised code on thousands of
seeded random inputs, edge cases included (unreachable inputs and orientations,
inputs near type I singularities, NaN refused).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.errors import InputError, UnreachableError
from spm_pin.hardware import HardwareConfig, SafetyGuard, SafetyLimits
from spm_pin.hardware.control_table import POSITION_UNIT, PULSES_PER_TURN
from spm_pin.hardware.joints import JointMap
from spm_pin.kinematics import _scalar
from spm_pin.kinematics.jacobian import SINGULAR_TOL

#: Sizes of the random samples.
N = {"kinematics": 3000, "guard": 1500, "pulses": 2000}
#: Seeds.
SEED = {"kinematics": 20270, "guard": 20271, "pulses": 20272, "edge": 20273}


def _same(a: float, b: float) -> bool:
    """Equal bits, NaN equal to NaN."""
    return a == b or (math.isnan(a) and math.isnan(b))


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


@pytest.fixture(scope="module")
def design() -> spm.SPMDesign:
    return spm.SPMDesign.prototype()


def _inputs(rng: np.random.Generator, n: int) -> np.ndarray:
    """Reachable, unreachable and multi-turn inputs, and some near a type I boundary
    (one actuator alone near +-107 deg)."""
    wide = rng.uniform(-1.3, 1.3, (n, 3))
    turns = rng.uniform(-1.0, 1.0, (n // 10, 3)) + 2 * np.pi * rng.integers(-2, 3, (n // 10, 1))
    edge = np.zeros((n // 10, 3))
    edge[:, 0] = rng.choice([-1.0, 1.0], n // 10) * np.radians(rng.uniform(100.0, 110.0, n // 10))
    return np.vstack([wide, turns, edge])


def test_forward_kinematics_and_measures_bit_for_bit(design: spm.SPMDesign) -> None:
    k = _scalar.constants(design)
    thetas = _inputs(np.random.default_rng(SEED["kinematics"]), N["kinematics"])
    reachable = 0
    for theta in thetas:
        fk = spm.forward_kinematics(theta, design)
        rotation = _scalar.fk_home(theta.tolist(), k)
        assert (rotation is not None) == bool(fk.reachable), theta
        if rotation is None:
            continue
        reachable += 1
        assert np.array_equal(np.array(rotation), fk.R), theta
        jac = spm.jacobian(theta[None], design, R=fk.R[None])
        margin, dexterity = _scalar.measures(theta.tolist(), rotation, k, SINGULAR_TOL)
        assert _same(margin, float(jac.singularity_margin[0])), theta
        assert _same(dexterity, float(jac.dexterity[0])), theta
    assert N["kinematics"] // 2 < reachable < len(thetas)  # both kinds present


def test_inverse_kinematics_of_one_rotation_bit_for_bit(design: spm.SPMDesign) -> None:
    rng = np.random.default_rng(SEED["kinematics"] + 1)
    rotations = spm.forward_kinematics(rng.uniform(-1.0, 1.0, (N["kinematics"], 3)), design).R
    rotations = rotations[np.all(np.isfinite(rotations), axis=(1, 2))]
    batch = spm.inverse_kinematics(rotations, design)
    unreachable = 0
    for k, R in enumerate(rotations):
        if not batch.reachable[k]:
            unreachable += 1
            with pytest.raises(UnreachableError):
                spm.inverse_kinematics(R, design)
            continue
        one = spm.inverse_kinematics(R, design)
        assert np.array_equal(one.theta, batch.theta[k]), k
        assert np.array_equal(one.b, batch.b[k]), k
        assert bool(one.reachable) and one.mode == "+++"
        # The batch path of one item (the code every single call ran before).
        stacked = spm.inverse_kinematics(R[None], design)
        assert np.array_equal(one.theta, stacked.theta[0]), k


def test_unreachable_orientation_refused_alike(design: spm.SPMDesign) -> None:
    tilt = math.radians(85.0)
    R = np.array(
        [
            [1.0, 0.0, 0.0],
            [0.0, math.cos(tilt), -math.sin(tilt)],
            [0.0, math.sin(tilt), math.cos(tilt)],
        ]
    )
    batch = spm.inverse_kinematics(R[None], design)
    assert not bool(batch.reachable[0])
    leg = int(np.argmin(batch.leg_reachable[0])) + 1
    with pytest.raises(UnreachableError) as caught:
        spm.inverse_kinematics(R, design)
    assert caught.value.leg == leg and "cannot close" in str(caught.value)


def test_nan_refused_on_every_path(robot: spm.SPMRobot) -> None:
    guard = SafetyGuard(robot)
    verdict = guard.check([0.0, math.nan, 0.0])
    assert not verdict.safe and "not finite" in verdict.reasons[0]
    with pytest.raises(InputError):
        spm.inverse_kinematics(np.full((3, 3), math.nan))
    with pytest.raises(InputError):
        JointMap(HardwareConfig().joints).to_pulses([0.0, math.inf, 0.0])


def _same_verdict(a: object, b: object) -> bool:
    return (
        a.safe == b.safe  # type: ignore[attr-defined]
        and a.reasons == b.reasons  # type: ignore[attr-defined]
        and a.reachable == b.reachable  # type: ignore[attr-defined]
        and a.collisions == b.collisions  # type: ignore[attr-defined]
        and _same(a.singularity_margin, b.singularity_margin)  # type: ignore[attr-defined]
        and _same(a.dexterity, b.dexterity)  # type: ignore[attr-defined]
        and np.array_equal(a.theta, b.theta)  # type: ignore[attr-defined]
        and _same_rotation(a.R, b.R)  # type: ignore[attr-defined]
    )


def _same_rotation(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Both None, or equal bits."""
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))


@pytest.mark.parametrize(
    "limits",
    [SafetyLimits(), SafetyLimits(min_dexterity=0.3, theta_max=(1.0, 1.0, 1.0))],
    ids=["default", "strict"],
)
def test_guard_fast_verdict_equals_the_batch_verdict(
    robot: spm.SPMRobot, limits: SafetyLimits
) -> None:
    guard = SafetyGuard(robot, limits)
    assert guard._fast is not None
    rng = np.random.default_rng(SEED["guard"])
    goals = _inputs(rng, N["guard"])
    goals = np.vstack([goals, np.radians([[60.0, 90.0, 220.0], [60.0, 90.0, 120.0]])])
    kinds = {"safe": 0, "unreachable": 0, "singular": 0, "colliding": 0}
    for goal in goals:
        fast = guard.static_verdict(goal)
        batch = guard._compute(goal[None])[0]
        assert _same_verdict(fast, batch), (goal, fast, batch)
        # The rotation is forward_kinematics' own (home mode), bit for bit.
        fk = spm.forward_kinematics(goal, robot.design)
        assert _same_rotation(fast.R, np.asarray(fk.R) if bool(fk.reachable) else None), goal
        kinds["safe"] += fast.safe
        kinds["unreachable"] += not fast.reachable
        kinds["singular"] += any("singularity" in r for r in fast.reasons)
        kinds["colliding"] += bool(fast.collisions)
    assert all(count > 0 for count in kinds.values()), kinds


def test_guard_check_uses_the_fast_path_and_caches(robot: spm.SPMRobot) -> None:
    guard = SafetyGuard(robot)
    goal = np.radians([10.0, -5.0, 20.0])
    first = guard.check(goal)
    again = guard.check(goal)
    assert first is again and guard.stats["computed"] == 1 and guard.stats["cache_hits"] == 1
    assert _same_verdict(first, guard._compute(goal[None])[0])


def test_replaced_collision_check_takes_the_batch_path(robot: spm.SPMRobot) -> None:
    class Fake:
        design = robot.design

        def collisions(self, theta: object, *, margin: float = 0.0) -> list[tuple[str, str]]:
            return [("proximal_1", "proximal_2")]

    guard = SafetyGuard(Fake())  # type: ignore[arg-type]
    assert guard._fast is None
    verdict = guard.check([0.0, 0.0, 0.0])
    assert not verdict.safe and verdict.collisions == (("proximal_1", "proximal_2"),)


def test_pulses_as_the_array_formula() -> None:
    config = HardwareConfig()
    joints = JointMap(config.joints)
    rng = np.random.default_rng(SEED["pulses"])
    zero = np.array([j.zero_offset for j in joints.joints], dtype=float)
    direction = np.array([j.direction for j in joints.joints], dtype=float)
    gear = np.array([j.gear_ratio for j in joints.joints], dtype=float)
    for theta in rng.uniform(-20.0, 20.0, (N["pulses"], 3)):
        joints.turns = rng.integers(-3, 4, 3).tolist()
        array = (
            zero
            + PULSES_PER_TURN * np.asarray(joints.turns)
            + direction * gear * theta / POSITION_UNIT
        )
        expected = {j.servo_id: round(float(x)) for j, x in zip(joints.joints, array, strict=True)}
        assert joints.to_pulses(theta) == expected
