"""Forward kinematics: every assembly mode against a brute-force solver, the home
mode, closures, labels, torsion invariance and multi-turn inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _brute_force import brute_force_fk
from conftest import (
    COAXIAL_NAMES,
    DESIGN_NAMES,
    design_names,
    get_design,
    leg_signs,
    loop_residual,
    platform_axes,
    proximal_axes,
    random_inputs,
    reachable_inputs,
    rot_z,
    seeds,
)
from hypothesis import given, settings
from hypothesis import strategies as st

import spm_pin as spm

#: Tolerances of this module.
TOL = {
    # A brute-force solution and one of ours are the same mode [max |R - R'|].
    "match": 1e-9,
    # Loop closure and orthonormality of every solution.
    "closure": 1e-11,
    # forward_kinematics vs the home slot of forward_kinematics_all [max |R - R'|].
    "home_vs_all": 1e-10,
    # Torsion invariance and whole turns [max |R - R'|].
    "invariance": 1e-10,
    # Signs of b_ii and det A are compared only when |value| exceeds this.
    "sign": 1e-8,
    # One input (the float fast path) vs the same input in a batch [max |R - R'|].
    "single_vs_batch": 1e-13,
}

BATCH = 128
#: Random inputs per design compared with the brute-force solver.
BRUTE_FORCE_SAMPLES = 20


# ------------------------------------------------------------- brute force
def _brute_force_cases() -> list[tuple[str, np.ndarray]]:
    cases = []
    for k, name in enumerate(DESIGN_NAMES):
        rng = np.random.default_rng(1000 + k)
        thetas = [np.zeros(3), np.radians([60.0, 90.0, 120.0])]
        thetas += list(random_inputs(rng, BRUTE_FORCE_SAMPLES))
        cases += [(name, theta) for theta in thetas]
    return cases


@pytest.mark.parametrize(
    ("name", "theta"),
    _brute_force_cases(),
    ids=[f"{n}-{i}" for i, (n, _) in enumerate(_brute_force_cases())],
)
def test_all_modes_match_brute_force(name: str, theta: np.ndarray) -> None:
    """Same number of modes; every brute-force solution is one of ours and vice versa."""
    design = get_design(name)
    expected = brute_force_fk(theta, design.u, design.w0, design.v0, design.alpha2)
    every = spm.forward_kinematics_all(theta, design)
    ours = every.R[every.valid]
    assert every.count == len(expected) == len(ours), (
        f"{name} at {np.degrees(theta).round(3)} deg: brute force finds {len(expected)} "
        f"modes, forward_kinematics_all {int(every.count)} ({every.labels})"
    )
    if len(expected) == 0:
        assert not spm.forward_kinematics(theta, design).reachable
        return
    distance = np.abs(expected[:, None] - ours[None]).max(axis=(-2, -1))
    np.testing.assert_array_less(distance.min(axis=1), TOL["match"])  # all found
    np.testing.assert_array_less(distance.min(axis=0), TOL["match"])  # none spurious
    # One to one: distinct modes are far apart, so each has its own partner.
    assert len(set(np.argmin(distance, axis=1))) == len(expected)
    # The home mode: exists iff a brute-force solution satisfies the sign rule (signs
    # recomputed here; b_ii or det A within rounding of 0 is singular, not home: the
    # Agile Eye, for one, always has four modes with every v_i = +-u_i, all b_ii = 0),
    # and then forward_kinematics returns one of those.
    b, _, det_a = leg_signs(design, np.broadcast_to(theta, (len(expected), 3)), expected)
    home = (
        np.all(b > TOL["sign"], axis=-1)
        & (np.sign(det_a) == np.sign(design.home_det_a))
        & (np.abs(det_a) > TOL["sign"])
    )
    fk = spm.forward_kinematics(theta, design)
    assert bool(fk.reachable) == bool(np.any(home))
    if fk.reachable:
        assert np.min(np.abs(expected[home] - fk.R).max(axis=(-2, -1))) < TOL["match"]


def test_brute_force_solver_finds_home() -> None:
    """The reference solver itself: the identity is among the solutions at home."""
    for name in DESIGN_NAMES:
        design = get_design(name)
        found = brute_force_fk(np.zeros(3), design.u, design.w0, design.v0, design.alpha2)
        assert np.min(np.abs(found - np.eye(3)).max(axis=(-2, -1))) < TOL["match"], name


# ------------------------------------------------------ every mode, properties
@settings(max_examples=25)
@given(seed=seeds, name=design_names)
def test_all_modes_are_solutions_with_consistent_labels(seed: int, name: str) -> None:
    design = get_design(name)
    theta = random_inputs(np.random.default_rng(seed), BATCH)
    every = spm.forward_kinematics_all(theta, design)
    valid = every.valid
    assert every.R.shape == (BATCH, 8, 3, 3)
    np.testing.assert_array_equal(every.count, valid.sum(axis=-1))
    # Valid slots come first.
    assert np.all(np.sort(valid, axis=-1)[:, ::-1] == valid)
    assert np.all(np.isnan(every.R[~valid]))
    theta_modes = np.broadcast_to(theta[:, None], (BATCH, 8, 3))[valid]
    R = every.R[valid]
    np.testing.assert_array_less(loop_residual(design, theta_modes, R), TOL["closure"])
    np.testing.assert_allclose(
        np.swapaxes(R, -1, -2) @ R, np.broadcast_to(np.eye(3), R.shape), atol=TOL["closure"]
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=TOL["closure"])
    np.testing.assert_array_less(every.residual[valid], TOL["closure"])
    np.testing.assert_allclose(every.v[valid], platform_axes(design, R), atol=1e-14)
    np.testing.assert_allclose(every.w, proximal_axes(design, theta), atol=1e-14)
    # b, det A, the home rule and the labels, recomputed here.
    b, _, det_a = leg_signs(design, theta_modes, R)
    np.testing.assert_allclose(every.b[valid], b, atol=1e-12)
    np.testing.assert_allclose(every.det_a[valid], det_a, atol=1e-12)
    clear = np.all(np.abs(b) > TOL["sign"], axis=-1) & (np.abs(det_a) > TOL["sign"])
    home = np.all(b > 0, axis=-1) & (np.sign(det_a) == np.sign(design.home_det_a))
    np.testing.assert_array_equal(every.home[valid][clear], home[clear])
    labels = np.array(every.labels, dtype=object)
    for label, bb, dd in zip(labels[valid][clear], b[clear], det_a[clear], strict=True):
        expected = "".join("+" if x > 0 else "-" for x in bb) + ("/+" if dd > 0 else "/-")
        assert label.split("#")[0] == expected
    assert np.all(labels[~valid] == "")
    # Labels are unique per input: the k-th mode sharing signs with earlier slots
    # carries "#k", and modes sharing signs are ordered by growing platform tilt.
    for i in range(BATCH):
        row = [str(x) for x in labels[i][valid[i]]]
        assert len(set(row)) == len(row), row
        for k, label in enumerate(row):
            signs, _, ordinal = label.partition("#")
            earlier = [j for j in range(k) if row[j].split("#")[0] == signs]
            assert ordinal == ("" if not earlier else str(len(earlier) + 1)), row
            for j in earlier:
                # cos(tilt) of the platform normal: the earlier mode tilts less
                cos_j, cos_k = every.R[i, j, 2, 2], every.R[i, k, 2, 2]
                if every.home[i, j] == every.home[i, k]:
                    assert cos_j >= cos_k - 1e-12, row
    # Home-rule modes fill the first slots; home_index and ambiguous follow.
    n_home = every.home.sum(axis=-1)
    for i in range(BATCH):
        assert np.all(every.home[i, : n_home[i]])
    np.testing.assert_array_equal(every.home_index, np.where(n_home > 0, 0, -1))
    np.testing.assert_array_equal(every.ambiguous, n_home > 1)
    # A 3-RRR SPM has an even number of real assembly modes (complex roots pair up).
    assert np.all(every.count % 2 == 0)


def test_agile_eye_always_has_four_degenerate_modes() -> None:
    """Agile Eye (a1 = a2 = 90 deg, orthonormal u_i and v_i0): for every input, the four
    rotations with v_i = s_i u_i (s_1 s_2 s_3 = det of the triads) are assembly modes,
    singular in every leg (b_ii = 0); they never count as the home mode."""
    design = get_design("agile_eye")
    theta = random_inputs(np.random.default_rng(6), 64)
    every = spm.forward_kinematics_all(theta, design)
    for signs in np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]):
        R = np.einsum("i,ij,ik->jk", signs, design.u, design.v0)
        if np.linalg.det(R) < 0:
            R = -R
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        np.testing.assert_array_less(
            loop_residual(design, theta, np.broadcast_to(R, (64, 3, 3))), 1e-12
        )
        distance = np.where(every.valid, np.abs(every.R - R).max(axis=(-2, -1)), np.inf)
        slot = np.argmin(distance, axis=-1)
        np.testing.assert_array_less(distance[np.arange(64), slot], TOL["match"])
        np.testing.assert_array_less(np.abs(every.b[np.arange(64), slot]), TOL["sign"])
        assert not np.any(every.home[np.arange(64), slot])


# ------------------------------------------------------------- the home mode
@settings(max_examples=40)
@given(seed=seeds, name=design_names)
def test_home_mode_agrees_with_all_modes(seed: int, name: str) -> None:
    """forward_kinematics = the home slot of forward_kinematics_all (reachability and R);
    where several modes satisfy the home rule, it returns one of them."""
    design = get_design(name)
    theta = random_inputs(np.random.default_rng(seed), BATCH)
    fk = spm.forward_kinematics(theta, design)
    every = spm.forward_kinematics_all(theta, design)
    index = every.home_index
    np.testing.assert_array_equal(fk.reachable, index >= 0)
    assert np.all(np.isnan(fk.R[~fk.reachable]))
    assert np.all(np.isnan(fk.residual[~fk.reachable]))
    single = fk.reachable & ~every.ambiguous
    rows = np.nonzero(single)[0]
    np.testing.assert_allclose(fk.R[rows], every.R[rows, index[rows]], atol=TOL["home_vs_all"])
    for i in np.nonzero(fk.reachable & every.ambiguous)[0]:
        distance = np.abs(every.R[i][every.home[i]] - fk.R[i]).max(axis=(-2, -1))
        assert distance.min() < TOL["home_vs_all"]
    # The home mode's own invariants.
    reach = fk.reachable
    np.testing.assert_array_less(loop_residual(design, theta[reach], fk.R[reach]), TOL["closure"])
    np.testing.assert_array_less(fk.residual[reach], TOL["closure"])
    b, _, det_a = leg_signs(design, theta[reach], fk.R[reach])
    assert np.all(b > 0)
    assert np.all(np.sign(det_a) == np.sign(design.home_det_a))
    np.testing.assert_allclose(fk.v[reach], platform_axes(design, fk.R[reach]), atol=1e-14)
    np.testing.assert_allclose(fk.w, proximal_axes(design, theta), atol=1e-14)


def test_prototype_home_mode_is_unique(prototype: spm.SPMDesign) -> None:
    theta = random_inputs(np.random.default_rng(8), 20_000)
    every = spm.forward_kinematics_all(theta, prototype)
    assert not np.any(every.ambiguous)
    assert 0.3 < np.mean(every.home_index >= 0) < 0.6
    # Random prototype inputs have 4 or 8 real assembly modes.
    assert set(np.unique(every.count)) <= {4, 8}


def test_reference_chooses_among_ambiguous_home_modes() -> None:
    """Where the home sign rule admits several modes (general design), the reference
    picks the mode nearest to it."""
    design = get_design("general")
    theta = random_inputs(np.random.default_rng(4), 4000)
    every = spm.forward_kinematics_all(theta, design)
    items = np.nonzero(every.ambiguous)[0]
    assert items.size > 0, "expected some ambiguous inputs for the general design"
    for i in items[:10]:
        for R in every.R[i][every.home[i]]:
            fk = spm.forward_kinematics(theta[i], design, reference=R)
            assert fk.reachable
            np.testing.assert_allclose(fk.R, R, atol=TOL["home_vs_all"])


def test_home_and_paper_input(prototype: spm.SPMDesign) -> None:
    fk = spm.forward_kinematics(np.zeros(3), prototype)
    np.testing.assert_allclose(fk.R, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(fk.v, prototype.v0, atol=1e-14)
    np.testing.assert_allclose(fk.w, prototype.w0, atol=1e-14)
    # Conventions: w_i = [sin a1 cos(eta_i - theta_i), sin a1 sin(eta_i - theta_i), -cos a1].
    theta = np.radians([60.0, 90.0, 120.0])
    fk = spm.forward_kinematics(theta, prototype)
    eta = np.radians([0.0, 120.0, 240.0])
    a1 = math.radians(45.0)
    w = np.stack(
        [
            math.sin(a1) * np.cos(eta - theta),
            math.sin(a1) * np.sin(eta - theta),
            np.full(3, -math.cos(a1)),
        ],
        axis=1,
    )
    np.testing.assert_allclose(fk.w, w, atol=1e-14)
    np.testing.assert_allclose(np.sum(fk.w * fk.v, axis=-1), 0.0, atol=1e-14)  # a2 = 90 deg
    assert fk.reachable


def test_unreachable_input(prototype: spm.SPMDesign) -> None:
    """theta = [0, 0, 200] deg: proximal link 3 has passed both others; real assembly
    modes exist but none satisfies the home sign rule (checked by brute force)."""
    theta = np.radians([0.0, 0.0, 200.0])
    fk = spm.forward_kinematics(theta, prototype)
    assert not fk.reachable
    assert np.all(np.isnan(fk.R)) and np.all(np.isnan(fk.v)) and np.isnan(fk.residual)
    found = brute_force_fk(theta, prototype.u, prototype.w0, prototype.v0, prototype.alpha2)
    assert len(found) > 0
    b, _, det_a = leg_signs(prototype, np.broadcast_to(theta, (len(found), 3)), found)
    assert not np.any(np.all(b > 0, axis=-1) & (det_a < 0))
    # Mixed batch: flagged per item.
    batch = np.stack([np.zeros(3), theta, np.radians([60.0, 90.0, 120.0])])
    fk = spm.forward_kinematics(batch, prototype)
    np.testing.assert_array_equal(fk.reachable, [True, False, True])


# ---------------------------------------------------------- invariances
@settings(max_examples=40)
@given(
    seed=seeds,
    name=st.sampled_from(COAXIAL_NAMES),
    c=st.floats(min_value=-4 * math.pi, max_value=4 * math.pi, allow_nan=False),
)
def test_common_input_turns_the_platform_about_z(seed: int, name: str, c: float) -> None:
    """Coaxial SPM: R(theta + c (1, 1, 1)) = Rz(-c) R(theta), in every assembly mode."""
    design = get_design(name)
    theta = random_inputs(np.random.default_rng(seed), BATCH)
    fk = spm.forward_kinematics(theta, design)
    turned = spm.forward_kinematics(theta + c, design)
    np.testing.assert_array_equal(turned.reachable, fk.reachable)
    reach = fk.reachable
    np.testing.assert_allclose(turned.R[reach], rot_z(-c) @ fk.R[reach], atol=TOL["invariance"])
    every = spm.forward_kinematics_all(theta, design)
    every_turned = spm.forward_kinematics_all(theta + c, design)
    np.testing.assert_array_equal(every_turned.count, every.count)
    _assert_same_mode_sets(every_turned, rot_z(-c) @ every.R, every.valid)


def test_prototype_torsion_examples(prototype: spm.SPMDesign) -> None:
    theta = np.radians([60.0, 90.0, 120.0])
    for c in np.radians([-720.0, -35.0, 1.0, 90.0, 400.0]):
        turned = spm.forward_kinematics(theta + c, prototype)
        np.testing.assert_allclose(
            turned.R,
            rot_z(-c) @ spm.forward_kinematics(theta, prototype).R,
            atol=TOL["invariance"],
        )
    # At home the platform only turns: R(c, c, c) = Rz(-c).
    for c in np.radians([-170.0, 30.0, 250.0]):
        np.testing.assert_allclose(
            spm.forward_kinematics(np.full(3, c), prototype).R, rot_z(-c), atol=1e-12
        )


@settings(max_examples=25)
@given(seed=seeds, name=design_names)
def test_whole_turns_of_one_input_change_nothing(seed: int, name: str) -> None:
    design = get_design(name)
    rng = np.random.default_rng(seed)
    theta = random_inputs(rng, BATCH)
    turns = rng.integers(-5, 6, size=theta.shape)
    every = spm.forward_kinematics_all(theta, design)
    shifted = spm.forward_kinematics_all(theta + 2 * np.pi * turns, design)
    np.testing.assert_array_equal(shifted.count, every.count)
    _assert_same_mode_sets(shifted, every.R, every.valid)
    fk = spm.forward_kinematics(theta, design)
    fk_shifted = spm.forward_kinematics(theta + 2 * np.pi * turns, design)
    np.testing.assert_array_equal(fk_shifted.reachable, fk.reachable)
    single = fk.reachable & ~every.ambiguous
    np.testing.assert_allclose(fk_shifted.R[single], fk.R[single], atol=TOL["invariance"])


def _assert_same_mode_sets(result: spm.FKAllResult, R: np.ndarray, valid: np.ndarray) -> None:
    """Every valid R of each item is among the valid modes of ``result`` and vice versa."""
    distance = np.abs(result.R[:, :, None] - R[:, None]).max(axis=(-2, -1))
    both = result.valid[:, :, None] & valid[:, None, :]
    distance = np.where(both, distance, np.inf)
    np.testing.assert_array_less(
        np.where(result.valid, distance.min(axis=2), 0.0), TOL["invariance"]
    )
    np.testing.assert_array_less(np.where(valid, distance.min(axis=1), 0.0), TOL["invariance"])


# ---------------------------------------------------------------- shapes
def test_batch_shapes_are_kept(design: spm.SPMDesign) -> None:
    theta = reachable_inputs(design, np.random.default_rng(2), 12).reshape(2, 2, 3, 3)
    fk = spm.forward_kinematics(theta, design)
    assert fk.R.shape == (2, 2, 3, 3, 3)
    assert fk.reachable.shape == (2, 2, 3)
    flat = spm.forward_kinematics(theta.reshape(-1, 3), design)
    np.testing.assert_allclose(fk.R.reshape(-1, 3, 3), flat.R, atol=1e-15)
    every = spm.forward_kinematics_all(theta, design)
    assert every.R.shape == (2, 2, 3, 8, 3, 3)
    assert every.valid.shape == (2, 2, 3, 8)
    assert np.asarray(every.home_index).shape == (2, 2, 3)
    assert np.array(every.labels, dtype=object).shape == (2, 2, 3, 8)
    one = spm.forward_kinematics(theta[0, 0, 0], design)
    assert one.R.shape == (3, 3)
    assert one.reachable.shape == ()
    np.testing.assert_allclose(one.R, fk.R[0, 0, 0], atol=TOL["single_vs_batch"])


@pytest.mark.parametrize("name", DESIGN_NAMES)
def test_single_input_equals_the_batch(name: str) -> None:
    """One input takes a float fast path; it gives the batch answer, reachable or not."""
    design = get_design(name)
    rng = np.random.default_rng(11)
    theta = np.concatenate(
        [random_inputs(rng, 300), reachable_inputs(design, rng, 300), np.zeros((1, 3))]
    )
    batch = spm.forward_kinematics(theta, design)
    for k, item in enumerate(theta):
        one = spm.forward_kinematics(item, design)
        assert bool(one.reachable) == bool(batch.reachable[k]), item
        if batch.reachable[k]:
            np.testing.assert_allclose(one.R, batch.R[k], atol=TOL["single_vs_batch"])
            assert one.residual <= 1e-12
        else:
            assert np.isnan(one.R).all()


# ------------------------------------------- early detection of unreachable inputs
def _fk_without_table(theta: np.ndarray, design: spm.SPMDesign) -> tuple[np.ndarray, np.ndarray]:
    """The home-mode solve with no early detection (Newton, then the resultant)."""
    from spm_pin.kinematics import fk as fk_module

    reduced, common = fk_module._torsion_split(theta, design)
    R, done = fk_module._home_solve(reduced, design, None)
    if common is not None:
        R = fk_module.turned(fk_module.rotation_about(design.u[0], common), R)
    return R, done


@pytest.mark.parametrize("name", DESIGN_NAMES)
def test_early_unreachable_changes_no_answer(name: str) -> None:
    """100,000 uniform inputs: with the certified unreachable-cell table (coaxial
    designs) reachability and every rotation are those of the full solve."""
    from spm_pin.kinematics import _reach

    design = get_design(name)
    theta = random_inputs(np.random.default_rng(2024), 100_000)
    fk = spm.forward_kinematics(theta, design)
    R, done = _fk_without_table(theta, design)
    np.testing.assert_array_equal(fk.reachable, done)
    np.testing.assert_array_equal(fk.R[done], R[done])
    if design.is_coaxial:
        reduced = theta - theta.mean(axis=1, keepdims=True)
        row, col = _reach.gap_index(reduced)
        table = _reach.cached_table(design)  # built by the batch of 100,000 above
        assert table is not None
        flagged = table[row, col]
        assert not np.any(flagged & done)
        assert np.mean(flagged[~done]) > 0.85  # the table decides most unreachable inputs
    every = spm.forward_kinematics_all(theta[:5_000], design)
    np.testing.assert_array_equal(np.any(every.home, axis=-1), fk.reachable[:5_000])


@pytest.mark.parametrize("name", COAXIAL_NAMES)
def test_early_unreachable_near_the_boundary(name: str) -> None:
    """Points 1e-9..1e-3 rad either side of the reachability boundary (bisected along
    random rays from a reachable to an unreachable input): the same answers as the
    full solve."""
    design = get_design(name)
    rng = np.random.default_rng(7)
    inside = reachable_inputs(design, rng, 300)
    outside = random_inputs(rng, 3_000)
    outside = outside[~_fk_without_table(outside, design)[1]][:300]
    lo, hi = np.zeros(300), np.ones(300)
    for _ in range(45):
        mid = 0.5 * (lo + hi)
        ok = _fk_without_table(inside + mid[:, None] * (outside - inside), design)[1]
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    direction = outside - inside
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    edge = inside + lo[:, None] * (outside - inside)
    steps = np.array([1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3])
    steps = np.concatenate([-steps, steps])
    theta = (edge[:, None] + steps[None, :, None] * direction[:, None]).reshape(-1, 3)
    theta = np.concatenate([theta] * 2)  # >= 4096 items: the table is used
    fk = spm.forward_kinematics(theta, design)
    R, done = _fk_without_table(theta, design)
    np.testing.assert_array_equal(fk.reachable, done)
    np.testing.assert_array_equal(fk.R[done], R[done])
    assert 0.2 < np.mean(done) < 0.8  # both sides are sampled


def test_early_unreachable_only_for_coaxial_batches() -> None:
    """Non-coaxial designs and small batches (table not built yet) take the usual path."""
    from spm_pin.kinematics import fk as fk_module

    theta = np.zeros((10, 3))
    assert fk_module._maybe_reachable(theta, get_design("general")) is None
    assert fk_module._maybe_reachable(theta, get_design("agile_eye")) is None
