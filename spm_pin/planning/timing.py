"""Time-optimal timing along a planned path: :func:`time_path`, :class:`Trajectory`.

The path is timed by TOPP-RA (the ``toppra`` library, the ``planning`` extra): the
fastest motion along a given geometric path whose every joint keeps within its speed
and acceleration limits, from rest to rest.

A planned path is a polyline. Moving along a polyline without leaving it means
stopping at every corner (the direction of motion changes there), so two shapes of
the same motion are timed and the faster one kept:

* **rest at the corners**: each straight segment timed on its own, from rest to rest
  (the positions stay on the certified polyline);
* **smoothed**: a cubic spline through the waypoints (parameterized by chord length
  in input space), timed as a whole without stopping. The spline leaves the
  polyline near the corners, so it is certified again as a continuous curve before
  it is used (:func:`certify_curve`); when it is not, splines pinned closer to the
  polyline (extra knots on each segment) are tried, and failing those the polyline is
  kept.

The timing uses TOPP-RA's constant-acceleration output (positions exactly on the
path at every instant). Its limits hold at the grid points of the parameterization;
between them the trajectory is sampled densely and, where a limit is exceeded by the
discretization, the whole piece is slowed uniformly in time (a time scale k turns
speeds into speeds / k and accelerations into accelerations / k^2) until every
sample is within the limits.

Jerk limits and the torque-speed limits of the servos are not imposed yet.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import numpy.typing as npt

from ..errors import InputError, PlanningError

if TYPE_CHECKING:
    from .input_space import InputSafeSet
    from .safe_set import SafeSet

__all__ = [
    "DEFAULT_MAX_ACCELERATION",
    "DEFAULT_MAX_SPEED",
    "MotionLimits",
    "TimingLimits",
    "Trajectory",
    "certify_curve",
    "time_path",
    "trapezoid_duration",
]

FloatArray = npt.NDArray[np.float64]

#: Joint speed limit of the servos' guard [rad/s] (90 deg/s).
DEFAULT_MAX_SPEED = math.radians(90.0)
#: Joint acceleration limit of the servos' guard [rad/s^2] (360 deg/s^2).
DEFAULT_MAX_ACCELERATION = math.radians(360.0)
#: Grid points of the parameterization per degree of path length (at least
#: :data:`MIN_GRID_POINTS` per timed piece, at most :data:`MAX_GRID_POINTS`).
GRID_PER_DEG = 4.0
MIN_GRID_POINTS = 100
MAX_GRID_POINTS = 6000
#: Samples per grid interval at which the limits are checked after timing.
LIMIT_SAMPLES = 4
#: Fractions of each segment at which extra knots pin a spline to the polyline, in
#: the order tried after the spline through the bare waypoints fails its certificate.
PIN_FRACTIONS = (0.25, 0.1)
#: Halvings of an interval of a curve that its samples do not cover, at most.
MAX_REFINEMENTS = 12
#: Gap rates [deg] per radian of input: (D12, D23) change by G (dtheta) (signs aside).
_GAP_RATE = np.degrees(np.array([[1.0, -1.0, 0.0], [0.0, 1.0, -1.0]]))


class MotionLimits(Protocol):
    """Anything with joint speed and acceleration limits, e.g.
    :class:`~spm_pin.hardware.config.SafetyLimits` or :class:`TimingLimits`."""

    @property
    def max_speed(self) -> Any:
        """Joint speed limit [rad/s], one number or one per joint."""

    @property
    def max_acceleration(self) -> Any:
        """Joint acceleration limit [rad/s^2], one number or one per joint."""


@dataclasses.dataclass(frozen=True)
class TimingLimits:
    """Joint limits of a timed motion (default: the servos' guard's).

    Attributes:
        max_speed: Joint speed limit [rad/s], one number or one per joint.
        max_acceleration: Joint acceleration limit [rad/s^2], one number or one per
            joint.
    """

    max_speed: float | tuple[float, float, float] = DEFAULT_MAX_SPEED
    max_acceleration: float | tuple[float, float, float] = DEFAULT_MAX_ACCELERATION


def _per_joint(value: Any, name: str) -> FloatArray:
    try:
        array: FloatArray = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
    except (TypeError, ValueError):
        raise InputError(
            f"{name} must be a positive number or three of them, got {value!r}",
            argument=name,
            value=value,
        ) from None
    if not np.all(np.isfinite(array) & (array > 0.0)):
        raise InputError(
            f"{name} must be positive and finite, got {value!r}", argument=name, value=value
        )
    return array


def _limits(limits: MotionLimits | None) -> tuple[FloatArray, FloatArray]:
    if limits is None:
        limits = TimingLimits()
    for name in ("max_speed", "max_acceleration"):
        if not hasattr(limits, name):
            raise InputError(
                f"limits must have max_speed [rad/s] and max_acceleration [rad/s^2], got "
                f"{limits!r}",
                argument="limits",
            )
    return (
        _per_joint(limits.max_speed, "max_speed"),
        _per_joint(limits.max_acceleration, "max_acceleration"),
    )


def _waypoints(theta: npt.ArrayLike) -> FloatArray:
    try:
        path = np.array(theta, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"theta must be waypoints [rad] of shape (n, 3), got {theta!r}", argument="theta"
        ) from None
    if path.ndim != 2 or path.shape[1] != 3 or path.shape[0] < 1:
        raise InputError(
            f"theta must be waypoints [rad] of shape (n, 3), n >= 1, got shape {path.shape}",
            argument="theta",
        )
    if not np.all(np.isfinite(path)):
        raise InputError("theta must be finite angles [rad]", argument="theta")
    return path


def _segment_time(distance: FloatArray, speed: FloatArray, acceleration: FloatArray) -> float:
    """Shortest rest-to-rest time [s] of a straight move by ``distance`` (3,) [rad]."""
    moving = np.abs(distance) > 0.0
    if not np.any(moving):
        return 0.0
    # Along the line theta = theta0 + lam * distance, lam in [0, 1]: the joints bound
    # lam's speed and acceleration by the tightest ratio; a trapezoid in lam.
    v = float(np.min(speed[moving] / np.abs(distance[moving])))
    a = float(np.min(acceleration[moving] / np.abs(distance[moving])))
    if v * v / a <= 1.0:
        return 1.0 / v + v / a
    return 2.0 * math.sqrt(1.0 / a)


def trapezoid_duration(theta: npt.ArrayLike, limits: MotionLimits | None = None) -> float:
    """Duration [s] of the trapezoidal profile along a polyline, at rest at every
    waypoint: each straight segment the fastest rest-to-rest move under the per-joint
    speed and acceleration limits (the slowest joint sets the pace).

    Args:
        theta: Waypoints [rad], (n, 3).
        limits: Joint limits (default: the servos' guard's).
    """
    speed, acceleration = _limits(limits)
    return _trapezoid(_waypoints(theta), speed, acceleration)


def _trapezoid(theta: FloatArray, speed: FloatArray, acceleration: FloatArray) -> float:
    return float(sum(_segment_time(d, speed, acceleration) for d in np.diff(theta, axis=0)))


def certify_curve(
    safe: SafeSet | InputSafeSet,
    curve: Any,
    knots: npt.ArrayLike,
    *,
    max_refinements: int = MAX_REFINEMENTS,
) -> tuple[bool, int]:
    """Certify a piecewise-cubic curve of input angles as a continuous safe path.

    The curve is sampled (its knots among the samples) and each sample is certified
    safe within a gap radius by :meth:`SafeSet.evaluate`. Between two samples s_i,
    s_j of one cubic piece the curve's gap velocity g'(s) = G theta'(s) has a linear
    derivative, so its arc length in the gap plane is at most
    ``ds min(|g'(s_i)|, |g'(s_j)|) + ds^2 / 2 max(|g''(s_i)|, |g''(s_j)|)``; every
    point of the curve between them lies within its arc length of one end, so the
    two samples cover the way between them when their radii add up to that bound.
    Where they do not, the interval is halved.

    Args:
        safe: The safe set.
        curve: ``curve(s, order)`` -> input angles [rad] (order 0) and their first
            and second derivatives, (m, 3), cubic between the knots.
        knots: Parameters of the curve's knots, increasing; the first and last bound
            the curve.
        max_refinements: Halvings of uncovered intervals, at most.

    Returns:
        (safe, samples checked).
    """
    breaks = np.asarray(knots, dtype=float)
    step = safe.settings.check_step_deg
    want = 0.5 * step
    # Degrees of the safe set's coordinates per radian of input: the gaps, or (a
    # safe set of the 3-D input space) the inputs themselves.
    rate = _GAP_RATE if getattr(safe, "coordinates", "gaps") == "gaps" else np.degrees(np.eye(3))

    def gap_norm(s: FloatArray, order: int) -> FloatArray:
        rates = np.asarray(curve(s, order), dtype=float).reshape(-1, 3) @ rate.T
        result: FloatArray = np.linalg.norm(rates, axis=1)
        return result

    parts = []
    for a, b in itertools.pairwise(breaks):
        fine = np.linspace(a, b, 65)
        length = float(np.sum(gap_norm(fine, 1)) * (b - a) / 64.0)
        count = max(1, math.ceil(1.2 * length / step))
        parts.append(np.linspace(a, b, count + 1)[:-1])
    s = np.concatenate([*parts, breaks[-1:]])
    radius = safe.evaluate(curve(s, 0), want=want).radius
    checked = s.size
    for _ in range(max_refinements + 1):
        if np.any(radius < 0.0):
            return False, checked
        speed, bend = gap_norm(s, 1), gap_norm(s, 2)
        ds = np.diff(s)
        bound = ds * np.minimum(speed[:-1], speed[1:]) + 0.5 * ds * ds * np.maximum(
            bend[:-1], bend[1:]
        )
        short = np.flatnonzero(radius[:-1] + radius[1:] < bound)
        if short.size == 0:
            return True, checked
        middle = 0.5 * (s[short] + s[short + 1])
        extra = safe.evaluate(curve(middle, 0), want=float(0.5 * bound[short].max())).radius
        s = np.insert(s, short + 1, middle)
        radius = np.insert(radius, short + 1, extra)
        checked += middle.size
    return False, checked


@dataclasses.dataclass(frozen=True)
class _Piece:
    """One timed piece: toppra's trajectory slowed by ``scale`` from ``start`` [s]."""

    start: float
    duration: float
    scale: float
    timed: Any


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """A timed motion along a path, sampled at any instant (:meth:`sample`).

    Attributes:
        theta: The waypoints [rad], (n, 3).
        times: When the motion passes them [s], (n,).
        duration: Its duration [s].
        smoothed: True when the corners are rounded by a certified spline; False when
            the motion follows the polyline and stops at every corner.
        trapezoid_duration: Duration of the trapezoidal profile along the same
            polyline, at rest at every waypoint (:func:`trapezoid_duration`) [s].
        max_speed: The joint speed limits [rad/s], (3,).
        max_acceleration: The joint acceleration limits [rad/s^2], (3,).
        samples_checked: Samples of the smoothed curve certified (0 when not smoothed).
    """

    theta: FloatArray
    times: FloatArray
    duration: float
    smoothed: bool
    trapezoid_duration: float
    max_speed: FloatArray
    max_acceleration: FloatArray
    samples_checked: int
    pieces: tuple[_Piece, ...] = dataclasses.field(repr=False)

    def sample(self, t: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Input angles [rad], speeds [rad/s] and accelerations [rad/s^2] at times
        ``t`` [s] (scalar or (m,)); before 0 and after the end the robot rests at
        the ends.

        Returns:
            (theta, theta_dot, theta_ddot), each (3,) for a scalar t, else (m, 3).
        """
        times = np.asarray(t, dtype=float)
        if not np.all(np.isfinite(times)):
            raise InputError(f"t must be finite times [s], got {t!r}", argument="t")
        flat = np.atleast_1d(times).ravel()
        theta = np.empty((flat.size, 3))
        speed = np.zeros((flat.size, 3))
        accel = np.zeros((flat.size, 3))
        starts = np.array([piece.start for piece in self.pieces])
        which = np.clip(np.searchsorted(starts, flat, side="right") - 1, 0, len(self.pieces) - 1)
        for k, piece in enumerate(self.pieces):
            rows = np.flatnonzero(which == k)
            if rows.size == 0:
                continue
            local = np.clip(flat[rows] - piece.start, 0.0, piece.duration) / piece.scale
            theta[rows] = piece.timed(local, 0)
            moving = (flat[rows] > piece.start) & (flat[rows] < piece.start + piece.duration)
            inside = rows[moving]
            if inside.size:
                speed[inside] = piece.timed(local[moving], 1) / piece.scale
                accel[inside] = piece.timed(local[moving], 2) / piece.scale**2
        if times.ndim == 0:
            return theta[0], speed[0], accel[0]
        return theta, speed, accel

    def times_at_rate(self, rate: float) -> FloatArray:
        """Times [s] from 0 to the end, ``rate`` [Hz] apart (the end included)."""
        if isinstance(rate, bool) or not (isinstance(rate, int | float) and rate > 0):
            raise InputError(f"rate must be a positive number [Hz], got {rate!r}", argument="rate")
        count = math.floor(self.duration * rate + 1e-9)
        times: FloatArray = np.arange(count + 1, dtype=float) / float(rate)
        if times[-1] < self.duration:
            times = np.append(times, self.duration)
        return times


def _toppra() -> Any:
    try:
        import toppra
        import toppra.algorithm
        import toppra.constraint
    except ImportError as exc:
        raise ImportError(
            "time-optimal timing needs toppra: pip install 'spm-pin[planning]'"
        ) from exc
    return toppra


def _time_curve(
    path: Any, knots: FloatArray, speed: FloatArray, acceleration: FloatArray
) -> tuple[_Piece, FloatArray]:
    """Time a geometric path from rest to rest with TOPP-RA; returns the piece
    (starting at 0) and the times of the knots [s]."""
    ta = _toppra()
    total_deg = math.degrees(float(knots[-1] - knots[0]))
    count = int(np.clip(GRID_PER_DEG * total_deg, MIN_GRID_POINTS, MAX_GRID_POINTS))
    grid = np.unique(np.concatenate([np.linspace(knots[0], knots[-1], count), knots]))
    constraints = [
        ta.constraint.JointVelocityConstraint(speed),
        ta.constraint.JointAccelerationConstraint(acceleration),
    ]
    algorithm = ta.algorithm.TOPPRA(
        constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel"
    )
    algorithm.compute_parameterization(0.0, 0.0)
    data = algorithm.problem_data
    if data.return_code != ta.algorithm.ParameterizationReturnCode.Ok or data.sd_vec is None:
        raise PlanningError(
            f"time parameterization failed ({data.return_code})",
            reasons=("time parameterization failed",),
            check="timing",
        )
    sd = np.maximum(np.asarray(data.sd_vec, dtype=float), 0.0)
    timed = ta.parametrizer.ParametrizeConstAccel(path, grid, sd)
    # The times of the grid points, as toppra's output computes them.
    dt = 2.0 * np.diff(grid) / (sd[:-1] + sd[1:])
    grid_times = np.concatenate([[0.0], np.cumsum(dt)])
    duration = float(grid_times[-1])
    # The limits at dense samples: slow the piece down uniformly where exceeded.
    fractions = np.arange(LIMIT_SAMPLES) / LIMIT_SAMPLES
    t = np.append((grid_times[:-1, None] + fractions * dt[:, None]).ravel(), duration)
    worst_speed = np.max(np.abs(timed(t, 1)) / speed)
    worst_acceleration = np.max(np.abs(timed(t, 2)) / acceleration)
    scale = max(1.0, float(worst_speed), math.sqrt(float(worst_acceleration)))
    knot_times = scale * grid_times[np.searchsorted(grid, knots)]
    return _Piece(0.0, scale * duration, scale, timed), knot_times


def _line(theta: FloatArray) -> tuple[Any, FloatArray]:
    """The polyline through theta (n, 3) as a cubic spline path of toppra, knots at
    the cumulative chord lengths [rad]."""
    ta = _toppra()
    knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(theta, axis=0), axis=1))])
    return ta.SplineInterpolator(knots, theta), knots


def _pinned(theta: FloatArray, fraction: float) -> FloatArray:
    """Waypoints with extra points at ``fraction`` and ``1 - fraction`` of each
    segment (a spline through them keeps closer to the polyline)."""
    rows = [theta[:1]]
    for a, b in itertools.pairwise(theta):
        rows.append(np.vstack([a + fraction * (b - a), a + (1.0 - fraction) * (b - a), b]))
    result: FloatArray = np.vstack(rows)
    return result


def _rest_at_corners(
    theta: FloatArray, speed: FloatArray, acceleration: FloatArray
) -> tuple[list[_Piece], FloatArray]:
    pieces: list[_Piece] = []
    times = [0.0]
    clock = 0.0
    for a, b in itertools.pairwise(theta):
        if np.array_equal(a, b):
            times.append(clock)
            continue
        path, knots = _line(np.vstack([a, b]))
        piece, _ = _time_curve(path, knots, speed, acceleration)
        pieces.append(dataclasses.replace(piece, start=clock))
        clock += piece.duration
        times.append(clock)
    return pieces, np.array(times)


def _at_rest(theta: FloatArray) -> _Piece:
    point = theta[0].copy()

    def hold(t: Any, order: int = 0) -> FloatArray:
        values: FloatArray = np.zeros((np.size(t), 3))
        if order == 0:
            values[:] = point
        return values

    return _Piece(0.0, 0.0, 1.0, hold)


def time_path(
    theta: npt.ArrayLike,
    limits: MotionLimits | None = None,
    *,
    safe: SafeSet | InputSafeSet | None = None,
    smooth: bool = True,
) -> Trajectory:
    """The fastest motion along a planned path under joint speed and acceleration
    limits, from rest to rest (see the module).

    Args:
        theta: Waypoints [rad], (n, 3): a path certified safe as the straight lines
            between them (:func:`~spm_pin.planning.plan`).
        limits: Joint limits (default: the servos' guard's, :class:`TimingLimits`).
        safe: The safe set that certifies a smoothed path (without it, or with
            ``smooth=False``, the motion stops at every corner).
        smooth: Try rounding the corners with a certified spline.

    Returns:
        The trajectory.

    Raises:
        InputError: bad waypoints or limits.
        ImportError: toppra is missing (``pip install 'spm-pin[planning]'``).
    """
    path = _waypoints(theta)
    speed, acceleration = _limits(limits)
    baseline = _trapezoid(path, speed, acceleration)
    keep = np.concatenate([[True], np.any(np.diff(path, axis=0) != 0.0, axis=1)])
    distinct = path[keep]
    if distinct.shape[0] == 1:
        return Trajectory(
            path, np.zeros(path.shape[0]), 0.0, False, 0.0, speed, acceleration, 0,
            (_at_rest(path),),
        )  # fmt: skip
    pieces, times = _rest_at_corners(path, speed, acceleration)
    best = Trajectory(
        path, times, float(times[-1]), False, baseline, speed, acceleration, 0, tuple(pieces)
    )
    if not smooth or safe is None or distinct.shape[0] < 3:
        return best
    checked = 0
    for fraction in (None, *PIN_FRACTIONS):
        knotted = distinct if fraction is None else _pinned(distinct, fraction)
        curve, knots = _line(knotted)
        ok, count = certify_curve(safe, curve, knots)
        checked += count
        if not ok:
            continue
        piece, knot_times = _time_curve(curve, knots, speed, acceleration)
        if piece.duration < best.duration:
            # The times of the given waypoints (repeated ones share a time).
            stride = 1 if fraction is None else 3
            at = np.cumsum(keep) - 1
            best = Trajectory(
                path, knot_times[::stride][at], piece.duration, True, baseline, speed,
                acceleration, checked, (piece,),
            )  # fmt: skip
        break
    return dataclasses.replace(best, samples_checked=checked)
