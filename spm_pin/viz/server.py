"""The meshcat server as a child process that this library owns from start to stop.

meshcat 0.3.2's own ``Visualizer`` starts its server and never stops it
(``Visualizer.close`` raises ``AttributeError``), lets it fill a pipe nobody reads
(after a few hundred browser connections the server blocks), and leaves it running
when the parent is killed (it runs in its own session). :class:`MeshcatServer` fixes
all three:

* :meth:`MeshcatServer.stop` (or leaving the ``with`` block, or the interpreter
  exiting, or the object being garbage collected) closes the ZeroMQ socket with
  linger 0, kills the server, waits for it and closes its pipes, so no process and
  no port is left behind;
* two daemon threads drain the server's stdout and stderr;
* the server watches a pipe from its parent and exits as soon as the parent goes
  away, even when the parent is killed with SIGKILL.

The server listens on 127.0.0.1 only: tcp port 6000 for commands (ZeroMQ) and http
port 7000 for the viewer page, or the next free ports.
"""

from __future__ import annotations

import collections
import math
import queue
import re
import subprocess
import sys
import threading
import time
import weakref
from types import TracebackType
from typing import IO, Any

import zmq

from ..errors import InputError, SPMError

__all__ = ["MeshcatServer", "ViewerError"]

#: Runs in the child: a thread exits the process when stdin (a pipe held by the
#: parent) reaches end of file, i.e. when the parent stops the server or dies; then
#: the meshcat server runs as ``python -m meshcat.servers.zmqserver`` would.
_SERVER_SCRIPT = """\
import os, sys, threading, warnings

def _exit_with_parent():
    while sys.stdin.buffer.read(65536):
        pass
    os._exit(0)

threading.Thread(target=_exit_with_parent, daemon=True).start()
warnings.simplefilter("ignore", DeprecationWarning)
from meshcat.servers.zmqserver import main
sys.argv = ["meshcat-server"]
main()
"""

_URL_LINE = re.compile(r"^(zmq_url|web_url)=(\S+)$")
_PORT = re.compile(r":(\d+)(?:/|$)")
#: Lines of the server's output kept for error messages.
_TAIL_LINES = 20


class ViewerError(SPMError, RuntimeError):
    """The meshcat server could not start, or did not answer.

    Attributes:
        output: The last lines the server printed, when known.
    """

    def __init__(self, message: str, *, output: str = "") -> None:
        super().__init__(message + (f"; server output:\n{output}" if output else ""))
        self.output = output


class _Process:
    """What a running server holds; stopped by a ``weakref.finalize`` of the owner."""

    def __init__(self, process: subprocess.Popen[bytes]) -> None:
        self.process = process
        self.lines: queue.Queue[str] = queue.Queue()
        self.tail: collections.deque[str] = collections.deque(maxlen=_TAIL_LINES)
        self.context: zmq.Context[Any] | None = None
        self.socket: zmq.Socket[Any] | None = None
        assert process.stdout is not None and process.stderr is not None
        self.threads = [
            threading.Thread(target=self._drain, args=(process.stdout, True), daemon=True),
            threading.Thread(target=self._drain, args=(process.stderr, False), daemon=True),
        ]
        for thread in self.threads:
            thread.start()

    def _drain(self, pipe: IO[bytes], announce: bool) -> None:
        for raw in iter(pipe.readline, b""):
            line = raw.decode("utf-8", "replace").rstrip()
            self.tail.append(line)
            if announce and _URL_LINE.match(line):
                self.lines.put(line)

    def output(self) -> str:
        return "\n".join(self.tail)

    def close_socket(self) -> None:
        if self.socket is not None:
            self.socket.close(linger=0)
            self.socket = None
        if self.context is not None:
            self.context.term()
            self.context = None

    def shutdown(self) -> None:
        """Close the socket, kill and wait the server, close its pipes (idempotent)."""
        self.close_socket()
        process = self.process
        if process.stdin is not None:
            process.stdin.close()  # the server's watcher exits on end of file, too
        if process.poll() is None:
            process.kill()
        process.wait()
        for thread in self.threads:
            thread.join(timeout=5.0)
        for pipe in (process.stdout, process.stderr):
            if pipe is not None:
                pipe.close()


class MeshcatServer:
    """A meshcat server (ZeroMQ commands in, a web page with the viewer out).

    Use it as a context manager, or call :meth:`start` and :meth:`stop`::

        with MeshcatServer() as server:
            print(server.url)  # open it in a browser

    Most users never touch it: :class:`~spm_pin.viz.Visualizer` starts and stops one.

    Args:
        timeout: How long to wait for the server to start and for each command to be
            acknowledged [s].

    Raises:
        InputError: ``timeout`` is not a positive finite number.
    """

    def __init__(self, *, timeout: float = 10.0) -> None:
        if (
            isinstance(timeout, bool)
            or not isinstance(timeout, (int, float))
            or not math.isfinite(timeout)
            or timeout <= 0
        ):
            raise InputError(
                f"timeout must be a positive number of seconds, got {timeout!r}",
                argument="timeout",
                value=timeout,
            )
        self.timeout = float(timeout)
        self._state: _Process | None = None
        self._finalizer: weakref.finalize[Any, Any] | None = None
        self._zmq_url = ""
        self._web_url = ""

    def __repr__(self) -> str:
        if not self.running:
            return "MeshcatServer(stopped)"
        return f"MeshcatServer(url={self._web_url!r}, pid={self.pid})"

    # --------------------------------------------------------------------- lifetime
    def start(self) -> MeshcatServer:
        """Start the server (no-op when it runs) and connect to it.

        Returns:
            ``self``.

        Raises:
            ViewerError: the server exited or did not report its addresses within
                ``timeout``.
        """
        if self.running:
            return self
        self.stop()  # a server that died on its own: release what is left of it
        process = subprocess.Popen(
            [sys.executable, "-u", "-c", _SERVER_SCRIPT],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,  # Ctrl-C in a terminal reaches only us; we stop it
        )
        state = _Process(process)
        self._state = state
        self._finalizer = weakref.finalize(self, state.shutdown)
        urls: dict[str, str] = {}
        try:
            deadline = time.monotonic() + self.timeout
            while len(urls) < 2:
                try:
                    line = state.lines.get(timeout=0.02)
                except queue.Empty:
                    if process.poll() is not None:
                        raise ViewerError(
                            f"the meshcat server exited with status {process.returncode} "
                            "while starting",
                            output=state.output(),
                        ) from None
                    if time.monotonic() > deadline:
                        raise ViewerError(
                            f"the meshcat server did not start within {self.timeout:g} s",
                            output=state.output(),
                        ) from None
                    continue
                match = _URL_LINE.match(line)
                assert match is not None
                urls[match.group(1)] = match.group(2)
            context: zmq.Context[Any] = zmq.Context()
            state.context = context
            state.socket = self._connect(context, urls["zmq_url"])
        except BaseException:
            self.stop()
            raise
        self._zmq_url, self._web_url = urls["zmq_url"], urls["web_url"]
        return self

    def _connect(self, context: zmq.Context[Any], url: str) -> zmq.Socket[Any]:
        socket: zmq.Socket[Any] = context.socket(zmq.REQ)
        milliseconds = int(self.timeout * 1000)
        socket.setsockopt(zmq.LINGER, 0)
        socket.setsockopt(zmq.RCVTIMEO, milliseconds)
        socket.setsockopt(zmq.SNDTIMEO, milliseconds)
        socket.connect(url)
        return socket

    def stop(self) -> None:
        """Stop the server and release its process, ports and pipes (idempotent)."""
        if self._finalizer is not None:
            self._finalizer()
        self._finalizer = None
        self._state = None

    def __enter__(self) -> MeshcatServer:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()

    # ------------------------------------------------------------------- addresses
    @property
    def running(self) -> bool:
        """True while the server process is alive."""
        return self._state is not None and self._state.process.poll() is None

    def _running_state(self) -> _Process:
        state = self._state
        if state is None or state.process.poll() is not None:
            output = "" if state is None else state.output()
            raise ViewerError(
                "the meshcat server is not running; call start() or use 'with'", output=output
            )
        return state

    @property
    def url(self) -> str:
        """The viewer page, ``http://127.0.0.1:<port>/static/``."""
        self._running_state()
        return self._web_url

    @property
    def zmq_url(self) -> str:
        """Where the server takes commands, ``tcp://127.0.0.1:<port>``."""
        self._running_state()
        return self._zmq_url

    @property
    def pid(self) -> int:
        """Process id of the server."""
        return int(self._running_state().process.pid)

    @property
    def ports(self) -> tuple[int, int]:
        """(ZeroMQ port, web port) the server listens on, both on 127.0.0.1."""
        self._running_state()
        zmq_port = _PORT.search(self._zmq_url)
        web_port = _PORT.search(self._web_url)
        assert zmq_port is not None and web_port is not None
        return int(zmq_port.group(1)), int(web_port.group(1))

    # -------------------------------------------------------------------- commands
    def send(self, kind: str, path: str, data: bytes) -> None:
        """Send one packed meshcat command and wait for the server to take it.

        Args:
            kind: The command type (``"set_object"``, ``"set_transform"``, ...).
            path: The scene path it applies to (``""`` for animations).
            data: The command, msgpack-packed as meshcat's viewer reads it.

        Raises:
            ViewerError: the server is not running, did not answer within
                ``timeout`` or refused the command.
        """
        state = self._running_state()
        socket = state.socket
        assert socket is not None and state.context is not None
        try:
            socket.send_multipart([kind.encode("utf-8"), path.encode("utf-8"), data])
            reply = socket.recv()
        except zmq.Again:
            # A REQ socket that missed its reply cannot send again: start a new one.
            socket.close(linger=0)
            state.socket = self._connect(state.context, self._zmq_url)
            raise ViewerError(
                f"the meshcat server did not take a {kind!r} command within {self.timeout:g} s",
                output=state.output(),
            ) from None
        if reply != b"ok":
            raise ViewerError(
                f"the meshcat server refused a {kind!r} command on {path!r}: "
                f"{reply.decode('utf-8', 'replace')}"
            )
