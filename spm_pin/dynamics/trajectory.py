"""Motions of the three inputs and the servos that follow them.

:class:`Trajectory` samples theta(t), theta_dot(t), theta_ddot(t) (a minimum-jerk
move, finite differences of samples, or a CSV file); :class:`ServoController` turns a
fixed goal or a trajectory into servo torques, once per simulated step.
"""

from __future__ import annotations

import bisect
import csv
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import FileFormatError, InputError
from ._checks import array3, positive, vector
from ._constants import ZERO3, FloatArray
from .servo import ServoModel

__all__ = ["ServoController", "Trajectory"]


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """A motion of the three inputs: theta(t), theta_dot(t), theta_ddot(t).

    Build one with :meth:`minimum_jerk`, :meth:`from_samples` or :meth:`load`.

    Attributes:
        time: Sample times [s], (N,), strictly increasing, N >= 2.
        theta: Input angles [rad], (N, 3).
        theta_dot: Input speeds [rad/s], (N, 3).
        theta_ddot: Input accelerations [rad/s^2], (N, 3).
    """

    time: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray

    def __post_init__(self) -> None:
        time = np.array(self.time, dtype=float).reshape(-1)
        if time.shape[0] < 2 or not np.all(np.isfinite(time)) or np.any(np.diff(time) <= 0.0):
            raise InputError(
                "time must hold at least 2 finite, strictly increasing sample times [s]",
                argument="time",
                value=self.time,
            )
        object.__setattr__(self, "time", time)
        n = time.shape[0]
        for name, unit in (
            ("theta", "[rad]"),
            ("theta_dot", "[rad/s]"),
            ("theta_ddot", "[rad/s^2]"),
        ):
            array = array3(getattr(self, name), name, unit)
            if array.shape != (n, 3):
                raise InputError(
                    f"{name} must have shape ({n}, 3) (one row per sample time), got {array.shape}",
                    argument=name,
                    value=getattr(self, name),
                )
            object.__setattr__(self, name, array)

    @classmethod
    def minimum_jerk(
        cls,
        start: npt.ArrayLike,
        goal: npt.ArrayLike,
        duration: float,
        rate: float = 1000.0,
    ) -> Trajectory:
        """Rest-to-rest minimum-jerk motion (quintic) from ``start`` to ``goal``.

        theta(t) = start + (goal - start) s(t / T), s(x) = 10 x^3 - 15 x^4 + 6 x^5, with
        exact derivatives; speed, acceleration are zero at both ends.

        Args:
            start: Input angles at t = 0 [rad], (3,).
            goal: Input angles at t = duration [rad], (3,).
            duration: T [s], > 0.
            rate: Samples per second [Hz], > 0 (at least 2 samples are made).
        """
        begin = vector(start, 3, "start", "[rad]")
        end = vector(goal, 3, "goal", "[rad]")
        total = positive(duration, "duration", "[s]")
        hz = positive(rate, "rate", "[Hz]")
        count = max(2, math.ceil(total * hz) + 1)
        t = np.linspace(0.0, total, count)
        x = t / total
        s = x**3 * (10.0 + x * (-15.0 + 6.0 * x))
        ds = x**2 * (30.0 + x * (-60.0 + 30.0 * x)) / total
        dds = x * (60.0 + x * (-180.0 + 120.0 * x)) / total**2
        span = end - begin
        theta = begin + s[:, None] * span
        theta[-1] = end  # exactly, not begin + (end - begin)
        return cls(
            time=t,
            theta=theta,
            theta_dot=ds[:, None] * span,
            theta_ddot=dds[:, None] * span,
        )

    @classmethod
    def from_samples(cls, time: npt.ArrayLike, theta: npt.ArrayLike) -> Trajectory:
        """A trajectory from sampled angles; speeds and accelerations by finite differences.

        Second-order central differences (one-sided at the ends), on any strictly
        increasing time grid: errors scale with the square of the sample spacing, so
        sample smooth motions densely (1 kHz is plenty).

        Args:
            time: Sample times [s], (N,), N >= 3.
            theta: Input angles [rad], (N, 3).
        """
        t = np.array(time, dtype=float).reshape(-1)
        angles = array3(theta, "theta", "[rad]")
        if t.shape[0] < 3 or angles.shape != (t.shape[0], 3):
            raise InputError(
                f"from_samples needs N >= 3 times and theta of shape (N, 3), got "
                f"{t.shape[0]} times and theta of shape {angles.shape}",
                argument="theta",
                value=theta,
            )
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            raise InputError(
                "time must be finite and strictly increasing [s]", argument="time", value=time
            )
        speed = np.gradient(angles, t, axis=0, edge_order=2)
        acceleration = np.gradient(speed, t, axis=0, edge_order=2)
        return cls(time=t, theta=angles, theta_dot=speed, theta_ddot=acceleration)

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """Read a CSV trajectory: a header, then one sample per line.

        Columns: time, then the three input angles, named with their unit:
        ``time_s,theta_1_deg,theta_2_deg,theta_3_deg`` (or ``..._rad``). Speeds and
        accelerations come from :meth:`from_samples`.

        Raises:
            FileFormatError: missing file, bad header, a line without 4 numbers,
                non-increasing times (the message names the line).
        """
        file = Path(path)
        try:
            text = file.read_text(encoding="utf-8")
        except OSError as exc:
            raise FileFormatError(f"cannot read the trajectory: {exc}", path=str(file)) from exc
        rows = list(csv.reader(text.splitlines()))
        lines = [(number, row) for number, row in enumerate(rows, start=1) if any(row)]
        if not lines:
            raise FileFormatError("the trajectory file is empty", path=str(file))
        head_line, header = lines[0]
        names = [cell.strip().lower() for cell in header]
        units = {name.rsplit("_", 1)[-1] for name in names[1:]}
        if (
            len(names) != 4
            or names[0] not in ("time_s", "t_s")
            or len(units) != 1
            or units - {"deg", "rad"}
        ):
            raise FileFormatError(
                "the header must be 'time_s,theta_1_deg,theta_2_deg,theta_3_deg' "
                f"(or _rad), got {','.join(header)!r}",
                path=str(file),
                line=head_line,
            )
        scale = math.pi / 180.0 if units == {"deg"} else 1.0
        values: list[list[float]] = []
        for number, row in lines[1:]:
            try:
                numbers = [float(cell) for cell in row]
            except ValueError:
                numbers = []
            if len(numbers) != 4 or not all(math.isfinite(x) for x in numbers):
                raise FileFormatError(
                    f"expected 4 finite numbers (time, three angles), got {','.join(row)!r}",
                    path=str(file),
                    line=number,
                )
            if values and numbers[0] <= values[-1][0]:
                raise FileFormatError(
                    f"times must increase: {numbers[0]:g} s after {values[-1][0]:g} s",
                    path=str(file),
                    line=number,
                )
            values.append(numbers)
        if len(values) < 3:
            raise FileFormatError(
                f"a trajectory needs at least 3 samples, got {len(values)}", path=str(file)
            )
        data = np.array(values)
        return cls.from_samples(data[:, 0], data[:, 1:] * scale)

    def save(self, path: str | Path, *, degrees: bool = True) -> Path:
        """Write the time and angles as CSV (see :meth:`load`); returns the path."""
        file = Path(path)
        unit = "deg" if degrees else "rad"
        angles = np.degrees(self.theta) if degrees else self.theta
        lines = [f"time_s,theta_1_{unit},theta_2_{unit},theta_3_{unit}"]
        lines += [
            ",".join(repr(float(x)) for x in (t, *row))
            for t, row in zip(self.time, angles, strict=True)
        ]
        file.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return file

    @property
    def duration(self) -> float:
        """Last time minus first time [s]."""
        return float(self.time[-1] - self.time[0])

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """(theta, theta_dot) at time t [s] by linear interpolation; held beyond the ends."""
        time = self.time
        if t <= time[0]:
            return self.theta[0].copy(), self.theta_dot[0].copy()
        if t >= time[-1]:
            return self.theta[-1].copy(), self.theta_dot[-1].copy()
        k = int(np.searchsorted(time, t, side="right")) - 1
        w = (t - time[k]) / (time[k + 1] - time[k])
        theta, speed = self.theta, self.theta_dot
        return theta[k] + w * (theta[k + 1] - theta[k]), speed[k] + w * (speed[k + 1] - speed[k])


@dataclasses.dataclass(frozen=True)
class ServoController:
    """Servos that follow a goal: a fixed goal (3,) or a :class:`Trajectory`.

    Call it as ``controller(t, theta, theta_dot)`` to get the servo torques [N m];
    :class:`Simulator` and :func:`simulate_mujoco` do so once per step.

    Attributes:
        servo: The servo model (gains and torque-speed envelope).
        goal: Goal angles [rad] (3,), or a trajectory (positions and speeds).
        feedforward: Optional torques [N m] added before clipping: (3,), or (N, 3) at
            the trajectory's sample times (interpolated), e.g. from
            :func:`inverse_dynamics`.
    """

    servo: ServoModel
    goal: Trajectory | FloatArray
    feedforward: FloatArray | None = None
    _constants: tuple[float, float, float, float] = dataclasses.field(
        init=False, repr=False, compare=False, default=(0.0, 0.0, 0.0, 0.0)
    )
    _table: Any = dataclasses.field(init=False, repr=False, compare=False, default=None)
    _goal_rows: Any = dataclasses.field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        if not isinstance(self.servo, ServoModel):
            raise InputError(
                f"servo must be a ServoModel, got {type(self.servo).__name__}",
                argument="servo",
                value=self.servo,
            )
        if not isinstance(self.goal, Trajectory):
            object.__setattr__(self, "goal", vector(self.goal, 3, "goal", "[rad]"))
        if self.feedforward is not None:
            ff = array3(self.feedforward, "feedforward", "[N m]")
            if ff.ndim == 2:
                n = self.goal.time.shape[0] if isinstance(self.goal, Trajectory) else -1
                if ff.shape[0] != n:
                    raise InputError(
                        "a feedforward of shape (N, 3) needs a trajectory goal with N "
                        f"samples, got {ff.shape[0]} rows",
                        argument="feedforward",
                        value=self.feedforward,
                    )
            object.__setattr__(self, "feedforward", ff)
        # Plain-float tables for __call__ (not dataclass fields).
        servo = self.servo
        object.__setattr__(
            self,
            "_constants",
            (servo.kp, servo.kd, servo.stall_torque, 1.0 / servo.no_load_speed),
        )
        ff_now = self.feedforward
        goal = self.goal
        if isinstance(goal, Trajectory):
            n = goal.time.shape[0]
            if ff_now is None:
                ff_rows = np.zeros((n, 3))
            elif ff_now.ndim == 1:
                ff_rows = np.broadcast_to(ff_now, (n, 3))
            else:
                ff_rows = ff_now
            table = (
                goal.time.tolist(),
                goal.theta.tolist(),
                goal.theta_dot.tolist(),
                np.asarray(ff_rows).tolist(),
                ff_now is not None and ff_now.ndim == 2,
            )
            object.__setattr__(self, "_table", table)
            object.__setattr__(self, "_goal_rows", None)
        else:
            ff_row = [0.0, 0.0, 0.0] if ff_now is None else ff_now.tolist()
            object.__setattr__(self, "_table", None)
            object.__setattr__(self, "_goal_rows", (goal.tolist(), [0.0, 0.0, 0.0], ff_row))

    def __call__(self, t: float, theta: FloatArray, theta_dot: FloatArray) -> FloatArray:
        """Servo torques [N m] at time t [s] and the present state (theta [rad],
        theta_dot [rad/s], (3,) each).

        The same as ``servo.command(theta, theta_dot, goal(t), goal_velocity(t),
        feedforward(t))``, written with plain floats: it runs once per simulated step.
        """
        table = self._table
        x = theta.tolist()
        xd = theta_dot.tolist()
        if table is None:
            g, gd, ff = self._goal_rows
        else:
            times = table[0]
            k = bisect.bisect_right(times, t) - 1
            angles, speeds, torques = table[1], table[2], table[3]
            if k < 0:
                g, gd, ff = angles[0], speeds[0], torques[0]
            elif k >= len(times) - 1:
                g, gd, ff = angles[-1], speeds[-1], torques[-1]
            else:
                w = (t - times[k]) / (times[k + 1] - times[k])
                a, b = angles[k], angles[k + 1]
                g = [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2])]
                a, b = speeds[k], speeds[k + 1]
                gd = [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2])]
                if table[4]:
                    a, b = torques[k], torques[k + 1]
                    ff = [
                        a[0] + w * (b[0] - a[0]),
                        a[1] + w * (b[1] - a[1]),
                        a[2] + w * (b[2] - a[2]),
                    ]
                else:
                    ff = ZERO3
        kp, kd, stall, scale = self._constants
        out = [0.0, 0.0, 0.0]
        for i in range(3):
            torque = kp * (g[i] - x[i]) + kd * (gd[i] - xd[i]) + ff[i]
            slope = xd[i] * scale
            upper = stall * (1.0 - slope)
            lower = -stall * (1.0 + slope)
            upper = stall if upper > stall else upper
            lower = -stall if lower < -stall else lower
            torque = lower if torque < lower else torque  # as np.clip: upper wins
            out[i] = upper if torque > upper else torque
        return np.array(out)
