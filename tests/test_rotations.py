"""Rotation conversions against scipy.spatial.transform.Rotation, and round trips; the
SO(3) exponential, logarithm and Jacobians against Pinocchio and finite differences."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from conftest import seeds
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

from spm_pin.errors import InputError
from spm_pin.rotations import (
    exp_so3,
    left_jacobian_so3,
    log_so3,
    matrix_from_quaternion,
    matrix_from_rpy,
    quaternion_from_matrix,
    right_jacobian_so3,
    rpy_from_matrix,
    skew,
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
    # exp, log and the Jacobians vs Pinocchio and scipy [max abs entry] ...
    "so3": 1e-13,
    # ... log kept at least this far from the angle pi, where its sign is free [rad].
    "pi_margin": 1e-3,
    # Jacobians vs central differences on the manifold, step h [rad]: error O(h^2).
    "fd_step": 1e-6,
    "fd": 1e-8,
    # J_r Jlog3 = I [max abs entry]: Pinocchio's small-angle series of Jlog3 is good to
    # about 2e-9 at the angle 1.5e-4.
    "jlog": 1e-8,
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


def _rotation_vectors(rng: np.random.Generator, count: int) -> np.ndarray:
    """Rotation vectors with angles spread over [0, pi), small ones (series) included."""
    axes = rng.normal(size=(count, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = rng.uniform(0.0, np.pi - TOL["pi_margin"], count)
    angles[:4] = [0.0, 1e-9, 3e-5, 1.5e-4]  # both sides of the series switch at 1e-4
    return angles[:, None] * axes


def test_skew_is_the_cross_product() -> None:
    rng = np.random.default_rng(5)
    v, u = rng.normal(size=(2, BATCH, 3))
    K = skew(v)
    assert K.shape == (BATCH, 3, 3)
    np.testing.assert_allclose(K @ u[..., None], np.cross(v, u)[..., None], atol=1e-14)
    np.testing.assert_array_equal(K, -np.swapaxes(K, -1, -2))
    np.testing.assert_array_equal(skew(v[0]), pin.skew(v[0]))
    assert skew(np.zeros((2, 0, 3))).shape == (2, 0, 3, 3)


@settings(max_examples=20)
@given(seed=seeds)
def test_exp_and_log_match_pinocchio_and_scipy(seed: int) -> None:
    for r in _rotation_vectors(np.random.default_rng(seed), 32):
        R = exp_so3(r)
        np.testing.assert_allclose(R, pin.exp3(r), atol=TOL["so3"])
        np.testing.assert_allclose(R, Rotation.from_rotvec(r).as_matrix(), atol=TOL["so3"])
        np.testing.assert_allclose(log_so3(R), pin.log3(R), atol=TOL["so3"])
        np.testing.assert_allclose(log_so3(R), r, atol=TOL["so3"])


def test_log_at_the_angle_pi() -> None:
    """At pi the axis sign is free: the log is any vector of length pi that exps back."""
    for axis in ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, -2.0, 2.0)):
        R = Rotation.from_rotvec(np.pi * np.asarray(axis) / np.linalg.norm(axis)).as_matrix()
        r = log_so3(R)
        np.testing.assert_allclose(np.linalg.norm(r), np.pi, atol=1e-12)
        np.testing.assert_allclose(exp_so3(r), R, atol=TOL["so3"])


@settings(max_examples=20)
@given(seed=seeds)
def test_jacobians_match_pinocchio(seed: int) -> None:
    """Pinocchio's Jexp3 is the right Jacobian; J_l(r) = J_r(-r) = R J_r(r)."""
    for r in _rotation_vectors(np.random.default_rng(seed), 32):
        J_r = right_jacobian_so3(r)
        np.testing.assert_allclose(J_r, pin.Jexp3(r), atol=TOL["so3"])
        np.testing.assert_allclose(left_jacobian_so3(r), pin.Jexp3(-r), atol=TOL["so3"])
        np.testing.assert_allclose(left_jacobian_so3(r), exp_so3(r) @ J_r, atol=TOL["so3"])
        # Jlog3 is the inverse of the right Jacobian at log(R).
        np.testing.assert_allclose(J_r @ pin.Jlog3(exp_so3(r)), np.eye(3), atol=TOL["jlog"])


def test_jacobians_against_finite_differences_on_the_manifold() -> None:
    """exp([r + h e_k]) = exp([h J_l e_k]) exp([r]) = exp([r]) exp([h J_r e_k]) + O(h^2)."""
    h = TOL["fd_step"]
    for r in _rotation_vectors(np.random.default_rng(11), 24):
        R = exp_so3(r)
        left = np.empty((3, 3))
        right = np.empty((3, 3))
        for k in range(3):
            step = h * np.eye(3)[k]
            plus, minus = exp_so3(r + step), exp_so3(r - step)
            left[:, k] = (log_so3(plus @ R.T) - log_so3(minus @ R.T)) / (2 * h)
            right[:, k] = (log_so3(R.T @ plus) - log_so3(R.T @ minus)) / (2 * h)
        np.testing.assert_allclose(left_jacobian_so3(r), left, atol=TOL["fd"])
        np.testing.assert_allclose(right_jacobian_so3(r), right, atol=TOL["fd"])


@pytest.mark.parametrize(
    ("function", "value"),
    [
        (skew, [1.0, 2.0]),
        (skew, [np.nan, 0.0, 0.0]),
        (skew, "abc"),
        (exp_so3, np.zeros((2, 3))),
        (exp_so3, [np.inf, 0.0, 0.0]),
        (left_jacobian_so3, [0.0, 0.0]),
        (right_jacobian_so3, None),
        (log_so3, np.eye(3) * 2.0),
        (log_so3, np.stack([np.eye(3)] * 2)),
    ],
)
def test_so3_bad_input(function: object, value: object) -> None:
    with pytest.raises(InputError):
        function(value)  # type: ignore[operator]
