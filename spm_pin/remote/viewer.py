"""The meshcat scene following a twin live (``spm serve --viewer``).

:class:`TwinViewer` polls a twin's input angles in a thread of its own and shows
every new pose in a :class:`~spm_pin.viz.Visualizer` (colliding links black, their
contacts marked), at most ``rate`` times a second. The visualizer has its own robot
model: the viewer never touches the twin's (Pinocchio's data is not shared between
threads). Needs the ``viz`` extra (meshcat).
"""

from __future__ import annotations

import math
import threading
from types import TracebackType
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError, SPMError
from .backend import TwinBackend

if TYPE_CHECKING:
    from ..viz import Visualizer

__all__ = ["DEFAULT_VIEWER_RATE", "TwinViewer"]

#: Poses shown per second at most.
DEFAULT_VIEWER_RATE = 20.0


class TwinViewer:
    """Shows a twin's pose in meshcat as it moves.

    Args:
        twin: The twin to follow.
        visualizer: The visualizer to draw in (default: a new one of the twin's
            design, with its own robot model).
        rate: Poses shown per second at most (> 0).

    Attributes:
        visualizer: The visualizer.
        shown: Poses shown so far.
        error: The last error of a display (the viewer goes on), or None.
    """

    def __init__(
        self,
        twin: TwinBackend,
        visualizer: Visualizer | None = None,
        *,
        rate: float = DEFAULT_VIEWER_RATE,
    ) -> None:
        if isinstance(rate, bool) or not isinstance(rate, int | float) or not 0 < rate < math.inf:
            raise InputError(
                f"rate must be a positive number of poses per second, got {rate!r}",
                argument="rate",
                value=rate,
            )
        if visualizer is None:
            from ..collision import build_robot
            from ..viz import Visualizer

            visualizer = Visualizer(build_robot(twin.design))
        self.twin = twin
        self.visualizer = visualizer
        self.period = 1.0 / float(rate)
        self.shown = 0
        self.error: str | None = None
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._last: bytes | None = None

    def show(self) -> bool:
        """Show the twin's present pose if it changed; True when something was drawn."""
        theta = np.asarray(self.twin.joints(), dtype=float)
        key = theta.tobytes()
        if key == self._last:
            return False
        try:
            self.visualizer.display(theta)
        except SPMError as exc:  # e.g. a pose without assembly: keep the last one
            self.error = f"{type(exc).__name__}: {exc}"
            return False
        self._last = key
        self.shown += 1
        return True

    def start(self) -> str:
        """Start the meshcat server and the thread that follows the twin.

        Returns:
            The URL of the viewer page.
        """
        url = self.visualizer.start()
        self.show()
        self._closing.clear()
        self._thread = threading.Thread(target=self._follow, name="spm-twin-viewer", daemon=True)
        self._thread.start()
        return url

    def _follow(self) -> None:
        while not self._closing.wait(self.period):
            self.show()

    def stop(self) -> None:
        """Stop following and stop the meshcat server."""
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
            self._thread = None
        self.visualizer.stop()

    def __enter__(self) -> TwinViewer:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
