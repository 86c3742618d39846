"""Following one assembly mode along a path: the published motion, endless rotation
with unwrapped yaw, leaving the workspace, other starting modes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import get_design, loop_residual, rot_z

import spm_pin as spm

#: Tolerances of this module.
TOL = {
    # Tracked R vs forward_kinematics [max |R - R'|].
    "rotation": 1e-10,
    # Loop closure of tracked solutions.
    "closure": 1e-11,
    # Unwrapped yaw vs the expected angle [rad].
    "yaw": 1e-9,
    # Largest change of R between successive samples of a smooth path [max entry].
    "continuity": 0.25,
}

PAPER_THETA = np.radians([60.0, 90.0, 120.0])


def _line(start: np.ndarray, end: np.ndarray, n: int) -> np.ndarray:
    return start + np.linspace(0.0, 1.0, n)[:, None] * (end - start)


def _yaw(R: np.ndarray) -> np.ndarray:
    return np.arctan2(R[..., 1, 0], R[..., 0, 0])


def test_published_motion_stays_home(prototype: spm.SPMDesign) -> None:
    """Home to theta = [60, 90, 120] deg in 25 samples, as in the published study."""
    path = _line(np.zeros(3), PAPER_THETA, 25)
    result = spm.track(path, prototype)
    fk = spm.forward_kinematics(path, prototype)
    assert np.all(fk.reachable)
    assert np.all(result.home)
    assert not np.any(result.lost)
    assert result.labels == ["+++/-"] * 25
    np.testing.assert_array_equal(result.theta, path)
    np.testing.assert_allclose(result.R, fk.R, atol=TOL["rotation"])
    np.testing.assert_allclose(result.v, fk.v, atol=TOL["rotation"])
    np.testing.assert_allclose(result.R[0], np.eye(3), atol=1e-14)
    # The yaw is the platform's heading; over this short path it needs no unwrapping.
    np.testing.assert_allclose(result.yaw, _yaw(fk.R), atol=TOL["yaw"])


@pytest.mark.parametrize("offsets_deg", [(0.0, 0.0, 0.0), (10.0, -20.0, 5.0), (30.0, 0.0, -40.0)])
def test_endless_rotation_unwraps_the_yaw(
    prototype: spm.SPMDesign, offsets_deg: tuple[float, float, float]
) -> None:
    """Common rotation 0 -> 4 pi plus fixed offsets: yaw = -(common turn) + const,
    monotone, -720 deg in total."""
    offsets = np.radians(offsets_deg)
    common = np.linspace(0.0, 4 * np.pi, 181)
    path = common[:, None] + offsets
    result = spm.track(path, prototype)
    assert np.all(result.home) and not np.any(result.lost)
    np.testing.assert_allclose(result.yaw + common, result.yaw[0], atol=TOL["yaw"])
    assert np.all(np.diff(result.yaw) < 0)
    np.testing.assert_allclose(result.yaw[-1] - result.yaw[0], -4 * np.pi, atol=TOL["yaw"])
    # Each sample is the home mode, turned about z.
    start = spm.forward_kinematics(offsets, prototype).R
    expected = np.stack([rot_z(-c) @ start for c in common])
    np.testing.assert_allclose(result.R, expected, atol=TOL["rotation"])


def test_endless_rotation_with_a_wobble(prototype: spm.SPMDesign) -> None:
    """The gaps between the links wobble while the inputs turn twice: the yaw still
    ends 720 deg lower and every sample agrees with forward_kinematics."""
    s = np.linspace(0.0, 4 * np.pi, 241)
    wobble = 0.3 * np.sin(3 * s)[:, None] * np.array([1.0, -1.0, 0.0])
    path = s[:, None] + np.radians([10.0, -20.0, 5.0]) + wobble
    result = spm.track(path, prototype)
    fk = spm.forward_kinematics(path, prototype)
    assert np.all(fk.reachable) and np.all(result.home)
    np.testing.assert_allclose(result.R, fk.R, atol=TOL["rotation"])
    np.testing.assert_allclose(result.yaw[-1] - result.yaw[0], -4 * np.pi, atol=TOL["yaw"])
    np.testing.assert_allclose(
        np.mod(result.yaw - _yaw(fk.R) + np.pi, 2 * np.pi), np.pi, atol=TOL["yaw"]
    )
    assert np.max(np.abs(np.diff(result.yaw))) < 0.5


def test_leaving_the_workspace_is_reported(prototype: spm.SPMDesign) -> None:
    """One actuator alone from home to 200 deg: past about 107 deg the home mode ends
    (type I), and the tracked samples are no longer home."""
    path = _line(np.zeros(3), np.radians([0.0, 0.0, 200.0]), 41)
    result = spm.track(path, prototype)
    reachable = spm.forward_kinematics(path, prototype).reachable
    assert not np.all(result.home | result.lost), "leaving the workspace went unnoticed"
    first_out = int(np.argmin(reachable))
    assert 100.0 < math.degrees(path[first_out, 2]) < 115.0
    np.testing.assert_array_equal(result.home[:first_out], True)
    np.testing.assert_array_equal(result.home[first_out:] & ~result.lost[first_out:], False)
    # Where still followed, the samples are genuine, continuous assembly modes.
    kept = ~result.lost
    np.testing.assert_array_less(
        loop_residual(prototype, path[kept], result.R[kept]), TOL["closure"]
    )
    assert np.abs(np.diff(result.R[kept], axis=0)).max() < TOL["continuity"]


def test_a_vanishing_mode_is_lost() -> None:
    """General design: along this path the home mode ceases to exist; tracking reports
    the samples from there on as lost, with NaN rotations and empty labels."""
    design = get_design("general")
    path = _line(np.zeros(3), np.array([1.0, -0.5, 0.8]), 50)
    result = spm.track(path, design)
    assert np.any(result.lost)
    first = int(np.argmax(result.lost))
    assert first > 0
    np.testing.assert_array_equal(result.lost[first:], True)
    assert np.all(np.isnan(result.R[first:]))
    assert np.all(np.isnan(result.yaw[first:]))
    assert all(label == "" for label in result.labels[first:])
    assert not np.any(result.home[first:])
    np.testing.assert_array_less(
        loop_residual(design, path[:first], result.R[:first]), TOL["closure"]
    )


@pytest.mark.parametrize("mode", range(8))
def test_any_starting_mode_is_followed_continuously(prototype: spm.SPMDesign, mode: int) -> None:
    """Start in each of the 8 assembly modes at home; the motion is continuous, every
    sample closes the loops, and tracking the path backwards returns to the start."""
    path = _line(np.zeros(3), PAPER_THETA, 25)
    first = spm.forward_kinematics_all(path[0], prototype)
    assert first.count == 8
    start = first.R[mode]
    result = spm.track(path, prototype, start=start)
    assert not np.any(result.lost)
    np.testing.assert_allclose(result.R[0], start, atol=1e-14)
    np.testing.assert_array_less(loop_residual(prototype, path, result.R), TOL["closure"])
    assert np.abs(np.diff(result.R, axis=0)).max() < TOL["continuity"]
    back = spm.track(path[::-1], prototype, start=result.R[-1])
    np.testing.assert_allclose(back.R[::-1], result.R, atol=TOL["rotation"])
    assert result.home[0] == (mode == 0)


def test_single_sample(prototype: spm.SPMDesign) -> None:
    result = spm.track(PAPER_THETA[None], prototype)
    assert result.R.shape == (1, 3, 3)
    np.testing.assert_allclose(
        result.R[0], spm.forward_kinematics(PAPER_THETA, prototype).R, atol=TOL["rotation"]
    )
    assert result.labels == ["+++/-"] and result.subdivisions == 0


def test_unreachable_first_sample(prototype: spm.SPMDesign) -> None:
    path = _line(np.radians([0.0, 0.0, 200.0]), np.zeros(3), 5)
    match = r"no home-mode assembly at the first sample, .*; pass start= to follow another mode"
    with pytest.raises(spm.UnreachableError, match=match):
        spm.track(path, prototype)
    # With an explicit start, a non-home mode is followed instead.
    every = spm.forward_kinematics_all(path[0], prototype)
    result = spm.track(path, prototype, start=every.R[0])
    assert not result.home[0]
    np.testing.assert_allclose(result.R[0], every.R[0], atol=1e-14)
