"""The ServoBus driver on the unmodified dynamixel-sdk against the emulated bus: every
item it uses round-trips, sync read and write (fast and plain), negative positions,
every injected fault ends in a clear SPMError after a bounded number of attempts, each
bounded by the packet timeout (shown on a fake clock, not measured on the wall clock:
speed is the benchmarks' business)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import pytest

pytest.importorskip("dynamixel_sdk")

from _hardware_data import BAUD, IDS, LATENCY_MS, TRIGGER, packet_timeout_s

from spm_pin.errors import (
    CommunicationError,
    HardwareError,
    InputError,
    ServoError,
)
from spm_pin.hardware import EmulatedBus, HardwareErrorFlag, ServoBus, ServoSettings
from spm_pin.hardware.control_table import VELOCITY_UNIT

pytestmark = pytest.mark.hardware
pytest_plugins = ["_hardware"]

#: What one failed transaction costs the fixture's driver (retries=2): 3 attempts.
FAILED_ONCE = {"transactions": 3, "retries": 2, "failures": 1}


def test_identify_and_configure_round_trip(servo_bus: ServoBus, bus: EmulatedBus) -> None:
    infos = servo_bus.identify()
    assert [(i.servo_id, i.model_number, i.firmware) for i in infos.values()] == [
        (1, 1130, 46),
        (2, 1130, 46),
        (3, 1130, 46),
    ]
    assert servo_bus.fast_sync_read is True
    settings = ServoSettings(
        profile_velocity=1.0, profile_acceleration=5.0, velocity_limit=3.0, current_limit=2.0
    )
    bus.set_item(2, "Status Return Level", 1)  # answers reads only: writes get no reply
    held = servo_bus.configure(settings)
    raw = settings.raw()
    assert held == dict.fromkeys(IDS, raw)
    assert raw["Profile Velocity"] == round(1.0 / VELOCITY_UNIT) == 42
    for i in IDS:  # what the servo itself holds
        state = bus.state(i)
        assert state["Operating Mode"] == 4 and state["Return Delay Time"] == 0
        assert state["Profile Velocity"] == 42 and state["Current Limit"] == round(2.0 / 2.69e-3)
        assert state["Torque Enable"] == 0 and state["Status Return Level"] == 2
    # EEPROM is written only where it differs: a second configure writes no EEPROM.
    since = bus.log()[-1].seq
    servo_bus.configure(settings)
    writes = [w for e in bus.log(since) for w in e.writes]
    assert all(address >= 64 for _, address, _ in writes)


@pytest.mark.parametrize(
    ("item", "value"),
    [
        ("Goal Position", -1_048_575),
        ("Goal Position", -131_072),
        ("Goal Position", -1),
        ("Goal Position", 1_048_575),
        ("Profile Velocity", 32767),
        ("Profile Acceleration", 1),
        ("LED", 1),
        ("Homing Offset", -1024),
        ("Shutdown", 36),
        ("Return Delay Time", 0),
        ("Drive Mode", 1),
        ("Velocity Limit", 200),
        ("Current Limit", 1000),
        ("Status Return Level", 1),
        ("Torque Enable", 1),
    ],
)
def test_item_round_trips(servo_bus: ServoBus, bus: EmulatedBus, item: str, value: int) -> None:
    servo_bus.write(2, "Operating Mode", 4)  # extended position: the full goal range
    servo_bus.write(2, item, value)
    assert servo_bus.read(2, item) == value
    assert bus.item(2, item) == value


def test_sync_write_and_read_with_negative_positions(servo_bus: ServoBus, bus: EmulatedBus) -> None:
    servo_bus.identify()
    servo_bus.configure(ServoSettings(profile_velocity=5.0, velocity_limit=5.5))
    goals = {1: -2148, 2: -1, 3: -131073}  # -131073 needs stuffing
    servo_bus.set_torque(True)
    sent = servo_bus.sync_write_goals(goals)
    assert sent == {1: goals[1], 2: -1, 3: -131072}  # one pulse nearer zero
    assert servo_bus.stuffing_workarounds == 1
    for fast in (True, False):
        servo_bus.fast_sync_read = fast
        readings = servo_bus.sync_read()
        assert readings.goal == (goals[1], -1, -131072) and readings.fast is fast
    assert [g.pulses for g in bus.goal_writes()] == [goals[1], -1, -131072]
    for _ in range(200):  # the move takes well under a second; a hang ends at 10 s
        if servo_bus.sync_read().position[0] == goals[1]:
            break
        time.sleep(0.05)
    readings = servo_bus.sync_read()
    assert readings.position[:2] == (goals[1], -1)
    assert readings.position[:2] == tuple(bus.item(i, "Present Position") for i in IDS[:2])
    assert readings.position[2] < 0 and readings.velocity[2] < 0  # on its way


@pytest.mark.parametrize("fast", [True, False])
def test_reads_a_reply_the_sdk_destuffs_wrongly(
    servo_bus: ServoBus, bus: EmulatedBus, fast: bool
) -> None:
    bus.freeze(3)
    for name, value in TRIGGER.items():
        bus.set_item(3, name, value)
    servo_bus.fast_sync_read = fast
    readings = servo_bus.sync_read()
    assert readings.goal[2] == TRIGGER["Goal Position"]
    assert readings.current[2] == TRIGGER["Present Current"]
    assert readings.velocity[2] == TRIGGER["Present Velocity"]
    assert readings.position[2] == TRIGGER["Present Position"]
    assert servo_bus.read(3, "Present Position") == TRIGGER["Present Position"]


# --------------------------------------------------------------------- faults
#: The start of every "no answer" message; the rest names the servos and the attempts.
NO_ANSWER = r"There is no status packet! from servo\(s\) "


class StepClock:
    """A fake clock that moves on ``step`` seconds each time it is read."""

    def __init__(self, step: float) -> None:
        self.step = step
        self.now = 0.0

    def __call__(self) -> float:
        self.now += self.step
        return self.now


def costs(
    driver: ServoBus, call: Callable[[], object], match: str
) -> tuple[CommunicationError, dict[str, int]]:
    """The CommunicationError that ``call`` raises and the driver's counters it spent."""
    before = dict(driver.stats)
    with pytest.raises(CommunicationError, match=match) as info:
        call()
    spent = {key: value - before.get(key, 0) for key, value in driver.stats.items()}
    return info.value, {key: value for key, value in spent.items() if value}


def test_silent_bus_is_a_communication_error_after_bounded_attempts(
    servo_bus: ServoBus, bus: EmulatedBus
) -> None:
    bus.silence()
    error, spent = costs(
        servo_bus,
        lambda: servo_bus.ping(1),
        rf"^ping servo 1: {NO_ANSWER}\[1\] after 3 attempt\(s\) at 57600 bit/s",
    )
    assert error.result == -3001 and error.servo_ids == (1,)
    assert spent == FAILED_ONCE
    error, spent = costs(
        servo_bus,
        servo_bus.sync_read,
        rf"^sync read of 20 byte\(s\) at 116: {NO_ANSWER}\[1, 2, 3\]",
    )
    assert error.servo_ids == IDS and spent == FAILED_ONCE


@pytest.mark.parametrize(
    ("operation", "reply_bytes"),
    [("ping", 11), ("sync_read", 3 * (11 + 20)), ("fast_sync_read", 3 * (11 + 20))],
)
def test_each_attempt_waits_its_packet_timeout_on_the_driver_clock(
    bus: EmulatedBus, operation: str, reply_bytes: int
) -> None:
    """A silent servo costs each attempt the packet timeout on the clock the driver was
    given, and no more: the SDK's wall clock plays no part. The fake clock moves on
    0.1 ms a reading; an attempt reads it once to set the deadline, then once a read
    of the port until a read begins past the deadline."""
    clock = StepClock(1e-4)
    bus.silence()
    with ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS, clock=clock) as driver:
        driver.fast_sync_read = operation == "fast_sync_read"
        call = (lambda: driver.ping(1)) if operation == "ping" else driver.sync_read
        error, spent = costs(driver, call, rf"{NO_ANSWER}.* after 3 attempt\(s\)")
    assert error.result == -3001
    attempts = spent["transactions"]
    assert attempts == (6 if operation == "fast_sync_read" else 3)  # fast, then plain
    timeout = packet_timeout_s(reply_bytes)
    assert attempts * (timeout + clock.step) < clock.now <= attempts * (timeout + 2.5 * clock.step)


def test_one_unplugged_servo_is_named(servo_bus: ServoBus, bus: EmulatedBus) -> None:
    servo_bus.identify()
    bus.unplug(2)
    for fast in (True, False):
        servo_bus.fast_sync_read = fast
        error, spent = costs(servo_bus, servo_bus.sync_read, rf"{NO_ANSWER}\[2\] after 3")
        assert error.servo_ids == (2,) and error.servo_id == 2
        # the fast read fails as a whole, then the plain one names the silent servo
        assert spent == (
            {"transactions": 6, "retries": 4, "failures": 2, "fast_fallbacks": 1}
            if fast
            else FAILED_ONCE
        )
    bus.plug(2)  # back: powered up afresh
    assert servo_bus.sync_read().ids == IDS


@pytest.mark.parametrize("kind", ["crc", "truncate", "noise"])
def test_a_corrupted_reply_is_retried(servo_bus: ServoBus, bus: EmulatedBus, kind: str) -> None:
    bus.corrupt(count=1, kind=kind)
    readings = servo_bus.sync_read()
    assert readings.position == (2048, 2048, 2048)
    assert bus.stats()["corrupted"] == 1
    if kind == "noise":  # a stray header before a good packet costs nothing
        return
    assert servo_bus.stats["retries"] >= 1
    bus.corrupt(count=None, ids=[3], kind=kind)
    error, spent = costs(
        servo_bus,
        lambda: servo_bus.read(3, "Present Position"),
        r"^read 4 byte\(s\) at 132 of servo 3: Incorrect status packet! from servo\(s\) \[3\]",
    )
    assert error.servo_ids == (3,) and spent == FAILED_ONCE


def test_alert_bit_is_recorded_and_decoded(servo_bus: ServoBus, bus: EmulatedBus) -> None:
    servo_bus.identify()
    servo_bus.configure()
    servo_bus.set_torque(True)
    assert bus.alert(2, int(HardwareErrorFlag.OVERLOAD | HardwareErrorFlag.INPUT_VOLTAGE)) == 32
    readings = servo_bus.sync_read()  # data still valid with the alert bit
    assert readings.alert == (False, True, False)
    assert servo_bus.alerts == {1: False, 2: True, 3: False}
    assert servo_bus.hardware_errors(2) == HardwareErrorFlag.OVERLOAD
    assert servo_bus.torque_enabled() == {1: True, 2: False, 3: True}
    with pytest.raises(HardwareError, match=r"servo 2 did not turn torque on.*overload"):
        servo_bus.set_torque(True, [2])
    servo_bus.reboot(2)
    assert servo_bus.alerts[2] is False
    assert servo_bus.hardware_errors(2) == HardwareErrorFlag(0)
    assert bus.item(2, "Profile Velocity") == 0  # RAM defaults after a reboot
    servo_bus.set_torque(True, [2])
    assert bus.item(2, "Torque Enable") == 1


def test_servo_errors_and_client_side_rules(servo_bus: ServoBus, bus: EmulatedBus) -> None:
    servo_bus.write(1, "Torque Enable", 1)
    with pytest.raises(HardwareError, match="EEPROM and is writable only with torque off"):
        servo_bus.write(1, "Operating Mode", 4)
    # position mode: beyond the position limits
    with pytest.raises(ServoError, match="servo 1 answered error 6: data limit error") as info:
        servo_bus.write(1, "Goal Position", 5000)
    assert info.value.error == 6 and info.value.servo_id == 1
    with pytest.raises(InputError, match="read-only"):
        servo_bus.write(1, "Present Position", 0)
    with pytest.raises(InputError, match=r"Profile Velocity must lie in \[0, 32767\]"):
        servo_bus.write(1, "Profile Velocity", -1)
    servo_bus.write(1, "Torque Enable", 0)
    with pytest.raises(HardwareError, match="byte stuffing"):
        servo_bus.write(1, "Homing Offset", -131073)  # FF FF FD in its bytes
    with pytest.raises(InputError, match="not on this bus"):
        servo_bus.sync_write_goals({7: 0})
    bus.set_item(3, "Model Number", 1020)
    with pytest.raises(HardwareError, match="servo 3 is model 1020, not an XM540-W150"):
        servo_bus.identify()


def test_baud_rate_mismatch_and_bad_arguments(bus: EmulatedBus) -> None:
    # Factory-fresh servos (57600 bit/s, the driver's default too) do not hear a
    # controller at 1 Mbit/s, as on a real bus: the error names the rate.
    assert bus.baudrate == BAUD == 57_600 == ServoBus(bus.port).baudrate
    with ServoBus(bus.port, IDS, baudrate=1_000_000, latency_timer_ms=LATENCY_MS) as fast:
        error, spent = costs(fast, fast.identify, rf"^ping servo 1: {NO_ANSWER}.* at 1000000 bit/s")
        assert error.result == -3001 and spent == FAILED_ONCE
    assert not [e for e in bus.log() if e.accepted]  # nothing reached a servo
    with pytest.raises(InputError, match="baudrate must be one of"):
        ServoBus(bus.port, baudrate=4_500_000)
    with pytest.raises(InputError, match="ids must be distinct"):
        ServoBus(bus.port, ids=(1, 1))
    with pytest.raises(InputError, match="retries"):
        ServoBus(bus.port, retries=-1)
    with pytest.raises(InputError, match=r"clock must be a callable returning seconds, got 3\.0"):
        ServoBus(bus.port, clock=3.0)  # type: ignore[arg-type]
    with pytest.raises(HardwareError, match="is not open"):
        ServoBus(bus.port).ping(1)
    with pytest.raises(HardwareError, match="cannot open servo port '/dev/no-such-port'"):
        ServoBus("/dev/no-such-port").open()
    with pytest.raises(InputError, match="positive"):
        ServoSettings(profile_velocity=math.nan)
    with pytest.raises(InputError, match="exceeds velocity_limit"):
        ServoSettings(profile_velocity=5.0, velocity_limit=4.0)


def test_emulator_gone_is_a_communication_error() -> None:
    """The SDK raises OSError or termios.error when the other end vanishes: the driver
    turns them into CommunicationError."""
    emulated = EmulatedBus((1,)).start()
    driver = ServoBus(emulated.port, (1,), baudrate=BAUD, latency_timer_ms=LATENCY_MS).open()
    try:
        assert driver.ping(1) == 1130
        emulated.stop()
        error, spent = costs(
            driver, lambda: driver.ping(1), r"^ping servo 1: the port '/dev/\S+' failed: "
        )
        # a port error is not retried: one transaction, no wait for a packet timeout
        assert error.servo_ids == (1,) and spent == {"transactions": 1, "failures": 1}
    finally:
        driver.close()
        emulated.stop()


def test_a_bus_at_another_rate_talks_only_at_that_rate() -> None:
    """Servos set to 1 Mbit/s (asked for explicitly) answer a controller at 1 Mbit/s
    and nobody at their factory default, 57600 bit/s."""
    with EmulatedBus((1,), baudrate=1_000_000) as emulated:
        assert emulated.baudrate == 1_000_000 and emulated.item(1, "Baud Rate") == 3
        with ServoBus(
            emulated.port, (1,), baudrate=1_000_000, latency_timer_ms=LATENCY_MS
        ) as driver:
            assert driver.ping(1) == 1130
        with ServoBus(emulated.port, (1,), latency_timer_ms=LATENCY_MS) as slow:  # 57600
            error, spent = costs(
                slow, lambda: slow.ping(1), rf"^ping servo 1: {NO_ANSWER}\[1\] .* at 57600 bit/s"
            )
            assert error.servo_ids == (1,) and spent == FAILED_ONCE
