"""Pictures of the orientation environments.

``rgb_array``: a matplotlib line drawing (the ``plot`` extra) of the legs' unit
vectors on the unit sphere, seen obliquely from above: for each leg the proximal link
as the great-circle arc u -> w_i, the distal link as w_i -> v_i, the platform as the
arcs between the v_i, the goal's platform dashed. A few milliseconds a frame, with no
browser. ``human``: the robot's meshes in meshcat (:class:`~spm_pin.viz.Visualizer`,
the ``viz`` extra), built and started at the first frame.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign

if TYPE_CHECKING:
    from ..viz import Visualizer

__all__ = ["FRAME_PIXELS", "HumanView", "draw_frame"]

FloatArray = npt.NDArray[np.float64]
#: Width and height of an ``rgb_array`` frame [pixels].
FRAME_PIXELS = 320
_LEG_COLOURS = ("tab:red", "tab:green", "tab:blue")
#: The view: azimuth and elevation [rad] of the viewer's direction.
_AZIMUTH, _ELEVATION = math.radians(-60.0), math.radians(25.0)


def _view_basis() -> FloatArray:
    """Rows: the screen's right and up directions in the world frame."""
    ca, sa = math.cos(_AZIMUTH), math.sin(_AZIMUTH)
    ce, se = math.cos(_ELEVATION), math.sin(_ELEVATION)
    towards = np.array([ce * ca, ce * sa, se])  # from O to the viewer
    right = np.cross([0.0, 0.0, 1.0], towards)
    right /= np.linalg.norm(right)
    up = np.cross(towards, right)
    return np.stack([right, up])


def _arc(a: FloatArray, b: FloatArray, samples: int = 16) -> FloatArray:
    """Points (samples, 3) of the great-circle arc from unit vector a to b."""
    angle = math.acos(max(-1.0, min(1.0, float(a @ b))))
    t = np.linspace(0.0, 1.0, samples)[:, None]
    if angle < 1e-9:
        return np.repeat(a[None], samples, axis=0)
    points: FloatArray = (np.sin((1 - t) * angle) * a + np.sin(t * angle) * b) / math.sin(angle)
    return points


def draw_frame(axes: tuple[FloatArray, ...]) -> npt.NDArray[np.uint8]:
    """An RGB picture (FRAME_PIXELS, FRAME_PIXELS, 3) of the legs.

    Args:
        axes: (u, w, v, goal v): the unit vectors of the three legs as rows, (3, 3)
            each.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    u, w, v, goal = axes
    basis = _view_basis()
    figure = Figure(figsize=(FRAME_PIXELS / 100, FRAME_PIXELS / 100), dpi=100)
    canvas = FigureCanvasAgg(figure)
    ax = figure.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(-1.1, 1.1)
    ax.set_ylim(-1.1, 1.1)
    ax.set_aspect("equal")
    ax.axis("off")
    circle = np.linspace(0.0, 2.0 * math.pi, 73)
    ax.plot(np.cos(circle), np.sin(circle), color="0.8", linewidth=1.0)

    def line(
        points: FloatArray, colour: str, width: float, alpha: float = 1.0, style: str = "-"
    ) -> None:
        xy = points @ basis.T
        ax.plot(xy[:, 0], xy[:, 1], color=colour, linewidth=width, alpha=alpha, linestyle=style)

    for i in range(3):
        colour = _LEG_COLOURS[i]
        line(_arc(u[i], w[i]), colour, 3.0)
        line(_arc(w[i], v[i]), colour, 2.0, alpha=0.6)
        line(_arc(v[i], v[(i + 1) % 3]), "0.2", 2.5)
        line(_arc(goal[i], goal[(i + 1) % 3]), "0.2", 1.0, style="--")
    line(np.stack([np.zeros(3), u[0]]), "0.4", 1.0)
    canvas.draw()  # type: ignore[no-untyped-call]
    rgba = np.asarray(canvas.buffer_rgba())  # type: ignore[no-untyped-call]
    frame: npt.NDArray[np.uint8] = np.array(rgba[..., :3], dtype=np.uint8)
    return frame


class HumanView:
    """The robot in meshcat, started at the first :meth:`show`.

    Args:
        design: The design drawn.
    """

    def __init__(self, design: SPMDesign) -> None:
        self.design = design
        self._viz: Visualizer | None = None

    def show(self, theta: FloatArray) -> None:
        """Show the robot at input angles theta [rad]."""
        if self._viz is None:
            from ..collision import build_robot
            from ..viz import Visualizer

            self._viz = Visualizer(build_robot(self.design), check_collisions=False)
            self._viz.start()
        self._viz.display(theta)

    @property
    def url(self) -> str | None:
        """The viewer's address, once started."""
        return None if self._viz is None else self._viz.url

    def close(self) -> None:
        """Stop the meshcat server."""
        if self._viz is not None:
            self._viz.stop()
            self._viz = None
