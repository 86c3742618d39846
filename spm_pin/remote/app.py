"""The HTTP API of a twin: a FastAPI application (:func:`create_app`).

Resources (JSON in and out; angles in degrees, the unit in the key)::

    GET  /             what this server is: version, design, backend, resources
    GET  /state        the twin's state: theta, orientation, collisions, dexterity, ...
    GET  /joints       the input angles
    PUT  /joints       {"theta_deg": [t1, t2, t3]}: guard, then move; -> the new state
    PUT  /orientation  {"rpy_deg": [r, p, y]} or {"quaternion_wxyz": [w, x, y, z]}:
                       inverse kinematics (home working mode), guard, move; -> the state
    GET  /collisions   every checked link pair: colliding, distance_m
    POST /check        {"theta_deg" | "rpy_deg" | "quaternion_wxyz": [...]}: the verdict
                       on a goal, nothing moves
    POST /stop         halt any motion; -> the state
    GET  /lease        whether a streaming client controls the twin, and the deadline
    WS   /stream       states pushed at ?rate=HZ; targets, lease, release, stop back
                       (see :mod:`spm_pin.remote.stream` and docs/remote.md)

Status codes: 200 with the answer; 409 when the guard refuses a goal (the body names
each failed check and its reason; nothing moved); 422 for a malformed body (NaN,
Infinity, wrong lengths or types, unknown keys, both or neither orientation form,
not JSON; the body names the field), for an orientation that inverse kinematics
cannot reach (the body names the legs that cannot close) and for any other error of
the library (its message); 413 for a body over the size limit (counted on the
received bytes, whatever Content-Length says); 401 with ``WWW-Authenticate: Bearer``
for a missing or wrong token when the server has one. The description of the API
(``/openapi.json``) and its browsable page (``/docs``) stay open: they tell the
shape of the API, nothing of the robot. No resource reads or writes files.

Streaming (``WS /stream``): one controlling client at a time holds the lease; while
it does, ``PUT /joints`` and ``PUT /orientation`` answer 409 (reads, ``/check`` and
``/stop`` stay open to everyone). The lease ends when its holder releases it,
disconnects or stays silent for ``deadline`` seconds; then the twin stops. The token
of a streaming client: the ``Authorization: Bearer`` header, or (browsers cannot set
headers on a WebSocket) a first message ``{"type": "auth", "token": ...}``; a wrong
one closes the connection with code 1008. Not in the query string, where access
logs would keep it.

Browser pages from other origins (``cors_origins``, off by default): a page served
from one of the listed origins may call the API (CORS headers; the preflight of a
``PUT`` with a JSON body or an ``Authorization`` header is answered before the token
is checked, since browsers send it without credentials; the request itself still
needs the token). ``WS /stream`` is not covered by CORS (browsers open WebSockets to
any site), so the server refuses a WebSocket whose ``Origin`` header (which browsers
always send) is neither its own nor an allowed origin: a page of another site open in
a browser on this machine cannot take the lease of a token-less loopback server.
Programs that send no ``Origin`` are not affected.
"""

from __future__ import annotations

import json
import math
import re
import secrets
from collections.abc import Awaitable, Callable, MutableMapping, Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np
from fastapi import Depends, FastAPI, Request, WebSocket
from fastapi.exceptions import RequestValidationError
from fastapi.middleware.cors import CORSMiddleware
from fastapi.responses import JSONResponse
from fastapi.security import HTTPBearer

from .._version import __version__
from ..errors import SPMError, UnreachableError, UnsafeCommandError
from ..rotations import matrix_from_quaternion, matrix_from_rpy
from .backend import GoalRefusedError, TwinBackend, TwinState
from .kinematic import KinematicBackend
from .models import (
    CheckRequest,
    CheckResponse,
    CollisionsResponse,
    ErrorResponse,
    GoalRefusedResponse,
    JointsGoal,
    JointsResponse,
    OrientationGoal,
    StateResponse,
    check_response,
    collisions_response,
    state_response,
)
from .stream import DEFAULT_DEADLINE, Lease, LeaseHeldError, StateCache, stream_session

__all__ = ["DEFAULT_MAX_BODY_BYTES", "OPEN_PATHS", "create_app"]

#: Largest request body accepted [bytes]; larger bodies are answered 413.
DEFAULT_MAX_BODY_BYTES = 16 * 1024
#: Paths that need no token: the API's description and its browsable page.
OPEN_PATHS = frozenset({"/openapi.json", "/docs", "/docs/oauth2-redirect"})

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]


async def _send_json(send: Send, status: int, body: dict[str, Any], headers: Any = ()) -> None:
    payload = json.dumps(body).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(payload)).encode()),
                *headers,
            ],
        }
    )
    await send({"type": "http.response.body", "body": payload})


class _Guarded:
    """ASGI middleware: the bearer token first, then the body size limit.

    The body is read whole (up to the limit) before the application sees it, so a
    body over the limit is refused whether or not its Content-Length says so.
    """

    def __init__(self, app: ASGIApp, token: str | None, max_body_bytes: int) -> None:
        self.app = app
        self._token = None if token is None else token.encode()
        self.max_body_bytes = max_body_bytes

    def _given(self, scope: Scope) -> bytes | None:
        """The bearer token of the request's headers, if any."""
        for name, value in scope.get("headers", ()):
            if name.lower() == b"authorization":
                scheme, _, given = bytes(value).partition(b" ")
                if scheme.lower() == b"bearer":
                    return given.strip()
        return None

    def _authorized(self, scope: Scope) -> bool:
        if self._token is None or scope.get("path") in OPEN_PATHS:
            return True
        given = self._given(scope)
        return given is not None and secrets.compare_digest(given, self._token)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "websocket":
            # The handler closes the connection (1008) without a valid token: from
            # the header, checked here, or from its first message.
            scope["spm.token_given"] = self._given(scope) is not None
            scope["spm.authorized"] = self._authorized(scope)
            await self.app(scope, receive, send)
            return
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if not self._authorized(scope):
            await _send_json(
                send,
                401,
                {"detail": "a valid bearer token is required", "error": "Unauthorized"},
                [(b"www-authenticate", b"Bearer")],
            )
            return
        limit = self.max_body_bytes
        too_large = {
            "detail": f"the request body exceeds {limit} bytes",
            "error": "PayloadTooLarge",
        }
        for name, value in scope.get("headers", ()):
            if name.lower() == b"content-length":
                try:
                    declared = int(value)
                except ValueError:
                    await _send_json(
                        send, 400, {"detail": "bad Content-Length", "error": "BadRequest"}
                    )
                    return
                if declared > limit:
                    await _send_json(send, 413, too_large, [(b"connection", b"close")])
                    return
        body = bytearray()
        while True:
            message = await receive()
            if message["type"] != "http.request":  # the client went away
                return
            body += message.get("body", b"")
            if len(body) > limit:
                await _send_json(send, 413, too_large, [(b"connection", b"close")])
                return
            if not message.get("more_body", False):
                break
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": bytes(body), "more_body": False}
            return await receive()

        await self.app(scope, replay, send)


def _error(status: int, exc: Exception) -> JSONResponse:
    body = ErrorResponse(detail=" ".join(str(exc).split()), error=type(exc).__name__)
    return JSONResponse(body.model_dump(), status_code=status)


def _refused(exc: GoalRefusedError) -> JSONResponse:
    verdict = check_response(exc.report)
    failed = [check for check in verdict.checks if check.passed is False]
    body = GoalRefusedResponse(
        detail=" ".join(str(exc).split()),
        error="GoalRefused",
        failed=failed,
        verdict=verdict,
    )
    return JSONResponse(body.model_dump(), status_code=409)


def _validation_errors(exc: RequestValidationError) -> JSONResponse:
    """422 naming each field; the offending input is left out (it may be NaN)."""
    errors = [
        {
            "loc": [str(part) for part in error.get("loc", ())],
            "msg": str(error.get("msg", "")),
            "type": str(error.get("type", "")),
        }
        for error in exc.errors()
    ]
    return JSONResponse({"detail": errors, "error": "RequestValidationError"}, status_code=422)


def _rotation(rpy_deg: Any, quaternion_wxyz: Any) -> Any:
    if rpy_deg is not None:
        return matrix_from_rpy(np.radians(np.asarray(rpy_deg, dtype=float)))
    return matrix_from_quaternion(np.asarray(quaternion_wxyz, dtype=float))


#: An origin as browsers send it: scheme, host and optional port, no path.
_ORIGIN = re.compile(r"https?://[^/\s?#*]+")


def _check_origins(cors_origins: Sequence[str]) -> tuple[str, ...]:
    """The allowed origins, each ``http(s)://host[:port]`` (no wildcard, no path)."""
    from ..errors import InputError

    if isinstance(cors_origins, str | bytes):
        raise InputError(
            f"cors_origins must be a sequence of origins, not one string: give [{cors_origins!r}]",
            argument="cors_origins",
            value=cors_origins,
        )
    origins = tuple(cors_origins)
    for origin in origins:
        if not isinstance(origin, str) or not _ORIGIN.fullmatch(origin):
            raise InputError(
                f"cors_origins: {origin!r} is not an origin; give scheme, host and port "
                "as a browser sends them, e.g. 'http://127.0.0.1:8000' (no path, no "
                "trailing slash, no wildcard)",
                argument="cors_origins",
                value=origin,
            )
    return origins


def _origin_allowed(origin: str, websocket: WebSocket, allowed: tuple[str, ...]) -> bool:
    """A browser's WebSocket may connect from the server's own pages or from an
    allowed origin; browsers open WebSockets to any site, so this is checked here."""
    if origin in allowed:
        return True
    host = websocket.headers.get("host")
    return host is not None and origin in (f"http://{host}", f"https://{host}")


def create_app(
    backend: TwinBackend | None = None,
    *,
    token: str | None = None,
    max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
    deadline: float = DEFAULT_DEADLINE,
    cors_origins: Sequence[str] = (),
) -> FastAPI:
    """The HTTP API of a twin, as an ASGI application (serve it with uvicorn).

    Args:
        backend: The twin (default: a :class:`~spm_pin.remote.KinematicBackend` of
            the prototype).
        token: With a token, every resource needs ``Authorization: Bearer TOKEN``
            (compared in constant time); without one, none does.
        max_body_bytes: Largest request body accepted [bytes] (larger: 413); also
            the largest message of a streaming client.
        deadline: Seconds the streaming client holding the lease may stay silent
            before the lease ends and the twin stops [s] (> 0).
        cors_origins: Origins (``"http://127.0.0.1:8000"``: scheme, host, port) whose
            browser pages may call the API (CORS); none by default. Preflight
            requests are answered before the token check (browsers send them
            without the ``Authorization`` header), every other request still needs
            the token; answers to allowed origins carry
            ``Access-Control-Allow-Origin``, also a 401, so the page can tell why.

    Returns:
        The FastAPI application.

    Raises:
        InputError: an empty token, a bad ``max_body_bytes`` or ``deadline``, or an
            entry of ``cors_origins`` that is not an origin (a wildcard, a path).
    """
    from ..errors import InputError

    if token is not None and not token:
        raise InputError("token must not be empty", argument="token", value=token)
    if isinstance(max_body_bytes, bool) or not isinstance(max_body_bytes, int):
        raise InputError(
            f"max_body_bytes must be an integer, got {max_body_bytes!r}",
            argument="max_body_bytes",
            value=max_body_bytes,
        )
    if max_body_bytes < 1:
        raise InputError(
            f"max_body_bytes must be >= 1, got {max_body_bytes}",
            argument="max_body_bytes",
            value=max_body_bytes,
        )
    if not isinstance(deadline, int | float) or not 0 < deadline < math.inf:
        raise InputError(
            f"deadline must be a positive number of seconds, got {deadline!r}",
            argument="deadline",
            value=deadline,
        )
    origins = _check_origins(cors_origins)
    twin: TwinBackend = backend if backend is not None else KinematicBackend()
    # Declares the bearer scheme in /openapi.json (the check itself is _Guarded's).
    security = [Depends(HTTPBearer(auto_error=False))] if token is not None else []
    app = FastAPI(
        title="spm-pin twin",
        version=__version__,
        description=f"The {twin.name} twin of the spherical parallel manipulator "
        f"{twin.design.name!r}: read its state, move it through the safety guard, check "
        "goals. Angles in degrees.",
        dependencies=security,
        redoc_url=None,
    )
    app.state.backend = twin
    lease = Lease(float(deadline))
    app.state.lease = lease
    hub = SimpleNamespace(
        twin=twin,
        lease=lease,
        token=None if token is None else token.encode(),
        max_message_bytes=max_body_bytes,
        states=None,  # made in the event loop, at the first connection
    )
    app.state.stream = hub

    def changed(state: TwinState) -> StateResponse:
        """The answer of an HTTP write; pushed states follow it at once."""
        if hub.states is not None:
            hub.states.invalidate()
        return state_response(state)

    app.add_middleware(_Guarded, token=token, max_body_bytes=max_body_bytes)
    if origins:
        # Added last, so outermost: preflights are answered before the token check.
        app.add_middleware(
            CORSMiddleware,
            allow_origins=list(origins),
            allow_methods=["GET", "PUT", "POST"],
            allow_headers=["Content-Type", "Authorization"],
            allow_credentials=False,
        )

    @app.exception_handler(GoalRefusedError)
    async def _on_refused(request: Request, exc: GoalRefusedError) -> JSONResponse:
        return _refused(exc)

    @app.exception_handler(LeaseHeldError)
    async def _on_lease_held(request: Request, exc: LeaseHeldError) -> JSONResponse:
        return _error(409, exc)

    @app.exception_handler(UnsafeCommandError)
    async def _on_unsafe(request: Request, exc: UnsafeCommandError) -> JSONResponse:
        return _error(409, exc)

    @app.exception_handler(UnreachableError)
    async def _on_unreachable(request: Request, exc: UnreachableError) -> JSONResponse:
        return _error(422, exc)

    @app.exception_handler(SPMError)
    async def _on_library_error(request: Request, exc: SPMError) -> JSONResponse:
        return _error(422, exc)

    @app.exception_handler(RequestValidationError)
    async def _on_invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        return _validation_errors(exc)

    refused: dict[int | str, dict[str, Any]] = {
        409: {
            "model": GoalRefusedResponse,
            "description": "The guard refused the goal, or a streaming client holds the lease.",
        },
        422: {"description": "Malformed body, or an error of the library."},
    }

    @app.get("/", summary="What this server is")
    def index() -> dict[str, Any]:
        return {
            "name": "spm-pin",
            "version": __version__,
            "design": twin.design.name,
            "backend": twin.name,
            "resources": [
                "/state",
                "/joints",
                "/orientation",
                "/collisions",
                "/check",
                "/stop",
                "/lease",
                "/stream",
            ],
            "docs": "/docs",
        }

    @app.get("/state", response_model=StateResponse, summary="The twin's state")
    def get_state() -> StateResponse:
        return state_response(twin.state())

    @app.get("/joints", response_model=JointsResponse, summary="The input angles")
    def get_joints() -> JointsResponse:
        theta = np.degrees(twin.joints())
        return JointsResponse(theta_deg=[float(x) + 0.0 for x in theta])

    @app.put(
        "/joints",
        response_model=StateResponse,
        responses=refused,
        summary="Move to input angles (through the guard)",
    )
    def put_joints(goal: JointsGoal) -> StateResponse:
        with lease.writing():
            return changed(twin.move(np.radians(goal.theta_deg)))

    @app.put(
        "/orientation",
        response_model=StateResponse,
        responses=refused,
        summary="Move to a platform orientation (inverse kinematics, then the guard)",
    )
    def put_orientation(goal: OrientationGoal) -> StateResponse:
        theta = twin.solve(_rotation(goal.rpy_deg, goal.quaternion_wxyz))
        with lease.writing():
            return changed(twin.move(theta))

    @app.get("/collisions", response_model=CollisionsResponse, summary="Every link pair")
    def get_collisions() -> CollisionsResponse:
        return collisions_response(twin.collisions())

    @app.post("/check", response_model=CheckResponse, summary="The guard's verdict on a goal")
    def post_check(goal: CheckRequest) -> CheckResponse:
        if goal.theta_deg is not None:
            theta = np.radians(goal.theta_deg)
        else:
            theta = twin.solve(_rotation(goal.rpy_deg, goal.quaternion_wxyz))
        return check_response(twin.check(theta))

    @app.post("/stop", response_model=StateResponse, summary="Halt any motion")
    def post_stop() -> StateResponse:
        return changed(twin.stop("POST /stop"))

    @app.get("/lease", summary="Whether a streaming client controls the twin")
    def get_lease() -> dict[str, Any]:
        return {"held": lease.held, "deadline_s": lease.deadline, "expired": lease.expired}

    @app.websocket("/stream")
    async def stream(websocket: WebSocket) -> None:
        origin = websocket.headers.get("origin")
        if origin is not None and not _origin_allowed(origin, websocket, origins):
            # A browser page of another site: refused before the handshake (HTTP 403).
            await websocket.close(code=1008, reason=f"origin {origin} is not allowed")
            return
        if hub.states is None:
            hub.states = StateCache(twin)
        await stream_session(websocket, hub)

    return app
