r"""Servo pulses <-> joint angles, with the multi-turn count made consistent.

For joint i with direction d, gear ratio g (servo turns per joint turn) and zero
offset p0 [pulses]:

    theta_i = d (p - p0 - 4096 k_i) (2 pi / 4096) / g,
    p       = p0 + 4096 k_i + d g theta_i 4096 / (2 pi)   (rounded to a pulse)

k_i counts whole servo turns. In extended position mode a servo counts turns, but
the count restarts within one turn at power-up and after a reboot, so k_i is chosen
when the loop starts (:meth:`JointMap.unwrap`):

* coaxial designs: theta_1 in (-pi, pi], then theta_2 and theta_3 such that the gaps
  between adjacent proximal links, D_12 = 2 pi / 3 + theta_1 - theta_2 and D_23 =
  2 pi / 3 + theta_2 - theta_3, lie in (0, 2 pi): links cannot pass through each
  other, so this is the only physical reading (for 1:1 gears);
* after the reboot of one servo, or for a non-coaxial design: the turn that puts
  theta_i closest to the last known angle (or to 0).

With a gear ratio other than 1 a servo turn is only 1/g of a joint turn and the
reading alone cannot tell the joint's turn: keep such servos powered, or start near
the zero position.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from .config import JointConfig
from .control_table import EXTENDED_POSITION_LIMIT, POSITION_UNIT, PULSES_PER_TURN, VELOCITY_UNIT

__all__ = ["JointMap"]

FloatArray = npt.NDArray[np.float64]


class JointMap:
    """Conversions between the servos' raw readings and the joint angles theta.

    Args:
        joints: The three joints' configurations, u_1, u_2, u_3 in order.
        coaxial: Unwrap with the gap rule of coaxial designs.

    Attributes:
        turns: Whole servo turns k_i added to each reading (set by :meth:`unwrap`).
    """

    def __init__(self, joints: Sequence[JointConfig], *, coaxial: bool = True) -> None:
        self.joints = tuple(joints)
        if len(self.joints) != 3:
            raise InputError(
                f"a JointMap needs 3 joints, got {len(self.joints)}",
                argument="joints",
                value=joints,
            )
        self.coaxial = coaxial
        self.turns = [0, 0, 0]
        self.unwrapped = False
        self._direction = np.array([j.direction for j in self.joints], dtype=float)
        self._gear = np.array([j.gear_ratio for j in self.joints], dtype=float)
        self._zero = np.array([j.zero_offset for j in self.joints], dtype=float)

    @property
    def ids(self) -> tuple[int, ...]:
        """Servo ids of u_1, u_2, u_3."""
        return tuple(j.servo_id for j in self.joints)

    def _theta(self, pulses: Sequence[int], turns: Sequence[int]) -> FloatArray:
        raw = np.asarray(pulses, dtype=float) - self._zero - PULSES_PER_TURN * np.asarray(turns)
        result: FloatArray = self._direction * raw * POSITION_UNIT / self._gear
        return result

    def to_theta(self, pulses: Sequence[int]) -> FloatArray:
        """Joint angles [rad] from Present Position [pulses], (3,)."""
        return self._theta(pulses, self.turns)

    def to_theta_rate(self, velocity: Sequence[int]) -> FloatArray:
        """Joint speeds [rad/s] from Present Velocity [0.229 rev/min units], (3,)."""
        result: FloatArray = (
            self._direction * np.asarray(velocity, dtype=float) * VELOCITY_UNIT / self._gear
        )
        return result

    def to_pulses(self, theta: npt.ArrayLike) -> dict[int, int]:
        """Goal Position [pulses] of each servo, by id, for joint angles [rad] (3,).

        Raises:
            InputError: theta is not 3 finite numbers, or a goal falls outside the
                servo's extended-position range (+-1,048,575 pulses).
        """
        values = np.asarray(theta, dtype=float)
        if values.shape != (3,) or not all(math.isfinite(x) for x in values.tolist()):
            raise InputError(
                f"theta must be 3 finite angles [rad], got {theta!r}", argument="theta", value=theta
            )
        # In Python floats, in the order (and so with the rounding) of the array formula
        # zero + PULSES_PER_TURN * turns + direction * gear * theta / POSITION_UNIT.
        pulses = [
            joint.zero_offset
            + PULSES_PER_TURN * turns
            + joint.direction * joint.gear_ratio * x / POSITION_UNIT
            for joint, turns, x in zip(self.joints, self.turns, values.tolist(), strict=True)
        ]
        result: dict[int, int] = {}
        for joint, angle, value in zip(self.joints, values, pulses, strict=True):
            goal = round(value)
            if abs(goal) > EXTENDED_POSITION_LIMIT:
                raise InputError(
                    f"joint {joint.joint} at {math.degrees(float(angle)):.1f} deg needs Goal "
                    f"Position {goal}, beyond the servo's +-{EXTENDED_POSITION_LIMIT} pulses",
                    argument="theta",
                    value=theta,
                )
            result[joint.servo_id] = goal
        return result

    def unwrap(self, pulses: Sequence[int], reference: npt.ArrayLike | None = None) -> FloatArray:
        """Fix the servo turns k_i from a reading; return the joint angles [rad].

        Args:
            pulses: Present Position of each servo [pulses], u_1, u_2, u_3 order.
            reference: Joint angles to stay closest to (e.g. the last known ones);
                default: the gap rule for coaxial designs, else closest to zero.
        """
        turn = 2.0 * math.pi / self._gear  # joint angle of one servo turn
        base = self._theta(pulses, (0, 0, 0))
        if reference is not None:
            target = np.asarray(reference, dtype=float)
            k = np.round((base - target) / turn)
            self.turns = [int(self._direction[i] * k[i]) for i in range(3)]
        elif self.coaxial:
            third = 2.0 * math.pi / 3.0
            theta = np.empty(3)
            turns = [0, 0, 0]
            k0 = round(float(base[0] / turn[0]))
            theta[0] = base[0] - k0 * turn[0]
            turns[0] = k0
            for i in (1, 2):
                # D = 2pi/3 + theta_{i-1} - theta_i in (0, 2pi): theta_i near theta_{i-1} - pi/3
                centre = theta[i - 1] + third - math.pi
                k = round(float((base[i] - centre) / turn[i]))
                theta[i] = base[i] - k * turn[i]
                turns[i] = k
            self.turns = [int(self._direction[i] * turns[i]) for i in range(3)]
        else:
            k = np.round(base / turn)
            self.turns = [int(self._direction[i] * k[i]) for i in range(3)]
        self.unwrapped = True
        return self.to_theta(pulses)

    def unwrap_one(self, index: int, pulses: int, reference: float) -> float:
        """Fix the turns of joint ``index`` (0..2) only, closest to ``reference`` [rad]."""
        joint = self.joints[index]
        turn = 2.0 * math.pi / joint.gear_ratio
        reading = [pulses if i == index else 0 for i in range(3)]
        base = float(self._theta(reading, (0, 0, 0))[index])
        k = round((base - reference) / turn)
        self.turns[index] = int(joint.direction * k)
        return float(self.to_theta(reading)[index])
