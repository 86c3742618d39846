"""Orientation control of the servos (spm_pin.hardware.orientation) on the emulated bus.

Every goal that reached a servo is read back from the emulator's own log and checked
again by a guard on a robot model of its own; orientations are checked with forward
kinematics of the servos' readings.
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from _hardware_data import BAUD, IDS, LATENCY_MS, fast_config

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.errors import UnsafeCommandError
from spm_pin.hardware import EmulatedBus, HardwareConfig, ServoBus
from spm_pin.hardware.guard import SafetyGuard
from spm_pin.hardware.joints import JointMap
from spm_pin.hardware.orientation import OrientationStream, move_planned, planned_goals
from spm_pin.hardware.sync import ServoSync
from spm_pin.rotations import matrix_from_rpy

pytest_plugins = ["_hardware"]

#: Two safe inputs whose straight line passes a collision (proximal_1-distal_2) [deg].
NOTCH_START_DEG = [71.0, 8.0, 67.0]
NOTCH_GOAL_DEG = [33.0, -37.0, 8.0]
#: One encoder pulse [rad].
PULSE = 2.0 * math.pi / 4096.0


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


@pytest.fixture(scope="module")
def guard() -> SafetyGuard:
    """The independent check of what reached the servos: a model of its own."""
    return SafetyGuard(spm.build_robot())


def _written(bus: EmulatedBus, config: HardwareConfig, since: int = 0) -> np.ndarray:
    """Every goal the servos received since a log position, as theta [rad], (n, 3)."""
    joints = JointMap(config.joints, coaxial=True)
    latest = dict.fromkeys(IDS, 2048)
    rows = []
    for write in bus.goal_writes(since):
        latest[write.servo_id] = write.pulses
        if write.servo_id == IDS[-1]:
            rows.append(joints.to_theta([latest[i] for i in IDS]))
    return np.array(rows).reshape(-1, 3)


def test_planned_goals_keep_the_limits_and_end_on_the_goal() -> None:
    path = np.radians([[0.0, 0.0, 0.0], [30.0, 10.0, 0.0], [40.0, 40.0, 20.0]])
    v, a, T = math.radians(90.0), math.radians(360.0), 0.01
    goals = planned_goals(path, max_speed=v, max_acceleration=a, period=T)
    np.testing.assert_array_equal(goals[-1], path[-1])
    padded = np.vstack([path[:1], path[:1], goals, goals[-1:]])  # from and to rest
    steps = np.diff(padded, axis=0)
    assert np.abs(steps).max() / T <= v * (1 + 1e-9)
    assert np.abs(np.diff(steps, axis=0)).max() / T**2 <= a * (1 + 1e-9)
    # On the polyline: every goal lies on one of its two straight pieces.
    for goal in goals:
        gaps = []
        for p, q in itertools.pairwise(path):
            t = np.clip(np.dot(goal - p, q - p) / np.dot(q - p, q - p), 0.0, 1.0)
            gaps.append(np.linalg.norm(goal - (p + t * (q - p))))
        assert min(gaps) < 1e-12


def test_an_orientation_goal_is_reached_along_a_planned_path(
    bus: EmulatedBus, robot: spm.SPMRobot, guard: SafetyGuard
) -> None:
    config = fast_config(bus.port)
    R = matrix_from_rpy(np.radians([0.0, 20.0, 45.0]))
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        _, result = move_planned(sync, R)
    assert result.reached
    reached = spm.forward_kinematics(result.final.theta).R
    angle = np.arccos(np.clip((np.trace(reached.T @ R) - 1.0) / 2.0, -1.0, 1.0))
    assert angle < 3 * PULSE  # within the encoders' resolution
    written = _written(bus, config)
    assert all(guard.check(goal).safe for goal in written)


def test_a_goal_across_the_notch_is_reached_by_a_detour(
    bus: EmulatedBus, robot: spm.SPMRobot, guard: SafetyGuard
) -> None:
    config = fast_config(bus.port)
    start, goal = np.radians(NOTCH_START_DEG), np.radians(NOTCH_GOAL_DEG)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        assert move_planned(sync, start)[1].reached
        before = len(bus.goal_writes())
        with pytest.raises(UnsafeCommandError):  # the straight line is refused
            sync.move_to(goal)
        assert len(bus.goal_writes()) == before
        path, result = move_planned(sync, goal)
    assert path.theta.shape[0] > 2 and result.reached
    np.testing.assert_allclose(result.final.theta, goal, atol=2 * PULSE)
    assert all(guard.check(theta).safe for theta in _written(bus, config, before))


def test_a_stream_tracks_then_slides_or_holds_and_never_sends_an_unsafe_goal(
    bus: EmulatedBus, robot: spm.SPMRobot, guard: SafetyGuard
) -> None:
    config = fast_config(bus.port)
    limits = config.safety
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoSync(servos, config, robot=robot) as sync,
    ):
        sync.start()
        stream = OrientationStream(sync)
        # A head turning: yaw 0 -> 30 deg and a 10-deg nod, 1 s at the loop rate.
        n = int(1.0 / config.period)
        sweep = [matrix_from_rpy(np.radians([0.0, 10.0 * k / n, 30.0 * k / n])) for k in range(n)]
        steps = stream.run(sweep + [sweep[-1]] * 60)
        assert {s.action for s in steps} <= {"track", "hold", "slide"}
        assert stream.counts["track"] > n // 2
        reached = spm.forward_kinematics(sync.goal).R
        np.testing.assert_allclose(reached, sweep[-1], atol=1e-6)
        # A target out of reach (pitch 85 deg): never sent; the reason is given.
        far = stream.run([matrix_from_rpy(np.radians([0.0, 85.0, 30.0]))] * 30)
        assert all(s.action in ("slide", "hold") for s in far[-5:])
        assert all(s.reason for s in far[-5:])
    written = _written(bus, config)
    assert all(guard.check(theta).safe for theta in written)
    speeds = np.abs(np.diff(written, axis=0)).max(axis=1) / config.period
    assert speeds.max() <= limits.max_speed * 1.05


def test_a_stream_slides_along_the_boundary_towards_a_target_beyond_it(
    bus: EmulatedBus, robot: spm.SPMRobot, guard: SafetyGuard
) -> None:
    """Streamed towards the notch goal (the straight way collides), the goal slides
    along the boundary of the safe set: it keeps nearing the target after it first
    meets the boundary, round the notch to the target, where mode "stop" stays at the
    boundary; every goal sent is safe and within the speed limit."""
    config = fast_config(bus.port)
    start, goal = np.radians(NOTCH_START_DEG), np.radians(NOTCH_GOAL_DEG)
    target = spm.forward_kinematics(goal).R
    ends = {}
    for mode in ("stop", "slide"):
        with (
            ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
            ServoSync(servos, config, robot=robot) as sync,
        ):
            sync.start()
            assert move_planned(sync, start)[1].reached
            before = len(bus.goal_writes())
            stream = OrientationStream(sync, mode=mode)
            steps = stream.run([target] * int(4.0 / config.period))
            ends[mode] = float(np.linalg.norm(np.asarray(sync.goal) - goal))
            assert not any("guard refused" in (s.reason or "") for s in steps)
            if mode == "slide":
                first = next(k for k, s in enumerate(steps) if s.action == "slide")
                distances = [float(np.linalg.norm(s.goal - goal)) for s in steps]
                assert distances[-1] < distances[first] - math.radians(2.0)  # slid on
                assert stream.counts["slide"] >= 3
        written = _written(bus, config, before)
        assert all(guard.check(theta).safe for theta in written)
        speeds = np.abs(np.diff(written, axis=0)).max(axis=1) / config.period
        assert speeds.max() <= config.safety.max_speed * 1.05
    assert ends["slide"] < ends["stop"] - math.radians(2.0)
    # The notch is small: sliding along its edge leads round it, to the target.
    assert ends["slide"] < math.radians(0.01)


def test_spm_servo_move_rpy(
    bus: EmulatedBus, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = fast_config(bus.port).save(tmp_path / "servos.toml")
    assert main(["servo", "move", "--rpy", "0", "20", "45", "--config", str(config), "--json"]) == 0
    moved = json.loads(capsys.readouterr().out)
    assert moved["reached"] is True and moved["planned"]["length_deg"] > 0
    R = spm.forward_kinematics(np.radians(moved["final"]["theta_deg"])).R
    np.testing.assert_allclose(R, matrix_from_rpy(np.radians([0.0, 20.0, 45.0])), atol=0.01)


def test_spm_servo_stream_file(
    bus: EmulatedBus, tmp_path: Path, capsys: pytest.CaptureFixture[str], guard: SafetyGuard
) -> None:
    config = fast_config(bus.port)
    config_file = config.save(tmp_path / "servos.toml")
    lines = [f"0 {0.2 * k:.3f} {0.5 * k:.3f}" for k in range(60)]
    lines += ["# a target out of reach, then holding", "0 85 30", "0 85 30", "hold"]
    targets = tmp_path / "targets.txt"
    targets.write_text("\n".join(lines) + "\n")
    argv = ["servo", "stream", str(targets), "--config", str(config_file), "--json"]
    assert main(argv) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["targets"] == 63 and sum(record["counts"].values()) == 63
    assert record["counts"]["track"] >= 50 and record["reasons"]
    assert all(guard.check(theta).safe for theta in _written(bus, config))
    bad = tmp_path / "bad.txt"
    bad.write_text("0 10\n")
    assert main(["servo", "stream", str(bad), "--config", str(config_file)]) == 2
    err = capsys.readouterr().err
    assert "line 1: expected 'roll pitch yaw'" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    ("path", "kwargs", "argument"),
    [
        ([[0.0, 0.0, 0.0], [0.1, np.nan, 0.0]], {}, "path"),
        ([[0.0, 0.0]], {}, "path"),
        ([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], {"max_speed": 0.0}, "max_speed"),
        ([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], {"period": -0.01}, "period"),
    ],
)
def test_planned_goals_refuse_bad_input(
    path: object, kwargs: dict[str, float], argument: str
) -> None:
    from spm_pin.errors import InputError

    limits = {"max_speed": 1.0, "max_acceleration": 1.0, "period": 0.01, **kwargs}
    with pytest.raises(InputError, match=argument):
        planned_goals(path, **limits)  # type: ignore[arg-type]
