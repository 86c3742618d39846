"""The certified cover of the safe set (spm_pin.planning.cover).

A cell that the cover calls certified must be safe at every point: random points in
random certified cells of every level are checked by an independent checker, the
servos' safety guard on a robot model of its own. The cell walk is checked against
plain geometry, the single-input vertices against the batch kinematics, and a path
that collides is never certified.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.errors import InputError
from spm_pin.hardware.config import SafetyLimits
from spm_pin.hardware.guard import SafetyGuard
from spm_pin.planning import SafeSet, safe_set_of
from spm_pin.planning.cover import SAMPLE_LEVEL, SafeCover

NOTCH_START_DEG = [71.0, 8.0, 67.0]  # the straight line to the goal collides
NOTCH_GOAL_DEG = [33.0, -37.0, 8.0]


@pytest.fixture(scope="module")
def safe() -> SafeSet:
    return safe_set_of()


@pytest.fixture(scope="module")
def guard(safe: SafeSet) -> SafetyGuard:
    s = safe.settings
    limits = SafetyLimits(
        collision_margin=s.margin,
        min_dexterity=s.min_dexterity,
        min_singularity_margin=s.min_singularity_margin,
    )
    return SafetyGuard(spm.build_robot(), limits)


@pytest.fixture(scope="module")
def grown(safe: SafeSet) -> SafeCover:
    """A cover of its own, grown by random paths between safe grid vertices."""
    cover = SafeCover(safe)
    rng = np.random.default_rng(3)
    vertices = np.argwhere(safe.safe)
    for _ in range(12):
        (i0, j0), (i1, j1) = vertices[rng.integers(len(vertices), size=2)]
        path = safe.theta_of(safe.d12[[i0, i1]], safe.d23[[j0, j1]], 0.0)
        cover.covers(path)
    # Paths to vertices at the boundary of the safe set, and into the notch: the
    # cells near the boundary are halved down to the finest level.
    mask = safe.safe
    edge = mask.copy()
    edge[1:-1, 1:-1] &= ~(mask[:-2, 1:-1] & mask[2:, 1:-1] & mask[1:-1, :-2] & mask[1:-1, 2:])
    boundary = np.argwhere(edge)
    for _ in range(8):
        (i0, j0) = vertices[rng.integers(len(vertices))]
        (i1, j1) = boundary[rng.integers(len(boundary))]
        cover.covers(safe.theta_of(safe.d12[[i0, i1]], safe.d23[[j0, j1]], 0.0))
    cover.covers(np.radians([NOTCH_START_DEG, NOTCH_GOAL_DEG]))
    return cover


def test_crossings_split_a_segment_exactly_at_the_grid_lines() -> None:
    rng = np.random.default_rng(0)
    for _ in range(200):
        step = float(rng.choice([0.5, 0.25, 0.0625]))
        p = tuple(rng.uniform(1.0, 50.0, 2))
        d = tuple(rng.uniform(-5.0, 5.0, 2) * rng.integers(0, 2, 2))  # axis-parallel too
        t0, t1 = sorted(rng.uniform(0.0, 1.0, 2))
        pieces = SafeCover._crossings(p, d, step, t0, t1)
        assert pieces[0][0] == t0 and pieces[-1][1] == t1
        for (_, b, _, _), (a, _, _, _) in itertools.pairwise(pieces):
            assert a == b  # contiguous
        for a, b, i, j in pieces:
            for t in a + (b - a) * rng.uniform(0.01, 0.99, 5):
                x, y = p[0] + t * d[0], p[1] + t * d[1]
                assert i * step <= x + 1e-9 and x <= (i + 1) * step + 1e-9
                assert j * step <= y + 1e-9 and y <= (j + 1) * step + 1e-9


def test_every_point_of_a_certified_cell_is_safe(
    safe: SafeSet, grown: SafeCover, guard: SafetyGuard
) -> None:
    """Random points of random certified cells (every level), checked by the guard."""
    rng = np.random.default_rng(1)
    cells = list(grown._minima)
    levels = {level for level, _, _ in cells}
    assert len(cells) > 100 and len(levels) >= 3  # the cover has cells of several sizes
    picked = [cells[k] for k in rng.choice(len(cells), size=80, replace=False)]
    for level in levels:  # at least one of each level
        picked.append(next(c for c in cells if c[0] == level))
    for level, i, j in picked:
        step = grown.root / 2**level
        corners = np.array([i, j], dtype=float) * step
        points = corners + rng.uniform(0.0, step, size=(6, 2))
        points = np.vstack([points, corners, corners + step])  # the corners too
        yaw = rng.uniform(-math.pi, math.pi)
        for d12, d23 in points:
            theta = safe.theta_of(d12, d23, yaw)
            verdict = guard.check(theta)
            assert verdict.safe, (level, i, j, d12, d23, verdict.reasons)


def test_single_input_vertices_equal_the_batch(safe: SafeSet) -> None:
    """Small batches of vertices take the float path: the batch values to rounding."""
    cover, batch = SafeCover(safe), SafeCover(safe)
    rng = np.random.default_rng(2)
    keys = [(int(a), int(b)) for a, b in rng.integers(1, 200 * 2**cover.levels, size=(40, 2))]
    keys += [(0, 5), (5, 0), (360 * 2**cover.levels, 32)]  # outside the gap triangle
    for key in keys:
        cover._ensure([key])  # one at a time: the float path
    batch._ensure(keys)  # all at once: numpy
    reachable = 0
    for key in keys:
        one, many = cover._vertices[key], batch._vertices[key]
        assert one[0] == many[0]
        if one[0]:
            reachable += 1
            # Singularity margin, dexterity, q: the single-input forward kinematics
            # equals the batch one to rounding.
            np.testing.assert_allclose(one[1:3], many[1:3], rtol=0, atol=1e-12)
            np.testing.assert_allclose(one[3], many[3], rtol=0, atol=1e-12)
    assert reachable >= 10


def test_a_path_that_collides_is_never_certified(safe: SafeSet) -> None:
    cover = SafeCover(safe)
    path = np.radians([NOTCH_START_DEG, NOTCH_GOAL_DEG])
    assert not cover.covers(path)
    assert cover.certificate(path) is None
    assert not safe.certify(path)[0]


def test_a_certified_path_reports_its_cells(safe: SafeSet, guard: SafetyGuard) -> None:
    """A path certified by cells: the certificate's rows are those cells (measures
    at least the thresholds), and the path is safe densely."""
    cover = SafeCover(safe)
    path = np.radians([[10.0, 5.0, -5.0], [30.0, 20.0, 10.0]])
    certificate = cover.certificate(path)
    assert certificate is not None and certificate.safe.size >= 5
    assert np.all(certificate.singularity_margin >= safe.settings.min_singularity_margin)
    assert np.all(certificate.radius > 0)
    dense = np.linspace(path[0], path[1], 400)
    assert all(guard.check(theta).safe for theta in dense)
    # Asked again, the cover answers from its cells (nothing new evaluated).
    before = dict(cover.stats)
    assert cover.covers(path)
    assert dict(cover.stats) == before


def test_a_saved_cover_reads_back_the_same_cells(
    safe: SafeSet, grown: SafeCover, tmp_path: Path
) -> None:
    route = np.radians([[10.0, 5.0, -5.0], [30.0, 20.0, 10.0]])
    before = grown.certificate(route)  # its cells join the grown cover
    path = tmp_path / "cover.npz"
    grown.save(path)
    loaded = SafeCover(safe)
    safe.checker._plans.clear()  # made again on demand
    loaded.load(path)
    # Loading made the collision check of every level's margin: no plan pays for it.
    for level in range(loaded.levels + 1):
        assert (loaded._margin(level), False, None) in safe.checker._plans, level
    assert np.array_equal(loaded._roots, grown._roots)
    assert loaded._cells == grown._cells and loaded._minima == grown._minima
    # The path is certified from the file alone, unchanged.
    after = loaded.certificate(route)
    assert before is not None and after is not None
    assert np.array_equal(before.dexterity, after.dexterity)
    assert loaded.stats["vertices"] == 0  # nothing evaluated again


def test_a_cover_of_other_settings_or_a_bad_file_is_refused(
    safe: SafeSet, grown: SafeCover, tmp_path: Path
) -> None:
    path = tmp_path / "cover.npz"
    grown.save(path)
    with pytest.raises(InputError, match="another design"):
        SafeCover(safe, levels=4).load(path)  # other cells: another fingerprint
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a cover")
    with pytest.raises(InputError, match="not a saved cover"):
        SafeCover(safe).load(bad)
    with pytest.raises(InputError, match="not a saved cover"):
        SafeCover(safe).load(tmp_path / "missing.npz")


def test_filling_decides_the_root_cells_as_paths_would(safe: SafeSet) -> None:
    filled = SafeCover(safe)
    filled.fill(max_level=0)
    decided = np.argwhere(filled._roots != -1)
    covered = np.argwhere(filled._roots == 1)
    assert len(covered) > 10_000  # most of the safe set is in whole root cells
    lazy = SafeCover(safe)
    rng = np.random.default_rng(4)
    sample = [(int(i), int(j)) for i, j in decided[rng.choice(len(decided), 200, replace=False)]]
    assert lazy._decide(0, sample) == [bool(filled._roots[i, j] == 1) for i, j in sample]


#: A formerly slow straight line (gaps [deg]): it runs along a narrow valley of small
#: clearance where cells of level 3 are not covered, and used to decide thousands of
#: cells of levels 4 and 5 (8493 vertices from an empty cover).
VALLEY_D12_DEG = (140.0, 204.0)
VALLEY_D23_DEG = (170.0, 104.0)
#: Vertices plus samples evaluated to certify it from an empty cover, at most.
VALLEY_MAX_EVALUATIONS = 7500


def test_a_line_along_a_valley_is_certified_by_samples_not_fine_cells(safe: SafeSet) -> None:
    """Cells from SAMPLE_LEVEL on that are not covered (children not decided) have
    their pieces certified by samples: no finer cell is decided, the work stays
    bounded, and the same line asked again evaluates nothing new."""
    cover = SafeCover(safe)
    path = safe.theta_of(np.array(VALLEY_D12_DEG), np.array(VALLEY_D23_DEG), 0.0)
    certificate = cover.certificate(path)
    assert certificate is not None
    assert np.all(certificate.safe)
    assert max(level for level, _, _ in cover._cells) <= SAMPLE_LEVEL
    assert cover.stats["dense"] > 0  # the valley's runs, by samples
    assert cover.stats["vertices"] + cover.stats["samples"] <= VALLEY_MAX_EVALUATIONS
    before = dict(cover.stats)
    assert cover.covers(path)
    assert dict(cover.stats) == before
