"""Link shapes and mass properties: closed meshes, plausible masses, the prototype's envelope."""

from __future__ import annotations

import itertools
import math

import coal
import numpy as np
import pytest
import trimesh
from conftest import general_design

import spm_pin as spm
from spm_pin.model.geometry import (
    LINK_NAMES,
    LinkInertia,
    combine_mass_properties,
    link_inertias,
    link_meshes,
    link_parts,
    part_mass_properties,
)

#: Tolerances, by what they compare.
TOL = {
    "closed_form": 1e-12,  # mass properties of a box against the closed form (relative)
    "polygon": 2e-2,  # a 64-gon plate against the round plate's closed form (relative)
    "sum": 1e-12,  # mass properties summed two ways (relative)
    "length": 1e-9,  # positions of faces and joints [m]
    "envelope": 0.006,  # the bounding box against 200 x 200 x 290 mm [m]
}

#: The prototype's envelope at home [m]: about 200 x 200 x 290 mm.
ENVELOPE = np.array([0.200, 0.200, 0.290])
#: Links that share a joint (including through the loop closures): they touch.
ADJACENT = {
    ("base", "proximal_1"),
    ("base", "proximal_2"),
    ("base", "proximal_3"),
    *((f"proximal_{i}", f"distal_{i}") for i in (1, 2, 3)),
    *((f"distal_{i}", "platform") for i in (1, 2, 3)),
}

DESIGNS = {
    "prototype": spm.SPMDesign.prototype,
    "agile_eye": spm.SPMDesign.agile_eye,
    "general": general_design,
}


@pytest.fixture(scope="module", params=sorted(DESIGNS))
def design(request: pytest.FixtureRequest) -> spm.SPMDesign:
    return DESIGNS[request.param]()


@pytest.fixture(scope="module")
def prototype() -> spm.SPMDesign:
    return spm.SPMDesign.prototype()


def _radii(mesh: trimesh.Trimesh) -> np.ndarray:
    return np.linalg.norm(np.asarray(mesh.vertices), axis=1)


def _part(design: spm.SPMDesign, link: str, name: str) -> trimesh.Trimesh:
    (part,) = [p for p in link_parts(design)[link] if p.name == name]
    return part.mesh


def _along_axis(mesh: trimesh.Trimesh, axis: np.ndarray, radius: float) -> np.ndarray:
    """Coordinates along ``axis`` of the vertices within ``radius`` of it."""
    vertices = np.asarray(mesh.vertices)
    along = vertices @ axis
    lateral = np.linalg.norm(vertices - along[:, None] * axis, axis=1)
    return along[lateral <= radius + TOL["length"]]


# ------------------------------------------------------------------------- meshes
def test_every_link_is_a_closed_volume(design: spm.SPMDesign) -> None:
    meshes = link_meshes(design)
    assert tuple(meshes) == LINK_NAMES
    for name, mesh in meshes.items():
        assert mesh.is_watertight, name
        assert mesh.is_winding_consistent, name
        assert mesh.volume > 0, name
        assert 100 <= len(mesh.faces) <= 2000, (name, len(mesh.faces))
    for name, parts in link_parts(design).items():
        for part in parts:
            assert part.mesh.is_volume, (name, part.name)


def test_default_design_is_the_prototype(prototype: spm.SPMDesign) -> None:
    default, explicit = link_meshes(), link_meshes(prototype)
    for name in LINK_NAMES:
        np.testing.assert_array_equal(default[name].vertices, explicit[name].vertices)
        np.testing.assert_array_equal(default[name].faces, explicit[name].faces)


def test_meshes_are_fresh_copies(prototype: spm.SPMDesign) -> None:
    first = link_meshes(prototype)["base"]
    first.apply_translation([1.0, 0.0, 0.0])
    np.testing.assert_array_less(link_meshes(prototype)["base"].vertices[:, 0], 0.5)


def test_prototype_fits_its_envelope(prototype: spm.SPMDesign) -> None:
    vertices = np.vstack([m.vertices for m in link_meshes(prototype).values()])
    extents = vertices.max(axis=0) - vertices.min(axis=0)
    np.testing.assert_allclose(extents, ENVELOPE, atol=TOL["envelope"])
    # The platform plate's top is the highest point, the base plate's bottom the lowest.
    dims = prototype.dimensions
    np.testing.assert_allclose(
        [vertices[:, 2].max(), vertices[:, 2].min()],
        [
            dims.platform_height + dims.platform_thickness / 2,
            -dims.base_depth - dims.base_thickness / 2,
        ],
        atol=TOL["length"],
    )


def test_proximal_plates_lie_on_the_inner_sphere(design: spm.SPMDesign) -> None:
    dims = design.dimensions
    r, t = dims.proximal_radius, dims.proximal_thickness
    for leg in range(3):
        radii = _radii(_part(design, f"proximal_{leg + 1}", "plate"))
        assert radii.min() >= r - t / 2 - TOL["length"]
        assert radii.max() <= r + t / 2 + TOL["length"]
        # The round end boss: a flat disc on w_i0 between the same radii.
        along = np.asarray(_part(design, f"proximal_{leg + 1}", "boss_w").vertices) @ design.w0[leg]
        np.testing.assert_allclose(
            [along.min(), along.max()], [r - t / 2, r + t / 2], atol=TOL["length"]
        )
        # The plate runs up to w_i0: its far end is at angle alpha1 from u_i.
        plate = np.asarray(_part(design, f"proximal_{leg + 1}", "plate").vertices)
        cosine = plate @ design.u[leg] / np.linalg.norm(plate, axis=1)
        centre = plate[np.argmax(np.arccos(np.clip(cosine, -1, 1)))]
        assert math.degrees(math.acos(centre @ design.u[leg] / np.linalg.norm(centre))) == (
            pytest.approx(math.degrees(design.alpha1), abs=2.0)
        )


def test_distal_plates_lie_on_the_outer_sphere(design: spm.SPMDesign) -> None:
    dims = design.dimensions
    r, t = dims.distal_radius, dims.distal_thickness
    for leg in range(3):
        radii = _radii(_part(design, f"distal_{leg + 1}", "plate"))
        assert radii.min() >= r - t / 2 - TOL["length"]
        assert radii.max() <= r + t / 2 + TOL["length"]
        for part, axis in (("boss_w", design.w0[leg]), ("boss_v", design.v0[leg])):
            along = np.asarray(_part(design, f"distal_{leg + 1}", part).vertices) @ axis
            np.testing.assert_allclose(
                [along.min(), along.max()], [r - t / 2, r + t / 2], atol=TOL["length"]
            )


def test_distal_link_reaches_both_its_joints(design: spm.SPMDesign) -> None:
    """The pin on w_i0 meets the proximal plate's outer face; the pin on v_i0 meets the
    platform bracket's inner face."""
    dims = design.dimensions
    meshes = link_meshes(design)
    pin = dims.joint_radius
    for leg in range(3):
        w, v = design.w0[leg], design.v0[leg]
        distal = meshes[f"distal_{leg + 1}"]
        proximal_face = dims.proximal_radius + dims.proximal_thickness / 2
        np.testing.assert_allclose(
            _along_axis(distal, w, pin).min(), proximal_face, atol=TOL["length"]
        )
        np.testing.assert_allclose(
            _along_axis(meshes[f"proximal_{leg + 1}"], w, pin).max(),
            proximal_face,
            atol=TOL["length"],
        )
        bracket = _along_axis(_part(design, "platform", f"boss_{leg + 1}"), v, pin).min()
        np.testing.assert_allclose(_along_axis(distal, v, pin).max(), bracket, atol=TOL["length"])
        assert bracket > dims.distal_radius + dims.distal_thickness / 2


def test_hub_stays_below_the_proximal_sphere(prototype: spm.SPMDesign) -> None:
    dims = prototype.dimensions
    hub = _part(prototype, "base", "hub")
    top = -(dims.proximal_radius + dims.proximal_thickness / 2)
    assert np.asarray(hub.vertices)[:, 2].max() < top
    assert np.linalg.norm(np.asarray(hub.vertices)[:, :2], axis=1).max() <= dims.hub_radius + 1e-12


def _bvh(mesh: trimesh.Trimesh) -> coal.BVHModelOBBRSS:
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(mesh.faces), len(mesh.vertices))
    model.addVertices(np.ascontiguousarray(mesh.vertices, dtype=float))
    model.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
    model.endModel()
    return model


def test_links_do_not_touch_at_home_unless_they_share_a_joint(prototype: spm.SPMDesign) -> None:
    """At home no two links collide: the proximal and distal links of a leg, and the
    distal links and the platform, touch at their pins; every other pair (the nested
    proximal drive tubes, the base and the tubes included) is apart."""
    shapes = {name: _bvh(mesh) for name, mesh in link_meshes(prototype).items()}
    identity = coal.Transform3s()
    for a, b in itertools.combinations(LINK_NAMES, 2):
        result = coal.DistanceResult()
        distance = coal.distance(
            shapes[a], identity, shapes[b], identity, coal.DistanceRequest(), result
        )
        if (a, b) in ADJACENT and a != "base":
            assert distance < 1e-6, (a, b, distance)
        else:
            assert distance > 0.5e-3, (a, b, distance)


# --------------------------------------------------------------- mass properties
def test_mass_properties_are_physical(design: spm.SPMDesign) -> None:
    inertias = link_inertias(design)
    assert tuple(inertias) == LINK_NAMES
    for name, inertia in inertias.items():
        assert inertia.mass > 0, name
        assert np.all(np.isfinite(inertia.com)) and np.all(np.isfinite(inertia.inertia))
        np.testing.assert_array_equal(inertia.inertia, inertia.inertia.T)
        moments = np.linalg.eigvalsh(inertia.inertia)
        assert moments.min() > 0, name
        # Principal moments of a real body satisfy the triangle inequality.
        a, b, c = moments
        assert a + b >= c * (1 - 1e-9), name


def test_prototype_masses_are_plausible(prototype: spm.SPMDesign) -> None:
    inertias = link_inertias(prototype)
    dims = prototype.dimensions
    total = sum(i.mass for i in inertias.values())
    assert 1.0 < total < 3.0
    assert inertias["base"].mass > 3 * dims.servo_mass
    for name in LINK_NAMES[1:]:
        assert 0.02 < inertias[name].mass < 0.5, name
    # The three legs are the same link turned by 120 degrees (up to their drive
    # tubes, which are nested: the distal links are exactly equal).
    masses = [inertias[f"distal_{i}"].mass for i in (1, 2, 3)]
    np.testing.assert_allclose(masses, masses[0], rtol=1e-9)
    # Every centre of mass lies in its link's bounding box.
    for name, mesh in link_meshes(prototype).items():
        low, high = mesh.bounds
        assert np.all(inertias[name].com >= low) and np.all(inertias[name].com <= high), name


def test_servos_weigh_their_mass(prototype: spm.SPMDesign) -> None:
    servos = [p for p in link_parts(prototype)["base"] if p.name.startswith("servo")]
    assert len(servos) == 3
    for part in servos:
        mass = part_mass_properties(part.mesh, part.density).mass
        np.testing.assert_allclose(mass, prototype.dimensions.servo_mass, rtol=TOL["sum"])


def test_box_against_the_closed_form() -> None:
    a, b, c, density = 0.03, 0.05, 0.008, 1240.0
    box = trimesh.creation.box(extents=[a, b, c])
    box.apply_translation([0.1, -0.2, 0.3])
    props = part_mass_properties(box, density)
    mass = a * b * c * density
    np.testing.assert_allclose(props.mass, mass, rtol=TOL["closed_form"])
    np.testing.assert_allclose(props.com, [0.1, -0.2, 0.3], atol=TOL["length"])
    expected = mass / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    np.testing.assert_allclose(props.inertia, expected, rtol=0, atol=TOL["closed_form"] * mass)


def test_combined_halves_equal_the_whole_box() -> None:
    """Two boxes side by side, joined with the parallel-axis theorem, are one box."""
    a, b, c, density = 0.04, 0.02, 0.01, 1000.0
    halves = []
    for x in (-a / 4, a / 4):
        half = trimesh.creation.box(extents=[a / 2, b, c])
        half.apply_translation([x, 0.0, 0.0])
        halves.append(part_mass_properties(half, density))
    whole = part_mass_properties(trimesh.creation.box(extents=[a, b, c]), density)
    combined = combine_mass_properties(halves)
    np.testing.assert_allclose(combined.mass, whole.mass, rtol=TOL["sum"])
    np.testing.assert_allclose(combined.com, whole.com, atol=TOL["length"])
    np.testing.assert_allclose(combined.inertia, whole.inertia, atol=TOL["sum"] * whole.mass)


def test_base_plate_against_the_round_plate(prototype: spm.SPMDesign) -> None:
    dims = prototype.dimensions
    plate = part_mass_properties(_part(prototype, "base", "plate"), dims.density)
    r, h = dims.base_radius, dims.base_thickness
    mass = math.pi * r * r * h * dims.density
    expected = mass * np.diag([(3 * r * r + h * h) / 12] * 2 + [r * r / 2])
    np.testing.assert_allclose(plate.mass, mass, rtol=TOL["polygon"])
    np.testing.assert_allclose(plate.com, [0, 0, -dims.base_depth], atol=TOL["length"])
    np.testing.assert_allclose(plate.inertia, expected, rtol=TOL["polygon"], atol=1e-12)


def test_link_inertia_is_the_sum_of_its_parts(design: spm.SPMDesign) -> None:
    """PLA-only links: the parts' sum equals trimesh's mass properties of the link mesh."""
    meshes, inertias = link_meshes(design), link_inertias(design)
    density = design.dimensions.density
    for name in LINK_NAMES[1:]:
        props = meshes[name].mass_properties
        whole = LinkInertia(
            mass=float(props["volume"]) * density,
            com=np.asarray(props["center_mass"]),
            inertia=np.asarray(props["inertia"]) * density,
        )
        np.testing.assert_allclose(inertias[name].mass, whole.mass, rtol=TOL["sum"])
        np.testing.assert_allclose(inertias[name].com, whole.com, atol=TOL["length"])
        scale = float(np.abs(whole.inertia).max())
        np.testing.assert_allclose(inertias[name].inertia, whole.inertia, atol=1e-9 * scale)
