"""The choice of probes: per link pair, the few convex piece pairs that catch most of
its collisions in a seeded sample of reachable inputs, and the collision counts of
that sample that order the body pass and the tables' penetration checks."""

from __future__ import annotations

import collections
import math

import coal
import numpy as np

from ..kinematics import forward_kinematics
from ._static import LinkModel
from .pairs import _EPA_ITERATIONS, PROBE_MIN_SHARE, LinkPair

__all__ = ["Probes", "choose_probes"]

#: Probe piece pairs per link pair; how often each link pair collided in the sample
#: with no probe catching it; how often each piece pair collided in the sample.
Probes = tuple[
    dict[LinkPair, tuple[tuple[int, int], ...]],
    dict[LinkPair, float],
    collections.Counter[tuple[int, int]],
]


def choose_probes(links: LinkModel, count: int, samples: int, seed: int) -> Probes:
    """For each link pair, up to ``count`` piece pairs that catch its collisions in
    seeded random reachable inputs (greedy cover). A probe is kept if it catches
    at least :data:`PROBE_MIN_SHARE` of the samples that the earlier probes
    missed: a probe costs a fraction of a microsecond where it misses, a contact
    left to the BVH costs several microseconds, up to tens.

    Returns:
        The probes per link pair, the share of samples in which each link pair
        collided with no probe catching it, and the collision count of each piece
        pair in the sample.
    """
    unprobed: dict[LinkPair, float] = {}
    piece_hits: collections.Counter[tuple[int, int]] = collections.Counter()
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-math.pi, math.pi, size=(8 * samples, 3))
    theta = theta[forward_kinematics(theta, links.design).reachable][:samples]
    if theta.shape[0] == 0:  # pragma: no cover - a design with no reachable input
        return {}, unprobed, piece_hits
    q = links.robot.configuration(theta)
    every = links.all
    pieces = links.pieces
    near = [g.static_bound <= 0.0 for g in every]
    a = np.concatenate([g.a[m] for g, m in zip(every, near, strict=True)])
    b = np.concatenate([g.b[m] for g, m in zip(every, near, strict=True)])
    owner = np.concatenate([np.full(int(m.sum()), k) for k, m in enumerate(near)]).astype(np.int64)
    reach = links.radii[a] + links.radii[b]
    request = coal.CollisionRequest()
    request.break_distance = 0.0
    request.epa_max_iterations = _EPA_ITERATIONS
    result = coal.CollisionResult()
    hits: dict[int, list[set[tuple[int, int]]]] = collections.defaultdict(list)
    for item in q:
        rotations = links.link_rotations(item)
        transforms = [coal.Transform3s(R, np.zeros(3)) for R in rotations]
        centers = np.einsum("pij,pj->pi", rotations[links.piece_link], links.centers)
        close = np.flatnonzero(np.linalg.norm(centers[a] - centers[b], axis=1) <= reach)
        found: dict[int, set[tuple[int, int]]] = collections.defaultdict(set)
        for k in close:
            i, j = int(a[k]), int(b[k])
            result.clear()
            first, second = pieces[i], pieces[j]
            if coal.collide(
                first.shape,
                transforms[first.link],
                second.shape,
                transforms[second.link],
                request,
                result,
            ):
                found[int(owner[k])].add((i, j))
        for pair_index, hit in found.items():
            hits[pair_index].append(hit)
    total = q.shape[0]
    piece_hits = collections.Counter(p for v in hits.values() for s in v for p in s)
    chosen: dict[LinkPair, tuple[tuple[int, int], ...]] = {}
    for pair_index in sorted(hits):
        remaining = hits[pair_index]
        picked: list[tuple[int, int]] = []
        while remaining and len(picked) < count:
            tally = collections.Counter(p for s in remaining for p in sorted(s))
            best, caught = tally.most_common(1)[0]
            if caught < PROBE_MIN_SHARE * total:
                break
            picked.append(best)
            remaining = [s for s in remaining if best not in s]
        if picked:
            chosen[every[pair_index].pair] = tuple(picked)
        unprobed[every[pair_index].pair] = len(remaining) / total
    return chosen, unprobed, piece_hits
