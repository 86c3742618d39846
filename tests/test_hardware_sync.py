"""The safety guard and the model-servo sync loop on the emulated bus: unsafe goals are
refused and, as the emulator's own log proves, never reach the servos; a full move
with the model following; faults hold, recover or turn torque off."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

pytest.importorskip("dynamixel_sdk")

from _hardware_data import BAUD, IDS, LATENCY_MS, TOL, fast_config

import spm_pin as spm
from spm_pin.errors import HardwareError, InputError, ServoAlertError, UnsafeCommandError
from spm_pin.hardware import (
    EmulatedBus,
    HardwareConfig,
    HardwareErrorFlag,
    JointConfig,
    JointMap,
    SafetyGuard,
    SafetyLimits,
    ServoBus,
    ServoSync,
)
from spm_pin.hardware.control_table import POSITION_UNIT

pytestmark = pytest.mark.hardware
pytest_plugins = ["_hardware"]

DEMO = np.radians([60.0, 90.0, 120.0])  # the study's demonstration input
#: Gap D_12 = 120 + 0 - 80 = 40 deg: proximal links 1 and 2 overlap (below about 49 deg).
COLLIDING = np.radians([0.0, 80.0, 0.0])
#: The study's input with a link collision: no home-mode assembly for the prototype.
UNREACHABLE = np.radians([60.0, 90.0, 220.0])
#: Smallest gap between adjacent proximal links that never collides [deg] (the
#: prototype's proximal links touch at a gap of about 49 deg).
SAFE_GAP_DEG = 50.0


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


def gaps_deg(theta: np.ndarray) -> np.ndarray:
    t = np.degrees(theta)
    return np.array([120 + t[0] - t[1], 120 + t[1] - t[2], 120 + t[2] - t[0]])


def independently_safe(theta: np.ndarray, limits: SafetyLimits) -> bool:
    """Safety of a goal from the kinematics alone, without the guard's code."""
    design = spm.SPMDesign.prototype()
    fk = spm.forward_kinematics(theta, design)
    if not bool(fk.reachable):
        return False
    jac = spm.jacobian(theta, design, R=fk.R)
    margin_ok = float(jac.singularity_margin) >= limits.min_singularity_margin
    return margin_ok and bool(np.all(gaps_deg(theta) >= SAFE_GAP_DEG - 1.0))


def goals_on_bus(bus: EmulatedBus, joints: JointMap, since: int = 0) -> list[np.ndarray]:
    """Every goal that reached the servos, as joint angles (complete triples only)."""
    by_time: dict[float, dict[int, int]] = {}
    for write in bus.goal_writes(since):
        by_time.setdefault(write.time, {})[write.servo_id] = write.pulses
    return [
        joints.to_theta([goals[i] for i in IDS]) for goals in by_time.values() if len(goals) == 3
    ]


def pulses_of(theta_deg: list[float], zero: int = 2048) -> dict[int, int]:
    return {
        i: round(zero + math.radians(t) / POSITION_UNIT)
        for i, t in zip(IDS, theta_deg, strict=True)
    }


# ------------------------------------------------------------------ the guard
def test_guard_accepts_safe_goals_with_the_models_numbers(robot: spm.SPMRobot) -> None:
    guard = SafetyGuard(robot)
    for theta in (np.zeros(3), DEMO):
        verdict = guard.check(theta)
        assert verdict.safe and verdict.reasons == () and verdict.collisions == ()
        jac = spm.jacobian(theta)
        assert verdict.singularity_margin == pytest.approx(float(jac.singularity_margin))
        assert verdict.dexterity == pytest.approx(float(jac.dexterity))
    guard.check(DEMO)
    assert guard.stats["cache_hits"] >= 1


def test_guard_refuses_a_colliding_goal(robot: spm.SPMRobot) -> None:
    pairs = robot.collisions(COLLIDING, margin=0.0)  # the model itself says so
    assert ("proximal_1", "proximal_2") in [tuple(sorted(p)) for p in pairs]
    assert spm.forward_kinematics(COLLIDING).reachable  # reachable and not singular:
    assert float(spm.jacobian(COLLIDING).singularity_margin) > 0.1  # only the collision
    verdict = SafetyGuard(robot).check(COLLIDING)
    assert not verdict.safe and len(verdict.reasons) == 1
    assert "links collide" in verdict.reasons[0] and "proximal_1" in verdict.reasons[0]
    with pytest.raises(UnsafeCommandError, match="nothing was sent") as info:
        verdict.require()
    np.testing.assert_array_equal(info.value.goal, COLLIDING)


def test_guard_refuses_unreachable_singular_and_out_of_limits(robot: spm.SPMRobot) -> None:
    verdict = SafetyGuard(robot).check(UNREACHABLE)
    assert verdict.reasons == ("no home-mode assembly exists there (unreachable)",)
    near = np.radians([0.0, 60.0, 0.0])  # margin 0.579, gaps 60, 180, 120 deg
    strict = SafetyGuard(robot, SafetyLimits(min_singularity_margin=0.6))
    assert "too close to a singularity: margin 0.5790 < 0.6" in strict.check(near).reasons[0]
    assert SafetyGuard(robot).check(near).safe
    limited = SafetyGuard(robot, SafetyLimits(theta_max=(1.0, 1.0, 1.0)))
    assert "outside the joint limits" in limited.check(np.array([1.1, 1.1, 1.1])).reasons[0]
    assert "not finite" in SafetyGuard(robot).check([0.0, math.nan, 0.0]).reasons[0]
    with pytest.raises(InputError, match=r"shape \(3,\)"):
        SafetyGuard(robot).check([0.0, 0.0])


def test_guard_checks_speed_acceleration_and_whole_paths(robot: spm.SPMRobot) -> None:
    guard = SafetyGuard(robot, SafetyLimits(max_speed=1.0, max_acceleration=60.0))
    step = np.array([0.02, 0.0, 0.0])
    assert guard.check(step, previous=np.zeros(3), period=0.01).reasons == (
        "joint speed 114.6 deg/s > 57.3 deg/s",
    )
    ok = guard.check(step / 4, previous=np.zeros(3), before_previous=np.zeros(3), period=0.01)
    assert ok.safe
    jerk = guard.check(step * 0.4, previous=np.zeros(3), before_previous=np.zeros(3), period=0.01)
    assert jerk.reasons == ("joint acceleration 4583.7 deg/s^2 > 3437.7 deg/s^2",)
    # A path is checked whole; its first unsafe sample is named.
    path = np.linspace(np.zeros(3), COLLIDING, 9)[1:]
    verdict = guard.check_path(path)
    first_colliding = next(k for k, t in enumerate(path) if gaps_deg(t)[0] < SAFE_GAP_DEG - 1.0)
    assert not verdict.safe and verdict.index is not None
    assert abs(verdict.index - first_colliding) <= 1
    assert verdict.checked > len(path)  # far-apart samples are subdivided
    with pytest.raises(UnsafeCommandError, match="path refused at sample"):
        verdict.require()
    assert guard.check_path(path[:2], period=1.0, start=np.zeros(3)).safe


# ------------------------------------------------------------------ the loop
def test_start_holds_where_the_servos_are(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        state = sync.start()
        np.testing.assert_allclose(state.theta, 0.0, atol=TOL["pulse"])
        assert sync.torque and [bus.item(i, "Torque Enable") for i in IDS] == [1, 1, 1]
        assert [w.pulses for w in bus.goal_writes()] == [2048, 2048, 2048]
        time.sleep(0.1)
        assert [bus.item(i, "Present Position") for i in IDS] == [2048, 2048, 2048]
    assert [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0]  # off on exit


def test_full_move_with_the_model_following(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    viewer = None
    try:
        from spm_pin.viz import Visualizer

        viewer = Visualizer(robot, check_collisions=False)
    except ImportError:  # pragma: no cover - the viz extra is part of the test extra
        pass
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot, viewer=viewer) as sync,
    ):
        sync.start()
        since = bus.log()[-1].seq
        result = sync.move_to(DEMO)
        assert result.reached
        np.testing.assert_allclose(result.final.theta, DEMO, atol=TOL["reached"])
        # The goals on the bus are exactly the planned path, all safe.
        sent = goals_on_bus(bus, sync.joints, since)
        assert len(sent) == len(result.path)
        np.testing.assert_allclose(sent, result.path, atol=TOL["pulse"])
        assert all(independently_safe(t, config.safety) for t in sent)
        # The model followed: every state's platform is the FK of what was read.
        assert len(result.states) >= len(result.path)
        for state in result.states[:: max(1, len(result.states) // 10)]:
            fk = spm.forward_kinematics(state.theta)
            np.testing.assert_allclose(state.R, fk.R, atol=TOL["model"])
            assert state.q is not None
            np.testing.assert_allclose(state.q[robot.actuated_q_idx], state.theta)
            assert robot.closure_residual(state.q) < 1e-10
        moving = [s.theta for s in result.states]
        assert np.all(np.diff(np.array(moving)[:, 2]) >= -TOL["pulse"])  # monotone
        if viewer is not None:
            np.testing.assert_allclose(viewer.q, result.final.q)


def test_unsafe_goals_never_reach_the_bus(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        sync.move_to(np.radians([0.0, 30.0, 0.0]))  # D_12 = 90 deg
        before = len(bus.goal_writes())
        refused = sync.step(COLLIDING)
        assert refused.refused and not refused.sent
        assert any("links collide" in r for r in refused.verdict.reasons)  # type: ignore[union-attr]
        assert sync.step(UNREACHABLE).refused
        jump = sync.goal + np.radians([0.0, 5.0, 0.0])  # type: ignore[operator]
        assert "joint speed" in sync.step(jump).verdict.reasons[0]  # type: ignore[union-attr]
        with pytest.raises(UnsafeCommandError, match="links collide"):
            sync.move_to(COLLIDING)  # checked whole: nothing sent
        with pytest.raises(UnsafeCommandError, match="path refused"):
            sync.move_to(UNREACHABLE)
        assert len(bus.goal_writes()) == before
        assert sync.step(sync.goal).sent  # the loop still works
    # The emulator's log: every goal that ever reached a servo was safe.
    joints = JointMap(config.joints)
    sent = goals_on_bus(bus, joints)
    assert len(sent) >= 2
    assert all(independently_safe(t, config.safety) for t in sent)
    assert not any(np.allclose(t, COLLIDING, atol=0.01) for t in sent)


def test_start_refuses_a_robot_standing_in_collision(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    for i, pulses in pulses_of([0.0, 80.0, 0.0]).items():
        bus.set_item(i, "Present Position", pulses)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        with pytest.raises(UnsafeCommandError, match="links collide"):
            sync.start()
        assert bus.goal_writes() == []
        state = sync.start(torque=False)  # following by hand is allowed
        np.testing.assert_allclose(state.theta, COLLIDING, atol=TOL["pulse"])
    assert [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0]


def test_follow_mirrors_a_robot_moved_by_hand(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot, update_model=False) as sync,
    ):
        sync.start(torque=False)
        for i, pulses in pulses_of([20.0, -10.0, 5.0]).items():
            bus.set_item(i, "Present Position", pulses)
        states = sync.follow(0.15)
        assert 5 <= len(states) <= 30
        np.testing.assert_allclose(states[-1].theta, np.radians([20, -10, 5]), atol=TOL["pulse"])
        fk = spm.forward_kinematics(states[-1].theta)
        np.testing.assert_allclose(states[-1].R, fk.R, atol=TOL["model"])
        assert states[-1].q is None
        with pytest.raises(HardwareError, match="torque is off"):
            sync.step(np.zeros(3))
    assert bus.goal_writes() == []


def test_faults_hold_the_goal_then_turn_torque_off(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port).replace(max_failures=3)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS, retries=1) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        goal = sync.goal.copy()  # type: ignore[union-attr]
        before = len(bus.goal_writes())
        bus.silence()
        for failures in (1, 2):
            result = sync.step(goal)
            assert not result.sent and "read failed" in str(result.fault)
            assert sync.failures == failures
        assert len(bus.goal_writes()) == before  # held: nothing sent
        with pytest.raises(HardwareError, match="torque turned off: 3 consecutive failed"):
            sync.step(goal)
        bus.clear_faults()
        assert [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0]
        assert any("torque off" in event for event in sync.events)


def test_a_goal_the_servo_does_not_hold_is_a_fault(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        bus.set_item(2, "Goal Position", 2100)  # as if a sync write had been lost
        result = sync.step(sync.goal)
        assert not result.sent
        assert "servo 2 holds 2100, expected 2048" in str(result.fault)
        assert sync.step(sync.goal).sent  # nothing was wrong with the next cycle


def test_overload_reboot_restores_turns_and_profile(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    joints = tuple(JointConfig(f"u_{i}", i, zero_offset=0) for i in IDS)
    config = fast_config(bus.port).replace(joints=joints)
    for i in IDS:
        bus.set_item(i, "Present Position", 30)  # theta = 2.6 deg
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        target = np.radians([-5.0, -5.0, -5.0])  # below the servos' zero: -57 pulses
        assert sync.move_to(target).reached
        assert bus.item(1, "Present Position") == -57
        assert bus.alert(1, int(HardwareErrorFlag.OVERLOAD)) == 32
        result = sync.step(sync.goal)
        assert not result.sent and "rebooted after a hardware error" in str(result.fault)
        assert sync.reboots == {1: 1, 2: 0, 3: 0}
        state = bus.state(1)
        assert state["Present Position"] == 4096 - 57  # the turn count restarted
        assert state["Torque Enable"] == 1 and state["Hardware Error Status"] == 0
        assert state["Profile Velocity"] == config.servo.raw()["Profile Velocity"]
        np.testing.assert_allclose(sync.goal, target, atol=TOL["pulse"])
        np.testing.assert_allclose(sync.read().theta, target, atol=TOL["pulse"])
        assert sync.step(sync.goal).sent
        assert sync.move_to(np.zeros(3)).reached  # no turn lost on the way back
        assert bus.item(1, "Present Position") == 4096
        # The policy allows one reboot per servo: the next overload stops everything.
        bus.alert(1, int(HardwareErrorFlag.OVERLOAD))
        with pytest.raises(ServoAlertError, match="servo 1: overload") as info:
            sync.step(sync.goal)
        assert info.value.status == {1: 32}
    assert [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0]


def test_start_clears_a_latched_overload(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    bus.set_item(2, "Torque Enable", 1)
    bus.alert(2, int(HardwareErrorFlag.OVERLOAD))  # left over from an earlier session
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        assert sync.reboots == {1: 0, 2: 1, 3: 0}
        assert "rebooted at start" in sync.events[0]
        assert [bus.item(i, "Torque Enable") for i in IDS] == [1, 1, 1]
    bus.alert(3, int(HardwareErrorFlag.OVERHEATING))
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
        pytest.raises(ServoAlertError, match="servo 3: overheating"),
    ):
        sync.start()


def test_overheating_is_never_rebooted(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    config = fast_config(bus.port)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        bus.alert(3, int(HardwareErrorFlag.OVERHEATING))
        with pytest.raises(ServoAlertError, match="servo 3: overheating"):
            sync.step(sync.goal)
        assert sync.reboots == {1: 0, 2: 0, 3: 0}
        assert not sync.torque
    assert [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0]


def test_loop_arguments_are_checked(bus: EmulatedBus, robot: spm.SPMRobot) -> None:
    with (
        ServoBus(bus.port, (1, 2, 4), baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        pytest.raises(InputError, match=r"use \[1, 2, 3\]"),
    ):
        ServoSync(servos, HardwareConfig(), robot=robot)
    with ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos:
        sync = ServoSync(servos, fast_config(bus.port), robot=robot)
        with pytest.raises(HardwareError, match="call start"):
            sync.step(np.zeros(3))
        sync.start()
        with pytest.raises(InputError, match="3 joint angles"):
            sync.step([0.0, 0.0])
        with pytest.raises(InputError, match="duration"):
            sync.follow(-1.0)
        sync.release()
