"""Protocol 2.0 packets and the XM540-W150 control table, checked against the SDK's own
code and the e-Manual's numbers; the SDK's stuffing defects shown on the bytes."""

from __future__ import annotations

import itertools
import math

import pytest

pytest.importorskip("dynamixel_sdk")

from _hardware_data import TRIGGER, state_block
from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler

from spm_pin.errors import InputError
from spm_pin.hardware import control_table as ct
from spm_pin.hardware.protocol import (
    PacketReader,
    ProtocolError,
    crc16,
    instruction_packet,
    parse_packet,
    status_packet,
    stuff,
    unstuff,
)

pytestmark = pytest.mark.hardware

SDK = Protocol2PacketHandler()
ALPHABET = (0x00, 0xFD, 0xFF)


def _sdk_packet(body: bytes) -> list[int]:
    """A status packet as a list, stuffed by us, for the SDK's removeStuffing."""
    return list(status_packet(1, body[0], body[1:]))


# ------------------------------------------------------------------------ CRC
def test_crc_check_value_and_sdk_agree() -> None:
    assert crc16(b"123456789") == 0xFEE8  # CRC-16/BUYPASS check value
    data = bytes(range(256)) * 3
    assert crc16(data) == SDK.updateCRC(0, list(data), len(data))


# ------------------------------------------------------------------- stuffing
@pytest.mark.parametrize("length", [3, 6, 7])
def test_stuffing_round_trip_and_matches_the_sdk(length: int) -> None:
    for combo in itertools.product(ALPHABET, repeat=length):
        body = bytes(combo)
        stuffed = stuff(body)
        assert unstuff(stuffed) == body
        # Every FF FF FD on the wire is followed by the stuffing FD.
        headers = [i for i in range(len(stuffed) - 2) if stuffed[i : i + 3] == b"\xff\xff\xfd"]
        assert all(stuffed[i + 3 : i + 4] == b"\xfd" for i in headers)
        # The SDK's addStuffing computes the same bytes (its caller then drops them).
        packet = [0xFF, 0xFF, 0xFD, 0, 1, (len(body) + 3) & 0xFF, 0, 0x03, *body, 0, 0]
        assert bytes(SDK.addStuffing(list(packet))[8:-2]) == stuffed


def test_unstuff_rejects_an_unstuffed_header() -> None:
    with pytest.raises(ProtocolError, match="not followed by FD"):
        unstuff(b"\x03\xff\xff\xfd\x00")


def test_sdk_txpacket_does_not_stuff() -> None:
    """The defect the driver works around: the SDK sends FF FF FD unstuffed."""

    class Port:
        is_using = False
        sent = b""

        def clearPort(self) -> None:
            pass

        def writePort(self, packet: list[int]) -> int:
            Port.sent = bytes(packet)
            return len(packet)

    value = ct.XM540_W150["Goal Position"].encode(-131073)
    assert value[:3] == b"\xff\xff\xfd"
    assert SDK.write4ByteTxOnly(Port(), 1, 116, -131073 & 0xFFFFFFFF) == 0
    with pytest.raises(ProtocolError, match="FF FF FD inside a packet body is not followed by FD"):
        parse_packet(Port.sent)  # a correct receiver must reject it
    assert parse_packet(instruction_packet(1, 0x03, b"\x74\x00" + value)).parameters[2:] == value


def test_sdk_remove_stuffing_drops_a_byte_in_the_state_block() -> None:
    data = state_block(**TRIGGER)
    packet = _sdk_packet(b"\x00" + data)
    sdk = SDK.removeStuffing(list(packet))
    sdk_data = bytes(sdk[9 : 9 + len(data)])
    assert sdk_data[:12] == data[:12]
    assert sdk_data[12:] != data[12:]  # velocity and position come out wrong
    assert parse_packet(bytes(packet)).parameters[1:] == data  # ours are right


def test_sdk_destuffing_is_harmless_for_single_items() -> None:
    """Every status packet of an error byte and 1..4 data bytes over {00, FD, FF} is
    destuffed right by the SDK, so single-item reads could use it."""
    for size in (1, 2, 4):
        for error in (0x00, 0x80):
            for combo in itertools.product(ALPHABET, repeat=size):
                body = bytes((error, *combo))
                sdk = SDK.removeStuffing(_sdk_packet(body))
                assert bytes(sdk[8 : 8 + len(body)]) == body


# -------------------------------------------------------------------- packets
def test_packet_reader_resynchronises_on_noise() -> None:
    reader = PacketReader()
    good = instruction_packet(2, 0x01)
    bad = bytearray(instruction_packet(3, 0x01))
    bad[-1] ^= 0xFF
    reader.feed(b"\x00\xff\x12" + good[:5])
    assert reader.packets() == []
    reader.feed(good[5:] + bytes(bad) + b"\xff\xff")
    found = reader.packets()
    assert [type(p).__name__ for _, p in found] == ["Packet", "ProtocolError"]
    assert found[0][1].servo_id == 2  # type: ignore[union-attr]
    assert reader.pending == 2  # a possible header start is kept


# -------------------------------------------------------------- control table
def test_control_table_matches_the_e_manual() -> None:
    table = ct.XM540_W150
    expected = {
        "Model Number": (0, 2),
        "ID": (7, 1),
        "Baud Rate": (8, 1),
        "Return Delay Time": (9, 1),
        "Drive Mode": (10, 1),
        "Operating Mode": (11, 1),
        "Homing Offset": (20, 4),
        "Current Limit": (38, 2),
        "Velocity Limit": (44, 4),
        "Max Position Limit": (48, 4),
        "Min Position Limit": (52, 4),
        "Shutdown": (63, 1),
        "Torque Enable": (64, 1),
        "Status Return Level": (68, 1),
        "Hardware Error Status": (70, 1),
        "Profile Acceleration": (108, 4),
        "Profile Velocity": (112, 4),
        "Goal Position": (116, 4),
        "Moving": (122, 1),
        "Present Current": (126, 2),
        "Present Velocity": (128, 4),
        "Present Position": (132, 4),
        "Present Input Voltage": (144, 2),
        "Present Temperature": (146, 1),
    }
    for name, (address, size) in expected.items():
        assert (table[name].address, table[name].size) == (address, size), name
    assert table["Shutdown"].default == 52 and table["Return Delay Time"].default == 250
    assert table["Model Number"].default == ct.MODEL_NUMBER == 1130
    assert all(item.eeprom == (item.address < 64) for item in table.values())
    # No two items overlap.
    spans = sorted((item.address, item.end) for item in table.values())
    assert all(a_end <= b_start for (_, a_end), (b_start, _) in itertools.pairwise(spans))
    assert table.covering(133) is table["Present Position"] and table.covering(14) is None
    with pytest.raises(InputError, match="no control item 'Goal Pos'"):
        table["Goal Pos"]


def test_units_and_signed_conversions() -> None:
    assert math.isclose(math.degrees(ct.POSITION_UNIT), 0.087890625)
    assert math.isclose(ct.VELOCITY_UNIT * 60 / (2 * math.pi), 0.229)
    assert math.isclose(ct.ACCELERATION_UNIT * 3600 / (2 * math.pi), 214.577)
    assert ct.to_signed(4294966272, 4) == -1024  # the note's homing offset reading
    assert ct.to_unsigned(-1024, 4) == 4294966272
    assert ct.to_signed(0xFFFF, 2) == -1 and ct.to_signed(0x7FFF, 2) == 32767
    item = ct.XM540_W150["Goal Position"]
    for value in (-1_048_575, -131073, -1, 0, 1, 4095, 1_048_575):
        assert item.decode(item.encode(value)) == value
    with pytest.raises(InputError, match=r"Goal Position must lie in \[-1048575, 1048575\]"):
        item.encode(1_048_576)
    with pytest.raises(InputError, match="must be an integer"):
        item.encode(1.5)  # type: ignore[arg-type]
    flags = ct.HardwareErrorFlag(52)
    assert flags.describe() == ["overheating", "electrical shock", "overload"]
    assert ct.describe_error_byte(0x87) == (
        "access error (read-only item, EEPROM with torque on, or no such address); "
        "hardware alert (see Hardware Error Status)"
    )
