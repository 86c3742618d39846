"""The emulated servo bus on a real pseudo-terminal, in a process of its own.

:func:`serve` answers Protocol 2.0 on the master side of a pseudo-terminal; a
controller opens the slave side (``/dev/pts/N``) exactly as it would open
``/dev/ttyUSB0``. The SDK busy-waits for replies, so the emulator runs in another
process: :class:`EmulatedBus` starts ``python -m spm_pin servo emulate`` (the same
program as the ``spm servo emulate`` command), reads the device path from its first
line and talks to it over a private control socket (fault injection, the log of
received packets, the servos' state)::

    with EmulatedBus(ids=(1, 2, 3)) as bus:
        print(bus.port)          # e.g. /dev/pts/4
        bus.unplug(2)            # servo 2 leaves the bus
        bus.log()                # every instruction packet received

The servos answer at the XM540-W150's factory default, 57600 bit/s, unless given
another ``baudrate``; the emulator drops replies while the line's baud rate (set by
the controller on the terminal) differs from a servo's Baud Rate item, as a real
servo hears only noise. So a controller must open the port at the servos' rate
(``ServoBus(bus.port, baudrate=bus.baudrate)``; the driver's default is the factory
rate too).

The emulator does not spend the wire time, but it is a process like any other: on a
machine whose cores are busy, the scheduler can hold a reply back by tens of
milliseconds. A controller of the emulated bus should allow for
:data:`LATENCY_TIMER_MS` (``latency_timer_ms``) rather than a real adapter's 1-16 ms.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import subprocess
import sys
import termios
import time
import tty
from collections.abc import Callable, Iterable, Mapping, Sequence
from types import FrameType, TracebackType
from typing import Any, NamedTuple

from ..errors import HardwareError, InputError
from .control_table import XM540_W150
from .emulator import DEFAULT_BAUDRATE, DEFAULT_FIRMWARE, LogEntry, ServoEmulator

__all__ = ["LATENCY_TIMER_MS", "EmulatedBus", "GoalWrite", "open_pty", "serve"]

#: How long :meth:`EmulatedBus.start` waits for the emulator's first line [s].
START_TIMEOUT = 30.0
#: How long a control request may take [s].
CONTROL_TIMEOUT = 10.0
#: Latency a controller of the emulated bus should allow for in its packet timeout
#: (``ServoBus(latency_timer_ms=...)``) [ms]. The packet timeout is the wire time
#: at the line rate plus twice this plus 2 ms, about 0.1 s: on 2 cores busy with 4
#: other processes the reply of the emulator process came up to ~50 ms after the
#: request (with 10 ms, 1 in 70 transactions timed out); a silent servo still
#: costs only a tenth of a second per attempt.
LATENCY_TIMER_MS = 50.0

_SPEEDS: dict[int, int] = {}
for _rate in (9600, 57600, 115200, 1000000, 2000000, 3000000, 4000000):
    _code = getattr(termios, f"B{_rate}", None)
    if _code is not None:
        _SPEEDS[int(_code)] = _rate


def open_pty() -> tuple[int, int, str]:
    """A raw pseudo-terminal: (master fd, slave fd, slave path).

    Both ends are raw (no echo, no line editing); the master is non-blocking, so a
    reply that nobody reads is dropped instead of blocking the emulator.
    """
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


def line_baudrate(slave_fd: int) -> int | None:
    """The baud rate a controller set on the terminal [bit/s] (None if unknown)."""
    try:
        speed = termios.tcgetattr(slave_fd)[5]
    except termios.error:
        return None
    return _SPEEDS.get(int(speed))


class _Control:
    """JSON-line requests on the control socket, answered by the server."""

    def __init__(self, sock: socket.socket, server: _Server) -> None:
        self.sock = sock
        self.server = server
        self.buffer = b""
        sock.setblocking(False)

    def poll(self) -> bool:
        """Handle what arrived; False when the other end closed the socket."""
        try:
            data = self.sock.recv(65536)
        except BlockingIOError:
            return True
        except OSError:
            return False
        if not data:
            return False
        self.buffer += data
        while b"\n" in self.buffer:
            line, self.buffer = self.buffer.split(b"\n", 1)
            self._answer(line)
        return True

    def _answer(self, line: bytes) -> None:
        try:
            request = json.loads(line)
            result = self.server.command(request)
            reply = {"ok": True, "result": result}
        except Exception as exc:  # reported to the client, which raises
            reply = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        self.sock.setblocking(True)
        try:
            self.sock.sendall(json.dumps(reply).encode() + b"\n")
        finally:
            self.sock.setblocking(False)


class _Server:
    """The select loop: bytes from the terminal to the emulator and back."""

    def __init__(
        self, emulator: ServoEmulator, master: int, slave: int, factory: Callable[[], ServoEmulator]
    ) -> None:
        self.emulator = emulator
        self.master = master
        self.slave = slave
        self.factory = factory
        self.running = True

    def command(self, request: Mapping[str, Any]) -> Any:
        """Execute one control request (fault injection, state, log)."""
        op = request.get("op")
        emulator = self.emulator
        if op == "stop":
            self.running = False
            return None
        if op == "ping":
            return {"ids": emulator.ids, "port": os.ttyname(self.slave)}
        if op == "reset":
            self.emulator = self.factory()
            return None
        if op == "unplug":
            emulator.unplug(int(request["id"]))
            return None
        if op == "plug":
            emulator.plug(int(request["id"]))
            return None
        if op == "silence":
            emulator.silence(request.get("count"), request.get("ids"))
            return None
        if op == "corrupt":
            emulator.corrupt(request.get("count"), request.get("ids"), request.get("kind", "crc"))
            return None
        if op == "clear_faults":
            emulator.clear_faults()
            return None
        if op == "alert":
            return emulator.alert(int(request["id"]), int(request["flags"]))
        if op == "set":
            servo = emulator.servo(int(request["id"]))
            servo.update(emulator.clock())
            servo.set(str(request["item"]), int(request["value"]))
            return None
        if op == "freeze":
            servo = emulator.servo(int(request["id"]))
            servo.update(emulator.clock())
            servo.frozen = bool(request["on"])
            return None
        if op == "state":
            servo = emulator.servo(int(request["id"]))
            servo.update(emulator.clock())
            state: dict[str, Any] = {name: servo.get(name) for name in XM540_W150}
            state["unplugged"] = servo.unplugged
            state["position_exact"] = servo.position
            return state
        if op == "log":
            since = int(request.get("since", 0))
            return [entry.to_dict() for entry in emulator.log if entry.seq > since]
        if op == "stats":
            return dict(emulator.stats)
        raise InputError(f"unknown control request {op!r}", argument="op", value=op)

    def pump(self) -> None:
        """Read what the controller sent and write the replies."""
        try:
            data = os.read(self.master, 65536)
        except BlockingIOError:
            return
        except OSError:  # nobody has the terminal open: nothing to answer
            time.sleep(0.001)
            return
        replies = self.emulator.receive(data, line_baudrate=line_baudrate(self.slave))
        for reply in replies:
            if reply.delay > 0:
                time.sleep(reply.delay)
            with contextlib.suppress(BlockingIOError, OSError):
                os.write(self.master, reply.data)


def serve(
    ids: Sequence[int] = (1, 2, 3),
    *,
    baudrate: int = DEFAULT_BAUDRATE,
    firmware: int = DEFAULT_FIRMWARE,
    positions: Mapping[int, int] | None = None,
    control_fd: int | None = None,
    announce: Callable[[str], None] | None = None,
) -> dict[str, int]:
    """Serve an emulated bus on a new pseudo-terminal until stopped.

    Stops on SIGTERM, Ctrl-C (SIGINT), a ``stop`` request or when the control socket
    closes.

    Args:
        ids: Servo IDs.
        baudrate: Baud rate of every servo [bit/s] (default: the factory default, 57600).
        firmware: Firmware Version of every servo.
        positions: Present Position at power-up by id [pulses].
        control_fd: A connected socket's file descriptor for control requests.
        announce: Called once with the device path when the bus is ready.

    Returns:
        Counters: packets received, replies sent, silenced, corrupted.
    """
    ids = tuple(ids)

    def factory() -> ServoEmulator:
        return ServoEmulator(ids, baudrate=baudrate, firmware=firmware, positions=positions)

    master, slave, path = open_pty()
    server = _Server(factory(), master, slave, factory)
    control = None
    if control_fd is not None:
        control = _Control(socket.socket(fileno=control_fd), server)

    def stop(signum: int, frame: FrameType | None) -> None:
        server.running = False

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        if announce is not None:
            announce(path)
        while server.running:
            watched: list[Any] = [master] if control is None else [master, control.sock]
            ready, _, _ = select.select(watched, [], [], 0.5)
            if master in ready:
                server.pump()
            if control is not None and control.sock in ready and not control.poll():
                break
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
        if control is not None:
            control.sock.close()
        os.close(master)
        os.close(slave)
    return dict(server.emulator.stats)


# ----------------------------------------------------------------------- client side
class GoalWrite(NamedTuple):
    """A Goal Position that reached a servo."""

    #: Emulator clock when the packet arrived [s].
    time: float
    #: The servo.
    servo_id: int
    #: The goal [pulses, signed].
    pulses: int


class EmulatedBus:
    """An emulated XM540-W150 bus in a child process, on a real pseudo-terminal.

    Use it as a context manager (or call :meth:`start` and :meth:`stop`). The child
    also stops when this object's control socket closes, so a crashed test leaves
    no emulator behind.

    Args:
        ids: Servo IDs on the bus.
        baudrate: Baud rate every servo expects [bit/s] (default: the XM540-W150's
            factory default, 57600); open the port at this rate.
        firmware: Firmware Version (fast sync read needs >= 45).
        positions: Present Position of each servo at power-up [pulses, 0..4095], by id.

    Attributes:
        port: Device path to open (e.g. ``/dev/pts/4``), set by :meth:`start`.
    """

    def __init__(
        self,
        ids: Iterable[int] = (1, 2, 3),
        *,
        baudrate: int = DEFAULT_BAUDRATE,
        firmware: int = DEFAULT_FIRMWARE,
        positions: Mapping[int, int] | None = None,
    ) -> None:
        self.ids = tuple(int(i) for i in ids)
        ServoEmulator(self.ids, baudrate=baudrate, firmware=firmware, positions=positions)
        self.baudrate = baudrate
        self.firmware = firmware
        self.positions = dict(positions or {})
        self.port = ""
        self._process: subprocess.Popen[str] | None = None
        self._sock: socket.socket | None = None
        self._buffer = b""

    def __repr__(self) -> str:
        state = f"port={self.port!r}" if self.running else "stopped"
        return f"EmulatedBus(ids={list(self.ids)}, {state})"

    @property
    def running(self) -> bool:
        """The child process is alive."""
        return self._process is not None and self._process.poll() is None

    def command(self) -> list[str]:
        """The command line of the emulator process."""
        cmd = [sys.executable, "-m", "spm_pin", "servo", "emulate", "--ids"]
        cmd += [str(i) for i in self.ids]
        cmd += ["--baud", str(self.baudrate), "--firmware", str(self.firmware)]
        if self.positions:
            cmd += ["--positions", *(str(self.positions.get(i, 2048)) for i in self.ids)]
        return cmd

    def start(self, timeout: float = START_TIMEOUT) -> EmulatedBus:
        """Start the emulator and wait until its terminal is ready.

        Raises:
            HardwareError: the process did not announce its device within ``timeout``.
        """
        if self.running:
            return self
        parent, child = socket.socketpair()
        cmd = [*self.command(), "--control-fd", str(child.fileno())]
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self._process = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            pass_fds=(child.fileno(),),
            text=True,
            env=env,
        )
        child.close()
        self._sock = parent
        stdout = self._process.stdout
        ready = select.select([stdout], [], [], timeout)[0] if stdout is not None else []
        line = stdout.readline() if ready and stdout is not None else ""
        if not line.strip():
            error = self._abort()
            raise HardwareError(
                f"the servo emulator did not start within {timeout:g} s: {error}",
                operation="start emulator",
            )
        self.port = line.split()[-1]
        return self

    def _abort(self) -> str:
        process = self._process
        if process is None:
            return ""
        with contextlib.suppress(OSError):
            process.kill()
        try:
            _, err = process.communicate(timeout=5)
        except (subprocess.TimeoutExpired, ValueError):
            err = ""
        self._close()
        return " ".join((err or "no output").split())[-500:]

    def _close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None
        process = self._process
        if process is not None:
            for stream in (process.stdout, process.stderr):
                if stream is not None:
                    stream.close()
        self._process = None

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the emulator (politely, then by signal) and release its terminal."""
        process = self._process
        if process is None:
            return
        if process.poll() is None:
            with contextlib.suppress(HardwareError, OSError):
                self._call("stop", timeout=timeout)
            try:
                process.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                process.terminate()
                try:
                    process.wait(timeout=timeout)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait(timeout=timeout)
        self._close()

    def __enter__(self) -> EmulatedBus:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    # --------------------------------------------------------------- control
    def _call(self, op: str, timeout: float = CONTROL_TIMEOUT, **arguments: Any) -> Any:
        sock = self._sock
        if sock is None or not self.running:
            raise HardwareError("the servo emulator is not running", operation=op)
        sock.sendall(json.dumps({"op": op, **arguments}).encode() + b"\n")
        deadline = time.monotonic() + timeout
        while b"\n" not in self._buffer:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([sock], [], [], max(left, 0.0))
            if not ready:
                raise HardwareError(
                    f"the servo emulator did not answer {op!r} within {timeout:g} s", operation=op
                )
            data = sock.recv(1 << 20)
            if not data:
                raise HardwareError("the servo emulator exited", operation=op)
            self._buffer += data
        line, self._buffer = self._buffer.split(b"\n", 1)
        reply = json.loads(line)
        if not reply["ok"]:
            raise HardwareError(f"emulator: {reply['error']}", operation=op)
        return reply["result"]

    def reset(self) -> None:
        """Power every servo up afresh (defaults, start positions); clear faults and log."""
        self._call("reset")

    def unplug(self, servo_id: int) -> None:
        """Take a servo off the bus: it neither acts nor answers."""
        self._call("unplug", id=servo_id)

    def plug(self, servo_id: int) -> None:
        """Put a servo back (it powers up: torque off, multi-turn count lost)."""
        self._call("plug", id=servo_id)

    def silence(self, count: int | None = None, ids: Iterable[int] | None = None) -> None:
        """Lose the next ``count`` status packets (None: all) from ``ids`` (None: all)."""
        self._call("silence", count=count, ids=None if ids is None else list(ids))

    def corrupt(
        self, count: int | None = 1, ids: Iterable[int] | None = None, kind: str = "crc"
    ) -> None:
        """Garble status packets: ``kind`` is ``"crc"``, ``"truncate"`` or ``"noise"``."""
        self._call("corrupt", count=count, ids=None if ids is None else list(ids), kind=kind)

    def clear_faults(self) -> None:
        """Stop silencing and garbling; plug every servo back in."""
        self._call("clear_faults")

    def alert(self, servo_id: int, flags: int) -> int:
        """A hardware condition (Hardware Error Status bits); returns the bits latched."""
        return int(self._call("alert", id=servo_id, flags=int(flags)))

    def set_item(self, servo_id: int, item: str, value: int) -> None:
        """Set a control item directly, bypassing the access rules."""
        self._call("set", id=servo_id, item=item, value=int(value))

    def freeze(self, servo_id: int, on: bool = True) -> None:
        """Hold a servo's Present items at what :meth:`set_item` put there (no motion)."""
        self._call("freeze", id=servo_id, on=on)

    def state(self, servo_id: int) -> dict[str, Any]:
        """Every control item of a servo by name (plus ``unplugged``)."""
        result: dict[str, Any] = self._call("state", id=servo_id)
        return result

    def item(self, servo_id: int, name: str) -> int:
        """One control item of a servo."""
        return int(self.state(servo_id)[name])

    def stats(self) -> dict[str, int]:
        """Counters: packets, replies, silenced, corrupted."""
        result: dict[str, int] = self._call("stats")
        return result

    def log(self, since: int = 0) -> list[LogEntry]:
        """Instruction packets received after sequence number ``since``."""
        return [LogEntry.from_dict(entry) for entry in self._call("log", since=since)]

    def goal_writes(self, since: int = 0) -> list[GoalWrite]:
        """Every Goal Position that reached a servo (WRITE, SYNC_WRITE, ACTION, ...)."""
        item = XM540_W150["Goal Position"]
        goals = []
        for entry in self.log(since):
            for servo_id, address, data in entry.writes:
                offset = item.address - address
                if offset >= 0 and offset + item.size <= len(data):
                    value = item.decode(data[offset : offset + item.size])
                    goals.append(GoalWrite(entry.time, servo_id, value))
        return goals
