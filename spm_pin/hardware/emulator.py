"""An emulated bus of XM540-W150 servos speaking Protocol 2.0 (no I/O here).

:class:`ServoEmulator` takes the bytes a controller sends and returns the bytes the
servos would answer, with the timing of their Return Delay Time. It is what
:class:`~spm_pin.hardware.emulated_bus.EmulatedBus` serves on a pseudo-terminal, so
that the unmodified dynamixel-sdk talks to it as to a real bus.

What is emulated:

* Instructions PING, READ, WRITE, REG_WRITE, ACTION, FACTORY_RESET, REBOOT, CLEAR,
  SYNC_READ, SYNC_WRITE, FAST_SYNC_READ, BULK_READ, BULK_WRITE; CRC checks (a garbled
  packet addressed to one servo gets a CRC error), byte stuffing both ways (an
  instruction body with an unstuffed FF FF FD is dropped), status packets with the
  error byte, Status Return Level, Return Delay Time, the line's baud rate against
  each servo's Baud Rate item (a mismatch is noise: no reply).
* The control table's access rules (:mod:`.control_table`): read-only items, EEPROM
  writable only with torque off (access error), writes that cover items only in
  part (data length error), values out of range (data range error), Goal Position
  outside the position limits in position mode and goals beyond the current or
  velocity limit (data limit error); changing the Operating Mode zeroes the profile.
* Motion toward Goal Position with torque on: velocity ramps at Profile Acceleration
  up to Profile Velocity (0 = Velocity Limit) and brakes to stop on the goal; Present
  Position, Velocity, Current, Moving follow. After power-up or REBOOT the
  multi-turn count restarts within one turn and the goal equals the present position.
* Hardware errors: a condition whose bit is set in Shutdown latches Hardware Error
  Status, turns torque off, sets the alert bit of every status packet and blocks
  torque on (result fail) until REBOOT.
* Faults to inject: :meth:`ServoEmulator.silence` (status packets lost),
  :meth:`ServoEmulator.corrupt` (bad CRC, truncated, noise),
  :meth:`ServoEmulator.unplug` (a servo gone from the bus), :meth:`ServoEmulator.alert`.

Every instruction packet received is logged (:attr:`ServoEmulator.log`) with the
control-table writes it caused, so tests can prove what reached the servos.
Behaviour not confirmed on a real servo (e.g. the error code when torque on is
refused after a shutdown) follows the e-Manual's description as closely as it goes.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

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
    HardwareErrorFlag,
    to_signed,
)
from .protocol import (
    BROADCAST_ID,
    Instruction,
    Packet,
    PacketReader,
    ProtocolError,
    crc16,
    status_packet,
    stuff,
)

__all__ = [
    "DEFAULT_BAUDRATE",
    "DEFAULT_FIRMWARE",
    "EmulatedServo",
    "LogEntry",
    "Reply",
    "ServoEmulator",
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
#: Parameters of the CLEAR (multi-turn) instruction.
CLEAR_MULTI_TURN = bytes((0x01, 0x44, 0x58, 0x4C, 0x22))

_T = XM540_W150
_ERR_RESULT, _ERR_INSTRUCTION, _ERR_CRC, _ERR_RANGE, _ERR_LENGTH, _ERR_LIMIT, _ERR_ACCESS = range(
    1, 8
)
_POSITION_MODES = (3, 4, 5)


@dataclasses.dataclass(frozen=True)
class Reply:
    """Bytes the bus sends back, after ``delay`` seconds from the previous reply."""

    delay: float
    data: bytes


@dataclasses.dataclass(frozen=True)
class LogEntry:
    """One instruction packet as the bus received it.

    Attributes:
        seq: Running number.
        time: Emulator clock at reception [s].
        servo_id: The packet's ID (254 for broadcast), None if unparsable.
        instruction: Instruction name (``"SYNC_WRITE"``), or ``"?"``.
        accepted: The packet was valid (CRC, stuffing, baud rate).
        note: Why it was dropped, or errors returned.
        writes: Control-table writes it caused: ``(servo_id, address, data)``.
    """

    seq: int
    time: float
    servo_id: int | None
    instruction: str
    accepted: bool
    note: str = ""
    writes: tuple[tuple[int, int, bytes], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (data as hex)."""
        return {
            "seq": self.seq,
            "time": self.time,
            "servo_id": self.servo_id,
            "instruction": self.instruction,
            "accepted": self.accepted,
            "note": self.note,
            "writes": [[i, a, d.hex()] for i, a, d in self.writes],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LogEntry:
        """Inverse of :meth:`to_dict`."""
        return cls(
            seq=int(data["seq"]),
            time=float(data["time"]),
            servo_id=data["servo_id"],
            instruction=str(data["instruction"]),
            accepted=bool(data["accepted"]),
            note=str(data["note"]),
            writes=tuple((int(i), int(a), bytes.fromhex(d)) for i, a, d in data["writes"]),
        )


def _instruction_name(code: int) -> str:
    try:
        return Instruction(code).name
    except ValueError:
        return f"0x{code:02X}"


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
            return _ERR_ACCESS, b""
        return 0, bytes(self.memory[address : address + length])

    def check_write(self, address: int, data: bytes) -> tuple[int, list[tuple[ControlItem, int]]]:
        """Validate a WRITE: (error number, [(item, value)]); nothing is changed."""
        end = address + len(data)
        if not data or address < 0 or end > _T.size:
            return _ERR_ACCESS, []
        values: list[tuple[ControlItem, int]] = []
        touched = [item for item in _T.values() if item.address < end and item.end > address]
        if not touched:
            return _ERR_ACCESS, []
        for item in touched:
            if item.address < address or item.end > end:
                return _ERR_LENGTH, []
            if not item.writable:
                return _ERR_ACCESS, []
            if item.eeprom and self.torque:
                return _ERR_ACCESS, []
            raw = int.from_bytes(data[item.address - address : item.end - address], "little")
            value = to_signed(raw, item.size) if item.signed else raw
            if not item.minimum <= value <= item.maximum:
                return _ERR_RANGE, []
            values.append((item, value))
        error = self._check_values(values)
        return error, values if error == 0 else []

    def _check_values(self, values: list[tuple[ControlItem, int]]) -> int:
        new = {item.name: value for item, value in values}

        def current(name: str) -> int:
            return new[name] if name in new else self.get(name)

        if "Operating Mode" in new and new["Operating Mode"] not in OPERATING_MODES:
            return _ERR_RANGE
        if "Baud Rate" in new and new["Baud Rate"] not in BAUD_RATES:
            return _ERR_RANGE
        if "Goal Position" in new:
            goal = new["Goal Position"]
            if current("Operating Mode") == 3:
                low, high = current("Min Position Limit"), current("Max Position Limit")
                if not low <= goal <= high:
                    return _ERR_LIMIT
            elif abs(goal) > EXTENDED_POSITION_LIMIT:
                return _ERR_LIMIT
        if "Goal Current" in new and abs(new["Goal Current"]) > current("Current Limit"):
            return _ERR_LIMIT
        if "Goal Velocity" in new and abs(new["Goal Velocity"]) > current("Velocity Limit"):
            return _ERR_LIMIT
        if new.get("Torque Enable") == 1 and self.get("Hardware Error Status"):
            return _ERR_RESULT  # a latched shutdown: only REBOOT re-enables torque
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
            return _ERR_RESULT
        self.position = float(round(self.position) % PULSES_PER_TURN)
        self._store(_T["Goal Position"], round(self.position))
        self._refresh(now)
        return 0


class ServoEmulator:
    """A bus of emulated XM540-W150 servos: bytes in, timed replies out.

    Args:
        ids: Servo IDs on the bus.
        baudrate: Baud rate every servo expects [bit/s] (default: the factory
            default, 57600, as out of the box; pass 1_000_000 for the rate a 3-servo
            robot is usually set to). A controller at another rate gets no reply.
        firmware: Firmware Version of every servo (fast sync read needs >= 45).
        positions: Present Position of each servo at power-up [pulses, 0..4095]
            (default 2048, the middle of the turn).
        clock: Time source [s] (default :func:`time.monotonic`).
        log_size: Entries kept in :attr:`log`.
    """

    def __init__(
        self,
        ids: Iterable[int] = (1, 2, 3),
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        firmware: int = DEFAULT_FIRMWARE,
        positions: Mapping[int, int] | None = None,
        clock: Callable[[], float] = time.monotonic,
        log_size: int = 200_000,
    ) -> None:
        id_list = [int(i) for i in ids]
        if (
            not id_list
            or len(set(id_list)) != len(id_list)
            or not all(0 <= i <= 252 for i in id_list)
        ):
            raise InputError(
                f"ids must be distinct servo ids in 0..252, got {id_list}",
                argument="ids",
                value=ids,
            )
        self.clock = clock
        now = clock()
        positions = dict(positions or {})
        self.servos: dict[int, EmulatedServo] = {
            i: EmulatedServo(
                i, baudrate=baudrate, firmware=firmware, position=positions.get(i, 2048), now=now
            )
            for i in id_list
        }
        self.reader = PacketReader()
        self.log: collections.deque[LogEntry] = collections.deque(maxlen=log_size)
        self._seq = 0
        self._silence: dict[str, Any] | None = None
        self._corrupt: dict[str, Any] | None = None
        #: Counters: packets received, replies sent, replies dropped or corrupted.
        self.stats = collections.Counter[str]()

    # ---------------------------------------------------------------- faults
    def servo(self, servo_id: int) -> EmulatedServo:
        """The servo with this ID (InputError if none)."""
        for servo in self.servos.values():
            if servo.servo_id == servo_id:
                return servo
        raise InputError(
            f"no emulated servo has id {servo_id}; ids: {self.ids}", argument="id", value=servo_id
        )

    @property
    def ids(self) -> list[int]:
        """Current IDs of the servos (an ID write changes them)."""
        return sorted(servo.servo_id for servo in self.servos.values())

    def silence(self, count: int | None = None, ids: Iterable[int] | None = None) -> None:
        """Lose status packets: the next ``count`` (None: all until cleared) from ``ids``.

        The servos still act on what they receive; only their replies are lost.
        """
        self._silence = {"count": count, "ids": None if ids is None else set(ids)}

    def corrupt(
        self, count: int | None = 1, ids: Iterable[int] | None = None, kind: str = "crc"
    ) -> None:
        """Garble the next ``count`` status packets from ``ids`` (None: any servo).

        Args:
            count: Replies to garble (None: all until cleared).
            ids: Servos whose replies are garbled (None: all).
            kind: ``"crc"`` (last byte flipped), ``"truncate"`` (second half lost) or
                ``"noise"`` (a stray header and random bytes first).
        """
        if kind not in ("crc", "truncate", "noise"):
            raise InputError(
                f"kind must be 'crc', 'truncate' or 'noise', got {kind!r}",
                argument="kind",
                value=kind,
            )
        self._corrupt = {"count": count, "ids": None if ids is None else set(ids), "kind": kind}

    def clear_faults(self) -> None:
        """Stop silencing and garbling; plug every servo back in (errors stay latched)."""
        self._silence = self._corrupt = None
        now = self.clock()
        for servo in self.servos.values():
            if servo.unplugged:
                servo.unplugged = False
                servo.update(now)
                servo._power_up(now)

    def unplug(self, servo_id: int) -> None:
        """Take a servo off the bus: it neither acts nor answers."""
        self.servo(servo_id).unplugged = True

    def plug(self, servo_id: int) -> None:
        """Put a servo back: it powers up (RAM defaults, torque off, one turn)."""
        servo = self.servo(servo_id)
        if servo.unplugged:
            servo.unplugged = False
            servo._power_up(self.clock())

    def alert(self, servo_id: int, flags: int) -> int:
        """A hardware condition on a servo (see :meth:`EmulatedServo.alert`)."""
        servo = self.servo(servo_id)
        servo.update(self.clock())
        return servo.alert(int(HardwareErrorFlag(flags & 0x3D)))

    # ---------------------------------------------------------------- reception
    def receive(self, data: bytes, *, line_baudrate: int | None = None) -> list[Reply]:
        """Feed bytes from the controller; return the replies (in order, with delays).

        Args:
            data: Bytes as received.
            line_baudrate: Baud rate the controller set on the line [bit/s] (None: every
                servo hears it right).
        """
        self.reader.feed(data)
        replies: list[Reply] = []
        for raw, packet in self.reader.packets():
            replies.extend(self.handle(raw, packet, line_baudrate=line_baudrate))
        return replies

    def _log(
        self,
        servo_id: int | None,
        instruction: str,
        accepted: bool,
        note: str = "",
        writes: tuple[tuple[int, int, bytes], ...] = (),
    ) -> None:
        self._seq += 1
        self.log.append(
            LogEntry(self._seq, self.clock(), servo_id, instruction, accepted, note, writes)
        )

    def handle(
        self, raw: bytes, packet: Packet | ProtocolError, *, line_baudrate: int | None = None
    ) -> list[Reply]:
        """Act on one complete packet; return the replies."""
        now = self.clock()
        self.stats["packets"] += 1
        servo_id = raw[4] if len(raw) > 4 else None
        listening = [
            s
            for s in self.servos.values()
            if not s.unplugged
            and not s.booting(now)
            and (line_baudrate is None or s.baudrate == line_baudrate)
        ]
        if not listening:
            self._log(servo_id, "?", False, "no servo hears the line (baud rate or unplugged)")
            return []
        if isinstance(packet, ProtocolError):
            self._log(servo_id, "?", False, f"dropped: {packet}")
            target = self._find(listening, servo_id)
            if target is not None and "CRC" in str(packet):
                return self._status(target, _ERR_CRC, b"", level=0)
            return []
        name = _instruction_name(packet.instruction)
        handler = _HANDLERS.get(packet.instruction)
        if packet.instruction == Instruction.STATUS:
            self._log(servo_id, name, False, "a status packet on the bus (ignored)")
            return []
        for servo in listening:
            servo.update(now)
        if handler is None:
            self._log(servo_id, name, False, "unknown instruction")
            target = self._find(listening, packet.servo_id)
            return [] if target is None else self._status(target, _ERR_INSTRUCTION, b"", level=0)
        return handler(self, packet, listening, now)

    @staticmethod
    def _find(servos: list[EmulatedServo], servo_id: int | None) -> EmulatedServo | None:
        for servo in servos:
            if servo.servo_id == servo_id:
                return servo
        return None

    # ---------------------------------------------------------------- replies
    def _status(self, servo: EmulatedServo, error: int, data: bytes, *, level: int) -> list[Reply]:
        """A status packet if Status Return Level >= level, with faults applied."""
        if servo.get("Status Return Level") < level:
            return []
        packet = status_packet(servo.servo_id, error | servo.error_bit, data)
        delay = servo.get("Return Delay Time") * 2e-6
        return self._deliver(servo.servo_id, packet, delay)

    def _deliver(self, servo_id: int, packet: bytes, delay: float) -> list[Reply]:
        silence = self._silence
        if silence is not None and (silence["ids"] is None or servo_id in silence["ids"]):
            if silence["count"] is not None:
                silence["count"] -= 1
                if silence["count"] <= 0:
                    self._silence = None
            self.stats["silenced"] += 1
            return []
        corrupt = self._corrupt
        if corrupt is not None and (corrupt["ids"] is None or servo_id in corrupt["ids"]):
            if corrupt["count"] is not None:
                corrupt["count"] -= 1
                if corrupt["count"] <= 0:
                    self._corrupt = None
            self.stats["corrupted"] += 1
            packet = _garble(packet, corrupt["kind"])
        self.stats["replies"] += 1
        return [Reply(delay, packet)]

    # ---------------------------------------------------------------- instructions
    def _ping(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        self._log(packet.servo_id, "PING", True)
        targets = (
            servos
            if packet.servo_id == BROADCAST_ID
            else [s for s in servos if s.servo_id == packet.servo_id]
        )
        replies: list[Reply] = []
        for servo in sorted(targets, key=lambda s: s.servo_id):
            data = servo.get("Model Number").to_bytes(2, "little")
            data += bytes((servo.get("Firmware Version"),))
            replies += self._status(servo, 0, data, level=0)
        return replies

    def _unicast(self, packet: Packet, servos: list[EmulatedServo]) -> EmulatedServo | None:
        if packet.servo_id == BROADCAST_ID:
            return None
        return self._find(servos, packet.servo_id)

    def _read(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        servo = self._unicast(packet, servos)
        self._log(packet.servo_id, "READ", True)
        if servo is None:
            return []
        if len(packet.parameters) != 4:
            return self._status(servo, _ERR_LENGTH, b"", level=1)
        address, length = _word(packet.parameters, 0), _word(packet.parameters, 2)
        error, data = servo.read(address, length)
        return self._status(servo, error, data, level=1)

    def _write_common(
        self, packet: Packet, servos: list[EmulatedServo], now: float, *, register: bool
    ) -> list[Reply]:
        name = "REG_WRITE" if register else "WRITE"
        servo = self._unicast(packet, servos)
        targets = servos if packet.servo_id == BROADCAST_ID else [] if servo is None else [servo]
        params = packet.parameters
        if len(params) < 3:
            self._log(packet.servo_id, name, True, "data length error")
            return [] if servo is None else self._status(servo, _ERR_LENGTH, b"", level=2)
        address, data = _word(params, 0), bytes(params[2:])
        writes: list[tuple[int, int, bytes]] = []
        errors: list[str] = []
        error = 0
        for target in targets:
            if register:
                error, _ = target.check_write(address, data)
                if not error:
                    target.registered = (address, data)
                    target._store(_T["Registered Instruction"], 1)
            else:
                error = target.write(address, data, now)
                if not error:
                    writes.append((target.servo_id, address, data))
            if error:
                errors.append(f"id {target.servo_id}: error {error}")
        self._log(packet.servo_id, name, True, "; ".join(errors), tuple(writes))
        return [] if servo is None else self._status(servo, error, b"", level=2)

    def _write(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        return self._write_common(packet, servos, now, register=False)

    def _reg_write(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        return self._write_common(packet, servos, now, register=True)

    def _action(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        servo = self._unicast(packet, servos)
        targets = servos if packet.servo_id == BROADCAST_ID else [] if servo is None else [servo]
        writes: list[tuple[int, int, bytes]] = []
        error = 0
        for target in targets:
            if target.registered is None:
                error = _ERR_INSTRUCTION
                continue
            address, data = target.registered
            target.registered = None
            target._store(_T["Registered Instruction"], 0)
            error = target.write(address, data, now)
            if not error:
                writes.append((target.servo_id, address, data))
        self._log(packet.servo_id, "ACTION", True, "", tuple(writes))
        return [] if servo is None else self._status(servo, error, b"", level=2)

    def _reboot(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        servo = self._unicast(packet, servos)
        self._log(packet.servo_id, "REBOOT", True)
        targets = servos if packet.servo_id == BROADCAST_ID else [] if servo is None else [servo]
        replies = [] if servo is None else self._status(servo, 0, b"", level=2)
        for target in targets:
            target.reboot(now)
        return replies

    def _factory_reset(
        self, packet: Packet, servos: list[EmulatedServo], now: float
    ) -> list[Reply]:
        servo = self._unicast(packet, servos)
        self._log(packet.servo_id, "FACTORY_RESET", True)
        if servo is None:  # broadcast factory reset is refused by real servos too
            return []
        option = packet.parameters[0] if packet.parameters else 0xFF
        if option not in (0x01, 0x02, 0xFF):
            return self._status(servo, _ERR_RANGE, b"", level=2)
        replies = self._status(servo, 0, b"", level=2)
        servo.factory_reset(option, now)
        return replies

    def _clear(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        servo = self._unicast(packet, servos)
        self._log(packet.servo_id, "CLEAR", True)
        targets = servos if packet.servo_id == BROADCAST_ID else [] if servo is None else [servo]
        error = 0
        for target in targets:
            if bytes(packet.parameters) != CLEAR_MULTI_TURN:
                error = _ERR_RANGE
            else:
                error = target.clear_multi_turn(now)
        return [] if servo is None else self._status(servo, error, b"", level=2)

    def _sync_read(
        self, packet: Packet, servos: list[EmulatedServo], now: float, *, fast: bool = False
    ) -> list[Reply]:
        name = "FAST_SYNC_READ" if fast else "SYNC_READ"
        params = packet.parameters
        if packet.servo_id != BROADCAST_ID or len(params) < 5:
            self._log(packet.servo_id, name, False, "not a broadcast with ids")
            return []
        address, length = _word(params, 0), _word(params, 2)
        ids = list(params[4:])
        self._log(packet.servo_id, name, True)
        if fast:
            return self._fast_reply(ids, address, length, servos)
        replies: list[Reply] = []
        for servo_id in ids:
            servo = self._find(servos, servo_id)
            if servo is None:
                continue
            error, data = servo.read(address, length)
            replies += self._status(servo, error, data, level=1)
        return replies

    def _fast_sync_read(
        self, packet: Packet, servos: list[EmulatedServo], now: float
    ) -> list[Reply]:
        return self._sync_read(packet, servos, now, fast=True)

    def _fast_reply(
        self, ids: list[int], address: int, length: int, servos: list[EmulatedServo]
    ) -> list[Reply]:
        """One packet from id 0xFE: [error, id, data, CRC] per servo, in id-list order.

        Each servo's CRC field is the running CRC of the packet so far; the last one is
        the packet's CRC. A servo missing from the chain ends the reply there.
        """
        segments: list[bytes] = []
        delay = 0.0
        complete = True
        for index, servo_id in enumerate(ids):
            servo = self._find(servos, servo_id)
            if servo is None or servo.get("Status Return Level") < 1:
                complete = False
                break
            if index == 0:
                delay = servo.get("Return Delay Time") * 2e-6
            error, data = servo.read(address, length)
            if error:
                data = bytes(length)
            segments.append(bytes((error | servo.error_bit, servo.servo_id)) + data)
        if not segments:
            return []
        # LEN covers the stuffed body, whose stuffing depends on the running CRCs, which
        # cover LEN: iterate until LEN is consistent (one or two rounds).
        length_field = 1 + len(ids) * (length + 4)
        for _ in range(8):
            head = bytes(
                (0xFF, 0xFF, 0xFD, 0x00, BROADCAST_ID, length_field & 0xFF, length_field >> 8)
            )
            plain = bytearray((Instruction.STATUS,))
            for k, segment in enumerate(segments):
                plain += segment
                if k < len(segments) - 1:
                    crc = crc16(head + stuff(bytes(plain)))
                    plain += bytes((crc & 0xFF, crc >> 8))
            body = stuff(bytes(plain))
            if not complete or len(body) + 2 == length_field:
                break
            length_field = len(body) + 2
        packet = head + body
        if complete:
            crc = crc16(packet)
            packet += bytes((crc & 0xFF, crc >> 8))
            return self._deliver(ids[0], packet, delay)
        self.stats["replies"] += 1
        return [Reply(delay, packet)]  # a broken chain: the rest never comes

    def _sync_write(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        params = packet.parameters
        if packet.servo_id != BROADCAST_ID or len(params) < 4:
            self._log(packet.servo_id, "SYNC_WRITE", False, "not a broadcast")
            return []
        address, length = _word(params, 0), _word(params, 2)
        records = params[4:]
        if length == 0 or len(records) % (length + 1):
            self._log(packet.servo_id, "SYNC_WRITE", False, "data length error")
            return []
        requests = [
            (records[start], address, bytes(records[start + 1 : start + 1 + length]))
            for start in range(0, len(records), length + 1)
        ]
        self._log(packet.servo_id, "SYNC_WRITE", True, *self._write_each(servos, requests, now))
        return []

    def _bulk_read(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        params = packet.parameters
        if packet.servo_id != BROADCAST_ID or not params or len(params) % 5:
            self._log(packet.servo_id, "BULK_READ", False, "bad parameters")
            return []
        self._log(packet.servo_id, "BULK_READ", True)
        replies: list[Reply] = []
        for start in range(0, len(params), 5):
            servo = self._find(servos, params[start])
            if servo is None:
                continue
            error, data = servo.read(_word(params, start + 1), _word(params, start + 3))
            replies += self._status(servo, error, data, level=1)
        return replies

    def _bulk_write(self, packet: Packet, servos: list[EmulatedServo], now: float) -> list[Reply]:
        params = packet.parameters
        requests: list[tuple[int, int, bytes]] = []
        start = 0
        while start + 5 <= len(params):
            servo_id, address = params[start], _word(params, start + 1)
            length = _word(params, start + 3)
            data = bytes(params[start + 5 : start + 5 + length])
            start += 5 + length
            if len(data) == length:
                requests.append((servo_id, address, data))
        self._log(packet.servo_id, "BULK_WRITE", True, *self._write_each(servos, requests, now))
        return []

    def _write_each(
        self, servos: list[EmulatedServo], requests: list[tuple[int, int, bytes]], now: float
    ) -> tuple[str, tuple[tuple[int, int, bytes], ...]]:
        """Apply (id, address, data) writes to the servos present: (errors, done) to log."""
        writes: list[tuple[int, int, bytes]] = []
        errors: list[str] = []
        for servo_id, address, data in requests:
            servo = self._find(servos, servo_id)
            if servo is None:
                continue
            error = servo.write(address, data, now)
            if error:
                errors.append(f"id {servo_id}: error {error}")
            else:
                writes.append((servo_id, address, data))
        return "; ".join(errors), tuple(writes)


def _word(data: bytes, index: int) -> int:
    return int(data[index] | data[index + 1] << 8)


def _garble(packet: bytes, kind: str) -> bytes:
    if kind == "crc":
        return packet[:-1] + bytes((packet[-1] ^ 0xFF,))
    if kind == "truncate":
        return packet[: len(packet) // 2]
    return b"\xff\xff\xfd\x00\x07\x55" + packet  # a stray header, then the packet


_Handler = Callable[[ServoEmulator, Packet, list[EmulatedServo], float], list[Reply]]
_HANDLERS: dict[int, _Handler] = {
    Instruction.PING: ServoEmulator._ping,
    Instruction.READ: ServoEmulator._read,
    Instruction.WRITE: ServoEmulator._write,
    Instruction.REG_WRITE: ServoEmulator._reg_write,
    Instruction.ACTION: ServoEmulator._action,
    Instruction.FACTORY_RESET: ServoEmulator._factory_reset,
    Instruction.REBOOT: ServoEmulator._reboot,
    Instruction.CLEAR: ServoEmulator._clear,
    Instruction.SYNC_READ: ServoEmulator._sync_read,
    Instruction.FAST_SYNC_READ: ServoEmulator._fast_sync_read,
    Instruction.SYNC_WRITE: ServoEmulator._sync_write,
    Instruction.BULK_READ: ServoEmulator._bulk_read,
    Instruction.BULK_WRITE: ServoEmulator._bulk_write,
}
