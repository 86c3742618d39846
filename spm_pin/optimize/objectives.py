"""What a design study varies and what it scores: :class:`DesignSpace` (the
variables and their bounds) and the objectives beyond the safe workspace's size
(:func:`~spm_pin.optimize.scoring.safe_workspace_score`):

* :func:`global_conditioning_index`: the mean dexterity 1/kappa_2(J) over the safe
  points of a score (the gap-plane grid: uniform in the input angles, each point
  standing for a whole free turn about the axis);
* :func:`cone_dexterity`: the worst dexterity over a required workspace, a cone of
  platform tilts (every azimuth) with free yaw: for a coaxial design the dexterity
  does not change when all three inputs turn together (the whole mechanism turns
  about the axis), so the torsion is left at zero;
* :func:`envelope`: the size of the robot: the ball about the centre O that holds
  every moving link in every pose (they all turn about O), and the fixed base below;
* :func:`home_clearance`: the smallest link distance at home (a constraint: no
  collision at home).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..design import LinkDimensions, SPMDesign
from ..errors import InputError
from ..kinematics import inverse_kinematics, jacobian
from ._margin_check import margin_check_of
from .scoring import WorkspaceScore

__all__ = [
    "ANGLE_VARIABLES",
    "SIZE_VARIABLES",
    "ConeDexterity",
    "DesignSpace",
    "Envelope",
    "Variable",
    "cone_dexterity",
    "envelope",
    "global_conditioning_index",
    "home_clearance",
    "tilt_rotations",
]

#: The link angles of a coaxial design [deg], by name.
ANGLE_VARIABLES = ("alpha1_deg", "alpha2_deg", "beta_deg")
#: The link sizes that may vary [m]: the lengths of LinkDimensions.
SIZE_VARIABLES = tuple(
    f.name
    for f in dataclasses.fields(LinkDimensions)
    if f.type in ("float", float) and f.name not in ("servo_mass", "density")
)


def _is_number(value: object) -> bool:
    """A real number (an int or a float, not a bool)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


@dataclasses.dataclass(frozen=True)
class Variable:
    """One variable of a study and its bounds (degrees for the link angles, metres
    for the link sizes).

    Raises:
        InputError: an unknown name, or bounds that are not finite with low < high.
    """

    name: str
    low: float
    high: float

    def __post_init__(self) -> None:
        if self.name not in ANGLE_VARIABLES + SIZE_VARIABLES:
            raise InputError(
                f"unknown variable {self.name!r}: the link angles "
                f"{list(ANGLE_VARIABLES)} or the link sizes {list(SIZE_VARIABLES)}",
                argument="name",
                value=self.name,
            )
        low, high = self.low, self.high
        if not (
            _is_number(low)
            and _is_number(high)
            and math.isfinite(low)
            and math.isfinite(high)
            and low < high
        ):
            raise InputError(
                f"the bounds of {self.name} must be finite numbers with low < high, "
                f"got [{low!r}, {high!r}]",
                argument=self.name,
            )


@dataclasses.dataclass(frozen=True)
class DesignSpace:
    """The designs a study may choose: the variables with their bounds, every other
    parameter from ``base`` (default: the prototype's angles and sizes). A base that
    is not coaxial (the Agile Eye, a design file) keeps its base axes and leg
    azimuths; the link angles and sizes vary as for a coaxial one.

    Raises:
        InputError: no variable, or one named twice.
    """

    variables: tuple[Variable, ...]
    base: SPMDesign = dataclasses.field(default_factory=SPMDesign.prototype)

    def __post_init__(self) -> None:
        names = [v.name for v in self.variables]
        if not names or len(set(names)) != len(names):
            raise InputError(
                f"a design space needs distinct variables, got {names}", argument="variables"
            )

    @property
    def names(self) -> tuple[str, ...]:
        """The variables' names, in order."""
        return tuple(v.name for v in self.variables)

    def design(self, values: Mapping[str, float], *, name: str = "candidate") -> SPMDesign:
        """The design with these values of the variables (coaxial when ``base`` is).

        Raises:
            InputError: a variable missing, one not of this space, or a value that is
                not finite or lies outside its bounds.
            DesignError: the design itself is invalid.
        """
        unknown = sorted(set(values) - set(self.names))
        missing = [n for n in self.names if n not in values]
        if unknown or missing:
            raise InputError(
                f"values must give exactly {list(self.names)}; unknown {unknown}, "
                f"missing {missing}",
                argument="values",
            )
        for variable in self.variables:
            value = values[variable.name]
            if not _is_number(value) or not variable.low <= value <= variable.high:
                raise InputError(  # NaN fails the comparison too
                    f"{variable.name} = {value!r} lies outside "
                    f"[{variable.low:g}, {variable.high:g}]",
                    argument=variable.name,
                    value=value,
                )
        base = self.base
        angles = {
            "alpha1_deg": math.degrees(base.alpha1),
            "alpha2_deg": math.degrees(base.alpha2),
            "beta_deg": math.degrees(base.beta),
        }
        angles.update({k: float(v) for k, v in values.items() if k in ANGLE_VARIABLES})
        sizes: dict[str, Any] = {k: float(v) for k, v in values.items() if k in SIZE_VARIABLES}
        dimensions = dataclasses.replace(base.dimensions, **sizes)
        if not base.is_coaxial:
            return dataclasses.replace(
                base,
                alpha1=math.radians(angles["alpha1_deg"]),
                alpha2=math.radians(angles["alpha2_deg"]),
                beta=math.radians(angles["beta_deg"]),
                dimensions=dimensions,
                name=name,
            )
        return SPMDesign.coaxial(
            angles["alpha1_deg"],
            angles["alpha2_deg"],
            angles["beta_deg"],
            dimensions=dimensions,
            name=name,
        )

    def values_of(self, design: SPMDesign) -> dict[str, float]:
        """The variables' values of a design (the inverse of :meth:`design`)."""
        out: dict[str, float] = {}
        for name in self.names:
            if name in ANGLE_VARIABLES:
                out[name] = math.degrees(getattr(design, name.removesuffix("_deg")))
            else:
                out[name] = float(getattr(design.dimensions, name))
        return out


def global_conditioning_index(score: WorkspaceScore) -> float | None:
    """The mean dexterity 1/kappa_2(J) over the safe points of a score (None where
    no point is safe): the global conditioning index over the safe workspace, each
    gap-plane point weighted alike."""
    safe = np.asarray(score.safe, dtype=bool)
    if not np.any(safe):
        return None
    return float(np.mean(np.asarray(score.dexterity)[safe]))


@dataclasses.dataclass(frozen=True)
class ConeDexterity:
    """The dexterity over a cone of platform tilts.

    Attributes:
        cone_deg: Half-angle of the cone [deg].
        worst_dexterity: The smallest dexterity over the samples (0 where a sample
            has no home-mode assembly).
        worst_tilt_deg, worst_azimuth_deg: Where it is [deg].
        reachable_fraction: Share of the samples with a home-mode assembly.
        samples: How many orientations were checked.
    """

    cone_deg: float
    worst_dexterity: float
    worst_tilt_deg: float
    worst_azimuth_deg: float
    reachable_fraction: float
    samples: int


def tilt_rotations(tilt_deg: Sequence[float], azimuth_deg: Sequence[float]) -> np.ndarray:
    """Platform rotations Rz(phi) Ry(tilt) Rz(-phi) (no torsion), (n, 3, 3), the
    convention of :func:`~spm_pin.workspace.gaps.tilt_torsion`."""
    tilt = np.radians(np.asarray(tilt_deg, dtype=float))
    phi = np.radians(np.asarray(azimuth_deg, dtype=float))
    c, s, ct, st = np.cos(phi), np.sin(phi), np.cos(tilt), np.sin(tilt)
    R = np.empty((tilt.size, 3, 3))
    R[:, 0, 0] = c * c * ct + s * s
    R[:, 0, 1] = c * s * (ct - 1.0)
    R[:, 0, 2] = c * st
    R[:, 1, 0] = c * s * (ct - 1.0)
    R[:, 1, 1] = s * s * ct + c * c
    R[:, 1, 2] = s * st
    R[:, 2, 0] = -c * st
    R[:, 2, 1] = -s * st
    R[:, 2, 2] = ct
    return R


def cone_dexterity(
    design: SPMDesign | str | None, cone_deg: float, *, step_deg: float = 2.0
) -> ConeDexterity:
    """The worst dexterity over platform tilts up to ``cone_deg`` in every azimuth
    (home working mode; free yaw: see the module), on a grid of tilt and azimuth
    ``step_deg`` apart. For a design that is not coaxial the yaw is not free: the
    figure is then that of zero torsion only.

    Raises:
        InputError: a cone outside [0, 90] deg or a step outside (0, 30] deg.
    """
    if not _is_number(cone_deg) or not 0.0 <= cone_deg <= 90.0:
        raise InputError(f"cone_deg must lie in [0, 90], got {cone_deg!r}", argument="cone_deg")
    if not _is_number(step_deg) or not 0.0 < step_deg <= 30.0:
        raise InputError(f"step_deg must lie in (0, 30], got {step_deg!r}", argument="step_deg")
    spm_design = SPMDesign.from_spec(design)
    tilts = np.linspace(0.0, cone_deg, max(2, math.ceil(cone_deg / step_deg) + 1))
    azimuths = np.arange(0.0, 360.0, step_deg)
    T, A = np.meshgrid(tilts, azimuths, indexing="ij")
    R = tilt_rotations(T.ravel(), A.ravel())
    ik = inverse_kinematics(R, spm_design)
    reachable = np.asarray(ik.reachable, dtype=bool)
    dexterity = np.zeros(R.shape[0])
    if np.any(reachable):
        jac = jacobian(ik.theta[reachable], spm_design, R=R[reachable])
        dexterity[reachable] = jac.dexterity
    worst = int(np.argmin(dexterity))
    return ConeDexterity(
        cone_deg=float(cone_deg),
        worst_dexterity=float(dexterity[worst]),
        worst_tilt_deg=float(T.ravel()[worst]),
        worst_azimuth_deg=float(A.ravel()[worst]),
        reachable_fraction=float(np.mean(reachable)),
        samples=int(R.shape[0]),
    )


@dataclasses.dataclass(frozen=True)
class Envelope:
    """The room a design takes [m].

    Attributes:
        radius_m: Radius of the ball about O that holds every moving link (proximal,
            distal, platform) in every pose: the links turn about O, so each point
            keeps its distance from O.
        base_radius_m: Largest distance of the fixed parts (base, servos) from the
            turning axis.
        height_m: From the lowest point of the fixed parts to the top of that ball.
    """

    radius_m: float
    base_radius_m: float
    height_m: float


def _robot_of(design: SPMDesign | str | None) -> Any:
    return margin_check_of(SPMDesign.from_spec(design)).robot


def envelope(design: SPMDesign | str | None = None, *, robot: Any = None) -> Envelope:
    """The envelope of a design from its links' real shapes (the convex pieces of
    the collision model; ``robot``: one already built, else built here)."""
    robot = robot if robot is not None else _robot_of(design)
    pieces = margin_check_of(robot.design).checker.pieces
    moving = np.vstack([p.vertices for p in pieces if p.link != "base"])
    fixed = np.vstack([p.vertices for p in pieces if p.link == "base"])
    radius = float(np.max(np.linalg.norm(moving, axis=1)))
    axis = np.asarray(robot.design.u[0], dtype=float)  # the turning axis (coaxial)
    along = fixed @ axis
    across = np.linalg.norm(fixed - along[:, None] * axis, axis=1)
    # The base lies along +u (below O for the prototype, u = -z).
    height = radius + max(float(np.max(along)), -radius) if fixed.size else 2.0 * radius
    return Envelope(radius_m=radius, base_radius_m=float(np.max(across)), height_m=height)


def home_clearance(design: SPMDesign | str | None = None, *, robot: Any = None) -> float:
    """The smallest distance between two checked links at home (all inputs 0) [m];
    negative or 0 where links touch. The constraint "no collision at home" is
    ``home_clearance(design) > margin``.

    The distances come from the design's collision checker made without probes
    (:mod:`spm_pin.optimize._margin_check`: the same pieces and distances as the
    full checker, without its costly set-up)."""
    robot = robot if robot is not None else _robot_of(design)
    distances = margin_check_of(robot.design).checker.distances(robot.configuration(np.zeros(3)))
    return float(min(distances.values()))
