"""Safe paths of a general (non-coaxial) SPM in its 3-D input space.

A coaxial SPM plans in its 2-D gap plane with a free yaw (:mod:`.safe_set`); a
general design, such as the Agile Eye, has no such symmetry: every input angle
changes what the mechanism looks like, so its safe set is a region of the 3-D input
space. :class:`InputSafeSet` checks input angles with the same static checks (the
home assembly mode, the singularity margin, the dexterity, the clearance of the real
link shapes) and certifies a polyline as a continuous path the same way as the gap
plane does, in input-space degrees (Euclidean):

* every point of every link moves, per degree of input motion, at most
  ``r_max * Lq`` metres (``Lq`` bounds the joint-angle change along a link's chain);
* the singularity margin and the dexterity change by at most ``Ls`` and ``Ld`` per
  degree.

``Lq``, ``Ls`` and ``Ld`` are measured at 3,000 random pairs of inputs 0.5 degree apart
in the planning box (both ends reachable, at least half the singularity threshold)
and multiplied by :data:`~spm_pin.planning.safe_set.LIPSCHITZ_FACTOR`: an estimate
from samples, as the gap plane's is from its grid. Samples of a path at most
``check_step_deg`` apart, each certified safe within a radius (its slack over the
bound), cover the way between them when their radii add up to their distance.

:func:`plan_inputs` searches with OMPL's RRTConnect (``pip install ompl``, in the
``planning`` extra), shortens the path with OMPL's simplifier, and returns it only
once the certificate holds. Its default planning box (the start and goal's box
widened by :data:`DEFAULT_HALF_WIDTH_DEG`) is rounded out to multiples of
:data:`BOX_LATTICE_DEG`, so that plans near each other share one safe set, built once
in a process (:func:`input_safe_set_of`: the robot model and the measured bounds,
a second or so), as the gap plane's :func:`~spm_pin.planning.safe_set.safe_set_of` is.
"""

from __future__ import annotations

import math
import time
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError, PlanningError
from ..model.robot import SPMRobot
from ._evaluation import Evaluation, nearest_phrase
from .safe_set import (
    LIPSCHITZ_FACTOR,
    Lipschitz,
    PlanSettings,
    certify_polyline,
    chain_change,
    densify_polyline,
    evaluate_with_radius,
    kinematic_checks,
    moving_radius,
)

__all__ = [
    "BOX_LATTICE_DEG",
    "DEFAULT_HALF_WIDTH_DEG",
    "InputSafeSet",
    "input_safe_set_of",
    "nearest_safe_input",
    "plan_inputs",
]

FloatArray = npt.NDArray[np.float64]

#: Half width of the default planning box about the start and goal [deg].
DEFAULT_HALF_WIDTH_DEG = 60.0
#: The default planning box's corners are rounded out to multiples of this [deg].
BOX_LATTICE_DEG = 120.0
#: Random pairs that count for the Lipschitz bounds (both ends reachable and not near
#: a singularity), their distance [deg], and the most batches of that many drawn.
LIPSCHITZ_PAIRS = 3000
LIPSCHITZ_BATCHES = 20
#: The search about the steepest pairs: how many, perturbed pairs per round, rounds,
#: and the first round's spread [deg] (halved each round).
REFINE_TOP = 40
REFINE_TRIES = 16
REFINE_ROUNDS = 4
REFINE_SPREAD_DEG = 4.0
LIPSCHITZ_STEP_DEG = 0.5
#: The search for the nearest safe input of an unsafe end point: sphere radii [deg],
#: directions per sphere, directions bisected at most, and bisection steps.
NEAREST_RADII_DEG = (0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 13.0, 16.0, 20.0, 25.0, 30.0,
                     40.0, 50.0, 60.0, 75.0, 90.0)  # fmt: skip
NEAREST_DIRECTIONS = 600
NEAREST_TRIES = 100
NEAREST_BISECTIONS = 12
#: Seconds OMPL may search, and attempts before giving up.
SEARCH_SECONDS = 5.0
ATTEMPTS = 3


class InputSafeSet:
    """The safe set of any SPM in a box of its 3-D input space (see the module).

    Args:
        design: The SPM (default: the Agile Eye).
        settings: The thresholds and the check step (``grid_step_deg`` unused).
        low: The planning box's lower corner [rad], (3,).
        high: Its upper corner [rad], (3,).
        robot: The robot with its collision checker (default: built).
        seed: Seed of the random pairs the Lipschitz bounds are measured at.

    Attributes:
        design: The design.
        settings: As given (or the default).
        robot: The robot model.
        checker: Its collision checker.
        low: The box's lower corner [rad].
        high: The box's upper corner [rad].
        lipschitz: The continuity bounds, per degree of input motion.
        coordinates: ``"inputs"``: radii and steps are degrees of input motion.
        build_time_s: Seconds spent measuring the bounds.
    """

    coordinates = "inputs"

    def __init__(
        self,
        design: SPMDesign | None = None,
        settings: PlanSettings | None = None,
        *,
        low: npt.ArrayLike,
        high: npt.ArrayLike,
        robot: SPMRobot | None = None,
        seed: int = 0,
    ) -> None:
        from ..collision import build_robot, checker_of

        if robot is None:
            robot = build_robot(design or SPMDesign.agile_eye())
        self.design = robot.design
        self.robot = robot
        self.checker = checker_of(robot)
        self.settings = settings or PlanSettings()
        self.low = np.asarray(low, dtype=float).reshape(3)
        self.high = np.asarray(high, dtype=float).reshape(3)
        if not (np.all(np.isfinite(self.low)) and np.all(self.high > self.low)):
            raise InputError(
                f"the planning box needs finite low < high, got {self.low} and {self.high}",
                argument="box",
            )
        start = time.perf_counter()
        self.lipschitz = self._measure(np.random.default_rng(seed))
        self.build_time_s = time.perf_counter() - start

    # ---------------------------------------------------------------- checks
    def _kinematics(self, theta: FloatArray) -> tuple[Any, Any, Any, FloatArray]:
        return kinematic_checks(self.robot, theta)

    def _rates(
        self, a: FloatArray, direction: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Per pair (a, a + LIPSCHITZ_STEP_DEG along ``direction``): the rates of the
        chain's joint angles, the singularity margin and the dexterity per degree,
        -inf where a pair does not count (an end unreachable or within half the
        singularity threshold)."""
        b = a + math.radians(LIPSCHITZ_STEP_DEG) * direction
        ra, sa, da, qa = self._kinematics(a)
        rb, sb, db, qb = self._kinematics(b)
        half = 0.5 * self.settings.min_singularity_margin
        both = ra & rb & (sa >= half) & (sb >= half)
        rates = np.full((3, a.shape[0]), -np.inf)
        if np.any(both):
            rates[0, both] = chain_change(qa[both], qb[both])
            rates[1, both] = np.abs(sb - sa)[both]
            rates[2, both] = np.abs(db - da)[both]
        rates /= LIPSCHITZ_STEP_DEG
        return rates[0], rates[1], rates[2]

    def _measure(self, rng: np.random.Generator) -> Lipschitz:
        """Lipschitz bounds from random pairs of inputs LIPSCHITZ_STEP_DEG apart.

        Drawn in batches until LIPSCHITZ_PAIRS pairs count (both ends reachable, at
        least half the singularity threshold; up to LIPSCHITZ_BATCHES batches), then
        each rate's steepest pairs are searched about (REFINE_ROUNDS rounds of
        REFINE_TRIES perturbed pairs about each of the REFINE_TOP steepest), so that
        the estimate finds the steep places of a large box, not only what the first
        draw hit."""
        starts, directions, rates = [], [], []
        counted = 0
        for _ in range(LIPSCHITZ_BATCHES):
            a = rng.uniform(self.low, self.high, size=(LIPSCHITZ_PAIRS, 3))
            direction = rng.normal(size=(LIPSCHITZ_PAIRS, 3))
            direction /= np.linalg.norm(direction, axis=1, keepdims=True)
            found = np.stack(self._rates(a, direction))
            starts.append(a)
            directions.append(direction)
            rates.append(found)
            counted += int(np.count_nonzero(np.isfinite(found[0])))
            if counted >= LIPSCHITZ_PAIRS:
                break
        if not counted:
            raise PlanningError(
                f"no reachable inputs in the planning box of {self.design.name!r}: "
                "nothing to plan in"
            )
        a, direction = np.concatenate(starts), np.concatenate(directions)
        steepest = np.concatenate(rates, axis=1).max(axis=1)
        for k in range(3):
            found = np.concatenate(rates, axis=1)[k]
            top = np.argsort(found)[::-1][:REFINE_TOP]
            top = top[np.isfinite(found[top])]
            centre, heading, best = a[top], direction[top], found[top]
            spread = math.radians(REFINE_SPREAD_DEG)
            for _ in range(REFINE_ROUNDS):
                tries = np.repeat(centre, REFINE_TRIES, axis=0)
                tries = tries + rng.normal(scale=spread, size=tries.shape)
                tries = np.clip(tries, self.low, self.high)
                turned = np.repeat(heading, REFINE_TRIES, axis=0) + rng.normal(
                    scale=0.3, size=tries.shape
                )
                turned /= np.linalg.norm(turned, axis=1, keepdims=True)
                value = self._rates(tries, turned)[k].reshape(-1, REFINE_TRIES)
                pick = np.argmax(value, axis=1)
                better = value[np.arange(len(pick)), pick] > best
                rows = np.flatnonzero(better)
                centre[rows] = tries.reshape(-1, REFINE_TRIES, 3)[rows, pick[rows]]
                heading[rows] = turned.reshape(-1, REFINE_TRIES, 3)[rows, pick[rows]]
                best[rows] = value[rows, pick[rows]]
                spread *= 0.5
            if best.size:
                steepest[k] = max(steepest[k], float(best.max()))
        joint = LIPSCHITZ_FACTOR * float(steepest[0])
        r_max = moving_radius(self.checker)
        return Lipschitz(
            clearance=2.0 * r_max * joint,
            singularity=LIPSCHITZ_FACTOR * float(steepest[1]),
            dexterity=LIPSCHITZ_FACTOR * float(steepest[2]),
            joint=joint,
            r_max=r_max,
        )

    def evaluate(self, theta: npt.ArrayLike, *, want: float = 0.0) -> Evaluation:
        """The checks at input angles (n, 3) [rad], each sample's certified radius
        [deg of input motion] up to ``want`` (negative where it fails)."""
        angles = np.asarray(theta, dtype=float).reshape(-1, 3)
        reachable, sing, dex, q = self._kinematics(angles)
        inside = np.all((angles >= self.low) & (angles <= self.high), axis=1)
        evaluation = evaluate_with_radius(
            self.checker, self.settings, self.lipschitz, reachable & inside, sing, dex, q, want
        )
        return evaluation

    @staticmethod
    def steps(theta: FloatArray) -> FloatArray:
        """Euclidean distance [deg] between consecutive rows of theta (n, 3)."""
        result: FloatArray = np.degrees(np.linalg.norm(np.diff(theta, axis=0), axis=1))
        return result

    def densify(self, theta: npt.ArrayLike) -> FloatArray:
        """The polyline (n, 3) [rad] sampled at most ``check_step_deg`` apart."""
        return densify_polyline(theta, self.steps, self.settings.check_step_deg)

    def certify(self, theta: npt.ArrayLike) -> tuple[bool, int, Evaluation]:
        """Check a polyline of input angles (n, 3) [rad] as a continuous path.

        Returns:
            (safe, index of the first sample that failed or -1, the evaluation).
        """
        return certify_polyline(
            self.densify(theta), self.evaluate, self.steps, self.settings.check_step_deg
        )


def _length_deg(theta: FloatArray) -> float:
    return float(np.sum(InputSafeSet.steps(theta)))


@lru_cache(maxsize=4)
def _robot_of(design: SPMDesign) -> SPMRobot:
    from ..collision import build_robot

    return build_robot(design)


@lru_cache(maxsize=16)
def input_safe_set_of(
    design: SPMDesign,
    settings: PlanSettings,
    low_deg: tuple[float, float, float],
    high_deg: tuple[float, float, float],
    seed: int = 0,
) -> InputSafeSet:
    """The safe set of ``design`` in the box [low_deg, high_deg] [deg], built once per
    design, settings, box and seed in a process and shared by later calls (the robot
    model is shared between boxes)."""
    return InputSafeSet(
        settings=settings,
        low=np.radians(low_deg),
        high=np.radians(high_deg),
        robot=_robot_of(design),
        seed=seed,
    )


def _default_box(
    a: FloatArray, b: FloatArray
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The start and goal's box widened by DEFAULT_HALF_WIDTH_DEG, its corners rounded
    out to multiples of BOX_LATTICE_DEG [deg]."""
    lattice = BOX_LATTICE_DEG
    low = np.floor((np.degrees(np.minimum(a, b)) - DEFAULT_HALF_WIDTH_DEG) / lattice) * lattice
    high = np.ceil((np.degrees(np.maximum(a, b)) + DEFAULT_HALF_WIDTH_DEG) / lattice) * lattice
    lows = (float(low[0]), float(low[1]), float(low[2]))
    highs = (float(high[0]), float(high[1]), float(high[2]))
    return lows, highs


def plan_inputs(
    theta0: npt.ArrayLike,
    theta1: npt.ArrayLike,
    design: SPMDesign | None = None,
    *,
    settings: PlanSettings | None = None,
    safe: InputSafeSet | None = None,
    seed: int = 0,
) -> tuple[FloatArray, dict[str, Any]]:
    """A certified safe path between input angles in the 3-D input space.

    The straight line when it is certified; else OMPL's RRTConnect in the planning
    box (the start and goal's box widened by :data:`DEFAULT_HALF_WIDTH_DEG`), its
    path simplified by OMPL and certified (up to :data:`ATTEMPTS` searches).

    Args:
        theta0: Start input angles [rad], (3,).
        theta1: Goal input angles [rad], (3,).
        design: The SPM (default: the Agile Eye); ignored when ``safe`` is given.
        settings: The thresholds (default :class:`PlanSettings`).
        safe: The safe set to plan in (default: :func:`input_safe_set_of` the start
            and goal's box widened by :data:`DEFAULT_HALF_WIDTH_DEG` and rounded out
            to multiples of :data:`BOX_LATTICE_DEG`).
        seed: OMPL's random seed (set once per process, at its first search).

    Returns:
        (path (n, 3) [rad], facts: ``straight_length_deg``, ``raw_length_deg`` (the
        search's path before simplification), ``samples``, ``min_singularity_margin``,
        ``min_dexterity``, ``planning_time_ms``, ``safe``).

    Raises:
        InputError: malformed angles.
        PlanningError: the start or goal is unsafe, OMPL is not installed, or no
            certified path was found.
    """
    begin = time.perf_counter()
    a = _angles(theta0, "start")
    b = _angles(theta1, "goal")
    if safe is None:
        low_deg, high_deg = _default_box(a, b)
        safe = input_safe_set_of(
            design or SPMDesign.agile_eye(), settings or PlanSettings(), low_deg, high_deg, seed
        )
    for name, theta in (("start", a), ("goal", b)):
        evaluation = safe.evaluate(theta[None])
        if not evaluation.safe[0]:
            reason = evaluation.reason(0, safe.settings)
            nearest = nearest_safe_input(safe, theta)
            where = nearest_phrase(safe.design, nearest, "found is")
            raise PlanningError(
                f"the {name} theta = {np.round(np.degrees(theta), 3).tolist()} deg is not "
                f"safe: {reason}{where}",
                reasons=(reason,),
                check=name,
                nearest=nearest,
            )
    straight = np.vstack([a, b])
    ok, _, evaluation = safe.certify(straight)
    path, raw = straight, straight
    if not ok:
        path, raw, evaluation = _search(safe, a, b, seed)
    facts = {
        "straight_length_deg": _length_deg(straight),
        "raw_length_deg": _length_deg(raw),
        "samples": int(evaluation.safe.size),
        "min_singularity_margin": float(np.nanmin(evaluation.singularity_margin)),
        "min_dexterity": float(np.nanmin(evaluation.dexterity)),
        "planning_time_ms": 1e3 * (time.perf_counter() - begin),
        "safe": safe,
    }
    return path, facts


def _sphere(count: int) -> FloatArray:
    """``count`` unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(count) + 0.5
    z = 1.0 - 2.0 * k / count
    azimuth = math.pi * (1.0 + math.sqrt(5.0)) * k
    ring = np.sqrt(1.0 - z * z)
    result: FloatArray = np.stack([ring * np.cos(azimuth), ring * np.sin(azimuth), z], axis=1)
    return result


def nearest_safe_input(safe: InputSafeSet, theta: npt.ArrayLike) -> FloatArray | None:
    """A safe input near ``theta`` [rad], (3,), in the safe set's box, or None when
    none is found within the largest radius.

    The search: spheres of growing radius about theta (:data:`NEAREST_RADII_DEG`,
    :data:`NEAREST_DIRECTIONS` directions each) up to the first that holds safe
    inputs; along each of those directions (up to :data:`NEAREST_TRIES`) bisection
    towards theta as far as the input stays safe; then, from the nearest of them,
    steps to safe inputs nearer theta on small spheres about it (4, 2, 1, 0.5 and
    0.25 deg). An approximation of the nearest safe input (a safe region thinner
    than the spacing of the directions can be missed), not a proof. "Safe" here
    means certified safe within half the check step of input motion, so that a path
    to the input can be certified too (a point on the very boundary cannot)."""
    centre = np.asarray(theta, dtype=float).reshape(3)

    slack = 0.5 * safe.settings.check_step_deg  # the largest radius evaluate gives

    def good(points: FloatArray) -> npt.NDArray[np.bool_]:
        radius = safe.evaluate(points, want=slack).radius
        result: npt.NDArray[np.bool_] = radius >= slack - 1e-12
        return result

    directions = _sphere(NEAREST_DIRECTIONS)
    inner = 0.0
    for radius in NEAREST_RADII_DEG:
        ok = good(centre + math.radians(radius) * directions)
        if np.any(ok):
            break
        inner = radius
    else:
        return None
    found = directions[np.flatnonzero(ok)[:NEAREST_TRIES]]
    low = np.full(found.shape[0], inner)
    high = np.full(found.shape[0], radius)
    for _ in range(NEAREST_BISECTIONS):
        middle = 0.5 * (low + high)
        inside = good(centre + np.radians(middle)[:, None] * found)
        high = np.where(inside, middle, high)
        low = np.where(inside, low, middle)
    k = int(np.argmin(high))
    best: FloatArray = centre + math.radians(float(high[k])) * found[k]
    distance = float(np.linalg.norm(best - centre))
    steps = _sphere(NEAREST_DIRECTIONS // 4)
    for step_deg in (4.0, 2.0, 1.0, 0.5, 0.25):
        while True:
            tries = best + math.radians(step_deg) * steps
            gaps = np.linalg.norm(tries - centre, axis=1)
            nearer = gaps < distance - 1e-12
            if not np.any(nearer):
                break
            order = np.flatnonzero(nearer)[np.argsort(gaps[nearer])]
            inside = good(tries[order])
            if not np.any(inside):
                break
            best = tries[order[int(np.argmax(inside))]]
            distance = float(np.linalg.norm(best - centre))
    return best


def _angles(theta: npt.ArrayLike, name: str) -> FloatArray:
    try:
        angles = np.asarray(theta, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be 3 input angles [rad], got {theta!r}") from None
    if angles.shape != (3,) or not np.all(np.isfinite(angles)):
        raise InputError(f"{name} must be 3 finite input angles [rad], got {theta!r}")
    return angles


_OMPL_SEEDED = False


def _search(
    safe: InputSafeSet, a: FloatArray, b: FloatArray, seed: int
) -> tuple[FloatArray, FloatArray, Evaluation]:
    """OMPL's RRTConnect + simplification, certified (see :func:`plan_inputs`)."""
    global _OMPL_SEEDED
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError as exc:
        raise PlanningError(
            "the straight line is not safe, and planning around it in the 3-D input "
            f"space needs OMPL (pip install 'spm-pin[planning]'): {exc}"
        ) from None
    ou.setLogLevel(ou.LogLevel.LOG_ERROR)
    if not _OMPL_SEEDED:  # OMPL accepts a seed once, before its first sampler
        ou.RNG.setSeed(seed)
        _OMPL_SEEDED = True
    space = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for j in range(3):
        bounds.setLow(j, float(safe.low[j]))
        bounds.setHigh(j, float(safe.high[j]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)

    def valid(state: Any) -> bool:
        theta = np.array([state[0], state[1], state[2]], dtype=float)
        return bool(safe.evaluate(theta[None]).safe[0])

    setup.setStateValidityChecker(valid)
    info = setup.getSpaceInformation()
    # OMPL checks motions at this fraction of the box's extent: the check step.
    extent = math.degrees(space.getMaximumExtent())
    info.setStateValidityCheckingResolution(min(0.01, safe.settings.check_step_deg / extent * 4))
    start, goal = space.allocState(), space.allocState()
    for j in range(3):
        start[j], goal[j] = float(a[j]), float(b[j])
    setup.setStartAndGoalStates(start, goal)
    setup.setPlanner(og.RRTConnect(info))
    why = "no path found"
    for _ in range(ATTEMPTS):
        setup.clear()
        setup.solve(SEARCH_SECONDS)
        if not setup.haveExactSolutionPath():
            why = f"no path found within {SEARCH_SECONDS:g} s"
            continue
        found = setup.getSolutionPath()
        raw = np.array(
            [[found.getState(k)[j] for j in range(3)] for k in range(found.getStateCount())]
        )
        setup.simplifySolution()
        found = setup.getSolutionPath()
        path = np.array(
            [[found.getState(k)[j] for j in range(3)] for k in range(found.getStateCount())]
        )
        path[0], path[-1] = a, b
        ok, index, evaluation = safe.certify(path)
        if ok:
            return path, raw, evaluation
        why = f"the path found fails the continuous certificate at sample {index}"
    raise PlanningError(
        f"no certified path from {np.round(np.degrees(a), 3).tolist()} deg to "
        f"{np.round(np.degrees(b), 3).tolist()} deg in the 3-D input space: {why}"
    )
