"""Rotation conversions against scipy.spatial.transform.Rotation, and round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import seeds
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

from spm_pin.rotations import (
    matrix_from_quaternion,
    matrix_from_rpy,
    quaternion_from_matrix,
    rpy_from_matrix,
)

#: Tolerances of this module.
TOL = {
    # Matrices and quaternions vs scipy [max abs entry].
    "matrix": 1e-14,
    "quaternion": 1e-14,
    # Angles recovered from matrices [rad], away from gimbal lock ...
    "angle": 1e-12,
    # ... kept at least this far from pitch = +-90 deg [rad].
    "gimbal_margin": 1e-3,
}

BATCH = 256


def _scipy_quaternion(rotation: Rotation) -> np.ndarray:
    """(w, x, y, z) with w >= 0 from scipy's scalar-last (x, y, z, w)."""
    xyzw = rotation.as_quat()
    wxyz = np.concatenate([xyzw[..., 3:], xyzw[..., :3]], axis=-1)
    return np.where(wxyz[..., :1] < 0, -wxyz, wxyz)


@settings(max_examples=30)
@given(seed=seeds)
def test_matrix_from_quaternion_matches_scipy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(BATCH, 4)) * rng.uniform(0.1, 10.0, size=(BATCH, 1))  # not unit
    expected = Rotation.from_quat(np.concatenate([q[:, 1:], q[:, :1]], axis=1)).as_matrix()
    np.testing.assert_allclose(matrix_from_quaternion(q), expected, atol=TOL["matrix"])
    # q and -q are the same rotation.
    np.testing.assert_allclose(matrix_from_quaternion(-q), expected, atol=TOL["matrix"])


@settings(max_examples=30)
@given(seed=seeds)
def test_quaternion_from_matrix_matches_scipy(seed: int) -> None:
    rotation = Rotation.random(BATCH, random_state=np.random.default_rng(seed))
    q = quaternion_from_matrix(rotation.as_matrix())
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=TOL["quaternion"])
    assert np.all(q[:, 0] >= 0)
    expected = _scipy_quaternion(rotation)
    # Where w = 0 the sign is free; compare up to sign there.
    sign = np.where(np.sum(q * expected, axis=-1) < 0, -1.0, 1.0)[:, None]
    np.testing.assert_allclose(q, sign * expected, atol=TOL["quaternion"])
    np.testing.assert_allclose(matrix_from_quaternion(q), rotation.as_matrix(), atol=1e-14)


@settings(max_examples=30)
@given(seed=seeds)
def test_matrix_from_rpy_matches_scipy(seed: int) -> None:
    """R = Rz(yaw) Ry(pitch) Rx(roll): scipy's extrinsic 'xyz' Euler angles."""
    rpy = np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, size=(BATCH, 3))
    expected = Rotation.from_euler("xyz", rpy).as_matrix()
    np.testing.assert_allclose(matrix_from_rpy(rpy), expected, atol=TOL["matrix"])


@settings(max_examples=30)
@given(seed=seeds)
def test_rpy_round_trip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    limit = np.pi / 2 - TOL["gimbal_margin"]
    rpy = np.stack(
        [
            rng.uniform(-np.pi, np.pi, BATCH),
            rng.uniform(-limit, limit, BATCH),
            rng.uniform(-np.pi, np.pi, BATCH),
        ],
        axis=-1,
    )
    back = rpy_from_matrix(matrix_from_rpy(rpy))
    np.testing.assert_allclose(back, rpy, atol=TOL["angle"])
    expected = Rotation.from_euler("xyz", rpy).as_euler("xyz")
    np.testing.assert_allclose(back, expected, atol=TOL["angle"])
    # And any rotation comes back as itself (even at gimbal lock, through the matrix).
    R = Rotation.random(BATCH, random_state=rng).as_matrix()
    np.testing.assert_allclose(matrix_from_rpy(rpy_from_matrix(R)), R, atol=1e-13)
    assert np.all(np.abs(rpy_from_matrix(R)[:, 1]) <= np.pi / 2)


@settings(max_examples=30)
@given(seed=seeds)
def test_quaternion_round_trip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(BATCH, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q = np.where(q[:, :1] < 0, -q, q)
    np.testing.assert_allclose(quaternion_from_matrix(matrix_from_quaternion(q)), q, atol=1e-14)


@pytest.mark.parametrize(
    ("axis", "angle"),
    [((1, 0, 0), 0.3), ((0, 1, 0), -1.2), ((0, 0, 1), math.pi), ((1, 1, 1), 2.0), ((0, 0, 1), 0)],
)
def test_known_rotations(axis: tuple[float, ...], angle: float) -> None:
    unit = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    rotation = Rotation.from_rotvec(angle * unit)
    q = np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * unit])
    np.testing.assert_allclose(matrix_from_quaternion(q), rotation.as_matrix(), atol=1e-15)
    np.testing.assert_allclose(quaternion_from_matrix(rotation.as_matrix()), q, atol=1e-15)


def test_gimbal_lock_and_shapes() -> None:
    R = matrix_from_rpy([0.4, np.pi / 2, -0.3])
    np.testing.assert_allclose(matrix_from_rpy(rpy_from_matrix(R)), R, atol=1e-14)
    np.testing.assert_allclose(rpy_from_matrix(R)[1], np.pi / 2, atol=1e-8)
    rpy = np.zeros((2, 5, 3))
    assert matrix_from_rpy(rpy).shape == (2, 5, 3, 3)
    assert rpy_from_matrix(matrix_from_rpy(rpy)).shape == (2, 5, 3)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (4, 1, 1))
    assert matrix_from_quaternion(q).shape == (4, 1, 3, 3)
    assert quaternion_from_matrix(matrix_from_quaternion(q)).shape == (4, 1, 4)
    np.testing.assert_allclose(matrix_from_quaternion([2.0, 0.0, 0.0, 0.0]), np.eye(3))
