"""Serving a twin with uvicorn: :func:`serve` (blocking, what ``spm serve`` runs) and
:class:`BackgroundServer` (a server in a thread of this process, for scripts and
tests).

Safe by default: the server binds 127.0.0.1, where only this machine can reach it.
Binding any other address (another interface, or 0.0.0.0 for all of them) needs a
bearer token; without one the server refuses to start, before it binds anything.
The token comes from a file (:func:`load_token`) or from the environment variable
``SPM_TOKEN``; once given, every resource needs it, on loopback too.
"""

from __future__ import annotations

import ipaddress
import os
import socket
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import uvicorn

from ..errors import InputError, SPMError
from .app import DEFAULT_MAX_BODY_BYTES, create_app
from .backend import TwinBackend
from .stream import DEFAULT_DEADLINE

__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "TOKEN_ENVIRONMENT_VARIABLE",
    "BackgroundServer",
    "check_binding",
    "is_loopback",
    "load_token",
    "serve",
]

#: The address served by default: loopback only.
DEFAULT_HOST = "127.0.0.1"
#: The port served by default.
DEFAULT_PORT = 8750
#: The environment variable read for the bearer token.
TOKEN_ENVIRONMENT_VARIABLE = "SPM_TOKEN"


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (127.0.0.0/8, ::1) or ``localhost``."""
    name = host.strip().strip("[]").lower()
    if name == "localhost":
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def _check_token(token: str, source: str) -> str:
    token = token.strip()
    if not token:
        raise InputError(f"the token from {source} is empty", argument="token", value=source)
    if any(ord(c) < 33 or ord(c) > 126 for c in token):
        raise InputError(
            f"the token from {source} must be printable ASCII without spaces",
            argument="token",
            value=source,
        )
    return token


def load_token(
    token_file: str | os.PathLike[str] | None = None,
    *,
    environ: Mapping[str, str] | None = None,
) -> str | None:
    """The bearer token: from ``token_file`` if given, else from ``SPM_TOKEN``.

    Leading and trailing white space (a final newline) is dropped.

    Args:
        token_file: A file holding the token.
        environ: The environment to read ``SPM_TOKEN`` from (default ``os.environ``).

    Returns:
        The token, or None when neither gives one.

    Raises:
        InputError: the file or the variable holds an empty token, or one with
            spaces or characters outside printable ASCII.
        OSError: the file cannot be read.
    """
    if token_file is not None:
        path = Path(token_file)
        return _check_token(path.read_text(encoding="utf-8"), f"token file {path}")
    value = (os.environ if environ is None else environ).get(TOKEN_ENVIRONMENT_VARIABLE)
    if value is None:
        return None
    return _check_token(value, f"the environment variable {TOKEN_ENVIRONMENT_VARIABLE}")


def check_binding(host: str, port: int, token: str | None) -> None:
    """Refuse a server that others could reach without a token.

    Raises:
        InputError: ``host`` is not a loopback address and there is no token, or
            ``port`` is not in 0..65535.
    """
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise InputError(f"port must be an integer in 0..65535, got {port!r}", argument="port")
    if not is_loopback(host) and token is None:
        raise InputError(
            f"refusing to serve on {host}, which other machines can reach, without a token: "
            f"give one with --token-file FILE or the environment variable "
            f"{TOKEN_ENVIRONMENT_VARIABLE} (or serve on 127.0.0.1)",
            argument="host",
            value=host,
        )


def _config(app: Any, host: str, port: int, log_level: str) -> uvicorn.Config:
    return uvicorn.Config(
        app,
        host=host,
        port=port,
        log_level=log_level,
        server_header=False,
        ws_per_message_deflate=False,
    )


def serve(
    backend: TwinBackend | None = None,
    *,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    token: str | None = None,
    max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
    deadline: float = DEFAULT_DEADLINE,
    log_level: str = "info",
    cors_origins: Sequence[str] = (),
) -> None:
    """Serve a twin over HTTP until interrupted (Ctrl-C or SIGTERM).

    Args:
        backend: The twin (default: the kinematic twin of the prototype).
        host: Address to bind (default 127.0.0.1; any other needs ``token``).
        port: Port to bind.
        token: Bearer token every resource then needs.
        max_body_bytes: Largest request body accepted [bytes].
        deadline: Seconds a streaming client holding the lease may stay silent
            before the lease ends and the twin stops.
        log_level: uvicorn's log level (``"info"``, ``"warning"``, ...).
        cors_origins: Origins of browser pages allowed to call the API (see
            :func:`~spm_pin.remote.create_app`).

    Raises:
        InputError: a non-loopback ``host`` without a token (nothing is bound).
    """
    check_binding(host, port, token)
    app = create_app(
        backend,
        token=token,
        max_body_bytes=max_body_bytes,
        deadline=deadline,
        cors_origins=cors_origins,
    )
    uvicorn.Server(_config(app, host, port, log_level)).run()


class BackgroundServer:
    """A twin served by uvicorn in a thread of this process.

    Use it as a context manager; the server stops when the block ends::

        with BackgroundServer() as server:
            urllib.request.urlopen(server.url + "/state")

    Args:
        backend: The twin (default: the kinematic twin of the prototype).
        host: Address to bind (default 127.0.0.1; any other needs ``token``).
        port: Port to bind; 0 (default) picks a free one.
        token: Bearer token every resource then needs.
        max_body_bytes: Largest request body accepted [bytes].
        deadline: Seconds a streaming client holding the lease may stay silent.
        timeout: Seconds to wait for the server to start and to stop.
        cors_origins: Origins of browser pages allowed to call the API.

    Attributes:
        app: The application served.
        port: The bound port (known once started).
        url: ``http://host:port`` (known once started).
        ws_url: ``ws://host:port`` (known once started).
    """

    def __init__(
        self,
        backend: TwinBackend | None = None,
        *,
        host: str = DEFAULT_HOST,
        port: int = 0,
        token: str | None = None,
        max_body_bytes: int = DEFAULT_MAX_BODY_BYTES,
        deadline: float = DEFAULT_DEADLINE,
        timeout: float = 30.0,
        cors_origins: Sequence[str] = (),
    ) -> None:
        check_binding(host, port, token)
        self.host = host
        self.port = port
        self.timeout = float(timeout)
        self.app = create_app(
            backend,
            token=token,
            max_body_bytes=max_body_bytes,
            deadline=deadline,
            cors_origins=cors_origins,
        )
        self._server = uvicorn.Server(_config(self.app, host, port, "warning"))
        self._thread: threading.Thread | None = None
        self._socket: socket.socket | None = None

    @property
    def url(self) -> str:
        """``http://host:port`` of the running server."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"

    @property
    def ws_url(self) -> str:
        """``ws://host:port`` of the running server (``ws_url + "/stream"`` streams)."""
        return "ws" + self.url[len("http") :]

    def start(self) -> BackgroundServer:
        """Bind, start serving in a thread and wait until the server answers."""
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        # IPPROTO_TCP named: asyncio then sets TCP_NODELAY on the connections (with
        # protocol 0 it does not, and every answer waits ~40 ms for a delayed ACK).
        sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((self.host, self.port))
        self._socket = sock
        self.port = int(sock.getsockname()[1])
        self._thread = threading.Thread(
            target=self._server.run, kwargs={"sockets": [sock]}, name="spm-remote", daemon=True
        )
        self._thread.start()
        deadline = time.monotonic() + self.timeout
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                self.stop()
                raise SPMError(f"the server on {self.url} did not start")
            time.sleep(0.01)
        return self

    def stop(self) -> None:
        """Stop serving and wait for the thread."""
        self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(self.timeout)
            self._thread = None
        if self._socket is not None:
            self._socket.close()
            self._socket = None

    def __enter__(self) -> BackgroundServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
