"""``spm serve``: the robot model over HTTP + JSON (:mod:`spm_pin.remote`, the
``remote`` extra, imported when the command runs).

Command::

    spm serve [--host 127.0.0.1] [--port 8750] [--sim kinematic|dynamic] [--design NAME|FILE]
              [--device DEV [--config FILE]] [--viewer] [--cors-origin ORIGIN ...]
              [--token-file FILE] [--deadline SECONDS]

Serves until Ctrl-C (or SIGTERM), then exits with status 0. Binding an address other
than loopback needs a bearer token (``--token-file`` or the environment variable
``SPM_TOKEN``); without one the command exits with status 2 before binding anything.
``--deadline``: seconds the streaming client that holds the lease (``WS /stream``)
may stay silent before the lease ends and the twin stops (default 0.5).
``--device``: the servos on that port (:class:`~spm_pin.remote.ServoBackend`); a stop
turns their torque off. ``--viewer``: a meshcat page follows the twin.
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


def _twin(args: argparse.Namespace, design: Any, stack: contextlib.ExitStack) -> Any:
    """The twin the options ask for, closed by ``stack``."""
    from ..remote import DynamicBackend, KinematicBackend

    if args.device is None:
        if args.config is not None:
            raise _UsageError("--config is the servos' configuration: give --device too")
        if args.sim == "dynamic":
            return stack.enter_context(DynamicBackend(design))
        # A stream's exact distances in a child process: the event loop is not
        # stalled by them.
        return stack.enter_context(KinematicBackend(design, distance_process=True))
    from ..collision import build_robot
    from ..hardware.config import HardwareConfig
    from ..hardware.driver import ServoBus
    from ..remote import ServoBackend

    if args.sim != "kinematic":
        raise _UsageError("--sim is the simulated twin: leave it out with --device")
    config = HardwareConfig() if args.config is None else HardwareConfig.load(args.config)
    config = config.replace(port=args.device)
    bus = stack.enter_context(
        ServoBus(
            config.port,
            config.ids,
            baudrate=config.baudrate,
            latency_timer_ms=config.latency_timer_ms,
            retries=config.retries,
            fast_sync_read=config.fast_sync_read,
        )
    )
    return stack.enter_context(ServoBackend(bus, config, robot=build_robot(design)))


class _Terminated(BaseException):
    """SIGTERM, raised in the main thread to unwind ``spm serve``.

    Not KeyboardInterrupt: CPython remembers a KeyboardInterrupt that passes through a
    nested C-level evaluation (an extension module running Python code while it
    imports, say) and then ends the process by SIGINT at exit, exit status -2, even
    when the exception was caught and everything closed cleanly. A BaseException of
    its own passes every ``except Exception`` on the way and leaves no such mark.
    """


def _serve_twin(
    args: argparse.Namespace, design: Any, token: str | None, stack: Any, serve: Any
) -> None:
    """Open the twin in ``stack``, say where it is served, serve until interrupted."""
    backend = _twin(args, design, stack)
    host = f"[{args.host}]" if ":" in args.host else args.host
    url = f"http://{host}:{args.port}"
    guarded = "bearer token required" if token is not None else "no token: loopback only"
    where = f" on {args.device}" if args.device is not None else ""
    print(
        f"spm serve: the {backend.name} twin of design {design.name!r}{where} at {url} "
        f"(API docs at {url}/docs; {guarded}); Ctrl-C stops",
        file=sys.stderr,
        flush=True,
    )
    if args.viewer:
        try:
            from ..remote.viewer import TwinViewer

            viewer = TwinViewer(backend)
        except ImportError as exc:
            raise _UsageError(
                f'--viewer needs meshcat ({exc}): pip install "spm-pin[viz]"'
            ) from exc
        viewer_url = viewer.start()
        stack.callback(viewer.stop)
        print(f"spm serve: the viewer follows the twin at {viewer_url}", file=sys.stderr)
    with contextlib.suppress(KeyboardInterrupt, _Terminated):
        serve(
            backend,
            host=args.host,
            port=args.port,
            token=token,
            deadline=args.deadline,
            cors_origins=tuple(args.cors_origin or ()),
        )


def _run_serve(args: argparse.Namespace) -> int:
    try:  # imported here: FastAPI, uvicorn and pydantic are the remote extra
        from ..remote import check_binding, load_token, serve
    except ImportError as exc:
        raise _UsageError(str(exc)) from exc
    token = load_token(args.token_file)
    check_binding(args.host, args.port, token)
    design = _design(args)

    def terminate(signum: int, frame: Any) -> None:
        raise _Terminated

    # SIGTERM stops like Ctrl-C from the start (uvicorn shuts down gracefully on SIGINT
    # and SIGTERM, then raises the signal again with the previous handlers): whenever
    # it comes, the twin is closed (the servos' torque off) and the exit status is 0.
    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        with (
            contextlib.suppress(KeyboardInterrupt, _Terminated),
            contextlib.ExitStack() as stack,
        ):
            _serve_twin(args, design, token, stack, serve)
            # Served: nothing interrupts the closing below (torque off, viewer down).
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
    finally:
        signal.signal(signal.SIGTERM, previous)
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
    serve.add_argument(
        "--device",
        metavar="DEV",
        help="serve the real robot: the servos on this serial port (e.g. /dev/ttyUSB0), "
        "kept in sync with the model; every goal passes the guard before the bus",
    )
    serve.add_argument(
        "--config",
        metavar="FILE",
        help="the servos' configuration (TOML, as spm servo takes; with --device)",
    )
    serve.add_argument(
        "--viewer",
        action="store_true",
        help="show the twin live in a meshcat viewer (viz extra)",
    )
    serve.add_argument(
        "--cors-origin",
        action="append",
        metavar="ORIGIN",
        help="let browser pages of this origin (e.g. http://127.0.0.1:8000) call the API; "
        "may be repeated",
    )
    serve.set_defaults(run=_run_serve)
