"""Poses for a calibration run: :func:`plan_poses` (greedy D-optimal choice among
admissible poses), :class:`PosePlan` and its pose list, :func:`load_poses`."""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign, _read_text
from ..errors import FileFormatError, InputError
from ..kinematics import jacobian
from ..kinematics._common import check_design
from ._constants import COMPONENTS, BoolArray, FloatArray, check_count, check_positive, parse_number
from .convention import JointConvention
from .identifiability import Observability, _observability_of, _pose_jacobians
from .parameters import CalibrationParameters, _expand


@dataclasses.dataclass(frozen=True, eq=False)
class PosePlan:
    """Poses chosen for a calibration run.

    Attributes:
        theta: Input angles [rad] (N, 3), in the order to visit them (nearest
            neighbour from home).
        observability: Of the chosen poses.
        design: The nominal design planned for.
        candidates: How many admissible candidates the poses were chosen from.
        random_index: Observability index of as many random admissible poses (for
            comparison).
    """

    theta: FloatArray
    observability: Observability
    design: SPMDesign
    candidates: int
    random_index: float

    @property
    def theta_deg(self) -> FloatArray:
        """Input angles [deg] (N, 3)."""
        return np.degrees(self.theta)

    def to_csv(
        self, path: str | Path | None = None, *, joints: JointConvention | None = None
    ) -> str:
        """The pose list as CSV (``pose, theta1_deg, theta2_deg, theta3_deg``).

        With ``joints``, goal encoder counts ``servo1_ticks..servo3_ticks`` follow
        (rounded; the convention of :class:`JointConvention`).
        """
        obs = self.observability
        out = io.StringIO()
        out.write(
            f"# spm-pin calibration poses for {self.design.name}: {len(self.theta)} poses, "
            f"observability index {obs.index:.4g} (random poses: {self.random_index:.4g}), "
            f"condition number {obs.condition_number:.4g}\n"
        )
        out.write(
            "# At each pose: record the servo positions and the sensor orientation as one "
            "row of the readings file.\n"
        )
        header = ["pose", "theta1_deg", "theta2_deg", "theta3_deg"]
        if joints is not None:
            header += ["servo1_ticks", "servo2_ticks", "servo3_ticks"]
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(header)
        ticks = None if joints is None else np.rint(joints.angle_to_ticks(self.theta))
        for k, row in enumerate(self.theta_deg):
            values = [str(k + 1), *(f"{a:.6f}" for a in row)]
            if ticks is not None:
                values += [str(int(t)) for t in ticks[k]]
            writer.writerow(values)
        text = out.getvalue()
        if path is not None:
            Path(path).write_text(text, encoding="utf-8")
        return text


def load_poses(path: str | Path) -> FloatArray:
    """Input angles [rad] (N, 3) of a pose list written by :meth:`PosePlan.to_csv`.

    Needs the columns ``theta1_deg..theta3_deg`` (or ``_rad``); others are ignored.
    """
    path = Path(path)
    text, _ = _read_text(path, "pose list")
    header: list[str] | None = None
    rows: list[list[float]] = []
    cols: list[int] = []
    unit = "deg"
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f.strip() for f in next(csv.reader([line]))]
        if header is None:
            header = fields
            for candidate in ("deg", "rad"):
                names = [f"theta{i}_{candidate}" for i in (1, 2, 3)]
                if all(n in header for n in names):
                    cols, unit = [header.index(n) for n in names], candidate
                    break
            else:
                raise FileFormatError(
                    f"missing columns theta1_deg, theta2_deg, theta3_deg (or _rad); the header "
                    f"has {header}",
                    path=str(path),
                    line=number,
                )
            continue
        if len(fields) != len(header):
            raise FileFormatError(
                f"{len(fields)} values, but the header has {len(header)} columns",
                path=str(path),
                line=number,
            )
        rows.append([parse_number(fields[c], header[c], number, str(path)) for c in cols])
    if not rows:
        raise FileFormatError("no poses in the file", path=str(path))
    theta = np.array(rows)
    return np.radians(theta) if unit == "deg" else theta


def _gaps_deg(theta: FloatArray, design: SPMDesign) -> FloatArray:
    """Gaps between adjacent proximal links [deg] of a coaxial design (N, 3)."""
    eta = np.asarray(design.eta)
    gaps = []
    for i in range(3):
        j = (i + 1) % 3
        gap = np.mod(eta[j] - eta[i], 2 * math.pi) + theta[:, i] - theta[:, j]
        gaps.append(np.degrees(gap))
    return np.stack(gaps, axis=1)


def _admissible(
    theta: FloatArray,
    design: SPMDesign,
    min_margin: float,
    min_gap_deg: float,
    accept: Callable[[FloatArray], npt.ArrayLike] | None,
) -> BoolArray:
    jac = jacobian(theta, design)
    ok = np.asarray(jac.reachable) & (np.nan_to_num(jac.singularity_margin) >= min_margin)
    if design.is_coaxial:
        ok &= np.all(_gaps_deg(theta, design) >= min_gap_deg, axis=1)
    if accept is not None and np.any(ok):
        verdict = np.asarray(accept(theta[ok]), dtype=bool)
        if verdict.shape != (int(np.sum(ok)),):
            raise InputError(
                f"accept must return one bool per pose, shape ({int(np.sum(ok))},), got "
                f"{verdict.shape}",
                argument="accept",
            )
        ok[np.nonzero(ok)[0][~verdict]] = False
    return ok


def _sample_poses(
    count: int,
    design: SPMDesign,
    rng: np.random.Generator,
    max_angle_deg: float,
    min_margin: float,
    min_gap_deg: float,
    accept: Callable[[FloatArray], npt.ArrayLike] | None,
) -> FloatArray:
    found: list[FloatArray] = []
    have = 0
    limit = math.radians(max_angle_deg)
    for _ in range(200):
        batch = rng.uniform(-limit, limit, size=(max(4 * (count - have), 256), 3))
        good = batch[_admissible(batch, design, min_margin, min_gap_deg, accept)]
        found.append(good)
        have += good.shape[0]
        if have >= count:
            return np.concatenate(found)[:count]
    raise InputError(
        f"found only {have} admissible poses of {count}: relax min_margin ({min_margin}), "
        f"min_gap_deg ({min_gap_deg}) or max_angle_deg ({max_angle_deg})",
        argument="min_margin",
        value=min_margin,
    )


def plan_poses(
    count: int,
    design: SPMDesign | str | None = None,
    *,
    parameters: Sequence[str] | str | None = None,
    kind: str = "quaternion",
    candidates: int = 2000,
    seed: int = 0,
    max_angle_deg: float = 90.0,
    min_margin: float = 0.25,
    min_gap_deg: float = 45.0,
    accept: Callable[[FloatArray], npt.ArrayLike] | None = None,
    noise_deg: float = 0.5,
) -> PosePlan:
    """Choose informative poses for a calibration run (greedy D-optimal design).

    Candidates are input angles uniform in [-max_angle_deg, max_angle_deg]^3 that the
    nominal design assembles, with singularity margin >= ``min_margin`` (see
    :func:`spm_pin.jacobian`), for coaxial designs gaps between adjacent proximal
    links >= ``min_gap_deg``, and accepted by ``accept`` (e.g. a collision check).
    Poses are added one at a time, each maximising log det(J^T J) of the poses so far
    (the observability index O1), then ordered by nearest neighbour from home.

    Args:
        count: Number of poses (>= 1).
        design: The nominal design (default: the prototype).
        parameters: Names or groups to identify (default as in :func:`calibrate`).
        kind: ``"quaternion"`` or ``"axes"`` readings.
        candidates: Number of admissible candidates to choose from.
        seed: Seed of the candidate sampler.
        max_angle_deg: Range of each input angle around home [deg].
        min_margin: Smallest singularity margin, in [0, 1).
        min_gap_deg: Smallest gap between adjacent proximal links [deg] (coaxial).
        accept: Optional filter, (M, 3) input angles [rad] -> (M,) bools.
        noise_deg: Measurement noise per axis [deg] for the predicted deviations.

    Returns:
        PosePlan; ``plan.to_csv(path)`` writes the pose list.
    """
    design = check_design(design)
    count = check_count(count, "count")
    candidates = check_count(candidates, "candidates")
    if kind not in COMPONENTS:
        raise InputError(f"kind must be one of {sorted(COMPONENTS)}", argument="kind", value=kind)
    names = _expand(parameters, kind)
    check_positive(max_angle_deg, "max_angle_deg")
    noise = math.radians(check_positive(noise_deg, "noise_deg"))
    if (
        isinstance(min_margin, bool)
        or not isinstance(min_margin, (int, float))
        or not (0.0 <= min_margin < 1.0)
    ):
        raise InputError(
            f"min_margin must lie in [0, 1), got {min_margin!r}", argument="min_margin"
        )
    if isinstance(min_gap_deg, bool) or not isinstance(min_gap_deg, (int, float)):
        raise InputError(
            f"min_gap_deg must be a number, got {min_gap_deg!r}", argument="min_gap_deg"
        )
    rng = np.random.default_rng(seed)
    pool = _sample_poses(
        max(candidates, count), design, rng, max_angle_deg, min_margin, min_gap_deg, accept
    )
    start = CalibrationParameters.nominal(design)
    blocks, _ = _pose_jacobians(pool, design, names, kind, start)
    P = blocks.shape[-1]
    scale = float(np.mean(np.einsum("nkp,nkp->n", blocks, blocks))) / P
    M = 1e-6 * max(scale, 1e-12) * np.eye(P)
    chosen: list[int] = []
    available = np.ones(pool.shape[0], dtype=bool)
    for _ in range(count):
        Minv = np.linalg.inv(M)
        S = blocks @ Minv @ np.swapaxes(blocks, -1, -2)
        gain = np.linalg.slogdet(np.eye(blocks.shape[1]) + S)[1]
        gain[~available] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        available[best] = False
        M = M + blocks[best].T @ blocks[best]
    theta = _nearest_neighbour_order(pool[chosen])
    chosen_blocks, _ = _pose_jacobians(theta, design, names, kind, start)
    obs = _observability_of(chosen_blocks, names, noise, count)
    random_blocks = blocks[rng.choice(pool.shape[0], size=count, replace=False)]
    random_index = _observability_of(random_blocks, names, noise, count).index
    return PosePlan(
        theta=theta,
        observability=obs,
        design=design,
        candidates=int(pool.shape[0]),
        random_index=random_index,
    )


def _nearest_neighbour_order(theta: FloatArray) -> FloatArray:
    order: list[int] = []
    left = list(range(theta.shape[0]))
    here = np.zeros(3)
    while left:
        dist = np.max(np.abs(theta[left] - here), axis=1)
        k = left.pop(int(np.argmin(dist)))
        order.append(k)
        here = theta[k]
    return theta[order]
