"""Inverse kinematics: round trips with FK, loop closures, working modes, reachability."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import (
    design_names,
    get_design,
    leg_signs,
    loop_residual,
    platform_axes,
    proximal_axes,
    random_rotations,
    reachable_inputs,
    rot_z,
    seeds,
    wrap,
)
from hypothesis import given, settings

import spm_pin as spm

#: Tolerances of this module.
TOL = {
    # |IK(FK(theta)) - theta| [rad] away from type I singularities ...
    "theta": 1e-9,
    # ... plus this over the leg's normalised b_ii (theta is ill-conditioned near b = 0).
    "theta_per_margin": 1e-12,
    # Loop closure w_i . v_i - cos a2 of IK solutions [dot product].
    "closure": 1e-12,
    # max |R - R'| between a rotation and the one found again by FK.
    "rotation": 1e-10,
    # Margin kept from the reachability boundary when comparing with the geometric test.
    "boundary": 1e-9,
}

BATCH = 96


def _theta_tolerance(design: spm.SPMDesign, theta: np.ndarray, R: np.ndarray) -> np.ndarray:
    b, _, _ = leg_signs(design, theta, R)
    w_rate = np.cross(design.u, proximal_axes(design, theta))
    margin = np.abs(b) / np.linalg.norm(w_rate, axis=-1)
    return TOL["theta"] + TOL["theta_per_margin"] / margin


# ------------------------------------------------------------------- round trips
@settings(max_examples=30)
@given(seed=seeds, name=design_names)
def test_fk_then_ik_gives_back_theta(seed: int, name: str) -> None:
    """FK home-mode R -> IK home working mode -> the same theta modulo 2 pi."""
    design = get_design(name)
    rng = np.random.default_rng(seed)
    theta = reachable_inputs(design, rng, BATCH)
    turns = rng.integers(-3, 4, size=theta.shape)
    fk = spm.forward_kinematics(theta + 2 * np.pi * turns, design)
    assert np.all(fk.reachable)
    ik = spm.inverse_kinematics(fk.R, design)
    assert ik.mode == "+++"
    assert np.all(ik.reachable)
    assert np.all(ik.leg_reachable)
    assert np.all(ik.theta > -np.pi) and np.all(ik.theta <= np.pi)
    error = np.abs(wrap(ik.theta - theta))
    np.testing.assert_array_less(error, _theta_tolerance(design, theta, fk.R))
    # The home working mode: every b_ii > 0, and b agrees with (u_i x w_i) . v_i.
    b, _, _ = leg_signs(design, theta, fk.R)
    assert np.all(ik.b > 0)
    np.testing.assert_allclose(ik.b, b, atol=1e-9)


@settings(max_examples=30)
@given(seed=seeds, name=design_names)
def test_ik_then_fk_finds_the_rotation(seed: int, name: str) -> None:
    """Random R in the reachable set -> IK -> FK: all modes contain R; FK with R as
    reference returns R when R satisfies the home sign rule."""
    design = get_design(name)
    rng = np.random.default_rng(seed)
    R = random_rotations(rng, 4 * BATCH)
    ik = spm.inverse_kinematics(R, design)
    R, theta = R[ik.reachable], ik.theta[ik.reachable]
    assert not np.any(np.isnan(theta))
    np.testing.assert_array_less(loop_residual(design, theta, R), TOL["closure"])

    every = spm.forward_kinematics_all(theta, design)
    distance = np.abs(every.R - R[:, None]).max(axis=(-2, -1))
    nearest = np.where(every.valid, distance, np.inf).min(axis=-1)
    np.testing.assert_array_less(nearest, TOL["rotation"])

    b, _, det_a = leg_signs(design, theta, R)
    home_rule = np.all(b > 0, axis=-1) & (np.sign(det_a) == np.sign(design.home_det_a))
    if not np.any(home_rule):
        return
    fk = spm.forward_kinematics(theta[home_rule], design, reference=R[home_rule])
    assert np.all(fk.reachable)
    np.testing.assert_allclose(fk.R, R[home_rule], atol=TOL["rotation"])


@settings(max_examples=20)
@given(seed=seeds, name=design_names)
def test_all_working_modes_close_every_loop(seed: int, name: str) -> None:
    design = get_design(name)
    rng = np.random.default_rng(seed)
    R = random_rotations(rng, BATCH)
    every = spm.inverse_kinematics_all(R, design)
    assert every.theta.shape == (BATCH, 8, 3)
    assert every.labels == ("+++", "-++", "+-+", "--+", "++-", "-+-", "+--", "---")
    ok = every.reachable
    theta = every.theta[ok]
    R_modes = np.broadcast_to(R[ok][:, None], (*theta.shape[:2], 3, 3))
    np.testing.assert_array_less(loop_residual(design, theta, R_modes), TOL["closure"])
    assert np.all(np.isnan(every.theta[~ok]).any(axis=-1))
    # Mode m puts leg i on the '-' root (b_ii < 0) when bit i of m is set.
    b, _, _ = leg_signs(design, theta, R_modes)
    for m in range(8):
        expected = np.array([-1.0 if (m >> i) & 1 else 1.0 for i in range(3)])
        assert np.all(np.sign(b[:, m]) == expected), every.labels[m]
        single = spm.inverse_kinematics(R[ok], design, mode=m)
        np.testing.assert_allclose(single.theta, theta[:, m], atol=1e-12)
        by_label = spm.inverse_kinematics(R[ok], design, mode=every.labels[m])
        np.testing.assert_array_equal(by_label.theta, single.theta)
        assert single.mode == every.labels[m]
        np.testing.assert_allclose(np.sign(single.b), np.broadcast_to(expected, single.b.shape))


def _leg_reachable_by_geometry(design: spm.SPMDesign, R: np.ndarray) -> tuple[np.ndarray, ...]:
    """Leg i closes iff alpha2 is an angle between w_i on its cone (half-angle alpha1
    about u_i) and v_i at angle gamma from u_i: |a1 - gamma| <= a2 <= min(a1 + gamma,
    360 deg - a1 - gamma). Returns (reachable, distance to the boundary) per leg."""
    v = platform_axes(design, R)
    gamma = np.arccos(np.clip(np.sum(design.u * v, axis=-1), -1.0, 1.0))
    a1, a2 = design.alpha1, design.alpha2
    low = np.abs(a1 - gamma)
    high = np.minimum(a1 + gamma, 2 * np.pi - a1 - gamma)
    slack = np.minimum(a2 - low, high - a2)
    return slack >= 0, np.abs(slack)


@settings(max_examples=20)
@given(seed=seeds, name=design_names)
def test_leg_reachability_matches_cone_geometry(seed: int, name: str) -> None:
    design = get_design(name)
    R = random_rotations(np.random.default_rng(seed), 4 * BATCH)
    expected, slack = _leg_reachable_by_geometry(design, R)
    clear = np.all(slack > TOL["boundary"], axis=-1)
    ik = spm.inverse_kinematics(R, design)
    np.testing.assert_array_equal(ik.leg_reachable[clear], expected[clear])
    np.testing.assert_array_equal(ik.reachable[clear], np.all(expected[clear], axis=-1))
    # Unreachable items of a batch are flagged and NaN, never raised.
    assert np.all(np.isnan(ik.theta[~ik.reachable]).any(axis=-1))
    assert not np.any(np.isnan(ik.theta[ik.reachable]))


# ------------------------------------------------------------ multi-turn requests
@settings(max_examples=20)
@given(seed=seeds, name=design_names)
def test_theta_near_selects_the_turn(seed: int, name: str) -> None:
    design = get_design(name)
    rng = np.random.default_rng(seed)
    theta = reachable_inputs(design, rng, BATCH)
    R = spm.forward_kinematics(theta, design).R
    turns = rng.integers(-4, 5, size=theta.shape)
    near = theta + 2 * np.pi * turns + rng.uniform(-2.5, 2.5, size=theta.shape)
    ik = spm.inverse_kinematics(R, design, theta_near=near)
    np.testing.assert_array_less(np.abs(ik.theta - near), np.pi + 1e-12)
    expected = theta + 2 * np.pi * turns
    np.testing.assert_array_less(
        np.abs(ik.theta - expected), _theta_tolerance(design, theta, R) + 1e-12 * np.abs(expected)
    )
    every = spm.inverse_kinematics_all(R, design, theta_near=near)
    np.testing.assert_allclose(every.theta[:, 0], ik.theta, atol=1e-12)
    np.testing.assert_array_less(np.abs(every.theta - near[:, None]), np.pi + 1e-12)


# ------------------------------------------------------------------ known poses
def test_home_rotation_gives_zero_inputs(design: spm.SPMDesign) -> None:
    ik = spm.inverse_kinematics(np.eye(3), design)
    np.testing.assert_allclose(ik.theta, np.zeros(3), atol=1e-12)
    np.testing.assert_allclose(ik.b, leg_signs(design, np.zeros(3), np.eye(3))[0], atol=1e-12)


def test_platform_turn_about_the_axis_is_a_common_input(prototype: spm.SPMDesign) -> None:
    """For the coaxial prototype, R = Rz(-c) needs theta = c (1, 1, 1)."""
    for c in np.radians([-170.0, -45.0, 10.0, 90.0, 179.0]):
        ik = spm.inverse_kinematics(rot_z(-c), prototype)
        np.testing.assert_allclose(wrap(ik.theta - c), np.zeros(3), atol=TOL["theta"])


def test_paper_input_round_trip(prototype: spm.SPMDesign) -> None:
    """theta = [60, 90, 120] deg of the published study."""
    theta = np.radians([60.0, 90.0, 120.0])
    fk = spm.forward_kinematics(theta, prototype)
    ik = spm.inverse_kinematics(fk.R, prototype)
    np.testing.assert_allclose(ik.theta, theta, atol=TOL["theta"])


# ------------------------------------------------------------------ unreachable
def _tilt_away(leg: int) -> np.ndarray:
    """Prototype pose that only leg ``leg`` (1-based) cannot reach: its platform axis
    v_k is tilted 60 deg out of the horizontal plane, 30 deg from u = -z, while the
    leg can only reach 45..135 deg from u."""
    c, s = math.cos(math.radians(60.0)), math.sin(math.radians(60.0))
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    turn = rot_z(math.radians(120.0 * (leg - 1)))
    return turn @ tilt @ turn.T


@pytest.mark.parametrize("leg", [1, 2, 3])
def test_unreachable_rotation_raises_with_the_leg(prototype: spm.SPMDesign, leg: int) -> None:
    R = _tilt_away(leg)
    expected, _ = _leg_reachable_by_geometry(prototype, R)
    assert list(expected) == [i != leg - 1 for i in range(3)]
    match = rf"orientation unreachable: leg {leg} cannot close \(P\^2 \+ Q\^2 - S\^2 = .* < 0\)"
    with pytest.raises(spm.UnreachableError, match=match) as info:
        spm.inverse_kinematics(R, prototype)
    assert info.value.leg == leg
    assert f"leg {leg}" in str(info.value)
    np.testing.assert_array_equal(info.value.value, R)


def test_unreachable_rotation_names_the_first_failing_leg(prototype: spm.SPMDesign) -> None:
    c, s = math.cos(math.radians(80.0)), math.sin(math.radians(80.0))
    R = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # 80 deg about y
    expected, _ = _leg_reachable_by_geometry(prototype, R)
    assert not expected[1] and not expected[2] and expected[0]
    match = "orientation unreachable: leg 2 cannot close"
    with pytest.raises(spm.UnreachableError, match=match) as info:
        spm.inverse_kinematics(R, prototype)
    assert info.value.leg == 2


def test_unreachable_items_of_a_batch_are_flagged(prototype: spm.SPMDesign) -> None:
    batch = np.stack([np.eye(3), _tilt_away(1), rot_z(0.3), _tilt_away(3), _tilt_away(2)])
    ik = spm.inverse_kinematics(batch, prototype)
    np.testing.assert_array_equal(ik.reachable, [True, False, True, False, False])
    np.testing.assert_array_equal(
        ik.leg_reachable,
        [[1, 1, 1], [0, 1, 1], [1, 1, 1], [1, 1, 0], [1, 0, 1]],
    )
    assert np.all(np.isnan(ik.theta[~ik.reachable]).any(axis=-1))
    np.testing.assert_allclose(ik.theta[0], np.zeros(3), atol=1e-12)
    every = spm.inverse_kinematics_all(batch, prototype)
    np.testing.assert_array_equal(every.reachable, ik.reachable)
    # A batch of one is still a batch: flagged, not raised.
    single = spm.inverse_kinematics(_tilt_away(1)[None], prototype)
    np.testing.assert_array_equal(single.reachable, [False])


def test_batch_shapes_are_kept(design: spm.SPMDesign) -> None:
    R = random_rotations(np.random.default_rng(3), 12).reshape(3, 4, 3, 3)
    ik = spm.inverse_kinematics(R, design)
    assert ik.theta.shape == (3, 4, 3)
    assert ik.reachable.shape == (3, 4)
    assert ik.leg_reachable.shape == (3, 4, 3)
    flat = spm.inverse_kinematics(R.reshape(-1, 3, 3), design)
    np.testing.assert_array_equal(ik.theta.reshape(-1, 3), flat.theta)
    every = spm.inverse_kinematics_all(R, design)
    assert every.theta.shape == (3, 4, 8, 3)
