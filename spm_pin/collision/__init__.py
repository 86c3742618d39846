r"""Self-collision of an SPM's links with coal: colliding link pairs, distances, clearance.

Every link is checked against every other link except the pairs that share a joint,
which touch by construction: ``base``-``proximal_i`` (joint u_i),
``proximal_i``-``distal_i`` (w_i) and ``distal_i``-``platform`` (v_i, the loop
closures). That leaves 19 link pairs (:data:`LINK_PAIRS`).

The shapes are the link shapes that are drawn (:func:`spm_pin.model.link_parts`):
every part is cut into exact convex pieces (:func:`convex_pieces`): convex parts
stay whole; curved plates, tubes and gears are swept shapes, cut along their sweep
into cells between consecutive cross-sections. Each cell is the convex hull of two
neighbouring sections, and that hull *is* the cell (its faces are planar), so the
pieces and the drawn triangles bound the same volume; the cut is checked by volume
when it is made.

How one check runs (choices measured by ``benchmarks/bench_collision.py``):

* **Static culling.** Every joint axis passes through O, so each link moves by a
  rotation about O and every piece keeps its distance range from O: two pieces whose
  shells are further apart than the margin can never meet. Links that turn about one
  common axis (the coaxial proximal links) also keep each piece's height along that
  axis and its distance from it, which removes the nested drive tubes and gears from
  each other's checks as long as the margin is below their clearance
  (:attr:`CollisionChecker.fixed_clearance`: a bound of 0.94 mm for the prototype,
  whose tubes are 1 mm apart).
* **Units.** Each link pair is split by piece groups: a link's parts that are
  symmetric about its axis (a proximal link's drive tube and gear, the base hub:
  faceted solids that turn onto themselves every 2 pi / 48) and the rest. Each unit
  has one culling body per side: a triangle-mesh BVH (coal OBBRSS) of the parts in
  reach, which proves a pair apart in well under a microsecond but is slow to confirm
  a contact (its triangles are thin). Against a distal link, a proximal link's joint
  boss has a BVH of its own, apart from its plate and spoke (near misses then cost
  less).
* **Tables.** Some units are placed relative to each other by one or two joint
  angles: two coaxial proximal links by the difference of their inputs; a symmetric
  part against a distal link by the turn about the axis (modulo its symmetry) and the
  distal link's joint w. A table over those angles, made once per margin, certifies
  each cell free (a check at a larger margin at the cell's middle and a Lipschitz
  bound), colliding (two convex pieces that overlap deeper than that bound) or
  undecided; a lookup in Python floats then settles the unit, and only undecided
  cells leave it to the passes below (about 1 % of them).
* **Probes.** Convex piece pairs that, in a seeded sample of the workspace, caught
  most collisions of their link pair (GJK confirms a contact in about a
  microsecond). All probes of the units left run in one ``pin.computeCollisions``
  call that does not stop; a probe that collides settles its link pair.
* **Bodies.** The culling bodies of the link pairs still open run in one call that
  stops at the first collision; that link pair is recorded and switched off, and the
  call repeats until nothing collides. Switching pairs on and off is done only where
  the set changed since the previous call.

Tables, probes and culling only decide what to skip, never the answer: each table
cell is proved for every angle in it, each probe is a piece of both links, and the
BVHs decide whenever no table or probe does.

Distances (:meth:`CollisionChecker.distances`) are exact minima over the convex
pieces (GJK), pruned with bounding spheres; negative values are penetration depths
of the deepest-overlapping pieces (a lower bound of the links' penetration).
"""

from .checker import CollisionChecker, build_robot, checker_of
from .pairs import ADJACENT_PAIRS, DEFAULT_PROBES, LINK_PAIRS, LinkPair
from .pieces import ConvexPiece, convex_pieces
from .report import CollisionReport, check_input

__all__ = [
    "ADJACENT_PAIRS",
    "DEFAULT_PROBES",
    "LINK_PAIRS",
    "CollisionChecker",
    "CollisionReport",
    "ConvexPiece",
    "LinkPair",
    "build_robot",
    "check_input",
    "checker_of",
    "convex_pieces",
]
