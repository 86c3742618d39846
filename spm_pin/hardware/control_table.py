"""The XM540-W150 control table (Protocol 2.0, model number 1130) and its units.

Every item has an address, a size in bytes, an access right, a memory area and a
range; :data:`XM540_W150` lists them by name. The servo's own units are converted to
SI units here and nowhere else:

==================  ====================  =======================================
quantity            raw unit              SI
==================  ====================  =======================================
position            1 pulse               2 pi / 4096 rad (0.088 deg)
velocity            0.229 rev/min         0.229 * 2 pi / 60 rad/s
acceleration        214.577 rev/min^2     214.577 * 2 pi / 3600 rad/s^2
current             2.69 mA               2.69e-3 A
input voltage       0.1 V                 0.1 V
return delay time   2 us                  2e-6 s
==================  ====================  =======================================

Items at addresses below 64 live in EEPROM: the servo accepts writes to them only
while Torque Enable is 0. Reads return unsigned integers; :func:`to_signed` turns
them into the signed values of the items marked ``signed`` (a Homing Offset of -1024
reads 4294966272).
"""

from __future__ import annotations

import dataclasses
import enum
import math
import operator
from collections.abc import Iterator, Mapping

from ..errors import InputError

__all__ = [
    "ACCELERATION_UNIT",
    "ALERT_BIT",
    "BAUD_RATES",
    "CURRENT_UNIT",
    "EEPROM_END",
    "EXTENDED_POSITION_LIMIT",
    "INSTRUCTION_ERRORS",
    "MODEL_NUMBER",
    "OPERATING_MODES",
    "POSITION_UNIT",
    "PULSES_PER_TURN",
    "VELOCITY_UNIT",
    "VOLTAGE_UNIT",
    "XM540_W150",
    "ControlItem",
    "ControlTable",
    "HardwareErrorFlag",
    "describe_error_byte",
    "to_signed",
    "to_unsigned",
]

#: Model number of the XM540-W150 (Model Number item, and the reply to PING).
MODEL_NUMBER = 1130
#: Encoder pulses per output-shaft turn.
PULSES_PER_TURN = 4096
#: Position unit [rad per pulse].
POSITION_UNIT = 2.0 * math.pi / PULSES_PER_TURN
#: Velocity unit [rad/s per 0.229 rev/min].
VELOCITY_UNIT = 0.229 * 2.0 * math.pi / 60.0
#: Profile acceleration unit [rad/s^2 per 214.577 rev/min^2].
ACCELERATION_UNIT = 214.577 * 2.0 * math.pi / 3600.0
#: Current unit [A per 2.69 mA].
CURRENT_UNIT = 2.69e-3
#: Input voltage unit [V].
VOLTAGE_UNIT = 0.1
#: Goal Position range in extended position mode [pulses], +-256 turns.
EXTENDED_POSITION_LIMIT = 1_048_575
#: First RAM address: items below are EEPROM (writable only with torque off).
EEPROM_END = 64

#: Baud Rate item value -> bits per second.
BAUD_RATES: Mapping[int, int] = {
    0: 9_600,
    1: 57_600,
    2: 115_200,
    3: 1_000_000,
    4: 2_000_000,
    5: 3_000_000,
    6: 4_000_000,
    7: 4_500_000,
}

#: Operating Mode item value -> name.
OPERATING_MODES: Mapping[int, str] = {
    0: "current",
    1: "velocity",
    3: "position",
    4: "extended position",
    5: "current-based position",
    16: "PWM",
}

#: Instruction error numbers (low 7 bits of a status packet's error byte) -> meaning.
INSTRUCTION_ERRORS: Mapping[int, str] = {
    1: "result fail (the instruction could not be processed)",
    2: "instruction error (undefined instruction, or ACTION without REG_WRITE)",
    3: "CRC error (the instruction packet was garbled)",
    4: "data range error (value outside the item's range)",
    5: "data length error (the data does not cover whole items)",
    6: "data limit error (value beyond a limit item)",
    7: "access error (read-only item, EEPROM with torque on, or no such address)",
}

#: The alert bit of a status packet's error byte: read Hardware Error Status.
ALERT_BIT = 0x80


class HardwareErrorFlag(enum.IntFlag):
    """Bits of the Hardware Error Status item (address 70)."""

    INPUT_VOLTAGE = 1
    OVERHEATING = 4
    MOTOR_ENCODER = 8
    ELECTRICAL_SHOCK = 16
    OVERLOAD = 32

    def describe(self) -> list[str]:
        """Names of the set bits, e.g. ``["overheating", "overload"]``."""
        return [
            str(flag.name).lower().replace("_", " ")
            for flag in HardwareErrorFlag
            if flag in self and flag.value
        ]


def describe_error_byte(error: int) -> str:
    """A status packet's error byte in words (``""`` when it is 0).

    Args:
        error: The error byte (0..255): bit 7 the hardware alert, bits 0..6 the
            instruction error number.
    """
    parts = []
    number = error & 0x7F
    if number:
        parts.append(INSTRUCTION_ERRORS.get(number, f"unknown instruction error {number}"))
    if error & ALERT_BIT:
        parts.append("hardware alert (see Hardware Error Status)")
    return "; ".join(parts)


def to_signed(raw: int, size: int) -> int:
    """Two's complement of an unsigned ``size``-byte reading (4294966272 -> -1024)."""
    bits = 8 * size
    raw &= (1 << bits) - 1
    return raw - (1 << bits) if raw >= 1 << (bits - 1) else raw


def to_unsigned(value: int, size: int) -> int:
    """The unsigned ``size``-byte word that carries a signed value (-1024 -> 4294966272)."""
    return value & ((1 << (8 * size)) - 1)


@dataclasses.dataclass(frozen=True)
class ControlItem:
    """One item of the control table.

    Attributes:
        name: The e-Manual's name, e.g. ``"Goal Position"``.
        address: First byte.
        size: Number of bytes (1, 2 or 4), little-endian.
        writable: False for read-only items.
        default: Value after power-up or factory reset (None: set by the servo).
        minimum: Smallest accepted value (signed items: signed).
        maximum: Largest accepted value.
        signed: The value is two's complement.
        unit: SI value of one raw unit (None when dimensionless).
    """

    name: str
    address: int
    size: int
    writable: bool
    default: int | None
    minimum: int
    maximum: int
    signed: bool = False
    unit: float | None = None

    @property
    def eeprom(self) -> bool:
        """The item lives in EEPROM (writable only with torque off)."""
        return self.address < EEPROM_END

    @property
    def end(self) -> int:
        """One past the last byte."""
        return self.address + self.size

    def check(self, value: int) -> int:
        """The value if it lies in [minimum, maximum], else InputError naming the item."""
        if isinstance(value, bool):
            raise InputError(
                f"{self.name} must be an integer, got {value!r}", argument=self.name, value=value
            )
        try:
            value = operator.index(value)
        except TypeError:
            raise InputError(
                f"{self.name} must be an integer, got {value!r}", argument=self.name, value=value
            ) from None
        if not self.minimum <= value <= self.maximum:
            raise InputError(
                f"{self.name} must lie in [{self.minimum}, {self.maximum}], got {value}",
                argument=self.name,
                value=value,
            )
        return value

    def encode(self, value: int) -> bytes:
        """Little-endian bytes of a checked value."""
        return to_unsigned(self.check(value), self.size).to_bytes(self.size, "little")

    def decode(self, data: bytes | bytearray) -> int:
        """The value of the item's bytes (signed when the item is)."""
        if len(data) != self.size:
            raise InputError(
                f"{self.name} takes {self.size} bytes, got {len(data)}",
                argument="data",
                value=bytes(data),
            )
        raw = int.from_bytes(bytes(data), "little")
        return to_signed(raw, self.size) if self.signed else raw


class ControlTable(Mapping[str, ControlItem]):
    """A servo's control table: items by name, and by address.

    Args:
        model_name: e.g. ``"XM540-W150"``.
        model_number: The Model Number item's value.
        items: The items, in address order.
    """

    def __init__(self, model_name: str, model_number: int, items: tuple[ControlItem, ...]):
        self.model_name = model_name
        self.model_number = model_number
        self._items = {item.name: item for item in items}
        self._by_address = {item.address: item for item in items}
        #: One past the last byte of the table.
        self.size = max(item.end for item in items)

    def __getitem__(self, name: str) -> ControlItem:
        try:
            return self._items[name]
        except KeyError:
            raise InputError(
                f"{self.model_name} has no control item {name!r}; items: {sorted(self._items)}",
                argument="item",
                value=name,
            ) from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def at(self, address: int) -> ControlItem | None:
        """The item that starts at ``address`` (None if none does)."""
        return self._by_address.get(address)

    def covering(self, address: int) -> ControlItem | None:
        """The item that contains byte ``address`` (None in a gap)."""
        for item in self._items.values():
            if item.address <= address < item.end:
                return item
        return None


_PULSES_RAD = POSITION_UNIT
_I32 = (-(2**31), 2**31 - 1)


def _item(
    name: str,
    address: int,
    size: int,
    writable: bool,
    default: int | None,
    minimum: int,
    maximum: int,
    *,
    signed: bool = False,
    unit: float | None = None,
) -> ControlItem:
    return ControlItem(name, address, size, writable, default, minimum, maximum, signed, unit)


#: The XM540-W150 control table (e-Manual, Protocol 2.0), up to Backup Ready.
#: The Goal Position range is the extended-position range; in position mode the
#: servo further limits it to [Min Position Limit, Max Position Limit].
XM540_W150 = ControlTable(
    "XM540-W150",
    MODEL_NUMBER,
    (
        _item("Model Number", 0, 2, False, MODEL_NUMBER, 0, 65535),
        _item("Model Information", 2, 4, False, 0, 0, 2**32 - 1),
        _item("Firmware Version", 6, 1, False, None, 0, 255),
        _item("ID", 7, 1, True, 1, 0, 252),
        _item("Baud Rate", 8, 1, True, 1, 0, 7),
        _item("Return Delay Time", 9, 1, True, 250, 0, 254, unit=2e-6),
        _item("Drive Mode", 10, 1, True, 0, 0, 13),
        _item("Operating Mode", 11, 1, True, 3, 0, 16),
        _item("Secondary ID", 12, 1, True, 255, 0, 255),
        _item("Protocol Type", 13, 1, True, 2, 1, 2),
        _item(
            "Homing Offset", 20, 4, True, 0, -1_044_479, 1_044_479, signed=True, unit=_PULSES_RAD
        ),
        _item("Moving Threshold", 24, 4, True, 10, 0, 1023, unit=VELOCITY_UNIT),
        _item("Temperature Limit", 31, 1, True, 80, 0, 100),
        _item("Max Voltage Limit", 32, 2, True, 160, 95, 160, unit=VOLTAGE_UNIT),
        _item("Min Voltage Limit", 34, 2, True, 95, 95, 160, unit=VOLTAGE_UNIT),
        _item("PWM Limit", 36, 2, True, 885, 0, 885),
        _item("Current Limit", 38, 2, True, 2047, 0, 2047, unit=CURRENT_UNIT),
        _item("Velocity Limit", 44, 4, True, 230, 0, 1023, unit=VELOCITY_UNIT),
        _item("Max Position Limit", 48, 4, True, 4095, 0, 4095, unit=_PULSES_RAD),
        _item("Min Position Limit", 52, 4, True, 0, 0, 4095, unit=_PULSES_RAD),
        _item("External Port Mode 1", 56, 1, True, 3, 0, 3),
        _item("External Port Mode 2", 57, 1, True, 3, 0, 3),
        _item("External Port Mode 3", 58, 1, True, 3, 0, 3),
        _item("Shutdown", 63, 1, True, 52, 0, 255),
        _item("Torque Enable", 64, 1, True, 0, 0, 1),
        _item("LED", 65, 1, True, 0, 0, 1),
        _item("Status Return Level", 68, 1, True, 2, 0, 2),
        _item("Registered Instruction", 69, 1, False, 0, 0, 1),
        _item("Hardware Error Status", 70, 1, False, 0, 0, 255),
        _item("Velocity I Gain", 76, 2, True, 1920, 0, 16383),
        _item("Velocity P Gain", 78, 2, True, 100, 0, 16383),
        _item("Position D Gain", 80, 2, True, 0, 0, 16383),
        _item("Position I Gain", 82, 2, True, 0, 0, 16383),
        _item("Position P Gain", 84, 2, True, 800, 0, 16383),
        _item("Feedforward 2nd Gain", 88, 2, True, 0, 0, 16383),
        _item("Feedforward 1st Gain", 90, 2, True, 0, 0, 16383),
        _item("Bus Watchdog", 98, 1, True, 0, 0, 127),
        _item("Goal PWM", 100, 2, True, 0, -885, 885, signed=True),
        _item("Goal Current", 102, 2, True, 0, -2047, 2047, signed=True, unit=CURRENT_UNIT),
        _item("Goal Velocity", 104, 4, True, 0, -1023, 1023, signed=True, unit=VELOCITY_UNIT),
        _item("Profile Acceleration", 108, 4, True, 0, 0, 32767, unit=ACCELERATION_UNIT),
        _item("Profile Velocity", 112, 4, True, 0, 0, 32767, unit=VELOCITY_UNIT),
        _item(
            "Goal Position",
            116,
            4,
            True,
            None,
            -EXTENDED_POSITION_LIMIT,
            EXTENDED_POSITION_LIMIT,
            signed=True,
            unit=_PULSES_RAD,
        ),
        _item("Realtime Tick", 120, 2, False, 0, 0, 32767),
        _item("Moving", 122, 1, False, 0, 0, 1),
        _item("Moving Status", 123, 1, False, 0, 0, 255),
        _item("Present PWM", 124, 2, False, 0, -885, 885, signed=True),
        _item("Present Current", 126, 2, False, 0, -2047, 2047, signed=True, unit=CURRENT_UNIT),
        _item("Present Velocity", 128, 4, False, 0, *_I32, signed=True, unit=VELOCITY_UNIT),
        _item("Present Position", 132, 4, False, None, *_I32, signed=True, unit=_PULSES_RAD),
        _item("Velocity Trajectory", 136, 4, False, 0, *_I32, signed=True, unit=VELOCITY_UNIT),
        _item("Position Trajectory", 140, 4, False, 0, *_I32, signed=True, unit=_PULSES_RAD),
        _item("Present Input Voltage", 144, 2, False, 120, 0, 65535, unit=VOLTAGE_UNIT),
        _item("Present Temperature", 146, 1, False, 30, 0, 255),
        _item("Backup Ready", 147, 1, False, 0, 0, 1),
    ),
)
