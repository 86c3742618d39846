"""Safe motion planning (spm_pin.planning, spm plan).

Every planned path is checked again by an independent dense checker: the servos'
safety guard (its own robot model) at samples 0.05 deg apart. Orientation goals are
checked with forward kinematics, the Lipschitz bounds of the certificate against
exact link distances and Jacobians at random nearby states.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.errors import InputError, PlanningError
from spm_pin.hardware.config import SafetyLimits
from spm_pin.hardware.guard import SafetyGuard
from spm_pin.planning import PlanSettings, SafeSet, gap_length, plan, safe_set_of
from spm_pin.rotations import matrix_from_rpy

#: Two safe inputs whose straight line passes a collision (proximal_1-distal_2) [deg].
NOTCH_START_DEG = [71.0, 8.0, 67.0]
NOTCH_GOAL_DEG = [33.0, -37.0, 8.0]
TOL = {
    "ends": 1e-12,  # the path's end points against the asked ones [rad]
    "orientation": 1e-9,  # forward kinematics of a goal against the asked rotation
    "length": 1e-9,  # [deg]
}
#: Resolution of the independent dense check [deg].
DENSE_DEG = 0.05


@pytest.fixture(scope="module")
def safe() -> SafeSet:
    return safe_set_of()


@pytest.fixture(scope="module")
def guard() -> SafetyGuard:
    """The independent checker: the servos' guard on a robot model of its own."""
    return SafetyGuard(spm.build_robot(), SafetyLimits(path_resolution=math.radians(DENSE_DEG)))


def _dense_safe(guard: SafetyGuard, theta: np.ndarray) -> bool:
    return bool(guard.check_path(theta[1:], start=theta[0]).safe)


def _random_safe(guard: SafetyGuard, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    while len(out) < n:
        theta = np.radians(rng.uniform(-70.0, 70.0, 3))
        if guard.check(theta).safe:
            out.append(theta)
    return out


def test_random_safe_pairs_give_dense_safe_near_shortest_paths(
    safe: SafeSet, guard: SafetyGuard
) -> None:
    rng = np.random.default_rng(7)
    points = _random_safe(guard, rng, 8)
    for start, goal in zip(points[::2], points[1::2], strict=True):
        path = plan(start, goal, safe=safe)
        np.testing.assert_allclose(path.theta[0], start, atol=TOL["ends"])
        np.testing.assert_allclose(path.theta[-1], goal, atol=TOL["ends"])
        assert _dense_safe(guard, path.theta)
        assert path.straight_length_deg - TOL["length"] <= path.length_deg
        assert path.length_deg <= path.grid_length_deg + TOL["length"]


def test_a_goal_across_the_notch_is_reached_by_a_short_detour(
    safe: SafeSet, guard: SafetyGuard
) -> None:
    start, goal = np.radians(NOTCH_START_DEG), np.radians(NOTCH_GOAL_DEG)
    assert guard.check(start).safe and guard.check(goal).safe
    assert not _dense_safe(guard, np.vstack([start, goal]))  # the straight line collides
    path = plan(start, goal, safe=safe)
    assert path.theta.shape[0] > 2  # a detour
    assert _dense_safe(guard, path.theta)
    np.testing.assert_allclose(path.theta[[0, -1]], [start, goal], atol=TOL["ends"])
    # Near-shortest: shorter than the grid search's path, within 1 % of the straight
    # line (which is shorter than any safe path).
    assert path.length_deg <= path.grid_length_deg + TOL["length"]
    assert path.length_deg <= 1.01 * path.straight_length_deg


def test_an_orientation_goal_is_reached_the_shortest_way_round(safe: SafeSet) -> None:
    R = matrix_from_rpy(np.radians([0.0, 20.0, 45.0]))
    start = np.radians([400.0, 400.0, 400.0])  # more than a turn away from home
    path = plan(start, R, safe=safe)
    fk = spm.forward_kinematics(path.goal)
    np.testing.assert_allclose(fk.R, R, atol=TOL["orientation"])
    assert abs(np.degrees(path.goal.mean() - start.mean())) <= 180.0
    more = plan(start, R, safe=safe, turns=2)
    np.testing.assert_allclose(more.goal - path.goal, 4.0 * math.pi, atol=1e-12)
    np.testing.assert_allclose(spm.forward_kinematics(more.goal).R, R, atol=TOL["orientation"])
    assert more.turns == 2 and more.length_deg > path.length_deg + 700.0


def test_an_orientation_goal_whose_inputs_wrap_apart_is_not_turned_by_a_third(
    safe: SafeSet,
) -> None:
    """Inverse kinematics wraps each input on its own: here the third comes back a
    turn below the other two, and the plain mean of the three would be a third of a
    turn off (the platform turned by 120 degrees)."""
    consistent = np.radians([166.8, 168.2, 190.8])
    R = np.asarray(spm.forward_kinematics(consistent).R)
    solved = spm.inverse_kinematics(R).theta
    assert np.degrees(np.ptp(solved)) > 180.0  # wrapped apart
    path = plan(np.zeros(3), R, safe=safe)
    np.testing.assert_allclose(spm.forward_kinematics(path.goal).R, R, atol=TOL["orientation"])


def test_an_unsafe_goal_is_refused_with_the_check_and_a_nearest_safe_input(
    safe: SafeSet, guard: SafetyGuard
) -> None:
    with pytest.raises(PlanningError) as refused:
        plan(np.zeros(3), np.radians([60.0, 90.0, 220.0]), safe=safe)
    assert refused.value.check == "goal"
    assert "unreachable" in str(refused.value)
    assert refused.value.nearest is not None and guard.check(refused.value.nearest).safe
    with pytest.raises(PlanningError, match="start"):
        plan(np.radians([60.0, 90.0, 220.0]), np.zeros(3), safe=safe)
    with pytest.raises(PlanningError, match=r"out of reach|unsafe"):
        plan(np.zeros(3), matrix_from_rpy(np.radians([0.0, 85.0, 0.0])), safe=safe)


@pytest.mark.parametrize(
    ("start", "goal", "argument"),
    [
        ([0.0, np.nan, 0.0], [0.1, 0.0, 0.0], "start"),
        ([0.0, 0.0], [0.1, 0.0, 0.0], "start"),
        ([0.0, 0.0, 0.0], np.eye(3) * 2.0, "goal"),
        ([0.0, 0.0, 0.0], "home", "goal"),
    ],
)
def test_bad_ends_are_input_errors(safe: SafeSet, start: Any, goal: Any, argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        plan(start, goal, safe=safe)


def test_turns_must_be_whole(safe: SafeSet) -> None:
    with pytest.raises(InputError, match="turns"):
        plan(np.zeros(3), np.eye(3), safe=safe, turns=0.5)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["margin", "check_step_deg", "grid_step_deg"])
def test_settings_are_checked(name: str) -> None:
    with pytest.raises(InputError, match=name):
        PlanSettings(**{name: float("nan")})


def test_the_lipschitz_bounds_hold_at_random_nearby_states(safe: SafeSet) -> None:
    """The certificate's bounds against exact distances and Jacobians: two states a
    small gap step apart differ by no more than bound x step in each check."""
    robot = spm.build_robot()
    lip = safe.lipschitz
    rng = np.random.default_rng(3)
    rows, cols = np.nonzero(safe.safe)
    checked = 0
    for k in rng.choice(rows.size, 25, replace=False):
        d12, d23 = safe.d12[rows[k]], safe.d23[cols[k]]
        step = rng.uniform(0.05, 0.5)
        angle = rng.uniform(0.0, 2.0 * math.pi)
        a = safe.theta_of(d12, d23, 0.0)
        b = safe.theta_of(d12 + step * math.cos(angle), d23 + step * math.sin(angle), 0.0)
        if not (spm.forward_kinematics(a).reachable and spm.forward_kinematics(b).reachable):
            continue
        ja, jb = spm.jacobian(a), spm.jacobian(b)
        assert abs(float(ja.dexterity - jb.dexterity)) <= lip.dexterity * step
        assert abs(float(ja.singularity_margin - jb.singularity_margin)) <= lip.singularity * step
        da = robot.distances(robot.configuration(a))
        db = robot.distances(robot.configuration(b))
        assert max(abs(da[p] - db[p]) for p in da) <= lip.clearance * step
        checked += 1
    assert checked >= 15


def test_gap_length_is_the_input_space_length_without_turning() -> None:
    safe = safe_set_of()
    d12, d23 = np.array([120.0, 150.0, 100.0]), np.array([120.0, 100.0, 140.0])
    theta = safe.theta_of(d12, d23, 0.0)  # the mean input held
    expected = np.sum(np.linalg.norm(np.degrees(np.diff(theta, axis=0)), axis=1))
    assert gap_length(d12, d23) == pytest.approx(expected, rel=1e-12)


# ---------------------------------------------------------------------------- spm plan
def test_spm_plan_json(capsys: pytest.CaptureFixture[str]) -> None:
    status = main(["plan", "--from", *map(str, NOTCH_START_DEG), "--to",
                   *map(str, NOTCH_GOAL_DEG), "--json"])  # fmt: skip
    assert status == 0
    record = json.loads(capsys.readouterr().out)
    for key in ("theta_deg", "t_s", "duration_s", "length_deg", "min_clearance_m",
                "min_dexterity", "planning_time_ms", "limits"):  # fmt: skip
        assert key in record
    theta = np.asarray(record["theta_deg"])
    np.testing.assert_allclose(theta[[0, -1]], [NOTCH_START_DEG, NOTCH_GOAL_DEG], atol=1e-9)
    assert len(record["t_s"]) == len(theta) and record["t_s"][-1] == record["duration_s"]
    assert np.all(np.diff(record["t_s"]) > 0)
    # Within the limits: no joint faster than the speed limit between waypoints.
    speeds = np.abs(np.diff(theta, axis=0)).max(axis=1) / np.diff(record["t_s"])
    assert speeds.max() <= record["limits"]["max_speed_deg_s"] * (1 + 1e-9)
    assert record["min_clearance_m"] >= record["limits"]["margin_m"]


def test_spm_plan_keeps_its_cells_in_a_file(
    tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    """--cells FILE: written after a plan, read by the next process (here: after the
    safe set's cache is emptied), refused for other settings with exit 2."""
    cells = tmp_path / "cells.npz"
    ask = ["plan", "--from", "10", "5", "-5", "--to", "30", "20", "10", "--json"]
    assert main([*ask, "--cells", str(cells)]) == 0
    first = json.loads(capsys.readouterr().out)["cells"]
    assert cells.exists() and first["read"] == 0 and first["written"] > 0
    safe_set_of.cache_clear()  # what a new process starts from
    assert main([*ask, "--cells", str(cells)]) == 0
    second = json.loads(capsys.readouterr().out)["cells"]
    assert second["read"] == first["written"] and second["written"] >= second["read"]
    assert main([*ask, "--margin-mm", "1.0", "--cells", str(cells)]) == 2
    assert "another design, other settings" in capsys.readouterr().err


def test_spm_plan_refuses_an_unsafe_goal_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--to", "60", "90", "220"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unreachable" in err and "nearest safe input" in err
    assert main(["plan", "--to", "10", "0", "0", "--turns", "1"]) == 2
    assert "--turns" in capsys.readouterr().err


def test_spm_plan_orientation_goal(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "--to-rpy", "0", "20", "45", "--turns", "1", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(record["goal_rpy_deg"], [0.0, 20.0, 45.0], atol=1e-9)
    assert record["turns"] == 1


def test_the_path_picture(safe: SafeSet, tmp_path: Any) -> None:
    from spm_pin.planning import path_figure

    path = plan(np.radians(NOTCH_START_DEG), np.radians(NOTCH_GOAL_DEG), safe=safe)
    fig = path_figure(safe, path)
    ax = fig.axes[0]
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert labels[:2] == ["safe", "unsafe"]
    assert labels[2] == f"planned path: {path.length_deg:.1f} deg"
    assert "[deg]" in ax.get_xlabel() and "[deg]" in ax.get_ylabel()
    # The drawn path starts and ends at the gaps of the path's ends.
    line = ax.get_lines()[0]
    d12, d23, _ = safe.gaps_of(path.theta[[0, -1]])
    np.testing.assert_allclose(line.get_ydata()[[0, -1]], d12, atol=1e-9)
    np.testing.assert_allclose(line.get_xdata()[[0, -1]], d23, atol=1e-9)
    out = tmp_path / "plan.png"
    assert main(["plan", "--from", *map(str, NOTCH_START_DEG), "--to",
                 *map(str, NOTCH_GOAL_DEG), "--png", str(out), "--json"]) == 0  # fmt: skip
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
