r"""Dynamixel Protocol 2.0 packets: CRC-16, byte stuffing, instruction and status packets.

Packet layout (LEN counts the bytes after itself: instruction, parameters and CRC)::

    FF FF FD 00 | ID | LEN_L LEN_H | INST | parameters ... | CRC_L CRC_H

A status packet has INST = 0x55 and an error byte as its first parameter. Inside the
body (from INST to the last parameter) the sequence FF FF FD is followed by an extra
FD ("byte stuffing"), so that a header cannot appear inside a packet; LEN and the CRC
cover the stuffed bytes. The CRC is CRC-16/BUYPASS: polynomial 0x8005, initial value
0, no reflection (the check value of ``b"123456789"`` is 0xFEE8).

This module is used by the emulated bus to speak the protocol, and by the driver to
destuff the status packets that dynamixel-sdk 4.1 receives without destuffing or
destuffs wrongly.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Iterable

__all__ = [
    "BROADCAST_ID",
    "HEADER",
    "MAX_ID",
    "Instruction",
    "Packet",
    "PacketReader",
    "ProtocolError",
    "crc16",
    "has_unstuffed_header",
    "instruction_packet",
    "parse_packet",
    "status_packet",
    "stuff",
    "unstuff",
]

#: Packet header with the reserved byte.
HEADER = b"\xff\xff\xfd\x00"
#: The id every servo listens to (and that fast sync read replies carry).
BROADCAST_ID = 0xFE
#: Largest servo id.
MAX_ID = 252
#: Largest LEN accepted when parsing.
MAX_LENGTH = 1024


class Instruction(enum.IntEnum):
    """Protocol 2.0 instruction codes."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class ProtocolError(ValueError):
    """A byte string is not a valid Protocol 2.0 packet (internal to the emulator)."""


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray | Iterable[int], crc: int = 0) -> int:
    """CRC-16/BUYPASS of ``data`` (continuing from ``crc``)."""
    table = _CRC_TABLE
    for byte in data:
        crc = ((crc << 8) ^ table[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes | bytearray) -> bytes:
    """Insert FD after every FF FF FD of a packet body (instruction and parameters)."""
    out = bytearray()
    for index, byte in enumerate(body):
        out.append(byte)
        if byte == 0xFD and index >= 2 and body[index - 1] == 0xFF and body[index - 2] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes | bytearray) -> bytes:
    """Remove the FD inserted after every FF FF FD (inverse of :func:`stuff`).

    Raises:
        ProtocolError: FF FF FD followed by anything but FD (an unstuffed header
            inside the body).
    """
    out = bytearray()
    index = 0
    length = len(body)
    while index < length:
        byte = body[index]
        out.append(byte)
        # The stuffing rule looks at the destuffed stream: FF FF FD there is stuffed.
        if byte == 0xFD and len(out) >= 3 and out[-2] == 0xFF and out[-3] == 0xFF:
            if index + 1 >= length or body[index + 1] != 0xFD:
                raise ProtocolError("FF FF FD inside a packet body is not followed by FD")
            index += 1  # skip the stuffing byte
        index += 1
    return bytes(out)


def has_unstuffed_header(body: bytes | bytearray) -> bool:
    """True if ``body`` (destuffed) contains FF FF FD, i.e. would need stuffing."""
    return b"\xff\xff\xfd" in bytes(body)


def _frame(servo_id: int, body: bytes) -> bytes:
    stuffed = stuff(body)
    length = len(stuffed) + 2
    head = HEADER + bytes((servo_id, length & 0xFF, length >> 8))
    packet = head + stuffed
    crc = crc16(packet)
    return packet + bytes((crc & 0xFF, crc >> 8))


def instruction_packet(servo_id: int, instruction: int, parameters: bytes = b"") -> bytes:
    """A complete, stuffed instruction packet."""
    return _frame(servo_id, bytes((instruction,)) + bytes(parameters))


def status_packet(servo_id: int, error: int, parameters: bytes = b"") -> bytes:
    """A complete, stuffed status packet (INST 0x55, error byte, parameters)."""
    return _frame(servo_id, bytes((Instruction.STATUS, error)) + bytes(parameters))


@dataclasses.dataclass(frozen=True)
class Packet:
    """A parsed packet.

    Attributes:
        servo_id: The ID byte.
        instruction: The INST byte (0x55 for a status packet).
        parameters: The destuffed parameters (for a status packet: error byte first).
        raw: The packet as it was on the wire.
    """

    servo_id: int
    instruction: int
    parameters: bytes
    raw: bytes


def parse_packet(raw: bytes | bytearray) -> Packet:
    """Parse one complete packet (header to CRC), checking LEN and CRC, destuffing.

    Raises:
        ProtocolError: bad header, length, CRC or stuffing.
    """
    raw = bytes(raw)
    if len(raw) < 10 or raw[:4] != HEADER:
        raise ProtocolError("not a Protocol 2.0 packet (header FF FF FD 00)")
    length = raw[5] | raw[6] << 8
    if length < 3 or len(raw) != 7 + length:
        raise ProtocolError(f"LEN {length} does not match the packet size {len(raw)}")
    crc = raw[-2] | raw[-1] << 8
    if crc16(raw[:-2]) != crc:
        raise ProtocolError("CRC mismatch")
    body = unstuff(raw[7:-2])
    return Packet(raw[4], body[0], body[1:], raw)


class PacketReader:
    """Split a byte stream into packets (resynchronising on garbage).

    Feed bytes with :meth:`feed`; :meth:`packets` yields ``(raw, packet_or_error)``
    for every complete packet: the parsed :class:`Packet`, or the
    :class:`ProtocolError` of a packet that arrived whole but is invalid (bad CRC
    or stuffing), so that a servo can answer with a CRC error.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> None:
        """Append received bytes."""
        self._buffer.extend(data)

    def clear(self) -> None:
        """Drop everything buffered."""
        self._buffer.clear()

    @property
    def pending(self) -> int:
        """Bytes buffered but not yet part of a complete packet."""
        return len(self._buffer)

    def packets(self) -> list[tuple[bytes, Packet | ProtocolError]]:
        """Complete packets found so far (removed from the buffer)."""
        found: list[tuple[bytes, Packet | ProtocolError]] = []
        buffer = self._buffer
        while True:
            start = buffer.find(HEADER)
            if start < 0:
                # Keep a possible partial header at the end.
                keep = next((n for n in (3, 2, 1) if buffer.endswith(HEADER[:n])), 0)
                del buffer[: len(buffer) - keep]
                return found
            del buffer[:start]
            if len(buffer) < 7:
                return found
            length = buffer[5] | buffer[6] << 8
            if length < 3 or length > MAX_LENGTH:
                del buffer[:1]  # not a real header: resynchronise
                continue
            if len(buffer) < 7 + length:
                return found
            raw = bytes(buffer[: 7 + length])
            del buffer[: 7 + length]
            try:
                found.append((raw, parse_packet(raw)))
            except ProtocolError as exc:
                found.append((raw, exc))
