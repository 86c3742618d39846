"""``WS /stream``: the twin's state pushed at a requested rate, goals streamed back.

One :class:`Lease` per application: one controlling client at a time, any number of
readers. The lease is taken by the first client that asks (``{"type": "lease"}``) or
sends a target while it is free; it ends when its holder releases it, disconnects
or sends nothing for ``deadline`` seconds (a watchdog task in the server's event
loop), and whenever it ends the backend's ``stop`` runs (the twin holds still; the
servos' torque goes off). HTTP writes (``PUT /joints``, ``PUT /orientation``) are
refused (409) while a lease is held; they take the lease's lock for their move, so
a streaming client never starts from a goal it has not seen.

Per connection two tasks run in the event loop: the receiver (this module's
:func:`stream_session`, answering every client message exactly once) and the pusher
(a state every 1/rate seconds). The backend's calls take its lock and may take
milliseconds: they run in worker threads, except a twin's ``command_quick`` (the
guard's checks of a streamed goal, a fraction of a millisecond), which runs in the
event loop, and a twin's ``state_quick`` (a state read that needs no exact distance
computation). States come from one :class:`StateCache`
shared by every connection, so ten readers cost one backend read per period, not ten.

The guard checks a streamed goal's speed and acceleration over the times between
goals: their arrival times (the goals taken as evenly spaced, unless goals were
refused in between), or, when targets carry ``t`` (the goal's time on the client's
clock), those times, which network jitter does not disturb. A client's
times may not run ahead of the server's clock by more than :data:`CLOCK_SLACK` (plus
:data:`CLOCK_DRIFT` of the time since its first timed goal): goals sent faster than
their times say are answered 422. A refused goal changes nothing: the next one is
checked against the last goal accepted, over the time since it.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import math
import secrets
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
from anyio import to_thread
from pydantic import ValidationError
from starlette.websockets import WebSocket, WebSocketDisconnect

from ..errors import SPMError, UnreachableError
from ..rotations import matrix_from_quaternion, matrix_from_rpy
from .backend import GoalRefusedError, TwinBackend
from .models import CLIENT_MESSAGE, StreamAuth, StreamTarget, check_response, state_json

__all__ = [
    "CLOCK_DRIFT",
    "CLOCK_SLACK",
    "DEFAULT_DEADLINE",
    "DEFAULT_RATE",
    "MAX_RATE",
    "MIN_RATE",
    "Lease",
    "LeaseHeldError",
    "StateCache",
    "stream_session",
]

#: Seconds the lease holder may stay silent before the lease ends and the twin stops.
DEFAULT_DEADLINE = 0.5
#: State pushes per second when the client asks for no rate [Hz].
DEFAULT_RATE = 50.0
#: The lowest push rate a client may ask for [Hz].
MIN_RATE = 1.0
#: The highest push rate a client may ask for [Hz].
MAX_RATE = 1000.0
#: Seconds a client without the token in its headers has to send the auth message.
AUTH_TIMEOUT = 5.0
#: WebSocket close code for a policy violation (wrong token, bad rate).
POLICY_VIOLATION = 1008
#: Seconds a streaming client's goal times ``t`` may run ahead of the server's clock
#: (measured from the client's first timed goal under its lease).
CLOCK_SLACK = 0.05
#: Relative rate at which the client's clock may run faster than the server's.
CLOCK_DRIFT = 1e-3


class LeaseHeldError(SPMError):
    """A write refused because a streaming client holds the lease (HTTP 409)."""


class Lease:
    """Who controls the twin: one streaming client at a time.

    Args:
        deadline: Seconds its holder may stay silent [s].

    Attributes:
        deadline: As given.
        holder: The holding connection's id, or None.
        expired: How many leases ended at the deadline.
    """

    def __init__(self, deadline: float = DEFAULT_DEADLINE) -> None:
        self.deadline = float(deadline)
        self.holder: int | None = None
        self.expired = 0
        self._lock = threading.Lock()

    @property
    def held(self) -> bool:
        """Some client holds the lease."""
        return self.holder is not None

    def acquire(self, holder: int) -> bool:
        """Take the lease for ``holder`` if free (or already its); True if it holds it."""
        with self._lock:
            if self.holder is None:
                self.holder = holder
            return self.holder == holder

    def release(self, holder: int) -> bool:
        """Give the lease back if ``holder`` holds it; True if it did."""
        with self._lock:
            if self.holder != holder:
                return False
            self.holder = None
            return True

    @contextlib.contextmanager
    def writing(self) -> Iterator[None]:
        """Hold off the streaming clients during an HTTP write.

        Raises:
            LeaseHeldError: a streaming client holds the lease.
        """
        with self._lock:
            if self.holder is not None:
                raise LeaseHeldError(
                    "another client holds the lease (a streaming client controls the twin)"
                )
            yield


class StateCache:
    """The latest state as JSON text, shared by every connection.

    Read from the backend at most once per ``max_age`` seconds asked for, however
    many connections ask; a read's age counts from when it started. A twin that can
    answer quickly (``state_quick``: the kinematic twin while nothing costly is due)
    is read on the event loop; otherwise, or when it cannot, in a worker thread
    (the thread hop and the handover of the interpreter lock cost more than the
    quick read). While a read is under way the pushers send the state read before it
    (its ``time`` says when) rather than wait: a slow read delays no push. A change
    (:meth:`invalidate`) during a read makes the next request read again.
    """

    def __init__(self, twin: TwinBackend) -> None:
        self._twin = twin
        self._text = ""
        self._read_at = -math.inf
        self._changes = 0  # invalidations so far
        self._lock = asyncio.Lock()

    def _read(self) -> str:
        body = state_json(self._twin.state())  # state_response(...).model_dump_json()
        return body[1:]  # without "{": the pusher puts its own keys first

    def _read_quick(self) -> str | None:
        """The state read here on the event loop when the twin answers it quickly
        (the kinematic twin's ``state_quick``: no distance to compute), else None."""
        quick = getattr(self._twin, "state_quick", None)
        state = None if quick is None else quick()
        return None if state is None else state_json(state)[1:]

    async def latest(self, max_age: float) -> str:
        """The state's JSON members (the object without its opening brace)."""
        if time.monotonic() - self._read_at < max_age:
            return self._text
        if self._text and self._lock.locked():  # a read is under way: no pusher waits
            return self._text
        async with self._lock:
            if time.monotonic() - self._read_at >= max_age:
                changes, started = self._changes, time.monotonic()
                text = self._read_quick()  # a fraction of a millisecond, or None
                self._text = text if text is not None else await to_thread.run_sync(self._read)
                # A change during the read may be missing from it: read again next.
                self._read_at = started if self._changes == changes else -math.inf
        return self._text

    def invalidate(self) -> None:
        """The state changed: read it again at the next push (also when a read is
        under way: it may have missed the change)."""
        self._read_at = -math.inf
        self._changes += 1


_ids = itertools.count(1)


def _rotation(rpy_deg: Any, quaternion_wxyz: Any) -> Any:
    if rpy_deg is not None:
        return matrix_from_rpy(np.radians(np.asarray(rpy_deg, dtype=float)))
    return matrix_from_quaternion(np.asarray(quaternion_wxyz, dtype=float))


def _seq_of(text: str) -> Any:
    """The ``seq`` of a message that failed validation, when it has an integer one."""
    with contextlib.suppress(ValueError, TypeError, AttributeError):
        seq = json.loads(text).get("seq")
        if isinstance(seq, int) and not isinstance(seq, bool):
            return seq
    return None


def _errors(exc: ValidationError) -> list[dict[str, Any]]:
    """Each field's error; the offending input is left out (it may be NaN)."""
    return [
        {
            "loc": [str(part) for part in error.get("loc", ())],
            "msg": str(error.get("msg", "")),
            "type": str(error.get("type", "")),
        }
        for error in exc.errors()
    ]


class _Session:
    """One connection: its sends, its pusher and, while it holds the lease, its
    stream of commanded goals and its watchdog."""

    def __init__(self, websocket: WebSocket, hub: Any, rate: float) -> None:
        self.websocket = websocket
        self.hub = hub
        self.id = next(_ids)
        self.period = 1.0 / rate
        self.rate = rate
        self.dropped = 0
        self.heard = time.monotonic()
        self.busy = False  # answering a message: the holder is not silent
        self._send_lock = asyncio.Lock()
        self._watchdog: asyncio.Task[None] | None = None
        # The goals commanded under this lease [rad], when the last one was [s]
        # (server clock; and on the client's clock, for timed targets), the time
        # between the two last ones [s] and the first timed goal (server, client).
        self._previous: Any = None
        self._before: Any = None
        self._commanded_at = 0.0
        self._stamp: float | None = None
        self._previous_period: float | None = None
        self._anchor: tuple[float, float] | None = None
        self._refused_since = False  # a goal was refused since the last accepted one
        self._previous_uneven = False  # ... and before that one was accepted

    @property
    def holds(self) -> bool:
        return bool(self.hub.lease.holder == self.id)

    def _lease_members(self) -> str:
        holder = self.hub.lease.holder
        if holder is None:
            return '"lease":{"held":false,"yours":false}'
        if holder == self.id:
            return '"lease":{"held":true,"yours":true}'
        return '"lease":{"held":true,"yours":false}'

    async def send(self, message: dict[str, Any]) -> None:
        text = json.dumps(message, allow_nan=False)
        async with self._send_lock:
            await self.websocket.send_text(text)

    # ------------------------------------------------------------------ pushing
    async def push(self) -> None:
        """A state every period; ticks missed while a send waits on a slow client
        are dropped (never queued) and counted in ``dropped``."""
        loop = asyncio.get_running_loop()
        due = loop.time()
        for seq in itertools.count(1):
            delay = due - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            members = await self.hub.states.latest(self.period)
            text = (
                f'{{"type":"state","seq":{seq},"dropped":{self.dropped},'
                f"{self._lease_members()},{members}"
            )
            async with self._send_lock:
                await self.websocket.send_text(text)
            due += self.period
            late = loop.time() - due
            if late >= self.period:
                missed = int(late // self.period)
                self.dropped += missed
                due += missed * self.period

    # ------------------------------------------------------------------ the lease
    async def take_lease(self) -> bool:
        lease = self.hub.lease
        if self.holds:
            return True
        twin = self.hub.twin
        if not await to_thread.run_sync(lease.acquire, self.id):
            return False
        self._previous = await to_thread.run_sync(twin.joints)
        self._before = self._previous  # from rest
        self._commanded_at = time.monotonic()
        self._stamp = self._previous_period = self._anchor = None
        self._refused_since = self._previous_uneven = False
        self._watchdog = asyncio.ensure_future(self._watch())
        return True

    async def end_lease(self, reason: str) -> bool:
        """Give the lease back (if held) and stop the twin."""
        if not self.holds:
            return False
        await to_thread.run_sync(self.hub.lease.release, self.id)
        watchdog, self._watchdog = self._watchdog, None
        if watchdog is not None and watchdog is not asyncio.current_task():
            watchdog.cancel()
        await to_thread.run_sync(self.hub.twin.stop, reason)
        self.hub.states.invalidate()
        return True

    async def _watch(self) -> None:
        deadline = self.hub.lease.deadline
        while self.holds:
            remaining = deadline if self.busy else self.heard + deadline - time.monotonic()
            if remaining <= 0:
                reason = f"deadline: nothing received for {deadline:g} s"
                self.hub.lease.expired += 1
                if await self.end_lease(reason):
                    with contextlib.suppress(Exception):  # the client may be gone
                        await self.send({"type": "lease", "held": False, "reason": reason})
                return
            await asyncio.sleep(remaining)

    # ------------------------------------------------------------------ messages
    async def handle(self, text: str | None) -> None:
        """Answer one client message (exactly one answer).

        The deadline counts from the end of the answer to the holder's last
        message: a holder is never silent while the server is busy with it.
        """
        self.busy = True
        try:
            await self._handle(text)
        finally:
            self.busy = False
            self.heard = time.monotonic()

    async def _handle(self, text: str | None) -> None:
        if text is None:
            await self.send(
                {"type": "error", "status": 422, "seq": None, "detail": "send JSON as text"}
            )
            return
        limit = self.hub.max_message_bytes
        if len(text.encode()) > limit:
            await self.send(
                {
                    "type": "error",
                    "status": 413,
                    "seq": None,
                    "detail": f"the message exceeds {limit} bytes",
                }
            )
            return
        try:
            message = CLIENT_MESSAGE.validate_json(text)
        except ValidationError as exc:
            await self.send(
                {"type": "error", "status": 422, "seq": _seq_of(text), "detail": _errors(exc)}
            )
            return
        seq = message.seq if not isinstance(message, StreamAuth) else None
        if isinstance(message, StreamAuth):
            await self.send(
                {"type": "error", "status": 400, "seq": None, "detail": "already authorized"}
            )
        elif isinstance(message, StreamTarget):
            await self._target(message)
        elif message.type == "lease":
            if await self.take_lease():
                await self.send(
                    {
                        "type": "lease",
                        "seq": seq,
                        "held": True,
                        "deadline_s": self.hub.lease.deadline,
                    }
                )
            else:
                await self._conflict(seq)
        elif message.type == "release":
            released = await self.end_lease("released by its holder")
            await self.send({"type": "lease", "seq": seq, "held": False, "released": released})
        elif message.type == "stop":
            await to_thread.run_sync(self.hub.twin.stop, "stop message")
            self.hub.states.invalidate()
            await self.send({"type": "stopped", "seq": seq})
        else:  # ping: keeps the lease alive
            await self.send({"type": "pong", "seq": seq})

    async def _conflict(self, seq: Any) -> None:
        await self.send(
            {"type": "error", "status": 409, "seq": seq, "detail": "another client holds the lease"}
        )

    async def _target(self, message: StreamTarget) -> None:
        seq = message.seq
        if not await self.take_lease():
            await self._conflict(seq)
            return
        twin = self.hub.twin
        now = time.monotonic()
        # Until this goal is accepted, it counts as refused (whatever the reason).
        refused_before, self._refused_since = self._refused_since, True
        period = self._period(message.t, now)
        if isinstance(period, str):
            await self.send({"type": "error", "status": 422, "seq": seq, "detail": period})
            return
        try:
            if message.theta_deg is not None:
                theta = np.radians(message.theta_deg)
            else:
                rotation = _rotation(message.rpy_deg, message.quaternion_wxyz)
                theta = await to_thread.run_sync(twin.solve, rotation)

            # A twin that can take a goal without reading its state back (the
            # kinematic twin's ``command``) is spared that work: the pushes read it.
            command = getattr(twin, "command", None) or twin.move

            # Timed goals: the two intervals as the client timed them. Untimed ones
            # are taken as evenly spaced (arrival jitter would make the intervals'
            # speeds differ), except around a refusal: an interval that spans a
            # refused goal is several intervals long, as measured.
            timed = message.t is not None and self._stamp is not None
            uneven = timed or refused_before or self._previous_uneven
            history = {
                "previous": self._previous,
                "before_previous": self._before,
                "period": period,
                "previous_period": self._previous_period if uneven else None,
            }

            def move() -> Any:
                return command(theta, **history)

            # A twin whose guard checks alone take a fraction of a millisecond (the
            # kinematic twin's ``command_quick``) takes a safe goal here, without a
            # worker thread; a refusal's report (milliseconds) is made in one.
            quick = getattr(twin, "command_quick", None)
            if quick is None or not quick(theta, **history):
                await to_thread.run_sync(move)
        except GoalRefusedError as exc:
            failed = [{"check": check.name, "reason": check.reason} for check in exc.report.failed]
            verdict = check_response(exc.report).model_dump()
            await self.send({"type": "refused", "seq": seq, "failed": failed, "verdict": verdict})
            return
        except UnreachableError as exc:
            await self.send({"type": "error", "status": 422, "seq": seq, "detail": str(exc)})
            return
        except SPMError as exc:
            await self.send({"type": "error", "status": 422, "seq": seq, "detail": str(exc)})
            return
        self._before, self._previous = self._previous, np.array(theta, dtype=float)
        self._commanded_at, self._previous_period = now, period
        self._stamp = message.t
        self._previous_uneven, self._refused_since = refused_before, False
        self.hub.states.invalidate()
        degrees = [float(x) + 0.0 for x in np.degrees(theta)]
        await self.send({"type": "ack", "seq": seq, "theta_deg": degrees})

    def _period(self, stamp: float | None, now: float) -> float | str:
        """The time [s] from the last goal accepted to a goal arriving ``now`` with
        the client's time ``stamp``; or why the stamp is refused."""
        if stamp is None or self._stamp is None:
            if stamp is not None and self._anchor is None:
                self._anchor = (now, stamp)
            return max(now - self._commanded_at, 1e-6)
        if not stamp > self._stamp:
            return (
                f"t must increase: {stamp!r} s after {self._stamp!r} s "
                "(the time of the last goal accepted)"
            )
        if self._anchor is not None:
            elapsed = now - self._anchor[0]
            ahead = (stamp - self._anchor[1]) - elapsed
            allowed = CLOCK_SLACK + CLOCK_DRIFT * elapsed
            if ahead > allowed:
                return (
                    f"the goals' times t run {ahead * 1e3:.1f} ms ahead of the server's "
                    f"clock (at most {allowed * 1e3:.1f} ms): send goals no faster than "
                    "their times"
                )
        return stamp - self._stamp

    async def close(self) -> None:
        """The connection ended: end its lease (the twin stops), even when the
        server is shutting down (the stop is shielded from cancellation)."""
        if self.holds:
            await asyncio.shield(self.end_lease("the controlling client disconnected"))


def _rate_of(websocket: WebSocket) -> float | str:
    """The rate asked for [Hz], or why it cannot be served."""
    text = websocket.query_params.get("rate")
    if text is None:
        return DEFAULT_RATE
    try:
        rate = float(text)
    except ValueError:
        return f"rate must be a number of Hz, got {text[:40]!r}"
    if not MIN_RATE <= rate <= MAX_RATE:  # NaN fails too
        return f"rate must lie in {MIN_RATE:g}..{MAX_RATE:g} Hz, got {text[:40]}"
    return rate


async def _authorize(websocket: WebSocket, token: bytes | None) -> bool:
    """The token: from the header (checked by the middleware) or the first message."""
    if token is None or websocket.scope.get("spm.authorized"):
        return True
    if websocket.scope.get("spm.token_given"):  # a header with a wrong token
        return False
    try:
        text = await asyncio.wait_for(websocket.receive_text(), AUTH_TIMEOUT)
        message = CLIENT_MESSAGE.validate_json(text)
    except (TimeoutError, ValidationError, KeyError, RuntimeError):
        return False
    if not isinstance(message, StreamAuth):
        return False
    return secrets.compare_digest(message.token.encode(), token)


async def stream_session(websocket: WebSocket, hub: Any) -> None:
    """Serve one ``WS /stream`` connection until it closes.

    Args:
        websocket: The connection (not yet accepted).
        hub: The application's streaming state: ``twin``, ``lease``, ``states``,
            ``token`` (bytes or None) and ``max_message_bytes``.
    """
    await websocket.accept()
    if not await _authorize(websocket, hub.token):
        await websocket.close(POLICY_VIOLATION, "a valid bearer token is required")
        return
    rate = _rate_of(websocket)
    if isinstance(rate, str):
        await websocket.close(POLICY_VIOLATION, rate)
        return
    session = _Session(websocket, hub, rate)
    await session.send(
        {
            "type": "hello",
            "rate_hz": rate,
            "deadline_s": hub.lease.deadline,
            "max_message_bytes": hub.max_message_bytes,
            "lease": {"held": hub.lease.held, "yours": False},
        }
    )
    pusher = asyncio.ensure_future(session.push())
    try:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                break
            text = message.get("text")
            await session.handle(text)
    except (WebSocketDisconnect, RuntimeError, OSError):
        pass
    finally:
        pusher.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await pusher
        await session.close()
