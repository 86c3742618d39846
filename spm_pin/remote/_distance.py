"""The exact smallest link distance, computed in a process of its own.

The exact distances of every checked link pair take about 12 ms (coal's queries hold
the interpreter lock); in the server's process they would stall its event loop. A
:class:`DistanceWorker` computes them in a child process (``spawn``: no state of the
server is copied) that builds its own robot of the design and keeps, as the twin
did, the pair nearest last time, whose distance caps the search of the next minimum.

The child runs at the lowest scheduling priority (:data:`NICENESS`): on a machine
with few cores, a distance computed meanwhile does not hold up the server's answers.
The worker answers one request at a time and never blocks its caller: ``request``
sends input angles when no request is under way, ``latest`` gives the last answer.
The child ends when the worker is closed or when its parent goes away (its pipe
closes).
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import threading
import time
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ..design import SPMDesign
    from ..model.robot import SPMRobot

__all__ = ["DistanceWorker", "exact_min_distance"]

FloatArray = npt.NDArray[np.float64]
LinkPair = tuple[str, str]

#: Seconds the worker's child may take to start (import, build its robot).
START_TIMEOUT = 60.0
#: How much the child lowers its scheduling priority (``os.nice``; 19: the lowest).
#: Its distances are background work: on a small machine the server's event loop,
#: answering streamed goals within milliseconds, takes the CPU first.
NICENESS = 19


def exact_min_distance(
    robot: SPMRobot, theta: FloatArray, nearest: LinkPair | None
) -> tuple[float, LinkPair | None]:
    """The smallest distance between two checked links at input angles ``theta``
    [rad] (home assembly mode, every checked pair, as
    :func:`~spm_pin.collision.check_input`), and the nearest pair when it was found
    (else ``nearest`` unchanged).

    ``nearest``: the pair nearest last time; its distance bounds the minimum from
    above, and with it as the cap the other pairs stop as soon as they cannot be
    nearer (the same minimum).
    """
    from ..collision.checker import checker_of

    checker = checker_of(robot)
    q = robot.configuration(theta)
    if nearest is not None:
        cap = checker.distances(q, pairs=[nearest])[nearest]
        if math.isfinite(cap) and cap > 0.0:
            return float(checker.clearances(q[None], include_fixed=True, cap=cap)[0]), nearest
    distances = checker.distances(q)
    pair = min(distances, key=distances.__getitem__)
    return float(distances[pair]), pair


def _child(design: SPMDesign, conn: Connection) -> None:  # pragma: no cover - child
    """The worker's process: answer (theta, distance) for every theta received."""
    from ..collision import build_robot

    if hasattr(os, "nice"):  # background work: the server's event loop goes first
        with contextlib.suppress(OSError):
            os.nice(NICENESS)
    robot = build_robot(design)
    nearest: LinkPair | None = None
    with contextlib.suppress(EOFError, OSError):  # the parent closed the pipe or went away
        conn.send("ready")
        while True:
            theta = conn.recv()
            if theta is None:
                return
            try:
                distance, nearest = exact_min_distance(robot, np.asarray(theta), nearest)
            except Exception as exc:
                conn.send(("error", f"{type(exc).__name__}: {exc}"))
                continue
            conn.send((theta, distance))


class DistanceWorker:
    """Exact smallest link distances of a design, computed in a child process.

    Args:
        design: The SPM whose links are checked.

    The child starts at once; until it is ready (a second or two), :meth:`request`
    returns False and the caller computes in process.
    """

    def __init__(self, design: SPMDesign) -> None:
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._process = ctx.Process(
            target=_child, args=(design, child), name="spm-distance", daemon=True
        )
        self._process.start()
        child.close()
        self._lock = threading.Lock()
        self._ready = False
        self._pending = False
        self._closed = False
        self._started = time.monotonic()
        #: The last answer: (monotonic time it arrived, theta [rad], distance [m]).
        self.last: tuple[float, FloatArray, float] | None = None
        #: Requests answered, and answered with an error.
        self.answers = 0
        self.errors = 0

    @property
    def alive(self) -> bool:
        """The child runs."""
        return not self._closed and self._process.is_alive()

    def _collect(self) -> None:
        """Take what the child sent (call with the lock held)."""
        while self._conn.poll():
            message: Any = self._conn.recv()
            if message == "ready":
                self._ready = True
            elif message[0] == "error":
                self.errors += 1
                self._pending = False
            else:
                theta, distance = message
                self.last = (time.monotonic(), np.asarray(theta, dtype=float), float(distance))
                self.answers += 1
                self._pending = False

    def request(self, theta: FloatArray) -> bool:
        """Ask for the distance at ``theta`` [rad], (3,), unless a request is under
        way. False when the child cannot take it (not ready yet, or gone)."""
        with self._lock:
            if not self.alive:
                return False
            try:
                self._collect()
                if not self._ready:
                    return False
                if not self._pending:
                    self._conn.send([float(x) for x in theta])
                    self._pending = True
            except (EOFError, OSError):
                self._closed = True
                return False
            return True

    def latest(self) -> tuple[float, FloatArray, float] | None:
        """The last answer (arrival time, theta, distance), or None."""
        with self._lock:
            if self.alive:
                try:
                    self._collect()
                except (EOFError, OSError):
                    self._closed = True
            return self.last

    def close(self) -> None:
        """Stop the child (it is a daemon: it also ends with this process)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            with contextlib.suppress(EOFError, OSError):
                self._conn.send(None)
            self._conn.close()
        self._process.join(5.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(5.0)
