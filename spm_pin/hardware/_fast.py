"""The guard's static checks of one goal on the single-input fast path.

:class:`~spm_pin.hardware.guard.SafetyGuard` checks a stream of goals one at a time.
Through the batch functions one goal costs several hundred microseconds, nearly all
of it numpy's per-call overhead on (1, 3) arrays. Here the same quantities come from
the float code of :mod:`spm_pin.kinematics._scalar` (forward kinematics, singularity
margin, dexterity: bit for bit the batch values) and the collision checker runs on the
closed configuration built from that rotation (what ``robot.collisions(theta)``
builds after its own forward kinematics), so the verdicts are the batch path's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .. import _jit
from ..kinematics import _scalar
from ..kinematics.jacobian import SINGULAR_TOL
from .config import SafetyLimits

if TYPE_CHECKING:
    from ..collision._configuration import Legs
    from ..collision.checker import CollisionChecker
    from ..model.robot import SPMRobot

__all__ = ["FastStatic"]

Rows = Sequence[Sequence[float]]
#: Largest change of an entry of R from the reference for which the single-input
#: solve stands for the continuous one (:meth:`FastStatic.rotation_near`).
CONTINUITY = 0.25


class FastStatic:
    """The measures and the collision check of one goal for a robot and limits.

    Build it with :meth:`of`, which gives None for robots whose collision check is not
    the library's own (a replaced ``collisions`` method): their goals take the batch
    path.
    """

    def __init__(self, robot: SPMRobot, checker: CollisionChecker, legs: Legs, margin: float):
        from ..collision import _configuration
        from ..kinematics import _fk_single

        self.robot = robot
        self.constants = _scalar.constants(robot.design)
        self._checker = checker
        self._legs = legs
        self._margin = margin
        # The compiled kernels (numba, extra "fast"; else the Python functions, same
        # bits): compiled, or read from numba's cache, here rather than in a cycle.
        self._fk_kernels = _jit.kernels(_fk_single.KERNELS)
        self._closed_angles = _jit.kernels(_configuration.KERNELS)["closed_angles"]
        scalar = _jit.kernels(_scalar.KERNELS)  # inverse_kinematics uses them too
        self._jacobian_parts = scalar["jacobian_parts"]
        from ..kinematics import fk as batch
        from ..model.robot import CLOSURE_TOL
        from . import _kernel

        self._closure_tol = CLOSURE_TOL

        self._static = _jit.kernels(_kernel.KERNELS)["static_parts"]
        k = self.constants
        self._static_args = (
            k.coaxial,
            batch._single_constants(robot.design),
            batch._NEWTON_STEPS_FAST,
            batch._POLISH_EXTRA,
            batch._POLISHED,
            batch.RESIDUAL_TOL,
            batch._SIGN_TOL,
            k.turn_axis,
            k.turn_outer,
            (k.u, k.v0, k.w_along, k.w_rest, k.w_cross),
            legs,
        )
        home = (0.0, 0.0, 0.0)
        rotation = _scalar.fk_home(home, self.constants, self._fk_kernels)
        if rotation is not None:
            _scalar.ik_home(rotation, self.constants, scalar["ik_parts"])
            self.measures(home)
            self.collisions(home, rotation)
            self.static(home)

    @classmethod
    def of(cls, robot: object, limits: SafetyLimits) -> FastStatic | None:
        """The fast path of ``robot``, or None where it does not apply."""
        from ..collision._configuration import leg_axes
        from ..collision.checker import CollisionChecker
        from ..model.robot import SPMRobot

        if not isinstance(robot, SPMRobot) or type(robot).collisions is not SPMRobot.collisions:
            return None
        if "collisions" in vars(robot):  # replaced on the instance
            return None
        checker = robot.collision_checker
        if type(checker) is not CollisionChecker:
            return None
        return cls(robot, checker, leg_axes(robot.design), float(limits.collision_margin))

    def measures(self, theta: Sequence[float]) -> tuple[bool, float, float, Rows | None]:
        """(reachable, singularity margin, dexterity, platform rotation rows) of one
        finite goal [rad]; NaN measures and no rotation where unreachable."""
        k = self.constants
        rotation = _scalar.fk_home(theta, k, self._fk_kernels)
        if rotation is None:
            return False, float("nan"), float("nan"), None
        margin, dexterity = _scalar.measures(theta, rotation, k, SINGULAR_TOL, self._jacobian_parts)
        return True, margin, dexterity, rotation

    def static(
        self, theta: Sequence[float]
    ) -> tuple[bool, float, float, Rows | None, npt.NDArray[np.float64] | None]:
        """:meth:`measures` and the closed q of one finite goal [rad] in one compiled
        call: (reachable, singularity margin, dexterity, platform rotation rows,
        q (9,) or None where :meth:`collisions` must build it)."""
        t0, t1, t2 = float(theta[0]), float(theta[1]), float(theta[2])
        if self.constants.coaxial:
            reduced, c, s = _scalar.reduce_input(t0, t1, t2)
        else:
            reduced, c, s = (t0, t1, t2), 1.0, 0.0
        ok, rotation, leg_margin, unit, A, b, first, second, third, worst = self._static(
            (t0, t1, t2), reduced, c, s, *self._static_args
        )
        if not ok:  # not settled by the float solve: the batch path decides
            reachable, margin, dexterity, rows = self.measures(theta)
            return reachable, margin, dexterity, rows, None
        margin, dexterity = _scalar.measures_of_parts(leg_margin, unit, A, b, SINGULAR_TOL)
        q = np.array(first + second + third) if worst <= self._closure_tol else None
        return True, margin, dexterity, rotation, q

    def collisions_at(self, q: npt.NDArray[np.float64]) -> tuple[tuple[str, str], ...]:
        """Colliding link pairs (with the guard's margin) at a closed q (9,)."""
        pairs = self._checker.collisions(q, margin=self._margin)
        return tuple((str(a), str(b)) for a, b in pairs)

    def rotation_near(
        self,
        theta: npt.NDArray[np.float64],
        reference: npt.NDArray[np.float64] | None,
        design: object,
    ) -> npt.NDArray[np.float64] | None:
        """The home-mode R of one input (3,) by the compiled kernels, where it
        continues ``reference`` (within :data:`CONTINUITY`) or there is none; else
        None, and ``forward_kinematics(theta, reference=...)`` decides (inputs not
        finite or unreachable, the rare inputs where the home rule admits a second
        mode, another ``design`` than the guard's)."""
        values = theta.tolist()
        same = design is self.constants.design or design == self.constants.design
        if not same or not math.isfinite(sum(values)):
            return None
        rows = _scalar.fk_home(values, self.constants, self._fk_kernels)
        if rows is None:
            return None
        rotation = np.array(rows)
        if reference is not None and not np.max(np.abs(rotation - reference)) <= CONTINUITY:
            return None
        return rotation

    def configuration(
        self, theta: npt.NDArray[np.float64], rotation: npt.NDArray[np.float64]
    ) -> npt.NDArray[np.float64]:
        """The closed q (9,) of one input whose home-mode rotation is known."""
        from ..collision._configuration import rotation_configuration

        return rotation_configuration(
            theta.tolist(), rotation.tolist(), self._legs, self._closed_angles
        )

    def collisions(
        self, theta: Sequence[float], rotation: Rows | None
    ) -> tuple[tuple[str, str], ...]:
        """Colliding link pairs (with the guard's margin) of a reachable goal."""
        from ..collision._configuration import rotation_configuration

        if rotation is None:
            return ()
        q = rotation_configuration(theta, rotation, self._legs, self._closed_angles)
        pairs = self._checker.collisions(q, margin=self._margin)
        return tuple((str(a), str(b)) for a, b in pairs)
