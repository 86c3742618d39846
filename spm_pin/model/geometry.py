r"""Link shapes of an SPM: triangle meshes and mass properties from an :class:`SPMDesign`.

Every joint axis passes through the centre O and the robot tree uses identity joint
placements, so every link frame coincides with the world frame at home (theta = 0,
R = identity). Each mesh is therefore given in world coordinates at home [m].

The links (see docs/conventions.md; sizes from :class:`~spm_pin.design.LinkDimensions`):

* ``base``: a round plate (``base_radius``, ``base_thickness``) centred ``base_depth``
  below O on the base axis (the mean of the u_i, -z for the coaxial SPM); three
  servo blocks (``servo_size`` = width x length x height, 33.5 x 58.5 x 44 mm for the
  XM540) standing on it at 120 degrees, between the legs; the central hub column
  (``hub_radius``) up the axis to just below the proximal sphere; for a coaxial
  design, the servo pinions (gear cylinders on the servo shafts) reaching up to their
  leg's driven gear.
* ``proximal_i``: a curved plate on the inner sphere (``proximal_radius``,
  ``proximal_thickness``, ``proximal_width``) along the great circle from near u_i to
  w_i0, with a round boss around w_i0. It starts a little away from u_i (where the
  three plates would overlap) and a straight spoke carries it down to its drive shaft
  below the sphere: for a coaxial design three nested tubes around the hub, the
  innermost (leg 1) reaching highest, each ending in a driven gear at its own height
  next to its servo's pinion; otherwise a short tube on u_i.
* ``distal_i``: a curved plate on the outer sphere (``distal_radius``,
  ``distal_thickness``, ``distal_width``) along the great circle from w_i0 to v_i0,
  round bosses at both ends, and the two joint pins (``joint_radius``): along w_i0
  from the proximal plate's outer face to the distal sphere, and along v_i0 from the
  distal sphere to the platform bracket.
* ``platform``: a round plate (``platform_radius``, ``platform_thickness``) centred
  ``platform_height`` above O with its normal +z, and three brackets, each a boss on
  v_i0 just outside the distal sphere (so the distal plate's end meets it along
  v_i0) joined to the plate by a rising bar and a radial bar.

Every shape is a plate or solid with real thickness, so collision checks with these
meshes find contacts where the real links would touch. Each link mesh is the
concatenation of closed primitives (swept plates, cylinders, tubes, boxes, convex
hulls): every body is watertight with outward normals, so the mesh is a volume, but
bodies of one link may overlap a little where they join. Mass properties are the sum
of the bodies' (PLA at ``density``; the base's servo blocks are solids of
``servo_mass`` each), so the overlaps are counted twice: a few percent of a link's
mass at most.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import trimesh

from ..design import SPMDesign

__all__ = [
    "LINK_NAMES",
    "LinkInertia",
    "LinkPart",
    "combine_mass_properties",
    "link_inertias",
    "link_meshes",
    "link_parts",
    "part_mass_properties",
]

FloatArray = npt.NDArray[np.float64]

#: The link names of docs/conventions.md, in tree order.
LINK_NAMES: tuple[str, ...] = (
    "base",
    "proximal_1",
    "proximal_2",
    "proximal_3",
    "distal_1",
    "distal_2",
    "distal_3",
    "platform",
)

# Construction sizes that LinkDimensions does not hold [m].
_CLEARANCE = 0.001  # between parts that move against each other
_TUBE_WALL = 0.003  # wall of a proximal drive tube
_TUBE_STEP = 0.006  # height step between the tops of the nested drive tubes
_TOP_GAP = 0.003  # between the proximal sphere's outer face and the top drive tube
_SPOKE_OVERLAP = 0.004  # how far a spoke reaches down over its tube
_SPOKE_JOIN = math.radians(2.0)  # how far the spoke reaches into the proximal plate
_SPOKE_TAPER = 0.6  # width of a spoke at its tube over the plate's width
_GEAR_THICKNESS = 0.006
_GEAR_GAP = 0.002
_PINION_RADIUS = 0.012
_SHORT_TUBE = 0.020  # drive tube length of a non-coaxial design
_SERVO_MARGIN = 0.002  # servo corner inside the base plate rim
_BRACKET_INSET = 0.010  # how far the radial bracket bar reaches over the platform plate
_MIN_BAND_ANGLE = math.radians(5.0)

# Mesh resolution.
_ROUND_SECTIONS = 32  # bosses, pins, pinions
_LARGE_SECTIONS = 48  # plates, tubes, gears, hub
_BAND_STEP = math.radians(3.0)  # sweep step of a curved plate
_MIN_BAND_SEGMENTS = 6


@dataclasses.dataclass(frozen=True)
class LinkInertia:
    """Mass properties of a link, in the link frame (= world frame at home).

    Attributes:
        mass: Mass [kg].
        com: Centre of mass, shape (3,) [m].
        inertia: Inertia tensor about the centre of mass, shape (3, 3) [kg m^2],
            symmetric positive definite.
    """

    mass: float
    com: FloatArray
    inertia: FloatArray


@dataclasses.dataclass(frozen=True)
class LinkPart:
    """One closed body of a link: a watertight mesh and its density.

    Attributes:
        name: What the body is (``"plate"``, ``"servo_2"``, ...).
        mesh: Watertight triangle mesh with outward normals, world frame at home [m].
        density: Density [kg/m^3] (a servo block's is its mass over its volume).
    """

    name: str
    mesh: trimesh.Trimesh
    density: float


# ----------------------------------------------------------------- mass properties
def part_mass_properties(mesh: trimesh.Trimesh, density: float) -> LinkInertia:
    """Mass, centre of mass and inertia about it of one closed mesh of uniform density.

    Args:
        mesh: Watertight mesh with outward normals [m].
        density: Density [kg/m^3].

    Returns:
        The mass properties in the mesh's frame.
    """
    props = mesh.mass_properties  # density 1: mass = volume
    return LinkInertia(
        mass=float(props["volume"]) * density,
        com=np.array(props["center_mass"], dtype=float),
        inertia=np.array(props["inertia"], dtype=float) * density,
    )


def combine_mass_properties(parts: Sequence[LinkInertia]) -> LinkInertia:
    r"""Mass properties of rigidly joined bodies (parallel-axis theorem).

    m = sum m_k, c = sum m_k c_k / m, I = sum (I_k + m_k (|d_k|^2 E - d_k d_k^T))
    with d_k = c_k - c.
    """
    mass = sum(p.mass for p in parts)
    com = sum((p.mass * p.com for p in parts), np.zeros(3)) / mass
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.com - com
        inertia += p.inertia + p.mass * (float(d @ d) * np.eye(3) - np.outer(d, d))
    inertia = 0.5 * (inertia + inertia.T)
    return LinkInertia(mass=float(mass), com=com, inertia=inertia)


# ---------------------------------------------------------------------- primitives
def _unit(vector: FloatArray) -> FloatArray:
    return np.asarray(vector / np.linalg.norm(vector), dtype=np.float64)


def _perpendicular(axis: FloatArray) -> FloatArray:
    """A unit vector perpendicular to ``axis`` (deterministic)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    return _unit(helper - (helper @ axis) * axis)


def _arc_frame(start: FloatArray, end: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(e1, e2, n): e1 = start, e2 in the plane of the arc towards end, n = e1 x e2."""
    e1 = _unit(start)
    e2 = end - (end @ e1) * e1
    e2 = _unit(e2) if np.linalg.norm(e2) > 1e-9 else _perpendicular(e1)
    return e1, e2, np.cross(e1, e2)


def _oriented(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh with its faces flipped if its signed volume is negative."""
    if mesh.volume < 0:
        mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False)
    return mesh


def _plate_corners(radius: float, thickness: float, width: float) -> list[tuple[float, float]]:
    """(rho, psi) of the cross-section corners of a curved plate, in loop order."""
    psi0 = width / (2.0 * radius)
    rho_in, rho_out = radius - thickness / 2, radius + thickness / 2
    return [(rho_in, -psi0), (rho_out, -psi0), (rho_out, psi0), (rho_in, psi0)]


def _plate_section(
    start: FloatArray, end: FloatArray, s: float, radius: float, thickness: float, width: float
) -> FloatArray:
    """The 4 corners (4, 3) of the cross-section at arc angle s of a curved plate
    (see :func:`_spherical_plate`)."""
    e1, e2, n = _arc_frame(start, end)
    centre = math.cos(s) * e1 + math.sin(s) * e2
    corners = _plate_corners(radius, thickness, width)
    return np.array([rho * (math.cos(psi) * centre + math.sin(psi) * n) for rho, psi in corners])


def _spherical_plate(
    start: FloatArray,
    end: FloatArray,
    s0: float,
    s1: float,
    radius: float,
    thickness: float,
    width: float,
) -> trimesh.Trimesh:
    r"""A curved plate on the sphere of ``radius`` around O along a great circle.

    The centre line is p(s) = radius (cos s e1 + sin s e2), s in [s0, s1], with e1 =
    start and e2 towards end. Its cross-section spans radii radius +- thickness/2 and
    lateral angles +-psi0 = width / (2 radius) about the arc (small circles, so the
    plate has the constant ``width`` along it):
    x = rho (cos psi (cos s e1 + sin s e2) + sin psi n).
    """
    e1, e2, n = _arc_frame(start, end)
    segments = max(_MIN_BAND_SEGMENTS, math.ceil((s1 - s0) / _BAND_STEP))
    s = np.linspace(s0, s1, segments + 1)
    loop = _plate_corners(radius, thickness, width)
    centre = np.cos(s)[:, None] * e1 + np.sin(s)[:, None] * e2  # (N, 3)
    vertices = np.concatenate(
        [rho * (math.cos(psi) * centre + math.sin(psi) * n) for rho, psi in loop], axis=0
    ).reshape(4, segments + 1, 3)
    vertices = vertices.transpose(1, 0, 2).reshape(-1, 3)  # index = 4 k + j
    faces = []
    for k in range(segments):
        for j in range(4):
            a, b = 4 * k + j, 4 * k + (j + 1) % 4
            faces += [(a, b, b + 4), (a, b + 4, a + 4)]
    last = 4 * segments
    faces += [(0, 2, 1), (0, 3, 2), (last, last + 1, last + 2), (last, last + 2, last + 3)]
    return _oriented(trimesh.Trimesh(vertices, np.array(faces), process=False))


def _cylinder(
    axis: FloatArray, d0: float, d1: float, radius: float, sections: int = _ROUND_SECTIONS
) -> trimesh.Trimesh:
    """A solid cylinder on ``axis`` through O, from distance d0 to d1 along it."""
    segment = np.array([d0 * axis, d1 * axis])
    return _oriented(trimesh.creation.cylinder(radius=radius, segment=segment, sections=sections))


def _tube(
    axis: FloatArray,
    d0: float,
    d1: float,
    r_min: float,
    r_max: float,
    sections: int = _LARGE_SECTIONS,
) -> trimesh.Trimesh:
    """A tube (annulus) on ``axis`` through O, from distance d0 to d1 along it."""
    segment = np.array([d0 * axis, d1 * axis])
    mesh = trimesh.creation.annulus(r_min=r_min, r_max=r_max, segment=segment, sections=sections)
    return _oriented(mesh)


def _box(centre: FloatArray, axes: FloatArray, extents: Sequence[float]) -> trimesh.Trimesh:
    """A box with its edges along the rows of ``axes`` (a right-handed frame)."""
    transform = np.eye(4)
    transform[:3, :3] = np.asarray(axes).T
    transform[:3, 3] = centre
    return _oriented(trimesh.creation.box(extents=list(extents), transform=transform))


def _bar(
    p0: FloatArray, p1: FloatArray, thickness_dir: FloatArray, thickness: float, width: float
) -> trimesh.Trimesh | None:
    """A rectangular bar from p0 to p1 (None if they coincide)."""
    length = float(np.linalg.norm(p1 - p0))
    if length < 1e-9:
        return None
    along = (p1 - p0) / length
    across = thickness_dir - (thickness_dir @ along) * along
    across = _unit(across) if np.linalg.norm(across) > 1e-9 else _perpendicular(along)
    axes = np.array([along, across, np.cross(along, across)])
    return _box(0.5 * (p0 + p1), axes, (length, thickness, width))


def _hull(points: FloatArray) -> trimesh.Trimesh:
    return _oriented(trimesh.convex.convex_hull(points))


# ---------------------------------------------------------------------- the links
@dataclasses.dataclass(frozen=True)
class _Drive:
    """Where the proximal drive shafts and the base's gears are (distances along the
    base axis from O, radii from it) [m]."""

    axis: FloatArray  # the base axis, unit, pointing from O down to the base
    x: FloatArray  # azimuth reference, perpendicular to axis
    y: FloatArray
    coaxial: bool
    tube_radii: tuple[tuple[float, float], ...]  # (inner, outer) per leg
    tube_top: tuple[float, float, float]  # distance of each leg's tube top
    tube_bottom: tuple[float, float, float]
    gear_top: tuple[float, float, float]  # distance of each driven gear's upper face
    gear_radius: float
    servo_inner: float  # radial start of the servo blocks
    servo_azimuth: tuple[float, float, float]
    pinion_radius: float
    pinion_centre: float  # radial distance of each servo's output shaft
    plate_top: float
    servo_top: float


def _drive(design: SPMDesign) -> _Drive:
    dims = design.dimensions
    mean_u = design.u.mean(axis=0)
    axis = _unit(mean_u) if np.linalg.norm(mean_u) > 1e-6 else np.array([0.0, 0.0, -1.0])
    up = -axis
    x = np.array([1.0, 0.0, 0.0]) - up[0] * up
    x = _unit(x) if np.linalg.norm(x) > 1e-6 else _perpendicular(up)
    y = np.cross(up, x)
    coaxial = design.is_coaxial
    width, length, height = dims.servo_size
    plate_top = dims.base_depth - dims.base_thickness / 2
    servo_top = plate_top - height
    top = dims.proximal_radius + dims.proximal_thickness / 2 + _TOP_GAP
    radii = []
    for k in range(3 if coaxial else 1):
        inner = dims.hub_radius + _CLEARANCE + k * (_TUBE_WALL + _CLEARANCE)
        radii.append((inner, inner + _TUBE_WALL))
    if coaxial:
        tube_top = tuple(top + k * _TUBE_STEP for k in range(3))
        gear_bottom = [servo_top - _GEAR_GAP - k * (_GEAR_THICKNESS + _GEAR_GAP) for k in range(3)]
        tube_bottom = tuple(gear_bottom)
        gear_top = tuple(b - _GEAR_THICKNESS for b in gear_bottom)
    else:
        radii *= 3
        tube_top = (top, top, top)
        tube_bottom = (top + _SHORT_TUBE,) * 3
        gear_top = tube_bottom
    # Servo blocks: length radial, the outer corners just inside the plate rim, the
    # output shaft centred on the block's inner end.
    rim = dims.base_radius - _SERVO_MARGIN
    servo_inner = math.sqrt(max(rim**2 - (width / 2) ** 2, 0.0)) - length
    servo_inner = max(servo_inner, dims.hub_radius + _CLEARANCE)
    pinion_centre = servo_inner + width / 2
    pinion_radius = min(_PINION_RADIUS, width / 2)
    gear_radius = pinion_centre - pinion_radius - _CLEARANCE
    gear_radius = max(gear_radius, radii[-1][1] + _CLEARANCE)
    eta = np.asarray(design.eta)
    servo_azimuth = tuple(float(e) + math.pi / 3 for e in eta)
    return _Drive(
        axis=axis,
        x=x,
        y=y,
        coaxial=coaxial,
        tube_radii=tuple(radii),
        tube_top=(tube_top[0], tube_top[1], tube_top[2]),
        tube_bottom=(tube_bottom[0], tube_bottom[1], tube_bottom[2]),
        gear_top=(gear_top[0], gear_top[1], gear_top[2]),
        gear_radius=gear_radius,
        servo_inner=servo_inner,
        servo_azimuth=(servo_azimuth[0], servo_azimuth[1], servo_azimuth[2]),
        pinion_radius=pinion_radius,
        pinion_centre=pinion_centre,
        plate_top=plate_top,
        servo_top=servo_top,
    )


def _base_parts(design: SPMDesign, drive: _Drive) -> list[LinkPart]:
    dims = design.dimensions
    pla = dims.density
    axis = drive.axis
    half = dims.base_thickness / 2
    parts = [
        LinkPart(
            "plate",
            _cylinder(axis, dims.base_depth - half, dims.base_depth + half, dims.base_radius, 64),
            pla,
        )
    ]
    width, length, height = dims.servo_size
    for k, azimuth in enumerate(drive.servo_azimuth):
        radial = math.cos(azimuth) * drive.x + math.sin(azimuth) * drive.y
        tangential = np.cross(-axis, radial)
        centre = (drive.servo_inner + length / 2) * radial + (drive.servo_top + height / 2) * axis
        block = _box(centre, np.array([radial, tangential, -axis]), (length, width, height))
        parts.append(LinkPart(f"servo_{k + 1}", block, dims.servo_mass / block.volume))
        if drive.coaxial:
            # Pinion on the servo shaft, up to its leg's driven gear.
            pinion = _cylinder(axis, drive.gear_top[k], drive.servo_top, drive.pinion_radius)
            pinion.apply_translation(drive.pinion_centre * radial)
            parts.append(LinkPart(f"pinion_{k + 1}", pinion, pla))
    hub = _cylinder(axis, drive.tube_top[0], drive.plate_top, dims.hub_radius, _LARGE_SECTIONS)
    parts.append(LinkPart("hub", hub, pla))
    return parts


def _band_start(design: SPMDesign, drive: _Drive) -> float:
    """Polar angle from u_i where the proximal plate begins: far enough from u_i that
    the plate clears every drive tube (so the three plates do not overlap there)."""
    dims = design.dimensions
    inner = dims.proximal_radius - dims.proximal_thickness / 2
    clear = max(r for _, r in drive.tube_radii) + 2 * _CLEARANCE
    s0 = math.asin(min(1.0, clear / inner))
    return min(s0, design.alpha1 - _MIN_BAND_ANGLE)


def _proximal_parts(design: SPMDesign, drive: _Drive, leg: int) -> list[LinkPart]:
    dims = design.dimensions
    pla = dims.density
    u, w = design.u[leg], design.w0[leg]
    r, t, width = dims.proximal_radius, dims.proximal_thickness, dims.proximal_width
    s0 = _band_start(design, drive)
    plate = _spherical_plate(u, w, s0, design.alpha1, r, t, width)
    boss = _cylinder(w, r - t / 2, r + t / 2, width / 2)
    # The spoke: the convex hull of a cross-section of the plate a little past its
    # start (inside it, so that no vertex of the two bodies coincides) and a narrower
    # patch over the top of the drive tube.
    e1, e2, n = _arc_frame(u, w)
    s_join = s0 + min(_SPOKE_JOIN, 0.5 * (design.alpha1 - s0))
    section = _plate_section(u, w, s_join, r, 0.999 * t, 0.999 * width)
    inner, outer = drive.tube_radii[leg]
    top = drive.tube_top[leg]
    patch = [
        a * e1 + b * e2 + side * _SPOKE_TAPER * width / 2 * n
        for a in (top, top + _SPOKE_OVERLAP)
        for b in (outer - _CLEARANCE, outer + _TUBE_WALL)
        for side in (-1.0, 1.0)
    ]
    spoke = _hull(np.vstack([section, np.array(patch)]))
    tube_axis = u if not drive.coaxial else drive.axis
    tube = _tube(tube_axis, top, drive.tube_bottom[leg], inner, outer)
    parts = [
        LinkPart("plate", plate, pla),
        LinkPart("boss_w", boss, pla),
        LinkPart("spoke", spoke, pla),
        LinkPart("tube", tube, pla),
    ]
    if drive.coaxial:
        # The gear's bore lies inside the tube wall, so no vertices coincide.
        bore = 0.5 * (inner + outer)
        gear = _tube(
            tube_axis, drive.gear_top[leg], drive.tube_bottom[leg], bore, drive.gear_radius
        )
        parts.append(LinkPart("gear", gear, pla))
    return parts


def _distal_parts(design: SPMDesign, leg: int) -> list[LinkPart]:
    dims = design.dimensions
    pla = dims.density
    w, v = design.w0[leg], design.v0[leg]
    big_r, t, width = dims.distal_radius, dims.distal_thickness, dims.distal_width
    outer_proximal = dims.proximal_radius + dims.proximal_thickness / 2
    bracket = big_r + t / 2 + _CLEARANCE
    return [
        LinkPart("plate", _spherical_plate(w, v, 0.0, design.alpha2, big_r, t, width), pla),
        LinkPart("boss_w", _cylinder(w, big_r - t / 2, big_r + t / 2, width / 2), pla),
        LinkPart("boss_v", _cylinder(v, big_r - t / 2, big_r + t / 2, width / 2), pla),
        LinkPart("pin_w", _cylinder(w, outer_proximal, big_r, dims.joint_radius), pla),
        LinkPart("pin_v", _cylinder(v, big_r, bracket, dims.joint_radius), pla),
    ]


def _platform_parts(design: SPMDesign) -> list[LinkPart]:
    dims = design.dimensions
    pla = dims.density
    z = np.array([0.0, 0.0, 1.0])
    h, t = dims.platform_height, dims.platform_thickness
    width = dims.distal_width
    parts = [
        LinkPart(
            "plate", _cylinder(z, h - t / 2, h + t / 2, dims.platform_radius, _LARGE_SECTIONS), pla
        )
    ]
    inner = dims.distal_radius + dims.distal_thickness / 2 + _CLEARANCE
    for leg in range(3):
        v = design.v0[leg]
        parts.append(LinkPart(f"boss_{leg + 1}", _cylinder(v, inner, inner + t, width / 2), pla))
        horizontal = v - (v @ z) * z
        if np.linalg.norm(horizontal) < 1e-6:
            continue  # the joint is over the plate: the boss touches it
        radial = _unit(horizontal)
        foot = (inner + t / 2) * v  # the boss centre
        corner = foot + (h - foot @ z) * z  # above (or below) it, at plate height
        # The rising bar starts just off the boss centre, so that its corners do not
        # coincide with vertices of the boss.
        rising = _bar(foot + 0.02 * (corner - foot), corner, radial, t, width)
        if rising is not None:
            parts.append(LinkPart(f"bar_{leg + 1}_rising", rising, pla))
        rim = (dims.platform_radius - _BRACKET_INSET) * radial + h * z
        reach = corner + t / 2 * radial
        if (reach - rim) @ radial > 0:
            radial_bar = _bar(rim, reach, z, t, width)
            if radial_bar is not None:
                parts.append(LinkPart(f"bar_{leg + 1}_radial", radial_bar, pla))
    return parts


@functools.lru_cache(maxsize=16)
def _parts(design: SPMDesign) -> dict[str, tuple[LinkPart, ...]]:
    drive = _drive(design)
    parts: dict[str, tuple[LinkPart, ...]] = {"base": tuple(_base_parts(design, drive))}
    for leg in range(3):
        parts[f"proximal_{leg + 1}"] = tuple(_proximal_parts(design, drive, leg))
    for leg in range(3):
        parts[f"distal_{leg + 1}"] = tuple(_distal_parts(design, leg))
    parts["platform"] = tuple(_platform_parts(design))
    return parts


def _design_or_default(design: SPMDesign | None) -> SPMDesign:
    return SPMDesign.prototype() if design is None else design


def link_parts(design: SPMDesign | None = None) -> dict[str, list[LinkPart]]:
    """The closed bodies of every link (keys :data:`LINK_NAMES`), world frame at home.

    Plates, tubes and gears are not convex; cylinders, boxes and spokes are.

    Args:
        design: The SPM (default: the prototype).
    """
    parts = _parts(_design_or_default(design))
    return {
        name: [dataclasses.replace(p, mesh=p.mesh.copy()) for p in parts[name]]
        for name in LINK_NAMES
    }


def link_meshes(design: SPMDesign | None = None) -> dict[str, trimesh.Trimesh]:
    """One triangle mesh per link (keys :data:`LINK_NAMES`), world frame at home [m].

    Each mesh is the concatenation of the link's closed bodies (see
    :func:`link_parts`): watertight, outward normals, positive volume; bodies may
    overlap where they join.

    Args:
        design: The SPM (default: the prototype).
    """
    parts = _parts(_design_or_default(design))
    meshes: dict[str, trimesh.Trimesh] = {}
    for name in LINK_NAMES:
        vertices, faces, offset = [], [], 0
        for part in parts[name]:
            vertices.append(np.asarray(part.mesh.vertices, dtype=float))
            faces.append(np.asarray(part.mesh.faces, dtype=np.int64) + offset)
            offset += len(part.mesh.vertices)
        meshes[name] = trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=False)
    return meshes


def link_inertias(design: SPMDesign | None = None) -> dict[str, LinkInertia]:
    """Mass, centre of mass and inertia of every link (keys :data:`LINK_NAMES`).

    Sum of the link's bodies (:func:`link_parts`): PLA at ``dimensions.density``, the
    base's servo blocks as uniform solids of ``dimensions.servo_mass`` each. Where
    bodies of one link overlap, the overlap is counted twice.

    Args:
        design: The SPM (default: the prototype).

    Returns:
        Per link, its mass properties in the link frame (= world frame at home).
    """
    parts = _parts(_design_or_default(design))
    return {
        name: combine_mass_properties(
            [part_mass_properties(p.mesh, p.density) for p in parts[name]]
        )
        for name in LINK_NAMES
    }
