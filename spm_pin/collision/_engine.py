"""The coal engine of a collision check at one margin: the probe piece pairs and the
culling BVHs of some link pairs as two Pinocchio geometry models, and the check that
runs them, switching off what a table or an earlier collision settled."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import pinocchio as pin

from ..model.geometry import LINK_NAMES
from ._static import LinkModel
from .pairs import _EPA_ITERATIONS, FloatArray, LinkPair

if TYPE_CHECKING:
    from ..model.robot import SPMRobot

__all__ = ["Engine", "collision_data", "geometry_object"]


def geometry_object(robot: SPMRobot, name: str, link: str, shape: Any) -> Any:
    """A Pinocchio geometry object of ``shape`` fixed to the frame of ``link``."""
    frame = robot.link_frames[link]
    model = robot.model
    return pin.GeometryObject(
        name, model.frames[frame].parentJoint, frame, pin.SE3.Identity(), shape
    )


def collision_data(gm: pin.GeometryModel, margin: float) -> pin.GeometryData:
    """GeometryData of ``gm`` whose requests test for a distance below ``margin``."""
    gd = pin.GeometryData(gm)
    for request in gd.collisionRequests:
        request.security_margin = margin
        request.break_distance = 0.0
        request.epa_max_iterations = _EPA_ITERATIONS
    return gd


class Engine:
    """The collision check of some link pairs at one margin (see :mod:`spm_pin.collision`).

    A link pair is split into units, one per pair of piece groups (a link's parts
    symmetric about its axis, and the rest), each with its culling BVH pair and the
    probes whose pieces it holds. Two Pinocchio geometry models, made once:

    * probes: the probe piece pairs of every unit, run in one ``pin.computeCollisions``
      call that does not stop (forward kinematics and placements included); a
      colliding probe settles its link pair;
    * bodies: the culling BVHs of every unit, run in one call that stops at the first
      collision; that link pair is recorded and switched off, and the call repeats
      until nothing collides.

    Units that a table settles (``skip``) and, in the body pass, the link pairs that a
    probe settled are switched off; only the changes since the previous call are
    made. Unit k of :attr:`units` is bit k of the masks. The body pass takes the link
    pairs in ``body_order`` (indices into :data:`LINK_PAIRS`).
    """

    def __init__(
        self,
        links: LinkModel,
        probes: dict[LinkPair, tuple[tuple[int, int], ...]],
        body_order: Sequence[int],
        margin: float,
        include_fixed: bool,
        pairs: frozenset[LinkPair] | None,
    ) -> None:
        robot = links.robot
        probe_model, body_model = pin.GeometryModel(), pin.GeometryModel()
        probe_objects: dict[int, int] = {}
        body_objects: dict[tuple[str, tuple[str, ...]], int] = {}

        def probe(index: int) -> int:
            if index not in probe_objects:
                piece = links.pieces[index]
                geometry = geometry_object(
                    robot, f"piece{index}", LINK_NAMES[piece.link], piece.shape
                )
                probe_objects[index] = probe_model.addGeometryObject(geometry)
            return probe_objects[index]

        def body(link: str, parts: Iterable[str]) -> int:
            key = (link, tuple(sorted(set(parts))))
            if key not in body_objects:
                geometry = geometry_object(
                    robot, f"{link}/{'+'.join(key[1])}", link, links.body(key)
                )
                body_objects[key] = body_model.addGeometryObject(geometry)
            return body_objects[key]

        group = links.piece_group
        #: The units: (link pair, group of the first link, group of the second).
        self.units: list[tuple[LinkPair, int, int]] = []
        self.link_pairs: list[LinkPair] = []
        self.pair_masks: dict[LinkPair, int] = {}
        probe_switches: list[list[int]] = []
        body_switches: list[list[int]] = []
        probe_owner: list[int] = []
        body_owner: list[int] = []
        # Link pairs whose bodies often have to confirm a contact go first: the body
        # pass then repeats over fewer pairs.
        for geometry in (links.all[k] for k in body_order):
            if pairs is not None and geometry.pair not in pairs:
                continue
            link_a, link_b = geometry.pair
            for group_a, group_b, parts_a, parts_b in links.unit_parts(
                geometry, margin, include_fixed
            ):
                number = len(self.units)
                self.units.append((geometry.pair, group_a, group_b))
                if geometry.pair not in self.pair_masks:
                    self.link_pairs.append(geometry.pair)
                    self.pair_masks[geometry.pair] = 0
                self.pair_masks[geometry.pair] |= 1 << number
                indices = []
                for i, j in probes.get(geometry.pair, ()):
                    if group[i] == group_a and group[j] == group_b:
                        indices.append(len(probe_owner))
                        probe_model.addCollisionPair(pin.CollisionPair(probe(i), probe(j)))
                        probe_owner.append(number)
                probe_switches.append(indices)
                chunks = [parts_a]
                if group_a == group_b == 0 and (link_a[:9], link_b[:7]) == ("proximal_", "distal_"):
                    # A proximal link's main parts against a distal link: the joint boss
                    # in a BVH of its own, apart from the plate and spoke; the tighter
                    # root volumes make near misses cheaper (measured: p95 -12 %,
                    # median +0.5 us).
                    bosses = {part for part in parts_a if part.startswith("boss")}
                    chunks = [chunk for chunk in (bosses, parts_a - bosses) if chunk]
                switches = []
                for chunk in chunks:
                    first, second = body(link_a, chunk), body(link_b, parts_b)
                    switches.append(len(body_owner))
                    body_model.addCollisionPair(pin.CollisionPair(first, second))
                    body_owner.append(number)
                body_switches.append(switches)
        self.margin = margin
        self.include_fixed = include_fixed
        self.bits = {key: 1 << k for k, key in enumerate(self.units)}
        self.every = (1 << len(self.units)) - 1
        self.probe_model, self.body_model = probe_model, body_model
        self.probe_data = collision_data(probe_model, margin)
        self.body_data = collision_data(body_model, margin)
        # Per collision pair: its unit's bit, the isCollision method of its result
        # (bound once: the reference follows the C++ object; indexing the vector
        # proxy at each look-up costs about 4x more), the mask of its link pair's
        # units and the link pair.
        results = self.probe_data.collisionResults
        self.probe_reads = [
            (1 << k, results[n].isCollision, self.pair_masks[self.units[k][0]], self.units[k][0])
            for n, k in enumerate(probe_owner)
        ]
        results = self.body_data.collisionResults
        self.body_reads = [
            (1 << k, results[n].isCollision, self.pair_masks[self.units[k][0]], self.units[k][0])
            for n, k in enumerate(body_owner)
        ]
        self.probe_switches = probe_switches
        self.body_switches = body_switches
        # Masks of the units whose probes, and bodies, are switched off.
        self.probe_off = 0
        self.body_off = 0

    @property
    def geometry_model(self) -> pin.GeometryModel:
        """Both passes in one model, for inspection: the probe pairs, then the bodies."""
        gm = pin.GeometryModel()
        for model in (self.probe_model, self.body_model):
            offset = gm.ngeoms
            for geometry in model.geometryObjects:
                gm.addGeometryObject(geometry)
            for pair in model.collisionPairs:
                gm.addCollisionPair(pin.CollisionPair(pair.first + offset, pair.second + offset))
        return gm

    @staticmethod
    def _switch(gd: pin.GeometryData, switches: list[list[int]], changed: int, off: int) -> None:
        """Switch the collision pairs of the units in mask ``changed`` off (if in mask
        ``off``) or on."""
        while changed:
            low = changed & -changed
            changed ^= low
            toggle = gd.deactivateCollisionPair if off & low else gd.activateCollisionPair
            for k in switches[low.bit_length() - 1]:
                toggle(k)

    def run(
        self, model: pin.Model, data: pin.Data, q: FloatArray, first_only: bool, skip: int
    ) -> list[LinkPair]:
        """The colliding link pairs at q, leaving out the units of mask ``skip`` (not
        sorted; with ``first_only``, at most one)."""
        if skip != self.probe_off:
            self._switch(self.probe_data, self.probe_switches, skip ^ self.probe_off, skip)
            self.probe_off = skip
        found = []
        off = skip
        if pin.computeCollisions(model, data, self.probe_model, self.probe_data, q, False):
            for bit, read, mask, pair in self.probe_reads:
                if not off & bit and read():  # (switched-off results are stale)
                    off |= mask
                    found.append(pair)
                    if first_only:
                        return found
        if off != self.body_off:
            self._switch(self.body_data, self.body_switches, off ^ self.body_off, off)
            self.body_off = off
        if off == self.every:
            return found
        gm, gd = self.body_model, self.body_data
        pin.updateGeometryPlacements(model, data, gm, gd)
        while pin.computeCollisions(gm, gd, True):
            # The first switched-on pair that collides (the pass stopped there).
            _, _, mask, pair = next(
                entry for entry in self.body_reads if not off & entry[0] and entry[1]()
            )
            found.append(pair)
            self._switch(gd, self.body_switches, mask & ~off, off | mask)
            off = self.body_off = off | mask
            if first_only or off == self.every:
                break
        return found
