"""Draw the figures of the documentation from the library's own computations.

    python docs/figures.py [--out docs/images] [--workspace-step 2]

writes ``conventions.png`` and ``workspace_gap_map.png``. ``conventions.png``: on the
left the unit sphere around the centre of rotation O with the joint axes u, w_i and v_i
of the prototype at home and the angles alpha1, alpha2 and beta of leg 1; on the right
the view from above with the leg azimuths eta_i, the direction of a positive input
angle theta_1 and the gaps between the proximal links. Every vector is computed by
spm-pin. ``workspace_gap_map.png``: the prototype's workspace map over the gaps
between neighbouring proximal links (a ``--workspace-step`` grid, 2 deg by default, as
in ``spm demo``), drawn by :meth:`spm_pin.workspace.WorkspaceMap.gap_figure`. Both need
matplotlib (``pip install "spm-pin[plot]"``).

The pictures of the robot (``spm_*.png``) come from ``examples/visualize.py --png``.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

import spm_pin as spm

FloatArray = npt.NDArray[np.float64]

#: Leg colours of the meshcat viewer (spm_pin.viz.LINK_COLORS): proximal (dark), distal.
PROXIMAL = ("#0066b3", "#d96600", "#733399")
DISTAL = ("#59a6e6", "#faa640", "#b380d1")
#: Joint-axis colours of the viewer (spm_pin.viz.JOINT_AXIS_COLORS).
AXIS_U, AXIS_W, AXIS_V = "#333333", "#e6b800", "#00a699"
#: The input of leg 1 drawn turned in the top view [deg].
THETA_1_DEG = 35.0
#: Camera of the 3D view [deg], and the world directions that point right and up on
#: the screen for it (for placing labels).
ELEVATION, AZIMUTH = 22.0, -45.0
SCREEN_RIGHT = np.array([-np.sin(np.radians(AZIMUTH)), np.cos(np.radians(AZIMUTH)), 0.0])
SCREEN_UP = np.array([0.0, 0.0, 1.0])


def screen(right: float, up: float) -> FloatArray:
    """A world-frame offset that moves a label right and up on the screen."""
    return np.asarray(right * SCREEN_RIGHT + up * SCREEN_UP, dtype=float)


def arc(a: FloatArray, b: FloatArray, radius: float = 1.0, samples: int = 40) -> FloatArray:
    """Points (samples, 3) of the great-circle arc from unit vector a to unit vector b."""
    angle = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
    t = np.linspace(0.0, 1.0, samples)[:, None]
    if angle < 1e-9:
        return radius * np.repeat(a[None], samples, axis=0)
    points = (np.sin((1 - t) * angle) * a + np.sin(t * angle) * b) / np.sin(angle)
    return np.asarray(radius * points, dtype=float)


def draw_sphere_view(ax: Any, design: spm.SPMDesign) -> None:
    """The 3D view: unit sphere, joint axes at home, link arcs, the angles of leg 1."""
    u, w, v = design.u[0], design.w0, design.v0
    z = np.array([0.0, 0.0, 1.0])
    circle = np.linspace(0.0, 2 * np.pi, 200)
    ax.plot(np.cos(circle), np.sin(circle), 0 * circle, color="0.75", lw=0.8)  # equator
    for azimuth in np.radians([0.0, 90.0]):  # two meridians
        ax.plot(
            np.cos(azimuth) * np.sin(circle),
            np.sin(azimuth) * np.sin(circle),
            np.cos(circle),
            color="0.85",
            lw=0.6,
        )
    ring = np.sin(design.alpha1)  # the circle on which every w_i moves
    ax.plot(
        ring * np.cos(circle),
        ring * np.sin(circle),
        -np.cos(design.alpha1) + 0 * circle,
        color=AXIS_W,
        lw=0.8,
        ls="--",
    )
    # world axes
    for axis, name in ((np.eye(3)[0], "x"), (np.eye(3)[1], "y")):
        ax.plot(*np.stack([0 * axis, 1.25 * axis]).T, color="0.55", lw=0.8)
        ax.text(*(1.32 * axis), name, color="0.4", fontsize=10)
    ax.plot([0, 0], [0, 0], [0, 1.2], color="0.55", lw=0.8, ls="--")
    ax.text(
        *(np.array([0.0, 0.0, 1.2]) + screen(0.05, 0.0)),
        "z: platform normal, up",
        color="0.3",
        fontsize=9,
    )
    # the platform plane at home (v_i lie in it for beta = 90 deg)
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # type: ignore[import-untyped]

    ax.add_collection3d(Poly3DCollection([v], facecolor="0.6", alpha=0.18, edgecolor="0.5"))
    # links as arcs on the sphere, joint axes as arrows from O
    for leg in range(3):
        ax.plot(*arc(u, w[leg]).T, color=PROXIMAL[leg], lw=3.0, solid_capstyle="round")
        ax.plot(*arc(w[leg], v[leg]).T, color=DISTAL[leg], lw=3.0, solid_capstyle="round")
    arrows = [(u, AXIS_U, "u = [0, 0, -1]\n(every u_i)", screen(-0.32, -0.2))]
    for leg in range(3):
        arrows.append((w[leg], AXIS_W, f"w_{leg + 1}", screen(0.1, -0.1)))
        arrows.append((v[leg], AXIS_V, f"v_{leg + 1}", screen(0.0, 0.07)))
    for vector, color, label, offset in arrows:
        ax.quiver(0, 0, 0, *vector, color=color, lw=1.8, arrow_length_ratio=0.1)
        ax.text(*(vector + offset), label, color="black", fontsize=10, ha="center")
    ax.scatter([0], [0], [0], color="black", s=14)
    ax.text(0.03, -0.05, -0.1, "O", fontsize=11, weight="bold")
    # the angles of leg 1, as small arcs near O
    for a, b, radius, text, where in (
        (u, w[0], 0.35, f"α1 = {np.degrees(design.alpha1):.0f}°", screen(0.3, -0.05)),
        (w[0], v[0], 0.45, f"α2 = {np.degrees(design.alpha2):.0f}°", screen(-0.3, -0.12)),
        (z, v[0], 0.42, f"β = {np.degrees(design.beta):.0f}°", screen(-0.22, 0.05)),
    ):
        points = arc(a, b, radius)
        ax.plot(*points.T, color="crimson", lw=1.6)
        middle = points[len(points) // 2]
        ax.text(*(middle + where), text, color="crimson", fontsize=10, ha="center")
    limit = 1.05
    ax.set_xlim(-limit, limit)
    ax.set_ylim(-limit, limit)
    ax.set_zlim(-limit, limit)
    ax.set_box_aspect((1, 1, 1), zoom=1.3)
    ax.view_init(elev=ELEVATION, azim=AZIMUTH)
    ax.set_axis_off()


def draw_top_view(ax: Any, design: spm.SPMDesign) -> None:
    """The view from above: leg azimuths, the sign of theta, the gaps D12, D23, D31."""
    circle = np.linspace(0.0, 2 * np.pi, 200)
    ax.plot(np.cos(circle), np.sin(circle), color="0.8", lw=0.8)
    w, v = design.w0, design.v0
    turned = spm.forward_kinematics(np.radians([THETA_1_DEG, 0.0, 0.0]), design)
    w_turned = turned.w[0]
    corner = np.array([-1.25, -1.1])
    for axis, name in (((0.28, 0.0), "x"), ((0.0, 0.28), "y")):
        tip = corner + np.array(axis)
        ax.annotate("", xy=tip, xytext=corner, arrowprops={"arrowstyle": "->", "color": "0.3"})
        ax.text(*(tip + 0.04), name, color="0.3", fontsize=10)
    ax.text(*(corner - [0.02, 0.13]), "z towards you", color="0.3", fontsize=8)
    ax.plot([0], [0], "ko", ms=3)
    ax.text(-0.15, -0.03, "O", fontsize=10, weight="bold")
    for leg in range(3):
        eta = design.eta[leg]
        direction = np.array([np.cos(eta), np.sin(eta)])
        ax.plot(*np.stack([0 * direction, 1.08 * direction]).T, color="0.7", lw=0.8, ls=":")
        # the proximal link seen from above: from O out to w_i
        ax.plot([0, w[leg, 0]], [0, w[leg, 1]], color=PROXIMAL[leg], lw=4, solid_capstyle="round")
        ax.plot(*w[leg, :2], "o", color=AXIS_W, ms=6)
        ax.plot(*v[leg, :2], "s", color=AXIS_V, ms=6)
        ax.text(
            *(1.24 * direction),
            f"leg {leg + 1}\nη{leg + 1} = {np.degrees(eta):.0f}°",
            fontsize=9,
            ha="center",
            va="center",
            color=PROXIMAL[leg],
        )
        ax.text(
            *(v[leg, :2] * 1.12), f"v_{leg + 1}", fontsize=9, color=AXIS_V, ha="center", va="center"
        )
        ax.text(*(w[leg, :2] + [0.0, 0.08]), f"w_{leg + 1}", fontsize=9, color="0.2", ha="center")
    # a positive theta_1 turns proximal link 1 clockwise seen from above
    ax.plot([0, w_turned[0]], [0, w_turned[1]], color=PROXIMAL[0], lw=2, ls="--", alpha=0.7)
    ax.plot(*w_turned[:2], "o", color=AXIS_W, ms=5, alpha=0.7)
    sweep = np.linspace(0.0, -np.radians(THETA_1_DEG), 30)
    ax.plot(0.5 * np.cos(sweep), 0.5 * np.sin(sweep), color="crimson", lw=1.5)
    ax.annotate(
        "",
        xy=(0.5 * np.cos(sweep[-1]), 0.5 * np.sin(sweep[-1])),
        xytext=(0.5 * np.cos(sweep[-3]), 0.5 * np.sin(sweep[-3])),
        arrowprops={"arrowstyle": "-|>", "color": "crimson"},
    )
    ax.text(
        0.53,
        -0.37,
        f"θ1 = {THETA_1_DEG:.0f}° > 0:\nclockwise from above",
        color="crimson",
        fontsize=9,
    )
    # the gaps between neighbouring proximal links
    gaps = (("D12", 0, 1), ("D23", 1, 2), ("D31", 2, 0))
    for name, i, j in gaps:
        start = design.eta[i]
        stop = design.eta[j] + (2 * np.pi if j < i else 0.0)
        sweep = np.linspace(start + 0.12, stop - 0.12, 40)
        ax.plot(0.25 * np.cos(sweep), 0.25 * np.sin(sweep), color="0.35", lw=1.0)
        middle = 0.5 * (start + stop)
        ax.text(
            0.36 * np.cos(middle),
            0.36 * np.sin(middle),
            name,
            fontsize=9,
            ha="center",
            va="center",
            color="0.25",
        )
    ax.text(
        -1.3,
        -1.36,
        "D12 = 120° + θ1 - θ2,  D23 = 120° + θ2 - θ3,  D31 = 120° + θ3 - θ1",
        fontsize=9,
        color="0.25",
    )
    ax.set_xlim(-1.4, 1.45)
    ax.set_ylim(-1.42, 1.35)
    ax.set_aspect("equal")
    ax.set_axis_off()


def conventions_figure(out: Path) -> Path:
    """Write ``conventions.png`` into directory ``out`` and return its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    design = spm.SPMDesign.prototype()
    figure = plt.figure(figsize=(12.0, 5.8))
    draw_sphere_view(figure.add_subplot(1, 2, 1, projection="3d"), design)
    draw_top_view(figure.add_subplot(1, 2, 2), design)
    figure.subplots_adjust(left=0.0, right=0.98, top=0.92, bottom=0.02, wspace=0.02)
    for x, title in ((0.25, "At home: theta = [0, 0, 0], R = identity"), (0.73, "Seen from above")):
        figure.text(x, 0.95, title, ha="center", fontsize=12)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "conventions.png"
    figure.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(figure)
    return path


def workspace_figure(out: Path, step_deg: float = 2.0) -> Path:
    """Write ``workspace_gap_map.png`` (the prototype's gap map) into ``out``; its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from spm_pin.workspace import workspace_map

    result = workspace_map(step_deg=step_deg, progress=False)
    figure = result.gap_figure()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "workspace_gap_map.png"
    figure.savefig(path, dpi=90, metadata={"Software": None})
    plt.close(figure)
    return path


def planning_figure(out: Path) -> Path:
    """Write ``plan_paths.png`` (two planned paths on the prototype's safe set) into
    ``out``; its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from spm_pin.planning import path_figure, plan, safe_set_of
    from spm_pin.rotations import matrix_from_rpy

    safe = safe_set_of()
    detour = plan(np.radians([71.0, 8.0, 67.0]), np.radians([33.0, -37.0, 8.0]), safe=safe)
    pointing = plan(np.zeros(3), matrix_from_rpy(np.radians([0.0, 20.0, 45.0])), safe=safe)
    figure = path_figure(safe, detour, pointing)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "plan_paths.png"
    figure.savefig(path, dpi=90, metadata={"Software": None})
    plt.close(figure)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "images")
    parser.add_argument(
        "--workspace-step", type=float, default=2.0, help="grid step of the workspace map [deg]"
    )
    args = parser.parse_args()
    print(conventions_figure(args.out))
    print(workspace_figure(args.out, args.workspace_step))
    print(planning_figure(args.out))


if __name__ == "__main__":
    main()
