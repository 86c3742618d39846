"""The emulated XM540-W150 bus: protocol, control-table rules, motion, hardware errors
(in process, with a controlled clock), and the unmodified SDK talking to it over the
pseudo-terminal (including the SDK's own pitfalls)."""

from __future__ import annotations

import math
import time

import pytest

pytest.importorskip("dynamixel_sdk")

import dynamixel_sdk as sdk
from _hardware_data import BAUD, IDS, TRIGGER, state_block

from spm_pin.errors import InputError
from spm_pin.hardware import XM540_W150, EmulatedBus, ServoEmulator
from spm_pin.hardware.control_table import ACCELERATION_UNIT, POSITION_UNIT, VELOCITY_UNIT
from spm_pin.hardware.protocol import (
    BROADCAST_ID,
    Instruction,
    Packet,
    crc16,
    instruction_packet,
    parse_packet,
    unstuff,
)

pytestmark = pytest.mark.hardware
pytest_plugins = ["_hardware"]

T = XM540_W150


class Clock:
    """A clock the test advances [s]."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def make(ids: tuple[int, ...] = IDS, **kwargs: object) -> tuple[ServoEmulator, Clock]:
    clock = Clock()
    return ServoEmulator(ids, clock=clock, **kwargs), clock  # type: ignore[arg-type]


def send(emu: ServoEmulator, servo_id: int, instruction: int, params: bytes = b"") -> list[Packet]:
    """Send one instruction; return the status packets (parsed)."""
    replies = emu.receive(instruction_packet(servo_id, instruction, params))
    return [parse_packet(reply.data) for reply in replies]


def write(emu: ServoEmulator, servo_id: int, name: str, value: int) -> int | None:
    """WRITE an item; return the error byte of the reply (None: no reply)."""
    item = T[name]
    params = item.address.to_bytes(2, "little") + item.encode(value)
    replies = send(emu, servo_id, Instruction.WRITE, params)
    return replies[0].parameters[0] if replies else None


def read(emu: ServoEmulator, servo_id: int, name: str) -> tuple[int, int]:
    """READ an item: (error byte, value)."""
    item = T[name]
    params = item.address.to_bytes(2, "little") + item.size.to_bytes(2, "little")
    (reply,) = send(emu, servo_id, Instruction.READ, params)
    return reply.parameters[0], item.decode(reply.parameters[1:])


# --------------------------------------------------------------- instructions
def test_ping_identifies_every_servo_in_id_order() -> None:
    emu, _ = make(firmware=47)
    (reply,) = send(emu, 2, Instruction.PING)
    assert reply.servo_id == 2 and reply.instruction == Instruction.STATUS
    assert reply.parameters == b"\x00" + (1130).to_bytes(2, "little") + b"\x2f"
    replies = send(emu, BROADCAST_ID, Instruction.PING)
    assert [r.servo_id for r in replies] == [1, 2, 3]
    assert send(emu, 9, Instruction.PING) == []  # nobody has id 9


def test_default_baud_rate_is_the_factory_default_and_must_match_the_line() -> None:
    emu, _ = make()
    assert [s.baudrate for s in emu.servos.values()] == [57_600] * 3
    assert read(emu, 1, "Baud Rate") == (0, 1)  # item 1: 57600, as out of the box
    ping = instruction_packet(1, Instruction.PING)
    assert emu.receive(ping, line_baudrate=1_000_000) == []  # noise to the servos
    assert len(emu.receive(ping, line_baudrate=57_600)) == 1
    fast, _ = make(baudrate=1_000_000)  # asked otherwise
    assert read(fast, 2, "Baud Rate") == (0, 3)
    assert fast.receive(ping, line_baudrate=57_600) == []
    assert len(fast.receive(ping, line_baudrate=1_000_000)) == 1


def test_access_rules_of_the_control_table() -> None:
    emu, _ = make()
    assert write(emu, 1, "Goal Position", 3000) == 0
    assert read(emu, 1, "Goal Position") == (0, 3000)
    # Read-only item: access error.
    params = T["Present Position"].address.to_bytes(2, "little") + bytes(4)
    assert send(emu, 1, Instruction.WRITE, params)[0].parameters[0] == 7
    # A write that covers an item in part: data length error.
    assert send(emu, 1, Instruction.WRITE, b"\x74\x00\x01\x02")[0].parameters[0] == 5
    # Out of the item's range: data range error.
    assert write(emu, 1, "Operating Mode", 4) == 0
    params = T["Operating Mode"].address.to_bytes(2, "little") + b"\x02"
    assert send(emu, 1, Instruction.WRITE, params)[0].parameters[0] == 4
    # EEPROM with torque on: access error, and the value is kept.
    assert write(emu, 1, "Torque Enable", 1) == 0
    assert write(emu, 1, "Return Delay Time", 0) == 7
    assert read(emu, 1, "Return Delay Time") == (0, 250)
    assert write(emu, 1, "Torque Enable", 0) == 0
    assert write(emu, 1, "Return Delay Time", 0) == 0
    # Position mode: Goal Position beyond the limits is a data limit error.
    assert write(emu, 2, "Goal Position", -5) == 6
    assert write(emu, 2, "Goal Position", 4095) == 0
    # A read past the table: access error; an unknown instruction: instruction error.
    (reply,) = send(
        emu, 1, Instruction.READ, (140).to_bytes(2, "little") + (20).to_bytes(2, "little")
    )
    assert reply.parameters[0] == 7
    assert send(emu, 1, 0x7A)[0].parameters[0] == 2


def test_operating_mode_change_zeroes_the_profile() -> None:
    emu, _ = make()
    assert write(emu, 1, "Profile Velocity", 100) == 0
    assert write(emu, 1, "Profile Acceleration", 50) == 0
    assert write(emu, 1, "Operating Mode", 4) == 0
    assert read(emu, 1, "Profile Velocity") == (0, 0)
    assert read(emu, 1, "Profile Acceleration") == (0, 0)


def test_status_return_level_and_return_delay() -> None:
    emu, _ = make()
    assert write(emu, 1, "Status Return Level", 1) is None  # SRL 1: no reply to WRITE ...
    assert read(emu, 1, "Status Return Level") == (0, 1)  # ... but to READ
    write(emu, 2, "Status Return Level", 0)
    assert send(emu, 2, Instruction.READ, b"\x40\x00\x01\x00") == []
    assert len(send(emu, 2, Instruction.PING)) == 1  # PING is always answered
    replies = emu.receive(instruction_packet(3, Instruction.PING))
    assert math.isclose(replies[0].delay, 250 * 2e-6)


def test_garbled_and_unstuffed_packets() -> None:
    emu, _ = make()
    packet = bytearray(instruction_packet(1, Instruction.PING))
    packet[-1] ^= 0x55
    (reply,) = [parse_packet(r.data) for r in emu.receive(bytes(packet))]
    assert reply.parameters[0] == 3  # CRC error
    # FF FF FD inside the body without its stuffing byte: dropped, and logged.
    body = bytes((Instruction.WRITE, 116, 0)) + T["Goal Position"].encode(-131073)
    head = b"\xff\xff\xfd\x00\x01" + (len(body) + 2).to_bytes(2, "little")
    crc = crc16(head + body)
    raw = head + body + crc.to_bytes(2, "little")
    assert emu.receive(raw) == []
    assert emu.log[-1].accepted is False and "not followed by FD" in emu.log[-1].note
    assert read(emu, 1, "Goal Position") == (0, 2048)


def test_reg_write_action_reboot_factory_reset_clear() -> None:
    emu, clock = make()
    item = T["Goal Position"]
    params = item.address.to_bytes(2, "little") + item.encode(3000)
    assert send(emu, 1, Instruction.REG_WRITE, params)[0].parameters[0] == 0
    assert read(emu, 1, "Goal Position") == (0, 2048)
    assert read(emu, 1, "Registered Instruction") == (0, 1)
    assert send(emu, 1, Instruction.ACTION)[0].parameters[0] == 0
    assert read(emu, 1, "Goal Position") == (0, 3000)
    assert send(emu, 1, Instruction.ACTION)[0].parameters[0] == 2  # nothing registered
    # REBOOT: silent for a while, then RAM defaults.
    assert send(emu, 1, Instruction.REBOOT)[0].parameters[0] == 0
    assert send(emu, 1, Instruction.PING) == []
    clock.now += 0.1
    assert read(emu, 1, "Goal Position") == (0, 2048)
    # FACTORY_RESET 0x02 keeps ID and baud rate, resets the rest of the EEPROM.
    write(emu, 2, "Return Delay Time", 0)
    assert send(emu, 2, Instruction.FACTORY_RESET, b"\x02")[0].parameters[0] == 0
    clock.now += 0.1
    assert read(emu, 2, "Return Delay Time") == (0, 250)
    assert read(emu, 2, "Baud Rate") == (0, 1)  # 57600, as it was
    # CLEAR: the multi-turn count back within one turn.
    emu.servo(3).set("Present Position", 3 * 4096 + 100)
    (reply,) = send(emu, 3, Instruction.CLEAR, b"\x01\x44\x58\x4c\x22")
    assert reply.parameters[0] == 0
    assert read(emu, 3, "Present Position") == (0, 100)


def test_bulk_read_and_bulk_write() -> None:
    emu, _ = make()
    records = b"".join(
        bytes((i,))
        + (116).to_bytes(2, "little")
        + (4).to_bytes(2, "little")
        + T["Goal Position"].encode(1000 * i)
        for i in (1, 3)
    )
    assert send(emu, BROADCAST_ID, Instruction.BULK_WRITE, records) == []
    params = b"".join(bytes((i,)) + b"\x74\x00\x04\x00" for i in (3, 1))
    replies = send(emu, BROADCAST_ID, Instruction.BULK_READ, params)
    assert [(r.servo_id, T["Goal Position"].decode(r.parameters[1:])) for r in replies] == [
        (3, 3000),
        (1, 1000),
    ]


def test_sync_read_and_fast_sync_read_packets() -> None:
    emu, _ = make()
    for i in IDS:
        emu.servo(i).set("Present Position", -1000 * i)
    params = (132).to_bytes(2, "little") + (4).to_bytes(2, "little") + bytes(IDS)
    replies = send(emu, BROADCAST_ID, Instruction.SYNC_READ, params)
    assert [T["Present Position"].decode(r.parameters[1:]) for r in replies] == [
        -1000,
        -2000,
        -3000,
    ]
    (raw,) = emu.receive(instruction_packet(BROADCAST_ID, Instruction.FAST_SYNC_READ, params))
    packet = parse_packet(raw.data)
    assert packet.servo_id == BROADCAST_ID
    body = unstuff(raw.data[7:-2])
    segments = [body[1 + k * 8 : 1 + k * 8 + 6] for k in range(3)]
    assert [(s[0], s[1], T["Present Position"].decode(s[2:])) for s in segments] == [
        (0, 1, -1000),
        (0, 2, -2000),
        (0, 3, -3000),
    ]
    # One servo gone: its plain reply is missing, the fast chain breaks there.
    emu.unplug(2)
    replies = send(emu, BROADCAST_ID, Instruction.SYNC_READ, params)
    assert [r.servo_id for r in replies] == [1, 3]
    (raw,) = emu.receive(instruction_packet(BROADCAST_ID, Instruction.FAST_SYNC_READ, params))
    length = raw.data[5] | raw.data[6] << 8
    assert len(raw.data) < 7 + length  # truncated: the controller times out


# ------------------------------------------------------------------- motion
def test_motion_follows_the_profile_and_stops_on_the_goal() -> None:
    emu, clock = make()
    write(emu, 1, "Operating Mode", 4)
    write(emu, 1, "Profile Velocity", 100)  # 22.9 rev/min
    write(emu, 1, "Profile Acceleration", 100)
    write(emu, 1, "Torque Enable", 1)
    goal = 2048 + 2 * 4096
    write(emu, 1, "Goal Position", goal)
    speed = 100 * VELOCITY_UNIT / POSITION_UNIT  # [pulses/s]
    accel = 100 * ACCELERATION_UNIT / POSITION_UNIT
    t_ramp = speed / accel
    clock.now += t_ramp + 0.2
    expected = 2048 + 0.5 * accel * t_ramp**2 + speed * 0.2
    _, position = read(emu, 1, "Present Position")
    assert abs(position - expected) < 0.01 * expected
    assert read(emu, 1, "Present Velocity") == (0, 100)
    assert read(emu, 1, "Moving") == (0, 1)
    clock.now += 6.0  # 2 turns at 22.9 rev/min take 5.2 s
    assert read(emu, 1, "Present Position") == (0, goal)
    assert read(emu, 1, "Present Velocity") == (0, 0)
    assert read(emu, 1, "Moving") == (0, 0)
    # Torque off: the shaft stays where it is whatever the goal.
    write(emu, 1, "Torque Enable", 0)
    write(emu, 1, "Goal Position", 0)
    clock.now += 1.0
    assert read(emu, 1, "Present Position") == (0, goal)


def test_shutdown_mask_decides_which_errors_drop_torque() -> None:
    emu, clock = make()
    write(emu, 1, "Torque Enable", 1)
    assert emu.alert(1, 1) == 0  # input voltage: not in the default mask (52)
    assert read(emu, 1, "Torque Enable") == (0, 1)
    assert emu.alert(1, 32) == 32  # overload: in the mask
    error, torque = read(emu, 1, "Torque Enable")
    assert (error, torque) == (0x80, 0)  # alert bit set, torque dropped
    assert read(emu, 1, "Hardware Error Status") == (0x80, 32)
    assert write(emu, 1, "Torque Enable", 1) == 0x81  # refused until REBOOT
    # With overload out of the mask, the same condition is ignored.
    write(emu, 2, "Shutdown", 4)
    write(emu, 2, "Torque Enable", 1)
    assert emu.alert(2, 32) == 0
    assert read(emu, 2, "Torque Enable") == (0, 1)
    # REBOOT clears it; the multi-turn count restarts within one turn.
    emu.servo(1).set("Present Position", -4096 - 1000)
    send(emu, 1, Instruction.REBOOT)
    clock.now += 0.1
    assert read(emu, 1, "Hardware Error Status") == (0, 0)
    assert read(emu, 1, "Present Position") == (0, (-4096 - 1000) % 4096)
    assert read(emu, 1, "Goal Position") == (0, (-4096 - 1000) % 4096)


def test_fault_counts_and_bad_arguments() -> None:
    emu, _ = make()
    emu.silence(count=2, ids=[1])
    assert send(emu, 1, Instruction.PING) == []
    assert send(emu, 2, Instruction.PING) != []  # only servo 1 is silenced
    assert send(emu, 1, Instruction.PING) == []
    assert send(emu, 1, Instruction.PING) != []  # two replies lost, then back
    emu.corrupt(count=1, kind="truncate")
    (raw,) = emu.receive(instruction_packet(3, Instruction.PING))
    assert len(raw.data) < 14
    assert emu.stats["silenced"] == 2 and emu.stats["corrupted"] == 1
    with pytest.raises(InputError, match="kind must be"):
        emu.corrupt(kind="loud")
    with pytest.raises(InputError, match="distinct servo ids"):
        ServoEmulator((1, 1))
    with pytest.raises(InputError, match="no emulated servo has id 7"):
        emu.unplug(7)


# ---------------------------------------------------- the real SDK over the pty
def open_sdk(port: str, baudrate: int = BAUD) -> tuple[object, object]:
    handler = sdk.PortHandler(port)
    assert handler.openPort()
    assert handler.setBaudRate(baudrate)
    return handler, sdk.PacketHandler(2.0)


def test_unmodified_sdk_round_trips(bus: EmulatedBus) -> None:
    port, packets = open_sdk(bus.port)
    try:
        model, result, error = packets.ping(port, 2)  # type: ignore[attr-defined]
        assert (model, result, error) == (1130, sdk.COMM_SUCCESS, 0)
        result, error = packets.write1ByteTxRx(port, 1, 11, 4)  # type: ignore[attr-defined]
        assert (result, error) == (sdk.COMM_SUCCESS, 0)
        result, error = packets.write4ByteTxRx(port, 1, 116, (-5000) & 0xFFFFFFFF)  # type: ignore[attr-defined]
        assert (result, error) == (sdk.COMM_SUCCESS, 0)
        value, result, error = packets.read4ByteTxRx(port, 1, 116)  # type: ignore[attr-defined]
        assert result == sdk.COMM_SUCCESS and error == 0
        assert value == 4294962296  # unsigned: the caller converts (-5000)
        assert bus.item(1, "Goal Position") == -5000
        group = sdk.GroupSyncRead(port, packets, 132, 4)
        for i in IDS:
            assert group.addParam(i)
        assert group.fastSyncRead() == sdk.COMM_SUCCESS
        assert [group.getData(i, 132, 4) for i in IDS] == [2048, 2048, 2048]
    finally:
        port.closePort()  # type: ignore[attr-defined]


def test_sdk_pitfalls_on_the_emulated_bus(bus: EmulatedBus) -> None:
    """What the driver guards against, shown with the plain SDK."""
    port, packets = open_sdk(bus.port)
    try:
        # 1. One silent servo fails the whole sync read, and getData then reads 0.
        bus.unplug(2)
        group = sdk.GroupSyncRead(port, packets, 132, 4)
        for i in IDS:
            group.addParam(i)
        assert group.txRxPacket() == sdk.COMM_RX_TIMEOUT  # one try, then it gives up
        assert [(e.instruction, e.accepted) for e in bus.log()] == [("SYNC_READ", True)]
        assert [group.getData(i, 132, 4) for i in IDS] == [0, 0, 0]
        bus.clear_faults()
        # 2. The SDK sends -131073 without byte stuffing: the servo drops the packet.
        writer = sdk.GroupSyncWrite(port, packets, 116, 4)
        writer.addParam(1, list(XM540_W150["Goal Position"].encode(-131073)))
        assert writer.txPacket() == sdk.COMM_SUCCESS  # ... and reports success
        time.sleep(0.05)
        assert bus.item(1, "Goal Position") == 2048
        assert any("not followed by FD" in e.note for e in bus.log())
        # 3. Its destuffing loses a byte of a rare but valid reply: wrong data, no error.
        bus.freeze(3)
        for name, value in TRIGGER.items():
            bus.set_item(3, name, value)
        group = sdk.GroupSyncRead(port, packets, 116, 20)
        group.addParam(3)
        assert group.txRxPacket() == sdk.COMM_SUCCESS
        assert group.getData(3, 128, 4) != (TRIGGER["Present Velocity"] & 0xFFFFFFFF)
        assert bus.state(3)["Present Velocity"] == TRIGGER["Present Velocity"]
        assert state_block(**TRIGGER)[12:16] == (-3).to_bytes(4, "little", signed=True)
        # 4. A baud-rate mismatch is silence: 1 Mbit/s to factory-fresh servos.
        assert port.setBaudRate(1_000_000)  # type: ignore[attr-defined]
        _, result, _ = packets.ping(port, 1)  # type: ignore[attr-defined]
        assert result == sdk.COMM_RX_TIMEOUT
    finally:
        port.closePort()  # type: ignore[attr-defined]
