"""See the SPM: meshcat scenes, live in a browser or as self-contained HTML files.

Needs the ``viz`` extra (``pip install "spm-pin[viz]"``, which brings meshcat);
``import spm_pin`` never imports this package.

* :class:`Visualizer`: the robot with its legs in distinct colours, colliding links
  in (shaded) black with their contacts marked (:mod:`spm_pin.viz.contacts`),
  optional joint axes and platform frame, animations, HTML export.
* :class:`MeshcatServer`: a meshcat server process that is always stopped.
* :data:`VIEWS`: the camera's preset views (``iso``, ``top``, ``front``, ``side``),
  :mod:`spm_pin.viz.views`; the key of the colours, :mod:`spm_pin.viz.key`.
* :mod:`spm_pin.viz.browser`: pictures of a scene from a headless Chromium.
"""

from __future__ import annotations

import warnings

try:
    with warnings.catch_warnings():
        # meshcat 0.3.2 imports a module pyzmq deprecated; nothing to act on.
        warnings.filterwarnings(
            "ignore", message="zmq.eventloop.ioloop is deprecated", category=DeprecationWarning
        )
        import meshcat  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        f"spm_pin.viz needs meshcat ({exc}); install it with: pip install 'spm-pin[viz]'"
    ) from exc

from .server import MeshcatServer, ViewerError
from .views import DEFAULT_VIEW, VIEWS
from .visualizer import (
    COLLIDING_COLOR,
    JOINT_AXIS_COLORS,
    LINK_COLORS,
    ROOT,
    RobotAnimation,
    Visualizer,
    link_path,
)

__all__ = [
    "COLLIDING_COLOR",
    "DEFAULT_VIEW",
    "JOINT_AXIS_COLORS",
    "LINK_COLORS",
    "ROOT",
    "VIEWS",
    "MeshcatServer",
    "RobotAnimation",
    "ViewerError",
    "Visualizer",
    "link_path",
]
