"""Servo torques of the study's motion, then the same motion simulated with the servos."""

from __future__ import annotations

import numpy as np

import spm_pin as spm


def main() -> None:
    robot = spm.build_robot()
    dynamics = spm.ClosedLoopDynamics(robot)  # upright, frictionless
    goal = np.radians([60.0, 90.0, 120.0])
    motion = spm.Trajectory.minimum_jerk(np.zeros(3), goal, duration=1.0, rate=1000.0)

    # What the servos must give (closed-loop inverse dynamics).
    needed = spm.inverse_dynamics(dynamics, motion)
    check = spm.check_servo(needed.torque, needed.theta_dot, spm.XM540_W150, time=motion.time)
    print(f"move home -> {np.degrees(goal)} deg in {motion.duration:g} s")
    peak = np.abs(needed.torque).max(axis=0)
    holding = spm.holding_torques(dynamics, goal)
    print(f"  peak torque per servo: {', '.join(f'{x:.4f}' for x in peak)} N m")
    print(f"  holding torque at the goal: {', '.join(f'{x:+.4f}' for x in holding)} N m")
    print(f"  {check.message}")

    # The servos drive the simulated robot along the move (rk4, 1 kHz).
    servos = spm.ServoController(spm.XM540_W150, motion)
    sim = spm.Simulator(dynamics, dt=1e-3, integrator="rk4")
    run = sim.run(1.5, servos, record_every=10)
    error = np.degrees(np.abs(run.theta[-1] - goal).max())
    print(f"simulated {run.steps} steps: final error {error:.4f} deg, closure residual")
    print(f"  at most {run.max_closure_residual:.1e} rad, energy balance error")
    print(f"  {np.abs(run.energy_error).max():.1e} J (servo work {run.actuator_work[-1]:.4f} J)")
    gap = np.abs(run.torque[:101] - needed.torque[::10]).max()
    print(f"  servo torques vs inverse dynamics during the move: within {gap:.1e} N m")


if __name__ == "__main__":
    main()
