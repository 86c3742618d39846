r"""Where links touch: contact markers, penetration depths and the nearest clearance.

For a configuration q, :func:`contacts` gives every colliding link pair's witness
points and penetration depth, and :func:`nearest_clearance` the closest points of the
nearest non-colliding pair. Both measure the links as the collision layer does
(:meth:`~spm_pin.collision.CollisionChecker.distances`: the minimum over the links'
convex pieces, GJK/EPA with coal), so a contact's ``distance`` equals
``robot.distances(q)[pair]``; the witness points are coal's nearest points of the
piece pair that gives that minimum (overlapping pieces: the ends of the penetration
vector, each on one link's surface and inside the other).

Scene layout (under :data:`CONTACTS_PATH`, ``/meshcat/spm/contacts``):

* ``<a>-<b>``, one node per colliding pair (e.g. ``proximal_2-distal_3``): two red
  spheres ``p1``, ``p2`` at the witness points and a red segment ``segment`` between
  them, drawn over the links (no depth test: the points lie inside them).
* ``clearance``, on request: the nearest non-colliding pair's closest points, joined
  by a green segment.

On a saved page, :func:`contacts_html` lists them at the top right, below meshcat's
controls (``#spm-contacts``,
one ``li.spm-contact`` per pair with ``data-pair`` and ``data-depth-mm``, and
``li.spm-clearance`` with ``data-clearance-mm``).
"""

from __future__ import annotations

import dataclasses
import html
import math
from typing import Any

import coal
import meshcat.geometry as mg
import numpy as np
import numpy.typing as npt

from ..collision import checker_of
from ..model.robot import SPMRobot
from ._scene import Scene

__all__ = [
    "CLEARANCE_COLOR",
    "CONTACTS_PATH",
    "CONTACT_COLOR",
    "Contact",
    "contact_path",
    "contacts",
    "contacts_html",
    "draw_contacts",
    "nearest_clearance",
]

FloatArray = npt.NDArray[np.float64]
LinkPair = tuple[str, str]

#: Scene path of the contact markers.
CONTACTS_PATH = "/meshcat/spm/contacts"
#: Colour of the contact markers (0xRRGGBB).
CONTACT_COLOR = 0xE01010
#: Colour of the clearance segment (0xRRGGBB).
CLEARANCE_COLOR = 0x10A040
_MARKER_RADIUS = 0.0025  # [m]
_SEGMENT_RADIUS = 0.0008  # [m]


@dataclasses.dataclass(frozen=True)
class Contact:
    """Two links' nearest or deepest points.

    Attributes:
        pair: The link pair (as in :attr:`~spm_pin.collision.CollisionChecker.pairs`).
        distance: Their distance [m]; negative when they overlap (minus the
            penetration depth, as ``robot.distances``).
        p1: Witness point on (or, overlapping, inside) the first link, world [m].
        p2: The same for the second link [m].
    """

    pair: LinkPair
    distance: float
    p1: FloatArray
    p2: FloatArray

    @property
    def depth(self) -> float:
        """Penetration depth [m] (0 when the links do not overlap)."""
        return max(0.0, -self.distance)

    @property
    def name(self) -> str:
        """``<a>-<b>``, the pair's node name."""
        return f"{self.pair[0]}-{self.pair[1]}"


def contact_path(pair: LinkPair) -> str:
    """Scene path of a colliding pair's markers."""
    return f"{CONTACTS_PATH}/{pair[0]}-{pair[1]}"


_SHAPES: dict[int, list[tuple[str, Any]]] = {}


def _shapes(robot: SPMRobot) -> list[tuple[str, Any]]:
    """(link, coal convex shape in the link frame) of every convex piece."""
    checker = checker_of(robot)
    known = _SHAPES.get(id(checker))
    if known is None:
        known = []
        for piece in checker.pieces:
            vector = coal.StdVec_Vec3s()
            for point in np.ascontiguousarray(piece.vertices, dtype=np.float64):
                vector.append(point)
            known.append((piece.link, coal.Convex.convexHull(vector, True, None)))
        _SHAPES.clear()  # one robot at a time
        _SHAPES[id(checker)] = known
    return known


def _measure(robot: SPMRobot, q: FloatArray, pairs: list[LinkPair]) -> list[Contact]:
    """Each pair's minimum over its piece pairs, with coal's witness points."""
    placements = robot.placements(q)
    transforms = {
        name: coal.Transform3s(se3.rotation, se3.translation) for name, se3 in placements.items()
    }
    by_link: dict[str, list[Any]] = {}
    for link, shape in _shapes(robot):
        by_link.setdefault(link, []).append(shape)
    request = coal.DistanceRequest()
    request.enable_signed_distance = True
    out = []
    for a, b in pairs:
        best: tuple[float, FloatArray, FloatArray] | None = None
        for shape_a in by_link.get(a, []):
            for shape_b in by_link.get(b, []):
                result = coal.DistanceResult()
                d = coal.distance(shape_a, transforms[a], shape_b, transforms[b], request, result)
                if best is None or d < best[0]:
                    p1 = np.array(result.getNearestPoint1(), dtype=float)
                    p2 = np.array(result.getNearestPoint2(), dtype=float)
                    best = (float(d), p1, p2)
        if best is not None:
            out.append(Contact((a, b), *best))
    return out


def contacts(
    robot: SPMRobot, q: npt.ArrayLike, pairs: list[LinkPair] | None = None
) -> list[Contact]:
    """Witness points and depth of each colliding link pair at q.

    Args:
        robot: The robot.
        q: A joint configuration (9,) [rad].
        pairs: The colliding pairs (default: ``robot.collisions(q)``).

    Returns:
        One :class:`Contact` per pair, in the order given.
    """
    array = np.asarray(q, dtype=float)
    if pairs is None:
        pairs = checker_of(robot).collisions(array)
    return _measure(robot, array, list(pairs))


def nearest_clearance(robot: SPMRobot, q: npt.ArrayLike) -> Contact | None:
    """Closest points of the nearest non-colliding link pair at q (None if none).

    The pair is the one of least positive ``robot.distances(q)``; its ``distance`` is
    that clearance [m] and ``|p2 - p1|`` equals it.
    """
    array = np.asarray(q, dtype=float)
    distances = checker_of(robot).distances(array)
    free = {pair: d for pair, d in distances.items() if 0.0 < d < math.inf}
    if not free:
        return None
    pair = min(free, key=free.__getitem__)
    return _measure(robot, array, [pair])[0]


def _cylinder(p1: FloatArray, p2: FloatArray) -> tuple[mg.Cylinder, FloatArray]:
    """A cylinder (meshcat: along y, centred) from p1 to p2 and its transform."""
    axis = p2 - p1
    length = float(np.linalg.norm(axis))
    transform = np.eye(4)
    transform[:3, 3] = 0.5 * (p1 + p2)
    if length > 1e-12:
        y = axis / length
        helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        x = np.cross(y, helper)
        x /= np.linalg.norm(x)
        transform[:3, :3] = np.column_stack([x, y, np.cross(x, y)])
    return mg.Cylinder(max(length, 1e-6), _SEGMENT_RADIUS), transform


def _draw(scene: Scene, path: str, contact: Contact, color: int, spheres: bool) -> None:
    # Drawn over the links (the points lie inside them): no depth test, and
    # "transparent" so three.js draws them after the opaque links.
    material = mg.MeshPhongMaterial(
        color=color, shininess=60, transparent=True, depthTest=False, depthWrite=False
    )
    cylinder, transform = _cylinder(contact.p1, contact.p2)
    scene.set_object(f"{path}/segment", mg.Mesh(cylinder, material))
    scene.set_transform(f"{path}/segment", transform)
    if spheres:
        for name, point in (("p1", contact.p1), ("p2", contact.p2)):
            scene.set_object(f"{path}/{name}", mg.Mesh(mg.Sphere(_MARKER_RADIUS), material))
            at = np.eye(4)
            at[:3, 3] = point
            scene.set_transform(f"{path}/{name}", at)
    scene.set_property(path, "visible", True)


def draw_contacts(scene: Scene, found: list[Contact], clearance: Contact | None) -> None:
    """Replace the markers under :data:`CONTACTS_PATH` with those of ``found`` and
    (when given) the clearance segment; the old ones are hidden."""
    names = {contact.name for contact in found}
    for child in scene.children(CONTACTS_PATH):
        if child not in names and not (child == "clearance" and clearance is not None):
            scene.set_property(f"{CONTACTS_PATH}/{child}", "visible", False)
    for contact in found:
        _draw(scene, contact_path(contact.pair), contact, CONTACT_COLOR, spheres=True)
    if clearance is not None:
        _draw(scene, f"{CONTACTS_PATH}/clearance", clearance, CLEARANCE_COLOR, spheres=True)


def shown_contacts(scene: Scene) -> list[str]:
    """Names of the visible nodes under :data:`CONTACTS_PATH`."""
    return [
        child
        for child in scene.children(CONTACTS_PATH)
        if scene.property(f"{CONTACTS_PATH}/{child}", "visible")
    ]


def contacts_html(found: list[Contact], clearance: Contact | None, checked: bool = True) -> str:
    """The ``#spm-contacts`` overlay: each colliding pair's depth, the clearance."""
    items = []
    for contact in found:
        depth_mm = 1000.0 * contact.depth
        items.append(
            f'<li class="spm-contact" data-pair="{html.escape(contact.name)}" '
            f'data-depth-mm="{depth_mm:.3f}">{html.escape(contact.name)}: '
            f"{depth_mm:.1f} mm deep</li>"
        )
    if not found and checked:
        items.append('<li class="spm-no-contact">no collision</li>')
    if clearance is not None:
        mm = 1000.0 * clearance.distance
        items.append(
            f'<li class="spm-clearance" data-pair="{html.escape(clearance.name)}" '
            f'data-clearance-mm="{mm:.3f}">nearest: {html.escape(clearance.name)}, '
            f"{mm:.2f} mm clear</li>"
        )
    if not items:
        return ""
    return (
        '<ul id="spm-contacts" style="position:absolute;right:8px;top:40px;margin:0;'
        "padding:4px 8px;list-style:none;font:12px/1.5 sans-serif;color:#222;"
        'background:rgba(255,255,255,0.85);border-radius:3px;pointer-events:none;z-index:10">'
        + "".join(items)
        + "</ul>\n"
    )
