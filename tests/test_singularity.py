"""Singularity flags against singular poses built independently of the library.

Type I (serial): b_ii = 0, found by bisection on one input with a Newton solve of the
loop closures written here from the documented formulas. Type II (parallel):
det A = 0, found by bisection along a family of rotations in a working mode other
than home (the prototype's home working mode has no type II singularity), with the
inputs from a closed-form inverse kinematics written here. Poses within the
documented tolerance of a singularity must be flagged; near-singular but regular
poses (a few times the tolerance away and more) must not be.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from _prototype_truth import A1, A2, ETA, V0, U, rot, w_axes

import spm_pin as spm
from spm_pin.errors import SingularityError

#: Tolerances of this file (restated from the documentation, not imported).
TOL = {
    # Documented threshold on the normalised singularity measures (jacobian.py):
    # type I when min_i |b_ii| / |u x w_i| <= tol, type II when sigma_min of A with
    # unit rows <= tol.
    "documented": 1e-7,
    # Poses within the tolerance: margins of these multiples of it are flagged.
    "within": (0.1, 0.5, 0.9),
    # Near-singular but regular: margins of these multiples are not flagged.
    "regular": (2.0, 10.0, 100.0, 500.0),
    # Library quantities against the numpy recomputation here.
    "model": 1e-9,
    # A measure found by bisection matches its target to this (relative).
    "bisect": 1e-6,
}

# ------------------------------------------------------------ independent kinematics
# The prototype's constants and w_i(theta) come from tests/_prototype_truth.py.


def ik_roots(R: np.ndarray) -> np.ndarray:
    """Both roots of w_i . v_i = cos a2 per leg, (3, 2) [rad] (closed form)."""
    v = V0 @ R.T
    out = np.full((3, 2), np.nan)
    for i in range(3):
        r = np.hypot(v[i, 0], v[i, 1])
        psi = np.arctan2(v[i, 1], v[i, 0])
        c = (np.cos(A2) + np.cos(A1) * v[i, 2]) / (np.sin(A1) * r)
        for j, sign in enumerate((1.0, -1.0)):
            t = ETA[i] - (psi + sign * np.arccos(c))
            out[i, j] = (t + np.pi) % (2 * np.pi) - np.pi
    return out


def fk_newton(theta: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Newton on the loop closures from R: d(w_i . v_i) = -a_i . delta for R <- exp(delta) R."""
    w = w_axes(theta)
    for _ in range(60):
        v = V0 @ R.T
        residual = np.sum(w * v, axis=1) - np.cos(A2)
        delta = np.linalg.solve(np.cross(w, v), residual)
        R = rot(delta) @ R
        if np.max(np.abs(delta)) < 1e-15:
            break
    return R


def measures(theta: np.ndarray, R: np.ndarray) -> dict[str, np.ndarray | float]:
    """b_ii, det A, the two normalised singularity measures and 1/kappa_2(J)."""
    w = w_axes(theta)
    v = V0 @ R.T
    uxw = np.cross(U, w)
    b = np.sum(uxw * v, axis=1)
    A = np.cross(w, v)
    leg = np.abs(b) / np.linalg.norm(uxw, axis=1)
    sigma_a = np.linalg.svd(A / np.linalg.norm(A, axis=1, keepdims=True), compute_uv=False)
    if abs(np.linalg.det(A)) > 1e-300:
        s = np.linalg.svd(np.linalg.solve(A, np.diag(b)), compute_uv=False)
    else:  # exactly type II: J does not exist
        s = np.array([np.inf, 0.0])
    return {
        "b": b,
        "det_a": float(np.linalg.det(A)),
        "leg": float(leg.min()),
        "sa": float(sigma_a[-1]),
        "margin": float(min(leg.min(), sigma_a[-1])),
        "dexterity": float(s[-1] / s[0]),
        "closure": float(np.max(np.abs(np.sum(w * v, axis=1) - np.cos(A2)))),
    }


def bisect(f: Callable[[float], float], good: float, bad: float, level: float) -> float:
    """The parameter between good (f > level) and bad (f <= level) where f = level."""
    assert f(good) > level >= f(bad)
    for _ in range(200):
        mid = 0.5 * (good + bad)
        if mid in (good, bad):
            break
        if f(mid) > level:
            good = mid
        else:
            bad = mid
    return good


# ------------------------------------------------------------ type I: b_11 = 0
#: Start: the platform tilted 40 deg about x, home working mode; then theta_1 alone
#: decreases until leg 1 is stretched flat (b_11 = 0 near theta_1 = -91.2 deg).
_TILT = rot(np.radians([40.0, 0.0, 0.0]))


@pytest.fixture(scope="module")
def type_i() -> dict[str, object]:
    # Pick the home working mode roots (b_ii > 0) of the tilted pose.
    roots = ik_roots(_TILT)
    theta0 = np.empty(3)
    for i in range(3):
        for t in roots[i]:
            probe = theta0.copy()
            probe[i] = t
            if np.cross(U, w_axes(probe)[i]) @ (_TILT @ V0[i]) > 0:
                theta0[i] = t
    assert measures(theta0, _TILT)["closure"] < 1e-14
    # Continue the assembly along theta_1 down to -89 deg (regular all the way).
    R = _TILT
    for t in np.linspace(theta0[0], np.radians(-89.0), 40)[1:]:
        R = fk_newton(np.array([t, theta0[1], theta0[2]]), R)
    reference = R

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        theta = np.array([t, theta0[1], theta0[2]])
        return theta, fk_newton(theta, reference)

    def b11(t: float) -> float:
        return float(measures(*pose(t))["b"][0])

    regular, beyond = np.radians(-89.0), np.radians(-93.0)
    assert b11(regular) > 0.01 and b11(beyond) < -0.01
    t_star = bisect(b11, regular, beyond, 0.0)
    return {"pose": pose, "t_star": t_star, "regular": regular}


def _at_leg_margin(type_i: dict[str, object], margin: float) -> tuple[np.ndarray, np.ndarray]:
    pose = type_i["pose"]
    assert callable(pose)

    def leg(t: float) -> float:
        return float(measures(*pose(t))["leg"])

    t = bisect(leg, float(type_i["regular"]), float(type_i["t_star"]), margin)  # type: ignore[arg-type]
    theta, R = pose(t)
    measured = measures(theta, R)
    assert measured["leg"] == pytest.approx(margin, rel=TOL["bisect"])
    assert measured["sa"] > 0.5  # only leg 1 is near its singularity
    return theta, R


def test_exact_type_i_pose_is_singular(type_i: dict[str, object]) -> None:
    pose = type_i["pose"]
    assert callable(pose)
    theta, R = pose(type_i["t_star"])
    measured = measures(theta, R)
    assert abs(measured["b"][0]) < 1e-12 and measured["closure"] < 1e-14
    jac = spm.jacobian(theta, R=R)
    assert bool(jac.type_i) and bool(jac.singular) and not bool(jac.type_ii)
    assert float(jac.dexterity) == 0.0 and float(jac.singularity_margin) <= TOL["documented"]
    np.testing.assert_allclose(jac.b, measured["b"], atol=TOL["model"])


@pytest.mark.parametrize("factor", TOL["within"])
def test_poses_within_the_tolerance_of_type_i_are_flagged(
    type_i: dict[str, object], factor: float
) -> None:
    theta, R = _at_leg_margin(type_i, factor * TOL["documented"])
    # Through the library's own forward kinematics (the home mode, theta only) ...
    batch = spm.jacobian(theta[None])
    assert bool(batch.reachable[0])
    np.testing.assert_allclose(batch.R[0], R, atol=TOL["model"])
    assert bool(batch.type_i[0]) and bool(batch.singular[0]) and not bool(batch.type_ii[0])
    assert float(batch.dexterity[0]) == 0.0
    # ... and with the rotation given.
    given = spm.jacobian(theta, R=R)
    assert bool(given.type_i) and float(given.dexterity) == 0.0
    assert float(given.singularity_margin) == pytest.approx(factor * TOL["documented"], rel=1e-3)


@pytest.mark.parametrize("factor", TOL["regular"])
def test_near_singular_regular_poses_are_not_flagged_type_i(
    type_i: dict[str, object], factor: float
) -> None:
    margin = factor * TOL["documented"]
    theta, R = _at_leg_margin(type_i, margin)
    measured = measures(theta, R)
    for jac in (spm.jacobian(theta), spm.jacobian(theta, R=R)):
        assert not bool(jac.type_i) and not bool(jac.type_ii) and not bool(jac.singular)
        assert np.all(np.isfinite(jac.J))
        assert float(jac.singularity_margin) == pytest.approx(margin, rel=1e-3)
        assert float(jac.dexterity) == pytest.approx(measured["dexterity"], rel=1e-6)
        assert float(jac.dexterity) > 0.0
        np.testing.assert_allclose(jac.b, measured["b"], atol=TOL["model"])
        assert float(jac.det_a) == pytest.approx(measured["det_a"], abs=TOL["model"])


# ------------------------------------------------------------ type II: det A = 0
#: A family of rotations about a fixed axis, leg 1 in its other working mode: det A
#: changes sign between s = 0.425 and 0.475 rad.
_AXIS = np.array([0.106, -0.444, 0.041]) / np.linalg.norm([0.106, -0.444, 0.041])
_MODE = (1, 0, 0)


def _type_ii_pose(s: float) -> tuple[np.ndarray, np.ndarray]:
    R = rot(s * _AXIS)
    theta = ik_roots(R)[[0, 1, 2], list(_MODE)]
    return theta, R


@pytest.fixture(scope="module")
def type_ii() -> float:
    def det_a(s: float) -> float:
        return -measures(*_type_ii_pose(s))["det_a"]

    return bisect(det_a, 0.425, 0.475, 0.0)


def _at_a_margin(s_star: float, margin: float) -> tuple[np.ndarray, np.ndarray]:
    def sa(s: float) -> float:
        return float(measures(*_type_ii_pose(s))["sa"])

    s = bisect(sa, 0.425, s_star, margin)
    theta, R = _type_ii_pose(s)
    measured = measures(theta, R)
    assert measured["sa"] == pytest.approx(margin, rel=TOL["bisect"])
    assert measured["leg"] > 0.5 and measured["closure"] < 1e-14
    return theta, R


def test_exact_type_ii_pose_is_singular(type_ii: float) -> None:
    theta, R = _type_ii_pose(type_ii)
    measured = measures(theta, R)
    assert abs(measured["det_a"]) < 1e-12
    jac = spm.jacobian(theta[None], R=R[None])
    assert bool(jac.type_ii[0]) and bool(jac.singular[0]) and not bool(jac.type_i[0])
    assert np.all(np.isnan(jac.J[0]))
    assert abs(float(jac.det_a[0])) < 1e-12
    with pytest.raises(SingularityError, match="type II"):
        spm.jacobian(theta, R=R)


@pytest.mark.parametrize("factor", TOL["within"])
def test_poses_within_the_tolerance_of_type_ii_are_flagged(type_ii: float, factor: float) -> None:
    theta, R = _at_a_margin(type_ii, factor * TOL["documented"])
    jac = spm.jacobian(theta[None], R=R[None])
    assert bool(jac.type_ii[0]) and bool(jac.singular[0]) and not bool(jac.type_i[0])
    assert np.all(np.isnan(jac.J[0]))
    match = r"type II \(parallel\) singularity at theta = .* deg: det A = .*does not exist"
    with pytest.raises(SingularityError, match=match):
        spm.jacobian(theta, R=R)


@pytest.mark.parametrize("factor", TOL["regular"])
def test_near_singular_regular_poses_are_not_flagged_type_ii(type_ii: float, factor: float) -> None:
    margin = factor * TOL["documented"]
    theta, R = _at_a_margin(type_ii, margin)
    measured = measures(theta, R)
    jac = spm.jacobian(theta, R=R)
    assert not bool(jac.type_ii) and not bool(jac.type_i) and not bool(jac.singular)
    assert np.all(np.isfinite(jac.J))
    assert float(jac.singularity_margin) == pytest.approx(margin, rel=1e-3)
    assert float(jac.det_a) == pytest.approx(measured["det_a"], abs=TOL["model"])
    assert float(jac.dexterity) == pytest.approx(measured["dexterity"], rel=1e-5)
    assert float(jac.dexterity) > 0.0


# ------------------------------------------------------------ regular poses
@pytest.mark.parametrize("tilt_deg", [(0, 0, 0), (20, 0, 0), (0, 25, 0), (10, -15, 30)])
def test_measures_match_the_independent_computation(tilt_deg: tuple[float, float, float]) -> None:
    R = rot(np.radians(tilt_deg))
    roots = ik_roots(R)
    theta = np.empty(3)
    for i in range(3):  # home working mode: b_ii > 0
        theta[i] = next(
            t for t in roots[i] if np.cross(U, w_axes(np.full(3, t))[i]) @ (R @ V0[i]) > 0
        )
    measured = measures(theta, R)
    jac = spm.jacobian(theta)
    np.testing.assert_allclose(jac.R, R, atol=TOL["model"])
    np.testing.assert_allclose(jac.b, measured["b"], atol=TOL["model"])
    assert float(jac.det_a) == pytest.approx(measured["det_a"], abs=TOL["model"])
    assert float(jac.singularity_margin) == pytest.approx(measured["margin"], abs=TOL["model"])
    assert float(jac.dexterity) == pytest.approx(measured["dexterity"], abs=TOL["model"])
    assert not bool(jac.singular)
