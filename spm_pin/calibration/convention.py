"""Encoder conventions: how raw servo counts become input-shaft angles
(:class:`JointConvention`), as in the joints of a servo configuration."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ._constants import TICKS_PER_TURN, FloatArray, as_triple

if TYPE_CHECKING:  # pragma: no cover
    from ..hardware.config import HardwareConfig


@dataclasses.dataclass(frozen=True)
class JointConvention:
    """How raw encoder counts become input-shaft angles (one entry per servo).

    ``reading_i [rad] = direction_i * (ticks_i - zero_offset_ticks_i) * 2 pi /
    (ticks_per_turn * gear_ratio_i)``. These are the per-joint settings of a servo
    configuration: direction +1 or -1, gear ratio (servo turns per input-shaft turn,
    1 for the prototype's 1:1 gears) and the zero offset in counts. It is the formula
    of :class:`spm_pin.hardware.JointConfig` (``theta_i = direction * (pulses -
    zero_offset - 4096 k_i) * 2 pi / 4096 / gear_ratio``) for ticks_per_turn = 4096,
    with the whole servo turns k_i left in the reading. With 1:1 gears they change
    nothing (a servo turn is a turn of the input, and the kinematics repeat every
    turn); with other gears, take all readings without the servos losing their turn
    count (no power cycle or reboot). In a readings file the zero offset is the
    setting ``zero_offset``, as in the servo configuration.

    Attributes:
        ticks_per_turn: Encoder counts per servo turn (4096 for the XM540).
        direction: +1 or -1 per servo.
        zero_offset_ticks: Counts at which the input angle reads zero (need not be
            whole: :meth:`with_offsets` gives the exact value).
        gear_ratio: Servo turns per input-shaft turn (> 0).
    """

    ticks_per_turn: int = TICKS_PER_TURN
    direction: tuple[int, int, int] = (1, 1, 1)
    zero_offset_ticks: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gear_ratio: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        tpt = self.ticks_per_turn
        if isinstance(tpt, bool) or not isinstance(tpt, (int, np.integer)) or tpt < 1:
            raise InputError(
                f"ticks_per_turn must be a positive whole number, got {tpt!r}",
                argument="ticks_per_turn",
                value=tpt,
            )
        object.__setattr__(self, "ticks_per_turn", int(tpt))
        direction = as_triple(self.direction, "direction")
        if any(d not in (1.0, -1.0) for d in direction):
            raise InputError(
                f"direction must hold +1 or -1 per servo, got {self.direction!r}",
                argument="direction",
                value=self.direction,
            )
        object.__setattr__(self, "direction", tuple(int(d) for d in direction))
        object.__setattr__(
            self, "zero_offset_ticks", as_triple(self.zero_offset_ticks, "zero_offset_ticks")
        )
        gear = as_triple(self.gear_ratio, "gear_ratio")
        if any(g <= 0 for g in gear):
            raise InputError(
                f"gear_ratio must be positive, got {self.gear_ratio!r}",
                argument="gear_ratio",
                value=self.gear_ratio,
            )
        object.__setattr__(self, "gear_ratio", gear)

    @property
    def radians_per_tick(self) -> FloatArray:
        """Input-shaft angle per count [rad], per servo, with its sign (3,)."""
        result: FloatArray = (
            np.asarray(self.direction, dtype=float)
            * 2.0
            * math.pi
            / (self.ticks_per_turn * np.asarray(self.gear_ratio))
        )
        return result

    def ticks_to_angle(self, ticks: npt.ArrayLike) -> FloatArray:
        """Input-shaft angles [rad] (..., 3) from encoder counts (..., 3)."""
        counts = np.asarray(ticks, dtype=float)
        result: FloatArray = (counts - np.asarray(self.zero_offset_ticks)) * self.radians_per_tick
        return result

    def angle_to_ticks(self, angle: npt.ArrayLike) -> FloatArray:
        """Encoder counts (not rounded) (..., 3) at input-shaft angles [rad] (..., 3)."""
        result: FloatArray = (
            np.asarray(self.zero_offset_ticks)
            + np.asarray(angle, dtype=float) / self.radians_per_tick
        )
        return result

    def with_offsets(self, offsets: npt.ArrayLike) -> JointConvention:
        """The convention whose zero reads the model's zero, given identified offsets [rad].

        With ``offset_i`` the reading at the model's zero, the new zero offset is
        ``zero_offset_ticks_i + offset_i / radians_per_tick_i`` (exact, not rounded).
        """
        shift = np.asarray(offsets, dtype=float) / self.radians_per_tick
        zero = np.asarray(self.zero_offset_ticks) + shift
        return dataclasses.replace(
            self, zero_offset_ticks=(float(zero[0]), float(zero[1]), float(zero[2]))
        )

    @classmethod
    def from_servo_config(cls, config: HardwareConfig) -> JointConvention:
        """The convention of a servo configuration's joints (4096 pulses per turn).

        Readings of the servos' Present Position [pulses] convert to the very angles
        the hardware layer uses (up to whole turns); load them with
        ``load_readings(path, joints=JointConvention.from_servo_config(config))``.

        Args:
            config: A :class:`spm_pin.hardware.HardwareConfig`.
        """
        hardware_config = _hardware_config_class()
        if not isinstance(config, hardware_config):
            raise InputError(
                f"config must be a spm_pin.hardware.HardwareConfig, got {type(config).__name__}",
                argument="config",
                value=config,
            )
        u1, u2, u3 = config.joints
        return cls(
            ticks_per_turn=TICKS_PER_TURN,
            direction=(u1.direction, u2.direction, u3.direction),
            zero_offset_ticks=(float(u1.zero_offset), float(u2.zero_offset), float(u3.zero_offset)),
            gear_ratio=(float(u1.gear_ratio), float(u2.gear_ratio), float(u3.gear_ratio)),
        )


def _hardware_config_class() -> type[HardwareConfig]:
    """spm_pin.hardware.HardwareConfig, imported when first needed.

    The hardware package imports its SDK (dynamixel-sdk, the ``hardware`` extra) only
    when a port is opened, so the configuration works without it.
    """
    from ..hardware.config import HardwareConfig

    return HardwareConfig
