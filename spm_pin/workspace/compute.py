"""The computation of a workspace map over the gap plane (:func:`workspace_map`):
grid or sampled points, chunks sent to an executor, a progress bar."""

from __future__ import annotations

import concurrent.futures
import dataclasses
import itertools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from .._checks import FloatArray
from ..design import SPMDesign
from ..errors import InputError
from ._evaluate import chunk_task
from .gaps import coaxial, gap_inputs
from .result import MAP_FIELDS, WorkspaceMap
from .settings import WorkspaceSettings, check_count, check_number

__all__ = ["DEFAULT_CHUNK", "workspace_map"]

IntArray = npt.NDArray[np.int64]

#: Points per chunk sent to the executor by default.
DEFAULT_CHUNK = 2048


def _grid_points(
    step: float, low: float, high: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, IntArray]:
    axis = np.arange(low, high + 0.5 * step, step)
    axis = axis[axis <= high + 1e-9]
    d12, d23 = np.meshgrid(axis, axis, indexing="ij")
    d31 = 360.0 - d12 - d23
    inside = (d31 >= low - 1e-9) & (d31 <= high + 1e-9)
    rows, columns = np.nonzero(inside)
    index = np.stack([rows, columns], axis=1).astype(np.int64)
    return axis, axis.copy(), d12[inside], d23[inside], index


def _sampled_points(
    count: int, seed: int, low: float, high: float
) -> tuple[FloatArray, FloatArray]:
    """Uniform points of the gap triangle (all three gaps in [low, high]), by rejection."""
    rng = np.random.default_rng(seed)
    found: list[FloatArray] = []
    total = 0
    while total < count:
        d = rng.uniform(low, high, size=(4 * count + 16, 2))
        d31 = 360.0 - d.sum(axis=1)
        d = d[(d31 >= low) & (d31 <= high)]
        found.append(d)
        total += d.shape[0]
    points = np.concatenate(found)[:count]
    return points[:, 0], points[:, 1]


def workspace_map(
    design: SPMDesign | str | None = None,
    *,
    step_deg: float = 2.0,
    gap_range_deg: tuple[float, float] = (0.0, 360.0),
    samples: int | None = None,
    seed: int = 0,
    settings: WorkspaceSettings | None = None,
    executor: concurrent.futures.Executor | Any | None = None,
    workers: int = 1,
    chunk_size: int = DEFAULT_CHUNK,
    progress: bool = True,
) -> WorkspaceMap:
    """Map the workspace over the gap plane (see :mod:`spm_pin.workspace`).

    Args:
        design: A coaxial SPM (default: the prototype).
        step_deg: Grid step [deg] (grid maps).
        gap_range_deg: Range of every gap [deg]; points outside are left out. The
            default keeps the proximal links in their order; a lower bound below 0
            also maps links that have passed each other.
        samples: If given, that many random points uniform over the gap domain instead
            of a grid (reproducible for a given ``seed``).
        seed: Seed of the random points.
        settings: What to compute (margin, dexterity threshold, clearance).
        executor: A ``concurrent.futures``-style executor (``submit(fn, *args)``);
            it is used as is and not shut down. Default: a process pool of
            ``workers`` processes, or this process when ``workers`` is 1.
        workers: Processes of the default pool.
        chunk_size: Points per task.
        progress: Show a progress bar (tqdm) on stderr.

    Returns:
        The map.

    Raises:
        InputError: bad arguments or a non-coaxial design.
    """
    design = coaxial(design)
    settings = WorkspaceSettings() if settings is None else settings
    if not isinstance(settings, WorkspaceSettings):
        raise InputError(
            f"settings must be a WorkspaceSettings, got {type(settings).__name__}",
            argument="settings",
            value=settings,
        )
    check_number("settings.margin", settings.margin, 0.0, 0.1)
    check_number("settings.min_dexterity", settings.min_dexterity, 0.0, 1.0)
    try:
        ladder = tuple(float(v) for v in settings.ladder)
    except (TypeError, ValueError, OverflowError):
        ladder = ()
    if (
        not ladder
        or ladder[0] != 0.0
        or not all(math.isfinite(v) for v in ladder)
        or any(b <= a for a, b in itertools.pairwise(ladder))
    ):
        raise InputError(
            "settings.ladder must be increasing margins [m] starting at 0, got "
            f"{settings.ladder!r}",
            argument="settings.ladder",
            value=settings.ladder,
        )
    # The workers and the map get the ladder as floats (cached plans key on floats).
    settings = dataclasses.replace(settings, ladder=ladder)
    try:
        low, high = (float(v) for v in gap_range_deg)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"gap_range_deg must be (low, high) [deg], got {gap_range_deg!r}",
            argument="gap_range_deg",
            value=gap_range_deg,
        ) from exc
    if not (math.isfinite(low) and math.isfinite(high) and -180.0 <= low < high <= 540.0):
        raise InputError(
            f"gap_range_deg must satisfy -180 <= low < high <= 540 [deg], got {gap_range_deg!r}",
            argument="gap_range_deg",
            value=gap_range_deg,
        )
    if 3.0 * low > 360.0 or 3.0 * high < 360.0:
        raise InputError(
            f"gap_range_deg {gap_range_deg!r} holds no point: the three gaps sum to 360 deg",
            argument="gap_range_deg",
            value=gap_range_deg,
        )
    chunk = check_count("chunk_size", chunk_size)
    count_workers = check_count("workers", workers)
    grid: tuple[FloatArray, FloatArray, IntArray] | None
    step: float | None
    if samples is None:
        step = check_number("step_deg", step_deg, 0.05, 60.0)
        axis12, axis23, d12, d23, index = _grid_points(step, low, high)
        grid = (axis12, axis23, index)
        used_seed: int | None = None
    else:
        count = check_count("samples", samples)
        used_seed = check_count("seed", seed, 0)
        d12, d23 = _sampled_points(count, used_seed, low, high)
        grid, step = None, None
    theta = gap_inputs(d12, d23, design)
    n = theta.shape[0]
    starts = list(range(0, n, chunk))

    def run(pool: Any) -> list[dict[str, npt.NDArray[Any]]]:
        futures = {
            pool.submit(chunk_task, design, theta[s : s + chunk], settings): number
            for number, s in enumerate(starts)
        }
        parts: list[dict[str, npt.NDArray[Any]] | None] = [None] * len(starts)
        bar = _progress(n, progress)
        try:
            for future in concurrent.futures.as_completed(futures):
                number = futures[future]
                parts[number] = future.result()
                bar(min(chunk, n - starts[number]))
        finally:
            bar(None)
        return [p for p in parts if p is not None]

    if executor is not None:
        if not callable(getattr(executor, "submit", None)):
            raise InputError(
                "executor must have a concurrent.futures-style submit(fn, *args) method, "
                f"got {type(executor).__name__}",
                argument="executor",
                value=executor,
            )
        chunks = run(executor)
    elif count_workers > 1:
        with concurrent.futures.ProcessPoolExecutor(max_workers=count_workers) as pool:
            chunks = run(pool)
    else:  # one chunk after the other: the bar moves, and Ctrl-C stops at once
        bar = _progress(n, progress)
        try:
            chunks = []
            for s in starts:
                chunks.append(chunk_task(design, theta[s : s + chunk], settings))
                bar(min(chunk, n - s))
        finally:
            bar(None)
    fields = {name: np.concatenate([c[name] for c in chunks]) for name in chunks[0]}
    fields["d12_deg"] = np.asarray(d12, dtype=float)
    fields["d23_deg"] = np.asarray(d23, dtype=float)
    fields["d31_deg"] = 360.0 - fields["d12_deg"] - fields["d23_deg"]
    ordered = {name: fields[name] for name in MAP_FIELDS}
    return WorkspaceMap(
        design=design,
        settings=settings,
        theta=theta,
        fields=ordered,
        grid=grid,
        step_deg=step,
        seed=used_seed,
    )


def _progress(total: int, enabled: bool) -> Callable[[int | None], None]:
    """A tqdm progress bar as a function: bar(k) advances by k points, bar(None) closes."""
    if not enabled:
        return lambda _step: None
    from tqdm.auto import tqdm

    bar = tqdm(total=total, unit="pt", desc="workspace", leave=False)

    def update(step: int | None) -> None:
        if step is None:
            bar.close()
        else:
            bar.update(step)

    return update
