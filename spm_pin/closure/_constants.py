"""Tolerances, limits and defaults of the loop-closure solver, and its small numeric helpers.

The public constants are documented here and re-exported by :mod:`spm_pin.closure`;
:func:`rank`, :func:`orientation` and :func:`check_solver_options` are shared by the
solver's modules.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..kinematics._common import ANGLE_LIMIT, check_count

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: ``actuated.dot(actuated)`` at most this bounds every entry by ANGLE_LIMIT.
LIMIT_SQUARED = ANGLE_LIMIT**2
#: Largest |entry| of a frame target (positions [m], matrix entries): generous for a
#: mechanism metres in size, and small enough that the least-squares steps stay finite.
TARGET_LIMIT = 1e6

#: Closure tolerance of :meth:`ClosedLoop.project`: Euclidean norm of the stacked
#: constraint residual [m and rad]; it bounds every component (max-abs).
DEFAULT_TOL = 1e-12
#: Newton iterations (accepted and retried steps) before :meth:`ClosedLoop.project`
#: gives up.
DEFAULT_MAX_ITERATIONS = 50
#: Newton iterations per sub-step in :meth:`ClosedLoop.follow` before the step is halved.
FOLLOW_MAX_ITERATIONS = 12
#: Damping factor mu of the Newton steps, lambda = mu ||e||^2 (lambda in the units of
#: J_p^T J_p; 1 suits joints in rad and lengths in m).
DEFAULT_DAMPING = 1.0
#: Relative rank threshold: a pivot of the rank-revealing QR counts as zero below
#: RANK_TOL times the largest one.
RANK_TOL = 1e-9
#: A configuration counts as closed (velocity maps accept it) when ||e|| <= CLOSED_TOL.
CLOSED_TOL = 1e-9
#: Default number of halvings of a path step in :meth:`ClosedLoop.follow`.
DEFAULT_MAX_HALVINGS = 12
#: Largest path step tried by the continuation fallback of :meth:`ClosedLoop.project`
#: (max-abs over the actuated values) [rad or m].
CONTINUATION_STEP = 0.1
#: A path sub-step is accepted when the corrector moved the passive joints by at most
#: this fraction of the predicted change (plus :data:`CLOSED_TOL`).
CORRECTOR_RATIO = 0.5
#: Values of the ``continuation`` argument of :meth:`ClosedLoop.project`.
CONTINUATION_MODES = ("never", "fallback", "always")
#: Consecutive rejected Newton steps (damping x 10 each) that mean a stall.
MAX_REJECTIONS = 8
FLOAT64 = np.dtype(np.float64)
#: Seed of the random configurations that estimate the generic ranks.
RANK_SEED = 20_240_611


def rank(matrix: FloatArray) -> int:
    """Numerical rank: singular values above RANK_TOL times the largest."""
    if matrix.size == 0:
        return 0
    s = np.linalg.svd(matrix, compute_uv=False)
    if s[0] == 0.0:
        return 0
    return int(np.sum(s > RANK_TOL * s[0]))


def orientation(passive: FloatArray) -> tuple[FloatArray, float]:
    """An orthonormal basis Q of the range of J_p (full column rank) and sign det(Q^T J_p)."""
    basis, triangle = np.linalg.qr(passive)
    return basis, float(np.sign(np.prod(np.diag(triangle))))


def check_solver_options(tol: Any, max_iterations: Any, damping: Any) -> None:
    """Raise InputError unless tol > 0, max_iterations >= 0 and damping >= 0 (finite)."""
    if not isinstance(tol, (int, float, np.floating)) or not (0.0 < float(tol) < math.inf):
        raise InputError(
            f"tol must be a number > 0 [m, rad], got {tol!r}", argument="tol", value=tol
        )
    check_count(max_iterations, "max_iterations", 0)
    if not isinstance(damping, (int, float, np.floating)) or not (0.0 <= float(damping) < math.inf):
        raise InputError(
            f"damping must be a finite number >= 0, got {damping!r}",
            argument="damping",
            value=damping,
        )
