"""The variables and objectives of a design study (spm_pin.optimize.objectives).

The global conditioning index is recomputed from the safe points' input angles with
the batch kinematics; the cone's worst dexterity from the inputs solved for each
orientation, round-tripped through forward kinematics; the free yaw is checked by
turning the platform about the axis.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.errors import InputError
from spm_pin.optimize import (
    DesignSpace,
    Variable,
    cone_dexterity,
    envelope,
    global_conditioning_index,
    home_clearance,
    safe_workspace_score,
)
from spm_pin.optimize.objectives import tilt_rotations
from spm_pin.workspace.gaps import gap_inputs, tilt_torsion


def test_a_design_space_builds_designs_and_reads_them_back() -> None:
    space = DesignSpace(
        (
            Variable("alpha1_deg", 30.0, 80.0),
            Variable("beta_deg", 45.0, 120.0),
            Variable("distal_radius", 0.08, 0.12),
        )
    )
    prototype = spm.SPMDesign.prototype()
    same = space.design(space.values_of(prototype))
    assert (same.alpha1, same.alpha2, same.beta) == (
        prototype.alpha1,
        prototype.alpha2,
        prototype.beta,
    )
    assert same.dimensions == prototype.dimensions
    values = {"alpha1_deg": 50.0, "beta_deg": 100.0, "distal_radius": 0.1}
    design = space.design(values)
    assert space.values_of(design) == pytest.approx(values, abs=1e-12)
    assert design.alpha2 == prototype.alpha2  # not a variable: the base's
    assert design.dimensions.distal_radius == 0.1


@pytest.mark.parametrize(
    "values",
    [
        {"alpha1_deg": 90.0, "beta_deg": 90.0},  # out of bounds
        {"alpha1_deg": math.nan, "beta_deg": 90.0},
        {"alpha1_deg": 45.0},  # missing
        {"alpha1_deg": True, "beta_deg": 90.0},  # not a number
        {"alpha1_deg": 45.0, "beta_deg": 90.0, "alpha2_deg": 90.0},  # not a variable
    ],
)
def test_bad_values_are_input_errors(values: dict[str, float]) -> None:
    space = DesignSpace((Variable("alpha1_deg", 30.0, 80.0), Variable("beta_deg", 45.0, 120.0)))
    with pytest.raises(InputError):
        space.design(values)


@pytest.mark.parametrize(
    ("name", "low", "high"),
    [("gamma_deg", 0.0, 1.0), ("beta_deg", 2.0, 1.0), ("beta_deg", 0.0, math.inf)],
)
def test_bad_variables_are_input_errors(name: str, low: float, high: float) -> None:
    with pytest.raises(InputError):
        Variable(name, low, high)
    with pytest.raises(InputError):
        DesignSpace((Variable("beta_deg", 0.0, 1.0), Variable("beta_deg", 0.0, 2.0)))


def test_the_global_conditioning_index_is_the_mean_dexterity_of_the_safe_points() -> None:
    score = safe_workspace_score("prototype", step_deg=6.0)
    gci = global_conditioning_index(score)
    theta = gap_inputs(score.d12_deg[score.safe], score.d23_deg[score.safe], "prototype")
    fk = spm.forward_kinematics(theta)
    assert np.all(fk.reachable)
    truth = float(np.mean(spm.jacobian(theta, R=fk.R).dexterity))
    assert gci is not None and gci == pytest.approx(truth, rel=1e-12)
    assert 0.0 < gci < 1.0


def test_the_cone_dexterity_is_the_worst_over_the_cone_and_free_in_yaw() -> None:
    cone = cone_dexterity("prototype", 30.0, step_deg=5.0)
    assert cone.samples == 7 * 72 and cone.reachable_fraction == 1.0
    # Independent recomputation: the inputs of every orientation, forward kinematics
    # back to the orientation, and the Jacobian from the inputs alone.
    tilts = np.linspace(0.0, 30.0, 7)
    T, A = np.meshgrid(tilts, np.arange(0.0, 360.0, 5.0), indexing="ij")
    R = tilt_rotations(T.ravel(), A.ravel())
    tilt, azimuth, torsion = tilt_torsion(R)
    np.testing.assert_allclose(np.degrees(tilt), T.ravel(), atol=1e-9)
    tilted = T.ravel() > 0
    wrapped = np.degrees(azimuth[tilted]) - A.ravel()[tilted]
    np.testing.assert_allclose((wrapped + 180.0) % 360.0 - 180.0, 0.0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(torsion), 0.0, atol=1e-9)
    theta = spm.inverse_kinematics(R).theta
    np.testing.assert_allclose(spm.forward_kinematics(theta).R, R, atol=1e-9)
    dexterity = spm.jacobian(theta).dexterity
    assert cone.worst_dexterity == pytest.approx(float(np.min(dexterity)), abs=1e-9)
    # Free yaw: turning the platform about the axis (all inputs together) keeps it.
    worst = tilt_rotations([cone.worst_tilt_deg], [cone.worst_azimuth_deg])[0]
    for yaw in np.radians([17.0, 120.0, -75.0]):
        c, s = math.cos(yaw), math.sin(yaw)
        turned = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ worst
        theta_turned = spm.inverse_kinematics(turned).theta
        assert spm.jacobian(theta_turned).dexterity == pytest.approx(cone.worst_dexterity, abs=1e-9)
    # A wider cone is never better; no cone is the home orientation's dexterity.
    assert cone_dexterity("prototype", 45.0, step_deg=5.0).worst_dexterity <= cone.worst_dexterity
    home = cone_dexterity("prototype", 0.0)
    assert home.worst_dexterity == pytest.approx(
        float(spm.jacobian(spm.inverse_kinematics(np.eye(3)).theta).dexterity), abs=1e-12
    )


@pytest.mark.parametrize(
    ("cone", "step"), [(-1.0, 2.0), (91.0, 2.0), (30.0, 0.0), (30.0, math.nan), (True, 2.0)]
)
def test_bad_cones_are_input_errors(cone: float, step: float) -> None:
    with pytest.raises(InputError):
        cone_dexterity("prototype", cone, step_deg=step)


def test_the_envelope_holds_every_moving_link_in_every_pose() -> None:
    from spm_pin.collision import checker_of

    robot = spm.build_robot()
    box = envelope(robot=robot)
    pieces = checker_of(robot).pieces
    rng = np.random.default_rng(5)
    reached = 0.0
    for theta in np.radians(rng.uniform(-60.0, 60.0, size=(6, 3))):
        if not spm.forward_kinematics(theta).reachable:
            continue
        placements = robot.placements(robot.configuration(theta))
        for piece in pieces:
            if piece.link == "base":
                continue
            frame = placements[piece.link]
            world = piece.vertices @ np.asarray(frame.rotation).T + np.asarray(frame.translation)
            reached = max(reached, float(np.max(np.linalg.norm(world, axis=1))))
    assert reached == pytest.approx(box.radius_m, abs=1e-12)  # the links turn about O
    base = np.vstack([p.vertices for p in pieces if p.link == "base"])
    assert box.height_m == pytest.approx(box.radius_m - float(np.min(base[:, 2])), abs=1e-12)
    assert box.base_radius_m == pytest.approx(float(np.max(np.hypot(base[:, 0], base[:, 1]))))


def test_the_home_clearance_is_the_smallest_link_distance_at_home() -> None:
    from spm_pin.collision import checker_of

    robot = spm.build_robot()
    distances = checker_of(robot).distances(robot.configuration(np.zeros(3)))
    assert home_clearance(robot=robot) == pytest.approx(min(distances.values()), abs=1e-12)
    assert 0.0 < home_clearance(robot=robot) < 0.002  # the nested drive tubes, 1 mm apart
