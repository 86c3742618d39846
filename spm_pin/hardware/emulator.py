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
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from ..errors import InputError
from ._emulated_servo import BOOT_TIME as BOOT_TIME
from ._emulated_servo import (
    DEFAULT_BAUDRATE,
    DEFAULT_FIRMWARE,
    ERR_CRC,
    ERR_INSTRUCTION,
    ERR_LENGTH,
    ERR_RANGE,
    EmulatedServo,
)
from ._emulated_servo import FRICTION_CURRENT as FRICTION_CURRENT
from ._emulated_servo import INERTIA_CURRENT as INERTIA_CURRENT
from ._emulated_servo import MOTION_STEP as MOTION_STEP
from ._emulated_servo import NO_LOAD_SPEED as NO_LOAD_SPEED
from .control_table import XM540_W150, HardwareErrorFlag
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

#: Parameters of the CLEAR (multi-turn) instruction.
CLEAR_MULTI_TURN = bytes((0x01, 0x44, 0x58, 0x4C, 0x22))

_T = XM540_W150


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
                return self._status(target, ERR_CRC, b"", level=0)
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
            return [] if target is None else self._status(target, ERR_INSTRUCTION, b"", level=0)
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
            return self._status(servo, ERR_LENGTH, b"", level=1)
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
            return [] if servo is None else self._status(servo, ERR_LENGTH, b"", level=2)
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
                error = ERR_INSTRUCTION
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
            return self._status(servo, ERR_RANGE, b"", level=2)
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
                error = ERR_RANGE
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
