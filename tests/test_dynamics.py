"""Constrained dynamics: forward/inverse round trips, statics against independent
computations, simulation (closure, energy), servos, trajectories, MuJoCo cross-checks,
``spm torques`` and bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import spm_pin as spm
from spm_pin import cli
from spm_pin import dynamics as D

ROOT = Path(__file__).resolve().parent.parent
MJCF = ROOT / "urdf" / "spm.xml"

#: Tolerances of this file (absolute unless named relative).
TOL = {
    "round_trip": 1e-9,  # theta_ddot back after inverse then forward [rad/s^2]
    "methods": 1e-12,  # pinocchio vs null-space forward dynamics, relative
    "statics": 1e-12,  # virtual work / body balances [N m]
    "potential_fd": 1e-8,  # holding torque vs finite differences of V [N m]
    "lambda": 1e-12,  # weld torques vs Pinocchio's multipliers [N m]
    # Closure residual of any simulated state [rad]: docs/dynamics.md, "a simulation
    # never carries more than 1e-10".
    "drift": 1e-10,
    # Closure residual after each step's projection [rad]: docs/dynamics.md, Newton steps
    # "until the weld residual is below 1e-12".
    "projection": 1e-12,
    "velocity": 1e-12,  # |J v| / |v| of simulated states
    "energy": 1e-6,  # frictionless 10 s energy drift / max kinetic energy (the target)
    "energy_balance": 1e-8,  # E - E0 - W + D over the kinetic energy scale, rk4
    "servo": 1e-12,  # fast servo law vs ServoModel.command [N m]
    "trajectory_fd": 1e-4,  # finite-difference speeds of a 1 kHz quintic [rad/s]
    # MuJoCo with stiff welds (solref 2e-4 s, solimp 0.999/0.9999), RK4 at 0.1 ms:
    "mj_theta": 1e-6,  # input angles [rad] (measured ~3e-8)
    "mj_speed": 1e-4,  # input speeds [rad/s] (measured ~2e-6)
    "mj_torque": 1e-4,  # servo torques of the driven motion [N m] (measured ~1e-6)
    "mj_inverse": 1e-3,  # our inverse dynamics of MuJoCo's motion vs its torques [N m]
}


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


@pytest.fixture(scope="module")
def upright(robot: spm.SPMRobot) -> D.ClosedLoopDynamics:
    return D.ClosedLoopDynamics(robot)


@pytest.fixture(scope="module")
def hanging(robot: spm.SPMRobot) -> D.ClosedLoopDynamics:
    """The robot mounted upside down: home is a stable equilibrium."""
    return D.ClosedLoopDynamics(robot, gravity=(0.0, 0.0, 9.81))


@pytest.fixture(scope="module")
def rich(robot: spm.SPMRobot) -> D.ClosedLoopDynamics:
    """Gravity sideways, friction everywhere, armature on the inputs."""
    friction = D.JointFriction(
        viscous=np.linspace(0.001, 0.009, 9), coulomb=0.002, smoothing_speed=0.5
    )
    return D.ClosedLoopDynamics(
        robot, gravity=(3.0, -2.0, -9.0), friction=friction, armature=[0.002, 0.003, 0.004]
    )


def random_states(n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return [
        (rng.uniform(-0.6, 0.6, 3), rng.normal(size=3) * 2.0, rng.normal(size=3) * 0.05)
        for _ in range(n)
    ]


# ------------------------------------------------------------ forward/inverse
@pytest.mark.parametrize("which", ["upright", "rich"])
def test_forward_methods_agree(which: str, request: pytest.FixtureRequest) -> None:
    dyn: D.ClosedLoopDynamics = request.getfixturevalue(which)
    for theta, theta_dot, torque in random_states(5, 1):
        pinocchio = dyn.forward(theta, theta_dot, torque)
        nullspace = dyn.forward(theta, theta_dot, torque, method="nullspace")
        scale = np.abs(nullspace.theta_ddot).max()
        np.testing.assert_allclose(
            pinocchio.theta_ddot, nullspace.theta_ddot, atol=TOL["methods"] * scale
        )
        np.testing.assert_allclose(
            pinocchio.constraint_torque, nullspace.constraint_torque, atol=TOL["lambda"]
        )
        # the accelerations keep the loops closed: J qdd + Jdot v = 0
        J = dyn.robot.constraint_jacobian(pinocchio.q)[dyn.constraint_rows]
        gamma = dyn._gamma(pinocchio.q, pinocchio.v)
        np.testing.assert_allclose(J @ pinocchio.ddq + gamma, 0.0, atol=1e-9 * scale)


def test_inverse_then_forward_round_trip(rich: D.ClosedLoopDynamics) -> None:
    for theta, theta_dot, _ in random_states(6, 2):
        theta_ddot = np.random.default_rng(3).normal(size=3) * 20.0
        inverse = rich.inverse(theta, theta_dot, theta_ddot)
        for method in ("pinocchio", "nullspace"):
            forward = rich.forward(theta, theta_dot, inverse.torque, method=method)
            np.testing.assert_allclose(forward.theta_ddot, theta_ddot, atol=TOL["round_trip"])
            np.testing.assert_allclose(
                forward.constraint_torque, inverse.constraint_torque, atol=TOL["lambda"]
            )


def test_inverse_dynamics_of_a_trajectory_round_trip(upright: D.ClosedLoopDynamics) -> None:
    motion = D.Trajectory.minimum_jerk([0.0, 0.0, 0.0], np.radians([40, 70, 100]), 0.8, 200)
    result = D.inverse_dynamics(upright, motion)
    assert result.torque.shape == (motion.time.shape[0], 3)
    assert result.constraint_torque.shape == (motion.time.shape[0], 2, 3)
    np.testing.assert_array_equal(result.time, motion.time)
    for k in range(0, motion.time.shape[0], 40):
        forward = upright.forward(result.q[k], motion.theta_dot[k], result.torque[k])
        np.testing.assert_allclose(forward.theta_ddot, motion.theta_ddot[k], atol=TOL["round_trip"])
    # at rest at both ends: the holding torques
    np.testing.assert_allclose(
        result.torque[0], upright.holding_torques(motion.theta[0]), atol=TOL["statics"]
    )
    np.testing.assert_allclose(result.power, result.torque * result.theta_dot)


def test_weld_torques_match_pinocchio_multipliers(upright: D.ClosedLoopDynamics) -> None:
    """Pinocchio's legacy welds (J1 - J2 sign, LOCAL frame of the leg end) give the
    torque the platform exerts on leg k: minus ours, after rotation to the world."""
    robot = upright.robot
    for theta, theta_dot, torque in random_states(3, 4):
        result = upright.forward(theta, theta_dot, torque)
        lam = np.array(upright._data.lambda_c).reshape(2, 6)
        for k, name in enumerate(("platform_leg2", "platform_leg3")):
            R = robot.placement(result.q, name).rotation
            np.testing.assert_allclose(R @ lam[k, 3:], -result.constraint_torque[k], atol=1e-12)
            np.testing.assert_allclose(lam[k, :3], 0.0, atol=1e-12)  # indeterminate: min norm


# ---------------------------------------------------------------------- statics
def _gravity_torques(
    robot: spm.SPMRobot, q: np.ndarray, gravity: np.ndarray
) -> dict[str, np.ndarray]:
    """c_b x (m_b g) about O for every moving body, from the link placements (world)."""
    placements = robot.placements(q)
    model = robot.model
    torques = {}
    for name in (*spm.model.LINK_NAMES[1:], "platform_leg2", "platform_leg3"):
        frame = robot.link_frames.get(name)
        if frame is None:
            frame = robot.end_frames[("platform", "platform_leg2", "platform_leg3").index(name)]
        inertia = model.inertias[model.frames[frame].parentJoint]
        com = placements[name].rotation @ inertia.lever
        torques[name] = np.cross(com, inertia.mass * gravity)
    return torques


@pytest.mark.parametrize("gravity", [(0.0, 0.0, -9.81), (0.0, 0.0, 9.81), (6.0, 4.0, -5.0)])
def test_holding_torques_by_virtual_work(robot: spm.SPMRobot, gravity: tuple[float, ...]) -> None:
    """tau = -sum_b J_b^T (c_b x m_b g), with the body Jacobians from the analytic
    kinematics (omega = A^-1 B theta_dot), not from Pinocchio."""
    design = robot.design
    dyn = D.ClosedLoopDynamics(robot, gravity=gravity)
    g = np.array(gravity)
    for theta in np.random.default_rng(5).uniform(-0.5, 0.5, size=(4, 3)):
        q = robot.configuration(theta)
        fk = spm.forward_kinematics(theta, design)
        J = spm.jacobian(theta, design, R=fk.R).J  # platform: omega = J theta_dot
        u = np.asarray(design.u)
        torques = _gravity_torques(robot, q, g)
        tau = np.zeros(3)
        for i in range(3):
            e = np.eye(3)[i]
            J_prox = np.outer(u[i], e)
            # leg i: omega_platform = u theta_i' + w_i psi_i' + v_i chi_i'
            rates = np.linalg.lstsq(np.column_stack([fk.w[i], fk.v[i]]), J - J_prox, rcond=None)[0]
            J_dist = J_prox + np.outer(fk.w[i], rates[0])
            tau -= J_prox.T @ torques[f"proximal_{i + 1}"]
            tau -= J_dist.T @ torques[f"distal_{i + 1}"]
        for name in ("platform", "platform_leg2", "platform_leg3"):
            tau -= J.T @ torques[name]
        np.testing.assert_allclose(dyn.holding_torques(theta), tau, atol=TOL["statics"])
        np.testing.assert_allclose(
            D.holding_torques(dyn, theta), tau, atol=TOL["statics"]
        )  # the function form


def test_holding_torques_are_the_potential_gradient(rich: D.ClosedLoopDynamics) -> None:
    """tau_i = dV/dtheta_i along the closed mechanism (central differences of Pinocchio's
    potential energy at the analytic configurations)."""
    robot, model = rich.robot, rich.model
    data = model.createData()

    def potential(theta: np.ndarray) -> float:
        return float(pin.computePotentialEnergy(model, data, robot.configuration(theta)))

    h = 1e-5
    for theta in np.random.default_rng(6).uniform(-0.5, 0.5, size=(3, 3)):
        gradient = np.array(
            [(potential(theta + h * e) - potential(theta - h * e)) / (2 * h) for e in np.eye(3)]
        )
        np.testing.assert_allclose(rich.holding_torques(theta), gradient, atol=TOL["potential_fd"])
        # friction does not act at rest: the inverse dynamics agrees
        inverse = rich.inverse(theta, np.zeros(3), np.zeros(3))
        np.testing.assert_allclose(inverse.torque, gradient, atol=TOL["potential_fd"])


def test_weld_torques_balance_every_body(robot: spm.SPMRobot) -> None:
    """Statics body by body, independent of the dynamics code: a passive joint carries
    no torque about its axis, an actuated one the servo torque. With G_b = c_b x m_b g
    and lambda_k the torque leg k exerts on the platform (k = 2, 3):
    leg k:  v_k.(lambda_k - G_E) = 0, w_k.(lambda_k - G_D - G_E) = 0,
            tau_k = u.(lambda_k - G_P - G_D - G_E);
    leg 1:  v_1.(G_E + lambda_2 + lambda_3) = 0, w_1.(G_D + G_E + ...) = 0,
            tau_1 = -u.(G_P + G_D + G_E + lambda_2 + lambda_3)."""
    g = np.array([2.0, -1.0, -9.81])
    dyn = D.ClosedLoopDynamics(robot, gravity=g)
    design = robot.design
    for theta in np.random.default_rng(7).uniform(-0.5, 0.5, size=(3, 3)):
        result = dyn.inverse(theta, np.zeros(3), np.zeros(3))
        q = result.q
        G = _gravity_torques(robot, q, g)
        placements = robot.placements(q)
        lam = {2: result.constraint_torque[0], 3: result.constraint_torque[1]}
        ends = {1: "platform", 2: "platform_leg2", 3: "platform_leg3"}
        for k in (1, 2, 3):
            w_axis = placements[f"distal_{k}"].rotation @ design.w0[k - 1]
            v_axis = placements[ends[k]].rotation @ design.v0[k - 1]
            u_axis = np.asarray(design.u[k - 1])
            G_E, G_D, G_P = G[ends[k]], G[f"distal_{k}"], G[f"proximal_{k}"]
            if k == 1:
                load = G_E + lam[2] + lam[3]
                checks = [v_axis @ load, w_axis @ (load + G_D)]
                tau = -u_axis @ (load + G_D + G_P)
            else:
                checks = [v_axis @ (lam[k] - G_E), w_axis @ (lam[k] - G_E - G_D)]
                tau = u_axis @ (lam[k] - G_E - G_D - G_P)
            np.testing.assert_allclose(checks, 0.0, atol=TOL["statics"])
            assert math.isclose(result.torque[k - 1], tau, abs_tol=TOL["statics"])


def test_reduced_mass_matrix_and_energy(rich: D.ClosedLoopDynamics) -> None:
    theta, theta_dot = np.array([0.2, -0.1, 0.3]), np.array([0.7, -1.1, 0.4])
    Mr = rich.mass_matrix(theta)
    np.testing.assert_allclose(Mr, Mr.T, atol=1e-15)
    assert np.linalg.eigvalsh(Mr).min() > 0
    kinetic, _ = rich.energy(theta, theta_dot)
    assert math.isclose(kinetic, 0.5 * theta_dot @ Mr @ theta_dot, rel_tol=1e-12)
    S = rich.velocity_map(theta)
    np.testing.assert_allclose(S[rich.actuated_idx], np.eye(3))
    J = rich.robot.constraint_jacobian(rich.configuration(theta))
    np.testing.assert_allclose(J @ S, 0.0, atol=1e-12)


# ------------------------------------------------------------------ simulation
def test_simulation_tolerances_are_no_looser_than_documented() -> None:
    """The library's projection target and drift bound keep docs/dynamics.md's figures:
    loosening either fails here instead of silently loosening the checks below."""
    assert TOL["projection"] >= D.CLOSURE_TOL
    assert TOL["drift"] >= D.DRIFT_TOL


def test_passive_fall_keeps_the_loops_closed(
    robot: spm.SPMRobot, upright: D.ClosedLoopDynamics
) -> None:
    """Upright, home is unstable: the robot falls through large motions. Every state of
    both integrators closes the loops (checked with the robot's own residual) and its
    velocities satisfy J v = 0."""
    for integrator in D.INTEGRATORS:
        sim = D.Simulator(upright, integrator=integrator, state=np.radians([2.0, -1.0, 0.5]))
        result = sim.run(0.8, record_every=20)
        assert result.steps == 800 and result.time[-1] == pytest.approx(0.8)
        assert np.ptp(result.theta, axis=0).max() > 0.5  # a large motion
        assert result.max_closure_residual <= TOL["drift"]
        assert result.closure_residual.max() <= TOL["drift"]
        for q in result.q:
            assert robot.closure_residual(q) <= TOL["drift"]
        np.testing.assert_allclose(result.theta, result.q[:, robot.actuated_q_idx])
        v = sim.v
        J = robot.constraint_jacobian(sim.q)
        assert np.abs(J @ v).max() <= TOL["velocity"] * np.abs(v).max()


def test_energy_is_conserved_over_10_s(hanging: D.ClosedLoopDynamics) -> None:
    """The project's target: a frictionless passive motion keeps its energy to 1e-6
    (relative to its largest kinetic energy) over 10 s at 1 kHz (rk4)."""
    sim = D.Simulator(hanging, dt=1e-3, integrator="rk4", state=np.radians([20.0, -10.0, 5.0]))
    result = sim.run(10.0, record_every=10)
    drift = np.abs(result.energy - result.energy[0]).max() / result.kinetic.max()
    assert result.kinetic.max() > 1e-3  # a real oscillation
    assert drift <= TOL["energy"], drift
    assert result.max_closure_residual <= TOL["drift"]
    np.testing.assert_array_equal(result.actuator_work, 0.0)


def test_energy_balance_with_servo_and_friction(rich: D.ClosedLoopDynamics) -> None:
    motion = D.Trajectory.minimum_jerk([0.0, 0.0, 0.0], np.radians([30, 50, 70]), 0.6)
    controller = D.ServoController(D.XM540_W150, motion)
    result = D.Simulator(rich, integrator="rk4").run(1.0, controller, record_every=5)
    scale = max(result.kinetic.max(), np.abs(result.actuator_work).max())
    assert np.abs(result.energy_error).max() <= TOL["energy_balance"] * max(scale, 1.0)
    assert result.friction_loss[-1] > 0 and np.all(np.diff(result.friction_loss) >= 0)
    assert result.max_closure_residual <= TOL["drift"]
    # the servo tracks the motion and stays in its envelope
    assert np.abs(result.theta[-1] - motion.theta[-1]).max() < np.radians(1.0)
    assert result.check_servo().within_limits


def test_inverse_dynamics_feedforward_makes_the_servos_track(
    upright: D.ClosedLoopDynamics,
) -> None:
    """The simulator and the inverse dynamics agree: with the inverse-dynamics torques
    as feedforward the PD loop has almost nothing left to correct."""
    motion = D.Trajectory.minimum_jerk([0.0, 0.0, 0.0], np.radians([60, 90, 120]), 1.0)
    feedforward = D.inverse_dynamics(upright, motion).torque
    errors = []
    for ff in (None, feedforward):
        controller = D.ServoController(D.XM540_W150, motion, ff)
        result = D.Simulator(upright).run(1.0, controller, record_every=10)
        errors.append(np.abs(result.theta - motion.theta[::10]).max())
    assert errors[0] > 1e-3 > 1e-5 > errors[1]  # measured 1.7e-3 and 2.6e-6 rad


def test_euler_converges_to_rk4(upright: D.ClosedLoopDynamics) -> None:
    motion = D.Trajectory.minimum_jerk([0.0, 0.0, 0.0], np.radians([20, 30, 40]), 0.3)
    controller = D.ServoController(D.XM540_W150, motion)
    reference = D.Simulator(upright, dt=1e-3).run(0.3, controller, record_every=300)
    errors = []
    for dt in (1e-3, 5e-4):
        sim = D.Simulator(upright, dt=dt, integrator="euler")
        result = sim.run(0.3, controller, record_every=round(0.3 / dt))
        assert result.max_closure_residual <= TOL["drift"]
        errors.append(np.abs(result.theta[-1] - reference.theta[-1]).max())
    assert errors[1] < 0.75 * errors[0] and errors[0] < 1e-3


def test_step_and_state_accessors(upright: D.ClosedLoopDynamics) -> None:
    sim = D.Simulator(upright, state=[0.1, 0.0, -0.1], theta_dot=[0.2, 0.0, 0.0])
    theta_ddot = sim.step([0.01, 0.0, 0.0])
    forward = upright.forward([0.1, 0.0, -0.1], [0.2, 0.0, 0.0], [0.01, 0.0, 0.0])
    np.testing.assert_allclose(theta_ddot, forward.theta_ddot, atol=1e-9)
    assert sim.steps == 1 and sim.time == pytest.approx(1e-3)
    assert sim.closure_residual <= TOL["drift"]
    kinetic, potential = sim.energy()
    assert kinetic > 0 and math.isfinite(potential)
    sim.reset(sim.q, time=2.0)
    assert sim.time == 2.0 and sim.steps == 0 and np.all(sim.theta_dot == 0)
    assert "Simulator(" in repr(sim) and "ClosedLoopDynamics(" in repr(upright)


def test_constant_torque_and_callable_controllers_agree(upright: D.ClosedLoopDynamics) -> None:
    torque = np.array([0.01, -0.02, 0.005])
    a = D.Simulator(upright, integrator="euler").run(0.05, torque, record_every=50)
    b = D.Simulator(upright, integrator="euler").run(
        0.05, lambda t, theta, theta_dot: torque.copy(), record_every=50
    )
    np.testing.assert_allclose(a.theta, b.theta, atol=0.0)
    np.testing.assert_allclose(a.torque, torque[None].repeat(a.time.shape[0], axis=0))


def test_a_fall_into_a_singularity_is_reported(upright: D.ClosedLoopDynamics) -> None:
    """This fall reaches a parallel singularity at t = 0.467 s: input angles cannot
    describe the motion past it, and the simulator says so (not a silent NaN)."""
    sim = D.Simulator(upright, integrator="euler", state=np.radians([4.708, -7.914, -15.78]))
    with pytest.raises(spm.SingularityError, match="type II") as info:
        sim.run(0.6)
    assert 0.4 < sim.time < 0.5 and info.value.kind == "type II"
    assert sim.max_closure_residual <= TOL["drift"]  # every accepted state closed


def test_a_time_step_too_large_is_refused(upright: D.ClosedLoopDynamics) -> None:
    sim = D.Simulator(upright, integrator="rk4", dt=0.02, state=np.radians([2.0, -1.0, 0.5]))
    with pytest.raises(spm.ConvergenceError, match="smaller time step"):
        sim.run(1.0)


def test_generic_solver_takes_over_from_the_lean_newton(
    upright: D.ClosedLoopDynamics, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With no lean Newton steps allowed every projection goes to ClosedLoop.project;
    the motion is the same."""
    start = np.radians([5.0, -3.0, 2.0])
    reference = {
        k: D.Simulator(upright, integrator=k, state=start).run(0.05) for k in D.INTEGRATORS
    }
    monkeypatch.setattr(D._kernel, "NEWTON_MAX_ITERATIONS", 0)
    for integrator, expected in reference.items():
        result = D.Simulator(upright, integrator=integrator, state=start).run(0.05)
        np.testing.assert_allclose(result.theta, expected.theta, atol=1e-11)
        assert result.max_closure_residual <= TOL["projection"]


def test_singularity_is_reported(
    upright: D.ClosedLoopDynamics, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every configuration counts as singular when the threshold is above 1."""
    for module in (D.closed_loop, D._kernel, D.simulator):  # every module that reads it
        monkeypatch.setattr(module, "SINGULAR_RCOND", 2.0)
    with pytest.raises(spm.SingularityError, match="type II"):
        D.Simulator(upright)
    match = r"parallel \(type II\) singularity: .*at theta = \[0\.0, 0\.0, 0\.0\] deg"
    with pytest.raises(spm.SingularityError, match=match):
        upright.forward(np.zeros(3), np.zeros(3))


# ----------------------------------------------------------------------- servos
def test_servo_envelope() -> None:
    servo = D.XM540_W150
    assert servo.stall_torque == 7.3 and math.isclose(servo.no_load_rpm, 53.0)
    lower, upper = servo.torque_limits([0.0, servo.no_load_speed, -servo.no_load_speed])
    np.testing.assert_allclose(upper, [7.3, 0.0, 7.3])
    np.testing.assert_allclose(lower, [-7.3, -7.3, 0.0])
    lower, upper = servo.torque_limits(0.5 * servo.no_load_speed)
    assert math.isclose(upper, 3.65) and math.isclose(lower, -7.3)
    # utilisation <= 1 exactly inside the envelope
    rng = np.random.default_rng(8)
    tau, omega = rng.uniform(-10, 10, 20_000), rng.uniform(-15, 15, 20_000)
    lower, upper = servo.torque_limits(omega)
    inside = (tau >= lower) & (tau <= upper)
    np.testing.assert_array_equal(servo.utilisation(tau, omega) <= 1.0, inside)
    np.testing.assert_array_equal(servo.saturate(tau, omega), np.clip(tau, lower, upper))


def test_servo_controller_is_the_servo_law() -> None:
    motion = D.Trajectory.minimum_jerk([0.0, 0.0, 0.0], np.radians([60, 90, 120]), 1.0)
    feedforward = np.random.default_rng(9).normal(size=(motion.time.shape[0], 3))
    servo = D.XM540_W150.with_gains(200.0, 3.0)
    cases = [
        D.ServoController(D.XM540_W150, motion),
        D.ServoController(servo, motion, feedforward),
        D.ServoController(servo, [0.1, 0.2, 0.3], [0.01, 0.0, 0.0]),
    ]
    rng = np.random.default_rng(10)
    for controller in cases:
        for _ in range(200):
            t = rng.uniform(-0.1, 1.1)
            theta, theta_dot = rng.normal(size=3), rng.normal(size=3) * 5
            if isinstance(controller.goal, D.Trajectory):
                goal, speed = motion.sample(t)
                ff = controller.feedforward
                if ff is not None:
                    ff = np.array([np.interp(t, motion.time, ff[:, i]) for i in range(3)])
            else:
                goal, speed, ff = controller.goal, None, controller.feedforward
            expected = controller.servo.command(theta, theta_dot, goal, speed, ff)
            np.testing.assert_allclose(controller(t, theta, theta_dot), expected, atol=TOL["servo"])


def test_check_servo_verdicts() -> None:
    ok = D.check_servo([[0.1, 0.0, -0.2]], [[0.0, 0.0, 0.0]], time=[0.5])
    assert ok.within_limits and ok.message.startswith("OK")
    assert ok.worst_joint == 2 and "t = 0.500 s" in ok.message
    assert math.isclose(ok.max_utilisation, 0.2 / 7.3)
    # the load counts the duty a speed needs: 0.1 N m at 1 rad/s > 0.2 N m at rest
    assert D.check_servo([[0.1, 0.0, -0.2]], [[1.0, 0.0, 0.0]]).worst_joint == 0
    bad = D.check_servo([[0.0, 8.0, 0.0], [0.0, 0.0, 0.0]], [[0.0, 0.0, 0.0], [7.0, 0, 0]])
    assert not bad.within_limits and bad.message.startswith("EXCEEDS")
    assert (bad.worst_sample, bad.worst_joint) == (1, 0)  # 7 rad/s > 53 rpm beats 8 N m
    np.testing.assert_allclose(bad.peak_torque, [0.0, 8.0, 0.0])
    # what sets the peak load is named: torque at rest, speed for the fast sample
    assert ok.limit == "torque" and "set by torque" in ok.message
    assert bad.limit == "speed" and "limited by speed" in bad.message


def test_torque_figure_one_unit_system_and_full_envelope() -> None:
    """The torque plot speaks rpm on its axis as in its title and legend, draws the
    whole torque-speed envelope of the servo, and names what sets the peak load."""
    pytest.importorskip("matplotlib")
    from matplotlib.patches import Polygon

    from spm_pin.dynamics.plots import torque_figure

    motion = D.Trajectory.minimum_jerk(np.zeros(3), np.radians([60.0, 90.0, 120.0]), 1.0, 100.0)
    result = D.inverse_dynamics(None, motion)
    check = D.check_servo(result.torque, result.theta_dot, time=motion.time)
    assert check.limit == "speed"  # 37.5 of 53 rpm, a few thousandths of the stall torque
    figure = torque_figure(result)
    left, right = figure.axes[:2]
    assert right.get_xlabel() == "speed [rpm]" and left.get_xlabel() == "time [s]"
    texts = [figure.get_suptitle()]
    for axis in (left, right):
        texts += [axis.get_title(), axis.get_xlabel(), axis.get_ylabel()]
        texts += [text.get_text() for text in axis.get_legend().get_texts()]
    assert all("rad/s" not in text for text in texts), texts
    assert "rpm" in figure.get_suptitle()  # the default title is the verdict, in rpm
    servo = D.XM540_W150
    (envelope,) = [p for p in right.patches if isinstance(p, Polygon)]
    corners = envelope.get_xy()
    np.testing.assert_allclose(corners[:, 0].max(), 2.0 * servo.no_load_rpm)
    np.testing.assert_allclose(corners[:, 0].min(), -2.0 * servo.no_load_rpm)
    np.testing.assert_allclose(np.abs(corners[:, 1]).max(), servo.stall_torque)
    lo, hi = right.get_ylim()
    assert lo < -servo.stall_torque and hi > servo.stall_torque  # all of it in view
    legend = [text.get_text() for text in right.get_legend().get_texts()]
    assert any("peak load 70.5%" in text and "set by speed" in text for text in legend)
    # every legend entry stands for something drawn
    for handle, label in zip(*right.get_legend_handles_labels(), strict=True):
        if hasattr(handle, "get_xdata"):
            assert np.isfinite(np.atleast_1d(handle.get_xdata())).any(), label


# ------------------------------------------------------------------ trajectory
def test_minimum_jerk_and_finite_differences(tmp_path: Path) -> None:
    start, goal = np.array([0.1, -0.2, 0.3]), np.array([1.0, 0.5, -0.4])
    motion = D.Trajectory.minimum_jerk(start, goal, 2.0, 1000)
    np.testing.assert_allclose(motion.theta[[0, -1]], [start, goal], atol=1e-15)
    np.testing.assert_allclose(motion.theta_dot[[0, -1]], 0.0, atol=1e-15)
    np.testing.assert_allclose(motion.theta_ddot[[0, -1]], 0.0, atol=1e-12)
    # peak speed of a quintic: 15/8 * span / T at the middle
    np.testing.assert_allclose(motion.theta_dot[1000], 1.875 * (goal - start) / 2.0)
    sampled = D.Trajectory.from_samples(motion.time, motion.theta)
    np.testing.assert_allclose(sampled.theta_dot, motion.theta_dot, atol=TOL["trajectory_fd"])
    file = motion.save(tmp_path / "motion.csv")
    loaded = D.Trajectory.load(file)
    np.testing.assert_allclose(loaded.theta, motion.theta, atol=1e-12)
    np.testing.assert_allclose(loaded.time, motion.time, atol=0.0)
    radians = D.Trajectory.load(motion.save(tmp_path / "rad.csv", degrees=False))
    np.testing.assert_allclose(radians.theta, motion.theta, atol=0.0)
    _, speed = motion.sample(1.0)
    np.testing.assert_allclose(speed, motion.theta_dot[1000])
    np.testing.assert_array_equal(motion.sample(5.0)[0], goal)


_HEADER = r"the header must be 'time_s,theta_1_deg,theta_2_deg,theta_3_deg' \(or _rad\)"
_FOUR_NUMBERS = r"expected 4 finite numbers \(time, three angles\)"


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("", None, "the trajectory file is empty"),
        ("t,a,b,c\n0,0,0,0\n", 1, _HEADER),
        ("time_s,theta_1_deg,theta_2_deg,theta_3_rad\n", 1, _HEADER),
        ("time_s,theta_1_deg,theta_2_deg,theta_3_deg\n0,0,0,0\n0.1,1,x,0\n", 3, _FOUR_NUMBERS),
        (
            "time_s,theta_1_deg,theta_2_deg,theta_3_deg\n0,0,0,0\n0,1,1,0\n",
            3,
            "times must increase: 0 s after 0 s",
        ),
        ("time_s,theta_1_deg,theta_2_deg,theta_3_deg\n0,0,0,0\n0.1,1,nan,0\n", 3, _FOUR_NUMBERS),
        (
            "time_s,theta_1_deg,theta_2_deg,theta_3_deg\n0,0,0,0\n0.1,1,1,1\n",
            None,
            "a trajectory needs at least 3 samples, got 2",
        ),
    ],
)
def test_bad_trajectory_files(tmp_path: Path, text: str, line: int | None, message: str) -> None:
    file = tmp_path / "bad.csv"
    file.write_text(text)
    with pytest.raises(spm.FileFormatError, match=rf"bad\.csv(:{line})?: {message}") as info:
        D.Trajectory.load(file)
    assert info.value.line == line
    with pytest.raises(spm.FileFormatError, match=r"missing\.csv: cannot read the trajectory"):
        D.Trajectory.load(tmp_path / "missing.csv")


# ---------------------------------------------------------------------- MuJoCo
@pytest.fixture(scope="module")
def mujoco_available() -> None:
    pytest.importorskip("mujoco")


def test_mujoco_passive_motion_hanging(
    mujoco_available: None, hanging: D.ClosedLoopDynamics
) -> None:
    """Mounted upside down the passive motion is a stable oscillation: MuJoCo (stiff
    welds, RK4 at 0.1 ms) and ours (rk4, 1 ms) agree over 3 s."""
    theta0 = np.radians([20.0, -10.0, 5.0])
    ours = D.Simulator(hanging, state=theta0).run(3.0, record_every=10)
    theirs = D.simulate_mujoco(MJCF, hanging, 3.0, state=theta0, record_every=10)
    assert np.ptp(ours.theta, axis=0).max() > np.radians(20)  # a large swing
    np.testing.assert_allclose(theirs.time, ours.time)
    np.testing.assert_allclose(theirs.theta, ours.theta, atol=TOL["mj_theta"])
    np.testing.assert_allclose(theirs.theta_dot, ours.theta_dot, atol=TOL["mj_speed"])
    # MuJoCo's soft welds open slightly; ours stay closed
    assert 1e-12 < theirs.max_closure_residual < 1e-6
    assert ours.max_closure_residual <= TOL["drift"]


def test_mujoco_passive_fall_upright(mujoco_available: None, upright: D.ClosedLoopDynamics) -> None:
    """Upright, home is unstable: differences grow exponentially, so the comparison
    covers the first 0.5 s of the fall (a 30 degree swing)."""
    theta0 = np.radians([2.0, -1.0, 0.5])
    ours = D.Simulator(upright, state=theta0).run(0.5, record_every=10)
    theirs = D.simulate_mujoco(MJCF, upright, 0.5, state=theta0, record_every=10)
    assert np.ptp(ours.theta, axis=0).max() > np.radians(20)
    np.testing.assert_allclose(theirs.theta, ours.theta, atol=TOL["mj_theta"])


def test_mujoco_driven_motion(mujoco_available: None, upright: D.ClosedLoopDynamics) -> None:
    """The same servos (PD + torque-speed envelope, 1 kHz zero-order hold) drive both
    simulators along a minimum-jerk move; trajectories and torques agree over 3 s, and
    our inverse dynamics of MuJoCo's motion reproduces MuJoCo's torques."""
    motion = D.Trajectory.minimum_jerk([0.0, 0.0, 0.0], np.radians([60, 90, 120]), 1.5)
    controller = D.ServoController(D.XM540_W150, motion)
    ours = D.Simulator(upright).run(3.0, controller, record_every=10)
    theirs = D.simulate_mujoco(MJCF, upright, 3.0, controller, record_every=10)
    np.testing.assert_allclose(theirs.theta, ours.theta, atol=TOL["mj_theta"])
    np.testing.assert_allclose(theirs.torque, ours.torque, atol=TOL["mj_torque"])
    assert np.abs(ours.torque).max() > 0.01
    inverse = D.inverse_dynamics(upright, theirs.theta, theirs.theta_dot, theirs.theta_ddot)
    np.testing.assert_allclose(inverse.torque, theirs.torque, atol=TOL["mj_inverse"])
    exact = D.inverse_dynamics(upright, ours.theta, ours.theta_dot, ours.theta_ddot)
    np.testing.assert_allclose(exact.torque, ours.torque, atol=1e-12)


def test_mujoco_rejects_another_robot(mujoco_available: None, tmp_path: Path) -> None:
    other = spm.build_robot(spm.SPMDesign.agile_eye())
    with pytest.raises(spm.InputError, match="not the MJCF"):
        D.simulate_mujoco(MJCF, D.ClosedLoopDynamics(other), 0.01)
    coulomb = D.ClosedLoopDynamics(other, friction=D.JointFriction(coulomb=0.01))
    with pytest.raises(spm.InputError, match="viscous"):
        D.simulate_mujoco(MJCF, coulomb, 0.01)
    with pytest.raises(spm.InputError, match="does not exist"):
        D.simulate_mujoco(tmp_path / "none.xml", None, 0.01)


# ----------------------------------------------------------------------- the CLI
def test_cli_torques(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    plot = tmp_path / "torques.png"
    assert cli.main(["torques", "--to", "60", "90", "120", "--plot", str(plot), "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["within_limits"] is True and record["verdict"].startswith("OK")
    assert record["servo"]["stall_torque_nm"] == 7.3
    assert record["trajectory"]["samples"] == 1001
    assert 0 < max(record["peak_torque_nm"]) < 0.1
    assert math.isclose(max(record["peak_speed_rpm"]), 1.875 * 120 / 360 * 60)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # too fast for the servo: 141 rpm > 53 rpm
    # (the report is printed, and the exit status says the servos cannot do it)
    status = cli.main(["torques", "--to", "90", "0", "0", "--duration", "0.2"])
    assert status == cli.EXIT_OVER_LIMITS == 1
    text, err = capsys.readouterr()
    assert "EXCEEDS" in text and "within_limits    false" in text
    assert err.startswith("spm: warning: EXCEEDS") and err.count("\n") == 1
    # a file of the same motion gives the same torques
    motion = D.Trajectory.minimum_jerk([0.0, 0.0, 0.0], np.radians([60, 90, 120]), 1.0)
    file = motion.save(tmp_path / "motion.csv")
    assert cli.main(["torques", "--file", str(file), "--json"]) == 0
    from_file = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(from_file["peak_torque_nm"], record["peak_torque_nm"], rtol=1e-3)


@pytest.mark.parametrize(
    "argv",
    [
        ["torques"],
        ["torques", "--to", "1", "2"],
        ["torques", "--to", "1", "2", "3", "--duration", "0"],
        ["torques", "--to", "1", "2", "3", "--rate", "-5"],
        ["torques", "--to", "1", "2", "3", "--file", "x.csv"],
        ["torques", "--file", "does-not-exist.csv"],
        ["torques", "--from", "60", "90", "220", "--to", "0", "0", "0"],  # no home mode
        ["torques", "--to", "nan", "0", "0"],
    ],
)
def test_cli_torques_bad_arguments(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("spm: error:") and err.count("\n") == 1


# ---------------------------------------------------------------------- bad input
def _bad(match: str, call: object, error: type[Exception] = spm.InputError) -> None:
    """``call()`` raises ``error`` (an SPMError) with a message matching ``match``."""
    with pytest.raises(error, match=match) as info:
        call()  # type: ignore[operator]
    assert isinstance(info.value, spm.SPMError)
    assert str(info.value)


def test_bad_input_raises_spm_errors(upright: D.ClosedLoopDynamics) -> None:
    nan3 = [math.nan, 0.0, 0.0]
    for dt in (0.0, -1e-3, math.nan, math.inf, True, "1e-3"):
        _bad(r"^dt must be a finite number > 0 \[s\]", lambda dt=dt: D.Simulator(upright, dt=dt))
    _bad(
        r"^integrator must be one of \['rk4', 'euler'\], got 'rk45'",
        lambda: D.Simulator(upright, integrator="rk45"),
    )
    _bad(
        r"^state must be theta \(3,\) \[rad\] or a closed configuration q \(9,\)",
        lambda: D.Simulator(upright, state=[0.0, 0.0]),
    )
    _bad(
        r"^theta_dot must be finite with \|theta_dot\| <= 10000 \[rad/s\]",
        lambda: D.Simulator(upright, theta_dot=nan3),
    )
    sim = D.Simulator(upright, integrator="euler")
    _bad(r"^torque must be finite with \|torque\| <= 10000 \[N m\]", lambda: sim.step(nan3))
    _bad(
        r"^torque must be finite with \|torque\| <= 10000 \[N m\]",
        lambda: sim.step([0.0, math.inf, 0.0]),
    )
    _bad(r"^torque must have shape \(3,\) \[N m\], got shape \(2,\)", lambda: sim.step([1.0, 2.0]))
    _bad(r"^torque must be 3 numbers \[N m\]", lambda: sim.step("torque"))
    for duration in (0.0, -1.0, math.nan):
        _bad(r"^duration must be a finite number > 0 \[s\]", lambda d=duration: sim.run(d))
    _bad(r"^record_every must be an integer >= 1, got 0", lambda: sim.run(0.01, record_every=0))
    _bad(r"^controller must be finite \[N m\] \(a constant torque\)", lambda: sim.run(0.01, nan3))
    _bad(
        r"^controller output must be finite \[N m\] \(at t = 0 s\)",
        lambda: sim.run(0.01, lambda t, a, b: np.full(3, math.nan)),
    )
    _bad(
        r"^controller output must have shape \(3,\) \[N m\] \(at t = 0 s\)",
        lambda: sim.run(0.01, lambda t, a, b: np.zeros(2)),
    )
    with pytest.raises(spm.InputError, match="at t = "):
        sim.run(0.01, lambda t, a, b: np.array([0.0, 0.0, math.nan if t > 0.004 else 0.0]))
    sim.reset()
    _bad(r"^time must be finite \[s\], got nan", lambda: sim.reset(time=math.nan))
    assert sim.max_closure_residual <= TOL["drift"]  # the state is still sound
    _bad(
        r"^theta_dot must be finite with \|theta_dot\| <= 10000 \[rad/s\]",
        lambda: upright.forward(np.zeros(3), nan3),
    )
    _bad(
        r"^torque must be finite with \|torque\| <= 10000 \[N m\]",
        lambda: upright.forward(np.zeros(3), np.zeros(3), nan3),
    )
    _bad(
        r"^state must be theta \(3,\) \[rad\] or a closed configuration q \(9,\), got shape \(4,\)",
        lambda: upright.forward(np.zeros(4), np.zeros(3)),
    )
    _bad(
        r"^method must be 'pinocchio' or 'nullspace', got 'aba'",
        lambda: upright.forward(np.zeros(3), np.zeros(3), method="aba"),
    )
    q = upright.configuration([0.1, 0.2, 0.3])
    q[1] += 1e-3
    _bad(
        r"^q does not close the loops: residual .* > 1e-09 rad",
        lambda: upright.forward(q, np.zeros(3)),
    )  # q does not close the loops
    _bad(
        r"^theta_ddot must have the shape of theta \(4, 3\), got \(3, 3\)",
        lambda: upright.inverse(np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((3, 3))),
    )
    _bad(
        r"^theta_ddot must be finite with \|theta_ddot\| <= 1e\+07 \[rad/s\^2\]",
        lambda: upright.inverse(np.zeros(3), np.zeros(3), nan3),
    )
    _bad(
        r"^theta_dot and theta_ddot are required with theta",
        lambda: D.inverse_dynamics(upright, np.zeros(3)),
    )
    _bad(
        r"^robot must be an SPMRobot \(spm\.build_robot\(\)\), got str",
        lambda: D.ClosedLoopDynamics("robot"),
    )  # type: ignore[arg-type]
    _bad(
        r"^gravity must have shape \(3,\) \[m/s\^2\], got shape \(2,\)",
        lambda: D.ClosedLoopDynamics(upright.robot, gravity=[0.0, -9.81]),
    )
    _bad(
        r"^armature must be >= 0 \[kg m\^2\]",
        lambda: D.ClosedLoopDynamics(upright.robot, armature=-1.0),
    )
    _bad(
        r"^friction must be a JointFriction or None, got float",
        lambda: D.ClosedLoopDynamics(upright.robot, friction=0.1),
    )  # type: ignore[arg-type]
    _bad(r"^viscous must be >= 0 \[N m s/rad\]", lambda: D.JointFriction(viscous=-0.1))
    _bad(
        r"^coulomb must have shape \(9,\) \[N m\], got shape \(8,\)",
        lambda: D.JointFriction(coulomb=np.ones(8)),
    )
    _bad(
        r"^smoothing_speed must be a finite number > 0 \[rad/s\], got 0\.0",
        lambda: D.JointFriction(smoothing_speed=0.0),
    )
    _bad(
        r"^stall_torque must be a finite number > 0 \[N m\], got 0\.0",
        lambda: D.ServoModel(stall_torque=0.0),
    )
    _bad(
        r"^kp must be a finite number >= 0 \[N m/rad\], got nan", lambda: D.ServoModel(kp=math.nan)
    )
    _bad(
        r"^servo must be a ServoModel, got str", lambda: D.ServoController("servo", [0.0, 0.0, 0.0])
    )  # type: ignore[arg-type]
    _bad(
        r"^goal must have shape \(3,\) \[rad\], got shape \(2,\)",
        lambda: D.ServoController(D.XM540_W150, [0.0, 0.0]),
    )
    _bad(
        r"^duration must be a finite number > 0 \[s\], got 0\.0",
        lambda: D.Trajectory.minimum_jerk([0, 0, 0], [1, 1, 1], 0.0),
    )
    _bad(
        r"^time must hold at least 2 finite, strictly increasing sample times \[s\]",
        lambda: D.Trajectory(
            np.array([0.0, 0.0]), np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3))
        ),
    )
    _bad(
        r"^from_samples needs N >= 3 times and theta of shape \(N, 3\)",
        lambda: D.Trajectory.from_samples([0.0, 1.0], np.zeros((2, 3))),
    )
    _bad(
        r"^torque and speed must have the same shape, got \(2, 3\) and \(3, 3\)",
        lambda: D.check_servo(np.zeros((2, 3)), np.zeros((3, 3))),
    )
    _bad(
        r"^time must have shape \(2,\), got \(1,\)",
        lambda: D.check_servo(np.zeros((2, 3)), np.zeros((2, 3)), time=[0.0]),
    )
    _bad(
        r"^expected a ClosedLoopDynamics or an SPMRobot, got int",
        lambda: D.forward_dynamics(42, np.zeros(3), np.zeros(3)),
    )  # type: ignore[arg-type]
    match = r"theta = \[60\.0, 90\.0, 220\.0\] deg has no assembly in mode 'home'"
    with pytest.raises(spm.UnreachableError, match=match):
        upright.forward(np.radians([60.0, 90.0, 220.0]), np.zeros(3))


@settings(max_examples=60)
@given(
    st.lists(
        st.one_of(
            st.floats(min_value=-0.01, max_value=0.01),
            st.sampled_from([math.nan, math.inf, -math.inf]),
        ),
        min_size=0,
        max_size=5,
    )
)
def test_step_accepts_exactly_three_finite_torques(
    upright: D.ClosedLoopDynamics, torque: list[float]
) -> None:
    sim = D.Simulator(upright, integrator="euler")
    valid = len(torque) == 3 and all(math.isfinite(x) for x in torque)
    if valid:
        sim.step(torque)
        assert sim.steps == 1 and sim.closure_residual <= TOL["drift"]
    else:
        match = r"^torque must (have shape \(3,\)|be finite with \|torque\| <= 10000) \[N m\]"
        with pytest.raises(spm.InputError, match=match):
            sim.step(torque)
        assert sim.steps == 0  # nothing happened
