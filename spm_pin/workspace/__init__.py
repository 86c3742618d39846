r"""Workspace maps of a coaxial SPM: reachability, singularities, dexterity, collisions.

Adding one angle c to all three inputs of a coaxial SPM only turns the platform
about the common axis (by -c), so every quantity mapped here depends on the gaps
between neighbouring proximal links alone (docs/conventions.md). With w_i at azimuth
eta_i - theta_i, the gap from link i to the next one counterclockwise is

    D12 = (eta_2 - theta_2) - (eta_1 - theta_1),  D23 = (eta_3 - theta_3) - (eta_2 - theta_2),
    D31 = 360 deg - D12 - D23

(for the prototype D12 = 120 + theta_1 - theta_2, ...). A map samples the plane
(D12, D23) and evaluates the input theta = (0, eta_2 - eta_1 - D12,
eta_3 - eta_1 - D12 - D23) at each point. Every kinematic quantity is the same at
any other torsion; so are the collisions of every link pair except those with the
base, whose hub (the only base part within reach of the moving links) is a faceted
cylinder, so they change by at most its facet depth (0.04 mm for the prototype).

At each point (home assembly mode):

* ``reachable``: a home-mode assembly exists;
* ``type_i`` / ``type_ii``, ``singularity_margin``, ``det_a``: singularity data of
  :func:`spm_pin.jacobian` (type I bounds the home-mode region; type II does not
  occur inside it for the prototype);
* ``dexterity``: 1/kappa_2(J);
* ``collision``, ``pair_mask``: self-collision (:mod:`spm_pin.collision`) in the
  assembly mode of the library's rule (:func:`spm_pin.select_assembly`): where no
  home-mode assembly exists, in the real mode nearest to it, as ``spm collide``
  reports; with no real assembly, only the proximal links, placed by theta alone;
* ``clearance``: a lower bound of the distance between the links at the point, from
  collision checks at a ladder of margins (the largest level at which nothing
  collides), leaving out the parts whose distance does not depend on the
  configuration (the nested drive tubes);
* ``safe``: reachable, dexterity >= ``min_dexterity`` and no collision at ``margin``;
* ``tilt``, ``azimuth``, ``torsion``: tilt-and-torsion angles of the platform, R =
  Rz(azimuth) Ry(tilt) Rz(-azimuth) Rz(torsion). Tilt and azimuth - torsion do not
  depend on the torsion of the inputs: they describe the orientation workspace.

The points are evaluated in chunks through a ``concurrent.futures``-style executor
(anything with ``submit(fn, *args)`` returning futures), so a process pool, a Dask
``client.get_executor()`` or a Ray executor run the same code; results are put back
in point order, so a map does not depend on the executor.
"""

from .compute import workspace_map
from .gaps import gap_inputs, gaps_from_theta, tilt_torsion
from .result import MAP_FIELDS, WorkspaceMap
from .settings import CLEARANCE_LADDER, WorkspaceSettings

__all__ = [
    "CLEARANCE_LADDER",
    "MAP_FIELDS",
    "WorkspaceMap",
    "WorkspaceSettings",
    "gap_inputs",
    "gaps_from_theta",
    "tilt_torsion",
    "workspace_map",
]
