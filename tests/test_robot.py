"""The Pinocchio model: closed configurations against the analytic kinematics, loop
constraints and their Jacobian, mass properties, geometry, and the same robot loaded
from the exported MJCF (Pinocchio and MuJoCo) and URDF."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
from conftest import get_design, reachable_inputs, wrap
from hypothesis import given
from hypothesis import strategies as st

import spm_pin as spm
from spm_pin.model.robot import (
    ACTUATED_JOINTS,
    CONSTRAINT_NAMES,
    END_BODIES,
    JOINT_NAMES,
    PASSIVE_JOINTS,
    SPMRobot,
)

#: Tolerances of this module.
TOL = {
    # Platform axes / rotation of configuration(theta) vs forward_kinematics [unit vectors].
    "axes": 1e-12,
    # Loop closure at configuration(theta): leg-end placements and weld errors [rad, m].
    "closure": 1e-12,
    # Code-built model vs the model read from the exported files [m, rad, kg, kg m^2].
    "placement": 1e-12,
    # Mass properties read back from the files, relative: the exporter rounds them to
    # a fixed number of significant digits and zeroes inertia entries below 1e-10 of
    # the largest (rounding noise).
    "mass_file": 1e-10,
    # MuJoCo body poses of the welded bodies and its equality residuals.
    "mujoco": 1e-10,
    # Constraint Jacobian times a velocity built from the analytic Jacobian.
    "velocity": 1e-10,
    # Central differences of configuration(theta) [rad] (step 1e-6).
    "fd_step": 1e-6,
    "fd": 1e-7,
}

#: The designs whose model is tested against the analytic kinematics.
MODEL_DESIGNS = ("prototype", "agile_eye", "general")
#: Random reachable inputs per design.
SAMPLES = 40
#: Random joint configurations at which the models read from files are compared.
RANDOM_Q = 200
#: Plausible total mass of the prototype [kg]: three 165 g servos plus printed parts.
PROTOTYPE_MASS_RANGE = (0.6, 3.0)

LINK_NAMES = (
    "base",
    "proximal_1",
    "proximal_2",
    "proximal_3",
    "distal_1",
    "distal_2",
    "distal_3",
    "platform",
)

_ROBOTS: dict[str, SPMRobot] = {}


def get_robot(name: str) -> SPMRobot:
    """The robot of design ``name`` (built once)."""
    if name not in _ROBOTS:
        _ROBOTS[name] = spm.build_robot(get_design(name))
    return _ROBOTS[name]


@pytest.fixture(scope="module")
def robot() -> SPMRobot:
    return get_robot("prototype")


def _frame_placements(model: Any, q: np.ndarray) -> dict[str, np.ndarray]:
    """World placements (4x4) of every BODY frame of ``model`` at q, by name."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return {
        frame.name: data.oMf[i].homogeneous.copy()
        for i, frame in enumerate(model.frames)
        if frame.type == pin.FrameType.BODY
    }


# --------------------------------------------------------------- structure
def test_public_api_is_lazy(tmp_path: Path) -> None:
    """``import spm_pin`` does not import Pinocchio; spm.build_robot does, on first use."""
    code = (
        "import sys, spm_pin as spm\n"
        "assert 'pinocchio' not in sys.modules, 'pinocchio imported eagerly'\n"
        "assert 'trimesh' not in sys.modules, 'trimesh imported eagerly'\n"
        "robot = spm.build_robot()\n"
        "assert 'pinocchio' in sys.modules\n"
        "assert isinstance(robot, spm.SPMRobot)\n"
        "assert 'build_robot' in dir(spm) and 'SPMRobot' in spm.__all__\n"
    )
    package_root = str(Path(spm.__file__).resolve().parent.parent)
    path = os.pathsep.join(p for p in (package_root, os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, "PYTHONPATH": path}
    subprocess.run([sys.executable, "-c", code], check=True, cwd=tmp_path, env=env)


def test_joint_names_order_and_split(robot: SPMRobot) -> None:
    model = robot.model
    assert (model.nq, model.nv) == (9, 9)
    assert tuple(model.names)[1:] == JOINT_NAMES
    assert robot.actuated_joints == ACTUATED_JOINTS
    assert robot.passive_joints == PASSIVE_JOINTS
    np.testing.assert_array_equal(robot.actuated_q_idx, [0, 3, 6])
    np.testing.assert_array_equal(robot.passive_q_idx, [1, 2, 4, 5, 7, 8])
    for name in JOINT_NAMES:
        joint = model.getJointId(name)
        assert model.idx_qs[joint] == model.idx_vs[joint] == JOINT_NAMES.index(name)
        assert model.joints[joint].shortname() == "JointModelRevoluteUnaligned"
        assert model.jointPlacements[joint].isIdentity()


@pytest.mark.parametrize("name", MODEL_DESIGNS)
def test_joint_axes_are_the_design_axes(name: str) -> None:
    """Each joint's motion subspace at q = 0 is a rotation about its design axis."""
    robot = get_robot(name)
    design = robot.design
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, np.zeros(9))
    axes = {"u": design.u, "w": design.w0, "v": design.v0}
    for joint_name in JOINT_NAMES:
        joint = robot.model.getJointId(joint_name)
        S = np.asarray(data.joints[joint].S).reshape(6)
        leg = int(joint_name[-1]) - 1
        np.testing.assert_allclose(S[:3], 0.0, atol=1e-15)
        np.testing.assert_allclose(S[3:], axes[joint_name[0]][leg], atol=1e-15)


def test_home_is_identity_everywhere(robot: SPMRobot) -> None:
    """q = 0 is home: configuration(0) = 0 and every link frame equals the world frame."""
    np.testing.assert_allclose(robot.configuration(np.zeros(3)), np.zeros(9), atol=1e-14)
    for name, placement in robot.placements(np.zeros(9)).items():
        np.testing.assert_allclose(placement.homogeneous, np.eye(4), atol=0, err_msg=name)


def test_link_frames(robot: SPMRobot) -> None:
    model = robot.model
    assert tuple(robot.link_frames) == LINK_NAMES
    for name, frame_id in robot.link_frames.items():
        frame = model.frames[frame_id]
        assert frame.name == name
        assert frame.type == pin.FrameType.BODY
        assert frame.placement.isIdentity()
    assert model.frames[robot.link_frames["base"]].parentJoint == 0
    assert model.frames[robot.link_frames["platform"]].parentJoint == model.getJointId("v_1")
    for leg, frame_id in enumerate(robot.end_frames):
        assert model.frames[frame_id].name == END_BODIES[leg]
        assert model.frames[frame_id].parentJoint == model.getJointId(f"v_{leg + 1}")


def test_geometry_models(robot: SPMRobot) -> None:
    """One mesh per link, named after it, on the link's body (the platform on leg 1's)."""
    model = robot.model
    for geometry_model in (robot.visual_model, robot.collision_model):
        names = [g.name for g in geometry_model.geometryObjects]
        assert names == list(LINK_NAMES)
        for geometry in geometry_model.geometryObjects:
            frame = robot.link_frames[geometry.name]
            assert geometry.parentFrame == frame
            assert geometry.parentJoint == model.frames[frame].parentJoint
            assert geometry.placement.isIdentity()
            shape = geometry.geometry
            assert shape.num_tris > 0
            assert shape.num_vertices > 0
    platform = robot.collision_model.getGeometryId("platform")
    assert robot.collision_model.geometryObjects[platform].parentJoint == model.getJointId("v_1")


# --------------------------------------------------------- configuration
@pytest.mark.parametrize("name", MODEL_DESIGNS)
def test_configuration_matches_forward_kinematics(name: str) -> None:
    """Platform axes oMf.rotation @ v_i0 at configuration(theta) equal fk.v; the inputs
    are the actuated joint positions; the three legs hold the same platform."""
    robot = get_robot(name)
    design = robot.design
    rng = np.random.default_rng(20 + MODEL_DESIGNS.index(name))
    thetas = np.concatenate(
        [np.radians([[60.0, 90.0, 120.0]]), reachable_inputs(design, rng, SAMPLES)]
    )
    thetas = thetas[spm.forward_kinematics(thetas, design).reachable]
    fk = spm.forward_kinematics(thetas, design)
    assert np.all(fk.reachable)
    for theta, R, v in zip(thetas, fk.R, fk.v, strict=True):
        q = robot.configuration(theta)
        np.testing.assert_array_equal(q[robot.actuated_q_idx], theta)
        placements = robot.placements(q)
        platform = placements["platform"]
        axes = (platform.rotation @ design.v0.T).T
        np.testing.assert_allclose(axes, v, atol=TOL["axes"])
        np.testing.assert_allclose(platform.rotation, R, atol=TOL["axes"])
        np.testing.assert_allclose(platform.translation, 0.0, atol=TOL["closure"])
        for end in END_BODIES[1:]:
            np.testing.assert_allclose(
                placements[end].homogeneous, platform.homogeneous, atol=TOL["closure"]
            )
        assert robot.closure_residual(q) <= TOL["closure"]
        np.testing.assert_array_less(np.abs(q[robot.passive_q_idx]), math.pi + 1e-15)


def test_configuration_batch_equals_single(robot: SPMRobot) -> None:
    rng = np.random.default_rng(3)
    thetas = reachable_inputs(robot.design, rng, 12).reshape(3, 4, 3)
    q = robot.configuration(thetas)
    assert q.shape == (3, 4, 9)
    for index in np.ndindex(3, 4):
        np.testing.assert_allclose(q[index], robot.configuration(thetas[index]), atol=TOL["axes"])
    residual = robot.closure_residual(q)
    assert isinstance(residual, np.ndarray)
    assert residual.shape == (3, 4)
    np.testing.assert_array_less(residual, TOL["closure"])


def test_whole_turns_of_the_inputs(robot: SPMRobot) -> None:
    """Whole turns of an input stay in q_ui; the passive joints and the pose do not change."""
    theta = np.radians([20.0, -35.0, 50.0])
    turns = theta + 2 * np.pi * np.array([1.0, -2.0, 3.0])
    q, q_turns = robot.configuration(theta), robot.configuration(turns)
    np.testing.assert_array_equal(q_turns[robot.actuated_q_idx], turns)
    np.testing.assert_allclose(
        wrap(q_turns[robot.passive_q_idx] - q[robot.passive_q_idx]), 0.0, atol=1e-10
    )


def test_configuration_is_smooth(robot: SPMRobot) -> None:
    """Central differences of configuration(theta) along theta_dot keep the loops closed
    to first order: the constraint Jacobian annihilates them."""
    rng = np.random.default_rng(5)
    h = TOL["fd_step"]
    for theta in reachable_inputs(robot.design, rng, 10):
        theta_dot = rng.normal(size=3)
        q_dot = wrap(
            robot.configuration(theta + h * theta_dot) - robot.configuration(theta - h * theta_dot)
        ) / (2 * h)
        G = robot.constraint_jacobian(robot.configuration(theta))
        np.testing.assert_allclose(G @ q_dot, 0.0, atol=TOL["fd"])


def test_other_assembly_modes() -> None:
    """mode='<label>' builds the closed configuration of that assembly mode."""
    robot = get_robot("prototype")
    theta = np.radians([60.0, 90.0, 120.0])
    every = spm.forward_kinematics_all(theta, robot.design)
    labels = every.labels
    assert isinstance(labels, list)
    for slot, label in enumerate(labels):
        if not every.valid[slot]:
            continue
        q = robot.configuration(theta, mode=str(label))
        assert robot.closure_residual(q) <= TOL["closure"]
        platform = robot.placement(q, "platform").rotation
        if labels.count(label) == 1:
            np.testing.assert_allclose(platform, every.R[slot], atol=TOL["axes"])
    home = every.home_index
    np.testing.assert_allclose(
        robot.configuration(theta, mode=str(labels[int(home)])),
        robot.configuration(theta),
        atol=TOL["axes"],
    )


# ------------------------------------------------------------- constraints
def test_constraint_models(robot: SPMRobot) -> None:
    model = robot.model
    assert isinstance(robot.constraint_models, pin.StdVec_ConstraintModel)
    assert isinstance(robot.constraint_datas, pin.StdVec_ConstraintData)
    assert len(robot.constraint_models) == len(robot.constraint_datas) == 2
    for leg, (constraint, name) in enumerate(
        zip(robot.constraint_models, CONSTRAINT_NAMES, strict=True)
    ):
        weld = constraint.extract()
        assert isinstance(weld, pin.FrameAnchorConstraintModel)
        assert constraint.name == weld.name == name
        assert weld.joint1_id == model.getJointId(f"v_{leg + 2}")
        assert weld.joint2_id == model.getJointId("v_1")
        assert weld.joint1_placement.isIdentity()
        assert weld.joint2_placement.isIdentity()
        assert constraint.residualSize() == 6


def test_constraint_jacobian_annihilates_analytic_velocities() -> None:
    """With omega = J theta_dot (spm.jacobian), the passive rates solving
    u_i theta_dot_i + w_i psi_dot_i + v_i chi_dot_i = omega make a velocity v that
    pin's constraint Jacobian maps to zero, and Pinocchio's platform angular velocity
    is omega for each of the three legs."""
    for name in ("prototype", "agile_eye"):
        robot = get_robot(name)
        design = robot.design
        model, data = robot.model, robot.model.createData()
        rng = np.random.default_rng(11)
        for theta in reachable_inputs(design, rng, 10):
            jac = spm.jacobian(theta, design)
            fk = spm.forward_kinematics(theta, design)
            theta_dot = rng.normal(size=3)
            omega = jac.J @ theta_dot
            v = np.zeros(9)
            for leg in range(3):
                axes = np.stack([fk.w[leg], fk.v[leg]], axis=1)
                rhs = omega - design.u[leg] * theta_dot[leg]
                rates, *_ = np.linalg.lstsq(axes, rhs, rcond=None)
                np.testing.assert_allclose(axes @ rates, rhs, atol=TOL["velocity"])
                v[3 * leg : 3 * leg + 3] = [theta_dot[leg], *rates]
            q = robot.configuration(theta)
            pin.computeJointJacobians(model, data, q)
            cds = pin.StdVec_ConstraintData([cm.createData() for cm in robot.constraint_models])
            for cm, cd in zip(robot.constraint_models, cds, strict=True):
                cm.calc(model, data, cd)
            G = pin.getConstraintsJacobian(model, data, robot.constraint_models, cds)
            assert G.shape == (12, 9)
            assert np.linalg.matrix_rank(G, tol=1e-9) == 6
            np.testing.assert_allclose(G @ v, 0.0, atol=TOL["velocity"])
            np.testing.assert_allclose(robot.constraint_jacobian(q), G, atol=0)
            pin.forwardKinematics(model, data, q, v)
            for frame in robot.end_frames:
                twist = pin.getFrameVelocity(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
                np.testing.assert_allclose(twist.angular, omega, atol=TOL["velocity"])
                np.testing.assert_allclose(twist.linear, 0.0, atol=TOL["velocity"])


def test_rigid_constraint_models_drive_constraint_dynamics(robot: SPMRobot) -> None:
    """Legacy welds: same joints; constraintDynamics gives the three leg ends one
    angular acceleration (the platform stays rigid)."""
    model, data = robot.model, robot.model.createData()
    rigid = robot.rigid_constraint_models()
    assert isinstance(rigid, pin.StdVec_RigidConstraintModel)
    for cm, constraint, name in zip(rigid, robot.constraint_models, CONSTRAINT_NAMES, strict=True):
        assert cm.type == pin.ContactType.CONTACT_6D
        assert cm.reference_frame == pin.ReferenceFrame.LOCAL
        assert cm.name == name
        assert cm.joint1_id == constraint.extract().joint1_id
        assert cm.joint2_id == constraint.extract().joint2_id
    datas = pin.StdVec_RigidConstraintData([cm.createData() for cm in rigid])
    theta = np.radians([60.0, 90.0, 120.0])
    q = robot.configuration(theta)
    G = robot.constraint_jacobian(q)
    # A velocity in the kernel of the constraint Jacobian with the given input rates.
    theta_dot = np.array([0.4, -0.3, 0.2])
    passive = robot.passive_q_idx
    actuated = robot.actuated_q_idx
    v = np.zeros(9)
    v[actuated] = theta_dot
    v[passive] = -np.linalg.lstsq(G[:, passive], G[:, actuated] @ theta_dot, rcond=None)[0]
    np.testing.assert_allclose(G @ v, 0.0, atol=TOL["velocity"])
    tau = np.zeros(9)
    tau[actuated] = [0.1, -0.2, 0.05]
    pin.initConstraintDynamics(model, data, rigid, datas)
    a = pin.constraintDynamics(
        model, data, q, v, tau, rigid, datas, pin.ProximalSettings(1e-12, 1e-8, 20)
    )
    assert np.all(np.isfinite(a))
    pin.forwardKinematics(model, data, q, v, a)
    accelerations = [
        pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED).angular
        for frame in robot.end_frames
    ]
    scale = max(1.0, float(np.abs(accelerations[0]).max()))
    for other in accelerations[1:]:
        np.testing.assert_allclose(other, accelerations[0], atol=1e-9 * scale)


# ------------------------------------------------------------------ masses
@pytest.mark.parametrize("name", MODEL_DESIGNS)
def test_masses_and_inertias_positive_definite(name: str) -> None:
    robot = get_robot(name)
    for index, inertia in enumerate(robot.model.inertias):
        assert inertia.mass > 0, robot.model.names[index]
        assert np.all(np.isfinite(inertia.inertia))
        np.testing.assert_allclose(inertia.inertia, inertia.inertia.T, atol=0)
        eigenvalues = np.linalg.eigvalsh(inertia.inertia)
        assert eigenvalues.min() > 0, (robot.model.names[index], eigenvalues)
        # Physical: each principal moment at most the sum of the other two.
        assert eigenvalues[2] <= eigenvalues[0] + eigenvalues[1] + 1e-12 * eigenvalues[2]
        # The 6x6 spatial inertia at the joint is positive definite too.
        assert np.linalg.eigvalsh(inertia.matrix()).min() > 0


def test_platform_split_in_thirds(robot: SPMRobot) -> None:
    inertias = [robot.model.inertias[robot.model.frames[f].parentJoint] for f in robot.end_frames]
    for other in inertias[1:]:
        np.testing.assert_allclose(other.matrix(), inertias[0].matrix(), atol=0)
    assert robot.link_masses["platform"] == pytest.approx(3 * inertias[0].mass, rel=1e-15)


def test_total_mass_is_plausible(robot: SPMRobot, record_property: Any) -> None:
    """Three 165 g servos plus PLA links: about a kilogram or two."""
    total = robot.total_mass
    record_property("prototype_total_mass_kg", total)
    print(f"prototype total mass: {total:.4f} kg, links: {robot.link_masses}")
    assert sum(robot.link_masses.values()) == pytest.approx(total, rel=1e-14)
    assert total == pytest.approx(sum(i.mass for i in robot.model.inertias), rel=1e-15)
    assert robot.link_masses["base"] > 3 * robot.design.dimensions.servo_mass
    assert PROTOTYPE_MASS_RANGE[0] < total < PROTOTYPE_MASS_RANGE[1]


# ---------------------------------------------------------------- exported
@pytest.fixture(scope="module", params=["prototype", "agile_eye"])
def exported(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> tuple[str, dict[str, Path]]:
    """The robot files of a design, written by spm_pin.model.export."""
    export = pytest.importorskip("spm_pin.model.export")
    name = str(request.param)
    paths = export.export(get_design(name), tmp_path_factory.mktemp(f"export_{name}"))
    return name, {key: Path(path) for key, path in paths.items()}


def _assert_same_inertia(read: Any, ours: Any) -> None:
    """Mass, centre of mass and rotational inertia agree to the files' precision."""
    tol = TOL["mass_file"]
    assert read.mass == pytest.approx(ours.mass, rel=tol)
    np.testing.assert_allclose(read.lever, ours.lever, rtol=tol, atol=tol * 1e-2)
    scale = float(np.abs(ours.inertia).max())
    np.testing.assert_allclose(read.inertia, ours.inertia, rtol=tol, atol=tol * scale)


def _file(paths: dict[str, Path], suffix: str) -> Path:
    found = [p for p in paths.values() if p.suffix == suffix]
    if not found:
        directory = next(iter(paths.values()))
        directory = directory if directory.is_dir() else directory.parent
        found = sorted(directory.glob(f"*{suffix}"))
    assert found, f"export wrote no {suffix} file: {paths}"
    return found[0]


def test_export_uses_the_model_names() -> None:
    export = pytest.importorskip("spm_pin.model.export")
    assert tuple(export.JOINT_NAMES) == JOINT_NAMES
    assert tuple(export.END_BODIES) == END_BODIES


def test_mjcf_model_is_the_same_robot(exported: tuple[str, dict[str, Path]]) -> None:
    """pin.buildModelAndConstraintsFromMJCF(spm.xml): same joints in the same order,
    every link frame at the same placement at random q, same masses and inertias,
    and the same two welds."""
    name, paths = exported
    robot = get_robot(name)
    ours = robot.model
    theirs, point_anchors, frame_anchors = pin.buildModelAndConstraintsFromMJCF(
        str(_file(paths, ".xml"))
    )
    assert tuple(theirs.names) == tuple(ours.names)
    assert (theirs.nq, theirs.nv) == (9, 9)
    for joint in range(1, ours.njoints):
        assert theirs.parents[joint] == ours.parents[joint]
        assert theirs.idx_qs[joint] == ours.idx_qs[joint]
    rng = np.random.default_rng(7)
    for q in [np.zeros(9), *rng.uniform(-np.pi, np.pi, size=(RANDOM_Q, 9))]:
        mine, read = _frame_placements(ours, q), _frame_placements(theirs, q)
        for body in (*LINK_NAMES, *END_BODIES[1:]):
            np.testing.assert_allclose(read[body], mine[body], atol=TOL["placement"], err_msg=body)
    for joint in range(ours.njoints):
        _assert_same_inertia(theirs.inertias[joint], ours.inertias[joint])
    assert len(point_anchors) == 0
    assert len(frame_anchors) == 2
    # The same welds, in the same order and direction (joint 1 the leg end, joint 2
    # the platform), so that constraint rows and signs agree too.
    welds = [(cm.joint1_id, cm.joint2_id) for cm in frame_anchors]
    expected = [(cm.extract().joint1_id, cm.extract().joint2_id) for cm in robot.constraint_models]
    assert welds == expected
    for cm in frame_anchors:
        assert cm.joint1_placement.isIdentity()
        assert cm.joint2_placement.isIdentity()
    q = robot.configuration(reachable_inputs(robot.design, rng, 1)[0])
    data = theirs.createData()
    pin.framesForwardKinematics(theirs, data, q)
    for cm in frame_anchors:
        c1 = data.oMi[cm.joint1_id] * cm.joint1_placement
        c2 = data.oMi[cm.joint2_id] * cm.joint2_placement
        np.testing.assert_allclose(pin.log6(c1.actInv(c2)).vector, 0.0, atol=TOL["closure"])
    # Their constraint Jacobian is ours.
    cms = pin.StdVec_ConstraintModel([pin.ConstraintModel(cm) for cm in frame_anchors])
    cds = pin.StdVec_ConstraintData([cm.createData() for cm in cms])
    pin.computeJointJacobians(theirs, data, q)
    for cm, cd in zip(cms, cds, strict=True):
        cm.calc(theirs, data, cd)
    G = pin.getConstraintsJacobian(theirs, data, cms, cds)
    np.testing.assert_allclose(G, robot.constraint_jacobian(q), atol=TOL["placement"])


def test_mujoco_welds_hold_at_configuration(exported: tuple[str, dict[str, Path]]) -> None:
    """MuJoCo loads spm.xml; its qpos order is ours; with qpos = configuration(theta),
    the welded bodies have identical poses and the equality residuals vanish."""
    mujoco = pytest.importorskip("mujoco")
    name, paths = exported
    robot = get_robot(name)
    model = mujoco.MjModel.from_xml_path(str(_file(paths, ".xml")))
    assert model.nq == model.nv == 9
    names = tuple(model.joint(i).name for i in range(model.njnt))
    assert names == JOINT_NAMES
    np.testing.assert_array_equal(model.jnt_qposadr, np.arange(9))
    assert model.neq == 2
    assert {model.equality(i).name for i in range(2)} == set(CONSTRAINT_NAMES)
    np.testing.assert_array_equal(model.eq_type, mujoco.mjtEq.mjEQ_WELD)
    bodies = [model.body(body).id for body in END_BODIES]
    data = mujoco.MjData(model)
    rng = np.random.default_rng(17)
    for theta in reachable_inputs(robot.design, rng, 20):
        q = robot.configuration(theta)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        platform = robot.placement(q, "platform")
        np.testing.assert_allclose(
            data.xmat[bodies[0]].reshape(3, 3), platform.rotation, atol=TOL["mujoco"]
        )
        for body in bodies[1:]:
            np.testing.assert_allclose(data.xpos[body], data.xpos[bodies[0]], atol=TOL["mujoco"])
            np.testing.assert_allclose(data.xmat[body], data.xmat[bodies[0]], atol=TOL["mujoco"])
            same = min(
                np.abs(data.xquat[body] - data.xquat[bodies[0]]).max(),
                np.abs(data.xquat[body] + data.xquat[bodies[0]]).max(),
            )
            assert same <= TOL["mujoco"]
        for link in LINK_NAMES:
            pose = robot.placement(q, link)
            body = model.body(link).id
            np.testing.assert_allclose(data.xpos[body], pose.translation, atol=TOL["mujoco"])
            np.testing.assert_allclose(
                data.xmat[body].reshape(3, 3), pose.rotation, atol=TOL["mujoco"]
            )
        mujoco.mj_fwdPosition(model, data)
        equality = data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        assert np.count_nonzero(equality) == 12
        np.testing.assert_allclose(data.efc_pos[: data.nefc][equality], 0.0, atol=TOL["mujoco"])


def test_urdf_loads_with_pinocchio(exported: tuple[str, dict[str, Path]]) -> None:
    """pin.buildModelFromUrdf reads the open tree: same joints, nv = 9, and the same
    link placements at random joint angles."""
    name, paths = exported
    robot = get_robot(name)
    model = pin.buildModelFromUrdf(str(_file(paths, ".urdf")))
    assert tuple(model.names)[1:] == JOINT_NAMES
    assert model.nv == 9
    rng = np.random.default_rng(9)
    for angles in rng.uniform(-np.pi, np.pi, size=(RANDOM_Q, 9)):
        q = np.concatenate(
            [
                [angles[k]]
                if model.joints[k + 1].nq == 1
                else [np.cos(angles[k]), np.sin(angles[k])]
                for k in range(9)
            ]
        )
        read = _frame_placements(model, q)
        mine = _frame_placements(robot.model, angles)
        for body in (*LINK_NAMES, *END_BODIES[1:]):
            np.testing.assert_allclose(read[body], mine[body], atol=TOL["placement"], err_msg=body)
    for joint in range(robot.model.njoints):
        _assert_same_inertia(model.inertias[joint], robot.model.inertias[joint])


# --------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "theta",
    [
        [0.1, 0.2],
        [[0.1, 0.2, 0.3, 0.4]],
        [0.1, np.nan, 0.3],
        [np.inf, 0.0, 0.0],
        "abc",
        0.5,
        [[0.1, 0.2, None]],
    ],
    ids=["short", "four", "nan", "inf", "string", "scalar", "none"],
)
def test_bad_theta(robot: SPMRobot, theta: Any) -> None:
    with pytest.raises(spm.InputError, match="theta"):
        robot.configuration(theta)


@pytest.mark.parametrize("mode", ["elbow", "+++", "++/-+", 3, None])
def test_bad_mode(robot: SPMRobot, mode: Any) -> None:
    with pytest.raises(spm.InputError, match="mode"):
        robot.configuration(np.zeros(3), mode=mode)


def test_unreachable(robot: SPMRobot) -> None:
    """An input without a home-mode assembly raises UnreachableError (also in a batch)."""
    rng = np.random.default_rng(1)
    thetas = rng.uniform(-np.pi, np.pi, size=(200, 3))
    reachable = spm.forward_kinematics(thetas, robot.design).reachable
    assert not np.all(reachable)
    bad = thetas[~reachable][0]
    with pytest.raises(spm.UnreachableError, match="no assembly") as info:
        robot.configuration(bad)
    assert isinstance(info.value, spm.SPMError)
    with pytest.raises(spm.UnreachableError, match="reachable"):
        robot.configuration(thetas)
    missing = next(
        label
        for label in ("+++/+", "+++/-", "---/+", "---/-", "+-+/+", "-+-/-")
        if label not in spm.forward_kinematics_all(np.zeros(3), robot.design).labels
    )
    match = rf"theta = \[0\.0, 0\.0, 0\.0\] deg has no assembly in mode '{re.escape(missing)}'"
    with pytest.raises(spm.UnreachableError, match=match):
        robot.configuration(np.zeros(3), mode=missing)


@pytest.mark.parametrize(
    "q",
    [np.zeros(8), np.zeros((2, 10)), [0.0] * 8 + [np.nan], "q", np.zeros(0)],
    ids=["short", "long", "nan", "string", "empty"],
)
def test_bad_q(robot: SPMRobot, q: Any) -> None:
    with pytest.raises(spm.InputError, match="q"):
        robot.closure_residual(q)
    with pytest.raises(spm.InputError, match="q"):
        robot.placement(q, "platform")


def test_single_q_only_where_one_is_needed(robot: SPMRobot) -> None:
    with pytest.raises(spm.InputError, match=r"\(9,\)"):
        robot.placement(np.zeros((2, 9)), "platform")
    with pytest.raises(spm.InputError, match=r"\(9,\)"):
        robot.constraint_jacobian(np.zeros((2, 9)))


@pytest.mark.parametrize("mode", ["home", "+++/-"])
def test_bad_reference(robot: SPMRobot, mode: str) -> None:
    with pytest.raises(spm.InputError, match="reference"):
        robot.configuration(np.zeros(3), mode, reference=np.ones((3, 3)))
    with pytest.raises(spm.InputError, match="reference"):
        robot.configuration(np.zeros((2, 3)), mode, reference=np.stack([np.eye(3)] * 3))


def test_bad_link(robot: SPMRobot) -> None:
    with pytest.raises(spm.InputError, match="proximal_1") as info:
        robot.placement(np.zeros(9), "proximal_4")
    assert info.value.argument == "link"


def test_bad_design() -> None:
    with pytest.raises(spm.InputError, match="design"):
        spm.build_robot(42)  # type: ignore[arg-type]
    with pytest.raises(spm.InputError, match="agile_eye"):  # not a preset, not a file
        spm.build_robot("nope")


@given(
    theta=st.lists(st.floats(min_value=-4 * math.pi, max_value=4 * math.pi), min_size=3, max_size=3)
)
def test_any_input_closes_or_is_unreachable(theta: list[float]) -> None:
    robot = get_robot("prototype")
    try:
        q = robot.configuration(theta)
    except spm.UnreachableError:
        assert not spm.forward_kinematics(theta, robot.design).reachable
        return
    assert robot.closure_residual(q) <= TOL["closure"]
    np.testing.assert_array_equal(q[robot.actuated_q_idx], theta)


def test_the_robot_receives_its_collision_checker() -> None:
    """spm.build_robot gives the robot the collision layer's checker; the model layer
    alone builds a robot without one, which says how to get one."""
    from spm_pin.collision import CollisionChecker, checker_of
    from spm_pin.model.robot import build_robot as build_model

    robot = spm.build_robot()
    assert isinstance(robot.collision_checker, CollisionChecker)
    assert robot.collision_checker is robot.collision_checker  # made once, kept
    bare = build_model()
    with pytest.raises(spm.InputError, match=r"no self-collision checker: build it with spm\."):
        bare.collisions(np.zeros(3))
    theta = np.radians([0.0, 0.0, 80.0])  # proximal links 2 and 3 meet
    assert checker_of(bare).collisions(theta) == robot.collisions(theta)
    assert bare.collisions(theta) == robot.collisions(theta)  # kept on the robot now
    with pytest.raises(spm.InputError, match="checker_factory must be callable"):
        build_model(checker_factory=42)  # type: ignore[arg-type]
