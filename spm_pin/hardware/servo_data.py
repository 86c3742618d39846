"""Plain records of the servo driver: what a servo is, what it reads, how it is set up.

* :class:`ServoInfo`: model number and firmware of a servo (from PING and EEPROM).
* :class:`ServoReadings`: one sync read of every servo on the bus, in raw units.
* :class:`ServoSettings`: the control-table values that
  :meth:`~spm_pin.hardware.driver.ServoBus.configure` writes, range-checked.

They hold data only and need neither a port nor dynamixel-sdk.
"""

from __future__ import annotations

import dataclasses
import math

from ..errors import InputError
from .control_table import (
    ACCELERATION_UNIT,
    CURRENT_UNIT,
    VELOCITY_UNIT,
    XM540_W150,
    HardwareErrorFlag,
)

__all__ = ["FAST_SYNC_READ_FIRMWARE", "ServoInfo", "ServoReadings", "ServoSettings"]

#: First firmware version with FAST_SYNC_READ.
FAST_SYNC_READ_FIRMWARE = 45


@dataclasses.dataclass(frozen=True)
class ServoInfo:
    """What PING and the EEPROM tell about a servo."""

    servo_id: int
    model_number: int
    firmware: int

    @property
    def fast_sync_read(self) -> bool:
        """The firmware knows FAST_SYNC_READ."""
        return self.firmware >= FAST_SYNC_READ_FIRMWARE


@dataclasses.dataclass(frozen=True)
class ServoReadings:
    """One sync read of every servo on the bus (raw units, signed), in id order.

    Attributes:
        ids: Servo ids.
        goal: Goal Position the servo holds [pulses].
        position: Present Position [pulses].
        velocity: Present Velocity [0.229 rev/min].
        current: Present Current [2.69 mA].
        moving: Moving flag.
        alert: The status packet's alert bit (a hardware error is latched).
        time: :func:`time.perf_counter` when the read completed [s].
        fast: Read with FAST_SYNC_READ.
    """

    ids: tuple[int, ...]
    goal: tuple[int, ...]
    position: tuple[int, ...]
    velocity: tuple[int, ...]
    current: tuple[int, ...]
    moving: tuple[bool, ...]
    alert: tuple[bool, ...]
    time: float
    fast: bool

    def velocity_rad_s(self) -> list[float]:
        """Present Velocity of each servo shaft [rad/s]."""
        return [v * VELOCITY_UNIT for v in self.velocity]

    def current_a(self) -> list[float]:
        """Present Current of each servo [A]."""
        return [c * CURRENT_UNIT for c in self.current]


@dataclasses.dataclass(frozen=True)
class ServoSettings:
    """How :meth:`ServoBus.configure` sets up every servo.

    Operating Mode is always 4 (extended position: multi-turn, for endless yaw).

    Attributes:
        profile_velocity: Profile Velocity [rad/s of the servo shaft] (> 0; 0 would
            mean "unlimited" to the servo).
        profile_acceleration: Profile Acceleration [rad/s^2] (> 0).
        velocity_limit: Velocity Limit [rad/s] (EEPROM; caps Profile Velocity).
        current_limit: Current Limit [A] (EEPROM, at most 2047 x 2.69 mA = 5.5 A).
        return_delay: Return Delay Time [s] (EEPROM; 0 for the fastest bus).
        shutdown: Hardware errors that drop torque (Shutdown item, EEPROM).
    """

    profile_velocity: float = math.radians(120.0)
    profile_acceleration: float = math.radians(1200.0)
    velocity_limit: float = math.radians(300.0)
    current_limit: float = 5.5
    return_delay: float = 0.0
    shutdown: HardwareErrorFlag = (
        HardwareErrorFlag.OVERHEATING
        | HardwareErrorFlag.ELECTRICAL_SHOCK
        | HardwareErrorFlag.OVERLOAD
    )

    def __post_init__(self) -> None:
        for name in ("profile_velocity", "profile_acceleration", "velocity_limit"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise InputError(
                    f"{name} must be a positive number, got {value!r}", argument=name, value=value
                )
        if self.profile_velocity > self.velocity_limit:
            raise InputError(
                f"profile_velocity {self.profile_velocity} rad/s exceeds velocity_limit "
                f"{self.velocity_limit} rad/s",
                argument="profile_velocity",
                value=self.profile_velocity,
            )
        self.raw()  # range checks of every item

    def raw(self) -> dict[str, int]:
        """Control-table values: item name -> raw value (each range-checked)."""

        def units(value: float, unit: float, name: str, *, at_least_one: bool) -> int:
            raw = round(value / unit)
            if at_least_one:
                raw = max(raw, 1)
            return XM540_W150[name].check(raw)

        return {
            # First: a servo set to answer reads only would leave every write unanswered.
            "Status Return Level": 2,
            "Operating Mode": 4,
            "Drive Mode": 0,
            "Return Delay Time": units(
                self.return_delay, 2e-6, "Return Delay Time", at_least_one=False
            ),
            "Velocity Limit": units(
                self.velocity_limit, VELOCITY_UNIT, "Velocity Limit", at_least_one=True
            ),
            "Current Limit": units(
                self.current_limit, CURRENT_UNIT, "Current Limit", at_least_one=True
            ),
            "Shutdown": XM540_W150["Shutdown"].check(int(self.shutdown)),
            "Profile Acceleration": units(
                self.profile_acceleration,
                ACCELERATION_UNIT,
                "Profile Acceleration",
                at_least_one=True,
            ),
            "Profile Velocity": units(
                self.profile_velocity, VELOCITY_UNIT, "Profile Velocity", at_least_one=True
            ),
        }
