"""Every limit of SafetyLimits in both directions, through the guard and on the bus.

For each limit a goal just inside is accepted and one just outside is refused with
its reason; on the emulated bus (the real dynamixel-sdk over a pseudo-terminal) the
accepted goal reaches the servos and the refused one never does, as the emulator's
wire log and Goal Position registers show. The goals are found by bisection on the
measured quantity, computed here from the documented formulas (own inverse
kinematics, A rows a_i = w_i x v_i, B = diag(b_ii), J = A^-1 B, dexterity
1/kappa_2(J)) or from the model's link distances, never from the guard.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Iterator

import numpy as np
import pytest

pytest.importorskip("dynamixel_sdk")

from _hardware_data import BAUD, IDS, LATENCY_MS
from _prototype_truth import A1, A2, ETA, V0, U, rot, w_axes

import spm_pin as spm
from spm_pin.errors import InputError, UnsafeCommandError
from spm_pin.hardware import (
    EmulatedBus,
    HardwareConfig,
    SafetyGuard,
    SafetyLimits,
    ServoBus,
    ServoSync,
)
from spm_pin.hardware.control_table import POSITION_UNIT
from spm_pin.hardware.driver import ServoSettings

pytestmark = pytest.mark.hardware
pytest_plugins = ["_hardware"]

#: Tolerances of this file.
TOL = {
    "margin": 1e-6,  # singularity margin / dexterity just inside/outside the limit
    "distance": 2e-5,  # link distance just inside/outside the collision margin [m]
    "rate": 1e-6,  # relative: speed, acceleration, path resolution (guard slack 1e-9)
    "angle": 1e-7,  # joint limits [rad]
    "bisect": 1e-12,  # bisection stops when the bracket is this narrow
}
RATE_HZ = 100.0
PERIOD = 1.0 / RATE_HZ
MAX_SPEED = 3.0  # [rad/s]
MAX_ACCEL = 20.0  # [rad/s^2]

# ------------------------------------------------------------ independent kinematics
# The prototype's constants and w_i(theta) come from tests/_prototype_truth.py.


def ik_home(R: np.ndarray) -> np.ndarray:
    """Inputs of the home working mode (b_ii > 0) for the rotation R (closed form)."""
    v = V0 @ R.T
    theta = np.full(3, np.nan)
    for i in range(3):
        r = np.hypot(v[i, 0], v[i, 1])
        psi = np.arctan2(v[i, 1], v[i, 0])
        c = (np.cos(A2) + np.cos(A1) * v[i, 2]) / (np.sin(A1) * r)
        for sign in (1.0, -1.0):
            t = (ETA[i] - psi - sign * np.arccos(c) + np.pi) % (2 * np.pi) - np.pi
            if np.cross(U, w_axes(np.full(3, t))[i]) @ v[i] > 0:
                theta[i] = t
    return theta


def fk_newton(theta: np.ndarray, R: np.ndarray) -> np.ndarray:
    w = w_axes(theta)
    for _ in range(60):
        v = V0 @ R.T
        delta = np.linalg.solve(np.cross(w, v), np.sum(w * v, axis=1) - np.cos(A2))
        R = rot(delta) @ R
        if np.max(np.abs(delta)) < 1e-15:
            break
    return R


def fk_along(theta: np.ndarray, steps: int = 40) -> np.ndarray:
    """The platform rotation at theta, continued from home along the joint-space line."""
    R = np.eye(3)
    for f in np.linspace(0.0, 1.0, steps + 1)[1:]:
        R = fk_newton(f * np.asarray(theta), R)
    return R


def margin_and_dexterity(theta: np.ndarray, R: np.ndarray) -> tuple[float, float]:
    w = w_axes(theta)
    v = V0 @ R.T
    uxw = np.cross(U, w)
    b = np.sum(uxw * v, axis=1)
    A = np.cross(w, v)
    leg = np.abs(b) / np.linalg.norm(uxw, axis=1)
    sigma_a = np.linalg.svd(A / np.linalg.norm(A, axis=1, keepdims=True), compute_uv=False)
    s = np.linalg.svd(np.linalg.solve(A, np.diag(b)), compute_uv=False)
    return float(min(leg.min(), sigma_a[-1])), float(s[-1] / s[0])


def bisect(f: Callable[[float], float], good: float, bad: float, level: float) -> float:
    """The parameter between good (f > level) and bad (f < level) where f = level."""
    assert f(good) > level > f(bad)
    while abs(good - bad) > TOL["bisect"]:
        mid = 0.5 * (good + bad)
        if f(mid) > level:
            good = mid
        else:
            bad = mid
    return good


def tilt_pose(s: float) -> np.ndarray:
    """The inputs that tilt the platform by s [rad] about x."""
    return ik_home(rot([s, 0.0, 0.0]))


def pulses(theta: np.ndarray) -> list[int]:
    """Goal Position of each servo for theta (direction +1, gear 1, zero at 2048)."""
    return [round(2048 + float(t) / POSITION_UNIT) for t in theta]


# ------------------------------------------------------------ scenarios
class Edge:
    """A limit, a goal just inside, one just outside, and the reason expected."""

    def __init__(self, limits: SafetyLimits, inside: np.ndarray, outside: np.ndarray, reason: str):
        self.limits, self.inside, self.outside, self.reason = limits, inside, outside, reason


def _singularity_edge() -> Edge:
    limit = 0.75  # crossed near a 18 deg tilt; collision-free, dexterity high

    def margin(s: float) -> float:
        theta = tilt_pose(s)
        return margin_and_dexterity(theta, rot([s, 0, 0]))[0]

    lo, hi = np.radians(10.0), np.radians(30.0)
    s_in = bisect(margin, lo, hi, limit + TOL["margin"])
    s_out = bisect(margin, lo, hi, limit - TOL["margin"])
    assert margin(s_in) >= limit + 0.99 * TOL["margin"]
    assert margin(s_out) <= limit - 0.99 * TOL["margin"]
    return Edge(
        SafetyLimits(min_singularity_margin=limit, max_speed=MAX_SPEED, max_acceleration=MAX_ACCEL),
        tilt_pose(s_in),
        tilt_pose(s_out),
        r"too close to a singularity: margin 0\.7500 < 0\.75",
    )


def _dexterity_edge() -> Edge:
    limit = 0.6  # crossed near a 21 deg tilt; the singularity margin is above 0.7 there

    def dexterity(s: float) -> float:
        return margin_and_dexterity(tilt_pose(s), rot([s, 0, 0]))[1]

    lo, hi = np.radians(10.0), np.radians(30.0)
    s_in = bisect(dexterity, lo, hi, limit + TOL["margin"])
    s_out = bisect(dexterity, lo, hi, limit - TOL["margin"])
    return Edge(
        SafetyLimits(min_dexterity=limit, max_speed=MAX_SPEED, max_acceleration=MAX_ACCEL),
        tilt_pose(s_in),
        tilt_pose(s_out),
        r"dexterity 0\.6000 < 0\.6",
    )


def _collision_edge(robot: spm.SPMRobot) -> Edge:
    margin = 0.0005  # [m]; links closer than this count as colliding

    def distance(t: float) -> float:
        return float(robot.distances(np.array([0.0, t, 0.0]))[("proximal_1", "proximal_2")])

    lo, hi = np.radians(60.0), np.radians(75.0)  # gap D_12 = 60 .. 45 deg
    t_in = bisect(distance, lo, hi, margin + TOL["distance"])
    t_out = bisect(distance, lo, hi, margin - TOL["distance"])
    return Edge(
        SafetyLimits(collision_margin=margin, max_speed=MAX_SPEED, max_acceleration=MAX_ACCEL),
        np.array([0.0, t_in, 0.0]),
        np.array([0.0, t_out, 0.0]),
        r"links collide \(margin 0\.5 mm\): proximal_1-proximal_2",
    )


def _joint_limit_edge() -> Edge:
    high = 0.3  # theta_2 only; a common turn of all inputs only turns the platform
    limits = SafetyLimits(
        theta_max=(10.0, high, 10.0), max_speed=MAX_SPEED, max_acceleration=MAX_ACCEL
    )
    return Edge(
        limits,
        np.full(3, high - TOL["angle"]),
        np.full(3, high + TOL["angle"]),
        r"theta_2 = 17\.189 deg is outside the joint limits \[-72000\.0, 17\.2\] deg",
    )


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


@pytest.fixture(scope="module")
def edges(robot: spm.SPMRobot) -> dict[str, Edge]:
    return {
        "singularity_margin": _singularity_edge(),
        "dexterity": _dexterity_edge(),
        "collision_margin": _collision_edge(robot),
        "joint_limits": _joint_limit_edge(),
    }


STATIC = ["singularity_margin", "dexterity", "collision_margin", "joint_limits"]


def config_for(port: str, limits: SafetyLimits, rate_hz: float = RATE_HZ) -> HardwareConfig:
    servo = ServoSettings(profile_velocity=4.0, profile_acceleration=40.0)
    return HardwareConfig(
        port=port,
        baudrate=BAUD,
        latency_timer_ms=LATENCY_MS,
        rate_hz=rate_hz,
        servo=servo,
        safety=limits,
    )


@pytest.fixture
def servos(bus: EmulatedBus) -> Iterator[ServoBus]:
    with ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as driver:
        yield driver


def last_seq(bus: EmulatedBus) -> int:
    log = bus.log()
    return log[-1].seq if log else 0


def goal_registers(bus: EmulatedBus) -> list[int]:
    return [bus.item(i, "Goal Position") for i in IDS]


def assert_nothing_sent(bus: EmulatedBus, since: int) -> None:
    """No Goal Position in any packet the bus received after ``since``."""
    assert bus.goal_writes(since) == []


def assert_sent(bus: EmulatedBus, since: int, theta: np.ndarray) -> None:
    """The last goal triple on the wire after ``since`` is theta's pulses."""
    writes = bus.goal_writes(since)
    assert writes, "nothing reached the bus"
    last = {w.servo_id: w.pulses for w in writes if w.time == writes[-1].time}
    assert [last[i] for i in IDS] == pulses(theta)


# ------------------------------------------------------------ static limits
@pytest.mark.parametrize("name", STATIC)
def test_static_limit_through_the_guard(
    name: str, edges: dict[str, Edge], robot: spm.SPMRobot
) -> None:
    edge = edges[name]
    guard = SafetyGuard(robot, edge.limits)
    accepted = guard.check(edge.inside)
    assert accepted.safe and accepted.reasons == ()
    refused = guard.check(edge.outside)
    assert not refused.safe and len(refused.reasons) == 1
    assert re.fullmatch(edge.reason, refused.reasons[0]), refused.reasons
    with pytest.raises(UnsafeCommandError, match="nothing was sent"):
        refused.require()
    # With this one limit relaxed, every other check passes both goals.
    relaxed = {
        "singularity_margin": {"min_singularity_margin": 0.0},
        "dexterity": {"min_dexterity": 0.0},
        "collision_margin": {"collision_margin": 0.0},
        "joint_limits": {"theta_max": SafetyLimits().theta_max},
    }[name]
    other = SafetyGuard(robot, dataclasses.replace(edge.limits, **relaxed))
    assert other.check(edge.inside).safe and other.check(edge.outside).safe


def test_guard_measures_agree_with_the_independent_ones(
    edges: dict[str, Edge], robot: spm.SPMRobot
) -> None:
    guard = SafetyGuard(robot)
    for name in ("singularity_margin", "dexterity"):
        for theta in (edges[name].inside, edges[name].outside):
            verdict = guard.check(theta)
            margin, dexterity = margin_and_dexterity(theta, fk_along(theta))
            assert verdict.singularity_margin == pytest.approx(margin, abs=1e-9)
            assert verdict.dexterity == pytest.approx(dexterity, abs=1e-9)


@pytest.mark.parametrize("joint", [0, 1, 2])
@pytest.mark.parametrize("side", ["min", "max"])
def test_every_joint_limit_both_ways(joint: int, side: str, robot: spm.SPMRobot) -> None:
    low, high = [-0.5] * 3, [0.5] * 3
    bound = -0.2 if side == "min" else 0.2
    (low if side == "min" else high)[joint] = bound
    guard = SafetyGuard(robot, SafetyLimits(theta_min=tuple(low), theta_max=tuple(high)))
    sign = 1.0 if side == "min" else -1.0
    inside, outside = np.zeros(3), np.zeros(3)
    inside[joint] = bound + sign * TOL["angle"]
    outside[joint] = bound - sign * TOL["angle"]
    assert guard.check(inside).safe
    reasons = guard.check(outside).reasons
    assert len(reasons) == 1 and reasons[0].startswith(f"theta_{joint + 1} = ")
    assert "outside the joint limits" in reasons[0]
    at = np.zeros(3)
    at[joint] = bound
    assert guard.check(at).safe  # the bound itself is inside


@pytest.mark.parametrize("name", STATIC)
def test_static_limit_on_the_bus(
    name: str, edges: dict[str, Edge], bus: EmulatedBus, servos: ServoBus, robot: spm.SPMRobot
) -> None:
    edge = edges[name]
    with ServoSync(servos, config_for(bus.port, edge.limits), robot=robot) as sync:
        sync.start()
        since = last_seq(bus)
        sync.move_to(edge.inside)  # checked whole, then streamed
        assert_sent(bus, since, edge.inside)
        assert sync.step(sync.goal).sent  # hold: the next step starts from rest
        since = last_seq(bus)
        result = sync.step(edge.outside)
        assert result.refused and not result.sent
        assert result.verdict is not None and len(result.verdict.reasons) == 1
        assert re.fullmatch(edge.reason, result.verdict.reasons[0])
        with pytest.raises(UnsafeCommandError, match="nothing was sent"):
            sync.move_to(edge.outside)
        assert_nothing_sent(bus, since)
        assert goal_registers(bus) == pulses(edge.inside)
        assert sync.step(edge.inside).sent  # the loop goes on
    # Over the whole session, the wire carried the accepted goal, never the refused one.
    triples = {}
    for write in bus.goal_writes():
        triples.setdefault(write.time, {})[write.servo_id] = write.pulses
    sent = [[t[i] for i in IDS] for t in triples.values() if len(t) == 3]
    assert pulses(edge.inside) in sent
    if pulses(edge.outside) != pulses(edge.inside):
        assert pulses(edge.outside) not in sent


def test_min_dexterity_goal_never_appears_on_the_bus(
    edges: dict[str, Edge], bus: EmulatedBus, servos: ServoBus, robot: spm.SPMRobot
) -> None:
    """With min_dexterity set, a low-dexterity goal is refused and never on the bus."""
    limits = SafetyLimits(min_dexterity=0.6, max_speed=MAX_SPEED, max_acceleration=MAX_ACCEL)
    low = tilt_pose(np.radians(26.0))  # dexterity about 0.57, margin above 0.7
    margin, dexterity = margin_and_dexterity(low, rot(np.radians([26.0, 0, 0])))
    assert dexterity < 0.59 and margin > 0.5
    assert SafetyGuard(robot).check(low).safe  # only the dexterity limit refuses it
    with ServoSync(servos, config_for(bus.port, limits), robot=robot) as sync:
        sync.start()
        since = last_seq(bus)
        with pytest.raises(UnsafeCommandError, match=r"dexterity 0\.5\d+ < 0\.6"):
            sync.move_to(low)
        assert_nothing_sent(bus, since)
        sync.move_to(edges["dexterity"].inside)
    sent = {w.pulses for w in bus.goal_writes() if w.servo_id == 1}
    assert pulses(low)[0] not in sent


# ------------------------------------------------------------ speed and acceleration
def _speed_reason(speed: float) -> str:
    return f"joint speed {math.degrees(speed):.1f} deg/s > {math.degrees(MAX_SPEED):.1f} deg/s"


def _accel_reason(accel: float) -> str:
    return (
        f"joint acceleration {math.degrees(accel):.1f} deg/s^2 > "
        f"{math.degrees(MAX_ACCEL):.1f} deg/s^2"
    )


RATE_LIMITS = SafetyLimits(max_speed=MAX_SPEED, max_acceleration=MAX_ACCEL)


def test_speed_limit_through_the_guard(robot: spm.SPMRobot) -> None:
    guard = SafetyGuard(robot, RATE_LIMITS)
    step = MAX_SPEED * PERIOD
    cruise = np.full(3, step)  # already moving at max speed: no acceleration
    for joint in range(3):
        inside, outside = 2 * cruise, 2 * cruise  # the other joints cruise on
        inside[joint] = 2 * step * (1 - TOL["rate"] / 2)
        outside[joint] = 2 * step * (1 + TOL["rate"] / 2)
        ok = guard.check(inside, previous=cruise, before_previous=np.zeros(3), period=PERIOD)
        assert ok.safe
        bad = guard.check(outside, previous=cruise, before_previous=np.zeros(3), period=PERIOD)
        speed = (outside[joint] - step) / PERIOD
        assert bad.reasons == (_speed_reason(speed),)
    # Backwards too (|theta_k - theta_k-1|).
    assert not guard.check(-cruise * (1 + TOL["rate"]), previous=np.zeros(3), period=PERIOD).safe
    assert guard.check(-cruise * (1 - TOL["rate"]), previous=np.zeros(3), period=PERIOD).safe


def test_acceleration_limit_through_the_guard(robot: spm.SPMRobot) -> None:
    guard = SafetyGuard(robot, RATE_LIMITS)
    step = MAX_ACCEL * PERIOD**2  # from rest
    for sign in (1.0, -1.0):
        rest = np.zeros(3)
        inside = np.array([0.0, sign * step * (1 - TOL["rate"]), 0.0])
        outside = np.array([0.0, sign * step * (1 + TOL["rate"]), 0.0])
        assert guard.check(inside, previous=rest, before_previous=rest, period=PERIOD).safe
        bad = guard.check(outside, previous=rest, before_previous=rest, period=PERIOD)
        assert bad.reasons == (_accel_reason(abs(outside[1]) / PERIOD**2),)
    # Braking counts as well: moving at 0.1 rad/s, then stopping too hard.
    moving = np.full(3, 0.001)
    stop_in = moving + (0.001 - step * (1 - TOL["rate"]))
    stop_out = moving + (0.001 - step * (1 + TOL["rate"]))
    assert guard.check(stop_in, previous=moving, before_previous=np.zeros(3), period=PERIOD).safe
    assert not guard.check(
        stop_out, previous=moving, before_previous=np.zeros(3), period=PERIOD
    ).safe


def test_unevenly_timed_goals_are_checked_with_the_speeds_of_their_intervals(
    robot: spm.SPMRobot,
) -> None:
    """Goals h1 then h2 apart: the acceleration is the change of the two interval
    speeds over (h1 + h2) / 2, the limit found by bisection on a sampled motion
    (an independent truth: a constant-acceleration motion sampled at those times)."""
    guard = SafetyGuard(robot, RATE_LIMITS)
    h1, h2 = 0.03, 0.01
    v = 0.5  # [rad/s]: cruising, well below MAX_SPEED

    def goals(accel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # theta(t) = v t + accel t^2 / 2 from t = -h1 (before) over 0 (previous) to h2.
        def at(t: float) -> np.ndarray:
            return np.array([0.0, v * t + 0.5 * accel * t**2, 0.0])

        return at(h2), at(0.0), at(-h1)

    for factor, safe in ((1 - TOL["rate"], True), (1 + TOL["rate"], False)):
        goal, previous, before = goals(MAX_ACCEL * factor)
        verdict = guard.check(
            goal, previous=previous, before_previous=before, period=h2, previous_period=h1
        )
        assert verdict.safe is safe, verdict.reasons
        if not safe:
            assert verdict.reasons[0].startswith("joint acceleration")
    # Cruising at a constant speed after a refused goal: the next one spans two
    # intervals (2 h after previous, which was h after before): no acceleration.
    # Taken as evenly timed (no previous_period) the same goals would be refused.
    h = 1e-3
    goal, previous, before = (np.array([0.0, v * t, 0.0]) for t in (2 * h, 0.0, -h))
    history = {"previous": previous, "before_previous": before, "period": 2 * h}
    assert guard.check(goal, **history, previous_period=h).safe
    assert guard.check(goal, **history).reasons == (_accel_reason(v / (4 * h)),)
    # Evenly timed: previous_period equal to period gives the verdict without it.
    goal, previous, before = goals(MAX_ACCEL * 2)
    history = {"previous": previous, "before_previous": before, "period": h2}
    assert (
        guard.check(goal, **history, previous_period=h2).reasons
        == guard.check(goal, **history).reasons
    )
    # A previous_period that is not a positive finite time is bad input.
    for bad in (0.0, -h, math.nan, math.inf):
        with pytest.raises(InputError, match="previous_period"):
            guard.check(goal, **history, previous_period=bad)


def test_speed_limit_on_the_bus(bus: EmulatedBus, servos: ServoBus, robot: spm.SPMRobot) -> None:
    with ServoSync(servos, config_for(bus.port, RATE_LIMITS), robot=robot) as sync:
        sync.start()
        # Ramp up (all inputs together: the platform only turns) to just below max speed.
        top = MAX_SPEED * PERIOD * (1 - 1e-3)
        increment = 0.9 * MAX_ACCEL * PERIOD**2
        step = 0.0
        while step < top:
            step = min(step + increment, top)
            assert sync.step(sync.goal + step).sent  # type: ignore[operator]
        since = last_seq(bus)
        here = sync.goal.copy()  # type: ignore[union-attr]
        outside = here + MAX_SPEED * PERIOD * (1 + TOL["rate"])
        result = sync.step(outside)
        assert result.refused and not result.sent
        assert result.verdict is not None
        assert result.verdict.reasons == (_speed_reason(float(np.max(outside - here)) / PERIOD),)
        assert_nothing_sent(bus, since)
        inside = here + MAX_SPEED * PERIOD * (1 - TOL["rate"])
        assert sync.step(inside).sent
        assert_sent(bus, since, inside)
        assert goal_registers(bus) == pulses(inside)


def test_acceleration_limit_on_the_bus(
    bus: EmulatedBus, servos: ServoBus, robot: spm.SPMRobot
) -> None:
    with ServoSync(servos, config_for(bus.port, RATE_LIMITS), robot=robot) as sync:
        sync.start()
        assert sync.step(sync.goal).sent  # at rest: previous = before previous
        since = last_seq(bus)
        here = sync.goal.copy()  # type: ignore[union-attr]
        step = MAX_ACCEL * PERIOD**2
        outside = here + np.array([0.0, 0.0, step * (1 + TOL["rate"])])
        result = sync.step(outside)
        assert result.refused and result.verdict is not None
        assert result.verdict.reasons == (_accel_reason(float(outside[2] - here[2]) / PERIOD**2),)
        assert_nothing_sent(bus, since)
        inside = here + np.array([0.0, 0.0, step * (1 - TOL["rate"])])
        assert sync.step(inside).sent
        assert_sent(bus, since, inside)


# ------------------------------------------------------------ path resolution
#: A joint-space segment whose middle has a lower dexterity than both ends (found
#: by a search over segments of 0.15 rad): checked at the midpoint only when the
#: segment is longer than path_resolution.
DIP_START_PULSES = (2048, 2048 - 299, 2048 + 47)  # about [0, -26.3, 4.1] deg
DIP_STEP = np.radians([-8.59, -5.56, 4.89])


@pytest.fixture(scope="module")
def dip() -> dict[str, object]:
    start = (np.array(DIP_START_PULSES) - 2048) * POSITION_UNIT
    end = start + DIP_STEP
    middle = start + 0.5 * (end - start)  # the guard's interpolated sample
    dex = {k: margin_and_dexterity(t, fk_along(t))[1] for k, t in (("a", start), ("b", end))}
    dex["mid"] = margin_and_dexterity(middle, fk_along(middle))[1]
    low_end = min(dex["a"], dex["b"])
    assert low_end - dex["mid"] > 5e-4  # a real dip
    return {
        "start": start,
        "end": end,
        "limit": 0.5 * (low_end + dex["mid"]),
        "length": float(np.max(np.abs(end - start))),
    }


def _dip_limits(dip: dict[str, object], resolution: float) -> SafetyLimits:
    return SafetyLimits(
        min_dexterity=float(dip["limit"]),  # type: ignore[arg-type]
        path_resolution=resolution,
        max_speed=MAX_SPEED,
        max_acceleration=MAX_ACCEL,
    )


def test_path_resolution_through_the_guard(dip: dict[str, object], robot: spm.SPMRobot) -> None:
    length = float(dip["length"])  # type: ignore[arg-type]
    path = np.array([dip["start"], dip["end"]])
    fine = SafetyGuard(robot, _dip_limits(dip, length * (1 - TOL["rate"])))
    verdict = fine.check_path(path)
    assert not verdict.safe and verdict.index == 1 and verdict.checked == 3
    assert re.fullmatch(
        r"sample 1 \(between samples\): dexterity 0\.\d{4} < 0\.\d+", verdict.reasons[0]
    )
    coarse = SafetyGuard(robot, _dip_limits(dip, length * (1 + TOL["rate"])))
    verdict = coarse.check_path(path)
    assert verdict.safe and verdict.checked == 2


def test_path_resolution_on_the_bus(
    dip: dict[str, object], bus: EmulatedBus, robot: spm.SPMRobot
) -> None:
    length = float(dip["length"])  # type: ignore[arg-type]
    for i, p in zip(IDS, DIP_START_PULSES, strict=True):
        bus.set_item(i, "Present Position", p)
    # One step of 0.15 rad in one period of 0.1 s: 1.5 rad/s, 15 rad/s^2 from rest.
    for resolution, accepted in (
        (length * (1 - TOL["rate"]), False),
        (length * (1 + TOL["rate"]), True),
    ):
        config = config_for(bus.port, _dip_limits(dip, resolution), rate_hz=10.0)
        with (
            ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
            ServoSync(servos, config, robot=robot) as sync,
        ):
            sync.start()
            np.testing.assert_array_equal(sync.goal, dip["start"])
            since = last_seq(bus)
            if accepted:
                sync.run(np.array([dip["end"]]), settle_timeout=0.0)
                assert_sent(bus, since, dip["end"])  # type: ignore[arg-type]
            else:
                with pytest.raises(UnsafeCommandError, match="between samples"):
                    sync.run(np.array([dip["end"]]))
                assert_nothing_sent(bus, since)
                assert goal_registers(bus) == list(DIP_START_PULSES)
