r"""Camera views of the SPM: the preset directions and the framing of the mechanism.

A view is a direction from which the camera looks at the centre of rotation O (the
spherical centre of the mechanism, about which the camera orbits when dragged):
an azimuth from +x towards +y and an elevation above the xy plane [rad].

Framing: the camera stands on that direction at the distance from which the
mechanism's bounding sphere about O (radius r, through the farthest vertex of any
link drawn) fits in meshcat's field of view with a margin,
``distance = margin * r / sin(fov / 2)``; then a zoom and a vertical lens shift make
the mechanism as projected fill a given share of the view, centred. The fit assumes
a view at least 4:3 (width:height), as browser windows are.

The presets (:data:`VIEWS`):

* ``iso`` (the default): chosen by :func:`choose_iso_direction` for the prototype at
  the published study's input theta = [60, 90, 120] deg: among directions on a grid
  (azimuth every 10 deg, elevation 15..60 deg every 5 deg) that see the platform's
  face (its normal within about 45 deg of the view direction, ``dot >= 0.7``), the
  one where the worst-seen distal link is seen best (the share of its vertices that
  no other link hides, for a camera far away), ties to the lowest. The result:
  azimuth -160 deg, elevation 15 deg (the old default, azimuth -30 deg and
  elevation 20 deg, saw the platform edge-on: dot 0.01).
* ``top``: from above (elevation 89 deg, so the orbit keeps z up), x to the right.
* ``front``: from -y, level: x to the right, z up.
* ``side``: from +x, level: y to the right, z up.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError

__all__ = [
    "CAMERA_FOV",
    "DEFAULT_VIEW",
    "VIEWS",
    "CameraFit",
    "View",
    "check_camera",
    "check_view",
    "choose_iso_direction",
    "fit_camera",
    "is_real",
    "view_direction",
]

FloatArray = npt.NDArray[np.float64]

#: meshcat's default camera: its vertical field of view [rad].
CAMERA_FOV = math.radians(75.0)
#: The camera fit assumes a view at least this wide (width / height).
MIN_ASPECT = 4.0 / 3.0
#: The camera stands this much further than the bounding sphere needs (a gentler
#: perspective than at the sphere itself; zoom then frames the robot).
DISTANCE_MARGIN = 2.0
#: Scene path of meshcat's camera (three.js, y-up coordinates).
CAMERA_PATH = "/Cameras/default/rotated/<object>"

#: The rule of :func:`choose_iso_direction`: the grid searched [deg], the least
#: cosine between the platform normal and the view direction, every how many
#: vertices of a distal link are tested.
ISO_AZIMUTHS_DEG = tuple(range(-180, 180, 10))
ISO_ELEVATIONS_DEG = tuple(range(15, 65, 5))
ISO_MIN_FACING = 0.7
ISO_POINT_STEP = 3


@dataclasses.dataclass(frozen=True)
class View:
    """A camera direction seen from O.

    Attributes:
        azimuth: From +x towards +y [rad].
        elevation: Above the xy plane [rad], in (-pi/2, pi/2).
        description: What the view shows.
    """

    azimuth: float
    elevation: float
    description: str


#: The preset views, by name (the first is the default).
VIEWS: dict[str, View] = {
    "iso": View(
        math.radians(-160.0),
        math.radians(15.0),
        "the three legs and the platform's face (chosen for the study's input)",
    ),
    "top": View(math.radians(-90.0), math.radians(89.0), "from above: x right, y up"),
    "front": View(math.radians(-90.0), 0.0, "from -y, level: x right, z up"),
    "side": View(0.0, 0.0, "from +x, level: y right, z up"),
}
#: The view of a new :class:`~spm_pin.viz.Visualizer`.
DEFAULT_VIEW = "iso"


def check_view(name: Any) -> View:
    """The preset called ``name``.

    Raises:
        InputError: not a name of :data:`VIEWS` (the message lists them).
    """
    if not isinstance(name, str) or name not in VIEWS:
        raise InputError(
            f"view must be one of {', '.join(VIEWS)}, got {name!r}", argument="view", value=name
        )
    return VIEWS[name]


def is_real(value: Any) -> bool:
    """``value`` is a finite real number (not a bool)."""
    return (
        isinstance(value, (int, float, np.integer, np.floating))
        and not isinstance(value, (bool, np.bool_))
        and math.isfinite(float(value))
    )


def check_camera(azimuth: Any, elevation: Any, fill: Any) -> tuple[float, float, float]:
    """A camera direction and fill, checked: ``(azimuth, elevation, fill)`` as floats.

    Raises:
        InputError: one is not a finite number, the elevation is not in
            (-pi/2, pi/2) [rad] or the fill not in (0, 1].
    """
    for name, value in (("azimuth", azimuth), ("elevation", elevation), ("fill", fill)):
        if not is_real(value):
            raise InputError(
                f"{name} must be a finite number, got {value!r}", argument=name, value=value
            )
    if not abs(elevation) < math.pi / 2:
        raise InputError(
            f"elevation must lie in (-pi/2, pi/2) [rad], got {elevation!r}",
            argument="elevation",
            value=elevation,
        )
    if not 0 < fill <= 1:
        raise InputError(f"fill must lie in (0, 1], got {fill!r}", argument="fill", value=fill)
    return float(azimuth), float(elevation), float(fill)


def view_direction(azimuth: float, elevation: float) -> FloatArray:
    """Unit vector from O towards the camera."""
    ce = math.cos(elevation)
    return np.array([ce * math.cos(azimuth), ce * math.sin(azimuth), math.sin(elevation)])


def _basis(back: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Right and up of a camera looking along ``-back`` with z up."""
    right = np.cross(-back, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -back)
    return right, up


@dataclasses.dataclass(frozen=True)
class CameraFit:
    """Where the camera stands and how it is zoomed to frame some points.

    Attributes:
        eye: Camera position in the world (z-up) [m]; it looks at O.
        zoom: three.js zoom (divides the tangent of the half field of view).
        shift: Vertical lens shift, in view heights (three.js ``view.offsetY``).
        radius: Radius of the bounding sphere about O of the points [m].
    """

    eye: FloatArray
    zoom: float
    shift: float
    radius: float

    def properties(self) -> list[tuple[str, Any]]:
        """(property, value) pairs of meshcat's camera node (:data:`CAMERA_PATH`)."""
        x, y, z = (float(c) for c in self.eye)
        view = {
            "enabled": True,
            "fullWidth": 1.0,
            "fullHeight": 1.0,
            "offsetX": 0.0,
            "offsetY": float(self.shift),
            "width": 1.0,
            "height": 1.0,
        }
        # three.js is y-up: the world point (x, y, z) is (x, z, -y) there.
        return [("position", [x, z, -y]), ("zoom", float(self.zoom)), ("view", view)]


def fit_camera(points: FloatArray, back: FloatArray, fill: float) -> CameraFit:
    """Frame ``points`` (N, 3) from the direction ``back`` (unit, from O to the camera).

    The camera stands at ``DISTANCE_MARGIN * r / sin(CAMERA_FOV / 2)`` from O (r: the
    bounding sphere about O of the points), looks at O, and is zoomed and shifted so
    the points fill ``fill`` of the view height (or of a 4:3 width), centred.
    """
    radius = float(np.linalg.norm(points, axis=1).max())
    distance = DISTANCE_MARGIN * radius / math.sin(CAMERA_FOV / 2)
    eye = distance * back
    right, up = _basis(back)
    relative = points - eye
    depth = relative @ -back
    x = relative @ right / depth
    y = relative @ up / depth
    half = max(float(np.ptp(y)), 2 * float(np.max(np.abs(x))) / MIN_ASPECT) / (2 * fill)
    zoom = math.tan(CAMERA_FOV / 2) / half
    shift = -0.5 * float(y.max() + y.min()) / (2 * half)
    return CameraFit(eye=eye, zoom=zoom, shift=shift, radius=radius)


def _visible_share(
    points: FloatArray, triangles: FloatArray, back: FloatArray, right: FloatArray, up: FloatArray
) -> float:
    """Share of ``points`` (N, 3) that no triangle of ``triangles`` (F, 3, 3) hides from a
    camera far away along ``back`` (orthographic rays)."""
    p = np.stack([points @ right, points @ up, points @ back], axis=-1)
    t = np.stack([triangles @ right, triangles @ up, triangles @ back], axis=-1)
    a = t[:, 0]
    e1, e2 = t[:, 1] - a, t[:, 2] - a
    den = e1[:, 0] * e2[:, 1] - e2[:, 0] * e1[:, 1]
    keep = np.abs(den) > 1e-12  # triangles seen edge-on hide nothing
    a, e1, e2, den = a[keep], e1[keep], e2[keep], den[keep]
    d = p[:, None, :2] - a[None, :, :2]  # (N, F, 2)
    s = (d[..., 0] * e2[:, 1] - e2[:, 0] * d[..., 1]) / den
    r = (e1[:, 0] * d[..., 1] - d[..., 0] * e1[:, 1]) / den
    inside = (s >= 0) & (r >= 0) & (s + r <= 1)
    depth = a[:, 2] + s * e1[:, 2] + r * e2[:, 2]  # nearer the camera: larger
    hidden = np.any(inside & (depth > p[:, None, 2] + 1e-4), axis=1)
    return 1.0 - float(hidden.mean())


def choose_iso_direction(
    links: dict[str, tuple[npt.ArrayLike, npt.ArrayLike]], platform_normal: npt.ArrayLike
) -> tuple[float, float]:
    """The rule that chose the ``iso`` view: (azimuth, elevation) [rad].

    Over the grid :data:`ISO_AZIMUTHS_DEG` x :data:`ISO_ELEVATIONS_DEG`, keep the
    directions d with ``platform_normal . d >= ISO_MIN_FACING`` (the platform's face
    towards the camera); score each by the least, over the three distal links, share
    of the link's vertices (every :data:`ISO_POINT_STEP`-th) that no other link hides
    from a camera far along d; take the best score, ties (within 1e-9) to the lowest
    elevation.

    Args:
        links: Per link name (``distal_1`` .. ``distal_3`` and the others that may
            hide them): its mesh in the world, vertices (V, 3) [m] and triangles
            (F, 3) (vertex indices).
        platform_normal: The platform's z axis in the world, shape (3,).

    Raises:
        InputError: no direction of the grid sees the platform's face.
    """
    normal = np.asarray(platform_normal, dtype=float)
    meshes = {
        name: (np.asarray(v, dtype=float), np.asarray(f, dtype=np.intp))
        for name, (v, f) in links.items()
    }
    distal = [f"distal_{i}" for i in (1, 2, 3)]
    occluders = {
        name: np.concatenate([v[f] for other, (v, f) in meshes.items() if other != name])
        for name in distal
    }
    best: tuple[float, float, float] | None = None  # (score, -elevation, azimuth) [deg]
    for elevation in ISO_ELEVATIONS_DEG:
        for azimuth in ISO_AZIMUTHS_DEG:
            back = view_direction(math.radians(azimuth), math.radians(elevation))
            if normal @ back < ISO_MIN_FACING:
                continue
            right, up = _basis(back)
            score = min(
                _visible_share(meshes[name][0][::ISO_POINT_STEP], occluders[name], back, right, up)
                for name in distal
            )
            if best is None or score > best[0] + 1e-9:
                best = (score, -elevation, azimuth)
    if best is None:
        raise InputError(
            "no direction of the grid sees the platform's face",
            argument="platform_normal",
            value=normal,
        )
    return math.radians(best[2]), math.radians(-best[1])
