"""What the loop-closure solver returns: projections, paths and frame targets.

:class:`ProjectionResult`, :class:`PathResult` and :class:`FrameTargetResult` are
re-exported by :mod:`spm_pin.closure`; :data:`Start` is what a solve may start from;
:class:`LocalFailure` carries a failed local Newton solve inside the solver.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, TypeAlias

import numpy as np
import numpy.typing as npt

from ._constants import FloatArray, IntArray


class _Analysis(Protocol):
    """What a :class:`ProjectionResult` asks of the solver: the exact analysis at q."""

    nominal_rank: int

    def analysis(self, q: FloatArray) -> tuple[int, FloatArray]:
        """Exact rank of J_p and velocity map G at q."""
        ...


class ProjectionResult:
    """A closed configuration found by :meth:`ClosedLoop.project`.

    Pass it back as ``start`` of the next call: the solve then starts from a
    first-order prediction instead of from ``q``. ``rank``, ``singular`` and
    ``velocity_map`` are computed exactly at ``q`` when first read (one Jacobian and
    one small factorisation), so a control loop that never reads them does not pay
    for them.

    Attributes:
        q: Closed joint configuration, shape (nq,).
        actuated: The actuated joint values that were imposed, shape (n_actuated,)
            [rad or m].
        iterations: Newton steps taken (0 when the start was already closed).
        residual: ||e(q)||, Euclidean norm of the stacked constraint residual [m, rad].
        continuation: True when the answer came from path following (the
            ``continuation`` argument of :meth:`ClosedLoop.project`).
    """

    __slots__ = (
        "_core",
        "_map",
        "_predictor",
        "_rank",
        "actuated",
        "continuation",
        "iterations",
        "q",
        "residual",
    )

    def __init__(
        self,
        core: _Analysis,
        q: FloatArray,
        actuated: FloatArray,
        iterations: int,
        residual: float,
        predictor: FloatArray | None,
    ) -> None:
        self._core = core
        self.q = q
        self.actuated = actuated
        self.iterations = iterations
        self.residual = residual
        self.continuation = False
        self._predictor = predictor
        self._rank: int | None = None
        self._map: FloatArray | None = None

    def __repr__(self) -> str:
        return (
            f"ProjectionResult(q={self.q!r}, iterations={self.iterations}, "
            f"residual={self.residual:.3g}, continuation={self.continuation})"
        )

    def _analyse(self) -> tuple[int, FloatArray]:
        if self._rank is None or self._map is None:
            self._rank, self._map = self._core.analysis(self.q)
        return self._rank, self._map

    @property
    def rank(self) -> int:
        """Numerical rank of the passive constraint Jacobian J_p at ``q`` (the matrix
        the Newton steps invert; relative threshold :data:`RANK_TOL`)."""
        return self._analyse()[0]

    @property
    def singular(self) -> bool:
        """True when ``rank`` is below the generic rank (:attr:`ClosedLoop.nominal_rank`):
        the passive joints are not determined by the actuated ones here."""
        return self._analyse()[0] < self._core.nominal_rank

    @property
    def velocity_map(self) -> FloatArray:
        """G = -J_p^+ J_a at ``q``, shape (n_passive_v, n_actuated): passive joint
        velocities per unit actuated velocity (minimum norm, rank-revealing)."""
        return self._analyse()[1]


@dataclasses.dataclass
class PathResult:
    """A path of closed configurations found by :meth:`ClosedLoop.follow`.

    Attributes:
        q: Closed configurations, shape (N, nq).
        actuated: The actuated values of the path, shape (N, n_actuated).
        iterations: Newton steps spent on each point, sub-steps included, (N,).
        residual: ||e|| at each point [m, rad], (N,).
        rank: Rank of J_p at each point, (N,).
        substeps: Projections used to reach each point from the previous one, (N,);
            more than 1 where the step was halved.
        results: The :class:`ProjectionResult` of each point.
    """

    q: FloatArray
    actuated: FloatArray
    iterations: IntArray
    residual: FloatArray
    rank: IntArray
    substeps: IntArray
    results: list[ProjectionResult]

    @property
    def total_iterations(self) -> int:
        """Newton steps over the whole path."""
        return int(np.sum(self.iterations))


@dataclasses.dataclass
class FrameTargetResult:
    """Actuated values that bring a frame to a target (:meth:`ClosedLoop.solve_frame_target`).

    Attributes:
        actuated: The actuated joint values found, shape (n_actuated,) [rad or m].
        q: The closed configuration there, shape (nq,).
        iterations: Outer Newton steps on the actuated values.
        residual: Norm of the task error at the answer: ||log3|| [rad] for an
            orientation, ||log6|| [m, rad] for a placement, distance [m] for a position.
        kind: ``"orientation"``, ``"placement"`` or ``"position"``.
        projection: The closed configuration as a :class:`ProjectionResult` (closure
            residual, rank, velocity map).
    """

    actuated: FloatArray
    q: FloatArray
    iterations: int
    residual: float
    kind: str
    projection: ProjectionResult


#: What a solve may start from: None (a cold start at ``pin.neutral(model)``), a
#: configuration q (nq,), or a previous result (a warm start with a predictor).
Start: TypeAlias = "ProjectionResult | FrameTargetResult | npt.ArrayLike | None"


class LocalFailure(Exception):
    """Internal: the local Newton solve did not converge (data kept for the report)."""

    def __init__(self, reason: str, q: FloatArray, residual: float, iterations: int) -> None:
        super().__init__(reason)
        self.reason = reason
        self.q = q
        self.residual = residual
        self.iterations = iterations
