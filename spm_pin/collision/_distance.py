"""Exact distances between links: the minimum over their convex pieces' pairs (GJK),
pruned with bounding capsules of the parts and pieces and with the static bounds."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import coal
import numpy as np

from ._shapes import capsule, segment_distances
from ._static import LinkModel
from .pairs import FloatArray, IntArray, LinkPair

__all__ = ["DistanceIndex"]


class DistanceIndex:
    """Bounding capsules of the parts and pieces, for exact distances by pruning.

    The distance of a link pair is the minimum over its pieces' pairs. Part pairs
    whose capsules are further apart than an upper bound of the link pair's distance
    (two points of its parts) are dropped; the pieces of the others are tried in order
    of their capsule lower bounds (and the rotation-invariant static bound) with GJK,
    until the next lower bound is no smaller than the best distance found.
    """

    def __init__(self, links: LinkModel) -> None:
        pieces = links.pieces
        self.links = links
        self.pieces = pieces
        self.all = links.all
        part_key: dict[tuple[int, str], int] = {}
        part_of_piece = np.empty(len(pieces), dtype=np.int64)
        for k, piece in enumerate(pieces):
            part_of_piece[k] = part_key.setdefault((piece.link, piece.part), len(part_key))
        part_link = np.empty(len(part_key), dtype=np.int64)
        part_capsules: list[tuple[FloatArray, FloatArray, float]] = []
        part_anchor = np.empty((len(part_key), 3))
        for (link, _), number in part_key.items():
            part_link[number] = link
            vertices = np.vstack(
                [links.convex[k].vertices for k in np.flatnonzero(part_of_piece == number)]
            )
            p0, p1, radius = capsule(vertices)
            part_capsules.append((p0, p1, radius))
            middle = 0.5 * (p0 + p1)
            part_anchor[number] = vertices[np.argmin(np.linalg.norm(vertices - middle, axis=1))]
        self.piece_link = links.piece_link
        self.part_link = part_link
        self.piece_caps = np.array([[p.capsule[0], p.capsule[1]] for p in pieces])  # (n, 2, 3)
        self.piece_radius = np.array([p.capsule[2] for p in pieces])
        self.part_caps = np.array([[c[0], c[1]] for c in part_capsules])
        self.part_radius = np.array([c[2] for c in part_capsules])
        self.part_anchor = part_anchor
        # Per link pair and per choice of include_fixed: its part pairs, and for each
        # the rows of its piece pairs.
        self.groups: dict[bool, list[tuple[IntArray, IntArray, list[IntArray]]]] = {
            True: [],
            False: [],
        }
        count = len(part_key)
        for geometry in links.all:
            for include_fixed in (True, False):
                keep = np.ones(geometry.a.size, dtype=bool) if include_fixed else ~geometry.fixed
                kept = np.flatnonzero(keep)
                keys = part_of_piece[geometry.a[kept]] * count + part_of_piece[geometry.b[kept]]
                unique, inverse = np.unique(keys, return_inverse=True)
                order = np.argsort(inverse, kind="stable")
                bounds = np.searchsorted(inverse[order], np.arange(unique.size + 1))
                rows = [kept[order[bounds[k] : bounds[k + 1]]] for k in range(unique.size)]
                self.groups[include_fixed].append((unique // count, unique % count, rows))
        self.functors: dict[tuple[int, int], Any] = {}
        self.request = coal.DistanceRequest()
        self.result = coal.DistanceResult()

    def world(self, rotations: FloatArray) -> dict[str, FloatArray]:
        """Capsule end points and anchors in the world frame."""
        piece_r = rotations[self.piece_link]
        part_r = rotations[self.part_link]
        return {
            "pieces": np.einsum("pij,pkj->pki", piece_r, self.piece_caps),
            "parts": np.einsum("pij,pkj->pki", part_r, self.part_caps),
            "anchors": np.einsum("pij,pj->pi", part_r, self.part_anchor),
        }

    def link_pair_distance(
        self,
        number: int,
        world: dict[str, FloatArray],
        transforms: Sequence[Any],
        include_fixed: bool,
        cap: float,
    ) -> float:
        geometry = self.all[number]
        part_a, part_b, rows = self.groups[include_fixed][number]
        if part_a.size == 0:
            return math.inf
        parts, radius = world["parts"], self.part_radius
        lower = (
            segment_distances(
                parts[part_a, 0], parts[part_a, 1], parts[part_b, 0], parts[part_b, 1]
            )
            - radius[part_a]
            - radius[part_b]
        )
        upper = np.linalg.norm(world["anchors"][part_a] - world["anchors"][part_b], axis=1)
        best = float(np.min(upper))
        caps, piece_radius = world["pieces"], self.piece_radius
        # Branch and bound: part pairs in order of their lower bounds; within each,
        # pieces in order of theirs. Overlapping capsules bound nothing (-inf).
        part_lower = np.where(lower > 0.0, lower, -math.inf)
        for k in np.argsort(part_lower, kind="stable"):
            if part_lower[k] >= best or part_lower[k] > cap:
                break
            picked = rows[k]
            a, b = geometry.a[picked], geometry.b[picked]
            gap = (
                segment_distances(caps[a, 0], caps[a, 1], caps[b, 0], caps[b, 1])
                - piece_radius[a]
                - piece_radius[b]
            )
            bound = geometry.static_bound[picked]
            piece_lower = np.maximum(
                np.where(gap > 0.0, gap, -math.inf), np.where(bound > 0.0, bound, -math.inf)
            )
            for m in np.argsort(piece_lower, kind="stable"):
                if piece_lower[m] >= best or piece_lower[m] > cap:
                    break
                best = min(best, self.distance(int(a[m]), int(b[m]), transforms))
        return best if best <= cap else cap

    def distance(self, i: int, j: int, transforms: Sequence[Any]) -> float:
        """Distance of pieces i and j placed by their links' ``transforms`` [m] (GJK;
        negative: minus a penetration depth)."""
        functor = self.functors.get((i, j))
        if functor is None:
            functor = coal.ComputeDistance(self.pieces[i].shape, self.pieces[j].shape)
            self.functors[(i, j)] = functor
        result = self.result
        result.clear()
        return float(
            functor(
                transforms[self.pieces[i].link],
                transforms[self.pieces[j].link],
                self.request,
                result,
            )
        )

    def distances_q(
        self,
        q: FloatArray,
        pairs: Sequence[LinkPair],
        include_fixed: bool,
        cap: float,
    ) -> dict[LinkPair, float]:
        """Distance of each link pair of ``pairs`` at a checked q [m], in the order of
        :data:`LINK_PAIRS`; above ``cap``, ``cap``."""
        rotations = self.links.link_rotations(q)
        transforms = [coal.Transform3s(R, np.zeros(3)) for R in rotations]
        world = self.world(rotations)
        out: dict[LinkPair, float] = {}
        for number, geometry in enumerate(self.all):
            if geometry.pair not in pairs:
                continue
            out[geometry.pair] = self.link_pair_distance(
                number, world, transforms, include_fixed, cap
            )
        return out
