"""The study's figures (matplotlib, imported when a figure is drawn): the platform
axes along the motion, and the safe workspace over the gaps between the proximal
links."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .._records import FloatArray
from .context import STUDY_AGREEMENT, DemoContext
from .context import degrees_text as _degrees_text

__all__ = ["SAFE_CATEGORIES", "plot_motion", "plot_safe_workspace"]


def _figure(size: tuple[float, float]) -> Any:
    """A matplotlib Figure with an Agg canvas (no global pyplot state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def plot_motion(
    target: Path,
    path_deg: FloatArray,
    v_analytic: FloatArray,
    v_projection: FloatArray,
    v_mujoco: FloatArray | None,
) -> None:
    figure = _figure((13.0, 7.5))
    axes = figure.subplots(2, 3, sharex=True, height_ratios=(2.0, 1.0))
    samples = np.arange(path_deg.shape[0])
    colors = ("tab:red", "tab:green", "tab:blue")
    floor = 1e-17  # exact agreement drawn at the bottom of the log scale
    for i in range(3):
        top, bottom = axes[0, i], axes[1, i]
        for c, (letter, color) in enumerate(zip("xyz", colors, strict=True)):
            top.plot(samples, v_analytic[:, i, c], "-", color=color, lw=1.2, label=letter)
            top.plot(samples, v_projection[:, i, c], "o", mfc="none", color=color, ms=5)
            if v_mujoco is not None:
                top.plot(samples, v_mujoco[:, i, c], "x", color="k", ms=4)
        top.set_title(f"v_{i + 1}")
        top.set_ylim(-1.08, 1.08)
        top.grid(True, alpha=0.3)
        top.legend(loc="best", fontsize=8, title="analytic", title_fontsize=8)
        deviation = np.abs(v_projection[:, i] - v_analytic[:, i]).max(axis=-1)
        bottom.semilogy(samples, np.maximum(deviation, floor), "o-", ms=3, label="projection")
        if v_mujoco is not None:
            gap = np.abs(v_mujoco[:, i] - v_analytic[:, i]).max(axis=-1)
            bottom.semilogy(samples, np.maximum(gap, floor), "x-", ms=4, color="k", label="MuJoCo")
        bottom.axhline(STUDY_AGREEMENT, color="tab:red", ls="--", lw=0.8, label="the study")
        bottom.set_ylim(floor / 2.0, 1e-2)
        bottom.set_xlabel("sample")
        bottom.grid(True, alpha=0.3)
        bottom.legend(loc="center right", fontsize=7)
    axes[0, 0].set_ylabel("component")
    axes[1, 0].set_ylabel("max |v - v_analytic|")
    end = _degrees_text(np.round(path_deg[-1], 6).tolist())
    figure.suptitle(
        f"Platform axes from home to theta = {end} deg: analytic (lines), Newton projection "
        "(circles)" + (", MuJoCo (crosses)" if v_mujoco is not None else "")
    )
    figure.savefig(target, format="png", dpi=100)


#: The categories of the safe-workspace map: value, colour, legend label.
SAFE_CATEGORIES: tuple[tuple[int, str, str], ...] = (
    (0, "0.93", "no home-mode assembly"),
    (1, "tab:red", "links collide"),
    (2, "orange", "dexterity too low"),
    (3, "tab:blue", "safe"),
)


def plot_safe_workspace(
    target: Path | None,
    result: Any,
    gaps: FloatArray,
    colliding_gaps: FloatArray,
    ctx: DemoContext,
) -> Any:
    """The safe set over the gap plane with the motion and the two inputs of the study;
    writes ``target`` (PNG) unless None and returns the figure. The legend lists the
    categories that occur on the map only."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    f = result.fields
    category = np.zeros(len(result))
    reachable = f["reachable"]
    category[reachable] = 2.0
    category[reachable & f["collision"]] = 1.0
    category[f["safe"]] = 3.0
    d12, d23, index = result.grid
    image = np.full((d12.size, d23.size), np.nan)
    image[index[:, 0], index[:, 1]] = category
    colors = [color for _, color, _ in SAFE_CATEGORIES]
    figure = _figure((7.5, 6.8))
    axis = figure.subplots()
    axis.imshow(
        image,
        origin="lower",
        extent=(d23[0], d23[-1], d12[0], d12[-1]),
        cmap=ListedColormap(colors),
        vmin=-0.5,
        vmax=3.5,
        interpolation="nearest",
        aspect="equal",
    )
    axis.plot(gaps[:, 1], gaps[:, 0], "-", color="white", lw=4.0)
    axis.plot(gaps[:, 1], gaps[:, 0], ".-", color="k", lw=1.0, ms=4, label="the motion from home")
    axis.plot(gaps[-1, 1], gaps[-1, 0], "*", color="gold", mec="k", ms=16, label="demonstration")
    axis.plot(
        colliding_gaps[1],
        colliding_gaps[0],
        "X",
        color="tab:red",
        mec="k",
        ms=11,
        label="colliding",
    )
    low = min(float(d23[0]), float(colliding_gaps[1])) - 10.0
    axis.set_xlim(low, float(d23[-1]) + 5.0)
    axis.set_ylim(min(float(d12[0]), float(colliding_gaps[0])) - 10.0, float(d12[-1]) + 5.0)
    axis.set_xlabel("D23 [deg]")
    axis.set_ylabel("D12 [deg]")
    present = set(np.unique(category).astype(int).tolist())
    handles = [
        Patch(color=color, label=label)
        for value, color, label in SAFE_CATEGORIES
        if value in present
    ]
    markers, _ = axis.get_legend_handles_labels()
    axis.legend(handles=handles + markers, loc="upper right", fontsize=8)
    axis.set_title(
        f"{ctx.design.name}: safe workspace over the proximal-link gaps "
        f"({ctx.workspace_step_deg:g} deg grid)",
        fontsize=10,
    )
    if target is not None:
        figure.savefig(target, format="png", dpi=100)
    return figure
