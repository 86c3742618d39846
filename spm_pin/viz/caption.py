"""The caption of a saved page: the pose shown, in one line of text.

:func:`pose_caption` names the design, the input angles [deg], the assembly mode
shown (and whether it is the home mode) and the colliding link pairs, e.g.
``prototype: theta = [60, 90, 120] deg, home assembly mode +++/+; no collision``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..model.robot import SPMRobot

__all__ = ["pose_caption"]

FloatArray = npt.NDArray[np.float64]
LinkPair = tuple[str, str]


def pose_caption(
    robot: SPMRobot, q: FloatArray, label: str, home: bool, pairs: list[LinkPair]
) -> str:
    """One line for a page: the design, the input angles, the mode and the collisions.

    Args:
        robot: The robot shown.
        q: The configuration shown (9,) [rad].
        label: Label of its assembly mode.
        home: That mode is the home assembly mode.
        pairs: The colliding link pairs.
    """
    theta_deg = np.degrees(q[robot.actuated_q_idx])
    angles = ", ".join(f"{value:g}" for value in np.round(theta_deg, 3))
    kind = "home assembly mode" if home else "assembly mode"
    text = f"{robot.design.name}: theta = [{angles}] deg, {kind} {label}"
    if not home:
        text += " (no home-mode assembly; the real mode nearest to it)"
    if pairs:
        links = ", ".join(f"{a}-{b}" for a, b in pairs)
        text += f"; colliding (black): {links}"
    else:
        text += "; no collision"
    return text
