"""A Python client of ``spm serve``: :class:`Client` (blocking), :class:`AsyncClient`
(``async``) and their streams over ``WS /stream`` (:class:`Stream`, :class:`AsyncStream`).

Needs httpx for HTTP (``pip install httpx``) and ``websockets`` (part of the
``remote`` extra) for streaming; both are imported when first used.

Every method mirrors one resource of the server (see docs/remote.md). Arguments take
anything numpy reads (lists, tuples, arrays; angles in degrees) and are checked
before anything is sent: three (four for a quaternion) finite numbers, exactly one
form of a goal. Answers are plain dicts, the server's JSON as it is sent (angles in
degrees, ``None`` where a value does not exist); :meth:`Client.joints` alone answers
a numpy array.

Errors (every one an :class:`~spm_pin.errors.SPMError`):

* 409, the guard refused the goal: :class:`RemoteRefusedError` (an
  :class:`~spm_pin.errors.UnsafeCommandError`) with each failed check; 409 because a
  streaming client holds the lease: :class:`~spm_pin.remote.LeaseHeldError`.
* 422: :class:`~spm_pin.errors.UnreachableError` for an orientation out of reach,
  else :class:`~spm_pin.errors.InputError`, with the server's reason.
* 401: :class:`AuthError` (the token is missing or wrong).
* No server at the URL, a timeout, any other status: :class:`RemoteError`, naming
  the URL.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import math
import time
from collections.abc import AsyncIterator, Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .._checks import ANGLE_LIMIT, FloatArray, float_array, require_bounded, require_finite
from ..errors import InputError, SPMError, UnreachableError, UnsafeCommandError
from .stream import DEFAULT_RATE, MAX_RATE, MIN_RATE, LeaseHeldError

if TYPE_CHECKING:  # pragma: no cover
    import httpx
    from websockets.asyncio.client import ClientConnection as AsyncConnection
    from websockets.sync.client import ClientConnection

__all__ = [
    "DEFAULT_URL",
    "AsyncClient",
    "AsyncStream",
    "AuthError",
    "Client",
    "RemoteError",
    "RemoteRefusedError",
    "Stream",
]

#: The server :class:`Client` talks to by default (``spm serve`` without options).
DEFAULT_URL = "http://127.0.0.1:8750"
#: Largest |angle| sent [deg]: the library's limit for angles (2048 rad).
_DEGREE_LIMIT = math.degrees(ANGLE_LIMIT)


class RemoteError(SPMError, RuntimeError):
    """The server could not be reached in time, or answered unexpectedly.

    Attributes:
        url: The server's URL.
        status: The HTTP status of the answer (None when there was none).
    """

    def __init__(self, message: str, *, url: str, status: int | None = None) -> None:
        super().__init__(message)
        self.url = url
        self.status = status


class AuthError(RemoteError):
    """The server needs a bearer token and got none, or a wrong one (HTTP 401)."""


class RemoteRefusedError(UnsafeCommandError):
    """The server's safety guard refused a goal (HTTP 409, or ``refused`` on the
    stream); nothing moved.

    Attributes:
        failed: The failed checks, ``{"check": name, "reason": text}`` each.
        checks: The names of the failed checks (e.g. ``("reachable", "collision")``).
        verdict: The server's whole verdict (as ``POST /check`` answers it), or None.
        reasons: The reasons of the failed checks.
        goal: The refused input angles [rad], when the verdict has them.
    """

    def __init__(
        self, message: str, *, failed: list[dict[str, Any]], verdict: dict[str, Any] | None
    ) -> None:
        theta = (verdict or {}).get("theta_deg")
        super().__init__(
            message,
            reasons=tuple(str(check.get("reason")) for check in failed),
            goal=None if theta is None else np.radians(np.asarray(theta, dtype=float)),
        )
        self.failed = tuple(dict(check) for check in failed)
        self.checks = tuple(str(check.get("check")) for check in failed)
        self.verdict = verdict


# ------------------------------------------------------------------------- inputs
def _vector(value: npt.ArrayLike, name: str, size: int, limit: float | None = None) -> list[float]:
    """``value`` as ``size`` finite floats (|x| <= limit), or InputError; nothing is sent."""
    message = f"{name} must be {size} numbers, got {value!r}"
    if isinstance(value, (str, bytes)) or value is None:
        raise InputError(message, argument=name, value=value)
    array: FloatArray = float_array(value, name, message)
    if array.shape != (size,):
        raise InputError(
            f"{name} must be {size} numbers (shape ({size},)), got shape {array.shape}",
            argument=name,
            value=value,
        )
    if limit is None:
        require_finite(array, name, value)
    else:
        require_bounded(array, name, value, limit, "deg")
    return [float(x) for x in array]


def _goal(
    theta_deg: npt.ArrayLike | None,
    rpy_deg: npt.ArrayLike | None,
    quaternion_wxyz: npt.ArrayLike | None,
    *,
    joints: bool = True,
) -> dict[str, list[float]]:
    """The JSON of exactly one goal form, checked."""
    given = {
        name: value
        for name, value in (
            ("theta_deg", theta_deg),
            ("rpy_deg", rpy_deg),
            ("quaternion_wxyz", quaternion_wxyz),
        )
        if value is not None
    }
    names = "theta_deg, rpy_deg or quaternion_wxyz" if joints else "rpy_deg or quaternion_wxyz"
    if len(given) != 1:
        raise InputError(
            f"give exactly one of {names}, got {sorted(given) or 'none'}", argument="goal"
        )
    ((name, value),) = given.items()
    if name == "quaternion_wxyz":
        quaternion = _vector(value, name, 4)
        if not math.hypot(*quaternion) > 1e-12:
            raise InputError(
                f"quaternion_wxyz must not be zero, got {quaternion}", argument=name, value=value
            )
        return {name: quaternion}
    return {name: _vector(value, name, 3, _DEGREE_LIMIT)}


def _stamp(t: float | None) -> float:
    """A streamed goal's time [s]: ``t`` checked, or now on the monotonic clock."""
    if t is None:
        return time.monotonic()
    if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
        raise InputError(f"t must be a finite number of seconds, got {t!r}", argument="t", value=t)
    return float(t)


def _base_url(url: str) -> str:
    if not isinstance(url, str) or not url.startswith(("http://", "https://")):
        raise InputError(
            f"url must start with http:// or https://, got {url!r}", argument="url", value=url
        )
    return url.rstrip("/")


def _headers(token: str | None) -> dict[str, str]:
    if token is None:
        return {}
    if not isinstance(token, str) or not token or any(ord(c) < 33 or ord(c) > 126 for c in token):
        raise InputError(
            "token must be a non-empty string of printable ASCII without spaces", argument="token"
        )
    return {"Authorization": f"Bearer {token}"}


def _timeout(timeout: float) -> float:
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)):
        raise InputError(
            f"timeout must be a number of seconds, got {timeout!r}", argument="timeout"
        )
    if not 0 < timeout < math.inf:
        raise InputError(f"timeout must be > 0 s, got {timeout!r}", argument="timeout")
    return float(timeout)


def _httpx() -> Any:
    try:
        import httpx
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImportError(
            f"spm_pin.remote.Client needs httpx ({exc}); install it with: pip install httpx"
        ) from exc
    return httpx


# ------------------------------------------------------------------------ answers
def _detail(body: Any) -> str:
    """The server's reason, one line (validation errors: ``field: message``)."""
    detail = body.get("detail") if isinstance(body, dict) else body
    if isinstance(detail, list):
        return "; ".join(
            f"{'.'.join(str(part) for part in error.get('loc', ()))}: {error.get('msg', '')}"
            if isinstance(error, dict)
            else str(error)
            for error in detail
        )
    return str(detail)


def _raise_for(status: int, body: Any, url: str, what: str, *, failed_key: str = "failed") -> None:
    """Raise the library's error for an answer that is not a success."""
    detail = _detail(body)
    error = body.get("error") if isinstance(body, dict) else None
    if status == 401:
        raise AuthError(
            f"{what}: the server at {url} needs a valid bearer token (token missing or wrong)",
            url=url,
            status=status,
        )
    if status == 409:
        if error == "LeaseHeldError" or ("lease" in detail and failed_key not in body):
            raise LeaseHeldError(f"{what}: {detail}")
        failed = body.get(failed_key) or [] if isinstance(body, dict) else []
        verdict = body.get("verdict") if isinstance(body, dict) else None
        checks = ", ".join(str(check.get("check")) for check in failed) or "refused"
        raise RemoteRefusedError(
            f"{what} refused by the checks {checks}: {detail}", failed=failed, verdict=verdict
        )
    if status == 422:
        if error == "UnreachableError":
            raise UnreachableError(f"{what}: {detail}")
        raise InputError(f"{what}: the server refused the request: {detail}")
    if status == 413:
        raise InputError(f"{what}: {detail}")
    raise RemoteError(
        f"{what}: the server at {url} answered {status}: {detail}", url=url, status=status
    )


class _Api:
    """What both clients share: the checked requests and the reading of answers."""

    def __init__(self, url: str, token: str | None, timeout: float) -> None:
        self.url = _base_url(url)
        self.timeout = _timeout(timeout)
        self._headers = _headers(token)
        self._token = token

    def _answer(self, response: Any, what: str) -> Any:
        try:
            body = response.json()
        except ValueError:
            body = {"detail": response.text[:200]}
        if response.status_code == 200:
            return body
        _raise_for(response.status_code, body, self.url, what)
        return None  # pragma: no cover - _raise_for always raises

    def _unreachable(self, exc: Exception, what: str) -> RemoteError:
        kind = "timed out" if "Timeout" in type(exc).__name__ else "failed"
        return RemoteError(
            f"{what}: no answer from the spm server at {self.url} ({kind} after at most "
            f"{self.timeout:g} s: {exc or type(exc).__name__})",
            url=self.url,
        )


class Client(_Api):
    """A blocking client of ``spm serve`` (on httpx); use it as a context manager.

    Args:
        url: The server, ``http://host:port`` (default ``http://127.0.0.1:8750``).
        token: The server's bearer token, when it has one.
        timeout: Seconds to wait for a connection and for each answer.

    Attributes:
        url: As given, without a final ``/``.
        timeout: As given.
        http: The ``httpx.Client`` that sends the requests (its event hooks may be
            extended, e.g. to log every request).

    Raises:
        InputError: a URL that is not http(s), an empty token, a timeout <= 0.
    """

    def __init__(
        self, url: str = DEFAULT_URL, *, token: str | None = None, timeout: float = 5.0
    ) -> None:
        super().__init__(url, token, timeout)
        self.http: httpx.Client = _httpx().Client(
            base_url=self.url, headers=self._headers, timeout=self.timeout
        )

    def _call(self, method: str, path: str, body: Any = None) -> Any:
        what = f"{method} {path}"
        httpx = _httpx()
        try:
            response = self.http.request(method, path, json=body)
        except httpx.HTTPError as exc:
            raise self._unreachable(exc, what) from exc
        return self._answer(response, what)

    def state(self) -> dict[str, Any]:
        """``GET /state``: the twin's state (``theta_deg``, ``R``, ``rpy_deg``, ``pairs``, ...)."""
        return dict(self._call("GET", "/state"))

    def joints(self) -> FloatArray:
        """``GET /joints``: the input angles [deg], shape (3,)."""
        return np.asarray(self._call("GET", "/joints")["theta_deg"], dtype=float)

    def set_joints(self, theta_deg: npt.ArrayLike) -> dict[str, Any]:
        """``PUT /joints``: move to input angles [deg] through the guard; the new state.

        Raises:
            RemoteRefusedError: the guard refused the goal (nothing moved).
            LeaseHeldError: a streaming client controls the twin.
        """
        body = {"theta_deg": _vector(theta_deg, "theta_deg", 3, _DEGREE_LIMIT)}
        return dict(self._call("PUT", "/joints", body))

    def set_orientation(
        self, rpy_deg: npt.ArrayLike | None = None, quaternion_wxyz: npt.ArrayLike | None = None
    ) -> dict[str, Any]:
        """``PUT /orientation``: move to a platform orientation (exactly one form).

        Raises:
            UnreachableError: inverse kinematics has no solution there.
            RemoteRefusedError: the guard refused the goal (nothing moved).
        """
        body = _goal(None, rpy_deg, quaternion_wxyz, joints=False)
        return dict(self._call("PUT", "/orientation", body))

    def collisions(self) -> dict[str, Any]:
        """``GET /collisions``: every checked link pair, ``colliding`` and ``distance_m``."""
        return dict(self._call("GET", "/collisions"))

    def check(
        self,
        theta_deg: npt.ArrayLike | None = None,
        rpy_deg: npt.ArrayLike | None = None,
        quaternion_wxyz: npt.ArrayLike | None = None,
    ) -> dict[str, Any]:
        """``POST /check``: the guard's verdict on a goal (``safe``, ``checks``,
        ``pairs``); nothing moves. Exactly one form of the goal."""
        return dict(self._call("POST", "/check", _goal(theta_deg, rpy_deg, quaternion_wxyz)))

    def stop(self) -> dict[str, Any]:
        """``POST /stop``: halt any motion; the state."""
        return dict(self._call("POST", "/stop"))

    def lease(self) -> dict[str, Any]:
        """``GET /lease``: ``held``, ``deadline_s``, ``expired``."""
        return dict(self._call("GET", "/lease"))

    def stream(self, rate: float = DEFAULT_RATE) -> Stream:
        """``WS /stream`` of this server at ``rate`` [Hz], a :class:`Stream` (use it in
        ``with``)."""
        return Stream(self.url, token=self._token, rate=rate, timeout=self.timeout)

    def close(self) -> None:
        """Close the connections."""
        self.http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AsyncClient(_Api):
    """The ``async`` twin of :class:`Client` (on ``httpx.AsyncClient``): the same
    methods, awaited; use it with ``async with``.

    Attributes:
        http: The ``httpx.AsyncClient`` that sends the requests.
    """

    def __init__(
        self, url: str = DEFAULT_URL, *, token: str | None = None, timeout: float = 5.0
    ) -> None:
        super().__init__(url, token, timeout)
        self.http: httpx.AsyncClient = _httpx().AsyncClient(
            base_url=self.url, headers=self._headers, timeout=self.timeout
        )

    async def _call(self, method: str, path: str, body: Any = None) -> Any:
        what = f"{method} {path}"
        httpx = _httpx()
        try:
            response = await self.http.request(method, path, json=body)
        except httpx.HTTPError as exc:
            raise self._unreachable(exc, what) from exc
        return self._answer(response, what)

    async def state(self) -> dict[str, Any]:
        """``GET /state``, as :meth:`Client.state`."""
        return dict(await self._call("GET", "/state"))

    async def joints(self) -> FloatArray:
        """``GET /joints``, as :meth:`Client.joints`."""
        return np.asarray((await self._call("GET", "/joints"))["theta_deg"], dtype=float)

    async def set_joints(self, theta_deg: npt.ArrayLike) -> dict[str, Any]:
        """``PUT /joints``, as :meth:`Client.set_joints`."""
        body = {"theta_deg": _vector(theta_deg, "theta_deg", 3, _DEGREE_LIMIT)}
        return dict(await self._call("PUT", "/joints", body))

    async def set_orientation(
        self, rpy_deg: npt.ArrayLike | None = None, quaternion_wxyz: npt.ArrayLike | None = None
    ) -> dict[str, Any]:
        """``PUT /orientation``, as :meth:`Client.set_orientation`."""
        body = _goal(None, rpy_deg, quaternion_wxyz, joints=False)
        return dict(await self._call("PUT", "/orientation", body))

    async def collisions(self) -> dict[str, Any]:
        """``GET /collisions``, as :meth:`Client.collisions`."""
        return dict(await self._call("GET", "/collisions"))

    async def check(
        self,
        theta_deg: npt.ArrayLike | None = None,
        rpy_deg: npt.ArrayLike | None = None,
        quaternion_wxyz: npt.ArrayLike | None = None,
    ) -> dict[str, Any]:
        """``POST /check``, as :meth:`Client.check`."""
        return dict(await self._call("POST", "/check", _goal(theta_deg, rpy_deg, quaternion_wxyz)))

    async def stop(self) -> dict[str, Any]:
        """``POST /stop``, as :meth:`Client.stop`."""
        return dict(await self._call("POST", "/stop"))

    async def lease(self) -> dict[str, Any]:
        """``GET /lease``, as :meth:`Client.lease`."""
        return dict(await self._call("GET", "/lease"))

    def stream(self, rate: float = DEFAULT_RATE) -> AsyncStream:
        """``WS /stream`` of this server at ``rate`` [Hz], an :class:`AsyncStream` (use
        it in ``async with``)."""
        return AsyncStream(self.url, token=self._token, rate=rate, timeout=self.timeout)

    async def close(self) -> None:
        """Close the connections."""
        await self.http.aclose()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()


# ---------------------------------------------------------------------- streaming
class _StreamBase:
    """What both streams share: the URL, the numbering and the reading of answers."""

    def __init__(self, url: str, token: str | None, rate: float, timeout: float) -> None:
        base = _base_url(url)
        if isinstance(rate, bool) or not isinstance(rate, (int, float)):
            raise InputError(f"rate must be a number of Hz, got {rate!r}", argument="rate")
        if not MIN_RATE <= rate <= MAX_RATE:
            raise InputError(
                f"rate must lie in {MIN_RATE:g}..{MAX_RATE:g} Hz, got {rate!r}", argument="rate"
            )
        self.url = base
        self.uri = "ws" + base[len("http") :] + f"/stream?rate={rate:g}"
        self.timeout = _timeout(timeout)
        self._headers = _headers(token)
        self._seq = itertools.count()
        #: The ``hello`` of the server (``rate_hz``, ``deadline_s``, ``lease``).
        self.hello: dict[str, Any] = {}
        #: The latest state pushed (None before the first).
        self.latest: dict[str, Any] | None = None
        #: Messages of the server that answer nothing sent (e.g. the lease lost at
        #: the deadline), oldest first.
        self.notices: list[dict[str, Any]] = []

    def _message(self, kind: str, seq: int | None, **fields: Any) -> tuple[int, str]:
        if seq is None:
            seq = next(self._seq)
        elif isinstance(seq, bool) or not isinstance(seq, int):
            raise InputError(f"seq must be an integer, got {seq!r}", argument="seq", value=seq)
        return seq, json.dumps({"type": kind, "seq": seq, **fields})

    def _sort(self, message: dict[str, Any], seq: int) -> bool:
        """Keep a state or a notice; True when ``message`` answers ``seq``."""
        if message.get("type") == "state":
            self.latest = message
            return False
        if message.get("seq") == seq and message.get("type") != "hello":
            return True
        self.notices.append(message)
        return False

    def _check_answer(self, answer: dict[str, Any], what: str) -> dict[str, Any]:
        if answer.get("type") == "error":
            _raise_for(int(answer.get("status", 0)), answer, self.url, what)
        return answer

    def _closed(self, exc: Exception, what: str) -> RemoteError:
        code = getattr(getattr(exc, "rcvd", None), "code", None)
        reason = getattr(getattr(exc, "rcvd", None), "reason", "") or str(exc)
        if code == 1008 and "token" in reason:
            return AuthError(
                f"{what}: the server at {self.url} needs a valid bearer token ({reason})",
                url=self.url,
            )
        return RemoteError(
            f"{what}: the stream of {self.uri} ended or failed: {reason}", url=self.url
        )


class Stream(_StreamBase):
    """``WS /stream`` of a server, blocking (the ``websockets`` sync client).

    Made by :meth:`Client.stream`; use it as a context manager. Entering connects
    (with the ``Authorization`` header when there is a token) and reads the
    ``hello``. The state pushes that arrive while an answer is awaited are kept:
    :attr:`latest` is the newest.

    Args:
        url: The server, ``http://host:port``.
        token: The server's bearer token, when it has one.
        rate: State pushes per second [Hz], 1 to 1000.
        timeout: Seconds to wait for the connection and for each message.
    """

    def __init__(
        self,
        url: str = DEFAULT_URL,
        *,
        token: str | None = None,
        rate: float = DEFAULT_RATE,
        timeout: float = 5.0,
    ) -> None:
        super().__init__(url, token, rate, timeout)
        self._ws: ClientConnection | None = None

    def open(self) -> Stream:
        """Connect and read the ``hello``."""
        from websockets.sync.client import connect

        try:
            connection = connect(
                self.uri, additional_headers=self._headers, open_timeout=self.timeout
            )
        except Exception as exc:
            raise RemoteError(
                f"cannot open the stream {self.uri} within {self.timeout:g} s: {exc}", url=self.url
            ) from exc
        self._ws = connection.__enter__()  # entered: this object is the context manager
        self.hello = self._recv("hello")
        return self

    def _recv(self, what: str) -> dict[str, Any]:
        if self._ws is None:
            raise RemoteError(f"{what}: the stream is not open", url=self.url)
        try:
            return dict(json.loads(self._ws.recv(timeout=self.timeout)))
        except TimeoutError as exc:
            raise RemoteError(
                f"{what}: no message from {self.uri} within {self.timeout:g} s", url=self.url
            ) from exc
        except Exception as exc:
            raise self._closed(exc, what) from exc

    def _ask(self, kind: str, seq: int | None = None, **fields: Any) -> dict[str, Any]:
        seq, text = self._message(kind, seq, **fields)
        if self._ws is None:
            raise RemoteError(f"{kind}: the stream is not open", url=self.url)
        try:
            self._ws.send(text)
        except Exception as exc:
            raise self._closed(exc, kind) from exc
        while not self._sort(answer := self._recv(kind), seq):
            pass
        return self._check_answer(answer, kind)

    def states(self) -> Iterator[dict[str, Any]]:
        """The states pushed, as they arrive (other messages go to :attr:`notices`);
        ends when the connection closes."""
        from websockets.exceptions import ConnectionClosed

        while self._ws is not None:
            try:
                message = json.loads(self._ws.recv(timeout=self.timeout))
            except ConnectionClosed:
                return
            except TimeoutError as exc:
                raise RemoteError(
                    f"no state from {self.uri} within {self.timeout:g} s", url=self.url
                ) from exc
            if message.get("type") == "state":
                self.latest = message
                yield message
            else:
                self.notices.append(message)

    def send_target(
        self,
        theta_deg: npt.ArrayLike | None = None,
        rpy_deg: npt.ArrayLike | None = None,
        quaternion_wxyz: npt.ArrayLike | None = None,
        *,
        seq: int | None = None,
        t: float | None = None,
    ) -> dict[str, Any]:
        """Stream a goal (exactly one form) and wait for its answer: ``ack`` (with
        ``theta_deg``) or ``refused`` (with ``failed`` and ``verdict``), as a dict.
        Takes the lease if it is free.

        ``t`` is the goal's time on this program's clock [s] (e.g. when the sample
        it follows was taken, or its time on a planned trajectory; default: now, on
        ``time.monotonic()``). The server's guard checks speed and acceleration over
        these times, so network jitter does not make a goal look faster than it is;
        goals may not be sent faster than their times say (50 ms slack).

        Raises:
            LeaseHeldError: another client holds the lease.
            InputError: the server found the goal malformed, out of reach or timed
                ahead of the clock.
        """
        goal = _goal(theta_deg, rpy_deg, quaternion_wxyz)
        return self._ask("target", seq, **goal, t=_stamp(t))

    def take_lease(self) -> dict[str, Any]:
        """Take the lease: ``{"held": True, "deadline_s": ...}``; LeaseHeldError if taken."""
        return self._ask("lease")

    def release(self) -> dict[str, Any]:
        """Give the lease back (the twin stops): ``{"held": False, "released": ...}``."""
        return self._ask("release")

    def stop(self) -> dict[str, Any]:
        """Stop the twin (anyone may): ``{"type": "stopped"}``."""
        return self._ask("stop")

    def ping(self) -> dict[str, Any]:
        """``{"type": "pong"}``; keeps the lease alive."""
        return self._ask("ping")

    def close(self) -> None:
        """Close the connection (a held lease ends, the twin stops)."""
        if self._ws is not None:
            self._ws.close()
            self._ws = None

    def __enter__(self) -> Stream:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()


class AsyncStream(_StreamBase):
    """The ``async`` twin of :class:`Stream` (``websockets.asyncio.client``), made by
    :meth:`AsyncClient.stream`; use it with ``async with``. The same methods,
    awaited; :meth:`states` is an async iterator."""

    def __init__(
        self,
        url: str = DEFAULT_URL,
        *,
        token: str | None = None,
        rate: float = DEFAULT_RATE,
        timeout: float = 5.0,
    ) -> None:
        super().__init__(url, token, rate, timeout)
        self._ws: AsyncConnection | None = None

    async def open(self) -> AsyncStream:
        """Connect and read the ``hello``."""
        from websockets.asyncio.client import connect

        try:
            self._ws = await connect(
                self.uri, additional_headers=self._headers, open_timeout=self.timeout
            )
        except Exception as exc:
            raise RemoteError(
                f"cannot open the stream {self.uri} within {self.timeout:g} s: {exc}", url=self.url
            ) from exc
        self.hello = await self._recv("hello")
        return self

    async def _recv(self, what: str) -> dict[str, Any]:
        if self._ws is None:
            raise RemoteError(f"{what}: the stream is not open", url=self.url)
        try:
            text = await asyncio.wait_for(self._ws.recv(), self.timeout)
        except asyncio.TimeoutError as exc:
            raise RemoteError(
                f"{what}: no message from {self.uri} within {self.timeout:g} s", url=self.url
            ) from exc
        except Exception as exc:
            raise self._closed(exc, what) from exc
        return dict(json.loads(text))

    async def _ask(self, kind: str, seq: int | None = None, **fields: Any) -> dict[str, Any]:
        seq, text = self._message(kind, seq, **fields)
        if self._ws is None:
            raise RemoteError(f"{kind}: the stream is not open", url=self.url)
        try:
            await self._ws.send(text)
        except Exception as exc:
            raise self._closed(exc, kind) from exc
        while not self._sort(answer := await self._recv(kind), seq):
            pass
        return self._check_answer(answer, kind)

    async def states(self) -> AsyncIterator[dict[str, Any]]:
        """The states pushed, as :meth:`Stream.states`."""
        from websockets.exceptions import ConnectionClosed

        while self._ws is not None:
            try:
                text = await asyncio.wait_for(self._ws.recv(), self.timeout)
            except ConnectionClosed:
                return
            except asyncio.TimeoutError as exc:
                raise RemoteError(
                    f"no state from {self.uri} within {self.timeout:g} s", url=self.url
                ) from exc
            message = json.loads(text)
            if message.get("type") == "state":
                self.latest = message
                yield message
            else:
                self.notices.append(message)

    async def send_target(
        self,
        theta_deg: npt.ArrayLike | None = None,
        rpy_deg: npt.ArrayLike | None = None,
        quaternion_wxyz: npt.ArrayLike | None = None,
        *,
        seq: int | None = None,
        t: float | None = None,
    ) -> dict[str, Any]:
        """As :meth:`Stream.send_target`."""
        goal = _goal(theta_deg, rpy_deg, quaternion_wxyz)
        return await self._ask("target", seq, **goal, t=_stamp(t))

    async def take_lease(self) -> dict[str, Any]:
        """As :meth:`Stream.take_lease`."""
        return await self._ask("lease")

    async def release(self) -> dict[str, Any]:
        """As :meth:`Stream.release`."""
        return await self._ask("release")

    async def stop(self) -> dict[str, Any]:
        """As :meth:`Stream.stop`."""
        return await self._ask("stop")

    async def ping(self) -> dict[str, Any]:
        """As :meth:`Stream.ping`."""
        return await self._ask("ping")

    async def close(self) -> None:
        """Close the connection (a held lease ends, the twin stops)."""
        if self._ws is not None:
            await self._ws.close()
            self._ws = None

    async def __aenter__(self) -> AsyncStream:
        return await self.open()

    async def __aexit__(self, *exc: object) -> None:
        await self.close()
