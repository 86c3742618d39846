"""Self-collision at one input whichever assembly mode exists: :func:`check_input`
and the :class:`CollisionReport` it returns."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..kinematics import select_assembly
from ..kinematics._common import as_theta
from .checker import build_robot, checker_of
from .pairs import _THETA_LINKS, FloatArray, LinkPair, _check_margin

if TYPE_CHECKING:
    from ..model.robot import SPMRobot

__all__ = ["CollisionReport", "check_input"]


@dataclasses.dataclass(frozen=True)
class CollisionReport:
    """Self-collision at one input, whichever assembly mode exists.

    Attributes:
        theta: Input angles [rad], (3,).
        reachable: A home-mode assembly exists.
        mode: Assembly-mode label that was checked (``"+++/-"`` style), or None when
            no assembly exists and only the links that theta alone places were checked.
        home: The checked mode is the home assembly mode.
        checked_pairs: The link pairs that were checked.
        pairs: The colliding link pairs (with ``margin``).
        distances: Distance of every checked pair [m] (negative where they overlap).
        margin: The safety margin used [m].
    """

    theta: FloatArray
    reachable: bool
    mode: str | None
    home: bool
    checked_pairs: tuple[LinkPair, ...]
    pairs: tuple[LinkPair, ...]
    distances: dict[LinkPair, float]
    margin: float

    @property
    def collision(self) -> bool:
        """Any checked pair collides."""
        return bool(self.pairs)

    @property
    def min_distance(self) -> float:
        """Smallest distance over the checked pairs [m] (``inf`` if none)."""
        return float(min(self.distances.values(), default=math.inf))


def check_input(
    theta: npt.ArrayLike,
    robot: SPMRobot | None = None,
    *,
    margin: float = 0.0,
    distances: bool = True,
) -> CollisionReport:
    """Self-collision at input angles, even where the home assembly mode does not exist.

    The assembly mode is chosen by the library's one rule
    (:func:`~spm_pin.select_assembly`): the home mode where it exists, else the real
    assembly mode nearest to it, named in the report. With no real assembly at all,
    only the links that theta alone places (base and proximal links) are checked.

    Args:
        theta: Input angles [rad], (3,).
        robot: The robot (default: the prototype).
        margin: Safety margin [m].
        distances: Also compute the exact distance of every checked pair. Without
            them (a yes/no question, much cheaper) the report's ``distances`` are
            empty and its ``min_distance`` is ``inf``; ``pairs`` are the same.

    Raises:
        InputError: bad ``theta``, ``robot`` or ``margin``.
    """
    from ..model.robot import SPMRobot

    angles = as_theta(theta)
    if angles.shape != (3,):
        raise InputError(
            f"theta must have shape (3,) [rad], got shape {angles.shape}",
            argument="theta",
            value=theta,
        )
    margin = _check_margin(margin)
    if robot is None:
        robot = build_robot()
    elif not isinstance(robot, SPMRobot):
        raise InputError(
            f"robot must be an SPMRobot, got {type(robot).__name__}", argument="robot", value=robot
        )
    checker = checker_of(robot)
    chosen = select_assembly(angles, robot.design)
    mode = str(chosen.label) if bool(chosen.exists) else None
    q: FloatArray | None = None
    if bool(chosen.exists):
        q = robot._closed_configuration(angles, chosen.R)
    if q is not None:
        checked = checker.pairs
    else:
        checked = tuple(p for p in checker.pairs if p[0] in _THETA_LINKS and p[1] in _THETA_LINKS)
        # Base and proximal links are placed by theta alone: any q with these inputs
        # places them (the passive joints, left at zero, only move the other links).
        q = np.zeros(robot.model.nq)
        q[robot.actuated_q_idx] = angles
    found = checker._check(q, checker._plan(margin), False)
    pairs = tuple(p for p in found if p in checked)
    exact = checker._distances_q(q, list(checked), True, math.inf) if distances else {}
    return CollisionReport(
        theta=angles,
        reachable=bool(chosen.home),
        mode=mode,
        home=bool(chosen.home),
        checked_pairs=tuple(checked),
        pairs=pairs,
        distances=exact,
        margin=margin,
    )
