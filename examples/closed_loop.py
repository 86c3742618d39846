"""Closed-loop kinematics of the SPM with the generic solver, next to the analytic one."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

import spm_pin as spm


def numbers(values: np.ndarray) -> str:
    """``values`` as space-separated numbers, to 12 significant digits."""
    return " ".join(f"{x:.12g}" for x in np.ravel(values))


def main() -> None:
    robot = spm.build_robot()
    loop = spm.ClosedLoop.from_robot(robot)
    print(f"loop: {loop}")

    # 1. The study's input from a cold start at home, against the analytic FK.
    theta = np.radians([60.0, 90.0, 120.0])
    result = loop.project(theta)
    R = robot.placement(result.q, "platform").rotation
    error = np.abs(R - spm.forward_kinematics(theta).R).max()
    print(f"theta_deg: {numbers(np.degrees(theta))}")
    print(f"newton_steps: {result.iterations}")
    print(f"residual: {result.residual:.1e}")
    print(f"rank: {result.rank}")
    print(f"R_platform: {numbers(R)}  (row by row)")
    print(f"R_error: {error:.1e}  (max |R - R_analytic|)")

    # 2. The study's motion, home to that input in 25 samples, by continuation.
    path = np.linspace(0.0, 1.0, 25)[:, None] * theta
    followed = loop.follow(path)
    print(f"path_samples: {len(followed.residual)}")
    print(f"path_newton_steps: {followed.total_iterations}")
    print(f"path_max_residual: {followed.residual.max():.1e}")

    # 3. A control loop: 1000 warm-started solves along a 1 kHz trajectory.
    t = np.arange(1000)[:, None] / 1000.0
    trajectory = theta + np.radians(10.0) * np.sin(2 * np.pi * np.array([0.5, 0.7, 0.9]) * t)
    previous = loop.project(trajectory[0], result)
    start = time.perf_counter()
    for item in trajectory[1:]:
        previous = loop.project(item, previous)
    elapsed = (time.perf_counter() - start) / (len(trajectory) - 1)
    drift = np.abs(previous.q - robot.configuration(trajectory[-1])).max()
    print(f"us_per_solve: {1e6 * elapsed:.0f}  (1 kHz trajectory, warm-started)")
    print(f"trajectory_drift_rad: {drift:.1e}  (final max |q - q_analytic|)")

    # 4. Velocities: the platform's angular velocity against the analytic Jacobian.
    theta_dot = np.array([0.2, -0.1, 0.4])
    J = loop.frame_jacobian(result.q, "platform", pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    omega = J[3:] @ theta_dot
    print(f"theta_dot: {numbers(theta_dot)}")
    print(f"omega: {numbers(omega)}  (rad/s)")
    print(f"omega_analytic: {numbers(spm.jacobian(theta).J @ theta_dot)}")

    # 5. Inverse kinematics through the loops: a platform orientation -> inputs.
    found = loop.solve_frame_target("platform", spm.forward_kinematics(theta).R)
    print(f"ik_theta_deg: {numbers(np.degrees(found.actuated))}")


if __name__ == "__main__":
    main()
