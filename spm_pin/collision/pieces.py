"""Exact convex pieces of the links: every part of a link (:mod:`spm_pin.model.geometry`)
as convex pieces whose union is the drawn shape, the raw material of the collision
checker."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import trimesh

from ..design import SPMDesign
from ..errors import SPMError
from ..kinematics._common import check_design
from ..model.geometry import link_parts
from ._shapes import convex_shape, section_angles

__all__ = ["VOLUME_RTOL", "ConvexPiece", "convex_pieces"]

FloatArray = npt.NDArray[np.float64]

#: Relative tolerance of the volume check of a convex cut.
VOLUME_RTOL = 1e-9


@dataclasses.dataclass(frozen=True)
class ConvexPiece:
    """One exact convex piece of a link part.

    Attributes:
        link: Link name.
        part: Part name (:attr:`spm_pin.model.LinkPart.name`).
        index: Index of the piece within its part (0 for a convex part).
        vertices: Vertices of the piece, link frame (= world frame at home) [m],
            shape (k, 3); the piece is their convex hull.
    """

    link: str
    part: str
    index: int
    vertices: FloatArray


def _sweep_cells(vertices: FloatArray, axis: FloatArray) -> list[FloatArray] | None:
    """Vertex sets of the cells between consecutive sections of a shape swept about
    ``axis`` (a plate bent along an arc, a tube), or None if it is not swept."""
    sections, label = section_angles(vertices, axis)
    count = sections.size
    if count < 3:
        return None
    steps = np.diff(np.concatenate([sections, [sections[0] + 2.0 * math.pi]]))
    closed = bool(steps.max() < 3.0 * np.median(steps))
    start = 0 if closed else (int(np.argmax(steps)) + 1) % count
    cells = []
    for k in range(count if closed else count - 1):
        a, b = (start + k) % count, (start + k + 1) % count
        cells.append(vertices[(label == a) | (label == b)])
    return cells


def _solid(points: FloatArray) -> bool:
    """At least 4 points spanning 3 dimensions (qhull needs that)."""
    if points.shape[0] < 4:
        return False
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return bool(spread[-1] > 1e-9 * max(float(spread[0]), 1e-300))


def _hull_volume(points: FloatArray) -> float:
    return float(convex_shape(points).computeVolume())


def _candidate_axes(design: SPMDesign) -> list[FloatArray]:
    """Axes about which the link parts are swept: joint axes and arc normals."""
    u, w0, v0 = design.u, design.w0, design.v0
    axes: list[FloatArray] = [np.array([0.0, 0.0, 1.0])]
    mean = u.mean(axis=0)
    if np.linalg.norm(mean) > 1e-6:
        axes.append(mean / np.linalg.norm(mean))
    for leg in range(3):
        axes += [u[leg], w0[leg], v0[leg]]
        for a, b in ((u[leg], w0[leg]), (w0[leg], v0[leg])):
            normal = np.cross(a, b)
            if np.linalg.norm(normal) > 1e-9:
                axes.append(normal / np.linalg.norm(normal))
    return axes


def _cut(mesh: trimesh.Trimesh, axes: Sequence[FloatArray]) -> list[FloatArray]:
    """Exact convex pieces of one closed part mesh (see :func:`convex_pieces`)."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    volume = float(mesh.volume)
    if mesh.is_convex:
        return [vertices]
    for axis in axes:
        cells = _sweep_cells(vertices, axis)
        if cells is None or not all(_solid(cell) for cell in cells):
            continue
        total = sum(_hull_volume(cell) for cell in cells)
        if abs(total - volume) <= VOLUME_RTOL * abs(volume) + 1e-15:
            return cells
    raise SPMError(  # pragma: no cover - a geometry module change the cut cannot follow
        f"a part with {len(vertices)} vertices is neither convex nor swept about a joint "
        "axis; the collision model cannot cut it into exact convex pieces"
    )


@functools.lru_cache(maxsize=8)
def _pieces(design: SPMDesign) -> dict[str, tuple[ConvexPiece, ...]]:
    axes = _candidate_axes(design)
    result: dict[str, tuple[ConvexPiece, ...]] = {}
    for link, parts in link_parts(design).items():
        pieces: list[ConvexPiece] = []
        for part in parts:
            for index, cell in enumerate(_cut(part.mesh, axes)):
                cell.setflags(write=False)
                pieces.append(ConvexPiece(link, part.name, index, cell))
        result[link] = tuple(pieces)
    return result


def convex_pieces(design: SPMDesign | str | None = None) -> dict[str, tuple[ConvexPiece, ...]]:
    """Exact convex pieces of every link (keys :data:`LINK_NAMES`), link frame [m].

    Convex parts (cylinders, boxes, hulls) are one piece each. Curved plates, tubes
    and gears are cut along their sweep (about a joint axis or the normal of their
    arc) into the cells between consecutive cross-sections; each cell is the convex
    hull of its two sections. The cut is accepted only if the cells' volumes add up
    to the part's volume (relative 1e-9), so the pieces are the drawn shape.

    Args:
        design: The SPM (default: the prototype).
    """
    return _pieces(check_design(design))
