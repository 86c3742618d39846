"""Servo configuration files, the pulse <-> joint angle map with its turn unwrapping,
and the trajectory planner."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from spm_pin.errors import FileFormatError, InputError
from spm_pin.hardware import (
    HardwareConfig,
    HardwareErrorFlag,
    JointConfig,
    JointMap,
    RebootPolicy,
    SafetyLimits,
    ServoSettings,
    plan_linear,
)

pytestmark = pytest.mark.hardware

TOL = {
    "angle": 1e-10,  # [rad] after a round trip through a file (degrees to 1e-9)
    "pulse": 1e-9,  # [pulses]
}


def custom_config() -> HardwareConfig:
    joints = (
        JointConfig("u_1", 11, direction=-1, gear_ratio=1.0, zero_offset=1000),
        JointConfig("u_2", 12, direction=1, gear_ratio=1.0, zero_offset=3000),
        JointConfig("u_3", 13, direction=-1, gear_ratio=1.0, zero_offset=-200),
    )
    return HardwareConfig(
        port="/dev/ttyUSB1",
        baudrate=2_000_000,
        latency_timer_ms=1.0,
        retries=1,
        fast_sync_read=False,
        rate_hz=200.0,
        max_failures=5,
        joints=joints,
        servo=ServoSettings(profile_velocity=3.0, profile_acceleration=30.0, velocity_limit=4.0),
        safety=SafetyLimits(
            min_singularity_margin=0.2,
            collision_margin=0.004,
            max_speed=2.0,
            max_acceleration=8.0,
            theta_min=(-1.0, -2.0, -3.0),
            theta_max=(1.0, 2.0, 3.0),
        ),
        reboot=RebootPolicy(max_reboots=2, reboot_on=HardwareErrorFlag.OVERLOAD),
    )


def assert_same(a: HardwareConfig, b: HardwareConfig) -> None:
    """Equal up to the rounding of a degree round trip."""
    da, db = a.to_dict(), b.to_dict()
    assert da.keys() == db.keys()
    for key in da:
        assert _close(da[key], db[key]), key


def _close(x: object, y: object) -> bool:
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(_close(x[k], y[k]) for k in x)
    if isinstance(x, float) and isinstance(y, float):
        return math.isclose(x, y, rel_tol=1e-12, abs_tol=TOL["angle"])
    if isinstance(x, list) and isinstance(y, list):
        return len(x) == len(y) and all(_close(a, b) for a, b in zip(x, y, strict=True))
    return x == y


@pytest.mark.parametrize("make", [HardwareConfig, custom_config])
def test_toml_round_trip(tmp_path: Path, make: object) -> None:
    config = make()  # type: ignore[operator]
    path = config.save(tmp_path / "servos.toml")
    back = HardwareConfig.load(path)
    assert_same(config, back)
    assert back.joints == config.joints and back.ids == config.ids
    assert back.reboot == config.reboot
    assert back.safety.theta_min == pytest.approx(config.safety.theta_min, abs=TOL["angle"])
    text = path.read_text()
    assert text.startswith("# spm-pin servo configuration")
    assert "joints" in text and "zero_offset" in text


BAD_FILES = {
    "not toml": ("port = ", "not valid TOML"),
    "unknown top key": ("speed = 3\n", "unknown key(s) ['speed']"),
    "port not a string": ("port = 3\n", "port must be a string"),
    "bad fast flag": ('fast_sync_read = "maybe"\n', "fast_sync_read must be"),
    "unknown servo key": ("[servo]\nprofile = 3\n", "[servo] has unknown key(s) ['profile']"),
    "unknown error name": (
        '[servo]\nshutdown = ["overload", "gremlins"]\n',
        "unknown hardware error 'gremlins'",
    ),
    "three angles": ("[safety]\ntheta_min_deg = [1, 2]\n", "theta_min_deg must be a list of 3"),
    "joint order": (
        '[[joints]]\njoint = "u_2"\nservo_id = 1\n[[joints]]\njoint = "u_1"\nservo_id = 2\n'
        '[[joints]]\njoint = "u_3"\nservo_id = 3\n',
        "joints must be u_1, u_2, u_3 in order",
    ),
    "direction": (
        '[[joints]]\njoint = "u_1"\nservo_id = 1\ndirection = 2\n',
        "direction must be 1 or -1",
    ),
    "servo slower than the guard": (
        "[safety]\nmax_speed_deg_s = 200\n",
        "could not track the checked path",
    ),
    "reboot cures no overheating": (
        '[reboot]\nreboot_on = ["overheating"]\n',
        "must not include overheating",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_files_name_the_problem(tmp_path: Path, case: str) -> None:
    text, message = BAD_FILES[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=re.escape(message)) as info:
        HardwareConfig.load(path)
    assert info.value.path == str(path)


def test_missing_file_and_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(FileFormatError, match="cannot read servo configuration"):
        HardwareConfig.load(tmp_path / "none.toml")
    with pytest.raises(InputError, match="own servo id"):
        HardwareConfig(joints=(JointConfig("u_1", 1), JointConfig("u_2", 1), JointConfig("u_3", 3)))
    with pytest.raises(InputError, match="rate_hz"):
        HardwareConfig(rate_hz=0.0)
    with pytest.raises(InputError, match="gear_ratio"):
        JointConfig("u_1", 1, gear_ratio=0.0)
    with pytest.raises(InputError, match="collision_margin"):
        SafetyLimits(collision_margin=-0.001)
    with pytest.raises(InputError, match="below theta_max"):
        SafetyLimits(theta_min=(0.0, 0.0, 0.0), theta_max=(1.0, 0.0, 1.0))


# ----------------------------------------------------------------- joint map
def test_pulses_and_angles_round_trip() -> None:
    joints = (
        JointConfig("u_1", 1, direction=-1, zero_offset=1000),
        JointConfig("u_2", 2, gear_ratio=2.0, zero_offset=0),
        JointConfig("u_3", 3, zero_offset=2048),
    )
    joint_map = JointMap(joints)
    theta = np.radians([30.0, -45.0, 720.0])
    pulses = joint_map.to_pulses(theta)
    assert pulses == {1: 1000 - 341, 2: -1024, 3: 2048 + 2 * 4096}  # 30 deg = 341.3 pulses
    back = joint_map.to_theta([pulses[1], pulses[2], pulses[3]])
    np.testing.assert_allclose(back, theta, atol=math.radians(360 / 4096) / 2)
    rates = joint_map.to_theta_rate([10, 10, 10])
    np.testing.assert_allclose(rates, np.array([-1.0, 0.5, 1.0]) * 10 * 0.229 * 2 * math.pi / 60)
    with pytest.raises(InputError, match="beyond the servo's"):
        joint_map.to_pulses([0.0, 0.0, 2 * math.pi * 300])
    with pytest.raises(InputError, match="3 finite angles"):
        joint_map.to_pulses([0.0, math.nan, 0.0])


def test_unwrap_uses_the_gaps_between_proximal_links() -> None:
    """After power-up each servo reads within one turn; the gaps D_12, D_23 in (0, 360)
    deg decide the turns."""
    joint_map = JointMap(HardwareConfig().joints)
    true_theta = np.radians([179.0, 240.0, 200.0])  # gaps 59, 160, 141 deg
    pulses = [round(2048 + t / (2 * math.pi) * 4096) % 4096 for t in true_theta]
    theta = joint_map.unwrap(pulses)
    np.testing.assert_allclose(theta, true_theta, atol=math.radians(0.1))
    gaps = np.degrees(
        [2 * math.pi / 3 + theta[0] - theta[1], 2 * math.pi / 3 + theta[1] - theta[2]]
    )
    assert np.all((gaps > 0) & (gaps < 360))
    # A servo rebooted: its turn restarts; unwrap_one puts it back near the last angle.
    reboot_reading = pulses[1]
    assert joint_map.unwrap_one(1, reboot_reading, theta[1]) == pytest.approx(theta[1])
    joint_map.turns[1] += 3  # as if the multi-turn count had been lost
    assert joint_map.unwrap_one(1, reboot_reading, theta[1]) == pytest.approx(theta[1])
    # With a reference, the turn nearest to it.
    near = joint_map.unwrap(pulses, reference=true_theta + 2 * math.pi)
    np.testing.assert_allclose(near, true_theta + 2 * math.pi, atol=math.radians(0.1))


# ------------------------------------------------------------------- planner
@pytest.mark.parametrize(
    ("goal_deg", "speed", "acceleration"),
    [([60.0, 90.0, 120.0], 1.5, 6.0), ([1.0, -2.0, 0.5], 1.5, 6.0), ([0.0, 0.0, 0.0], 1.0, 1.0)],
)
def test_plan_linear_respects_the_limits(
    goal_deg: list[float], speed: float, acceleration: float
) -> None:
    period = 0.01
    goal = np.radians(goal_deg)
    path = plan_linear(
        np.zeros(3), goal, max_speed=speed, max_acceleration=acceleration, period=period
    )
    np.testing.assert_array_equal(path[-1], goal)
    padded = np.vstack([np.zeros((2, 3)), path, path[-1:]])  # from rest, to rest
    v = np.diff(padded, axis=0) / period
    a = np.diff(v, axis=0) / period
    assert np.max(np.abs(v)) <= speed * (1 + 1e-9)
    assert np.max(np.abs(a)) <= acceleration * (1 + 1e-9)
    # A straight line: every sample is a multiple of the goal.
    distance = np.max(np.abs(goal))
    if distance:
        fraction = path[:, np.argmax(np.abs(goal))] / goal[np.argmax(np.abs(goal))]
        np.testing.assert_allclose(path, fraction[:, None] * goal, atol=1e-15)
        assert np.all(np.diff(fraction) >= 0)
    with pytest.raises(InputError, match="max_speed"):
        plan_linear(np.zeros(3), goal, max_speed=0.0, max_acceleration=1.0, period=period)


def test_core_never_imports_the_hardware_layer_or_the_sdk() -> None:
    code = (
        "import sys, spm_pin, spm_pin.cli\n"
        "assert 'spm_pin.hardware' not in sys.modules\n"
        "assert 'dynamixel_sdk' not in sys.modules\n"
        "spm_pin.cli.build_parser()\n"
        "import spm_pin.hardware\n"
        "assert 'dynamixel_sdk' not in sys.modules  # only when a port opens\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 0, result.stderr
