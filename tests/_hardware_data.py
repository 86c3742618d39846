"""Constants and helpers of the hardware tests (the fixtures are in ``_hardware``)."""

from __future__ import annotations

import numpy as np

from spm_pin.hardware import XM540_W150, HardwareConfig, SafetyLimits
from spm_pin.hardware.driver import ServoSettings

#: Latency allowed for in the packet timeout [ms]: a silent servo costs 2 x this + 2 ms
#: per attempt; large enough for a busy machine, small enough for quick fault tests.
LATENCY_MS = 10.0
IDS = (1, 2, 3)

#: Tolerances of the hardware tests.
TOL = {
    "pulse": np.radians(360.0 / 4096.0),  # one encoder pulse [rad]
    "reached": np.radians(0.5),  # end of a move [rad]
    "model": 1e-9,  # model quantities recomputed independently
}


def fast_config(port: str, **safety: float) -> HardwareConfig:
    """A configuration for quick moves on the emulated bus (faster than the default)."""
    limits = SafetyLimits(**{"max_speed": 3.0, "max_acceleration": 15.0, **safety})
    servo = ServoSettings(profile_velocity=4.0, profile_acceleration=40.0)
    return HardwareConfig(
        port=port, latency_timer_ms=LATENCY_MS, rate_hz=100.0, servo=servo, safety=limits
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
