"""Calibration: analytic Jacobian against finite differences, recovery of known
perturbations within the confidence intervals, the readings format and its errors,
identifiability warnings, pose planning and the ``spm calibrate`` family of commands."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import subprocess
import sys
import warnings
from pathlib import Path

import _calibration_truth as independent
import numpy as np
import pytest
from conftest import get_design
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

import spm_pin as spm
from spm_pin import calibration as cal
from spm_pin.cli import EXIT_NOT_IDENTIFIED, main
from spm_pin.hardware import (
    PULSES_PER_TURN,
    HardwareConfig,
    JointConfig,
    JointMap,
    SafetyLimits,
    ServoSettings,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

#: Tolerances, by what they compare.
TOL = {
    "jacobian": 2e-7,  # analytic against central differences (h = 1e-6 rad)
    "geometry": 1e-8,  # d w_i0 / d p against differences of SPMDesign.w0
    "exact": 1e-8,  # noise-free recovery [rad]
    "csv": 1e-11,  # values after a CSV round trip (12 significant digits)
    "poses_deg": 1e-6,  # pose list written with 6 decimals
    "fd_method": 1e-6,  # analytic and finite-difference calibrations agree [rad]
    # Readings from the documented rule (tests/_calibration_truth.py):
    "generators_reading": 1e-12,  # servo readings of both generators [rad] (same counts)
    "generators_sensor": 1e-12,  # sensor rotations / axes of both generators
    "truth_exact": 1e-8,  # noise-free, 2^40 counts per turn: estimates [rad]
    "truth_exact_counts": 1e-4,  # ... and the identified zero offsets [counts]
    "truth_counts_deg": 0.06,  # noise-free, XM540 counts (0.088 deg): estimates [deg]
    "truth_rms_counts_deg": 0.06,  # ... and the RMS orientation error after [deg]
    "truth_z": 5.0,  # 0.5 deg noise: |estimate - truth| <= truth_z standard deviations
    "truth_rms_noise": 1.25,  # ... and RMS error after <= this * what the noise leaves
    "wrong_factor": 10.0,  # a wrong convention misses by this many times the tolerance
}
#: Probability that an honest interval misses, per parameter and for the joint test
#: (small: the tests check many intervals).
MISS = 1e-4
JOINT_MISS = 1e-4
#: Seeds of the recovery test.
SEEDS = range(6)


def truth_of(result: cal.CalibrationResult, syn: cal.SyntheticReadings) -> np.ndarray:
    """The true values of the estimated parameters (mount/ref relative to the start)."""
    vector = syn.truth.vector(result.start)
    return np.array([vector[cal.PARAMETER_NAMES.index(e.name)] for e in result.estimates])


def calibrate_quietly(readings: cal.Readings, **kwargs: object) -> cal.CalibrationResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cal.IdentifiabilityWarning)
        return cal.calibrate(readings, **kwargs)  # type: ignore[arg-type]


# ------------------------------------------------------------------------- Jacobian
@pytest.mark.parametrize("design_name", ["prototype", "general", "agile_eye"])
def test_home_axis_derivatives_match_the_design(design_name: str) -> None:
    """d w_i0 / d(alpha1, alpha2, beta) against differences of SPMDesign.w0."""
    design = get_design(design_name)
    geo = cal._geometry(design)
    np.testing.assert_allclose(geo.w0, design.w0, atol=1e-12)
    h = 1e-6
    for p, name in enumerate(("alpha1", "alpha2", "beta")):
        up = dataclasses.replace(design, **{name: getattr(design, name) + h})
        down = dataclasses.replace(design, **{name: getattr(design, name) - h})
        numeric = (np.asarray(up.w0) - np.asarray(down.w0)) / (2 * h)
        np.testing.assert_allclose(geo.dw0[p], numeric, atol=TOL["geometry"], err_msg=name)


@pytest.mark.parametrize("kind", ["quaternion", "axes"])
@pytest.mark.parametrize("design_name", ["prototype", "general"])
def test_residual_jacobian_matches_finite_differences(kind: str, design_name: str) -> None:
    design = get_design(design_name)
    rng = np.random.default_rng(11)
    syn = cal.synthetic_readings(15, design, seed=3, kind=kind, max_angle_deg=60.0)
    start = cal.CalibrationParameters.nominal(
        design,
        mount=Rotation.random(random_state=rng).as_matrix(),
        reference=Rotation.random(random_state=rng).as_matrix(),
    )
    model = cal._Model(syn.readings.theta, syn.readings.orientation, kind, design, start)
    # A point away from every special value: offsets, links, mount and ref all perturbed.
    x = syn.truth.vector(start)
    x[9:12] = np.radians([1.5, -2.0, 0.7])
    x[6:9] += np.radians([0.4, 0.3, -0.5])
    evaluation = model.evaluate(x, jac=True)
    assert np.all(evaluation.reachable)
    assert evaluation.jacobian is not None
    J = evaluation.jacobian.reshape(-1, len(cal.PARAMETER_NAMES))
    h = 1e-6
    for p, name in enumerate(cal.PARAMETER_NAMES):
        step = np.zeros_like(x)
        step[p] = h
        up = model.evaluate(x + step, jac=False).residual.reshape(-1)
        down = model.evaluate(x - step, jac=False).residual.reshape(-1)
        np.testing.assert_allclose(
            J[:, p], (up - down) / (2 * h), atol=TOL["jacobian"], err_msg=name
        )


def test_analytic_and_finite_difference_calibrations_agree() -> None:
    syn = cal.synthetic_readings(60, seed=8)
    analytic = cal.calibrate(syn.readings)
    numeric = cal.calibrate(syn.readings, jacobian="3-point")
    np.testing.assert_allclose(
        [e.value for e in analytic.estimates],
        [e.value for e in numeric.estimates],
        atol=TOL["fd_method"],
    )
    assert analytic.method == "analytic"
    assert numeric.method == "3-point"


# ------------------------------------------------------------------------- recovery
@pytest.mark.parametrize("kind", ["quaternion", "axes"])
def test_known_perturbations_recovered_within_confidence_intervals(kind: str) -> None:
    """Over several seeds, every true value lies in its 99.9 % interval, the joint
    Mahalanobis distance passes the chi-square test, and its mean over the seeds is
    about the number of parameters (the covariance is neither too small nor too large:
    the mean of 6 chi-square(n) draws, divided by n, has a standard deviation of
    sqrt(2 / (6 n)) <= 0.24)."""
    distances = []
    for seed in SEEDS:
        syn = cal.synthetic_readings(100, seed=seed, kind=kind)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # good readings: no identifiability warning
            result = cal.calibrate(syn.readings, confidence=1 - MISS)
        assert result.ok, result.identifiability.warnings
        truth = truth_of(result, syn)
        values = np.array([e.value for e in result.estimates])
        low = np.array([e.low for e in result.estimates])
        high = np.array([e.high for e in result.estimates])
        assert np.all((low <= truth) & (truth <= high)), (seed, values - truth, high - values)
        error = values - truth
        distance = float(error @ np.linalg.solve(result.covariance, error))
        assert distance <= chi2.ppf(1 - JOINT_MISS, error.size), (seed, distance)
        distances.append(distance / error.size)
        # The calibrated design is the identified link angles on the nominal design.
        assert result.design.alpha1 == result.parameters.alpha1
        assert result.design.dimensions == spm.SPMDesign.prototype().dimensions
    assert 0.4 < float(np.mean(distances)) < 1.7, distances


def test_noise_free_readings_give_the_truth_exactly() -> None:
    fine = cal.JointConvention(ticks_per_turn=2**40)  # no visible encoder steps
    syn = cal.synthetic_readings(40, seed=2, noise_deg=0.0, joints=fine, offset_std_deg=20.0)
    result = cal.calibrate(syn.readings, parameters="offsets,links,mount,ref_x,ref_y")
    np.testing.assert_allclose(
        [e.value for e in result.estimates], truth_of(result, syn), atol=TOL["exact"]
    )
    np.testing.assert_allclose(result.error_deg, 0.0, atol=1e-6)


# ---------------------------------------------- truth independent of the generator
#: Known parameters of a simulated prototype, large and asymmetric enough that a sign
#: or side error in the measurement rule shows.
TRUTH = independent.Truth(
    offsets_deg=(2.5, -1.8, 3.1),
    alpha1_deg=45.4,
    alpha2_deg=89.7,
    beta_deg=90.3,
    mount_deg=(3.0, -2.0, 4.0),
    ref_deg=(2.0, -3.0, 0.0),
)
#: Encoder settings: one servo turning the other way, one geared 2:1, zero offsets
#: away from 0 counts.
ENCODERS = independent.Encoders(
    direction=(1, -1, 1), zero_offset=(2048.0, 2048.0, 1000.0), gear_ratio=(1.0, 2.0, 1.0)
)
#: The same without visible encoder steps.
FINE = dataclasses.replace(ENCODERS, ticks_per_turn=2**40)
#: Noise level of the noisy recovery test [deg per axis].
TRUTH_NOISE_DEG = 0.5


def truth_poses(count: int, seed: int = 1) -> np.ndarray:
    return independent.admissible_poses(count, TRUTH.design(spm.SPMDesign.prototype()), seed=seed)


def truth_readings(
    count: int,
    kind: str = "quaternion",
    *,
    encoders: independent.Encoders = ENCODERS,
    noise_deg: float = 0.0,
    convention: str = "documented",
) -> tuple[independent.Generated, cal.Readings]:
    """Independent readings of TRUTH, and the library's reading of their file."""
    generated = independent.generate(
        TRUTH,
        truth_poses(count),
        spm.SPMDesign.prototype(),
        kind=kind,
        encoders=encoders,
        noise_deg=noise_deg,
        seed=5,
        convention=convention,
    )
    return generated, cal.parse_readings(generated.text, source="independent.csv")


def truth_errors(result: cal.CalibrationResult) -> dict[str, float]:
    """|identified - true| per parameter [rad]; the mounting as one rotation angle."""
    found = result.parameters
    errors = {f"offset_{i + 1}": abs(float(found.offsets[i] - TRUTH.offsets[i])) for i in range(3)}
    for name, true_value in zip(("alpha1", "alpha2", "beta"), TRUTH.links, strict=True):
        errors[name] = abs(getattr(found, name) - float(true_value))
    if result.readings.kind == "quaternion":
        miss = independent.rotation_vector(found.mount.T @ TRUTH.mount)
        errors["mount"] = float(np.linalg.norm(miss))
    return errors


def truth_rms_deg(result: cal.CalibrationResult) -> float:
    return float(np.sqrt(np.mean(result.error_deg**2)))


def recovers_counts_truth(result: cal.CalibrationResult) -> tuple[bool, str]:
    """Whether a calibration of noise-free XM540 readings found TRUTH: every parameter
    within TOL["truth_counts_deg"] and an RMS error within TOL["truth_rms_counts_deg"]."""
    errors = {name: math.degrees(e) for name, e in truth_errors(result).items()}
    rms = truth_rms_deg(result)
    ok = max(errors.values()) <= TOL["truth_counts_deg"] and rms <= TOL["truth_rms_counts_deg"]
    rounded = {name: round(value, 4) for name, value in errors.items()}
    detail = f"errors [deg] {rounded}, rms {rms:.4f} deg"
    return ok, detail


@pytest.mark.parametrize("kind", ["quaternion", "axes"])
def test_independent_readings_match_the_library_generator(kind: str) -> None:
    """Readings made from the documented rule and by synthetic_readings agree, for the
    same parameters, poses and encoder settings (noise-free: the noise is drawn)."""
    design = spm.SPMDesign.prototype()
    generated, parsed = truth_readings(30, kind)
    # The parser reads the counts by the documented formula.
    np.testing.assert_allclose(
        parsed.theta, ENCODERS.reading_rad(generated.ticks), atol=TOL["generators_reading"]
    )
    np.testing.assert_allclose(
        parsed.orientation, generated.measured, atol=TOL["generators_sensor"]
    )
    truth = cal.CalibrationParameters(
        offsets=TRUTH.offsets,
        alpha1=float(TRUTH.links[0]),
        alpha2=float(TRUTH.links[1]),
        beta=float(TRUTH.links[2]),
        mount=TRUTH.mount,
        reference=TRUTH.reference,
    )
    joints = cal.JointConvention(
        direction=ENCODERS.direction,
        zero_offset_ticks=ENCODERS.zero_offset,
        gear_ratio=ENCODERS.gear_ratio,
    )
    # The servos stand where the model's inputs are theta: at theta + offset.
    commanded = generated.theta + TRUTH.offsets
    library = cal.synthetic_readings(
        commanded, design, truth=truth, noise_deg=0.0, kind=kind, joints=joints
    )
    np.testing.assert_allclose(library.theta, generated.theta, atol=TOL["generators_reading"])
    np.testing.assert_allclose(library.readings.theta, parsed.theta, atol=TOL["generators_reading"])
    np.testing.assert_allclose(
        library.readings.orientation, generated.measured, atol=TOL["generators_sensor"]
    )
    assert library.readings.kind == parsed.kind == kind
    assert library.readings.joints == parsed.joints == joints
    for name, value in zip(("alpha1", "alpha2", "beta"), TRUTH.links, strict=True):
        assert getattr(library.design, name) == pytest.approx(float(value), abs=1e-15)


@pytest.mark.parametrize("kind", ["quaternion", "axes"])
def test_calibration_recovers_the_independent_truth_exactly(kind: str) -> None:
    """Noise-free readings without visible encoder steps: every parameter, and the
    encoder zero in counts (the count at which servo i reads offset_i), exactly."""
    _, readings = truth_readings(40, kind, encoders=FINE)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # good readings: no identifiability warning
        result = cal.calibrate(readings, reference=TRUTH.reference)
    assert result.ok
    errors = truth_errors(result)
    assert max(errors.values()) <= TOL["truth_exact"], errors
    np.testing.assert_allclose(result.error_deg, 0.0, atol=1e-6)
    np.testing.assert_allclose(
        result.joints.zero_offset_ticks, FINE.counts(TRUTH.offsets), atol=TOL["truth_exact_counts"]
    )
    np.testing.assert_allclose(
        [result.design.alpha1, result.design.alpha2, result.design.beta],
        TRUTH.links,
        atol=TOL["truth_exact"],
    )


@pytest.mark.parametrize("kind", ["quaternion", "axes"])
def test_calibration_recovers_the_independent_truth_from_counts(kind: str) -> None:
    """Noise-free readings in whole XM540 counts (0.088 deg steps)."""
    _, readings = truth_readings(60, kind)
    result = calibrate_quietly(readings, reference=TRUTH.reference)
    assert result.ok
    ok, detail = recovers_counts_truth(result)
    assert ok, detail


@pytest.mark.parametrize("kind", ["quaternion", "axes"])
def test_calibration_recovers_the_independent_truth_from_noisy_readings(kind: str) -> None:
    """0.5 deg of sensor noise: each estimate within TOL["truth_z"] of its standard
    deviations from the truth, and the remaining error the size of the noise."""
    _, readings = truth_readings(100, kind, noise_deg=TRUTH_NOISE_DEG)
    result = calibrate_quietly(readings, reference=TRUTH.reference)
    assert result.ok
    true_values = {f"offset_{i + 1}": float(TRUTH.offsets[i]) for i in range(3)}
    true_values.update(zip(("alpha1", "alpha2", "beta"), map(float, TRUTH.links), strict=True))
    true_values.update(
        zip(("mount_x", "mount_y", "mount_z"), np.radians(TRUTH.mount_deg), strict=True)
    )
    for estimate in result.estimates:
        miss = abs(estimate.value - true_values[estimate.name])
        assert miss <= TOL["truth_z"] * estimate.std, (estimate.name, miss, estimate.std)
    # The RMS orientation error per reading that the noise alone leaves: sqrt(3) *
    # noise for a sensor rotation (the angle of 3 normal components); for axis readings
    # the largest of 3 axis errors, each a Rayleigh angle with mean square 2 noise^2,
    # so mean square 2 noise^2 (1 + 1/2 + 1/3).
    factor = math.sqrt(3.0) if kind == "quaternion" else math.sqrt(11.0 / 3.0)
    expected = factor * TRUTH_NOISE_DEG
    assert truth_rms_deg(result) <= TOL["truth_rms_noise"] * expected


WRONG = [
    ("quaternion", convention)
    for convention in independent.CONVENTIONS
    if convention != "documented"
] + [("axes", "offset_sign_flipped")]


@pytest.mark.parametrize(("kind", "convention"), WRONG)
def test_calibration_tells_a_wrong_measurement_rule_apart(kind: str, convention: str) -> None:
    """Readings made by a wrong rule (offset sign flipped, mounting on the other side
    or transposed, quaternion conjugated, reference on the other side) are not
    explained by the truth: calibration either finds other parameters or leaves a
    large error, by TOL["wrong_factor"] times the tolerance of the right rule."""
    _, readings = truth_readings(60, kind, convention=convention)
    result = calibrate_quietly(readings, reference=TRUTH.reference)
    errors = {name: math.degrees(e) for name, e in truth_errors(result).items()}
    rms = truth_rms_deg(result)
    ok, detail = recovers_counts_truth(result)
    assert not ok, detail
    assert (
        max(errors.values()) > TOL["wrong_factor"] * TOL["truth_counts_deg"]
        or rms > TOL["wrong_factor"] * TOL["truth_rms_counts_deg"]
    ), detail


def test_robust_loss_flags_and_survives_outliers() -> None:
    syn = cal.synthetic_readings(100, seed=4, outlier_fraction=0.1, outlier_deg=25.0)
    result = cal.calibrate(syn.readings, confidence=1 - MISS)
    assert result.ok
    np.testing.assert_array_equal(result.outliers, syn.outliers)
    truth = truth_of(result, syn)
    for entry, value in zip(result.estimates, truth, strict=True):
        assert entry.low <= value <= entry.high, entry
    assert np.all(result.weights[syn.outliers] < 0.5)
    assert any("lines" in m for m in result.messages)
    plain = cal.calibrate(syn.readings, loss="linear")
    assert plain.sigma_deg > result.sigma_deg


def test_encoder_conventions_and_offsets_in_ticks(tmp_path: Path) -> None:
    joints = cal.JointConvention(
        direction=(-1, 1, -1), zero_offset_ticks=(2048, 1000, 3000), gear_ratio=(2.0, 1.0, 1.0)
    )
    syn = cal.synthetic_readings(100, seed=6, joints=joints, unit="ticks")
    path = tmp_path / "r.csv"
    syn.readings.to_csv(path)
    readings = cal.load_readings(path)
    assert readings.servo_unit == "ticks"
    assert readings.joints == joints
    rows = [line.split(",") for line in path.read_text().splitlines() if line[0] != "#"]
    raw = np.array([[int(x) for x in row[1:4]] for row in rows[1:]])
    expected = (
        np.array([-1, 1, -1])
        * (raw - [2048, 1000, 3000])
        * 2
        * np.pi
        / (4096 * np.array([2.0, 1.0, 1.0]))
    )
    np.testing.assert_allclose(readings.theta, expected, atol=1e-12)
    result = cal.calibrate(readings)
    # The new zero counts read the model's zero: true offsets in counts.
    true_zero = np.array(joints.zero_offset_ticks) + syn.truth.offsets / joints.radians_per_tick
    std_ticks = np.array([result.estimate(f"offset_{i}").std for i in (1, 2, 3)]) / np.abs(
        joints.radians_per_tick
    )
    assert np.all(np.abs(np.array(result.joints.zero_offset_ticks) - true_zero) < 4 * std_ticks)
    np.testing.assert_allclose(result.zero_offsets, result.joints.zero_offset_ticks, atol=1e-12)
    # The offsets file holds [[joints]] tables in the servo configuration's keys.
    data = tomllib.loads(result.offsets_toml())
    assert set(data) == {"joints"}
    tables = data["joints"]
    assert [t["joint"] for t in tables] == ["u_1", "u_2", "u_3"]
    for i, table in enumerate(tables):
        assert set(table) == {"joint", "direction", "gear_ratio", "zero_offset"}
        assert table["direction"] == joints.direction[i]
        assert table["gear_ratio"] == joints.gear_ratio[i]
        assert table["zero_offset"] == round(result.joints.zero_offset_ticks[i])
    # Pasted into a servo configuration (with servo ids) they load as its joints.
    pasted = HardwareConfig.from_dict(
        {
            "joints": [{**t, "servo_id": i + 1} for i, t in enumerate(tables)],
            "servo": {"profile_velocity_deg_s": 200.0, "profile_acceleration_deg_s2": 2000.0},
        }
    )
    assert [j.zero_offset for j in pasted.joints] == [t["zero_offset"] for t in tables]
    assert [j.direction for j in pasted.joints] == list(joints.direction)
    encoder = result.as_dict()["encoder"]["joints"]
    assert [encoder[f"u_{i}"]["zero_offset"] for i in (1, 2, 3)] == [
        t["zero_offset"] for t in tables
    ]
    assert "zero_offset" in result.report()


# ------------------------------------------------------------ servo configuration
#: The servo configuration of a robot as it really is (ids, directions, a 2:1 gear,
#: zero offsets), and the one the readings were taken with: its zero offsets are off.
TRUE_ZERO = (1000, 3000, -200)
OLD_ZERO = (1000 - 45, 3000 + 27, -200 - 30)  # about 2 deg off


def servo_config(zero: tuple[int, int, int]) -> HardwareConfig:
    return HardwareConfig(
        port="/dev/ttyUSB1",
        baudrate=2_000_000,
        rate_hz=150.0,
        joints=(
            JointConfig("u_1", 11, direction=-1, gear_ratio=2.0, zero_offset=zero[0]),
            JointConfig("u_2", 12, direction=1, gear_ratio=1.0, zero_offset=zero[1]),
            JointConfig("u_3", 13, direction=-1, gear_ratio=1.0, zero_offset=zero[2]),
        ),
        servo=ServoSettings(profile_velocity=math.radians(200), profile_acceleration=40.0),
        safety=SafetyLimits(max_speed=math.radians(80), theta_min=(-2.0, -2.0, -2.0)),
    )


def readings_with_old_config(
    tmp_path: Path, count: int = 80, seed: int = 5
) -> tuple[Path, HardwareConfig]:
    """Readings of the robot taken with the old configuration, in pulses, in a file
    without settings (the configuration's apply)."""
    old = servo_config(OLD_ZERO)
    joints = cal.JointConvention.from_servo_config(old)
    # The model's zero sits at TRUE_ZERO pulses: reading - offset = model input.
    offsets = (np.array(TRUE_ZERO) - np.array(OLD_ZERO)) * joints.radians_per_tick
    drawn = cal.synthetic_readings(count, seed=seed, joints=joints).truth
    truth = dataclasses.replace(drawn, offsets=offsets)
    syn = cal.synthetic_readings(count, seed=seed, joints=joints, truth=truth)
    text = syn.readings.to_csv()
    path = tmp_path / "robot.csv"
    path.write_text("".join(line for line in text.splitlines(True) if " = " not in line))
    return path, old


def test_hardware_and_calibration_share_the_joint_convention() -> None:
    """theta = direction (pulses - zero_offset) 2 pi / 4096 / gear_ratio in both."""
    assert cal.TICKS_PER_TURN == PULSES_PER_TURN
    config = servo_config(OLD_ZERO)
    joints = cal.JointConvention.from_servo_config(config)
    assert joints == cal.JointConvention(
        direction=(-1, 1, -1), zero_offset_ticks=OLD_ZERO, gear_ratio=(2.0, 1.0, 1.0)
    )
    pulses = np.array([[1234, -5678, 40000], [0, 2048, -2048], list(OLD_ZERO)])
    hardware = JointMap(config.joints)
    for row in pulses:
        np.testing.assert_allclose(joints.ticks_to_angle(row), hardware.to_theta(row), atol=1e-12)
        goals = hardware.to_pulses(joints.ticks_to_angle(row))
        assert [goals[i] for i in config.ids] == row.tolist()
    with pytest.raises(spm.InputError, match="HardwareConfig"):
        cal.JointConvention.from_servo_config(joints)  # type: ignore[arg-type]


def test_servo_config_round_trip(tmp_path: Path) -> None:
    """Readings taken with perturbed zero offsets -> calibrate -> the updated
    configuration holds the true zero offsets, within the intervals."""
    path, old = readings_with_old_config(tmp_path)
    joints = cal.JointConvention.from_servo_config(old)
    readings = cal.load_readings(path, joints=joints)
    assert readings.joints == joints  # the file gives no settings: the configuration's
    result = cal.calibrate(readings, confidence=1 - MISS)
    assert result.ok
    new = result.servo_config(old)
    # Within the interval of each offset, widened by the rounding to whole pulses.
    for i, joint in enumerate(new.joints):
        estimate = result.estimate(f"offset_{i + 1}")
        ends = OLD_ZERO[i] + np.array([estimate.low, estimate.high]) / joints.radians_per_tick[i]
        assert ends.min() - 0.5 <= TRUE_ZERO[i] <= ends.max() + 0.5, (joint, ends)
        assert not ends.min() <= OLD_ZERO[i] <= ends.max()  # the old zero is rejected
        assert ends.min() - 0.5 <= joint.zero_offset <= ends.max() + 0.5
        assert joint.zero_offset == round(float(result.zero_offsets[i]))
    # Everything but the zero offsets is kept.
    kept = old.to_dict()
    changed = new.to_dict()
    for table in (*kept["joints"], *changed["joints"]):
        table.pop("zero_offset")
    assert changed == kept
    # The file loads back, and its joints turn the readings' pulses into the
    # calibrated input angles (to half a pulse, the rounding of the zero offsets).
    saved = new.save(tmp_path / "new.toml")
    loaded = HardwareConfig.load(saved)
    assert loaded.joints == new.joints and loaded.to_dict() == new.to_dict()
    from_file = result.servo_config(old.save(tmp_path / "old.toml"))
    assert from_file.to_dict() == new.to_dict()
    pulses = np.rint(joints.angle_to_ticks(readings.theta)).astype(int)
    before, after = JointMap(old.joints), JointMap(loaded.joints)
    half_pulse = 0.5 * 2 * math.pi / PULSES_PER_TURN / np.array([2.0, 1.0, 1.0])
    for k in range(len(readings)):
        np.testing.assert_allclose(before.to_theta(pulses[k]), readings.theta[k], atol=1e-12)
        calibrated = readings.theta[k] - result.parameters.offsets
        assert np.all(np.abs(after.to_theta(pulses[k]) - calibrated) <= half_pulse + 1e-12)


def test_servo_config_needs_the_readings_joints(tmp_path: Path) -> None:
    path, old = readings_with_old_config(tmp_path, count=30)
    plain = cal.calibrate(cal.load_readings(path))  # default convention: direction +1
    with pytest.raises(spm.InputError, match="joint u_1: the readings were converted with"):
        plain.servo_config(old)
    with pytest.raises(spm.InputError, match="HardwareConfig"):
        plain.servo_config({"port": "/dev/ttyUSB0"})  # type: ignore[arg-type]
    bad = tmp_path / "bad.toml"
    bad.write_text("[[joints]]\njoint = 'u_1'\n")
    with pytest.raises(spm.FileFormatError, match="needs 'joint' and 'servo_id'"):
        plain.servo_config(bad)


def test_readings_settings_use_the_servo_configuration_keys() -> None:
    joints = cal.JointConvention(direction=(1, -1, 1), zero_offset_ticks=(10, 20.5, -30))
    syn = cal.synthetic_readings(5, seed=2, joints=joints)
    text = syn.readings.to_csv()
    assert "# zero_offset = 10, 20.5, -30\n" in text
    assert "zero_offset_ticks" not in text
    assert cal.parse_readings(text).joints == joints
    # The older name is still read; both names are one setting.
    legacy = text.replace("# zero_offset =", "# zero_offset_ticks =")
    assert cal.parse_readings(legacy).joints == joints
    twice = text.replace("# gear_ratio", "# zero_offset_ticks = 0\n# gear_ratio")
    with pytest.raises(spm.FileFormatError, match="'zero_offset' given twice"):
        cal.parse_readings(twice)
    bad = text.replace("# zero_offset = 10, 20.5, -30", "# zero_offset = 1, nan, 3")
    with pytest.raises(spm.FileFormatError, match="setting zero_offset must be 3 finite"):
        cal.parse_readings(bad)
    # Settings the file does not give come from ``joints``; those it gives win.
    default = cal.JointConvention(direction=(-1, -1, -1), zero_offset_ticks=(1, 2, 3))
    partial = "".join(line for line in text.splitlines(True) if "# direction" not in line)
    merged = cal.parse_readings(partial, joints=default).joints
    assert merged == dataclasses.replace(joints, direction=(-1, -1, -1))
    # A default zero offset is a shaft angle: in the file's counts if they differ.
    rows = [line for line in text.splitlines(True) if not line.startswith("#")]
    finer = "".join(["# ticks_per_turn = 8192\n", *rows])
    assert cal.parse_readings(finer, joints=default).joints == dataclasses.replace(
        default, ticks_per_turn=8192, zero_offset_ticks=(2, 4, 6)
    )
    with pytest.raises(spm.InputError, match="joints must be a JointConvention"):
        cal.parse_readings(text, joints=servo_config(OLD_ZERO))  # type: ignore[arg-type]


def test_calibration_and_servo_config_without_the_sdk(tmp_path: Path) -> None:
    """The hardware extra (dynamixel-sdk) is not needed to calibrate or to update a
    servo configuration."""
    path, old = readings_with_old_config(tmp_path, count=30)
    old.save(tmp_path / "servos.toml")
    code = f"""
import sys
sys.modules["dynamixel_sdk"] = None  # import dynamixel_sdk now raises ImportError
from spm_pin import calibration as cal
from spm_pin.cli import main
assert main(["calibrate", {str(path)!r}, "--servo-config", {str(tmp_path / "servos.toml")!r},
             "--servo-out", {str(tmp_path / "new.toml")!r}, "--no-plot"]) == 0
assert "dynamixel_sdk" not in sys.modules or sys.modules["dynamixel_sdk"] is None
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert HardwareConfig.load(tmp_path / "new.toml").ids == (11, 12, 13)


# ------------------------------------------------------------------------ CSV format
@pytest.mark.parametrize("kind", ["quaternion", "axes"])
@pytest.mark.parametrize("unit", ["ticks", "deg", "rad"])
def test_readings_csv_round_trip(kind: str, unit: str) -> None:
    syn = cal.synthetic_readings(12, seed=1, kind=kind, unit=unit)
    text = syn.readings.to_csv(comments=["made by a test"])
    back = cal.parse_readings(text, source="mem.csv")
    assert back.kind == kind
    assert back.servo_unit == unit
    np.testing.assert_allclose(back.theta, syn.readings.theta, atol=TOL["csv"])
    np.testing.assert_allclose(back.orientation, syn.readings.orientation, atol=TOL["csv"])
    assert back.labels == syn.readings.labels
    assert back.lines is not None
    first_row = next(n for n, line in enumerate(text.splitlines(), 1) if line.startswith("1,"))
    assert back.lines.tolist() == list(range(first_row, first_row + 12))


def test_euler_columns_and_extra_columns() -> None:
    text = (
        "pose,servo1_deg,servo2_deg,servo3_deg,roll_deg,pitch_deg,yaw_deg,time_s,x_note\n"
        "a,10,20,30,5,-3,40,0.5,first\n"
        "b,0,0,0,0,0,0,1.0,second\n"
    )
    readings = cal.parse_readings(text)
    expected = Rotation.from_euler("xyz", [5, -3, 40], degrees=True).as_matrix()
    np.testing.assert_allclose(readings.orientation[0], expected, atol=1e-12)
    np.testing.assert_allclose(readings.theta[0], np.radians([10, 20, 30]))
    assert readings.labels == ("a", "b")
    assert readings.extra == {"time_s": ("0.5", "1.0"), "x_note": ("first", "second")}
    assert "x_note" in readings.to_csv()


GOOD = (
    "# readings\n"  # 1
    "# ticks_per_turn = 4096\n"  # 2
    "pose,servo1_deg,servo2_deg,servo3_deg,qw,qx,qy,qz\n"  # 3
    "1,0,0,0,1,0,0,0\n"  # 4
    "2,10,5,-3,0.9998477,0.0174524,0,0\n"  # 5
    "3,-20,5,7,0.9961947,0,0.0871557,0\n"  # 6
)


def _edit(old: str, new: str) -> str:
    assert old in GOOD
    return GOOD.replace(old, new, 1)


MALFORMED = {
    "missing servo column": (
        _edit("servo2_deg,", "").replace("1,0,0,0,1", "1,0,0,1"),
        3,
        "missing servo column(s) servo2_<unit>",
    ),
    "missing quaternion column": (_edit(",qz", ""), 3, "missing quaternion column(s) ['qz']"),
    "no orientation": (_edit(",qw,qx,qy,qz", ""), 3, "missing orientation columns"),
    "NaN": (_edit("2,10,5", "2,nan,5"), 5, "column servo1_deg: 'nan' is not allowed"),
    "infinite": (_edit("0.0871557", "inf"), 6, "column qy: 'inf' is not allowed"),
    "empty value": (_edit("2,10,5", "2,,5"), 5, "column servo1_deg: missing value"),
    "not a number": (_edit("3,-20", "3,-2O"), 6, "column servo1_deg: '-2O' is not a number"),
    "unknown unit": (_edit("servo1_deg", "servo1_grad"), 3, "unit 'grad' is not allowed"),
    "mixed units": (_edit("servo2_deg", "servo2_rad"), 3, "servo columns mix units"),
    "fractional ticks": (
        GOOD.replace("_deg", "_ticks").replace("2,10,5", "2,10.5,5"),
        5,
        "is not a whole number of encoder counts",
    ),
    "quaternion in degrees": (
        _edit("0.9961947,0,0.0871557,0", "0,0,10,0"),
        6,
        "the quaternion has norm 10",
    ),
    "unknown column": (
        _edit("qz\n", "qz,temp\n").replace("\n1,", "\n1,").replace(",0,0\n2", ",0,0,20\n2"),
        3,
        "unknown column 'temp'",
    ),
    "duplicate column": (_edit("servo3_deg", "servo1_deg"), 3, "appears twice"),
    "too many values": (_edit("1,0,0,0,1,0,0,0", "1,0,0,0,1,0,0,0,9"), 4, "9 values"),
    "unknown setting": (_edit("ticks_per_turn", "tick_per_turn"), 2, "unknown setting"),
    "bad direction": (_edit("# ticks_per_turn = 4096", "# direction = 1, 2, 1"), 2, "+1 or -1"),
    "no rows": (GOOD.split("1,0,0,0")[0], None, "no readings"),
    "two orientations": (
        _edit("qz\n", "qz,roll_deg,pitch_deg,yaw_deg\n"),
        3,
        "more than one orientation",
    ),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_files_report_the_line(case: str, tmp_path: Path) -> None:
    text, line, message = MALFORMED[case]
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(spm.FileFormatError, match=re.escape(message)) as info:
        cal.load_readings(path)
    error = info.value
    assert isinstance(error, ValueError)
    assert error.line == line
    assert error.path == str(path)
    assert message in str(error)
    if line is not None:
        assert str(error).startswith(f"{path}:{line}: ")


def test_good_file_and_missing_file(tmp_path: Path) -> None:
    readings = cal.parse_readings(GOOD)
    assert len(readings) == 3
    assert readings.lines is not None
    assert readings.lines.tolist() == [4, 5, 6]
    with pytest.raises(spm.FileFormatError, match="cannot read readings file"):
        cal.load_readings(tmp_path / "nope.csv")
    with pytest.raises(spm.FileFormatError, match="no header row"):
        cal.parse_readings("# only a comment\n")


# ------------------------------------------------------------------ identifiability
def test_too_few_readings_warn_and_give_no_false_answer() -> None:
    syn = cal.synthetic_readings(2, seed=3)
    with pytest.warns(cal.IdentifiabilityWarning, match="cannot identify"):
        result = cal.calibrate(syn.readings)
    assert not result.ok
    ident = result.identifiability
    assert ident.unidentified
    assert ident.redundancy <= 0
    for entry in result.estimates:
        assert math.isinf(entry.std)
        assert math.isinf(entry.high - entry.low)
        if not entry.identified:
            assert entry.value == entry.start
    assert "WARNING" in result.report()


def test_one_pose_repeated_cannot_identify_the_links() -> None:
    poses = np.tile(np.radians([10.0, -5.0, 3.0]), (40, 1))
    syn = cal.synthetic_readings(poses, seed=3)
    with pytest.warns(cal.IdentifiabilityWarning):
        result = cal.calibrate(syn.readings)
    assert not result.ok
    assert {"alpha1", "alpha2", "beta"} <= set(result.identifiability.unidentified)
    nominal = spm.SPMDesign.prototype()
    assert result.design.alpha1 == nominal.alpha1
    assert result.design.beta == nominal.beta


def test_pure_turns_about_the_axis_are_degenerate() -> None:
    turn = np.radians(np.linspace(-150.0, 150.0, 50))
    syn = cal.synthetic_readings(np.stack([turn, turn, turn], axis=1), seed=3)
    with pytest.warns(cal.IdentifiabilityWarning):
        result = cal.calibrate(syn.readings)
    assert not result.ok
    assert {"alpha1", "alpha2", "beta"} <= set(result.identifiability.unidentified)


def test_heading_of_the_sensor_and_common_offset_are_inseparable() -> None:
    """Coaxial SPM: a common offset turns the platform about the axis, as a turn of the
    sensor's reference frame does; the report names the combination."""
    syn = cal.synthetic_readings(80, seed=5)
    with pytest.warns(cal.IdentifiabilityWarning, match="ref_z"):
        result = cal.calibrate(syn.readings, parameters="offsets,links,mount,ref")
    ident = result.identifiability
    assert ident.unidentified == ("ref_z",)
    assert ident.combinations == ("ref_z ~ offset_1 + offset_2 + offset_3",)
    assert result.estimate("ref_z").value == 0.0
    # The differences of the offsets do not depend on that choice.
    truth = syn.truth.offsets
    found = result.parameters.offsets
    stds = [result.estimate(f"offset_{i}").std for i in (1, 2, 3)]
    assert abs((found[0] - found[1]) - (truth[0] - truth[1])) < 5 * max(stds)


def test_axis_readings_do_not_see_the_mounting() -> None:
    syn = cal.synthetic_readings(50, seed=2, kind="axes")
    with pytest.warns(cal.IdentifiabilityWarning, match="mount_x has no effect"):
        result = cal.calibrate(syn.readings, parameters="offsets,links,mount")
    assert set(result.identifiability.unidentified) == {"mount_x", "mount_y", "mount_z"}


def test_poor_conditioning_is_reported() -> None:
    rng = np.random.default_rng(0)
    poses = rng.uniform(-0.09, 0.09, size=(60, 3))  # +-5 deg around home only
    syn = cal.synthetic_readings(poses, seed=3)
    with pytest.warns(cal.IdentifiabilityWarning, match="inseparable"):
        result = cal.calibrate(syn.readings)
    assert result.identifiability.correlated
    assert result.identifiability.condition_number > 100


# ------------------------------------------------------------------------- planning
def test_plan_poses_is_admissible_and_informative(tmp_path: Path) -> None:
    design = spm.SPMDesign.prototype()
    plan = cal.plan_poses(15, design, candidates=600, seed=1, min_margin=0.3, min_gap_deg=50)
    assert plan.theta.shape == (15, 3)
    jac = spm.jacobian(plan.theta, design)
    assert np.all(jac.reachable)
    assert np.all(jac.singularity_margin >= 0.3)
    d12 = 120 + np.degrees(plan.theta[:, 0] - plan.theta[:, 1])
    d23 = 120 + np.degrees(plan.theta[:, 1] - plan.theta[:, 2])
    assert np.all(d12 >= 50) and np.all(d23 >= 50) and np.all(360 - d12 - d23 >= 50)
    assert plan.observability.index > plan.random_index
    assert plan.observability.identifiability.ok
    path = tmp_path / "poses.csv"
    plan.to_csv(path, joints=cal.JointConvention(zero_offset_ticks=(2048, 2048, 2048)))
    np.testing.assert_allclose(
        np.degrees(cal.load_poses(path)), plan.theta_deg, atol=TOL["poses_deg"]
    )
    header = next(line for line in path.read_text().splitlines() if not line.startswith("#"))
    assert header == "pose,theta1_deg,theta2_deg,theta3_deg,servo1_ticks,servo2_ticks,servo3_ticks"


def test_predicted_deviations_match_the_calibration() -> None:
    plan = cal.plan_poses(30, candidates=500, seed=2)
    predicted = plan.observability.predicted_std
    ratios = []
    for seed in range(3):
        syn = cal.synthetic_readings(plan.theta, seed=seed)
        result = cal.calibrate(syn.readings)
        ratios.append([e.std for e in result.estimates] / predicted)
    assert 0.6 < float(np.median(ratios)) < 1.6


def test_observability_of_degenerate_poses() -> None:
    turn = np.radians(np.linspace(-90.0, 90.0, 10))
    obs = cal.observability(np.stack([turn, turn, turn], axis=1))
    assert not obs.identifiability.ok
    assert obs.index == pytest.approx(0.0, abs=1e-6)
    assert np.all(np.isinf(obs.predicted_std[3:6]))


# ----------------------------------------------------------------------- bad inputs
def test_bad_arguments_name_what_is_allowed() -> None:
    syn = cal.synthetic_readings(10, seed=0)
    with pytest.raises(spm.InputError, match=r"unknown parameter 'alpha3'.*allowed"):
        cal.calibrate(syn.readings, parameters=["alpha3"])
    with pytest.raises(spm.InputError, match="loss must be one of"):
        cal.calibrate(syn.readings, loss="l2")
    with pytest.raises(spm.InputError, match="readings must be Readings"):
        cal.calibrate(np.zeros((3, 3)))  # type: ignore[arg-type]
    with pytest.raises(spm.InputError, match="confidence"):
        cal.calibrate(syn.readings, confidence=1.5)
    with pytest.raises(spm.InputError, match="direction"):
        cal.JointConvention(direction=(1, 0, 1))
    with pytest.raises(spm.InputError, match="poses must be a positive integer"):
        cal.synthetic_readings(0)
    with pytest.raises(spm.InputError, match="theta must have shape"):
        cal.Readings(theta=np.zeros((2, 2)), orientation=np.zeros((2, 3, 3)))
    with pytest.raises(spm.InputError, match="not a rotation"):
        cal.Readings(theta=np.zeros((1, 3)), orientation=np.ones((1, 3, 3)))
    with pytest.raises(spm.InputError, match="would not read back"):
        syn.readings.to_csv(comments=["ticks_per_turn = 12"])


def test_residual_plot_is_a_png(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    result = cal.calibrate(cal.synthetic_readings(30, seed=1, outlier_fraction=0.1).readings)
    path = result.plot_residuals(tmp_path / "res.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------------------ CLI
def test_cli_synth_calibrate_and_use_the_design(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    readings = tmp_path / "r.csv"
    assert main(["synth-readings", "80", "--out", str(readings), "--seed", "2", "--json"]) == 0
    synth = json.loads(capsys.readouterr().out)
    out = tmp_path / "cal.toml"
    assert main(["calibrate", str(readings), "--out", str(out), "--no-plot", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["ok"] is True
    assert set(record["files"]) == {"design", "report", "offsets"}
    design = spm.SPMDesign.load(out)
    by_name = {p["name"]: p for p in record["parameters"]}
    assert math.isclose(math.degrees(design.alpha1), by_name["alpha1"]["value_deg"])
    lo, hi = by_name["alpha1"]["ci_deg"]
    assert lo - 1.0 < synth["truth"]["alpha1_deg"] < hi + 1.0
    assert (tmp_path / "cal_report.txt").read_text().startswith("spm-pin calibration")
    offsets = tomllib.loads((tmp_path / "cal_offsets.toml").read_text())
    assert [t["joint"] for t in offsets["joints"]] == ["u_1", "u_2", "u_3"]
    assert not (tmp_path / "cal_servos.toml").exists()
    assert main(["fk", "60", "90", "120", "--design", str(out), "--json"]) == 0
    fk = json.loads(capsys.readouterr().out)
    assert fk["design"] == "prototype_calibrated"
    np.testing.assert_allclose(
        fk["R"], spm.forward_kinematics(np.radians([60, 90, 120]), design).R, atol=1e-12
    )


def test_cli_servo_config(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """spm calibrate --servo-config: the readings' ticks in the configuration's
    convention, and beside the design a copy of it with the identified zero offsets."""
    readings, old = readings_with_old_config(tmp_path)
    config = old.save(tmp_path / "servos.toml")
    out = tmp_path / "cal.toml"
    args = ["calibrate", str(readings), "--out", str(out), "--servo-config", str(config)]
    assert main([*args, "--no-plot", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["files"] == {
        "design": str(out),
        "report": str(tmp_path / "cal_report.txt"),
        "servos": str(tmp_path / "cal_servos.toml"),
    }
    assert not (tmp_path / "cal_offsets.toml").exists()
    written = HardwareConfig.load(tmp_path / "cal_servos.toml")
    joints = cal.JointConvention.from_servo_config(old)
    expected = cal.calibrate(cal.load_readings(readings, joints=joints)).servo_config(old)
    assert written.joints == expected.joints
    assert written.to_dict() == expected.to_dict()
    assert record["servo_config"] == {
        "from": str(config),
        "zero_offset_before": list(OLD_ZERO),
        "zero_offset": [j.zero_offset for j in written.joints],
    }
    # --servo-out names the file; without --out nothing else is written.
    elsewhere = tmp_path / "new" / "servos.toml"
    elsewhere.parent.mkdir()
    args = ["calibrate", str(readings), "--servo-config", str(config)]
    assert main([*args, "--servo-out", str(elsewhere)]) == 0
    text = capsys.readouterr().out
    assert f"servo configuration {config}: zero_offset {list(OLD_ZERO)} -> " in text
    assert f"wrote servos: {elsewhere}" in text
    assert HardwareConfig.load(elsewhere).joints == written.joints
    assert sorted(p.name for p in elsewhere.parent.iterdir()) == ["servos.toml"]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("port = 3\n", "port must be a string, got 3"),
        ("[[joints]]\njoint = 'u_1'\nservo_id = 1\nzero_offset = 1.5\n", "zero_offset must be"),
        ("[servo]\nprofile_velocity = 1\n", "[servo] has unknown key(s)"),
        ("joints = [", "not valid TOML"),
    ],
)
def test_cli_malformed_servo_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, message: str
) -> None:
    readings, _ = readings_with_old_config(tmp_path, count=30)
    config = tmp_path / "servos.toml"
    config.write_text(content)
    out = tmp_path / "cal.toml"
    assert main(["calibrate", str(readings), "--out", str(out), "--servo-config", str(config)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith(f"spm: error: {config}: ")
    assert message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robot.csv", "servos.toml"]


def test_cli_servo_config_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    readings, old = readings_with_old_config(tmp_path, count=30)
    config = old.save(tmp_path / "servos.toml")
    # Settings in the readings that contradict the configuration: exit 2, nothing written.
    header = tmp_path / "header.csv"
    header.write_text("# direction = 1, 1, 1\n" + readings.read_text())
    out = tmp_path / "cal.toml"
    assert main(["calibrate", str(header), "--out", str(out), "--servo-config", str(config)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("spm: error: joint u_1: the readings were converted with direction +1")
    assert not out.exists() and not (tmp_path / "cal_servos.toml").exists()
    assert main(["calibrate", str(readings), "--servo-config", str(tmp_path / "none.toml")]) == 2
    assert "cannot read servo configuration" in capsys.readouterr().err
    assert main(["calibrate", str(readings), "--servo-out", str(tmp_path / "x.toml")]) == 2
    assert "--servo-out needs --servo-config" in capsys.readouterr().err


def test_cli_malformed_file_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(MALFORMED["NaN"][0])
    assert main(["calibrate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith(f"spm: error: {path}:5: column servo1_deg")


def test_cli_unidentifiable_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    readings = tmp_path / "few.csv"
    assert main(["synth-readings", "2", "--out", str(readings)]) == 0
    capsys.readouterr()
    out = tmp_path / "cal.toml"
    assert main(["calibrate", str(readings), "--out", str(out)]) == EXIT_NOT_IDENTIFIED
    captured = capsys.readouterr()
    assert "spm: warning:" in captured.err and "--force" in captured.err
    assert not out.exists()
    assert not (tmp_path / "cal_report.txt").exists()
    assert main(["calibrate", str(readings), "--out", str(out), "--force", "--no-plot"]) == 0
    assert out.exists()


def test_cli_plan_poses_and_synth_at_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    poses = tmp_path / "poses.csv"
    assert main(["plan-poses", "12", "--out", str(poses), "--candidates", "300", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["poses"] == 12
    assert record["observability_index"] > record["random_poses_index"]
    np.testing.assert_allclose(
        np.degrees(cal.load_poses(poses)), record["theta_deg"], atol=TOL["poses_deg"]
    )
    readings = tmp_path / "r.csv"
    args = ["synth-readings", "--poses", str(poses), "--out", str(readings), "--unit", "deg"]
    assert main(args) == 0
    assert len(cal.load_readings(readings)) == 12
    assert main(["plan-poses", "0"]) == 2
    assert "N must be a positive number" in capsys.readouterr().err
