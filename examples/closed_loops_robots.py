"""The generic loop-closure solver on two example-robot-data robots.

Two UR5 arms hold one rigid bar (a 6D weld between the tools; arm a drives, arm b
follows), and a Solo-12 quadruped stands on its four feet (a point anchor per foot;
its free-flyer base passive) while its body is posed through the loops. Needs the
robot files of ``pip install example-robot-data``.
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np
import pinocchio as pin

import spm_pin as spm

#: Arm a's joints, then arm b's, at the start (arm b facing arm a, 1.2 m away).
UR5_START = np.array([0.3, -1.2, 1.5, -1.9, -1.57, 0.2, -0.2, -1.4, 1.7, -1.8, -1.6, -0.4])
#: Solo-12's six leg joints that serve as coordinates of the standing robot.
SOLO_COORDINATES = ("FL_HAA", "FL_HFE", "FL_KFE", "FR_HAA", "HL_HAA", "HR_HAA")
SOLO_FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")


def numbers(values: np.ndarray) -> str:
    """``values`` as space-separated numbers, to 12 significant digits."""
    return " ".join(f"{x:.12g}" for x in np.ravel(values))


def robots_folder() -> Path:
    """The robot files installed by example-robot-data."""
    folder = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    return Path(str(folder))


def ur5(urdf: Path, prefix: str) -> pin.Model:
    """The UR5 with every joint and frame name prefixed."""
    model = pin.buildModelFromUrdf(str(urdf))
    for joint in range(1, model.njoints):
        model.names[joint] = prefix + model.names[joint]
    for frame in model.frames:
        frame.name = prefix + frame.name
    return model


def two_arms(robots: Path) -> None:
    """Two UR5 arms holding one bar: project, follow, velocities, carry the bar."""
    urdf = robots / "ur_description" / "urdf" / "ur5_robot.urdf"
    base_b = pin.SE3(pin.utils.rotate("z", np.pi), np.array([1.2, 0.0, 0.0]))
    arms = pin.appendModel(ur5(urdf, "a_"), ur5(urdf, "b_"), 0, base_b)
    data = arms.createData()
    q0 = UR5_START
    pin.framesForwardKinematics(arms, data, q0)
    tool_a, tool_b = arms.getFrameId("a_tool0"), arms.getFrameId("b_tool0")
    bar = data.oMf[tool_a].actInv(data.oMf[tool_b])
    frame_a, frame_b = arms.frames[tool_a], arms.frames[tool_b]
    weld = pin.FrameAnchorConstraintModel(
        arms, frame_a.parentJoint, frame_a.placement * bar, frame_b.parentJoint, frame_b.placement
    )
    pair = spm.ClosedLoop(arms, [weld], [arms.names[j] for j in range(1, 7)])
    print(f"ur5_loop: {pair}")
    print(f"ur5_mobility: {pair.mobility}")
    print(f"ur5_q_start: {numbers(q0)}")

    # 1. Arm a moves by 0.1 rad on every joint; arm b keeps holding the bar.
    moved = pair.project(q0[:6] + 0.1, q0)
    print(f"ur5_actuated: {numbers(moved.actuated)}")
    print(f"ur5_q: {numbers(moved.q)}")
    print(f"ur5_newton_steps: {moved.iterations}")
    print(f"ur5_residual: {moved.residual:.1e}")

    # 2. A straight path of arm a's joints in 40 samples, by continuation.
    path = q0[:6] + np.linspace(0.0, 1.0, 40)[:, None] * np.array([0.4, 0.2, -0.3, 0.3, 0.2, 0.5])
    swing = pair.follow(path, q0)
    print(f"ur5_path_samples: {len(swing.residual)}")
    print(f"ur5_path_max_residual: {swing.residual.max():.1e}")
    print(f"ur5_path_end_q: {numbers(swing.q[-1])}")

    # 3. Velocities that keep the bar held, and arm b's tool Jacobian (LOCAL).
    rate = np.array([0.3, -0.2, 0.1, 0.4, -0.3, 0.2])
    print(f"ur5_rate: {numbers(rate)}  (arm a's joint rates, rad/s)")
    print(f"ur5_v: {numbers(pair.velocity(moved.q, rate))}")
    J_b = pair.frame_jacobian(moved.q, "b_tool0")
    print(f"ur5_J_b_tool: {numbers(J_b)}  (6 x 6, row by row, LOCAL)")

    # 4. Carry the bar: arm a's tool 5 cm up and turned 10 deg about the vertical.
    turn = pin.utils.rotate("z", np.radians(10.0))
    target = pin.SE3(
        turn @ data.oMf[tool_a].rotation, data.oMf[tool_a].translation + np.array([0, 0, 0.05])
    )
    carried = pair.solve_frame_target("a_tool0", target, q0)
    print(f"ur5_target: {numbers(target.homogeneous)}  (4 x 4, a_tool0 in the world)")
    print(f"ur5_target_q: {numbers(carried.q)}")
    print(f"ur5_target_iterations: {carried.iterations}")
    print(f"ur5_target_residual: {carried.residual:.1e}")


def quadruped(robots: Path) -> None:
    """Solo-12 standing on its four feet: pose the body, body twist to joint rates."""
    urdf = robots / "solo_description" / "robots" / "solo12.urdf"
    solo = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    pin.loadReferenceConfigurations(solo, str(robots / "solo_description" / "srdf" / "solo.srdf"))
    standing = solo.referenceConfigurations["standing"].copy()
    data = solo.createData()
    pin.framesForwardKinematics(solo, data, standing)
    feet = [solo.getFrameId(name) for name in SOLO_FEET]
    ground = [data.oMf[foot].translation.copy() for foot in feet]
    anchors = [
        pin.PointAnchorConstraintModel(
            solo,
            solo.frames[foot].parentJoint,
            solo.frames[foot].placement,
            0,
            pin.SE3(np.eye(3), p),
        )
        for foot, p in zip(feet, ground, strict=True)
    ]
    try:  # twelve leg joints as inputs of a 6-DoF mechanism: refused
        spm.ClosedLoop(solo, anchors, [solo.names[j] for j in range(2, 14)])
        print("solo_twelve_inputs: accepted")
    except spm.InputError as error:
        print(f"solo_twelve_inputs: refused ({str(error).split(':')[0]})")
    stand = spm.ClosedLoop(solo, anchors, SOLO_COORDINATES)
    print(f"solo_loop: {stand}")
    print(f"solo_mobility: {stand.mobility}")
    print(f"solo_q_start: {numbers(standing)}")
    print(f"solo_ground: {numbers(np.array(ground))}  (FL FR HL HR feet, m)")

    # 1. The body 3 cm lower, 2 cm forward, rolled, pitched and yawed 5, -4, 8 deg.
    pose = pin.SE3(
        pin.rpy.rpyToMatrix(np.radians([5.0, -4.0, 8.0])), np.array([0.02, -0.01, 0.205])
    )
    posed = stand.solve_frame_target("base_link", pose, standing)
    print(f"solo_target: {numbers(pose.homogeneous)}  (4 x 4, base_link in the world)")
    print(f"solo_q: {numbers(posed.q)}")
    print(f"solo_iterations: {posed.iterations}")
    print(f"solo_residual: {posed.residual:.1e}")
    other = spm.ClosedLoop(
        solo, anchors, ("HR_HAA", "HR_HFE", "HR_KFE", "FL_HAA", "FR_HAA", "HL_HAA")
    )
    same = other.solve_frame_target("base_link", pose, standing)
    difference = np.abs(pin.difference(solo, same.q, posed.q)).max()
    print(f"solo_other_coordinates_difference: {difference:.1e}  (max |q - q_other|)")

    # 2. A body twist (LOCAL) to the rates of all 18 joints, the feet standing still.
    twist = np.array([0.05, 0.0, -0.02, 0.1, 0.0, 0.2])
    rates = np.linalg.solve(stand.frame_jacobian(posed.q, "base_link"), twist)
    print(f"solo_twist: {numbers(twist)}  (m/s, rad/s, base_link frame)")
    print(f"solo_v: {numbers(stand.velocity(posed.q, rates))}")

    # 3. A squat: the body lowered to 17 cm in 14 warm-started solves.
    previous: spm.ProjectionResult | spm.FrameTargetResult = stand.project(
        standing[stand.actuated_q_idx], standing
    )
    steps = []
    for height in np.linspace(0.235, 0.17, 14):
        level = pin.SE3(np.eye(3), np.array([0.0, 0.0, height]))
        previous = stand.solve_frame_target("base_link", level, previous)
        steps.append(previous.iterations)
    print(f"solo_squat_iterations: {numbers(np.array(steps))}")
    print(f"solo_squat_q: {numbers(previous.q)}")


def main() -> None:
    robots = robots_folder()
    two_arms(robots)
    quadruped(robots)


if __name__ == "__main__":
    main()
