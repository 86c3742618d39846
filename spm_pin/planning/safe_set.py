"""The safe set of a coaxial SPM in the gap plane, with certified continuity.

A state is *safe* when the platform assembles in the home mode, the singularity
margin and the dexterity are at least their thresholds, and no two links come nearer
than the clearance margin: the static checks of the servos' safety guard
(:class:`~spm_pin.hardware.guard.SafetyGuard` with the same limits). For a coaxial
design they depend only on the gaps D12, D23 between neighbouring proximal links:
turning all three inputs together turns the whole mechanism about the axis (the
base's drawn geometry is a tessellated solid of revolution, so distances to it change
with that turn by up to :data:`YAW_TOLERANCE_M`, added to the margin).

**Continuity between samples.** Each check is Lipschitz in the gaps on the safe set:

* every point of every link moves, per degree of gap motion (Euclidean in the
  (D12, D23) plane), at most ``r_max * Lq`` metres, where ``r_max`` is the largest
  distance of a link's collision geometry from the centre O and ``Lq`` bounds the sum
  of the joint-angle changes along the link's kinematic chain (a rotation composed of
  revolute joints turns by at most the sum of their angles); the distance of two
  links thus changes by at most ``2 r_max Lq`` per degree;
* the singularity margin and the dexterity change by at most ``Ls`` and ``Ld`` per
  degree.

``Lq``, ``Ls`` and ``Ld`` are measured on the grid (finite differences between
neighbouring vertices whose singularity margin is at least half the threshold) and
multiplied by :data:`LIPSCHITZ_FACTOR`. A path is then checked at samples no more than
``delta`` degrees of gap apart, each against thresholds raised by the bound times
``delta / 2`` (every point of the path lies within ``delta / 2`` of a sample): the
whole continuous path is safe, not only its samples. See :class:`SafeSet`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError
from ..kinematics import forward_kinematics, jacobian
from ..model.robot import SPMRobot
from ._evaluation import YAW_TOLERANCE_M, Evaluation, sample_checks
from .cover import SafeCover

__all__ = [
    "LIPSCHITZ_FACTOR",
    "YAW_TOLERANCE_M",
    "Evaluation",
    "Lipschitz",
    "PlanSettings",
    "SafeSet",
    "safe_set_of",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Safety factor on the Lipschitz constants measured on the grid.
LIPSCHITZ_FACTOR = 1.5
#: Rungs of the ladder of radii at which a sample's clearance is checked (half the
#: check step, then halved each rung, then 0).
LADDER_STEPS = 8
#: Halvings of an interval of a path that its samples do not cover, at most.
MAX_REFINEMENTS = 12
#: Samples evaluated one by one on the float path (more: one numpy batch; a batch
#: costs about a millisecond whatever its size, one sample a tenth of that).
SCALAR_SAMPLES = 8


@dataclasses.dataclass(frozen=True)
class PlanSettings:
    """What counts as safe, and how finely it is checked.

    Attributes:
        margin: Clearance margin between links [m] (the guard's ``collision_margin``).
        min_dexterity: Smallest dexterity 1/kappa(J) (the guard's ``min_dexterity``).
        min_singularity_margin: Smallest singularity margin (the guard's).
        grid_step_deg: Step of the gap-plane grid the search runs on [deg].
        check_step_deg: Largest gap distance between two checked samples of a path
            [deg] (the continuity buffers grow with it).
    """

    margin: float = 0.0005
    min_dexterity: float = 0.0
    min_singularity_margin: float = 0.1
    grid_step_deg: float = 2.0
    check_step_deg: float = 0.05

    def __post_init__(self) -> None:
        for name, low, high in (
            ("margin", 0.0, 0.05),
            ("min_dexterity", 0.0, 1.0),
            ("min_singularity_margin", 0.0, 1.0),
            ("grid_step_deg", 0.1, 10.0),
            ("check_step_deg", 0.001, 1.0),
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(f"{name} must be a number, got {value!r}", argument=name)
            if not low <= value <= high:  # NaN fails too
                raise InputError(
                    f"{name} must lie in [{low:g}, {high:g}], got {value!r}",
                    argument=name,
                    value=value,
                )


@dataclasses.dataclass(frozen=True)
class Lipschitz:
    """Bounds of the change of each check per degree of gap motion.

    Attributes:
        clearance: Link distance [m/deg] (``2 r_max Lq``).
        singularity: Singularity margin [1/deg].
        dexterity: Dexterity [1/deg].
        joint: ``Lq``: joint-angle change along a link's chain [rad/deg].
        r_max: Largest distance of the links' collision geometry from O [m].
    """

    clearance: float
    singularity: float
    dexterity: float
    joint: float
    r_max: float


class SafeSet:
    """The safe set of a coaxial design on a grid of the gap plane.

    Args:
        design: A coaxial SPM (default: the prototype).
        settings: The thresholds and steps.
        robot: The robot model with its collision checker (default: built).

    Attributes:
        design: The design.
        settings: As given.
        d12, d23: The grid axes [deg].
        safe: (len(d12), len(d23)) vertices safe at the plain thresholds (and inside
            the gap triangle).
        lipschitz: The continuity bounds.
        cover: The cells certified safe so far (:class:`~spm_pin.planning.cover.
            SafeCover`), grown by :meth:`certify`.
        build_time_s: Seconds spent building.
    """

    def __init__(
        self,
        design: SPMDesign | None = None,
        settings: PlanSettings | None = None,
        *,
        robot: SPMRobot | None = None,
    ) -> None:
        from ..collision import build_robot, checker_of

        start = time.perf_counter()
        if robot is None:
            robot = build_robot(design or SPMDesign.prototype())
        design = robot.design
        if not design.is_coaxial:
            raise InputError(
                f"planning in the gap plane needs a coaxial design; {design.name!r} is not "
                "(non-coaxial designs are not supported yet)",
                argument="design",
                value=design.name,
            )
        self.design = design
        self.robot = robot
        self.checker = checker_of(robot)
        self.settings = settings or PlanSettings()
        h = self.settings.grid_step_deg
        axis = np.arange(h, 360.0, h)
        self.d12, self.d23 = axis, axis.copy()
        D12, D23 = np.meshgrid(axis, axis, indexing="ij")
        inside = D12 + D23 < 360.0 - 1e-9
        theta = self.theta_of(D12[inside], D23[inside], 0.0)
        reachable, sing, dex, q = kinematic_checks(robot, theta)
        self.lipschitz = self._measure(inside, reachable, sing, dex, q)
        evaluation = self._evaluate(theta, reachable, sing, dex, q, 0.0)
        self.safe = np.zeros(inside.shape, dtype=bool)
        self.safe[inside] = evaluation.safe
        self.cover = SafeCover(self)
        self.build_time_s = time.perf_counter() - start

    # ---------------------------------------------------------------- geometry
    def theta_of(self, d12: npt.ArrayLike, d23: npt.ArrayLike, yaw: npt.ArrayLike) -> FloatArray:
        """Input angles [rad] (..., 3) with gaps D12, D23 [deg] and mean input ``yaw``
        [rad] (broadcast)."""
        eta = np.degrees(np.asarray(self.design.eta, dtype=float))
        a, b, c = np.broadcast_arrays(
            np.asarray(d12, dtype=float), np.asarray(d23, dtype=float), np.asarray(yaw)
        )
        rel = np.stack([np.zeros_like(a), eta[1] - eta[0] - a, eta[2] - eta[0] - a - b], axis=-1)
        rel = rel - rel.mean(axis=-1, keepdims=True)
        result: FloatArray = np.radians(rel) + np.asarray(c, dtype=float)[..., None]
        return result

    def gaps_of(self, theta: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(D12, D23 [deg], mean input [rad]) of input angles (..., 3); the gaps are
        taken in [0, 360)."""
        angles = np.asarray(theta, dtype=float)
        eta = np.degrees(np.asarray(self.design.eta, dtype=float))
        deg = np.degrees(angles)
        d12 = np.mod(eta[1] - eta[0] - (deg[..., 1] - deg[..., 0]), 360.0)
        d23 = np.mod(eta[2] - eta[1] - (deg[..., 2] - deg[..., 1]), 360.0)
        return d12, d23, angles.mean(axis=-1)

    # ---------------------------------------------------------------- checks
    def _measure(
        self,
        inside: BoolArray,
        reachable: BoolArray,
        sing: FloatArray,
        dex: FloatArray,
        q: FloatArray,
    ) -> Lipschitz:
        """Lipschitz bounds from neighbouring vertices (see the module)."""
        h = self.settings.grid_step_deg
        shape = inside.shape
        good = np.zeros(shape, dtype=bool)
        good[inside] = reachable & (sing >= 0.5 * self.settings.min_singularity_margin)
        grids = {}
        for name, values in (("sing", sing), ("dex", dex)):
            grid = np.full(shape, np.nan)
            grid[inside] = values
            grids[name] = grid
        qgrid = np.full((*shape, q.shape[1]), np.nan)
        qgrid[inside] = q
        worst = {"joint": 0.0, "sing": 0.0, "dex": 0.0}
        for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
            a = (slice(0, shape[0] - di), slice(max(0, -dj), shape[1] - max(0, dj)))
            b = (slice(di, shape[0]), slice(max(0, dj), shape[1] + min(0, dj) or None))
            both = good[a] & good[b]
            if not np.any(both):
                continue
            step = h * math.hypot(di, dj)
            chain = chain_change(qgrid[a][both], qgrid[b][both])
            worst["joint"] = max(worst["joint"], float(chain.max()) / step)
            for name in ("sing", "dex"):
                diff = np.abs(grids[name][b] - grids[name][a])[both]
                worst[name] = max(worst[name], float(np.nanmax(diff)) / step)
        r_max = moving_radius(self.checker)
        joint = LIPSCHITZ_FACTOR * worst["joint"]
        return Lipschitz(
            clearance=2.0 * r_max * joint,
            singularity=LIPSCHITZ_FACTOR * worst["sing"],
            dexterity=LIPSCHITZ_FACTOR * worst["dex"],
            joint=joint,
            r_max=r_max,
        )

    def _evaluate(
        self,
        theta: FloatArray,
        reachable: BoolArray,
        sing: FloatArray,
        dex: FloatArray,
        q: FloatArray,
        want: float,
    ) -> Evaluation:
        """The checks, and each sample's certified radius up to ``want`` [deg]."""
        return evaluate_with_radius(
            self.checker,
            self.settings,
            self.lipschitz,
            reachable,
            sing,
            dex,
            q,
            want,
            extra_margin=YAW_TOLERANCE_M,
        )

    def evaluate(self, theta: npt.ArrayLike, *, want: float = 0.0) -> Evaluation:
        """The checks at input angles (n, 3) [rad]; ``radius``: the gap distance
        [deg], up to ``want``, around each sample that is certified safe (negative
        where the sample itself is unsafe)."""
        angles = np.asarray(theta, dtype=float).reshape(-1, 3)
        reachable, sing, dex, q = kinematic_checks(self.robot, angles)
        return self._evaluate(angles, reachable, sing, dex, q, want)

    def _gap_steps(self, theta: FloatArray) -> FloatArray:
        """Euclidean gap distance [deg] between consecutive rows of theta (n, 3)."""
        d12, d23, _ = self.gaps_of(theta)
        a = np.degrees(np.angle(np.exp(1j * np.radians(np.diff(d12)))))
        b = np.degrees(np.angle(np.exp(1j * np.radians(np.diff(d23)))))
        steps: FloatArray = np.hypot(a, b)
        return steps

    def certify(self, theta: npt.ArrayLike) -> tuple[bool, int, Evaluation]:
        """Check a polyline of input angles (n, 3) [rad] as a continuous path.

        By the cells of :attr:`cover` it crosses (a path inside certified cells is
        safe; its samples are then those cells' corners, and the path's own samples
        where it crosses a finest cell that is not covered); where that fails, by
        the path's own samples (:meth:`certify_samples`):
        The path is sampled at most ``check_step_deg`` of gap motion apart; each
        sample is certified safe within a radius (its slack in every check divided
        by the check's Lipschitz bound). Two neighbouring samples cover the way
        between them when their radii add up to their distance; where they do not
        (near the boundary of the safe set, e.g. an end point with little slack),
        the interval is halved, up to :data:`MAX_REFINEMENTS` times.

        Returns:
            (safe, index of the first sample that failed or -1, the evaluation of
            the final samples).
        """
        certificate = self.cover.certificate(theta)  # every cell it crosses certified
        if certificate is not None:
            return True, -1, certificate
        return self.certify_samples(theta)

    def prepare_samples(self) -> None:
        """Make the collision checks of the samples' ladder of raised margins now
        (:func:`ladder_margins`; tens of milliseconds each, made on first use
        otherwise), so that no certificate by samples pays for them later;
        :meth:`SafeCover.prepare <spm_pin.planning.cover.SafeCover.prepare>` calls it."""
        for _, margin in ladder_margins(self.settings, self.lipschitz, YAW_TOLERANCE_M):
            self.checker.prepare(margin, include_fixed=False)

    def certify_samples(self, theta: npt.ArrayLike) -> tuple[bool, int, Evaluation]:
        """:meth:`certify` by the path's own samples alone (no cells)."""
        return certify_polyline(
            self.densify(theta), self.evaluate, self._gap_steps, self.settings.check_step_deg
        )

    def densify(self, theta: npt.ArrayLike) -> FloatArray:
        """The polyline (n, 3) [rad] sampled at most ``check_step_deg`` of gap motion
        apart (its vertices kept)."""
        return densify_polyline(theta, self._gap_steps, self.settings.check_step_deg)


def kinematic_checks(
    robot: SPMRobot, theta: FloatArray
) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray]:
    """At input angles (n, 3) [rad]: whether the home assembly mode exists, the
    singularity margin and the dexterity there (NaN where it does not), and the
    robot's configurations (n, nq) (zeros where it does not)."""
    if theta.shape[0] <= SCALAR_SAMPLES:
        return _scalar_checks(robot, theta)
    fk = forward_kinematics(theta, robot.design)
    reachable = np.asarray(fk.reachable, dtype=bool)
    R = np.where(reachable[:, None, None], fk.R, np.eye(3))
    jac = jacobian(theta, robot.design, R=R)
    sing: FloatArray = np.where(reachable, jac.singularity_margin, np.nan)
    dex: FloatArray = np.where(reachable, jac.dexterity, np.nan)
    q = np.zeros((theta.shape[0], robot.model.nq))
    if np.any(reachable):
        q[reachable] = robot._configuration_from_rotation(theta[reachable], R[reachable])
    return reachable, sing, dex, q


def _scalar_checks(
    robot: SPMRobot, theta: FloatArray
) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray]:
    """:func:`kinematic_checks` of a few samples, one by one
    (:func:`~spm_pin.planning._evaluation.sample_checks`)."""
    n = theta.shape[0]
    reachable = np.zeros(n, dtype=bool)
    sing = np.full(n, np.nan)
    dex = np.full(n, np.nan)
    q = np.zeros((n, robot.model.nq))
    for m, row in enumerate(theta.tolist()):
        reachable[m], sing[m], dex[m], q[m] = sample_checks(robot, row)
    return reachable, sing, dex, q


def chain_change(qa: FloatArray, qb: FloatArray) -> FloatArray:
    """The largest joint-angle change along a link's kinematic chain [rad] between
    configurations (m, 9) ``qa`` and ``qb`` (per leg: proximal u, distal w, platform
    v): a distal link turns by at most the change of u plus w, the platform by at
    most the smallest change along a whole leg. (m,)."""
    dq = np.abs(np.angle(np.exp(1j * (qb - qa))))  # (m, 9)
    legs = dq.reshape(-1, 3, 3)  # (u, w, v) per leg
    distal = legs[:, :, 0] + legs[:, :, 1]
    platform = legs.sum(axis=2).min(axis=1)
    chain: FloatArray = np.maximum(distal.max(axis=1), platform)
    return chain


def moving_radius(checker: Any) -> float:
    """The largest distance from O of the moving links' collision geometry [m] (the
    base does not move: its own size does not count)."""
    return max(
        float(np.linalg.norm(piece.vertices, axis=1).max())
        for piece in checker.pieces
        if piece.link != "base"
    )


def ladder_margins(
    s: PlanSettings, lip: Lipschitz, extra_margin: float = 0.0
) -> list[tuple[float, float]]:
    """The ladder of :func:`evaluate_with_radius`: (radius [deg], the raised clearance
    margin [m] that certifies it), largest first: half the check step, halved
    :data:`LADDER_STEPS` - 1 times, then 0."""
    base = s.margin + extra_margin
    top = 0.5 * s.check_step_deg
    levels = [top / 2.0**k for k in range(LADDER_STEPS)] + [0.0]
    return [(level, base + lip.clearance * level) for level in levels]


def evaluate_with_radius(
    checker: Any,
    s: PlanSettings,
    lip: Lipschitz,
    reachable: BoolArray,
    sing: FloatArray,
    dex: FloatArray,
    q: FloatArray,
    want: float,
    *,
    extra_margin: float = 0.0,
) -> Evaluation:
    """The checks of samples (their configurations ``q`` (n, nq)), and each sample's
    radius [deg of the planning coordinates], up to ``want``, within which every check
    is certified by the Lipschitz bounds ``lip`` (negative where the sample fails).
    ``extra_margin`` [m] is added to the clearance margin."""
    n = reachable.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        r_s = (np.nan_to_num(sing, nan=-1.0) - s.min_singularity_margin) / lip.singularity
        r_d = (np.nan_to_num(dex, nan=-1.0) - s.min_dexterity) / lip.dexterity
    radius = np.minimum(np.minimum(r_s, r_d), want)
    radius[~reachable] = -1.0
    colliding = np.zeros(n, dtype=bool)
    if checker.fixed_clearance < s.margin:  # parts that never move are too near
        colliding[:] = True
        radius[:] = -1.0
    # A fixed ladder of radii (each margin's collision plan is built once).
    ladder = ladder_margins(s, lip, extra_margin)
    for k in np.flatnonzero(radius >= 0.0):
        # The largest level the clearance covers (the parts whose distance never
        # changes, checked above, need none).
        for level, margin in ladder:
            if level > radius[k]:
                continue
            if not checker.collisions(q[k], margin=margin, include_fixed=False):
                radius[k] = level
                break
        else:
            colliding[k] = True
            radius[k] = -1.0
    return Evaluation(reachable, sing, dex, colliding, radius >= 0.0, radius)


def densify_polyline(
    theta: npt.ArrayLike, steps_of: Callable[[FloatArray], FloatArray], check_step: float
) -> FloatArray:
    """The polyline (n, 3) [rad] sampled at most ``check_step`` apart in the planning
    coordinates whose distances between consecutive rows ``steps_of`` gives [deg]
    (its vertices kept)."""
    path = np.asarray(theta, dtype=float).reshape(-1, 3)
    steps = steps_of(path)
    rows = [path[:1]]
    for k in range(1, path.shape[0]):
        parts = max(1, math.ceil(steps[k - 1] / check_step))
        t = np.arange(1, parts + 1)[:, None] / parts
        rows.append(path[k - 1] + t * (path[k] - path[k - 1]))
    result: FloatArray = np.vstack(rows)
    return result


def certify_polyline(
    samples: FloatArray,
    evaluate: Callable[..., Evaluation],
    steps_of: Callable[[FloatArray], FloatArray],
    check_step: float,
) -> tuple[bool, int, Evaluation]:
    """Certify a densified polyline (n, 3) [rad] (see :meth:`SafeSet.certify`):
    ``evaluate(samples, want=...)`` checks samples, ``steps_of(samples)`` gives the
    distances between consecutive ones in the planning coordinates [deg].

    Returns:
        (safe, index of the first sample that failed or -1, the evaluation).
    """
    want = 0.5 * check_step
    evaluation = evaluate(samples, want=want)
    for _ in range(MAX_REFINEMENTS):
        bad = np.flatnonzero(~evaluation.safe)
        if bad.size:
            return False, int(bad[0]), evaluation
        steps = steps_of(samples)
        short = evaluation.radius[:-1] + evaluation.radius[1:] < steps - 1e-12
        if not np.any(short):
            return True, -1, evaluation
        at = np.flatnonzero(short)
        middle = 0.5 * (samples[at] + samples[at + 1])
        extra = evaluate(middle, want=float(0.5 * steps[at].max()))
        samples = np.insert(samples, at + 1, middle, axis=0)
        evaluation = Evaluation(
            *(
                np.insert(getattr(evaluation, f.name), at + 1, getattr(extra, f.name))
                for f in dataclasses.fields(Evaluation)
            )
        )
    steps = steps_of(samples)
    gaps = np.flatnonzero(evaluation.radius[:-1] + evaluation.radius[1:] < steps - 1e-12)
    return False, int(gaps[0]), evaluation


@lru_cache(maxsize=4)
def safe_set_of(design: SPMDesign | None = None, settings: PlanSettings | None = None) -> SafeSet:
    """The safe set of a design, built once per design and settings in a process (a
    few seconds) and shared by every later call."""
    return SafeSet(design or SPMDesign.prototype(), settings or PlanSettings())
