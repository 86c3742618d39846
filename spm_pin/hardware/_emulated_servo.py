"""One emulated XM540-W150 servo: its control table, access rules, motion and faults.

:class:`EmulatedServo` holds the control-table memory of one servo and applies what
an instruction does to it: reads of any byte range, writes checked against the
table's access rules and limits (each refusal is a status packet error number,
``ERR_*``), the motion toward Goal Position, REBOOT and FACTORY_RESET, and latched
hardware errors. It knows nothing about packets or the bus:
:class:`~spm_pin.hardware.emulator.ServoEmulator` parses the instructions and calls it.
"""

from __future__ import annotations

import math

from ..errors import InputError
from .control_table import (
    ACCELERATION_UNIT,
    BAUD_RATES,
    EEPROM_END,
    EXTENDED_POSITION_LIMIT,
    OPERATING_MODES,
    POSITION_UNIT,
    PULSES_PER_TURN,
    VELOCITY_UNIT,
    XM540_W150,
    ControlItem,
    to_signed,
)

__all__ = [
    "BOOT_TIME",
    "DEFAULT_BAUDRATE",
    "DEFAULT_FIRMWARE",
    "ERR_ACCESS",
    "ERR_CRC",
    "ERR_INSTRUCTION",
    "ERR_LENGTH",
    "ERR_LIMIT",
    "ERR_RANGE",
    "ERR_RESULT",
    "FRICTION_CURRENT",
    "INERTIA_CURRENT",
    "MOTION_STEP",
    "NO_LOAD_SPEED",
    "EmulatedServo",
]

#: Firmware version reported by emulated servos (fast sync read needs >= 45).
DEFAULT_FIRMWARE = 46
#: Line rate of an emulated servo unless asked otherwise [bit/s]: the XM540-W150's
#: factory default (Baud Rate item 1), the rate a servo out of the box answers at.
DEFAULT_BAUDRATE = BAUD_RATES[XM540_W150["Baud Rate"].default or 0]
#: Time a servo stays silent after REBOOT or FACTORY_RESET [s].
BOOT_TIME = 0.05
#: Integration step of the motion [s].
MOTION_STEP = 1e-3
#: No-load speed at 12 V [rad/s] (53 rev/min): the motor cannot go faster.
NO_LOAD_SPEED = 53.0 * 2.0 * math.pi / 60.0
#: Friction current while moving [A] and current per acceleration [A per rad/s^2].
FRICTION_CURRENT = 0.12
INERTIA_CURRENT = 0.02
#: Error numbers of a status packet: result fail, instruction, CRC, data range, data
#: length, data limit, access.
ERR_RESULT, ERR_INSTRUCTION, ERR_CRC, ERR_RANGE, ERR_LENGTH, ERR_LIMIT, ERR_ACCESS = range(1, 8)

_T = XM540_W150
_POSITION_MODES = (3, 4, 5)


class EmulatedServo:
    """One emulated XM540-W150: control-table memory, access rules and motion.

    Args:
        servo_id: ID (1..252).
        baudrate: Line rate the servo expects [bit/s], one of the Baud Rate values
            (default: the factory default, 57600).
        firmware: Firmware Version item.
        position: Present Position at power-up [pulses], in [0, 4096).
        now: Clock at power-up [s].
    """

    def __init__(
        self,
        servo_id: int,
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        firmware: int = DEFAULT_FIRMWARE,
        position: int = 2048,
        now: float = 0.0,
    ) -> None:
        codes = {rate: code for code, rate in BAUD_RATES.items()}
        if baudrate not in codes:
            raise InputError(
                f"baudrate must be one of {sorted(codes)}, got {baudrate!r}",
                argument="baudrate",
                value=baudrate,
            )
        self.memory = bytearray(_T.size)
        for item in _T.values():
            if item.default is not None:
                self._store(item, item.default)
        self._store(_T["ID"], servo_id)
        self._store(_T["Baud Rate"], codes[baudrate])
        self._store(_T["Firmware Version"], firmware)
        self.position = float(position % PULSES_PER_TURN)
        self.velocity = 0.0  # [pulses/s]
        self.acceleration = 0.0  # [pulses/s^2]
        self.unplugged = False
        #: While True the Present items keep what was set (readings held, for tests).
        self.frozen = False
        self.booting_until = -math.inf
        self.registered: tuple[int, bytes] | None = None
        self.boot_time = now
        self.last_update = now
        self._power_up(now)

    # ---------------------------------------------------------------- memory
    def get(self, name: str) -> int:
        """Value of an item (signed where the item is)."""
        item = _T[name]
        return item.decode(self.memory[item.address : item.end])

    def _store(self, item: ControlItem, value: int) -> None:
        raw = value & ((1 << (8 * item.size)) - 1)
        self.memory[item.address : item.end] = raw.to_bytes(item.size, "little")

    def set(self, name: str, value: int) -> None:
        """Set an item directly, bypassing access rules (for fault injection).

        Setting Present Position also moves the emulated shaft there.
        """
        item = _T[name]
        self._store(item, item.check(value))
        if name == "Present Position":
            self.position = float(value)
            self.velocity = 0.0

    @property
    def servo_id(self) -> int:
        """The ID item."""
        return self.get("ID")

    @property
    def baudrate(self) -> int:
        """Line rate the servo expects [bit/s]."""
        return BAUD_RATES[self.get("Baud Rate")]

    @property
    def torque(self) -> bool:
        """Torque Enable."""
        return bool(self.get("Torque Enable"))

    # ---------------------------------------------------------------- power
    def _power_up(self, now: float) -> None:
        """RAM back to defaults; the multi-turn count restarts within one turn."""
        for item in _T.values():
            if item.address >= EEPROM_END and item.default is not None:
                self._store(item, item.default)
        self.position = float(math.floor(self.position) % PULSES_PER_TURN)
        self.velocity = 0.0
        self.acceleration = 0.0
        self.registered = None
        present = round(self.position)
        self._store(_T["Present Position"], present)
        self._store(_T["Goal Position"], present)
        self._store(_T["Position Trajectory"], present)
        self.boot_time = now
        self.last_update = now

    def reboot(self, now: float) -> None:
        """REBOOT: silent for :data:`BOOT_TIME`, then powered up again (errors cleared)."""
        self.booting_until = now + BOOT_TIME
        self._power_up(now)

    def factory_reset(self, option: int, now: float) -> None:
        """FACTORY_RESET: EEPROM defaults (0xFF: all, 0x01: keep ID, 0x02: keep ID, baud)."""
        keep = {"ID", "Baud Rate"} if option == 0x02 else {"ID"} if option == 0x01 else set()
        for item in _T.values():
            eeprom = item.address < EEPROM_END and item.writable and item.name not in keep
            if eeprom and item.default is not None:
                self._store(item, item.default)
        self.reboot(now)

    def booting(self, now: float) -> bool:
        """True while the servo restarts after REBOOT (it answers nothing)."""
        return now < self.booting_until

    # ---------------------------------------------------------------- faults
    def alert(self, flags: int) -> int:
        """A hardware condition: latch the bits enabled in Shutdown and drop torque.

        Returns:
            The bits latched (those of ``flags`` that Shutdown enables).
        """
        latched = flags & self.get("Shutdown") & 0xFF
        if latched:
            self._store(_T["Hardware Error Status"], self.get("Hardware Error Status") | latched)
            self._store(_T["Torque Enable"], 0)
        return latched

    @property
    def error_bit(self) -> int:
        """The alert bit (0x80) of status packets while a hardware error is latched."""
        return 0x80 if self.get("Hardware Error Status") else 0

    # ---------------------------------------------------------------- motion
    def _limits(self) -> tuple[float, float]:
        """Speed [pulses/s] and acceleration [pulses/s^2] of the motion profile."""
        to_pulses = 1.0 / POSITION_UNIT
        limit = self.get("Velocity Limit")
        profile = self.get("Profile Velocity")
        units = limit if profile == 0 or profile > limit else profile
        speed = min(units * VELOCITY_UNIT, NO_LOAD_SPEED) * to_pulses
        accel_units = self.get("Profile Acceleration")
        accel = accel_units * ACCELERATION_UNIT * to_pulses if accel_units else math.inf
        return speed, accel

    def update(self, now: float) -> None:
        """Advance the motion to ``now`` and refresh the Present items."""
        dt = now - self.last_update
        if dt <= 0.0 or self.frozen:
            self.last_update = max(self.last_update, now)
            return
        self.last_update = now
        moving_modes = self.get("Operating Mode") in _POSITION_MODES
        if self.torque and moving_modes:
            goal = float(self.get("Goal Position"))
            speed, accel = self._limits()
            steps = max(1, min(math.ceil(dt / MOTION_STEP), 5000))
            h = dt / steps
            for _ in range(steps):
                self._step(goal, speed, accel, h)
        else:
            self.velocity = 0.0
            self.acceleration = 0.0
        self._refresh(now)

    def _step(self, goal: float, speed: float, accel: float, h: float) -> None:
        distance = goal - self.position
        if distance == 0.0 and self.velocity == 0.0:
            self.acceleration = 0.0
            return
        brake = math.sqrt(2.0 * accel * abs(distance)) if math.isfinite(accel) else math.inf
        wanted = math.copysign(min(speed, brake), distance)
        change = wanted - self.velocity
        if math.isfinite(accel):
            change = max(-accel * h, min(accel * h, change))
        new_velocity = self.velocity + change
        self.acceleration = change / h
        step = 0.5 * (self.velocity + new_velocity) * h
        if abs(step) >= abs(distance) or (distance != 0 and (distance - step) * distance < 0):
            self.position = goal
            self.velocity = 0.0
        else:
            self.position += step
            self.velocity = new_velocity

    def _refresh(self, now: float) -> None:
        velocity_units = round(self.velocity * POSITION_UNIT / VELOCITY_UNIT)
        rad_s2 = self.acceleration * POSITION_UNIT
        current = 0.0
        if self.torque:
            current = FRICTION_CURRENT * (1 if self.velocity > 0 else -1 if self.velocity else 0)
            current += INERTIA_CURRENT * rad_s2
        limit = self.get("Current Limit")
        current_units = max(-limit, min(limit, round(current / 2.69e-3)))
        present = round(self.position)
        goal = self.get("Goal Position")
        self._store(_T["Present Position"], present)
        self._store(_T["Position Trajectory"], present)
        self._store(_T["Present Velocity"], velocity_units)
        self._store(_T["Velocity Trajectory"], velocity_units)
        self._store(_T["Present Current"], current_units)
        moving = abs(velocity_units) > self.get("Moving Threshold")
        self._store(_T["Moving"], int(moving))
        in_position = self.torque and abs(goal - present) <= 1 and not moving
        self._store(_T["Moving Status"], int(in_position) | (0x02 if self.velocity else 0))
        tick = int((now - self.boot_time) * 1000.0) % 32768
        self._store(_T["Realtime Tick"], tick)

    # ---------------------------------------------------------------- access
    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """READ: (error number, data). Any byte range inside the table may be read."""
        if length < 1 or address < 0 or address + length > _T.size:
            return ERR_ACCESS, b""
        return 0, bytes(self.memory[address : address + length])

    def check_write(self, address: int, data: bytes) -> tuple[int, list[tuple[ControlItem, int]]]:
        """Validate a WRITE: (error number, [(item, value)]); nothing is changed."""
        end = address + len(data)
        if not data or address < 0 or end > _T.size:
            return ERR_ACCESS, []
        values: list[tuple[ControlItem, int]] = []
        touched = [item for item in _T.values() if item.address < end and item.end > address]
        if not touched:
            return ERR_ACCESS, []
        for item in touched:
            if item.address < address or item.end > end:
                return ERR_LENGTH, []
            if not item.writable:
                return ERR_ACCESS, []
            if item.eeprom and self.torque:
                return ERR_ACCESS, []
            raw = int.from_bytes(data[item.address - address : item.end - address], "little")
            value = to_signed(raw, item.size) if item.signed else raw
            if not item.minimum <= value <= item.maximum:
                return ERR_RANGE, []
            values.append((item, value))
        error = self._check_values(values)
        return error, values if error == 0 else []

    def _check_values(self, values: list[tuple[ControlItem, int]]) -> int:
        new = {item.name: value for item, value in values}

        def current(name: str) -> int:
            return new[name] if name in new else self.get(name)

        if "Operating Mode" in new and new["Operating Mode"] not in OPERATING_MODES:
            return ERR_RANGE
        if "Baud Rate" in new and new["Baud Rate"] not in BAUD_RATES:
            return ERR_RANGE
        if "Goal Position" in new:
            goal = new["Goal Position"]
            if current("Operating Mode") == 3:
                low, high = current("Min Position Limit"), current("Max Position Limit")
                if not low <= goal <= high:
                    return ERR_LIMIT
            elif abs(goal) > EXTENDED_POSITION_LIMIT:
                return ERR_LIMIT
        if "Goal Current" in new and abs(new["Goal Current"]) > current("Current Limit"):
            return ERR_LIMIT
        if "Goal Velocity" in new and abs(new["Goal Velocity"]) > current("Velocity Limit"):
            return ERR_LIMIT
        if new.get("Torque Enable") == 1 and self.get("Hardware Error Status"):
            return ERR_RESULT  # a latched shutdown: only REBOOT re-enables torque
        return 0

    def write(self, address: int, data: bytes, now: float) -> int:
        """WRITE with the access rules; returns the error number (0: done)."""
        self.update(now)
        error, values = self.check_write(address, data)
        if error:
            return error
        for item, value in values:
            self._apply(item, value)
        return 0

    def _apply(self, item: ControlItem, value: int) -> None:
        if item.name == "Operating Mode" and value != self.get("Operating Mode"):
            self._store(_T["Profile Velocity"], 0)
            self._store(_T["Profile Acceleration"], 0)
        if item.name == "Torque Enable" and value == 0:
            self.velocity = 0.0
        self._store(item, value)

    def clear_multi_turn(self, now: float) -> int:
        """CLEAR: Present Position back within one turn (only while not moving)."""
        self.update(now)
        if self.velocity:
            return ERR_RESULT
        self.position = float(round(self.position) % PULSES_PER_TURN)
        self._store(_T["Goal Position"], round(self.position))
        self._refresh(now)
        return 0
