"""The certified-cell lookup of the environments' safety checks (spm_pin.envs._safe_lookup).

A state whose gaps lie in a cell that a saved cover certified passes without the safe
set's checks: on tens of thousands of seeded inputs (anywhere in the gap plane, in the
covered cells next to cells that are not covered, near the boundary of the safe set,
and where robots driven by random actions go) every state the lookup passes passes
``SafeSet.evaluate`` too, so the environment's decisions are the same with the cover
and without. Environments with and without a cover step alike, and a file that is not
a cover of the design and limits is refused.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from conftest import ENV_COVER_LEVEL

import spm_pin as spm
from spm_pin.envs import OrientSettings, OrientVectorEnv
from spm_pin.envs import _kinematic_kernel as K
from spm_pin.envs._core import OrientCore
from spm_pin.envs._safe_lookup import BITMAP_DEPTH, SafeLookup
from spm_pin.errors import InputError
from spm_pin.hardware.config import SafetyLimits
from spm_pin.planning import SafeCover, SafeSet, safe_set_of

#: Level the test cover is filled to (root cells and their halves).
FILL_LEVEL = ENV_COVER_LEVEL
#: Random inputs of each kind checked against the safe set.
SAMPLES = 8000


def _parts(cover: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The compiled lookup's cover in its parts: the roots' index (n, n), the words,
    the table of searched levels (levels, 4) and the keys."""
    n = int(cover[K.ROOTS])
    at_words, at_table = int(cover[K.WORDS]), int(cover[K.TABLE])
    levels = int(cover[K.LEVELS])
    index = cover[K.HEADER : K.HEADER + n * n].reshape(n, n)
    table = cover[at_table : at_table + K.TABLE_ROW * levels].reshape(levels, K.TABLE_ROW)
    assert at_words == K.HEADER + n * n
    return index, cover[at_words:at_table], table, cover[at_table + K.TABLE_ROW * levels :]


@pytest.fixture(scope="module")
def settings() -> OrientSettings:
    return OrientSettings()


@pytest.fixture(scope="module")
def safe(settings: OrientSettings) -> SafeSet:
    return safe_set_of(settings.the_design, settings.plan_settings)


@pytest.fixture(scope="module")
def cover_path(env_cover_path: str) -> Path:
    return Path(env_cover_path)


@pytest.fixture(scope="module")
def lookup(safe: SafeSet, cover_path: Path) -> SafeLookup:
    return SafeLookup.from_file(safe, cover_path)


def _in_cells(
    safe: SafeSet, cells: np.ndarray, side: float, rng: np.random.Generator
) -> np.ndarray:
    """One input (3,) [rad] per cell (m, 2) of ``side`` [deg]: uniform in the cell, at
    a random turn about the axis."""
    gaps = (cells + rng.uniform(0.0, 1.0, size=cells.shape)) * side
    yaw = rng.uniform(-math.pi, math.pi, size=cells.shape[0])
    return safe.theta_of(gaps[:, 0], gaps[:, 1], yaw)


def _loaded(safe: SafeSet, path: Path) -> SafeCover:
    cover = SafeCover(safe)
    cover.load(path)
    return cover


def _covered_lattice(roots: np.ndarray, finer: np.ndarray, level: int) -> np.ndarray:
    """The covered cells (:meth:`SafeCover.covered_cells`) on the lattice of ``level``,
    a boolean mask."""
    k = 2**level
    mask = np.repeat(np.repeat(roots, k, axis=0), k, axis=1)
    for lv, i, j in finer.tolist():
        if lv <= level:
            m = 2 ** (level - lv)
            mask[i * m : (i + 1) * m, j * m : (j + 1) * m] = True
    return mask


def _inputs(safe: SafeSet, cover: SafeCover) -> dict[str, np.ndarray]:
    """The seeded inputs (n, 3) [rad] of each kind."""
    rng = np.random.default_rng(11)
    roots, finer = cover.covered_cells()
    step = cover.root
    out: dict[str, np.ndarray] = {}
    # Anywhere in the gap triangle.
    d12 = rng.uniform(0.0, 360.0, SAMPLES)
    d23 = rng.uniform(0.0, 360.0, SAMPLES)
    keep = d12 + d23 < 360.0
    out["plane"] = safe.theta_of(d12[keep], d23[keep], rng.uniform(-math.pi, math.pi, keep.sum()))
    # The covered cells on the edge of the covered region (every level drawn on the
    # finest lattice), and the cells within three of them, covered or not.
    mask = _covered_lattice(roots, finer, FILL_LEVEL)
    inner = mask.copy()
    inner[1:-1, 1:-1] &= mask[:-2, 1:-1] & mask[2:, 1:-1] & mask[1:-1, :-2] & mask[1:-1, 2:]
    edge = np.argwhere(mask & ~inner)
    side = step / 2**FILL_LEVEL
    pick = edge[rng.integers(len(edge), size=SAMPLES)]
    out["covered_edge"] = _in_cells(safe, pick.astype(float), side, rng)
    pick = edge[rng.integers(len(edge), size=SAMPLES)] + rng.integers(-3, 4, size=(SAMPLES, 2))
    out["around_edge"] = _in_cells(safe, pick.astype(float), side, rng)
    assert finer.shape[0] > 0
    for level in np.unique(finer[:, 0]).tolist():
        cells = finer[finer[:, 0] == level][:, 1:]
        pick = cells[rng.integers(len(cells), size=SAMPLES // 2)]
        out[f"covered_level_{level}"] = _in_cells(safe, pick.astype(float), step / 2**level, rng)
    # Within two degrees of a safe grid vertex at the boundary of the safe set.
    mask = safe.safe
    edge_vertices = mask.copy()
    edge_vertices[1:-1, 1:-1] &= ~(
        mask[:-2, 1:-1] & mask[2:, 1:-1] & mask[1:-1, :-2] & mask[1:-1, 2:]
    )
    at = np.argwhere(edge_vertices)[rng.integers(int(edge_vertices.sum()), size=SAMPLES)]
    h = safe.settings.grid_step_deg
    out["boundary"] = safe.theta_of(
        safe.d12[at[:, 0]] + rng.uniform(-h, h, SAMPLES),
        safe.d23[at[:, 1]] + rng.uniform(-h, h, SAMPLES),
        rng.uniform(-math.pi, math.pi, SAMPLES),
    )
    return out


def test_the_lookup_passes_only_states_the_safe_set_passes(
    safe: SafeSet, lookup: SafeLookup, cover_path: Path
) -> None:
    cover = _loaded(safe, cover_path)
    total = 0
    for kind, theta in _inputs(safe, cover).items():
        covered = lookup.covered(theta)
        total += theta.shape[0]
        if kind.startswith("covered"):  # points inside covered cells
            assert covered.all(), kind
        else:
            assert covered.any() and not covered.all(), kind
        verdict = safe.evaluate(theta).safe
        wrong = np.flatnonzero(covered & ~verdict)
        assert wrong.size == 0, (
            f"{kind}: the cover certifies {wrong.size} unsafe inputs, e.g. gaps "
            f"{[float(g[wrong[0]]) for g in safe.gaps_of(theta[wrong[:1]])[:2]]} deg"
        )
    assert total >= 30_000
    # The middle of every covered root cell is covered.
    roots, _ = cover.covered_cells()
    cells = np.argwhere(roots)
    step = lookup.root_step_deg
    middle = safe.theta_of((cells[:, 0] + 0.5) * step, (cells[:, 1] + 0.5) * step, 0.7)
    assert lookup.covered(middle).all()
    assert lookup.covered_root_cells == cells.shape[0]


def test_the_safety_check_decides_the_same_with_and_without_a_cover(
    safe: SafeSet, cover_path: Path
) -> None:
    """The environments' check (joint limits, then the safe set) with the lookup:
    the same verdicts, and the joint limits still refuse a certified state."""
    limits = SafetyLimits(theta_min=(-2.0, -2.0, -2.0), theta_max=(2.0, 2.0, 2.0))
    plain = OrientCore(OrientSettings(limits=limits), 1)
    fast = OrientCore(OrientSettings(limits=limits, cover=str(cover_path)), 1)
    assert fast.lookup is not None and plain.lookup is None
    rng = np.random.default_rng(5)
    at = np.argwhere(safe.safe)[rng.integers(int(safe.safe.sum()), size=6000)]
    theta = safe.theta_of(
        safe.d12[at[:, 0]] + rng.uniform(-1.5, 1.5, at.shape[0]),
        safe.d23[at[:, 1]] + rng.uniform(-1.5, 1.5, at.shape[0]),
        rng.uniform(-2.5, 2.5, at.shape[0]),  # some beyond the joint limits
    )
    outside = np.any(np.abs(theta) > 2.0, axis=1)
    assert 0.05 < outside.mean() < 0.5
    expected = plain.safe(theta)
    np.testing.assert_array_equal(fast.safe(theta), expected)
    certified = fast.lookup.covered(theta)
    assert np.any(certified & outside)  # certified gaps, yet refused by the limits
    assert not np.any(expected & outside)


def _rollout(
    num: int, seed: int, steps: int, fused: bool = True, **options: object
) -> list[tuple[np.ndarray, ...]]:
    env = OrientVectorEnv(num, **options)
    env.core.fused = fused
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    record = [(obs,)]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(
            rng.uniform(-1.0, 1.0, size=(num, 3)).astype(np.float32)
        )
        record.append((obs, reward, terminated, truncated, info["step_fraction"]))
    if options.get("cover") is not None:
        lookup = env.core.lookup
        assert lookup is not None and lookup.settled > 0.3 * lookup.asked
    return record


@pytest.mark.parametrize(
    ("seed", "safety", "goal"),
    [(0, "clip", "random"), (1, "terminate", "random"), (2, "clip", "curriculum")],
)
def test_vector_envs_with_and_without_a_cover_step_alike(
    cover_path: Path, seed: int, safety: str, goal: str
) -> None:
    options: dict[str, object] = {"safety": safety, "goal": goal, "max_steps": 120}
    without = _rollout(24, seed, 250, **options)
    with_cover = _rollout(24, seed, 250, fused=False, cover=str(cover_path), **options)
    for step, (a, b) in enumerate(zip(without, with_cover, strict=True)):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(y, x, err_msg=f"step {step}")
    # The compiled step (its own Newton for the rotation): the same decisions, the
    # same numbers to rounding (the geodesic angle near a half turn amplifies it).
    compiled = _rollout(24, seed, 250, cover=str(cover_path), **options)
    for step, (a, c) in enumerate(zip(without, compiled, strict=True)):
        np.testing.assert_allclose(c[0], a[0], atol=1e-6, err_msg=f"step {step}")
        if step:
            np.testing.assert_allclose(c[1], a[1], atol=1e-6, err_msg=f"step {step}")
            for x, y in zip(a[2:], c[2:], strict=True):
                np.testing.assert_array_equal(y, x, err_msg=f"step {step}")
    clipped = np.concatenate([np.asarray(r[4]) for r in without[1:]])
    assert np.any(clipped < 1.0)  # the safety check did decide something


def test_a_bad_cover_or_one_of_another_design_is_refused(cover_path: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a cover")
    with pytest.raises(InputError, match=r"cover: .*not a saved cover") as info:
        OrientVectorEnv(2, cover=str(bad))
    assert info.value.argument == "cover"
    with pytest.raises(InputError, match="not a saved cover"):
        OrientVectorEnv(2, cover=str(tmp_path / "missing.npz"))
    other = spm.SPMDesign.coaxial(50.0, 90.0, 90.0, name="wider")
    path = tmp_path / "other.npz"
    SafeCover(safe_set_of(other)).save(path)  # an (empty) cover of another design
    with pytest.raises(InputError, match="another design"):
        OrientVectorEnv(2, cover=str(path))
    with pytest.raises(InputError, match="another design"):  # other thresholds
        OrientVectorEnv(2, cover=str(cover_path), limits=SafetyLimits(min_dexterity=0.05))
    for wrong in (3, "", b"cover.npz"):
        with pytest.raises(InputError, match="cover must be None or the path"):
            OrientSettings(cover=wrong)  # type: ignore[arg-type]
    assert OrientSettings(cover=cover_path).cover == str(cover_path)  # type: ignore[arg-type]


def test_the_compiled_lookup_answers_as_numpy(safe: SafeSet, lookup: SafeLookup) -> None:
    """Random inputs and inputs whose gaps lie on the grid lines of the finest cells
    (where a point belongs to the cell below it): the same answers, one by one, with
    the levels held as bitmaps, searched in their keys, or both."""
    pytest.importorskip("numba")
    rng = np.random.default_rng(21)
    anywhere = rng.uniform(-math.pi, math.pi, size=(SAMPLES, 3))
    side = 0.5 / 2**FILL_LEVEL
    lines = rng.integers(0, int(360 / side), size=(SAMPLES, 2)) * side
    on_lines = safe.theta_of(lines[:, 0], lines[:, 1], rng.uniform(-math.pi, math.pi, SAMPLES))
    lookup.compiled = True
    assert lookup._covered_kernel() is not None
    # The bitmaps to every level (the default) and none (every level searched).
    for depth in (BITMAP_DEPTH, 0):
        lookup._arrays = lookup.arrays(depth)
        index, words, table, keys = _parts(lookup._arrays)
        assert (words.size > 0) == (depth > 0)
        assert table.shape[0] == max(FILL_LEVEL - depth, 0) and (keys.size > 0) == (
            depth < FILL_LEVEL
        )
        assert np.all(words == np.floor(words)) and np.all((words >= 0) & (words < 2.0**32))
        assert np.all(np.diff(keys) > 0) or table.shape[0] > 1
        assert np.count_nonzero(index == -2) == lookup.covered_root_cells
        for theta in (anywhere, on_lines, anywhere[:1]):
            lookup.compiled = True
            compiled = lookup.covered(theta)
            lookup.compiled = False
            np.testing.assert_array_equal(compiled, lookup.covered(theta))
            if theta.shape[0] > 1:
                assert np.any(compiled) and not np.all(compiled)
    lookup.compiled = True
    lookup._arrays = lookup.arrays()


def test_bitmaps_and_searched_levels_mix(safe: SafeSet, cover_path: Path) -> None:
    """Half of the cover's level-1 cells split into their four level-2 cells (the same
    points covered): the compiled lookup with level 1 as bitmaps and level 2 searched,
    with both as bitmaps and with both searched answers as numpy, which answers as
    the unsplit cover."""
    pytest.importorskip("numba")
    lookup = SafeLookup.from_file(safe, cover_path)
    plain = SafeLookup.from_file(safe, cover_path)
    n = lookup._roots.shape[0]
    (side, size, keys), *rest = lookup._levels
    assert size == 2 * n and not rest  # the fixture's cover: level 1 alone
    keep, split = keys[::2], keys[1::2]
    i, j = split // size, split % size
    children = np.sort(
        np.concatenate([(2 * i + a) * 2 * size + 2 * j + b for a in (0, 1) for b in (0, 1)])
    )
    lookup._levels = [(side, size, keep), (side / 2, 2 * size, children)]
    rng = np.random.default_rng(5)
    theta = rng.uniform(-math.pi, math.pi, size=(SAMPLES, 3))
    lines = rng.integers(0, int(360 / (side / 2)), size=(SAMPLES, 2)) * (side / 2)
    on_lines = safe.theta_of(lines[:, 0], lines[:, 1], rng.uniform(-math.pi, math.pi, SAMPLES))
    assert lookup._covered_kernel() is not None
    for points in (theta, on_lines):
        plain.compiled = lookup.compiled = False
        expected = plain.covered(points)
        np.testing.assert_array_equal(lookup.covered(points), expected)
        assert np.any(expected) and not np.all(expected)
        for depth, searched in ((1, 1), (BITMAP_DEPTH, 0), (0, 2)):
            lookup._arrays = lookup.arrays(depth)
            assert _parts(lookup._arrays)[2].shape[0] == searched
            lookup.compiled = True
            np.testing.assert_array_equal(lookup.covered(points), expected)


def test_tracked_counts_are_counted_once(safe: SafeSet, cover_path: Path) -> None:
    """A compiled step's counts, tracked by the lookup, add to ``asked`` and
    ``settled`` from then on (not what they held before), alongside the lookups of
    numpy; setting the totals (as the core does to hide its own lookups) keeps them."""
    lookup = SafeLookup.from_file(safe, cover_path)
    rng = np.random.default_rng(5)
    theta = rng.uniform(-math.pi, math.pi, size=(40, 3))
    lookup.compiled = False
    lookup.covered(theta)
    asked, settled = lookup.asked, lookup.settled
    assert asked == 40 and 0 < settled < 40
    counts = np.array([7, 3], dtype=np.int64)  # held before tracking: not counted
    lookup.track(counts)
    assert (lookup.asked, lookup.settled) == (asked, settled)
    counts += [5, 2]  # as a compiled step adds to them
    assert (lookup.asked, lookup.settled) == (asked + 5, settled + 2)
    found = lookup.covered(theta[:10])
    assert lookup.asked == asked + 5 + 10
    assert lookup.settled == settled + 2 + int(np.count_nonzero(found))
    lookup.asked, lookup.settled = 100, 50
    counts += [1, 1]
    assert (lookup.asked, lookup.settled) == (101, 51)


def test_a_lattice_too_fine_for_floats_is_refused(safe: SafeSet, cover_path: Path) -> None:
    """The compiled lookup holds a level's keys i * size + j in floats: a level whose
    keys could pass 2^53 (exact no more) is refused, not looked up wrongly."""
    lookup = SafeLookup.from_file(safe, cover_path)
    n = lookup._roots.shape[0]
    side, size, keys = lookup._levels[0]
    assert lookup.arrays().size > 0
    for level in (17, 18):
        deep = n * 2**level
        lookup._levels = [(side, size, keys), (side / 2**level, deep, np.array([deep + 1]))]
        if float(deep) ** 2 > 2.0**53:
            with pytest.raises(InputError, match="too fine for the compiled lookup"):
                lookup.arrays(depth=1)
        else:
            assert lookup.arrays(depth=1)[-1] == deep + 1
