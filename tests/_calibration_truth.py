"""Calibration readings built from the documented measurement rule, not by the library.

``spm_pin.calibration.synthetic_readings`` and the calibration model are written by the
same hands, so one sign error made in both passes every test that takes its truth from
the generator. This module makes readings of a prototype with known parameters from
docs/calibration.md alone (numpy; the platform rotation at given inputs comes from
``spm.forward_kinematics``, which other tests check against brute force):

* The servos: ``theta = r - offset`` (the model's input is the reading minus the
  offset), so servo i stands at the shaft angle ``r_i = theta_i + offset_i`` and its
  encoder reports the whole count nearest to the inverse of
  ``reading_i [deg] = direction_i * (ticks_i - zero_offset_i) * 360 /
  (ticks_per_turn * gear_ratio_i)``.
* The sensor: ``R_meas = R_ref R(theta; alpha1, alpha2, beta) R_mount`` with R_mount
  the sensor frame in the platform frame and R_ref the world frame in the sensor's
  reference frame, each the exponential of its rotation vector; the noise is a
  rotation by N(0, noise_deg^2) per axis in the sensor frame, ``R_meas exp([n])``.
  The file holds the unit quaternion (w, x, y, z), scalar first, Hamilton, sensor
  frame to reference frame.
* Axis readings: ``v_i,meas = R_ref R v_i0(beta)``, v_i0 = [sin b cos(eta_i - 90 deg),
  sin b sin(eta_i - 90 deg), cos b] (docs/conventions), each turned by its own noise.

The readings are written as the documented CSV text, so the library reads them through
its public parser. ``CONVENTIONS`` lists deliberately wrong variants of the rule, which
the tests use to show that calibration tells the conventions apart.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

import spm_pin as spm

#: Encoder counts per turn of the XM540 (docs/calibration.md).
TICKS_PER_TURN = 4096

#: The documented rule and deliberately wrong variants of it.
CONVENTIONS = (
    "documented",  # r = theta + offset; R_meas = R_ref R R_mount exp([n])
    "offset_sign_flipped",  # r = theta - offset
    "mount_on_left",  # R_meas = R_ref R_mount R
    "mount_transposed",  # R_meas = R_ref R R_mount^T
    "quaternion_conjugated",  # the file holds reference frame to sensor frame
    "reference_on_right",  # R_meas = R R_mount R_ref
)


@dataclasses.dataclass(frozen=True)
class Encoders:
    """The per-servo settings of the readings file (documented keys)."""

    direction: tuple[int, int, int] = (1, 1, 1)
    zero_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gear_ratio: tuple[float, float, float] = (1.0, 1.0, 1.0)
    ticks_per_turn: int = TICKS_PER_TURN

    def header(self) -> str:
        def triple(values: tuple[float, ...]) -> str:
            return ", ".join(repr(v) for v in values)

        return (
            "# spm-pin calibration readings (tests/_calibration_truth.py)\n"
            f"# ticks_per_turn = {self.ticks_per_turn}\n"
            f"# direction = {triple(self.direction)}\n"
            f"# zero_offset = {triple(self.zero_offset)}\n"
            f"# gear_ratio = {triple(self.gear_ratio)}\n"
        )

    def counts(self, shaft_rad: np.ndarray) -> np.ndarray:
        """Counts (not rounded) at shaft angles [rad]: the documented formula solved
        for ticks."""
        per_turn = self.ticks_per_turn * np.asarray(self.gear_ratio)
        direction = np.asarray(self.direction, dtype=float)
        result: np.ndarray = np.asarray(self.zero_offset) + np.asarray(
            shaft_rad
        ) / direction * per_turn / (2 * math.pi)
        return result

    def ticks(self, shaft_rad: np.ndarray) -> np.ndarray:
        """The whole counts an encoder reports at shaft angles [rad]."""
        return np.rint(self.counts(shaft_rad))

    def reading_rad(self, ticks: np.ndarray) -> np.ndarray:
        """Shaft angles [rad] the counts stand for (the documented formula)."""
        direction = np.asarray(self.direction, dtype=float)
        per_turn = self.ticks_per_turn * np.asarray(self.gear_ratio)
        degrees = direction * (ticks - np.asarray(self.zero_offset)) * 360.0 / per_turn
        return np.radians(degrees)


@dataclasses.dataclass(frozen=True)
class Truth:
    """Known parameters of the simulated prototype [deg]."""

    offsets_deg: tuple[float, float, float]
    alpha1_deg: float
    alpha2_deg: float
    beta_deg: float
    mount_deg: tuple[float, float, float]  # rotation vector of R_mount
    ref_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # rotation vector of R_ref

    @property
    def offsets(self) -> np.ndarray:
        return np.radians(self.offsets_deg)

    @property
    def links(self) -> np.ndarray:
        return np.radians([self.alpha1_deg, self.alpha2_deg, self.beta_deg])

    @property
    def mount(self) -> np.ndarray:
        return rotation(np.radians(self.mount_deg))

    @property
    def reference(self) -> np.ndarray:
        return rotation(np.radians(self.ref_deg))

    def design(self, base: spm.SPMDesign) -> spm.SPMDesign:
        alpha1, alpha2, beta = self.links
        return dataclasses.replace(
            base, alpha1=float(alpha1), alpha2=float(alpha2), beta=float(beta), name="truth"
        )


@dataclasses.dataclass(frozen=True)
class Generated:
    """Readings made by this module, with everything behind them."""

    text: str  # the readings file
    theta: np.ndarray  # the model's true inputs [rad] (N, 3)
    ticks: np.ndarray  # reported counts (N, 3)
    measured: np.ndarray  # R_meas (N, 3, 3) or measured axes as rows (N, 3, 3)


def skew(v: np.ndarray) -> np.ndarray:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation(rotvec: np.ndarray) -> np.ndarray:
    """exp([rotvec]) by Rodrigues' formula."""
    rotvec = np.asarray(rotvec, dtype=float)
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-15:
        return np.eye(3)
    K = skew(rotvec / angle)
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """log of a rotation matrix (angles below 180 deg)."""
    angle = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))
    axial = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    if angle < 1e-12:
        return axial
    return angle * axial / math.sin(angle)


def hamilton_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of the unit quaternion (w, x, y, z), Hamilton convention."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method)."""
    trace = float(np.trace(R))
    diagonal = np.diag(R)
    k = int(np.argmax([trace, *diagonal]))
    if k == 0:
        w = math.sqrt(1.0 + trace) / 2.0
        q = np.array([w, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        q[1:] /= 4.0 * w
    else:
        i = k - 1
        j, m = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(1.0 + 2.0 * R[i, i] - trace) / 2.0
        q = np.zeros(4)
        q[1 + i] = s
        q[0] = (R[m, j] - R[j, m]) / (4.0 * s)
        q[1 + j] = (R[j, i] + R[i, j]) / (4.0 * s)
        q[1 + m] = (R[m, i] + R[i, m]) / (4.0 * s)
    q /= np.linalg.norm(q)
    if q[0] < 0:
        q = -q
    assert np.allclose(hamilton_matrix(q), R, atol=1e-12), "quaternion round trip"
    return q


def v0(beta: float, eta: tuple[float, float, float]) -> np.ndarray:
    """Platform joint axes at home (rows), the documented formula."""
    return np.array(
        [
            [
                math.sin(beta) * math.cos(e - math.pi / 2),
                math.sin(beta) * math.sin(e - math.pi / 2),
                math.cos(beta),
            ]
            for e in eta
        ]
    )


def admissible_poses(
    count: int,
    design: spm.SPMDesign,
    *,
    seed: int,
    max_deg: float = 70.0,
    min_margin: float = 0.3,
) -> np.ndarray:
    """``count`` model inputs [rad] (N, 3), uniform in +-max_deg, that ``design``
    assembles in the home mode away from singularities."""
    rng = np.random.default_rng(seed)
    found = np.zeros((0, 3))
    while found.shape[0] < count:
        batch = rng.uniform(-math.radians(max_deg), math.radians(max_deg), size=(4 * count, 3))
        jac = spm.jacobian(batch, design)
        good = np.asarray(jac.reachable) & (np.nan_to_num(jac.singularity_margin) >= min_margin)
        found = np.concatenate([found, batch[good]])
    return found[:count]


def generate(
    truth: Truth,
    theta: np.ndarray,
    base: spm.SPMDesign,
    *,
    kind: str = "quaternion",
    encoders: Encoders = Encoders(),
    noise_deg: float = 0.0,
    seed: int = 0,
    convention: str = "documented",
) -> Generated:
    """Readings of the prototype ``truth`` at the model inputs ``theta`` [rad] (N, 3).

    Args:
        truth: The known parameters.
        theta: The model's true input angles (what the kinematics sees).
        base: The nominal design the truth perturbs.
        kind: ``"quaternion"`` (IMU) or ``"axes"`` (markers).
        encoders: Settings of the encoder columns.
        noise_deg: Sensor noise per axis [deg].
        seed: Seed of the noise.
        convention: One of :data:`CONVENTIONS` (``"documented"`` for the truth).
    """
    if convention not in CONVENTIONS:
        raise ValueError(f"convention must be one of {CONVENTIONS}, got {convention!r}")
    theta = np.asarray(theta, dtype=float)
    n = theta.shape[0]
    design = truth.design(base)
    fk = spm.forward_kinematics(theta, design)
    assert np.all(fk.reachable), "the true design must assemble every pose"
    sign = -1.0 if convention == "offset_sign_flipped" else 1.0
    shaft = theta + sign * truth.offsets  # theta = r - offset
    ticks = encoders.ticks(shaft)
    rng = np.random.default_rng(seed)
    noise = math.radians(noise_deg)
    R_ref, R_mount = truth.reference, truth.mount
    rows = []
    measured = np.zeros((n, 3, 3))
    for k in range(n):
        R = fk.R[k]
        if kind == "quaternion":
            if convention == "mount_on_left":
                sensor = R_ref @ R_mount @ R
            elif convention == "mount_transposed":
                sensor = R_ref @ R @ R_mount.T
            elif convention == "reference_on_right":
                sensor = R @ R_mount @ R_ref
            else:
                sensor = R_ref @ R @ R_mount
            sensor = sensor @ rotation(noise * rng.standard_normal(3))
            measured[k] = sensor
            q = quaternion(sensor)
            if convention == "quaternion_conjugated":
                q = q * np.array([1.0, -1.0, -1.0, -1.0])
            values = q
        elif kind == "axes":
            axes = (R @ v0(design.beta, design.eta).T).T  # rows R v_i0
            axes = axes @ R_ref.T  # rows R_ref R v_i0
            axes = np.stack([rotation(noise * rng.standard_normal(3)) @ a for a in axes])
            measured[k] = axes
            values = axes.reshape(-1)
        else:
            raise ValueError(f"kind must be 'quaternion' or 'axes', got {kind!r}")
        row = [str(k + 1), *(str(int(t)) for t in ticks[k]), *(repr(float(x)) for x in values)]
        rows.append(",".join(row))
    if kind == "quaternion":
        columns = ["qw", "qx", "qy", "qz"]
    else:
        columns = [f"v{i}_{c}" for i in (1, 2, 3) for c in "xyz"]
    header = ",".join(["pose", "servo1_ticks", "servo2_ticks", "servo3_ticks", *columns])
    text = encoders.header() + header + "\n" + "\n".join(rows) + "\n"
    return Generated(text=text, theta=theta, ticks=ticks, measured=measured)
