"""Constants and helpers of the hardware tests (the fixtures are in ``_hardware``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from spm_pin.hardware import XM540_W150, HardwareConfig, SafetyLimits
from spm_pin.hardware.driver import ServoSettings
from spm_pin.hardware.emulated_bus import LATENCY_TIMER_MS
from spm_pin.hardware.emulator import DEFAULT_BAUDRATE

#: Latency allowed for in the packet timeout [ms]: a silent servo costs 2 x this + 2 ms
#: + the wire time per attempt. The emulator is a process: on a loaded machine its
#: replies come tens of ms late (10 ms here made 1 transaction in 70 time out).
LATENCY_MS = LATENCY_TIMER_MS
#: Line rate of the session's emulated bus [bit/s]: the emulator's default, the
#: XM540-W150's factory default (57600). Every client of that bus opens it at this rate.
BAUD = DEFAULT_BAUDRATE
IDS = (1, 2, 3)


def packet_timeout_s(reply_bytes: int, baudrate: int = BAUD) -> float:
    """The driver's packet timeout for a reply of ``reply_bytes`` [s], restated here.

    The wire time of ``reply_bytes`` at ``baudrate`` (10 bits a byte) + 2 x LATENCY_MS
    + 2 ms: dynamixel-sdk's ``setPacketTimeout`` with the latency ServoBus was given.
    The SDK asks for 11 bytes after a PING or a write and (11 + data bytes) x servos
    after a (fast) sync read.
    """
    wire_ms = reply_bytes * 10_000.0 / baudrate
    return (wire_ms + 2.0 * LATENCY_MS + 2.0) / 1000.0


#: Tolerances of the hardware tests.
TOL = {
    "pulse": np.radians(360.0 / 4096.0),  # one encoder pulse [rad]
    "reached": np.radians(0.5),  # end of a move [rad]
    "model": 1e-9,  # model quantities recomputed independently
}


def fast_config(port: str, **safety: Any) -> HardwareConfig:
    """A configuration for quick moves on the emulated bus (faster than the default)."""
    limits = SafetyLimits(**{"max_speed": 3.0, "max_acceleration": 15.0, **safety})
    servo = ServoSettings(profile_velocity=4.0, profile_acceleration=40.0)
    return HardwareConfig(
        port=port,
        baudrate=BAUD,
        latency_timer_ms=LATENCY_MS,
        rate_hz=100.0,
        servo=servo,
        safety=limits,
    )


def state_block(**values: int) -> bytes:
    """The 20 bytes Goal Position .. Present Position that the driver sync-reads."""
    table = XM540_W150
    names = (
        "Goal Position",
        "Realtime Tick",
        "Moving",
        "Moving Status",
        "Present PWM",
        "Present Current",
        "Present Velocity",
        "Present Position",
    )
    return b"".join(table[name].encode(values.get(name, 0)) for name in names)


#: A state whose reply the SDK destuffs wrongly: a goal within 16 turns below zero and
#: a Realtime Tick ending in FD give FF FF FD (stuffed); Present Current -513 then
#: Present Velocity -3 give FF FD FD, which the SDK also destuffs once shifted.
TRIGGER = {
    "Goal Position": -1000,
    "Realtime Tick": 509,
    "Moving": 1,
    "Moving Status": 3,
    "Present PWM": 300,
    "Present Current": -513,
    "Present Velocity": -3,
    "Present Position": -1001,
}
