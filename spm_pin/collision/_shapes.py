"""Small geometry helpers of the collision model: coal shapes from points and meshes,
axis frames, float 3-vector arithmetic, the cross-section angles of a swept part, the
rotational symmetry of a vertex set, bounding capsules and segment distances."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import coal
import numpy as np
import numpy.typing as npt
import trimesh

__all__ = [
    "ANGLE_TOL",
    "AXIS_LENGTH",
    "AXIS_TOL",
    "MIN_ORDER",
    "TWO_PI",
    "axis_frame",
    "bvh",
    "capsule",
    "concatenate",
    "convex_shape",
    "cross",
    "dot",
    "revolution_order",
    "section_angles",
    "segment_distances",
    "symmetry_order",
    "turn",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Two section angles closer than this are one section [rad].
ANGLE_TOL = 1e-7
#: Axes closer than this are the same axis.
AXIS_TOL = 1e-12
#: Length of the segment that stands for a rotation axis in distance queries [m].
AXIS_LENGTH = 10.0
#: Symmetric parts turn onto themselves by at most this angle [rad] (2 pi / 8).
MIN_ORDER = 8
TWO_PI = 2.0 * math.pi


def convex_shape(points: FloatArray) -> Any:
    """coal.Convex hull of points (qhull), with triangles for fast support queries."""
    vector = coal.StdVec_Vec3s()
    for point in np.ascontiguousarray(points, dtype=np.float64):
        vector.append(point)
    return coal.Convex.convexHull(vector, True, None)


def bvh(mesh: trimesh.Trimesh) -> Any:
    points = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    triangles = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    model = coal.BVHModelOBBRSS()
    model.beginModel(int(triangles.shape[0]), int(points.shape[0]))
    model.addVertices(points)
    model.addTriangles(triangles)
    model.endModel()
    return model


def concatenate(meshes: Sequence[trimesh.Trimesh]) -> trimesh.Trimesh:
    vertices, faces, offset = [], [], 0
    for mesh in meshes:
        vertices.append(np.asarray(mesh.vertices, dtype=np.float64))
        faces.append(np.asarray(mesh.faces, dtype=np.int64) + offset)
        offset += len(mesh.vertices)
    return trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=False)


def axis_frame(axis: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors completing ``axis`` to a right-handed frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - (helper @ axis) * axis
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def turn(
    axis: Sequence[float], c: float, s: float, x: Sequence[float]
) -> tuple[float, float, float]:
    """Rodrigues in floats: x turned about the unit ``axis`` by the angle of cosine
    ``c`` and sine ``s``."""
    k = dot(axis, x) * (1.0 - c)
    return (
        x[0] * c + (axis[1] * x[2] - axis[2] * x[1]) * s + axis[0] * k,
        x[1] * c + (axis[2] * x[0] - axis[0] * x[2]) * s + axis[1] * k,
        x[2] * c + (axis[0] * x[1] - axis[1] * x[0]) * s + axis[2] * k,
    )


def section_angles(vertices: FloatArray, axis: FloatArray) -> tuple[FloatArray, IntArray]:
    """Distinct angles of the vertices about ``axis`` (sorted) and each vertex's index
    among them."""
    e1, e2 = axis_frame(axis)
    angle = np.arctan2(vertices @ e2, vertices @ e1)
    order = np.sort(angle)
    groups = [float(order[0])]
    for value in order[1:]:
        if value - groups[-1] > ANGLE_TOL:
            groups.append(float(value))
    if len(groups) > 1 and groups[0] + 2.0 * math.pi - groups[-1] <= ANGLE_TOL:
        groups.pop()
    sections = np.array(groups)
    gap = np.abs(np.angle(np.exp(1j * (angle[:, None] - sections[None, :]))))
    return sections, np.argmin(gap, axis=1).astype(np.int64)


def revolution_order(vertices: FloatArray, axis: FloatArray) -> int:
    """n if the vertex set is invariant under turns of 2 pi / n about ``axis`` through
    O (a faceted solid of revolution), else 0."""
    sections, label = section_angles(vertices, axis)
    n = sections.size
    if n < 8:
        return 0
    steps = np.diff(np.concatenate([sections, [sections[0] + 2.0 * math.pi]]))
    if np.ptp(steps) > 1e-6:
        return 0
    height = vertices @ axis
    radius = np.linalg.norm(vertices - height[:, None] * axis, axis=1)
    profile = {
        (round(float(h), 9), round(float(r), 9)) for h, r in zip(height, radius, strict=True)
    }
    counts = np.bincount(label, minlength=n)
    if counts.min() != counts.max() or len(profile) * n != len(vertices):
        return 0
    return int(n)


def capsule(points: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """A capsule (segment p0-p1, radius) containing the points: the segment along
    their principal direction, the radius their largest distance from it [m]."""
    middle = points.mean(axis=0)
    spread = points - middle
    direction = np.linalg.svd(spread, full_matrices=False)[2][0]
    along = spread @ direction
    p0 = middle + along.min() * direction
    p1 = middle + along.max() * direction
    t = np.clip((points - p0) @ direction / max(float(along.max() - along.min()), 1e-300), 0, 1)
    nearest = p0 + t[:, None] * (p1 - p0)
    return p0, p1, float(np.linalg.norm(points - nearest, axis=1).max())


def segment_distances(p0: FloatArray, p1: FloatArray, q0: FloatArray, q1: FloatArray) -> FloatArray:
    """Distances between segments p0-p1 and q0-q1, row by row (closest points of two
    segments, clamped closed form; C. Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    tiny = 1e-30
    a_ok, e_ok = a > tiny, e > tiny
    safe_a, safe_e = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    s = np.where(
        denom > tiny, np.clip((b * f - c * e) / np.where(denom > tiny, denom, 1.0), 0, 1), 0
    )
    s = np.where(a_ok, s, 0.0)
    t = np.where(e_ok, (b * s + f) / safe_e, 0.0)
    s_low = np.where(a_ok, np.clip(-c / safe_a, 0, 1), 0.0)
    s_high = np.where(a_ok, np.clip((b - c) / safe_a, 0, 1), 0.0)
    s = np.where(t < 0, s_low, np.where(t > 1, s_high, s))
    t = np.clip(t, 0.0, 1.0)
    # With a degenerate p-segment the nearest point of q follows from t alone.
    t = np.where(a_ok, t, np.where(e_ok, np.clip(f / safe_e, 0, 1), 0.0))
    gap = (p0 + s[:, None] * d1) - (q0 + t[:, None] * d2)
    result: FloatArray = np.linalg.norm(gap, axis=1)
    return result


def symmetry_order(vertices: FloatArray, axis: FloatArray) -> int:
    """The order n >= :data:`MIN_ORDER` of a vertex set that turns onto itself by
    2 pi / n about ``axis`` through O (to 1e-9 of its size), else 0."""
    height = vertices @ axis
    radial = vertices - height[:, None] * axis
    size = float(np.abs(vertices).max())
    off = np.linalg.norm(radial, axis=1) > 1e-9 * size
    if np.count_nonzero(off) < MIN_ORDER:
        return 0
    e1, e2 = axis_frame(axis)
    angle = np.sort(np.mod(np.arctan2(radial[off] @ e2, radial[off] @ e1), TWO_PI))
    steps = np.diff(np.concatenate([angle, [angle[0] + TWO_PI]]))
    steps = steps[steps > ANGLE_TOL]
    if steps.size == 0:
        return 0
    n = round(TWO_PI / float(steps.min()))
    if n < MIN_ORDER:
        return 0
    c, s = math.cos(TWO_PI / n), math.sin(TWO_PI / n)
    turned = vertices * c + np.cross(axis, vertices) * s + np.outer(vertices @ axis, axis) * (1 - c)
    gaps = np.linalg.norm(turned[:, None, :] - vertices[None, :, :], axis=2).min(axis=1)
    return n if float(gaps.max()) <= 1e-9 * size else 0
