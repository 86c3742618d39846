"""Self-collision: link pairs from the model, collisions built from geometry, distances
against brute-force surface sampling, the study's colliding input, margins, bad input.

Independent truths used here: the joint tree and loop closures of the Pinocchio model
(which pairs share a joint), the link meshes themselves (winding numbers for "inside",
exact point-to-triangle distances in numpy), a plain Pinocchio check with one
triangle BVH per link, and the torsion symmetry of the coaxial SPM.
"""

from __future__ import annotations

import itertools
import json
import math
from typing import Any

import coal
import numpy as np
import pinocchio as pin
import pytest
import trimesh
from conftest import get_design
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

import spm_pin as spm
from spm_pin.cli import main as cli_main
from spm_pin.collision import (
    ADJACENT_PAIRS,
    LINK_PAIRS,
    CollisionChecker,
    check_input,
    convex_pieces,
)
from spm_pin.model.geometry import LINK_NAMES, link_meshes, link_parts

#: Tolerances of this module.
TOL = {
    # Sum of the convex pieces' volumes against the part's volume (relative).
    "volume": 1e-9,
    # coal distance against the minimum over sampled surface points [m]: the sampled
    # minimum is an upper bound that the refinement brings within this.
    "sampled": 2e-4,
    # coal distance may undercut an exact sampled distance only by rounding [m].
    "undercut": 1e-9,
    # Distances closer than this to the margin are contacts that may go either way [m].
    "tie": 1e-9,
    # Distances of pairs that torsion leaves alone [m] (base facets excluded).
    "torsion": 1e-9,
}

#: Random reachable configurations per comparison.
SAMPLES = 24


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


@pytest.fixture(scope="module")
def checker(robot: spm.SPMRobot) -> CollisionChecker:
    return robot.collision_checker


@pytest.fixture(scope="module")
def samples(robot: spm.SPMRobot) -> np.ndarray:
    """Seeded random inputs with a home-mode assembly, and their q (n, 3 + 9)."""
    rng = np.random.default_rng(11)
    theta = rng.uniform(-math.pi, math.pi, size=(400, 3))
    theta = theta[spm.forward_kinematics(theta).reachable][:SAMPLES]
    return np.hstack([theta, robot.configuration(theta)])


# ---------------------------------------------------------------- brute force
def _closest_on_triangles(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Distance from each point (P, 3) to each triangle (T, 3, 3): (P, T), exact
    (Voronoi regions of the triangle; C. Ericson, Real-Time Collision Detection 5.1.5)."""
    p = points[:, None, :]
    a, b, c = (triangles[None, :, k, :] for k in range(3))
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("ptk,ptk->pt", ab, ap)
    d2 = np.einsum("ptk,ptk->pt", ac, ap)
    bp = p - b
    d3 = np.einsum("ptk,ptk->pt", ab, bp)
    d4 = np.einsum("ptk,ptk->pt", ac, bp)
    cp = p - c
    d5 = np.einsum("ptk,ptk->pt", ab, cp)
    d6 = np.einsum("ptk,ptk->pt", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = vb / denom
        w = vc / denom
        closest = a + v[..., None] * ab + w[..., None] * ac  # inside the face
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    regions = [
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + t_ab[..., None] * ab),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + t_ac[..., None] * ac),
        ((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), b + t_bc[..., None] * (c - b)),
    ]
    for mask, point in reversed(regions):
        closest = np.where(mask[..., None], np.broadcast_to(point, closest.shape), closest)
    return np.asarray(np.linalg.norm(p - closest, axis=-1))


def _min_point_mesh(points: np.ndarray, triangles: np.ndarray) -> tuple[float, int]:
    best, where = math.inf, -1
    for start in range(0, len(points), 256):
        d = _closest_on_triangles(points[start : start + 256], triangles).min(axis=1)
        k = int(np.argmin(d))
        if d[k] < best:
            best, where = float(d[k]), start + k
    return best, where


def _world_mesh(mesh: trimesh.Trimesh, rotation: np.ndarray) -> trimesh.Trimesh:
    return trimesh.Trimesh(np.asarray(mesh.vertices) @ rotation.T, mesh.faces, process=False)


def _sampled_distance(mesh_a: trimesh.Trimesh, mesh_b: trimesh.Trimesh, seed: int) -> float:
    """Minimum over surface points of either mesh of the exact distance to the other
    (an upper bound of the mesh distance), refined around the best point."""
    rng = np.random.default_rng(seed)
    best = math.inf
    for first, second in ((mesh_a, mesh_b), (mesh_b, mesh_a)):
        points, _ = trimesh.sample.sample_surface(first, 1500, seed=int(rng.integers(1 << 30)))
        points = np.vstack([points, np.asarray(first.vertices)])
        triangles = np.asarray(second.triangles)
        d, k = _min_point_mesh(points, triangles)
        # Refine: dense points on the faces of `first` near the best point.
        centre = points[k][None, :]
        near = _closest_on_triangles(centre, np.asarray(first.triangles))[0] < 0.004
        sub = trimesh.Trimesh(first.vertices, np.asarray(first.faces)[near], process=False)
        dense, _ = trimesh.sample.sample_surface(sub, 6000, seed=int(rng.integers(1 << 30)))
        keep = triangles[_closest_on_triangles(centre, triangles)[0] < d + 0.004]
        d = min(d, _min_point_mesh(dense, keep)[0])
        best = min(best, d)
    return best


def _winding_inside(points: np.ndarray, mesh: trimesh.Trimesh) -> np.ndarray:
    """Points inside a closed mesh: generalised winding number (sum of the solid angles
    of its triangles, Van Oosterom-Strackee) above 1/2."""
    triangles = np.asarray(mesh.triangles)
    total = np.zeros(len(points))
    for start in range(0, len(points), 512):
        r = triangles[None, :, :, :] - points[start : start + 512, None, None, :]
        length = np.linalg.norm(r, axis=-1)
        a, b, c = r[..., 0, :], r[..., 1, :], r[..., 2, :]
        la, lb, lc = length[..., 0], length[..., 1], length[..., 2]
        numerator = np.einsum("ptk,ptk->pt", a, np.cross(b, c))
        denominator = (
            la * lb * lc
            + np.einsum("ptk,ptk->pt", a, b) * lc
            + np.einsum("ptk,ptk->pt", b, c) * la
            + np.einsum("ptk,ptk->pt", c, a) * lb
        )
        total[start : start + 512] = (2.0 * np.arctan2(numerator, denominator)).sum(axis=1)
    return np.asarray(total / (4.0 * math.pi) > 0.5)


def _link_rotations(robot: spm.SPMRobot, q: np.ndarray) -> dict[str, np.ndarray]:
    placements = robot.placements(q)
    return {name: np.array(placements[name].rotation) for name in LINK_NAMES}


# ---------------------------------------------------------------- link pairs
def test_pairs_that_share_a_joint_come_from_the_model(robot: spm.SPMRobot) -> None:
    """A link shares its joint with the link of the parent joint; legs 2 and 3 close at
    v_2, v_3 on the platform. Every other pair is checked."""
    model = robot.model
    joint_of = {name: model.frames[robot.link_frames[name]].parentJoint for name in LINK_NAMES}
    link_on = {joint: name for name, joint in joint_of.items()}
    shared = set()
    for name, joint in joint_of.items():
        if joint > 0:
            shared.add(frozenset((name, link_on[model.parents[joint]])))
    for constraint in robot.constraint_models:
        weld = constraint.extract()
        closing = weld.joint1_id  # v_2 or v_3, welded to the platform
        shared.add(frozenset(("platform", link_on[model.parents[closing]])))
    assert {frozenset(p) for p in ADJACENT_PAIRS} == shared
    every = {frozenset(p) for p in itertools.combinations(LINK_NAMES, 2)}
    assert {frozenset(p) for p in LINK_PAIRS} == every - shared
    assert len(LINK_PAIRS) == 19 and len(set(LINK_PAIRS)) == 19
    assert all(LINK_NAMES.index(a) < LINK_NAMES.index(b) for a, b in LINK_PAIRS)


@pytest.mark.parametrize("name", ["prototype", "agile_eye", "general"])
def test_convex_pieces_are_the_parts(name: str) -> None:
    """Pieces are convex, made of the part's own vertices, and fill its volume (for
    coaxial and general designs)."""
    design = get_design(name)
    pieces = convex_pieces(design)
    for link, parts in link_parts(design).items():
        for part in parts:
            mine = [p for p in pieces[link] if p.part == part.name]
            assert mine, (link, part.name)
            vertices = {tuple(v) for v in np.round(part.mesh.vertices, 12)}
            volume = 0.0
            for piece in mine:
                assert {tuple(v) for v in np.round(piece.vertices, 12)} <= vertices
                hull = trimesh.convex.convex_hull(piece.vertices)
                volume += hull.volume
            assert abs(volume - part.mesh.volume) <= TOL["volume"] * part.mesh.volume


# ---------------------------------------------------------- built from geometry
def test_home_is_free_and_matches_the_triangle_meshes(
    robot: spm.SPMRobot, checker: CollisionChecker
) -> None:
    home = np.zeros(3)
    assert robot.collisions(home) == []
    assert robot.collisions(np.zeros(robot.model.nq)) == []
    distances = robot.distances(home)
    meshes = link_meshes()
    for pair in (
        ("proximal_1", "proximal_2"),
        ("proximal_1", "distal_2"),
        ("distal_1", "distal_2"),
    ):
        sampled = _sampled_distance(meshes[pair[0]], meshes[pair[1]], seed=1)
        assert distances[pair] <= sampled + TOL["undercut"], pair
        assert sampled - distances[pair] <= TOL["sampled"], (pair, sampled, distances[pair])
    # The nested drive tubes set the proximal links' clearance: about 1 mm.
    assert 0.0009 < distances[("proximal_1", "proximal_2")] < 0.001
    assert checker.fixed_clearance <= distances[("proximal_1", "proximal_2")]
    assert robot.min_clearance(home) == pytest.approx(min(distances.values()), abs=0.0)


@pytest.mark.parametrize("leg", [1, 2, 3])
def test_proximal_link_pushed_past_its_neighbour_collides(
    robot: spm.SPMRobot, checker: CollisionChecker, leg: int
) -> None:
    """Turn proximal link ``leg`` towards its counterclockwise neighbour: at a gap of 0
    they occupy the same place; just past the threshold a sampled surface point of one
    is inside the other (winding number)."""
    neighbour = leg % 3 + 1
    pair = tuple(sorted((f"proximal_{leg}", f"proximal_{neighbour}"), key=LINK_NAMES.index))

    def theta_at(gap_deg: float) -> np.ndarray:
        theta = np.zeros(3)
        theta[leg - 1] = math.radians(gap_deg - 120.0)  # gap D = 120 + theta_leg - theta_next
        return theta

    assert pair in check_input(theta_at(0.0), robot).pairs
    assert pair in check_input(theta_at(-10.0), robot).pairs  # passed
    assert pair not in check_input(theta_at(120.0), robot).pairs
    low, high = 0.0, 120.0  # collides at low, free at high
    for _ in range(30):
        middle = 0.5 * (low + high)
        if pair in check_input(theta_at(middle), robot).pairs:
            low = middle
        else:
            high = middle
    assert 40.0 < low < 60.0  # "adjacent proximal links touch below about 49 deg"
    if leg != 1:
        return  # the brute-force checks below once (they take a few seconds)
    meshes = link_meshes()
    q = np.zeros(robot.model.nq)
    q[robot.actuated_q_idx] = theta_at(low - 0.5)
    rotations = _link_rotations(robot, q)
    a = _world_mesh(meshes[pair[0]], rotations[pair[0]])
    b = _world_mesh(meshes[pair[1]], rotations[pair[1]])
    # Surface points of `a` on its faces near `b`, tested for being inside `b`.
    near = cKDTree(np.asarray(b.vertices)).query(np.asarray(a.triangles_center))[0] < 0.02
    region = trimesh.Trimesh(a.vertices, np.asarray(a.faces)[near], process=False)
    points, _ = trimesh.sample.sample_surface(region, 6000, seed=leg)
    assert np.any(_winding_inside(points, b)), (
        f"{pair} collides below {low:.3f} deg: no point inside"
    )
    q = np.zeros(robot.model.nq)
    q[robot.actuated_q_idx] = theta_at(high + 0.5)
    rotations = _link_rotations(robot, q)
    distance = checker.distances(q, pairs=[pair])[pair]
    assert distance > 0.0
    sampled = _sampled_distance(
        _world_mesh(meshes[pair[0]], rotations[pair[0]]),
        _world_mesh(meshes[pair[1]], rotations[pair[1]]),
        seed=leg,
    )
    assert distance <= sampled + TOL["undercut"]
    assert sampled - distance <= TOL["sampled"]


def test_the_study_colliding_input(robot: spm.SPMRobot) -> None:
    """theta = [60, 90, 220] deg: no home-mode assembly; the nearest real assembly mode
    is checked and proximal links 2 and 3 (gap -10 deg) collide."""
    theta = np.radians([60.0, 90.0, 220.0])
    report = check_input(theta, robot)
    every = spm.forward_kinematics_all(theta)
    labels = [str(label) for label in every.labels[: int(every.count)]]
    home = "+++/-"
    nearest = min(
        labels,
        key=lambda lab: (sum(x != y for x, y in zip(lab, home, strict=True)), labels.index(lab)),
    )
    assert not report.reachable and not report.home
    assert report.mode == nearest and report.mode in labels
    assert report.collision and ("proximal_2", "proximal_3") in report.pairs
    assert report.checked_pairs == LINK_PAIRS
    assert report.distances[("proximal_2", "proximal_3")] < 0.0
    match = r"theta = \[60\.0, 90\.0, 220\.0\] deg has no assembly in mode 'home'"
    with pytest.raises(spm.UnreachableError, match=match):
        robot.collisions(theta)


def test_only_theta_placed_links_without_an_assembly() -> None:
    design = get_design("coaxial_50_75_100")
    robot = spm.build_robot(design)
    theta = np.random.default_rng(4).uniform(-math.pi, math.pi, size=(4000, 3))
    none = theta[spm.forward_kinematics_all(theta, design).count == 0][0]
    report = check_input(none, robot)
    assert report.mode is None and not report.reachable
    assert report.checked_pairs == (
        ("proximal_1", "proximal_2"),
        ("proximal_1", "proximal_3"),
        ("proximal_2", "proximal_3"),
    )
    assert set(report.pairs) <= set(report.checked_pairs)
    for pair in report.checked_pairs:
        assert (pair in report.pairs) == (report.distances[pair] < 0.0) or abs(
            report.distances[pair]
        ) < TOL["tie"]


# ------------------------------------------------------------- random inputs
def test_matches_a_bvh_check_of_the_same_meshes(
    robot: spm.SPMRobot, checker: CollisionChecker, samples: np.ndarray
) -> None:
    """Plain Pinocchio with one triangle BVH per link and the 19 pairs gives the same
    pairs (up to contacts at zero distance), at margin 0 and 0.5 mm."""
    gm = pin.GeometryModel()
    for geometry in robot.collision_model.geometryObjects:
        gm.addGeometryObject(geometry)
    for a, b in LINK_PAIRS:
        gm.addCollisionPair(pin.CollisionPair(gm.getGeometryId(a), gm.getGeometryId(b)))
    gd = pin.GeometryData(gm)
    data = robot.model.createData()
    seen = set()
    for margin in (0.0, 0.0005):
        for k in range(len(gd.collisionRequests)):
            gd.collisionRequests[k].security_margin = margin
        for row in samples[:12]:
            q = row[3:]
            pin.computeCollisions(robot.model, data, gm, gd, q, False)
            truth = {p for k, p in enumerate(LINK_PAIRS) if gd.collisionResults[k].isCollision()}
            mine = set(checker.collisions(q, margin=margin))
            seen |= mine
            distances = checker.distances(q)
            for pair in mine ^ truth:
                assert abs(distances[pair] - margin) < TOL["tie"], (pair, margin, distances[pair])
    assert len(seen) >= 6  # the sample does exercise collisions


def test_margin_is_the_distance_threshold(checker: CollisionChecker, samples: np.ndarray) -> None:
    """A pair collides at margin m exactly when its exact distance is below m."""
    for row in samples[:10]:
        q = row[3:]
        distances = checker.distances(q)
        moving = checker.distances(q, include_fixed=False)
        for margin, include_fixed, reference in (
            (0.0, True, distances),
            (0.0004, True, distances),
            (0.003, False, moving),
        ):
            found = set(checker.collisions(q, margin=margin, include_fixed=include_fixed))
            for pair in LINK_PAIRS:
                if abs(reference[pair] - margin) < TOL["tie"]:
                    continue
                assert (pair in found) == (reference[pair] < margin), (pair, margin, reference)


def test_margins_above_the_tube_clearance(robot: spm.SPMRobot, checker: CollisionChecker) -> None:
    """The drive tubes are about 1 mm apart everywhere: with a margin of 1.5 mm the
    neighbouring proximal links collide at home, unless fixed parts are left out."""
    home = np.zeros(robot.model.nq)
    found = robot.collisions(home, margin=0.0015)
    assert ("proximal_1", "proximal_2") in found and ("proximal_2", "proximal_3") in found
    assert ("proximal_1", "proximal_3") not in found  # tubes 1 and 3 are 5 mm apart
    assert checker.collisions(home, margin=0.0015, include_fixed=False) == []


def test_never_a_pair_that_shares_a_joint(checker: CollisionChecker, samples: np.ndarray) -> None:
    adjacent = set(ADJACENT_PAIRS)
    matrix = checker.collision_matrix(samples[:, 3:], margin=0.0002)
    assert matrix.shape == (len(samples), 19)
    assert matrix.any()
    for row in samples:
        for pair in checker.collisions(row[3:], margin=0.0002):
            assert pair in LINK_PAIRS and pair not in adjacent
    # in_collision agrees with the list.
    for row, flags in zip(samples, matrix, strict=True):
        assert checker.in_collision(row[3:], margin=0.0002) == bool(flags.any())


def test_theta_and_q_give_the_same_answer(
    robot: spm.SPMRobot, checker: CollisionChecker, samples: np.ndarray
) -> None:
    for row in samples[:8]:
        assert robot.collisions(row[:3]) == robot.collisions(row[3:])
        from_theta, from_q = robot.distances(row[:3]), robot.distances(row[3:])
        assert list(from_theta) == list(from_q) == list(LINK_PAIRS)
        np.testing.assert_allclose(list(from_theta.values()), list(from_q.values()), atol=1e-12)
    # The checker builds q from theta in floats: the robot's q, to rounding, closed.
    for row in samples:
        q = checker.configuration(row[:3])
        np.testing.assert_allclose(q, row[3:], rtol=0.0, atol=1e-12)
        assert robot.closure_residual(q) <= 1e-10
    theta = samples[0, :3] + np.array([4, -2, 6]) * math.pi  # whole turns are kept
    np.testing.assert_allclose(
        checker.configuration(theta), robot.configuration(theta), rtol=0.0, atol=1e-12
    )


def test_random_sequence_matches_the_bvh_peer(
    robot: spm.SPMRobot, checker: CollisionChecker
) -> None:
    """The check keeps state between calls (pairs switched on and off): a long random
    sequence, mixing margins, ``in_collision`` and inputs, against plain Pinocchio with
    one BVH per link."""
    gm = pin.GeometryModel()
    for geometry in robot.collision_model.geometryObjects:
        gm.addGeometryObject(geometry)
    for a, b in LINK_PAIRS:
        gm.addCollisionPair(pin.CollisionPair(gm.getGeometryId(a), gm.getGeometryId(b)))
    datas = {}
    for margin in (0.0, 0.0003):
        datas[margin] = pin.GeometryData(gm)
        for request in datas[margin].collisionRequests:
            request.security_margin = margin
    data = robot.model.createData()
    rng = np.random.default_rng(21)
    theta = rng.uniform(-math.pi, math.pi, size=(1500, 3))
    theta = theta[spm.forward_kinematics(theta).reachable][:150]
    seen = 0
    for q in robot.configuration(theta):
        margin = float(rng.choice([0.0, 0.0003]))
        pin.computeCollisions(robot.model, data, gm, datas[margin], q, False)
        truth = [
            p for k, p in enumerate(LINK_PAIRS) if datas[margin].collisionResults[k].isCollision()
        ]
        if rng.uniform() < 0.3:
            assert checker.in_collision(q, margin=margin) == bool(truth)
        mine = checker.collisions(q, margin=margin)
        if mine != truth:
            distances = checker.distances(q)
            for pair in set(mine) ^ set(truth):
                assert abs(distances[pair] - margin) < TOL["tie"], (pair, margin)
        seen += len(truth)
    assert seen > 200


@settings(max_examples=25)
@given(
    gaps=st.tuples(st.floats(0.0, 360.0), st.floats(0.0, 360.0)),
    turn=st.floats(-math.pi, math.pi),
)
def test_torsion_leaves_every_pair_but_the_base_alone(
    checker: CollisionChecker, gaps: tuple[float, float], turn: float
) -> None:
    """Adding one angle to all inputs turns every moving link about the axis: distances
    of pairs without the base do not change (the base is fixed)."""
    d12, d23 = gaps
    if d12 + d23 > 360.0:
        d12, d23 = 360.0 - d12, 360.0 - d23
    theta = np.radians([0.0, 120.0 - d12, 240.0 - d12 - d23])
    assume(bool(spm.forward_kinematics(theta).reachable))
    first = checker.distances(theta)
    second = checker.distances(theta + turn)
    for pair in LINK_PAIRS:
        if pair[0] != "base":
            assert first[pair] == pytest.approx(second[pair], abs=TOL["torsion"]), pair


# ---------------------------------------------------------------- tables
def _mesh_bvh(meshes: list[trimesh.Trimesh]) -> Any:
    """A coal BVH of the triangles of some meshes (the reference of the table tests)."""
    merged = trimesh.util.concatenate(meshes)
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(merged.faces), len(merged.vertices))
    model.addVertices(np.asarray(merged.vertices, dtype=float))
    model.addTriangles(np.asarray(merged.faces, dtype=np.int64))
    model.endModel()
    return model


@pytest.mark.parametrize(("margin", "include_fixed"), [(0.0, True), (0.0005, False)])
def test_tables_are_certified(
    robot: spm.SPMRobot, checker: CollisionChecker, margin: float, include_fixed: bool
) -> None:
    """A table cell marked free or colliding is so for every angle in it: points drawn
    in the cells next to another state (where the bounds are tight) and in random
    cells, with the other joints at random and any number of turns (the loops need
    not close: only the two links' relative pose matters), checked on the drawn
    meshes with coal. Free: the parts the table covers (both links, or the symmetric
    parts of the first against the second) keep more than the margin apart;
    colliding: the two links collide."""
    rng = np.random.default_rng(8)
    plan = checker._plan(margin, include_fixed)
    assert len(plan.tables) == 10  # 3 pairs of proximal links, 4 tubes, 3 hub units
    parts = {name: {p.name: p.mesh for p in ps} for name, ps in link_parts(robot.design).items()}
    request = coal.CollisionRequest()
    request.security_margin = margin
    request.break_distance = 0.0
    checked = {0: 0, 1: 0}
    for table in plan.tables:
        link_a, link_b = table.pair
        if table.unit is None:
            covered = list(parts[link_a].values())
        else:  # the symmetric parts of the first link
            covered = [
                parts[link_a][name] for (k, name) in checker._orders if LINK_NAMES[k] == link_a
            ]
        first, second = _mesh_bvh(covered), _mesh_bvh(list(parts[link_b].values()))
        whole = _mesh_bvh(list(parts[link_a].values()))
        # (Drop the repeated last row and column.)
        state = np.array(table.state).reshape(table.rows, table.columns)[:-1]
        if table.columns > 1:
            state = state[:, :-1]
        rows, columns = state.shape
        edge = np.zeros_like(state, dtype=bool)
        for axis in (0, 1):
            for step in (-1, 1):
                edge |= state != np.roll(state, step, axis=axis)
        cells = np.argwhere(edge & (state != 2))
        cells = np.vstack(
            [cells, np.argwhere(state != 2)[rng.integers(0, (state != 2).sum(), 100)]]
        )
        for row, column in np.repeat(cells, 2, axis=0):  # two points per cell
            q = rng.uniform(-3 * math.pi, 3 * math.pi, robot.model.nq)
            alpha = (row + rng.uniform()) * table.period / rows + table.period * rng.integers(-9, 9)
            base = 0.0 if table.a == robot.model.nq else q[table.a]
            q[table.b] = base + alpha
            if table.c < robot.model.nq:
                q[table.c] = (
                    column + rng.uniform()
                ) * 2 * math.pi / columns + 2 * math.pi * rng.integers(-3, 3)
            placements = robot.placements(q)
            ta = coal.Transform3s(np.array(placements[link_a].rotation), np.zeros(3))
            tb = coal.Transform3s(np.array(placements[link_b].rotation), np.zeros(3))
            result = coal.CollisionResult()
            if state[row, column] == 0:
                assert not coal.collide(first, ta, second, tb, request, result), (
                    table.pair,
                    row,
                    column,
                )
            else:
                assert coal.collide(whole, ta, second, tb, request, result), (
                    table.pair,
                    row,
                    column,
                )
            checked[int(state[row, column])] += 1
    assert checked[0] > 1500 and checked[1] > 400, checked


# ------------------------------------------------------------------- probes
def test_probes_are_reproducible_and_never_change_the_answer(
    robot: spm.SPMRobot, checker: CollisionChecker, samples: np.ndarray
) -> None:
    again = CollisionChecker(robot)
    assert again.probes == checker.probes
    other = CollisionChecker(robot, seed=5, probe_samples=64)
    plain = CollisionChecker(robot, probes=0)
    assert plain.probes == {}
    for row in samples:
        q = row[3:]
        answer = checker.collisions(q)
        assert other.collisions(q) == answer
        assert plain.collisions(q) == answer


# ---------------------------------------------------------------------- CLI
def test_cli_collide_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["collide", "60", "90", "220", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["theta_deg"] == [60.0, 90.0, 220.0]
    assert record["reachable"] is False and record["home"] is False
    assert record["mode"] == "++-/-"
    assert record["collision"] is True
    assert ["proximal_2", "proximal_3"] in record["pairs"]
    assert record["min_distance_m"] < 0.0
    assert len(record["distances"]) == 19
    assert cli_main(["collide", "0", "0", "0"]) == 0
    text = capsys.readouterr().out
    assert "collision" in text and "false" in text and "+++/-" in text


@pytest.mark.parametrize(
    "argv",
    [
        ["collide", "0", "0"],
        ["collide", "0", "0", "nan"],
        ["collide", "0", "0", "0", "--margin-mm", "-1"],
    ],
)
def test_cli_collide_bad_input(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(argv) == 2
    error = capsys.readouterr().err
    assert error.startswith("spm: error:") and error.count("\n") == 1


# ---------------------------------------------------------------- bad input
@settings(max_examples=40)
@given(
    x=st.one_of(
        st.lists(st.floats(-10, 10), min_size=0, max_size=12).filter(
            lambda v: len(v) not in (3, 9)
        ),
        st.lists(
            st.one_of(st.just(math.nan), st.just(math.inf), st.just(-math.inf)),
            min_size=9,
            max_size=9,
        ),
    ),
    margin=st.one_of(st.floats(max_value=-1e-12), st.just(math.nan), st.just(math.inf)),
)
def test_bad_input_properties(checker: CollisionChecker, x: list[float], margin: float) -> None:
    """Wrong shapes and non-finite numbers raise InputError naming the argument; so
    does any negative or non-finite margin (even with a good x)."""
    shapes = r"input angles theta of shape \(3,\) or a joint configuration q of shape \(9,\)"
    allowed = rf"must (be {shapes}|be finite with \|x\| <= 2048 rad)"
    with pytest.raises(spm.InputError, match=f"^x {allowed}") as info:
        checker.collisions(x)
    assert info.value.argument == "x" and "x must" in str(info.value)
    match = r"^margin must be a finite distance >= 0 \[m\]"
    with pytest.raises(spm.InputError, match=match) as info:
        checker.collisions(np.zeros(9), margin=margin)
    assert info.value.argument == "margin" and repr(margin) in str(info.value)


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda r, c: r.collisions([0.0, 0.0]), "x"),
        (lambda r, c: r.collisions(np.zeros(8)), "x"),
        (lambda r, c: r.collisions([0.0, math.nan, 0.0]), "theta"),
        (lambda r, c: r.collisions(np.full(9, math.inf)), "x"),
        (lambda r, c: r.collisions("abc"), "x"),
        (lambda r, c: r.collisions(np.zeros(3), margin=-0.001), "margin"),
        (lambda r, c: r.collisions(np.zeros(3), margin=math.nan), "margin"),
        (lambda r, c: r.collisions(np.zeros(3), margin=True), "margin"),
        (lambda r, c: r.collisions(np.zeros(3), margin="1"), "margin"),
        (lambda r, c: c.distances(np.zeros(3), pairs=[("base", "proximal_1")]), "pairs"),
        (lambda r, c: c.distances(np.zeros(3), pairs=["base"]), "pairs"),
        (lambda r, c: c.collision_matrix(np.zeros(9)), "q"),
        (lambda r, c: c.clearances(np.zeros((2, 9)), cap=0.0), "cap"),
        (lambda r, c: CollisionChecker("robot"), "robot"),  # type: ignore[arg-type]
        (lambda r, c: CollisionChecker(r, probes=-1), "probes"),
        (lambda r, c: CollisionChecker(r, seed=1.5), "seed"),  # type: ignore[arg-type]
        (lambda r, c: check_input(np.zeros((2, 3)), r), "theta"),
        (lambda r, c: check_input(np.zeros(3), "robot"), "robot"),  # type: ignore[arg-type]
    ],
)
def test_bad_input(
    robot: spm.SPMRobot, checker: CollisionChecker, call: Any, argument: str
) -> None:
    with pytest.raises(spm.SPMError, match=rf"^{argument}( must\b|: )") as info:
        call(robot, checker)
    assert isinstance(info.value, spm.InputError)
    assert info.value.argument == argument
    assert argument.split(".")[0] in str(info.value)


def test_agile_eye_is_free_at_home() -> None:
    """The Agile Eye preset's links clear each other at home (by name, as the CLI takes
    it), the proximal links most narrowly."""
    robot = spm.build_robot("agile_eye")
    assert robot.design == spm.SPMDesign.agile_eye()
    home = np.zeros(3)
    assert robot.collisions(home) == []
    report = check_input(home, robot)
    assert report.reachable and not report.collision and report.pairs == ()
    distances = robot.distances(home)
    clearance = robot.min_clearance(home)
    assert clearance == pytest.approx(min(distances.values()), abs=0.0)
    assert 0.01 < clearance < 0.02  # 15.3 mm: two proximal links
    assert min(distances, key=distances.__getitem__)[0].startswith("proximal_")
    assert distances[("distal_1", "distal_2")] > 0.02
    assert distances[("proximal_1", "platform")] > 0.02
