"""Servo torques of the study's motion, then the same motion simulated with the servos."""

from __future__ import annotations

import numpy as np

import spm_pin as spm


def numbers(values: np.ndarray) -> str:
    """``values`` as space-separated numbers, to 12 significant digits."""
    return " ".join(f"{x:.12g}" for x in np.ravel(values))


def main() -> None:
    robot = spm.build_robot()
    dynamics = spm.ClosedLoopDynamics(robot)  # upright, frictionless
    goal = np.radians([60.0, 90.0, 120.0])
    motion = spm.Trajectory.minimum_jerk(np.zeros(3), goal, duration=1.0, rate=1000.0)
    print(f"goal_deg: {numbers(np.degrees(goal))}  (minimum-jerk move from home)")
    print(f"duration_s: {motion.duration:g}")

    # What the servos must give (closed-loop inverse dynamics).
    needed = spm.inverse_dynamics(dynamics, motion)
    check = spm.check_servo(needed.torque, needed.theta_dot, spm.XM540_W150, time=motion.time)
    print(f"peak_torque_Nm: {numbers(np.abs(needed.torque).max(axis=0))}")
    print(f"holding_torque_Nm: {numbers(spm.holding_torques(dynamics, goal))}")
    print(f"servo_check: {check.message}")

    # The servos drive the simulated robot along the move (rk4, 1 kHz), then hold it.
    servos = spm.ServoController(spm.XM540_W150, motion)
    sim = spm.Simulator(dynamics, dt=1e-3, integrator="rk4")
    run = sim.run(1.5, servos, record_every=10)
    print(f"sim_steps: {run.steps}")
    print(f"final_theta_deg: {numbers(np.degrees(run.theta[-1]))}")
    print(f"final_error_deg: {np.degrees(np.abs(run.theta[-1] - goal).max()):.4f}")
    print(f"max_closure_residual_rad: {run.max_closure_residual:.1e}")
    print(f"energy_balance_error_J: {np.abs(run.energy_error).max():.1e}")
    print(f"servo_work_J: {run.actuator_work[-1]:.6f}")
    gap = np.abs(run.torque[:101] - needed.torque[::10]).max()
    print(f"servo_vs_inverse_dynamics_Nm: {gap:.1e}  (during the move)")


if __name__ == "__main__":
    main()
