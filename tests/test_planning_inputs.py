"""Planning in the 3-D input space (spm_pin.planning.input_space): the Agile Eye, and
the prototype across its notch without the gap plane.

Every path is checked again by an independent dense checker: the servos' safety
guard (its own robot model) at samples 0.05 deg apart; the Lipschitz bounds of the
certificate against exact link distances and Jacobians at random nearby states.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.errors import InputError, PlanningError
from spm_pin.hardware.config import SafetyLimits
from spm_pin.hardware.guard import SafetyGuard
from spm_pin.planning import InputSafeSet, PlanSettings, plan, plan_inputs

pytest.importorskip("ompl")

#: Two safe inputs of the prototype whose straight line passes a collision [deg].
NOTCH_START_DEG = [71.0, 8.0, 67.0]
NOTCH_GOAL_DEG = [33.0, -37.0, 8.0]
#: A safe motion of the Agile Eye [deg].
EYE_START_DEG = [0.0, 0.0, 0.0]
EYE_GOAL_DEG = [20.0, 30.0, 10.0]
TOL = {"ends": 1e-12, "length": 1e-9}
#: Resolution of the independent dense check [deg].
DENSE_DEG = 0.05


def _guard(design: spm.SPMDesign) -> SafetyGuard:
    """The independent checker: the servos' guard on a robot model of its own, with
    the planner's thresholds."""
    settings = PlanSettings()
    limits = SafetyLimits(
        path_resolution=math.radians(DENSE_DEG),
        collision_margin=settings.margin,
        min_singularity_margin=settings.min_singularity_margin,
        min_dexterity=settings.min_dexterity,
    )
    return SafetyGuard(spm.build_robot(design), limits)


def _dense_safe(guard: SafetyGuard, theta: np.ndarray) -> bool:
    return bool(guard.check_path(theta[1:], start=theta[0]).safe)


@pytest.fixture(scope="module")
def eye() -> spm.SPMDesign:
    return spm.SPMDesign.agile_eye()


def test_the_agile_eye_plans_in_its_input_space(eye: spm.SPMDesign) -> None:
    start, goal = np.radians(EYE_START_DEG), np.radians(EYE_GOAL_DEG)
    path = plan(start, goal, eye)
    np.testing.assert_allclose(path.theta[[0, -1]], [start, goal], atol=TOL["ends"])
    assert isinstance(path.safe, InputSafeSet) and path.turns == 0
    assert _dense_safe(_guard(eye), path.theta)
    assert abs(path.length_deg - path.straight_length_deg) <= TOL["length"]  # a straight line
    assert path.min_dexterity > 0 and path.min_singularity_margin >= 0.1
    # An orientation goal: solved in the home working mode, planned the same way.
    R = np.asarray(spm.forward_kinematics(goal, eye).R)
    by_rotation = plan(start, R, eye)
    np.testing.assert_allclose(by_rotation.theta[-1], goal, atol=1e-9)


def test_a_detour_in_3d_around_the_prototypes_notch() -> None:
    """The prototype planned without its gap plane: OMPL's path around the notch,
    certified, checked densely, shorter than OMPL's own path before simplification."""
    prototype = spm.SPMDesign.prototype()
    start, goal = np.radians(NOTCH_START_DEG), np.radians(NOTCH_GOAL_DEG)
    path, facts = plan_inputs(start, goal, prototype, seed=1)
    safe = facts["safe"]
    assert not safe.certify(np.vstack([start, goal]))[0]  # the straight line is not safe
    np.testing.assert_allclose(path[[0, -1]], [start, goal], atol=TOL["ends"])
    assert safe.certify(path)[0]
    assert _dense_safe(_guard(prototype), path)
    length = float(np.sum(np.degrees(np.linalg.norm(np.diff(path, axis=0), axis=1))))
    assert facts["straight_length_deg"] < length <= facts["raw_length_deg"] + TOL["length"]


def test_the_lipschitz_bounds_hold_at_random_nearby_states(eye: spm.SPMDesign) -> None:
    """The 3-D certificate's bounds against exact distances and Jacobians at random
    pairs of safe inputs a small step apart (other pairs than those measured)."""
    safe = InputSafeSet(eye, low=np.radians([-20.0] * 3), high=np.radians([45.0] * 3))
    robot = spm.build_robot(eye)
    lip = safe.lipschitz
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(200):
        a = rng.uniform(safe.low, safe.high)
        if not safe.evaluate(a[None]).safe[0]:
            continue
        step = rng.uniform(0.05, 0.5)
        direction = rng.normal(size=3)
        b = a + math.radians(step) * direction / np.linalg.norm(direction)
        if not spm.forward_kinematics(b, eye).reachable:
            continue
        ja, jb = spm.jacobian(a, eye), spm.jacobian(b, eye)
        assert abs(float(ja.dexterity - jb.dexterity)) <= lip.dexterity * step
        assert abs(float(ja.singularity_margin - jb.singularity_margin)) <= lip.singularity * step
        da = robot.distances(robot.configuration(a))
        db = robot.distances(robot.configuration(b))
        assert max(abs(da[p] - db[p]) for p in da) <= lip.clearance * step
        checked += 1
        if checked == 20:
            break
    assert checked == 20


def test_the_bounds_exceed_every_rate_of_a_fresh_large_draw(eye: spm.SPMDesign) -> None:
    """The measured bounds (before the safety factor) against the steepest of 30,000
    fresh random pairs of the same box (another seed): the search about the steepest
    pairs must find at least as steep places as a draw ten times as large."""
    from spm_pin.planning.input_space import LIPSCHITZ_FACTOR

    box = np.radians([-90.0] * 3), np.radians([90.0] * 3)
    safe = InputSafeSet(eye, low=box[0], high=box[1], seed=0)
    rng = np.random.default_rng(99)
    a = rng.uniform(*box, size=(30_000, 3))
    direction = rng.normal(size=a.shape)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    joint, singularity, dexterity = safe._rates(a, direction)
    assert np.isfinite(joint).sum() > 3_000  # pairs that count
    lip = safe.lipschitz
    assert lip.joint / LIPSCHITZ_FACTOR >= joint.max()
    assert lip.singularity / LIPSCHITZ_FACTOR >= singularity.max()
    assert lip.dexterity / LIPSCHITZ_FACTOR >= dexterity.max()


def test_plans_near_each_other_share_one_safe_set(eye: spm.SPMDesign) -> None:
    """The default planning box is rounded out to the lattice: two plans in the same
    region use one safe set (built once), whose corners are lattice multiples."""
    from spm_pin.planning.input_space import BOX_LATTICE_DEG

    _, first = plan_inputs(np.radians(EYE_START_DEG), np.radians(EYE_GOAL_DEG), eye)
    _, second = plan_inputs(np.radians([5.0, 10.0, 0.0]), np.radians([15.0, 20.0, 5.0]), eye)
    assert first["safe"] is second["safe"]
    corners = np.degrees(np.concatenate([first["safe"].low, first["safe"].high]))
    assert np.allclose(corners / BOX_LATTICE_DEG, np.round(corners / BOX_LATTICE_DEG))
    assert np.all(first["safe"].low <= np.radians(-60.0))
    assert np.all(first["safe"].high >= np.radians(30.0 + 60.0))


def test_an_unsafe_goal_is_refused_with_the_nearest_safe_input(eye: spm.SPMDesign) -> None:
    """The refusal names the failing check and a safe input nearby (certified safe
    within half a check step, so that a path to it can be certified); a brute-force
    draw of 20,000 inputs inside that distance of the goal finds none such."""
    from spm_pin.planning.input_space import _default_box, input_safe_set_of

    goal = np.radians([-40.0, 0.0, 10.0])
    with pytest.raises(PlanningError) as info:
        plan_inputs(np.zeros(3), goal, eye)
    error = info.value
    assert error.check == "goal" and error.reasons and "collision" in error.reasons[0]
    assert "the nearest safe input found is" in str(error) and "rpy" in str(error)
    safe = input_safe_set_of(eye, PlanSettings(), *_default_box(np.zeros(3), goal))
    nearest = np.asarray(error.nearest)
    assert safe.evaluate(nearest[None]).safe[0]
    found = float(np.linalg.norm(nearest - goal))
    assert 0.0 < found < math.radians(45.0)
    rng = np.random.default_rng(7)
    direction = rng.normal(size=(20_000, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    radius = found * rng.uniform(0.0, 1.0, size=20_000) ** (1.0 / 3.0)
    inside = goal + radius[:, None] * direction
    slack = 0.5 * safe.settings.check_step_deg
    assert not np.any(safe.evaluate(inside, want=slack).radius >= slack - 1e-12)
    # The path to that input is planned.
    path, _ = plan_inputs(np.zeros(3), nearest, eye)
    np.testing.assert_allclose(path[-1], nearest, rtol=0.0, atol=1e-12)


def test_bad_requests_are_refused_with_the_reason(eye: spm.SPMDesign) -> None:
    start = np.radians(EYE_START_DEG)
    with pytest.raises(InputError, match="cannot spin endlessly"):
        plan(start, np.radians(EYE_GOAL_DEG), eye, turns=1)
    with pytest.raises(PlanningError, match=r"goal .* is not safe: links nearer"):
        plan(start, np.radians([-40.0, -40.0, -40.0]), eye)
    with pytest.raises(InputError, match="3 finite input angles"):
        plan_inputs(start, [0.0, math.nan, 0.0], eye)
    with pytest.raises(InputError, match="planning box"):
        InputSafeSet(eye, low=np.zeros(3), high=np.zeros(3))


def test_spm_plan_for_the_agile_eye(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["plan", "--design", "agile_eye", "--from", *map(str, EYE_START_DEG)]
    assert main([*args, "--to", *map(str, EYE_GOAL_DEG), "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(record["theta_deg"][-1], EYE_GOAL_DEG, atol=1e-9)
    assert record["min_clearance_m"] >= PlanSettings().margin
    assert record["duration_s"] > 0
    # The gap plane's options do not apply.
    assert main([*args, "--to", *map(str, EYE_GOAL_DEG), "--png", "x.png"]) == 2
    assert "not coaxial" in capsys.readouterr().err
