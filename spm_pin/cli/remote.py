"""``spm serve``: the robot model over HTTP + JSON (:mod:`spm_pin.remote`, the
``remote`` extra, imported when the command runs).

Command::

    spm serve [--host 127.0.0.1] [--port 8750] [--sim kinematic|dynamic] [--design NAME|FILE]
              [--token-file FILE] [--deadline SECONDS]

Serves until Ctrl-C (or SIGTERM), then exits with status 0. Binding an address other
than loopback needs a bearer token (``--token-file`` or the environment variable
``SPM_TOKEN``); without one the command exits with status 2 before binding anything.
``--deadline``: seconds the streaming client that holds the lease (``WS /stream``)
may stay silent before the lease ends and the twin stops (default 0.5).
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
from typing import Any

from ._options import UsageError as _UsageError
from ._options import add_design_option as _add_design_option
from ._options import design_of as _design

__all__ = ["SIMULATIONS", "add_parser"]

#: The twins ``spm serve --sim`` offers.
SIMULATIONS = ("kinematic", "dynamic")


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"ports lie in 0..65535, got {value}")
    return value


def _deadline(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not 0 < value <= 3600:  # NaN fails too
        raise argparse.ArgumentTypeError(f"the deadline lies in (0, 3600] s, got {text}")
    return value


def _run_serve(args: argparse.Namespace) -> int:
    try:  # imported here: FastAPI, uvicorn and pydantic are the remote extra
        from ..remote import (
            DynamicBackend,
            KinematicBackend,
            check_binding,
            load_token,
            serve,
        )
    except ImportError as exc:
        raise _UsageError(str(exc)) from exc
    token = load_token(args.token_file)
    check_binding(args.host, args.port, token)
    design = _design(args)
    backend: KinematicBackend | DynamicBackend = (
        DynamicBackend(design) if args.sim == "dynamic" else KinematicBackend(design)
    )
    host = f"[{args.host}]" if ":" in args.host else args.host
    url = f"http://{host}:{args.port}"
    guarded = "bearer token required" if token is not None else "no token: loopback only"
    print(
        f"spm serve: the {backend.name} twin of design {design.name!r} at {url} "
        f"(API docs at {url}/docs; {guarded}); Ctrl-C stops",
        file=sys.stderr,
        flush=True,
    )

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    # uvicorn shuts down gracefully on SIGINT and SIGTERM, then raises the signal again
    # with the previous handlers: both end here as KeyboardInterrupt, exit status 0.
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        with contextlib.suppress(KeyboardInterrupt):
            serve(backend, host=args.host, port=args.port, token=token, deadline=args.deadline)
    finally:
        signal.signal(signal.SIGTERM, previous)
        close = getattr(backend, "close", None)
        if close is not None:
            close()
    return 0


def add_parser(commands: Any) -> None:
    """``spm serve``."""
    serve = commands.add_parser(
        "serve",
        help="serve the robot model over HTTP + JSON (remote extra)",
        description="Serve a twin of the robot over HTTP with a JSON API: read its state "
        "and collisions, move it (every goal passes the safety guard of the servos), "
        "check goals. The API is described at /docs. Binds 127.0.0.1 by default; any "
        "other address needs a bearer token (--token-file FILE or SPM_TOKEN).",
    )
    serve.add_argument(
        "--host", default="127.0.0.1", help="address to bind (default: 127.0.0.1, loopback)"
    )
    serve.add_argument(
        "--port", type=_port, default=8750, metavar="PORT", help="port (default: 8750)"
    )
    serve.add_argument(
        "--sim",
        choices=SIMULATIONS,
        default="kinematic",
        help="the twin: kinematic (the model alone; goals are reached at once) or dynamic "
        "(the closed-loop dynamics with the servos' model, simulated in real time)",
    )
    _add_design_option(serve)
    serve.add_argument(
        "--token-file",
        metavar="FILE",
        help="file holding the bearer token every request must carry (default: the "
        "environment variable SPM_TOKEN; without either, only loopback is served)",
    )
    serve.add_argument(
        "--deadline",
        type=_deadline,
        default=0.5,
        metavar="SECONDS",
        help="seconds the streaming client that controls the twin (WS /stream) may stay "
        "silent before its lease ends and the twin stops (default: 0.5)",
    )
    serve.set_defaults(run=_run_serve)
