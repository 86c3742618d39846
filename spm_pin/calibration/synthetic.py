"""Simulated readings of a perturbed prototype with realistic noise, with the truth
behind them (:func:`synthetic_readings`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError
from ..kinematics import forward_kinematics
from ..kinematics._common import check_design
from ..rotations import exp_so3
from ._constants import COMPONENTS, SERVO_UNITS, BoolArray, FloatArray, check_count
from .convention import JointConvention
from .identifiability import _as_poses
from .parameters import CalibrationParameters
from .poses import _sample_poses
from .readings import Readings


@dataclasses.dataclass(frozen=True, eq=False)
class SyntheticReadings:
    """Readings of a simulated prototype, with the truth behind them.

    Attributes:
        readings: What the prototype would report (quantised encoders, noisy sensor).
        truth: The parameters the readings were made with.
        design: The true (perturbed) design.
        theta: The true model input angles [rad] (N, 3).
        outliers: (N,) readings given a gross sensor error.
    """

    readings: Readings
    truth: CalibrationParameters
    design: SPMDesign
    theta: FloatArray
    outliers: BoolArray


def synthetic_readings(
    poses: int | npt.ArrayLike = 100,
    design: SPMDesign | str | None = None,
    *,
    seed: int = 0,
    truth: CalibrationParameters | None = None,
    offset_std_deg: float = 2.0,
    link_std_deg: float = 0.5,
    mount_std_deg: float = 2.0,
    noise_deg: float = 0.5,
    kind: str = "quaternion",
    unit: str = "ticks",
    joints: JointConvention | None = None,
    outlier_fraction: float = 0.0,
    outlier_deg: float = 20.0,
    max_angle_deg: float = 90.0,
    min_margin: float = 0.25,
) -> SyntheticReadings:
    """Readings of a perturbed prototype with realistic noise, reproducible by ``seed``.

    The truth (unless given) draws each offset from N(0, offset_std_deg), each link
    angle from the design's value + N(0, link_std_deg) and the mounting rotation
    vector from N(0, mount_std_deg) per axis; the reference is the identity. At each
    pose the servos stand at ``poses`` (commanded angles, the model's inputs at zero
    offsets; or that many random admissible poses), the encoders report whole counts
    (``joints``, 4096 per turn: 0.088 deg steps, also for ``unit="deg"``), and the
    sensor reports R_ref R R_mount exp([n]) with n ~ N(0, noise_deg^2) per axis (for
    axis readings, each axis turned by its own such n).

    Args:
        poses: Number of random poses, or commanded angles [rad] (N, 3).
        design: The nominal design (default: the prototype).
        seed: Seed of every random draw.
        truth: The true parameters (default: drawn as above).
        offset_std_deg: Spread of the drawn offsets [deg].
        link_std_deg: Spread of the drawn link angles [deg].
        mount_std_deg: Spread of the drawn mounting rotation [deg].
        noise_deg: Sensor noise per axis [deg] (0.5 for a typical IMU; 0 for none).
        kind: ``"quaternion"`` or ``"axes"``.
        unit: Unit the servo columns will be written in: ``"ticks"``, ``"deg"``, ``"rad"``.
        joints: Encoder convention (default: XM540, zero at 0 counts, direction +1).
        outlier_fraction: Fraction of readings given a gross sensor error.
        outlier_deg: Size of those errors [deg].
        max_angle_deg: Range of the random poses around home [deg].
        min_margin: Smallest singularity margin of the random poses.

    Raises:
        InputError: bad arguments, or given poses the true design cannot assemble.
    """
    design = check_design(design)
    if kind not in COMPONENTS:
        raise InputError(f"kind must be one of {sorted(COMPONENTS)}", argument="kind", value=kind)
    if unit not in SERVO_UNITS:
        raise InputError(f"unit must be one of {list(SERVO_UNITS)}", argument="unit", value=unit)
    for value, name in (
        (offset_std_deg, "offset_std_deg"),
        (link_std_deg, "link_std_deg"),
        (mount_std_deg, "mount_std_deg"),
        (noise_deg, "noise_deg"),
        (outlier_deg, "outlier_deg"),
    ):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not (-1e308 <= value <= 1e308)  # NaN, inf and ints too large for a float
            or not (math.isfinite(value) and value >= 0)
        ):
            raise InputError(f"{name} must be a number >= 0, got {value!r}", argument=name)
    if (
        isinstance(outlier_fraction, bool)
        or not isinstance(outlier_fraction, (int, float))
        or not (0.0 <= outlier_fraction <= 1.0)
    ):
        raise InputError(
            f"outlier_fraction must lie in [0, 1], got {outlier_fraction!r}",
            argument="outlier_fraction",
        )
    joints = JointConvention() if joints is None else joints
    rng = np.random.default_rng(seed)
    if truth is None:
        link = np.radians(link_std_deg) * rng.standard_normal(3)
        truth = CalibrationParameters(
            offsets=np.radians(offset_std_deg) * rng.standard_normal(3),
            alpha1=design.alpha1 + link[0],
            alpha2=design.alpha2 + link[1],
            beta=design.beta + link[2],
            mount=exp_so3(np.radians(mount_std_deg) * rng.standard_normal(3)),
            reference=np.eye(3),
        )
    elif not isinstance(truth, CalibrationParameters):
        raise InputError("truth must be CalibrationParameters", argument="truth", value=truth)
    true_design = truth.design(design, name=f"{design.name}_true")
    if isinstance(poses, (int, np.integer)) and not isinstance(poses, bool):
        count = check_count(poses, "poses")

        def shifted(t: FloatArray) -> npt.ArrayLike:
            """Poses the true design assembles at the true inputs."""
            return forward_kinematics(t - truth.offsets, true_design).reachable

        commanded = _sample_poses(count, design, rng, max_angle_deg, min_margin, 0.0, shifted)
    else:
        commanded = _as_poses(poses, "poses")
    counts = joints.angle_to_ticks(commanded)
    reported = np.rint(counts)
    theta_reading = joints.ticks_to_angle(reported)
    theta_true = commanded - truth.offsets
    fk = forward_kinematics(theta_true, true_design)
    if not np.all(fk.reachable):
        bad = np.nonzero(~np.asarray(fk.reachable))[0]
        raise InputError(
            f"the true design cannot assemble poses {bad.tolist()}",
            argument="poses",
            value=commanded[bad],
        )
    n = commanded.shape[0]
    noise = math.radians(noise_deg)
    outliers = np.zeros(n, dtype=bool)
    n_out = round(outlier_fraction * n)
    if n_out:
        outliers[rng.choice(n, size=n_out, replace=False)] = True
    if kind == "quaternion":
        measured = truth.reference @ fk.R @ truth.mount
        kicks = noise * rng.standard_normal((n, 3))
        measured = np.stack([measured[k] @ exp_so3(kicks[k]) for k in range(n)])
        for k in np.nonzero(outliers)[0]:
            axis = rng.standard_normal(3)
            measured[k] = measured[k] @ exp_so3(
                math.radians(outlier_deg) * axis / np.linalg.norm(axis)
            )
    else:
        v = np.einsum("jk,nik->nij", truth.reference, fk.v)
        kicks = noise * rng.standard_normal((n, 3, 3))
        measured = np.stack(
            [np.stack([exp_so3(kicks[k, i]) @ v[k, i] for i in range(3)]) for k in range(n)]
        )
        for k in np.nonzero(outliers)[0]:
            axis = rng.standard_normal(3)
            turn = exp_so3(math.radians(outlier_deg) * axis / np.linalg.norm(axis))
            measured[k] = measured[k] @ turn.T
    readings = Readings(
        theta=theta_reading,
        orientation=measured,
        kind=kind,
        labels=tuple(str(k + 1) for k in range(n)),
        joints=joints,
        servo_unit=unit,
    )
    return SyntheticReadings(
        readings=readings, truth=truth, design=true_design, theta=theta_true, outliers=outliers
    )
