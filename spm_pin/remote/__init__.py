"""The robot model over the network: an HTTP + JSON API of a twin (``spm serve``).

Needs the ``remote`` extra (``pip install "spm-pin[remote]"``, which brings FastAPI,
uvicorn and pydantic); ``import spm_pin`` never imports this package.

* :class:`KinematicBackend`: the model alone, a twin whose input angles jump to each
  goal that the safety guard (:class:`~spm_pin.hardware.guard.SafetyGuard`, the
  same one that guards the servos) accepts. :class:`TwinBackend` is what every twin
  provides.
* :class:`DynamicBackend`: the closed-loop dynamics with the servos' model, simulated
  in real time (``spm serve --sim dynamic``): goals take the time they would take.
* :class:`ServoBackend`: the real servos through the hardware layer, the model in the
  loop (``spm serve --device DEV``); a stop turns their torque off.
* :class:`TwinViewer`: a meshcat scene that follows a twin live (``--viewer``).
* :func:`create_app`: the FastAPI application with the resources ``/state``,
  ``/joints``, ``/orientation``, ``/collisions``, ``/check`` and ``/stop`` (see
  :mod:`spm_pin.remote.app` for the status codes).
* :func:`serve`: serve it with uvicorn (127.0.0.1:8750 by default; other addresses
  only with a bearer token, :func:`load_token`); :class:`BackgroundServer`: the same
  in a thread of this process.
* ``WS /stream`` (:mod:`spm_pin.remote.stream`): the state pushed at a requested
  rate, goals streamed back by the one client that holds the :class:`Lease`; the
  twin stops when that client goes quiet for the deadline or disconnects.
* :class:`Client` and :class:`AsyncClient` (:mod:`spm_pin.remote.client`): the
  Python client of a server, blocking and ``async``, with its streams
  (:class:`Stream`, :class:`AsyncStream`) and errors (:class:`RemoteError`,
  :class:`AuthError`, :class:`RemoteRefusedError`); they need httpx.
"""

from __future__ import annotations

try:
    import fastapi  # noqa: F401
    import pydantic  # noqa: F401
    import uvicorn  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        f"spm_pin.remote needs FastAPI, uvicorn and pydantic ({exc}); install them with: "
        'pip install "spm-pin[remote]"'
    ) from exc

from ._motion import PATH_CHECK, MotionTwin
from .app import DEFAULT_MAX_BODY_BYTES, OPEN_PATHS, create_app
from .backend import (
    CHECK_NAMES,
    RATE_CHECK_NAMES,
    CheckOutcome,
    CollisionState,
    GoalRefusedError,
    GoalReport,
    GuardedTwin,
    PairState,
    TwinBackend,
    TwinState,
)
from .client import (
    DEFAULT_URL,
    AsyncClient,
    AsyncStream,
    AuthError,
    Client,
    RemoteError,
    RemoteRefusedError,
    Stream,
)
from .dynamic import DynamicBackend
from .kinematic import KinematicBackend
from .server import (
    DEFAULT_HOST,
    DEFAULT_PORT,
    TOKEN_ENVIRONMENT_VARIABLE,
    BackgroundServer,
    check_binding,
    is_loopback,
    load_token,
    serve,
)
from .servos import ServoBackend
from .stream import DEFAULT_DEADLINE, DEFAULT_RATE, MAX_RATE, MIN_RATE, Lease, LeaseHeldError
from .viewer import DEFAULT_VIEWER_RATE, TwinViewer

#: The command that installs what this package needs.
INSTALL_REMOTE = 'pip install "spm-pin[remote]"'

__all__ = [
    "CHECK_NAMES",
    "DEFAULT_DEADLINE",
    "DEFAULT_HOST",
    "DEFAULT_MAX_BODY_BYTES",
    "DEFAULT_PORT",
    "DEFAULT_RATE",
    "DEFAULT_URL",
    "DEFAULT_VIEWER_RATE",
    "INSTALL_REMOTE",
    "MAX_RATE",
    "MIN_RATE",
    "OPEN_PATHS",
    "PATH_CHECK",
    "RATE_CHECK_NAMES",
    "TOKEN_ENVIRONMENT_VARIABLE",
    "AsyncClient",
    "AsyncStream",
    "AuthError",
    "BackgroundServer",
    "CheckOutcome",
    "Client",
    "CollisionState",
    "DynamicBackend",
    "GoalRefusedError",
    "GoalReport",
    "GuardedTwin",
    "KinematicBackend",
    "Lease",
    "LeaseHeldError",
    "MotionTwin",
    "PairState",
    "RemoteError",
    "RemoteRefusedError",
    "ServoBackend",
    "Stream",
    "TwinBackend",
    "TwinState",
    "TwinViewer",
    "check_binding",
    "create_app",
    "is_loopback",
    "load_token",
    "serve",
]
