"""The yes/no self-collision check of a score: does any link pair come nearer than a
margin at a configuration? Built quickly for a new design, exact like the full check.

A workspace map asks the robot's :class:`~spm_pin.collision.CollisionChecker` for
every colliding link pair, which is worth a costly set-up per design: probe piece
pairs chosen from a random sample and certified relative-angle tables (about 1.5 s
together for the prototype). A score needs only whether anything collides, once per
point of a new design, so this check skips both (the checker's answers never depend
on them: a probe or a table only settles early what the culling BVHs would find) and
runs the checker's engine alone: the BVHs of the parts that the margin can reach,
stopping at the first link pair that collides.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

from ..collision import LINK_PAIRS, CollisionChecker
from ..collision._engine import Engine
from ..collision.pairs import FloatArray
from ..design import SPMDesign
from ..model.robot import SPMRobot, build_robot

__all__ = ["MarginCheck", "margin_check_of"]

#: Designs whose checks each thread keeps (the newest last).
CACHE_SIZE = 4

_LOCAL = threading.local()


class MarginCheck:
    """Whether a configuration collides at a margin (see the module).

    Not thread-safe (Pinocchio and coal work data): :func:`margin_check_of` gives each
    thread its own.

    Attributes:
        robot: The robot of the design.
        checker: Its collision checker, made without probes (only its static piece
            model and its engines are used).
    """

    def __init__(self, design: SPMDesign) -> None:
        self.robot: SPMRobot = build_robot(design)
        self.checker = CollisionChecker(self.robot, probe_samples=0)
        self._engines: dict[float, Engine] = {}

    def _engine(self, margin: float) -> Engine:
        """The engine of every link pair at ``margin`` (made on first use)."""
        engine = self._engines.get(margin)
        if engine is None:
            order = list(range(len(LINK_PAIRS)))
            engine = Engine(self.checker._links, {}, order, margin, True, frozenset(LINK_PAIRS))
            self._engines[margin] = engine
        return engine

    def collides(self, q: FloatArray, margin: float) -> bool:
        """Whether two links come nearer than ``margin`` [m] at the joint configuration
        q (9,) (the parts whose distance never changes included, as in a map)."""
        engine = self._engine(margin)
        return bool(engine.run(self.checker._model, self.checker._data, q, True, 0))


def margin_check_of(design: SPMDesign) -> MarginCheck:
    """This thread's :class:`MarginCheck` of ``design`` (made once per thread and design;
    the last :data:`CACHE_SIZE` designs are kept)."""
    cache: OrderedDict[SPMDesign, MarginCheck] | None = getattr(_LOCAL, "checks", None)
    if cache is None:
        cache = OrderedDict()
        _LOCAL.checks = cache
    check = cache.get(design)
    if check is None:
        check = cache[design] = MarginCheck(design)
        while len(cache) > CACHE_SIZE:
            cache.popitem(last=False)
    else:
        cache.move_to_end(design)
    return check
