"""Velocity kinematics: J against finite differences of FK, A omega = B theta_dot,
dexterity, and type I / type II singularities found by search."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _brute_force import brute_force_fk
from conftest import (
    design_names,
    get_design,
    leg_signs,
    platform_axes,
    proximal_axes,
    random_rotations,
    reachable_inputs,
    rot_z,
    seeds,
)
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

import spm_pin as spm

#: Tolerances of this module.
TOL = {
    # Central-difference step of FK [rad].
    "fd_step": 1e-6,
    # |J - J_fd| relative to max(1, |J|) (truncation h^2 plus rounding eps / h).
    "fd": 1e-7,
    # Identities that hold to rounding (A J = B, A, B, b recomputed).
    "identity": 1e-11,
    # Dexterity recomputed from an SVD.
    "dexterity": 1e-9,
    # The dexterity values quoted for the prototype at home (4 decimals).
    "quoted": 5e-5,
    # Bisection width on the input angle [rad].
    "bisection": 1e-12,
}

BATCH = 64


def _vee(skew: np.ndarray) -> np.ndarray:
    """The vector of a skew-symmetric matrix (..., 3, 3) (its symmetric part dropped)."""
    s = 0.5 * (skew - np.swapaxes(skew, -1, -2))
    return np.stack([s[..., 2, 1], s[..., 0, 2], s[..., 1, 0]], axis=-1)


def _finite_difference_jacobian(design: spm.SPMDesign, theta: np.ndarray) -> np.ndarray:
    """Columns omega_i from (R(theta + h e_i) - R(theta - h e_i)) / (2h) R^T, (n, 3, 3)."""
    h = TOL["fd_step"]
    R = spm.forward_kinematics(theta, design).R
    columns = []
    for i in range(3):
        step = np.zeros(3)
        step[i] = h
        plus = spm.forward_kinematics(theta + step, design)
        minus = spm.forward_kinematics(theta - step, design)
        assert np.all(plus.reachable) and np.all(minus.reachable)
        dR = (plus.R - minus.R) / (2 * h)
        columns.append(_vee(dR @ np.swapaxes(R, -1, -2)))
    return np.stack(columns, axis=-1)


def _safe_inputs(design: spm.SPMDesign, rng: np.random.Generator, n: int) -> np.ndarray:
    """Reachable inputs at least 0.05 from any singularity (FD stays in one mode)."""
    theta = reachable_inputs(design, rng, 4 * n)
    margin = spm.jacobian(theta, design).singularity_margin
    theta = theta[margin > 0.05]
    assert theta.shape[0] >= n // 4
    return theta[:n]


@settings(max_examples=25)
@given(seed=seeds, name=design_names)
def test_jacobian_matches_finite_differences(seed: int, name: str) -> None:
    design = get_design(name)
    theta = _safe_inputs(design, np.random.default_rng(seed), BATCH)
    result = spm.jacobian(theta, design)
    expected = _finite_difference_jacobian(design, theta)
    scale = np.maximum(1.0, np.abs(expected).max(axis=(-2, -1)))
    error = np.abs(result.J - expected).max(axis=(-2, -1)) / scale
    np.testing.assert_array_less(error, TOL["fd"])


@settings(max_examples=25)
@given(seed=seeds, name=design_names)
def test_velocity_identity(seed: int, name: str) -> None:
    """A omega = B theta_dot with A, B rebuilt here from w_i, v_i, and omega from FK."""
    design = get_design(name)
    rng = np.random.default_rng(seed)
    theta = _safe_inputs(design, rng, BATCH)
    result = spm.jacobian(theta, design)
    fk = spm.forward_kinematics(theta, design)
    np.testing.assert_allclose(result.R, fk.R, atol=1e-15)
    b, A, det_a = leg_signs(design, theta, fk.R)
    B = b[..., :, None] * np.eye(3)
    np.testing.assert_allclose(result.A, A, atol=TOL["identity"])
    np.testing.assert_allclose(result.B, B, atol=TOL["identity"])
    np.testing.assert_allclose(result.b, b, atol=TOL["identity"])
    np.testing.assert_allclose(result.det_a, det_a, atol=TOL["identity"])
    np.testing.assert_allclose(A @ result.J, B, atol=TOL["identity"])
    # A finite-difference omega along a random rate direction satisfies it too.
    rate = rng.normal(size=theta.shape)
    h = TOL["fd_step"]
    dR = (
        spm.forward_kinematics(theta + h * rate, design).R
        - spm.forward_kinematics(theta - h * rate, design).R
    ) / (2 * h)
    omega = _vee(dR @ np.swapaxes(fk.R, -1, -2))
    scale = np.maximum(1.0, np.abs(omega).max(axis=-1, keepdims=True))
    np.testing.assert_allclose(
        np.einsum("nij,nj->ni", A, omega) / scale,
        np.einsum("nij,nj->ni", B, rate) / scale,
        atol=10 * TOL["fd"],
    )
    # The platform axes move as omega x v_i; the proximal axes as theta_dot_i u_i x w_i.
    v_dot = np.cross(omega[:, None, :], platform_axes(design, fk.R))
    w_dot = rate[..., None] * np.cross(design.u, proximal_axes(design, theta))
    closure_rate = np.sum(w_dot * fk.v + fk.w * v_dot, axis=-1)
    np.testing.assert_allclose(closure_rate / scale, 0.0, atol=10 * TOL["fd"])


@settings(max_examples=25)
@given(seed=seeds, name=design_names)
def test_dexterity_from_singular_values(seed: int, name: str) -> None:
    design = get_design(name)
    theta = reachable_inputs(design, np.random.default_rng(seed), BATCH)
    result = spm.jacobian(theta, design)
    ok = ~result.singular
    sigma = np.linalg.svd(result.J[ok], compute_uv=False)
    np.testing.assert_allclose(
        result.dexterity[ok], sigma[:, -1] / sigma[:, 0], atol=TOL["dexterity"]
    )
    J = result.J[ok]
    norm = np.sqrt(np.trace(np.swapaxes(J, -1, -2) @ J, axis1=-2, axis2=-1) / 3)
    J_inv = np.linalg.inv(J)
    norm_inv = np.sqrt(np.trace(np.swapaxes(J_inv, -1, -2) @ J_inv, axis1=-2, axis2=-1) / 3)
    np.testing.assert_allclose(result.dexterity_ga[ok], 1 / (norm * norm_inv), rtol=1e-9)
    assert np.all((result.dexterity >= 0) & (result.dexterity <= 1 + 1e-12))
    assert np.all((result.dexterity_ga >= 0) & (result.dexterity_ga <= 1 + 1e-12))
    assert np.all((result.singularity_margin >= 0) & (result.singularity_margin <= 1 + 1e-12))


def test_prototype_dexterity_at_home(prototype: spm.SPMDesign) -> None:
    """0.7071 (2-norm) and 0.9487 (Gosselin-Angeles), computed here from the SVD of a
    finite-difference J."""
    result = spm.jacobian(np.zeros(3), prototype)
    J_fd = _finite_difference_jacobian(prototype, np.zeros((1, 3)))[0]
    np.testing.assert_allclose(result.J, J_fd, atol=TOL["fd"])
    sigma = np.linalg.svd(J_fd, compute_uv=False)
    two_norm = sigma[-1] / sigma[0]
    ga = 3.0 / math.sqrt(np.sum(sigma**2) * np.sum(sigma**-2))
    np.testing.assert_allclose(two_norm, 0.7071, atol=TOL["quoted"])
    np.testing.assert_allclose(ga, 0.9487, atol=TOL["quoted"])
    np.testing.assert_allclose(result.dexterity, two_norm, atol=1e-8)
    np.testing.assert_allclose(result.dexterity_ga, ga, atol=1e-8)
    assert not result.type_i and not result.type_ii and not result.singular
    assert result.reachable
    np.testing.assert_allclose(result.det_a, prototype.home_det_a, atol=1e-12)


def test_explicit_rotation_gives_the_same_jacobian(design: spm.SPMDesign) -> None:
    theta = reachable_inputs(design, np.random.default_rng(5), 32)
    default = spm.jacobian(theta, design)
    explicit = spm.jacobian(theta, design, R=spm.forward_kinematics(theta, design).R)
    np.testing.assert_allclose(explicit.J, default.J, atol=1e-13)
    np.testing.assert_allclose(explicit.singularity_margin, default.singularity_margin, atol=1e-13)
    assert default.J.shape == (32, 3, 3) and default.dexterity.shape == (32,)


# ----------------------------------------------------------- type I: bisection
def _edge_of_reach(design: spm.SPMDesign, actuator: int, sign: float) -> tuple[float, float]:
    """Move one actuator alone from home; bisect the last reachable angle [rad]."""
    direction = np.zeros(3)
    direction[actuator] = sign
    inside, outside = 0.0, math.pi
    assert spm.forward_kinematics(inside * direction, design).reachable
    assert not spm.forward_kinematics(outside * direction, design).reachable
    while outside - inside > TOL["bisection"]:
        middle = 0.5 * (inside + outside)
        if spm.forward_kinematics(middle * direction, design).reachable:
            inside = middle
        else:
            outside = middle
    return inside, outside


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("actuator", [0, 1, 2])
def test_one_actuator_reaches_a_type_i_singularity(
    prototype: spm.SPMDesign, actuator: int, sign: float
) -> None:
    """From home, one actuator alone reaches about 107 deg; there its leg turns type I
    singular (b_ii -> 0: the two IK roots of that leg merge)."""
    inside, _ = _edge_of_reach(prototype, actuator, sign)
    assert abs(math.degrees(inside) - 107.0) < 0.5
    direction = np.zeros(3)
    direction[actuator] = sign
    approach = np.array([inside - 0.1, inside - 0.01, inside - 1e-4, inside - 1e-7, inside])
    result = spm.jacobian(approach[:, None] * direction, prototype)
    margin = result.singularity_margin
    assert np.all(result.reachable)
    assert np.all(np.diff(margin) < 0), margin  # monotone towards the singularity
    assert margin[-1] < 1e-7
    assert margin[0] > 1e-2
    assert np.all(np.argmin(np.abs(result.b), axis=-1) == actuator)  # the moved leg
    np.testing.assert_allclose(result.dexterity[-1], 0.0, atol=1e-7)
    assert not np.any(result.type_ii)  # the home mode has no type II singularity here
    # Flagged with a threshold above the remaining margin, not far from it.
    flagged = spm.jacobian(approach[:, None] * direction, prototype, tol=1e-6)
    np.testing.assert_array_equal(flagged.type_i, [False, False, False, True, True])
    np.testing.assert_array_equal(flagged.singular, flagged.type_i)
    # The two IK roots of the moved leg coincide at the edge.
    R = spm.forward_kinematics(inside * direction, prototype).R
    roots = spm.inverse_kinematics_all(R, prototype).theta
    other_root = 1 << actuator
    np.testing.assert_allclose(roots[other_root], roots[0], atol=1e-6)
    np.testing.assert_allclose(roots[0], inside * direction, atol=1e-6)


def _leg_1_on_its_boundary() -> np.ndarray:
    """Prototype poses with v_1 exactly 45 deg from u = -z (tilt 45 deg about x, then
    turns about z), shape (9, 3, 3): leg 1 can just close, with u, w_1 and v_1
    coplanar (b_11 = 0, a type I singularity)."""
    c, s = math.cos(math.radians(45.0)), math.sin(math.radians(45.0))
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return np.stack([rot_z(angle) @ tilt for angle in np.linspace(-0.5, 0.5, 9)])


def test_exact_type_i_poses_have_zero_margin(prototype: spm.SPMDesign) -> None:
    R = _leg_1_on_its_boundary()
    ik = spm.inverse_kinematics(R, prototype)
    assert np.all(ik.reachable)
    result = spm.jacobian(ik.theta, prototype, R=R)
    # b_11 is known only to about sqrt(eps): the IK discriminant is 0 up to rounding.
    np.testing.assert_array_less(result.singularity_margin, 1e-7)
    np.testing.assert_array_less(np.abs(result.b[:, 0]), 1e-7)
    np.testing.assert_array_less(result.dexterity, 1e-7)
    assert np.all(spm.jacobian(ik.theta, prototype, R=R, tol=1e-7).type_i)
    # The two IK roots of leg 1 merge.
    roots = spm.inverse_kinematics_all(R, prototype).theta
    np.testing.assert_allclose(roots[:, 1], roots[:, 0], atol=1e-7)


def test_exact_type_i_poses_are_flagged_with_the_default_tolerance(
    prototype: spm.SPMDesign,
) -> None:
    """b_11 reads about sqrt(eps) ~ 7e-9 there (found with SINGULAR_TOL = 1e-9, which
    missed 7 of these 9 poses); the default threshold must sit above that."""
    R = _leg_1_on_its_boundary()
    ik = spm.inverse_kinematics(R, prototype)
    result = spm.jacobian(ik.theta, prototype, R=R)
    np.testing.assert_array_equal(result.type_i, True)
    np.testing.assert_array_equal(result.singular, True)


# ---------------------------------------------------------- type II: bisection
def _type_ii_pose(design: spm.SPMDesign, mode: int) -> tuple[np.ndarray, np.ndarray]:
    """A pose where det A = 0 in IK working mode ``mode``: bisect det A along a great
    circle of rotations, entirely reachable, between two poses of opposite det A."""

    def det_a(rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ik = spm.inverse_kinematics(rotations, design, mode=mode)
        theta = np.where(ik.reachable[..., None], ik.theta, 0.0)
        return leg_signs(design, theta, rotations)[2], ik.reachable

    rng = np.random.default_rng(11)
    start = Rotation.from_matrix(random_rotations(rng, 64))
    det, ok = det_a(start.as_matrix())
    negative = np.nonzero(ok & (det < -0.05))[0]
    positive = np.nonzero(ok & (det > 0.05))[0]
    for i in negative:
        for j in positive:
            step = (start[i].inv() * start[j]).as_rotvec()
            s = np.linspace(0.0, 1.0, 101)
            path = (start[i] * Rotation.from_rotvec(s[:, None] * step)).as_matrix()
            _, path_ok = det_a(path)
            if not np.all(path_ok):
                continue
            low, high = 0.0, 1.0
            for _ in range(80):
                middle = 0.5 * (low + high)
                pose = (start[i] * Rotation.from_rotvec(middle * step)).as_matrix()
                if det_a(pose[None])[0][0] < 0:
                    low = middle
                else:
                    high = middle
            pose = (start[i] * Rotation.from_rotvec(low * step)).as_matrix()
            return pose, spm.inverse_kinematics(pose, design, mode=mode).theta
    raise AssertionError("no reachable great-circle arc crosses det A = 0")


def test_type_ii_singularity_raises_and_is_flagged(prototype: spm.SPMDesign) -> None:
    """Prototype, working mode '-++': a parallel singularity inside the reachable set."""
    R, theta = _type_ii_pose(prototype, mode=1)
    _, A, det_a = leg_signs(prototype, theta, R)
    assert abs(det_a) < 1e-12
    assert np.linalg.svd(A, compute_uv=False)[-1] < 1e-12
    match = r"type II \(parallel\) singularity at theta = .* deg: det A = .*does not exist"
    with pytest.raises(spm.SingularityError, match=match) as info:
        spm.jacobian(theta, prototype, R=R)
    assert info.value.kind == "type II"
    assert isinstance(info.value, ValueError)
    batch = spm.jacobian(np.stack([theta, np.zeros(3)]), prototype, R=np.stack([R, np.eye(3)]))
    np.testing.assert_array_equal(batch.type_ii, [True, False])
    np.testing.assert_array_equal(batch.singular, [True, False])
    assert np.all(np.isnan(batch.J[0]))
    assert not np.any(np.isnan(batch.J[1]))
    assert batch.singularity_margin[0] < 1e-9 < batch.singularity_margin[1]
    assert batch.dexterity[0] == 0.0


def test_type_ii_pose_is_among_all_assembly_modes(prototype: spm.SPMDesign) -> None:
    R, theta = _type_ii_pose(prototype, mode=1)
    found = brute_force_fk(theta, prototype.u, prototype.w0, prototype.v0, prototype.alpha2)
    assert np.min(np.abs(found - R).max(axis=(-2, -1))) < 1e-6  # the reference finds it
    every = spm.forward_kinematics_all(theta, prototype)
    assert np.min(np.abs(every.R[every.valid] - R).max(axis=(-2, -1))) < 1e-6


# ----------------------------------------------------------------- unreachable
def test_unreachable_input(prototype: spm.SPMDesign) -> None:
    theta = np.radians([0.0, 0.0, 200.0])
    match = r"no home-mode assembly at theta = \[0\.0, 0\.0, 200\.0\] deg"
    with pytest.raises(spm.UnreachableError, match=match):
        spm.jacobian(theta, prototype)
    batch = spm.jacobian(np.stack([np.zeros(3), theta]), prototype)
    np.testing.assert_array_equal(batch.reachable, [True, False])
    assert np.all(np.isnan(batch.J[1])) and np.isnan(batch.dexterity[1])
    assert np.isnan(batch.singularity_margin[1])
    assert not batch.type_i[1] and not batch.type_ii[1]
    np.testing.assert_allclose(batch.J[0], spm.jacobian(np.zeros(3), prototype).J, atol=1e-15)
