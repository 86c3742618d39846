"""Each script in examples/ runs as is and prints what it promises.

The scripts print their key results one ``name: value`` per line; the tests parse those
numbers and check them against what they compute themselves (from the design's public
data, by finite differences, from the files the scripts write), not only for exit 0.
"""

from __future__ import annotations

import functools
import importlib.metadata
import importlib.util
import json
import math
import re
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from _brute_force import brute_force_fk, rodrigues

import spm_pin as spm
from spm_pin import calibration as cal
from spm_pin.collision import check_input

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))

#: Tolerances of the checks (absolute, in the unit the name says).
TOL = {
    "printed_digits": 1e-9,  # numbers printed to 12 significant digits
    "closure": 1e-9,  # loop closures w_i . v_i = cos(alpha2), rigid platform
    "newton_residual": 1e-10,  # closed-loop solver residuals [rad]
    "rotation_match": 1e-9,  # closed-loop R against the analytic FK
    "round_trip_deg": 1e-6,  # IK of the FK back to the input [deg]
    "finite_difference": 1e-6,  # central differences against analytic velocities
    "ratio_4_digits": 1e-6,  # dexterity, margin printed to 6 decimals
    "torque_Nm": 1e-9,  # printed torques against a recomputation [N m]
    "holding_fd_Nm": 1e-6,  # holding torque against dU/dtheta by finite differences
    "servo_work_J": 1e-4,  # servo work against the potential energy gained [J]
    "sim_final_error_deg": 0.2,  # the simulated servos end at the goal [deg]
    "energy_balance_J": 1e-9,  # the simulation's energy bookkeeping [J]
    "servo_pulses": 2,  # emulated servos at the goal [pulses of 360/4096 deg]
    "hardware_error_deg": 0.2,  # ServoSync's final error [deg]
    "read_back_deg": 0.1,  # a printed input read back against its FK axis [deg]
    "calibration_std": 3.0,  # estimates within this many standard deviations
    "calibration_offset_deg": 1.0,  # encoder offsets recovered to this [deg]
    "calibration_printed_deg": 5e-5,  # 4 decimals
    "noise_estimate_rel": 0.1,  # identified noise against the generator's 0.5 deg
    "clearance_mm": 1e-3,  # min distance printed to 4 decimals [mm]
    "fraction": 1e-5,  # fractions printed to 6 significant digits
}

_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
_LINE = re.compile(r"^(\w+): (.*)$")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
STUDY_DEG = np.array([60.0, 90.0, 120.0])


@functools.cache
def run(name: str, *args: str) -> str:
    """Stdout of ``python examples/<name>.py *args``, which must exit 0."""
    result = subprocess.run(
        [sys.executable, str(ROOT / "examples" / f"{name}.py"), *args],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        cwd=ROOT,
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    return result.stdout


def parse(stdout: str) -> dict[str, str]:
    """The ``name: value`` lines of ``stdout`` (each name once), without ``  (comments)``."""
    matches = [m for m in map(_LINE.match, stdout.splitlines()) if m]
    lines = [(m[1], m[2].split("  (")[0]) for m in matches]
    names = [name for name, _ in lines]
    assert len(names) == len(set(names)), f"repeated names in {names}"
    return dict(lines)


def numbers(text: str) -> np.ndarray:
    """Every number in ``text``."""
    return np.array([float(x) for x in _NUMBER.findall(text)])


def fields(text: str) -> dict[str, str]:
    """``key value; key value`` into a dict."""
    return dict(part.strip().split(" ", 1) for part in text.split(";"))


def closure_error(theta: np.ndarray, v: np.ndarray, design: spm.SPMDesign) -> float:
    """Largest violation of w_i(theta_i) . v_i = cos(alpha2) and of the platform's shape."""
    w = np.array([rodrigues(design.u[i], theta[i], design.w0[i]) for i in range(3)])
    loops = np.einsum("ij,ij->i", w, v) - math.cos(design.alpha2)
    shape = v @ v.T - design.v0 @ design.v0.T
    return float(max(np.abs(loops).max(), np.abs(shape).max()))


def test_examples_exist() -> None:
    names = {p.stem for p in EXAMPLES}
    assert {"kinematics", "closed_loop", "workspace", "visualize", "dynamics"} <= names
    assert {"hardware_emulated", "calibration"} <= names
    assert "closed_loops_robots" in names


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs_and_prints_results(script: Path) -> None:
    source = script.read_text(encoding="utf-8")
    assert source.startswith('"""') and 'if __name__ == "__main__":' in source
    assert parse(run(script.stem)), "the example printed no name: value results"


def test_kinematics() -> None:
    out = parse(run("kinematics"))
    design = spm.SPMDesign.prototype()
    theta_deg = numbers(out["theta_deg"])
    np.testing.assert_array_equal(theta_deg, STUDY_DEG)
    theta = np.radians(theta_deg)
    assert out["design"].startswith(design.summary().split(":")[0])

    # The number of real assembly modes, against an independent brute-force search.
    count = int(out["modes"].split()[0])
    assert count == len(brute_force_fk(theta, design.u, design.w0, design.v0, design.alpha2))
    modes = [out[f"mode_{k}"].split() for k in range(1, count + 1)]
    assert [m[-1] == "home" for m in modes].count(True) == 1
    assert all(float(m[2]) < TOL["closure"] for m in modes)

    # The printed platform axes close the three loops on a rigid platform ...
    v = np.array([numbers(out[f"v_{i}"]) for i in (1, 2, 3)])
    assert closure_error(theta, v, design) < TOL["closure"]
    # ... are the home mode's, and the printed IK gives the input back.
    np.testing.assert_allclose(v, spm.forward_kinematics(theta, design).v, atol=TOL["closure"])
    np.testing.assert_allclose(numbers(out["ik_theta_deg"]), theta_deg, atol=TOL["round_trip_deg"])

    # Dexterity = 1 / condition number of a finite-difference Jacobian omega = J theta_dot.
    J = fd_jacobian(theta, design)
    s = np.linalg.svd(J, compute_uv=False)
    assert float(out["dexterity"]) == pytest.approx(s[-1] / s[0], abs=TOL["ratio_4_digits"])
    margin = float(spm.jacobian(theta, design).singularity_margin)
    assert float(out["singularity_margin"]) == pytest.approx(margin, abs=TOL["ratio_4_digits"])


def fd_jacobian(theta: np.ndarray, design: spm.SPMDesign | None = None) -> np.ndarray:
    """Columns: the platform's angular velocity (world) per unit input rate, by differences."""
    h = 1e-6
    columns = []
    for i in range(3):
        step = np.zeros(3)
        step[i] = h
        plus = spm.forward_kinematics(theta + step, design).R
        minus = spm.forward_kinematics(theta - step, design).R
        columns.append(pin.log3(plus @ minus.T) / (2 * h))
    return np.array(columns).T


def test_closed_loop() -> None:
    out = parse(run("closed_loop"))
    design = spm.SPMDesign.prototype()
    theta = np.radians(numbers(out["theta_deg"]))
    np.testing.assert_allclose(np.degrees(theta), STUDY_DEG, atol=TOL["printed_digits"])
    assert "mobility=3" in out["loop"]
    assert int(out["rank"]) == 6  # 9 joints, 3 degrees of freedom
    assert 0 < int(out["newton_steps"]) < 50
    assert float(out["residual"]) < TOL["newton_residual"]
    assert float(out["path_max_residual"]) < TOL["newton_residual"]
    assert int(out["path_samples"]) == 25
    assert float(out["trajectory_drift_rad"]) < TOL["newton_residual"]
    assert float(out["us_per_solve"]) > 0

    # The generic solver's platform rotation closes the loops (checked from the design).
    R = numbers(out["R_platform"]).reshape(3, 3)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=TOL["closure"])
    assert np.linalg.det(R) == pytest.approx(1.0, abs=TOL["closure"])
    assert closure_error(theta, (R @ design.v0.T).T, design) < TOL["closure"]
    assert float(out["R_error"]) < TOL["rotation_match"]

    # Its angular velocity, against central differences of the FK.
    theta_dot = numbers(out["theta_dot"])
    expected = fd_jacobian(theta) @ theta_dot
    np.testing.assert_allclose(numbers(out["omega"]), expected, atol=TOL["finite_difference"])
    np.testing.assert_allclose(
        numbers(out["omega_analytic"]), expected, atol=TOL["finite_difference"]
    )
    np.testing.assert_allclose(numbers(out["ik_theta_deg"]), STUDY_DEG, atol=TOL["round_trip_deg"])


def potential_energy(robot: spm.SPMRobot, theta: np.ndarray) -> float:
    """m g z of every body, upright (z up), at the home-mode assembly of ``theta``."""
    model = robot.model.copy()
    model.gravity = pin.Motion(np.array([0.0, 0.0, -9.81, 0.0, 0.0, 0.0]))
    return float(pin.computePotentialEnergy(model, model.createData(), robot.configuration(theta)))


def test_dynamics() -> None:
    out = parse(run("dynamics"))
    robot = spm.build_robot()
    goal = np.radians(numbers(out["goal_deg"]))
    np.testing.assert_allclose(np.degrees(goal), STUDY_DEG, atol=TOL["printed_digits"])
    assert float(out["duration_s"]) == 1.0

    # Holding torques: the gradient of the potential energy (virtual work), by differences.
    h = 1e-6
    gradient = [
        (potential_energy(robot, goal + h * e) - potential_energy(robot, goal - h * e)) / (2 * h)
        for e in np.eye(3)
    ]
    holding = numbers(out["holding_torque_Nm"])
    np.testing.assert_allclose(holding, gradient, atol=TOL["holding_fd_Nm"])

    # Peak torques: the library's inverse dynamics of the same motion.
    motion = spm.Trajectory.minimum_jerk(np.zeros(3), goal, duration=1.0, rate=1000.0)
    needed = spm.inverse_dynamics(spm.ClosedLoopDynamics(robot), motion)
    peak = numbers(out["peak_torque_Nm"])
    np.testing.assert_allclose(peak, np.abs(needed.torque).max(axis=0), atol=TOL["torque_Nm"])
    assert np.all(peak >= np.abs(holding) - TOL["torque_Nm"])  # the move ends holding
    assert out["servo_check"].startswith("OK")

    # The simulated servos reach the goal; their work is the potential energy gained.
    assert int(out["sim_steps"]) == 1500
    final = np.radians(numbers(out["final_theta_deg"]))
    error = np.degrees(np.abs(final - goal).max())
    assert float(out["final_error_deg"]) == pytest.approx(error, abs=1e-4)
    assert error < TOL["sim_final_error_deg"]
    gained = potential_energy(robot, final) - potential_energy(robot, np.zeros(3))
    assert float(out["servo_work_J"]) == pytest.approx(gained, abs=TOL["servo_work_J"])
    assert float(out["max_closure_residual_rad"]) < TOL["newton_residual"]
    assert float(out["energy_balance_error_J"]) < TOL["energy_balance_J"]
    assert float(out["servo_vs_inverse_dynamics_Nm"]) < 0.01 * peak.max()


def pulses_to_deg(pulses: np.ndarray) -> np.ndarray:
    """XM540 Present/Goal Position at the default zero_offset 2048, direction +1."""
    return (np.asarray(pulses) - 2048) * 360.0 / 4096


def test_hardware_emulated() -> None:
    out = parse(run("hardware_emulated"))
    design = spm.SPMDesign.prototype()
    assert int(out["baudrate"]) == 57600
    np.testing.assert_array_equal(numbers(out["start_theta_deg"]), 0.0)
    goal = numbers(out["goal_deg"])
    np.testing.assert_array_equal(goal, STUDY_DEG)
    assert out["reached"] == "True"
    assert float(out["final_error_deg"]) < TOL["hardware_error_deg"]

    # The servos themselves stand at the goal.
    present = numbers(out["present_position_pulses"])
    np.testing.assert_allclose(
        pulses_to_deg(present), goal, atol=TOL["servo_pulses"] * 360.0 / 4096
    )

    # Every platform axis read back closes loop 1 at the inputs read with it.
    samples = [fields(out[name]) for name in sorted(out) if name.startswith("sample_")]
    assert len(samples) >= 5
    for sample in samples:
        theta = np.radians(numbers(sample["theta_deg"]))
        v1 = numbers(sample["v_1"])
        w1 = rodrigues(design.u[0], theta[0], design.w0[0])
        assert np.linalg.norm(v1) == pytest.approx(1.0, abs=TOL["closure"])
        angle = math.degrees(math.acos(np.clip(w1 @ v1, -1, 1)))
        assert angle == pytest.approx(math.degrees(design.alpha2), abs=TOL["read_back_deg"])
        assert float(sample["R_vs_fk"]) < TOL["closure"]
    first, last = (numbers(samples[k]["theta_deg"]) for k in (0, -1))
    np.testing.assert_allclose(first, 0.0, atol=TOL["read_back_deg"])
    np.testing.assert_allclose(last, goal, atol=1.0)

    # The colliding goal is refused and never sent; torque is off at the end.
    np.testing.assert_array_equal(numbers(out["refused_goal_deg"]), [60.0, 90.0, 220.0])
    assert "unreachable" in out["refused_because"]
    assert out["torque_off"].split() == ["True"] * 3
    assert int(out["goals_sent_to_servo_3"]) > 0
    highest = pulses_to_deg(float(out["highest_goal_3_pulses"].split()[0]))
    assert highest <= goal[2] + TOL["servo_pulses"] * 360.0 / 4096


def test_calibration() -> None:
    stdout = run("calibration")
    out = parse(stdout)
    assert int(out["poses"]) == 40
    assert float(out["observability_index"]) > float(out["random_poses_index"])

    # The truth printed is the simulated prototype's (same seeds, recomputed here).
    plan = cal.plan_poses(40, candidates=1000, seed=1)
    truth = cal.synthetic_readings(plan.theta, seed=2).truth
    exact = np.degrees(truth.vector())  # relative to the nominal (identity) mounting
    estimated = [name for name in cal.PARAMETER_NAMES if name in out]
    assert {"offset_1", "offset_2", "offset_3", "alpha1", "alpha2", "beta"} <= set(estimated)
    for name in estimated:
        k = cal.PARAMETER_NAMES.index(name)
        row = fields(out[name].replace(" estimate", "; estimate").replace(" std", "; std"))
        value, estimate, std = (float(row[key]) for key in ("truth", "estimate", "std"))
        assert value == pytest.approx(exact[k], abs=TOL["calibration_printed_deg"]), name
        assert abs(estimate - value) <= TOL["calibration_std"] * std, name
        if name.startswith("offset_"):
            assert abs(estimate - value) < TOL["calibration_offset_deg"], name
            # The encoder zero offset the report proposes for this estimate.
            i = name[-1]
            ticks = re.search(rf"u_{i}: offset .*zero_offset (-?\d+) \((-?[\d.]+)\)", stdout)
            assert ticks is not None
            assert float(ticks[2]) == pytest.approx(estimate * 4096 / 360, abs=0.01)
            assert int(ticks[1]) == round(float(ticks[2]))
    assert float(out["worst_error_in_std"]) <= TOL["calibration_std"]

    # The fit explains the readings down to the generator's 0.5 deg sensor noise.
    rms = re.search(r"rms orientation error: ([\d.]+) deg before, ([\d.]+) deg after", stdout)
    noise = re.search(r"noise estimate ([\d.]+) deg per axis", stdout)
    assert rms is not None and noise is not None
    assert float(rms[2]) < float(rms[1])
    assert float(noise[1]) == pytest.approx(0.5, rel=TOL["noise_estimate_rel"])


def test_workspace(tmp_path: Path) -> None:
    out = parse(run("workspace", "--out", str(tmp_path)))
    robot = spm.build_robot()
    pairs = {}
    for k in (1, 2, 3):
        check = fields(out[f"check_{k}"])
        theta = np.radians(numbers(check["theta_deg"]))
        distance = float(check["min_distance_mm"])
        pairs[k] = check["colliding"].split()
        assert (pairs[k] == ["none"]) == (distance > 0)
        if check["home"] == "True":  # the robot's own clearance at the home-mode assembly
            clearance = robot.min_clearance(robot.configuration(theta)) * 1e3
            assert distance == pytest.approx(clearance, abs=TOL["clearance_mm"])
        report = check_input(theta, robot)
        assert check["mode"] == report.mode
    assert pairs[1] == pairs[2] == ["none"]
    assert len(pairs[3]) == 4 and all("_2" in p or "_3" in p for p in pairs[3])

    # The files it says it writes exist, are valid and agree with the printed summary.
    written = {name[6:]: Path(v.split(" (")[0]) for name, v in out.items() if "wrote_" in name}
    assert set(written) == {"npz", "csv", "summary", "gap_map", "orientation"}
    assert all(path.parent == tmp_path and path.is_file() for path in written.values())
    for name in ("gap_map", "orientation"):
        assert written[name].read_bytes()[:8] == PNG_MAGIC
    summary = json.loads(written["summary"].read_text())
    assert {"design", "step_deg", "settings", "summary"} <= set(summary)
    assert summary["step_deg"] == 6.0
    lines = written["csv"].read_text().splitlines()
    header, rows = lines[0].split(","), [line.split(",") for line in lines[1:]]
    column = {name: np.array([float(r[i] or "nan") for r in rows]) for i, name in enumerate(header)}
    data = np.load(written["npz"])
    np.testing.assert_array_equal(data["safe"], column["safe"])

    # Recomputed from the rows: every (d12, d23) pair on a 6 deg grid with d12 + d23 <= 360.
    points = int(out["points"])
    assert points == len(rows) == summary["summary"]["points"] == 61 * 62 // 2
    safe = column["safe"] == 1
    assert np.all(column["reachable"][safe] == 1)
    assert np.all(column["clearance"][safe] >= 0.0005) and np.all(column["dexterity"][safe] >= 0.2)
    fractions = {
        "reachable_fraction": column["reachable"].mean(),
        "safe_fraction": safe.mean(),
        "max_safe_tilt_deg": column["tilt_deg"][safe].max(),
    }
    for name, value in fractions.items():
        assert float(out[name]) == pytest.approx(value, rel=TOL["fraction"]), name
        assert summary["summary"][name] == pytest.approx(value, rel=TOL["fraction"]), name


def _browser() -> bool:
    from spm_pin.viz.browser import find_chromium

    return importlib.util.find_spec("playwright") is not None and find_chromium() is not None


def test_visualize(tmp_path: Path) -> None:
    pictures = tmp_path / "png"
    args = ["--out", str(tmp_path)] + (["--png", str(pictures)] if _browser() else [])
    out = parse(run("visualize", *args))

    # The colliding links: those the collision module finds at that input.
    theta = np.radians(numbers(out["colliding_theta_deg"]))
    np.testing.assert_allclose(np.degrees(theta), [60.0, 90.0, 220.0], atol=TOL["printed_digits"])
    report = check_input(theta, spm.build_robot())
    assert out["colliding_mode"] == report.mode
    assert out["colliding_links"].split() == ["-".join(pair) for pair in report.pairs]
    assert int(out["motion_samples"]) == 25
    assert out["motion_colliding_samples"] == "none"

    # Each page holds the robot's scene: every link's object, sent to the viewer.
    for name in ("home", "demo", "safe", "colliding", "motion"):
        path = Path(out[f"wrote_{name}"].split(" (")[0])
        assert path == tmp_path / f"{name}.html"
        page = path.read_text(encoding="utf-8")
        assert f"({path.stat().st_size} B)" in out[f"wrote_{name}"]
        assert page.startswith("<!DOCTYPE html>") and "meshcat-pane" in page
        scene = b"".join(map(_base64, re.findall(r'"([A-Za-z0-9+/=]{40,})"', page)))
        for link in ("proximal_1", "distal_2", "platform"):
            assert link.encode() in scene, (name, link)
    caption = (tmp_path / "colliding.html").read_text(encoding="utf-8")
    assert "proximal_2-proximal_3" in caption and "220" in caption
    assert "no collision" in (tmp_path / "demo.html").read_text(encoding="utf-8")
    assert "no collision" in (tmp_path / "safe.html").read_text(encoding="utf-8")

    if _browser():  # the documentation's pictures: PNGs of the stated size
        for name in ("home", "demo", "safe", "colliding"):
            picture = pictures / f"spm_{name}.png"
            assert out[f"wrote_{name}_png"].startswith(str(picture))
            head = picture.read_bytes()[:24]
            assert head[:8] == PNG_MAGIC and struct.unpack(">II", head[16:24]) == (960, 720)


def _base64(text: str) -> bytes:
    import base64

    return base64.b64decode(text)


def _robot_files() -> Path:
    """The robot files of example-robot-data."""
    folder = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    return Path(str(folder))


def _two_ur5() -> pin.Model:
    """Two UR5s, names prefixed a_ and b_, arm b turned to face arm a 1.2 m away."""
    urdf = str(_robot_files() / "ur_description" / "urdf" / "ur5_robot.urdf")
    arms = []
    for prefix in ("a_", "b_"):
        arm = pin.buildModelFromUrdf(urdf)
        for joint in range(1, arm.njoints):
            arm.names[joint] = prefix + arm.names[joint]
        for frame in arm.frames:
            frame.name = prefix + frame.name
        arms.append(arm)
    base_b = pin.SE3(pin.utils.rotate("z", np.pi), np.array([1.2, 0.0, 0.0]))
    return pin.appendModel(arms[0], arms[1], 0, base_b)


def test_closed_loops_robots() -> None:
    out = parse(run("closed_loops_robots"))
    tol = TOL["printed_digits"]

    # Two UR5s: 12 joints, one 6D weld of rank 6, six degrees of freedom.
    arms = _two_ur5()
    data = arms.createData()
    tool_a, tool_b = arms.getFrameId("a_tool0"), arms.getFrameId("b_tool0")
    assert int(out["ur5_mobility"]) == arms.nv - 6 == 6
    assert "rank 6" in out["ur5_loop"] and "mobility=6" in out["ur5_loop"]

    def relative(q: np.ndarray) -> pin.SE3:
        """Arm b's tool seen from arm a's, by plain forward kinematics."""
        pin.framesForwardKinematics(arms, data, q)
        return data.oMf[tool_a].actInv(data.oMf[tool_b])

    q_start = numbers(out["ur5_q_start"])
    bar = relative(q_start)
    for name in ("ur5_q", "ur5_path_end_q", "ur5_target_q"):  # the bar is still held
        held = relative(numbers(out[name]))
        assert np.abs(pin.log6(bar.actInv(held)).vector).max() < tol, name
    q = numbers(out["ur5_q"])
    np.testing.assert_allclose(q[:6], q_start[:6] + 0.1, atol=tol)
    np.testing.assert_allclose(numbers(out["ur5_actuated"]), q_start[:6] + 0.1, atol=tol)
    assert not np.allclose(q[6:], q_start[6:], atol=1e-3)  # arm b did move
    np.testing.assert_allclose(
        numbers(out["ur5_path_end_q"])[:6],
        q_start[:6] + np.array([0.4, 0.2, -0.3, 0.3, 0.2, 0.5]),
        atol=tol,
    )
    assert int(out["ur5_path_samples"]) == 40
    assert 0 < int(out["ur5_newton_steps"]) < 50
    for name in ("ur5_residual", "ur5_path_max_residual", "ur5_target_residual"):
        assert float(out[name]) <= 1e-12, name

    # The velocities keep both tools on one rigid bar: equal spatial velocities (world).
    rate, v = numbers(out["ur5_rate"]), numbers(out["ur5_v"])
    np.testing.assert_allclose(v[:6], rate, atol=tol)
    pin.forwardKinematics(arms, data, q, v)
    world = pin.ReferenceFrame.WORLD
    np.testing.assert_allclose(
        pin.getFrameVelocity(arms, data, tool_a, world).vector,
        pin.getFrameVelocity(arms, data, tool_b, world).vector,
        atol=TOL["finite_difference"],
    )
    J_b = numbers(out["ur5_J_b_tool"]).reshape(6, 6)
    np.testing.assert_allclose(
        J_b @ rate, pin.getFrameVelocity(arms, data, tool_b).vector, atol=TOL["finite_difference"]
    )

    # The bar carried: arm a's tool at the printed target, 5 cm up and turned 10 deg.
    target = numbers(out["ur5_target"]).reshape(4, 4)
    pin.framesForwardKinematics(arms, data, numbers(out["ur5_target_q"]))
    np.testing.assert_allclose(data.oMf[tool_a].homogeneous, target, atol=tol)
    pin.framesForwardKinematics(arms, data, q_start)
    start = data.oMf[tool_a]
    np.testing.assert_allclose(target[:3, 3] - start.translation, [0, 0, 0.05], atol=tol)
    turn = target[:3, :3] @ start.rotation.T
    np.testing.assert_allclose(turn, pin.utils.rotate("z", np.radians(10.0)), atol=tol)

    # Solo-12 on four point contacts: 18 velocities, 12 rows, six degrees of freedom.
    robots = _robot_files()
    solo = pin.buildModelFromUrdf(
        str(robots / "solo_description" / "robots" / "solo12.urdf"), pin.JointModelFreeFlyer()
    )
    solo_data = solo.createData()
    feet = [solo.getFrameId(f"{leg}_FOOT") for leg in ("FL", "FR", "HL", "HR")]
    body = solo.getFrameId("base_link")
    assert int(out["solo_mobility"]) == solo.nv - 12 == 6
    assert "(12 rows, rank 12)" in out["solo_loop"] and "mobility=6" in out["solo_loop"]
    assert out["solo_twelve_inputs"].startswith("refused")

    pin.framesForwardKinematics(solo, solo_data, numbers(out["solo_q_start"]))
    ground = np.array([solo_data.oMf[foot].translation for foot in feet])
    np.testing.assert_allclose(numbers(out["solo_ground"]).reshape(4, 3), ground, atol=tol)

    def feet_error(q: np.ndarray) -> float:
        pin.framesForwardKinematics(solo, solo_data, q)
        return float(
            max(
                np.linalg.norm(solo_data.oMf[f].translation - p)
                for f, p in zip(feet, ground, strict=True)
            )
        )

    # The body at the target pose, the feet where they stood.
    q = numbers(out["solo_q"])
    assert np.linalg.norm(q[3:7]) == pytest.approx(1.0, abs=tol)
    assert feet_error(q) < tol
    target = numbers(out["solo_target"]).reshape(4, 4)
    np.testing.assert_allclose(solo_data.oMf[body].homogeneous, target, atol=tol)
    expected = pin.SE3(
        pin.rpy.rpyToMatrix(np.radians([5.0, -4.0, 8.0])), np.array([0.02, -0.01, 0.205])
    )
    np.testing.assert_allclose(target, expected.homogeneous, atol=tol)
    assert float(out["solo_residual"]) <= 1e-12
    assert float(out["solo_other_coordinates_difference"]) <= TOL["newton_residual"]
    assert 0 < int(out["solo_iterations"]) < 50

    # The joint rates move the body with the twist and hold every foot still.
    v = numbers(out["solo_v"])
    pin.forwardKinematics(solo, solo_data, q, v)
    np.testing.assert_allclose(
        pin.getFrameVelocity(solo, solo_data, body).vector,
        numbers(out["solo_twist"]),
        atol=TOL["finite_difference"],
    )
    for foot in feet:
        still = pin.getFrameVelocity(solo, solo_data, foot, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(still.linear, 0.0, atol=TOL["finite_difference"])

    # The squat ends with the body level at 17 cm, the feet still on the ground.
    squat = numbers(out["solo_squat_q"])
    assert feet_error(squat) < tol
    level = pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.17])).homogeneous
    np.testing.assert_allclose(solo_data.oMf[body].homogeneous, level, atol=tol)
    steps = numbers(out["solo_squat_iterations"])
    assert len(steps) == 14 and steps.max() < 50
