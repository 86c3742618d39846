"""The one rule for the assembly mode (spm.select_assembly) and the unique mode labels."""

from __future__ import annotations

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.collision import check_input
from spm_pin.kinematics.assembly import home_mode_label

TOL = {
    "rotation": 1e-12,  # |R - R'| between two routes to the same solution
}
STUDY_DEG = [60.0, 90.0, 120.0]
STUDY_COLLIDING_DEG = [60.0, 90.0, 220.0]
#: A design and input with no real assembly mode at all.
NO_ASSEMBLY_DESIGN = spm.SPMDesign.coaxial(50.0, 75.0, 100.0)
NO_ASSEMBLY_DEG = [81.3, -148.4, -37.8]


def _expected_choice(theta: np.ndarray, design: spm.SPMDesign) -> tuple[str, np.ndarray] | None:
    """The rule written out from forward_kinematics_all: the home mode, else the fewest
    signs differing from home, then the smallest tilt, then slot order."""
    every = spm.forward_kinematics_all(theta, design)
    count = int(every.count)
    if count == 0:
        return None
    home_sign = np.sign(design.home_det_a)
    keys = []
    for k in range(count):
        if every.home[k]:
            return str(every.labels[k]), every.R[k]
        differing = int(np.sum(every.b[k] <= 0)) + int(np.sign(every.det_a[k]) != home_sign)
        keys.append((differing, round(-float(every.R[k, 2, 2]), 9), k))
    k = min(keys)[2]
    return str(every.labels[k]), every.R[k]


def test_home_mode_where_it_exists() -> None:
    theta = np.radians(STUDY_DEG)
    chosen = spm.select_assembly(theta)
    fk = spm.forward_kinematics(theta)
    assert chosen.home and chosen.exists and chosen.label == "+++/-"
    np.testing.assert_allclose(chosen.R, fk.R, atol=TOL["rotation"])
    assert chosen.description == "home assembly mode +++/-"


@pytest.mark.parametrize("name", ["prototype", "agile_eye", "coaxial"])
def test_rule_against_all_modes(name: str) -> None:
    design = {
        "prototype": spm.SPMDesign.prototype(),
        "agile_eye": spm.SPMDesign.agile_eye(),
        "coaxial": spm.SPMDesign.coaxial(50.0, 75.0, 100.0),
    }[name]
    rng = np.random.default_rng(7)
    theta = rng.uniform(-np.pi, np.pi, size=(150, 3))
    chosen = spm.select_assembly(theta, design)
    assert chosen.R.shape == (150, 3, 3)
    assert np.any(~chosen.home), "the sample should hold inputs without a home mode"
    for i in range(theta.shape[0]):
        expected = _expected_choice(theta[i], design)
        if expected is None:
            assert not chosen.exists[i] and chosen.label[i] == ""  # type: ignore[index]
            assert np.all(np.isnan(chosen.R[i]))
            continue
        label, R = expected
        assert chosen.exists[i]
        assert chosen.label[i] == label  # type: ignore[index]
        np.testing.assert_allclose(chosen.R[i], R, atol=1e-9)
        single = spm.select_assembly(theta[i], design)
        assert single.label == label and bool(single.home) == bool(chosen.home[i])


def test_no_real_assembly() -> None:
    theta = np.radians(NO_ASSEMBLY_DEG)
    assert spm.forward_kinematics_all(theta, NO_ASSEMBLY_DESIGN).count == 0
    chosen = spm.select_assembly(theta, NO_ASSEMBLY_DESIGN)
    assert not chosen.exists and not chosen.home and chosen.label == ""
    assert np.all(np.isnan(chosen.R))
    assert chosen.description == "no real assembly mode"
    robot = spm.build_robot(NO_ASSEMBLY_DESIGN)
    with pytest.raises(spm.UnreachableError, match="has no assembly in mode 'nearest'"):
        robot.configuration(theta, "nearest")


def test_study_colliding_input_everywhere_the_same_mode() -> None:
    theta = np.radians(STUDY_COLLIDING_DEG)
    chosen = spm.select_assembly(theta)
    assert not chosen.home and chosen.exists
    assert "nearest" in chosen.description and str(chosen.label) in chosen.description
    robot = spm.build_robot()
    report = check_input(theta, robot)
    assert report.mode == chosen.label and report.home is False
    q = robot.configuration(theta, "nearest")
    np.testing.assert_array_equal(q, robot.configuration(theta, str(chosen.label)))
    np.testing.assert_allclose(robot.placement(q, "platform").rotation, chosen.R, atol=1e-12)
    assert set(report.pairs) == set(robot.collisions(q))


def test_every_unique_label_selects_its_own_mode() -> None:
    """configuration(theta, label) places the platform of exactly that slot, "#k"
    labels included."""
    theta = np.radians(STUDY_DEG)
    every = spm.forward_kinematics_all(theta)
    labels = [str(x) for x in every.labels[: int(every.count)]]
    assert len(set(labels)) == len(labels) == 8
    assert any("#" in label for label in labels)
    robot = spm.build_robot()
    for k, label in enumerate(labels):
        q = robot.configuration(theta, label)
        np.testing.assert_allclose(robot.placement(q, "platform").rotation, every.R[k], atol=1e-10)


@pytest.mark.parametrize("mode", ["+++/-#1", "+++/-#0", "+++/-#", "+++/-#x", "+++/-2", "near"])
def test_bad_mode_labels(mode: str) -> None:
    robot = spm.build_robot()
    with pytest.raises(spm.InputError, match="mode"):
        robot.configuration(np.zeros(3), mode)


def test_home_label_of_designs() -> None:
    for design in (spm.SPMDesign.prototype(), spm.SPMDesign.agile_eye()):
        every = spm.forward_kinematics_all(np.zeros(3), design)
        assert every.labels[int(every.home_index)] == home_mode_label(design)
