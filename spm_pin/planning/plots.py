"""Planned paths drawn on the safe set in the gap plane: :func:`path_figure`.

The picture shows the safe set of the search grid (home assembly mode, singularity
margin, dexterity, clearance margin) over the gaps D12, D23 between neighbouring
proximal links, with the planned paths on it and, for comparison, the straight line
between each path's ends. Needs matplotlib (the ``plot`` extra).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .planner import PlannedPath
from .safe_set import SafeSet

__all__ = ["path_figure", "save_path_figure"]

#: Colours of the map: unsafe, safe.
SAFE_COLORS = ("#d9d9d9", "#b8e0b0")


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise InputError(
            'path pictures need matplotlib: pip install "spm-pin[plot]"', argument="plots"
        ) from exc
    return plt


def _gaps(safe: SafeSet, theta: Any) -> tuple[Any, Any]:
    """D12, D23 [deg] along a polyline of input angles, sampled finely (a straight line
    in input space is straight in the gap plane; samples keep it continuous across the
    wrap of the angles)."""
    samples = safe.densify(theta)
    d12, d23, _ = safe.gaps_of(samples)
    return np.unwrap(d12, period=360.0), np.unwrap(d23, period=360.0)


def path_figure(safe: SafeSet, *paths: PlannedPath, title: str | None = None) -> Any:
    """The safe set in the gap plane with ``paths`` drawn on it (a matplotlib Figure).

    Each path is a solid line from a circle (start) to a star (goal), its straight
    line dashed; the legend says which is which and gives the lengths.
    """
    from matplotlib.patches import Patch

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 6.0), dpi=110)
    h = safe.settings.grid_step_deg
    extent = (
        float(safe.d23[0] - h / 2),
        float(safe.d23[-1] + h / 2),
        float(safe.d12[0] - h / 2),
        float(safe.d12[-1] + h / 2),
    )
    from matplotlib.colors import ListedColormap

    ax.imshow(
        safe.safe.astype(float),
        origin="lower",
        extent=extent,
        cmap=ListedColormap(list(SAFE_COLORS)),
        vmin=0.0,
        vmax=1.0,
        interpolation="nearest",
        aspect="equal",
    )
    handles: list[Any] = [
        Patch(facecolor=SAFE_COLORS[1], edgecolor="0.4", label="safe"),
        Patch(facecolor=SAFE_COLORS[0], edgecolor="0.4", label="unsafe"),
    ]
    rows, cols = np.nonzero(safe.safe)
    for k, path in enumerate(paths):
        color = f"C{k}"
        d12, d23 = _gaps(safe, path.theta)
        (line,) = ax.plot(d23, d12, "-", color=color, lw=2.0)
        line.set_label(f"planned path: {path.length_deg:.1f} deg")
        handles.append(line)
        s12, s23 = _gaps(safe, np.vstack([path.start, path.goal]))
        (straight,) = ax.plot(s23, s12, "--", color=color, lw=1.2)
        straight.set_label(f"straight line: {path.straight_length_deg:.1f} deg")
        handles.append(straight)
        ax.plot(d23[0], d12[0], "o", color=color, ms=7, mec="black")
        ax.plot(d23[-1], d12[-1], "*", color=color, ms=12, mec="black")
    if rows.size:
        low12, high12 = safe.d12[rows].min(), safe.d12[rows].max()
        low23, high23 = safe.d23[cols].min(), safe.d23[cols].max()
        pad = 10.0
        ax.set_xlim(low23 - pad, high23 + pad)
        ax.set_ylim(low12 - pad, high12 + pad)
    ax.set_xlabel("gap D23 between proximal links 2 and 3 [deg]")
    ax.set_ylabel("gap D12 between proximal links 1 and 2 [deg]")
    ax.set_title(title or f"Safe set of {safe.design.name!r} and planned paths")
    ax.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.9)
    ax.grid(True, color="white", lw=0.5, alpha=0.6)
    fig.tight_layout()
    return fig


def save_path_figure(
    path_png: str | Path, safe: SafeSet, *paths: PlannedPath, title: str | None = None
) -> Path:
    """Write :func:`path_figure` to a PNG file; returns its path."""
    out = Path(path_png)
    fig = path_figure(safe, *paths, title=title)
    try:
        fig.savefig(out)
    finally:
        _pyplot().close(fig)
    return out
