"""Reduced (three-coordinate) dynamics, batched: against the constrained dynamics,
Pinocchio's energies, the Simulator and MuJoCo; passivity; batching; bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import spm_pin as spm
from spm_pin import dynamics as D

ROOT = Path(__file__).resolve().parent.parent
MJCF = ROOT / "urdf" / "spm.xml"

#: Tolerances of this file (absolute unless named relative).
TOL = {
    "forward": 1e-9,  # theta_ddot vs ClosedLoopDynamics, relative to max(1, |ref|) (~1e-15)
    "terms": 1e-12,  # M [kg m^2], S, holding torques [N m] vs ClosedLoopDynamics
    "energy": 1e-12,  # kinetic / potential energy vs Pinocchio [J]
    "passivity": 1e-6,  # theta_dot^T (dM/dt/2 theta_dot - c) / scale, central differences
    "fk_batch": 1e-12,  # batch vs single through forward_kinematics [rad/s^2]
    "energy_rk4": 1e-9,  # energy drift of a passive 2 s rk4 motion / kinetic scale
    "simulator_euler": 1e-9,  # reduced vs Simulator, semi-implicit Euler, 1 s [rad]
    "simulator_rk4": 1e-9,  # reduced vs Simulator, rk4, 1 s [rad]
    "mujoco": 1e-4,  # reduced rk4 (1 ms) vs MuJoCo (stiff welds, rk4 0.1 ms), 3 s [rad]
}


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


def _physics(robot: spm.SPMRobot, kind: str) -> D.ClosedLoopDynamics:
    if kind == "upright":
        return D.ClosedLoopDynamics(robot)
    if kind == "hanging":
        return D.ClosedLoopDynamics(robot, gravity=(0.0, 0.0, 9.81))
    if kind == "weightless":
        return D.ClosedLoopDynamics(robot, gravity=(0.0, 0.0, 0.0))
    friction = D.JointFriction(
        viscous=np.linspace(0.001, 0.009, 9), coulomb=np.full(9, 0.002), smoothing_speed=0.5
    )
    return D.ClosedLoopDynamics(
        robot, gravity=(3.0, -2.0, -9.0), friction=friction, armature=[0.002, 0.003, 0.004]
    )


def _states(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reachable home-mode states away from singularities, speeds and torques."""
    rng = np.random.default_rng(seed)
    theta = rng.uniform(-0.6, 0.6, (n, 3))
    keep = spm.jacobian(theta).singularity_margin > 0.2
    theta = theta[keep]
    m = theta.shape[0]
    return theta, rng.normal(size=(m, 3)) * 2.0, rng.normal(size=(m, 3)) * 0.05


# ------------------------------------------------------------------ equations
@pytest.mark.parametrize("kind", ["upright", "hanging", "weightless", "rich"])
@pytest.mark.parametrize("method", ["nullspace", "pinocchio"])
def test_forward_equals_constrained_dynamics(robot: spm.SPMRobot, kind: str, method: str) -> None:
    closed = _physics(robot, kind)
    reduced = D.ReducedDynamics.from_dynamics(closed)
    theta, theta_dot, torque = _states(40, 11)
    assert theta.shape[0] >= 20
    batch = reduced.forward(theta, theta_dot, torque)
    for k in range(theta.shape[0]):
        expected = closed.forward(theta[k], theta_dot[k], torque[k], method=method).theta_ddot
        scale = max(1.0, float(np.abs(expected).max()))
        np.testing.assert_allclose(batch[k], expected, rtol=0.0, atol=TOL["forward"] * scale)


def test_terms_equal_the_constrained_quantities(robot: spm.SPMRobot) -> None:
    closed = _physics(robot, "rich")
    reduced = D.ReducedDynamics.from_dynamics(closed)
    theta, theta_dot, _ = _states(20, 12)
    terms = reduced.terms(theta, theta_dot)
    assert terms.M.shape == (theta.shape[0], 3, 3) and terms.S.shape == (theta.shape[0], 9, 3)
    np.testing.assert_allclose(reduced.mass_matrix(theta), terms.M, atol=0.0)
    for k in range(theta.shape[0]):
        np.testing.assert_allclose(terms.S[k], closed.velocity_map(theta[k]), atol=TOL["terms"])
        np.testing.assert_allclose(terms.M[k], closed.mass_matrix(theta[k]), atol=TOL["terms"])
        np.testing.assert_allclose(terms.g[k], closed.holding_torques(theta[k]), atol=TOL["terms"])
        J = spm.jacobian(theta[k]).J
        np.testing.assert_allclose(terms.J[k], J, atol=TOL["terms"])
    np.testing.assert_allclose(reduced.holding_torques(theta), terms.g, atol=0.0)


def test_mass_matrix_is_symmetric_positive_definite(robot: spm.SPMRobot) -> None:
    reduced = D.ReducedDynamics(robot)
    theta, _, _ = _states(200, 13)
    M = reduced.mass_matrix(theta)
    np.testing.assert_allclose(M, M.swapaxes(-1, -2), atol=1e-18)
    assert np.linalg.eigvalsh(M).min() > 0.0


def test_design_and_robot_inertias_agree(robot: spm.SPMRobot) -> None:
    theta, theta_dot, torque = _states(10, 14)
    from_robot = D.ReducedDynamics(robot).forward(theta, theta_dot, torque)
    from_design = D.ReducedDynamics(spm.SPMDesign.prototype()).forward(theta, theta_dot, torque)
    np.testing.assert_allclose(from_design, from_robot, rtol=1e-12, atol=1e-12)


def test_energies_equal_pinocchio(robot: spm.SPMRobot) -> None:
    """1/2 theta_dot^T M theta_dot is the tree's kinetic energy at the closed q (Pinocchio,
    armature included); potentials differ only by the base's constant term."""
    closed = _physics(robot, "rich")
    reduced = D.ReducedDynamics.from_dynamics(closed)
    theta, theta_dot, _ = _states(10, 15)
    kinetic, potential = reduced.energy(theta, theta_dot)
    offsets = []
    for k in range(theta.shape[0]):
        tree_kinetic, tree_potential = closed.energy(theta[k], theta_dot[k])
        assert abs(kinetic[k] - tree_kinetic) <= TOL["energy"]
        offsets.append(tree_potential - potential[k])
    assert np.ptp(offsets) <= TOL["energy"]


def test_passivity(robot: spm.SPMRobot) -> None:
    """theta_dot^T (dM/dt - 2C) theta_dot = 0: theta_dot . c = 1/2 theta_dot^T dM/dt
    theta_dot, dM/dt along the motion by central differences (the test only)."""
    reduced = D.ReducedDynamics(robot, gravity=(0.0, 0.0, 0.0))
    theta, theta_dot, _ = _states(10, 16)
    h = 1e-6
    dM = (
        reduced.mass_matrix(theta + h * theta_dot) - reduced.mass_matrix(theta - h * theta_dot)
    ) / (2.0 * h)
    c = reduced.terms(theta, theta_dot).c
    lhs = np.einsum("ni,ni->n", theta_dot, c)
    rhs = 0.5 * np.einsum("ni,nij,nj->n", theta_dot, dM, theta_dot)
    scale = np.abs(c).max() * np.abs(theta_dot).max()
    np.testing.assert_allclose(lhs, rhs, atol=TOL["passivity"] * scale)


# ------------------------------------------------------------------ stepping
def _run(
    reduced: D.ReducedDynamics,
    theta: np.ndarray,
    theta_dot: np.ndarray,
    steps: int,
    dt: float,
    integrator: str,
) -> tuple[np.ndarray, np.ndarray]:
    R = None
    for _ in range(steps):
        result = reduced.step(theta, theta_dot, None, dt, integrator=integrator, reference=R)
        theta, theta_dot, R = result.theta, result.theta_dot, result.R
    return theta, theta_dot


def test_passive_rk4_motion_keeps_its_energy(robot: spm.SPMRobot) -> None:
    reduced = D.ReducedDynamics.from_dynamics(_physics(robot, "hanging"))
    theta0 = np.radians([[20.0, -10.0, 5.0], [-15.0, 10.0, 25.0]])
    rate0 = np.zeros((2, 3))
    energy0 = np.add(*reduced.energy(theta0, rate0))
    theta, rate = _run(reduced, theta0, rate0, 2000, 1e-3, "rk4")
    kinetic, potential = reduced.energy(theta, rate)
    scale = np.ptp(energy0)  # of the order of the swing's kinetic energy
    assert np.abs(kinetic + potential - energy0).max() <= TOL["energy_rk4"] * max(scale, 1e-3)
    assert kinetic.max() > 1e-3


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_trajectory_equals_the_simulator(robot: spm.SPMRobot, integrator: str) -> None:
    closed = _physics(robot, "hanging")
    reduced = D.ReducedDynamics.from_dynamics(closed)
    theta0 = np.radians([20.0, -10.0, 5.0])
    ours = D.Simulator(closed, integrator=integrator, state=theta0).run(1.0, record_every=1000)
    theta, rate = _run(reduced, theta0[None], np.zeros((1, 3)), 1000, 1e-3, integrator)
    assert np.ptp(ours.theta, axis=0).max() > np.radians(10)
    np.testing.assert_allclose(theta[0], ours.theta[-1], atol=TOL[f"simulator_{integrator}"])
    np.testing.assert_allclose(
        rate[0], ours.theta_dot[-1], atol=10 * TOL[f"simulator_{integrator}"]
    )


def test_trajectory_equals_mujoco(robot: spm.SPMRobot) -> None:
    pytest.importorskip("mujoco")
    closed = _physics(robot, "hanging")
    reduced = D.ReducedDynamics.from_dynamics(closed)
    theta0 = np.radians([20.0, -10.0, 5.0])
    theirs = D.simulate_mujoco(MJCF, closed, 3.0, state=theta0, record_every=100)
    theta, rate, R = theta0[None], np.zeros((1, 3)), None
    samples = [theta[0]]
    for k in range(1, 3001):
        result = reduced.step(theta, rate, None, 1e-3, integrator="rk4", reference=R)
        theta, rate, R = result.theta, result.theta_dot, result.R
        if k % 100 == 0:
            samples.append(theta[0])
    assert np.ptp(theirs.theta, axis=0).max() > np.radians(20)
    np.testing.assert_allclose(np.array(samples), theirs.theta, atol=TOL["mujoco"])


def test_batch_equals_single_calls(robot: spm.SPMRobot) -> None:
    reduced = D.ReducedDynamics.from_dynamics(_physics(robot, "rich"))
    theta, theta_dot, torque = _states(30, 17)
    R = reduced.rotation(theta)
    for integrator in ("euler", "rk4"):
        batch = reduced.step(theta, theta_dot, torque, 1e-3, integrator=integrator, reference=R)
        for k in range(theta.shape[0]):
            one = reduced.step(
                theta[k], theta_dot[k], torque[k], 1e-3, integrator=integrator, reference=R[k]
            )
            assert one.theta.shape == (3,) and one.R.shape == (3, 3)
            np.testing.assert_array_equal(batch.theta[k], one.theta)
            np.testing.assert_array_equal(batch.theta_dot[k], one.theta_dot)
            np.testing.assert_array_equal(batch.theta_ddot[k], one.theta_ddot)
    # without a warm start, forward_kinematics solves the rotations (batch-dependent
    # to rounding)
    batch_ddot = reduced.forward(theta, theta_dot, torque)
    single = np.array(
        [reduced.forward(t, w, f) for t, w, f in zip(theta, theta_dot, torque, strict=True)]
    )
    np.testing.assert_allclose(batch_ddot, single, atol=TOL["fk_batch"])
    # a shared torque (3,) for every robot
    shared = reduced.forward(theta, theta_dot, torque[0])
    np.testing.assert_allclose(
        shared,
        reduced.forward(theta, theta_dot, np.tile(torque[0], (theta.shape[0], 1))),
        atol=0.0,
    )


def test_warm_start_matches_forward_kinematics(robot: spm.SPMRobot) -> None:
    reduced = D.ReducedDynamics(robot)
    theta, theta_dot, _ = _states(50, 18)
    R = reduced.rotation(theta)
    moved = theta + 0.01 * theta_dot
    np.testing.assert_allclose(
        reduced.rotation(moved, R), spm.forward_kinematics(moved).R, atol=1e-12
    )
    # a far reference that lands elsewhere falls back to forward kinematics
    far = np.broadcast_to(np.diag([1.0, -1.0, -1.0]), R.shape)
    np.testing.assert_allclose(
        reduced.rotation(moved, far), spm.forward_kinematics(moved).R, atol=1e-12
    )


# ------------------------------------------------------------------ bad input
def test_bad_input_is_refused(robot: spm.SPMRobot) -> None:
    reduced = D.ReducedDynamics(robot)
    zeros = np.zeros((4, 3))
    with pytest.raises(spm.InputError, match="theta"):
        reduced.forward(np.zeros(4), np.zeros(4))
    with pytest.raises(spm.InputError, match="theta_dot"):
        reduced.forward(zeros, np.zeros((3, 3)))
    with pytest.raises(spm.InputError, match="theta"):
        reduced.forward([[0.0, np.nan, 0.0]], [[0.0, 0.0, 0.0]])
    with pytest.raises(spm.InputError, match="theta_dot"):
        reduced.forward(zeros, np.full((4, 3), np.inf))
    with pytest.raises(spm.InputError, match="torque"):
        reduced.forward(zeros, zeros, np.zeros((5, 3)))
    with pytest.raises(spm.InputError, match="dt"):
        reduced.step(zeros, zeros, None, -1e-3)
    with pytest.raises(spm.InputError, match="integrator"):
        reduced.step(zeros, zeros, None, 1e-3, integrator="midpoint")
    with pytest.raises(spm.InputError, match="reference"):
        reduced.step(zeros, zeros, None, 1e-3, reference=np.eye(2))
    with pytest.raises(spm.InputError, match="robot"):
        D.ReducedDynamics(42)  # type: ignore[arg-type]
    with pytest.raises(spm.InputError, match="friction"):
        D.ReducedDynamics(robot, friction="none")  # type: ignore[arg-type]
    with pytest.raises(spm.InputError, match="dynamics"):
        D.ReducedDynamics.from_dynamics(robot)


def test_unreachable_rows_are_named(robot: spm.SPMRobot) -> None:
    reduced = D.ReducedDynamics(robot)
    theta = np.zeros((5, 3))
    theta[[1, 3]] = np.radians([0.0, 170.0, 0.0])  # a gap of -50 deg: no assembly
    assert not spm.forward_kinematics(theta[1]).reachable
    with pytest.raises(spm.UnreachableError, match=r"rows \[1, 3\]"):
        reduced.forward(theta, np.zeros((5, 3)))
