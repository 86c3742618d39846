"""The overlay arrows of the SPM's scene: the joint axes and the platform frame.

Scene layout (under :data:`OVERLAYS_PATH`, ``/meshcat/spm/overlays``):

* ``joint_axes/<u_i|w_i|v_i>``: arrows from O along the joint axes u_i (fixed to the
  base), w_i (moving with proximal link i) and v_i (moving with the platform), in
  the colours of :data:`~spm_pin.viz.key.JOINT_AXIS_COLORS`.
* ``platform_frame/<x|y|z>``: the platform frame's axes (red, green, blue), moving
  with the platform.

Each arrow is a meshcat cylinder (the shaft) and a cone (the head), drawn in the home
pose; the scene moves it with its node (:func:`overlay_transforms`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import meshcat.geometry as mg
import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ._scene import Scene
from .key import FRAME_COLORS, JOINT_AXIS_COLORS, Color, material

__all__ = [
    "OVERLAYS",
    "OVERLAYS_PATH",
    "Arrow",
    "draw_arrows",
    "overlay_arrows",
    "overlay_transforms",
]

FloatArray = npt.NDArray[np.float64]

#: Scene path of the overlays.
OVERLAYS_PATH = "/meshcat/spm/overlays"
#: Names of the overlays, each a node under :data:`OVERLAYS_PATH`.
OVERLAYS = ("joint_axes", "platform_frame")

_ARROW_RADIUS = 0.0015  # [m]
_HEAD_LENGTH = 0.012  # [m]
_HEAD_RADIUS = 0.004  # [m]


@dataclasses.dataclass(frozen=True)
class Arrow:
    """An overlay arrow: drawn at ``path`` along ``direction`` (at home) from O; it
    moves with the scene node ``node``, which belongs to the overlay ``overlay``."""

    overlay: str
    node: str
    path: str
    direction: FloatArray
    length: float
    color: Color


def overlay_arrows(design: SPMDesign, moving: Iterable[FloatArray]) -> list[Arrow]:
    """The arrows of the joint axes and of the platform frame.

    Args:
        design: The design whose joint axes (at home) are drawn.
        moving: Vertices (n, 3) of the moving links [m]; the joint-axis arrows reach
            1.1 times past the farthest from O, the platform frame's 0.8 times that.
    """
    length = 1.1 * max(float(np.linalg.norm(vertices, axis=1).max()) for vertices in moving)
    arrows = []
    for letter, axes in (("u", design.u), ("w", design.w0), ("v", design.v0)):
        for i in range(3):
            node = f"{OVERLAYS_PATH}/joint_axes/{letter}_{i + 1}"
            direction = np.array(axes[i], dtype=float)
            color = JOINT_AXIS_COLORS[letter]
            arrows.append(Arrow("joint_axes", node, node, direction, length, color))
    frame = f"{OVERLAYS_PATH}/platform_frame"
    for i, (letter, color) in enumerate(FRAME_COLORS.items()):
        path = f"{frame}/{letter}"
        arrows.append(Arrow("platform_frame", frame, path, np.eye(3)[i], 0.8 * length, color))
    return arrows


def overlay_transforms(placements: dict[str, FloatArray]) -> dict[str, FloatArray]:
    """Scene path -> transform (4, 4) of every moving overlay node, from the links'
    world placements (4, 4) by link name."""
    transforms = {}
    for i in range(1, 4):
        transforms[f"{OVERLAYS_PATH}/joint_axes/w_{i}"] = placements[f"proximal_{i}"]
        transforms[f"{OVERLAYS_PATH}/joint_axes/v_{i}"] = placements["platform"]
    transforms[f"{OVERLAYS_PATH}/platform_frame"] = placements["platform"]
    return transforms


def draw_arrows(scene: Scene, arrows: Iterable[Arrow]) -> None:
    """Put each arrow's shaft and head into the scene, at home."""
    for arrow in arrows:
        shaft = mg.Cylinder(arrow.length - _HEAD_LENGTH, _ARROW_RADIUS)
        head = mg.Cylinder(_HEAD_LENGTH, radiusTop=0.0, radiusBottom=_HEAD_RADIUS)
        rotation = _rotation_y_to(arrow.direction)
        middle = 0.5 * (arrow.length - _HEAD_LENGTH) * arrow.direction
        tip = (arrow.length - 0.5 * _HEAD_LENGTH) * arrow.direction
        for part, geometry, position in (("shaft", shaft, middle), ("head", head, tip)):
            scene.set_object(f"{arrow.path}/{part}", mg.Mesh(geometry, material(arrow.color)))
            scene.set_transform(f"{arrow.path}/{part}", _transform(rotation, position))


def _rotation_y_to(direction: FloatArray) -> FloatArray:
    """A rotation taking +y (meshcat's cylinder axis) to the unit vector ``direction``."""
    y = direction / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    result: FloatArray = np.stack([x, y, z], axis=1)
    return result


def _transform(rotation: FloatArray, translation: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = translation
    return T
