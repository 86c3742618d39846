"""Time-optimal timing along planned paths (spm_pin.planning.timing, spm plan --out/--html).

The timed motion is checked against the limits by finite differences of its samples
(the servos' guard's own rate check), against the safe set by its certificate and by
the guard's dense check, and against the trapezoidal profile along the same path.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("toppra")

import itertools

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.cli.plan import CSV_COLUMNS
from spm_pin.errors import InputError
from spm_pin.hardware.config import SafetyLimits
from spm_pin.hardware.guard import SafetyGuard
from spm_pin.planning import (
    PlannedPath,
    SafeSet,
    TimingLimits,
    Trajectory,
    plan,
    safe_set_of,
    time_path,
    trapezoid_duration,
)

#: Two safe inputs whose straight line passes a collision: the path has corners [deg].
NOTCH_START_DEG = [71.0, 8.0, 67.0]
NOTCH_GOAL_DEG = [33.0, -37.0, 8.0]
#: Rate of the finite-difference checks [Hz].
CHECK_RATE = 2000.0
#: Resolution of the independent dense check [deg].
DENSE_DEG = 0.05
TOL = {
    "ends": 1e-6,  # sampled end points against the waypoints [rad]
    "rest": 1e-12,  # speed and acceleration at the ends [rad/s, rad/s^2]
    "limit": 1e-6,  # relative excess of a limit by the analytic samples
    # Relative excess of a finite-difference acceleration: a second difference
    # averages the acceleration over two periods, but across a switch of the
    # piecewise-constant acceleration of a rounded corner it also sees the change of
    # the path's curvature term.
    "fd_limit": 1e-3,
    "on_path": 1e-9,  # distance of a sample from the polyline [rad]
    "csv": 1e-8,  # CSV round trip [deg]
    # Relative excess of toppra's duration over the exact trapezoid on a straight
    # segment (the parameterization's grid).
    "grid": 1e-4,
}


@pytest.fixture(scope="module")
def safe() -> SafeSet:
    return safe_set_of()


@pytest.fixture(scope="module")
def guard() -> SafetyGuard:
    return SafetyGuard(spm.build_robot(), SafetyLimits(path_resolution=math.radians(DENSE_DEG)))


@pytest.fixture(scope="module")
def notch(safe: SafeSet) -> PlannedPath:
    return plan(np.radians(NOTCH_START_DEG), np.radians(NOTCH_GOAL_DEG), safe=safe)


@pytest.fixture(scope="module")
def notch_timed(notch: PlannedPath) -> Trajectory:
    return notch.timed(SafetyLimits())


def _dense(trajectory: Trajectory) -> tuple[np.ndarray, ...]:
    t = trajectory.times_at_rate(CHECK_RATE)
    return (t, *trajectory.sample(t))


def _check_limits(trajectory: Trajectory) -> None:
    _t, theta, speed, acceleration = _dense(trajectory)
    v, a = trajectory.max_speed, trajectory.max_acceleration
    assert np.all(np.abs(speed) <= v * (1 + TOL["limit"]))
    assert np.all(np.abs(acceleration) <= a * (1 + TOL["limit"]))
    # Finite differences of the positions alone (uniform steps but the last).
    h = 1.0 / CHECK_RATE
    inner = theta[:-1]
    fd_speed = np.diff(inner, axis=0) / h
    fd_acceleration = np.diff(inner, n=2, axis=0) / h**2
    assert np.all(np.abs(fd_speed) <= v * (1 + TOL["limit"]))
    assert np.all(np.abs(fd_acceleration) <= a * (1 + TOL["fd_limit"]))


def _distance_to_polyline(points: np.ndarray, theta: np.ndarray) -> np.ndarray:
    best = np.full(points.shape[0], np.inf)
    for a, b in itertools.pairwise(theta):
        d = b - a
        lam = np.clip((points - a) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - (a + lam[:, None] * d), axis=1))
    return best


def _check_ends(trajectory: Trajectory, theta: np.ndarray) -> None:
    for t, end in ((0.0, theta[0]), (trajectory.duration, theta[-1])):
        position, speed, acceleration = trajectory.sample(t)
        np.testing.assert_allclose(position, end, atol=TOL["ends"])
        np.testing.assert_allclose(speed, 0.0, atol=TOL["rest"])
        np.testing.assert_allclose(acceleration, 0.0, atol=TOL["rest"])


def test_a_path_with_corners_is_rounded_safely_and_beats_the_trapezoid(
    safe: SafeSet, guard: SafetyGuard, notch: PlannedPath, notch_timed: Trajectory
) -> None:
    trajectory = notch_timed
    assert notch.theta.shape[0] > 2 and trajectory.smoothed
    _check_ends(trajectory, notch.theta)
    _check_limits(trajectory)
    assert trajectory.duration <= trajectory.trapezoid_duration
    assert trajectory.trapezoid_duration == pytest.approx(
        trapezoid_duration(notch.theta, SafetyLimits()), rel=1e-12
    )
    np.testing.assert_allclose(trajectory.times[[0, -1]], [0.0, trajectory.duration])
    assert np.all(np.diff(trajectory.times) > 0)
    # The waypoints are passed at their times (the spline interpolates them).
    np.testing.assert_allclose(trajectory.sample(trajectory.times)[0], notch.theta, atol=1e-9)
    # Safe along the motion: certified again, and the guard's dense check.
    _, theta, _, _ = _dense(trajectory)
    assert safe.certify(theta)[0]
    assert guard.check_path(theta[1:], start=theta[0]).safe


def test_corners_without_smoothing_stop_on_the_polyline(
    safe: SafeSet, guard: SafetyGuard, notch: PlannedPath
) -> None:
    trajectory = notch.timed(SafetyLimits(), smooth=False)
    assert not trajectory.smoothed
    _check_ends(trajectory, notch.theta)
    _check_limits(trajectory)
    _, theta, _, _ = _dense(trajectory)
    assert _distance_to_polyline(theta, notch.theta).max() <= TOL["on_path"]
    # At rest at every waypoint, passed at its time.
    position, speed, _ = trajectory.sample(trajectory.times)
    np.testing.assert_allclose(position, notch.theta, atol=TOL["ends"])
    np.testing.assert_allclose(speed, 0.0, atol=TOL["rest"])
    # Time-optimal rest to rest on straight lines is the trapezoid.
    assert trajectory.duration == pytest.approx(trajectory.trapezoid_duration, rel=TOL["grid"])
    assert guard.check_path(theta[1:], start=theta[0]).safe


def test_random_straight_paths_meet_the_limits_and_the_guard(
    safe: SafeSet, guard: SafetyGuard
) -> None:
    rng = np.random.default_rng(11)
    points: list[np.ndarray] = []
    while len(points) < 6:
        theta = np.radians(rng.uniform(-60.0, 60.0, 3))
        if guard.check(theta).safe:
            points.append(theta)
    limits = TimingLimits(max_speed=(1.0, 2.0, 1.5), max_acceleration=4.0)
    for start, goal in zip(points[::2], points[1::2], strict=True):
        path = plan(start, goal, safe=safe)
        trajectory = path.timed(limits)
        _check_ends(trajectory, path.theta)
        _check_limits(trajectory)
        assert trajectory.duration <= trajectory.trapezoid_duration * (1 + TOL["grid"])
        t = trajectory.times_at_rate(50.0)
        theta = trajectory.sample(t)[0]
        if not trajectory.smoothed:
            assert _distance_to_polyline(theta, path.theta).max() <= TOL["on_path"]
        # The guard's own rate check at the sampling period.
        tight = SafetyGuard(
            guard.robot,
            SafetyLimits(
                max_speed=max(limits.max_speed),  # type: ignore[arg-type]
                max_acceleration=4.0,
                path_resolution=math.radians(DENSE_DEG),
            ),
        )
        assert tight.check_path(theta[1:], start=theta[0], period=1.0 / 50.0).safe


def test_the_guard_refuses_a_trajectory_that_is_too_fast(notch: PlannedPath) -> None:
    """The rate check sees a limit broken: the test above is not vacuous."""
    fast = time_path(notch.theta, TimingLimits(max_speed=2 * math.radians(90.0)), smooth=False)
    t = fast.times_at_rate(100.0)
    theta = fast.sample(t)[0]
    guard = SafetyGuard(spm.build_robot(), SafetyLimits())
    verdict = guard.check_path(theta[1:-1], start=theta[0], period=0.01)
    assert not verdict.safe and "joint speed" in verdict.reasons[0]


def test_a_path_without_motion_is_at_rest() -> None:
    trajectory = time_path(np.zeros((2, 3)))
    assert trajectory.duration == 0.0
    position, speed, _ = trajectory.sample(np.array([0.0, 1.0]))
    np.testing.assert_allclose(position, 0.0)
    np.testing.assert_allclose(speed, 0.0)


@pytest.mark.parametrize(
    ("theta", "limits", "argument"),
    [
        (np.zeros((3, 2)), None, "theta"),
        ([[0.0, 0.0, np.nan], [0.1, 0.0, 0.0]], None, "theta"),
        (np.zeros((2, 3)), TimingLimits(max_speed=0.0), "max_speed"),
        (np.zeros((2, 3)), TimingLimits(max_acceleration=float("nan")), "max_acceleration"),
        (np.zeros((2, 3)), "fast", "limits"),
    ],
)
def test_bad_input_is_an_input_error(theta: object, limits: object, argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        time_path(theta, limits)  # type: ignore[arg-type]


def test_sample_refuses_nan_and_rate_must_be_positive(notch_timed: Trajectory) -> None:
    with pytest.raises(InputError, match="t must"):
        notch_timed.sample(float("nan"))
    with pytest.raises(InputError, match="rate"):
        notch_timed.times_at_rate(0.0)


# ---------------------------------------------------------------------------- spm plan
def test_spm_plan_times_csv_and_html(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, notch_timed: Trajectory
) -> None:
    pytest.importorskip("meshcat")
    out, page = tmp_path / "motion.csv", tmp_path / "motion.html"
    status = main(["plan", "--from", *map(str, NOTCH_START_DEG), "--to",
                   *map(str, NOTCH_GOAL_DEG), "--json", "--out", str(out), "--rate", "50",
                   "--html", str(page)])  # fmt: skip
    assert status == 0
    record = json.loads(capsys.readouterr().out)
    assert record["duration_s"] == pytest.approx(notch_timed.duration, rel=1e-12)
    assert record["duration_s"] <= record["trapezoid_duration_s"]
    assert record["smoothed"] is True
    np.testing.assert_allclose(record["t_s"], notch_timed.times, rtol=1e-12)
    assert record["limits"]["max_speed_deg_s"] == pytest.approx(90.0)
    assert record["limits"]["max_acceleration_deg_s2"] == pytest.approx(360.0)
    # The CSV holds the trajectory sampled at the rate.
    with out.open(encoding="utf-8") as handle:
        assert handle.readline().strip().split(",") == list(CSV_COLUMNS)
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    t = notch_timed.times_at_rate(50.0)
    np.testing.assert_allclose(table[:, 0], t, atol=1e-12)
    theta, speed, acceleration = notch_timed.sample(t)
    np.testing.assert_allclose(table[:, 1:4], np.degrees(theta), atol=TOL["csv"])
    np.testing.assert_allclose(table[:, 4:7], np.degrees(speed), atol=TOL["csv"] * 100)
    np.testing.assert_allclose(table[:, 7:10], np.degrees(acceleration), rtol=1e-8, atol=1e-6)
    # The page holds an animation of the motion.
    text = page.read_text(encoding="utf-8")
    assert record["html"] == str(page)
    assert "animation" in text.lower() and "<html" in text.lower()


def test_without_toppra_the_message_says_how_to_install(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "toppra", None)  # import toppra now fails
    with pytest.raises(ImportError, match=r"pip install 'spm-pin\[planning\]'"):
        time_path(np.radians([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]))
    assert main(["plan", "--to", "10", "0", "0"]) == 2
    assert "pip install 'spm-pin[planning]'" in capsys.readouterr().err
