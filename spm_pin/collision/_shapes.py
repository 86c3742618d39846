"""Small geometry helpers of the collision model: coal shapes from points and meshes,
axis frames, float 3-vector arithmetic and the cross-section angles of a swept part."""

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
    "axis_frame",
    "bvh",
    "concatenate",
    "convex_shape",
    "cross",
    "dot",
    "section_angles",
    "turn",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Two section angles closer than this are one section [rad].
ANGLE_TOL = 1e-7


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
