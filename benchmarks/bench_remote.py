"""Remote benchmark: ``spm serve``'s kinematic twin over HTTP and WebSocket on loopback.

Run from the repository root::

    python -m benchmarks.bench_remote [--out FILE.json] [--quick]

It prints a table and writes JSON (default ``benchmarks/results/remote.json``).

A real server (:class:`spm_pin.remote.BackgroundServer` serving a
:class:`~spm_pin.remote.KinematicBackend` on a free loopback port) runs in a process
of its own, as it would for a client program; the readers run in a third process, so
that client and server do not share an interpreter lock. What is measured:

1. ``get_state``: round trips of ``GET /state`` with httpx (one kept-alive
   connection, the body decoded), one request at a time.
2. ``stream_<rate>``: one controlling client on ``WS /stream`` (the ``websockets``
   client) takes the lease and sends targets at 100 Hz and at 1 kHz, open loop on a
   fixed schedule, each timed (``t``) with its time on that schedule: the platform
   spins about the axis (the three inputs together), from rest at 300 deg/s^2 up to
   30 deg/s (inside the guard's 90 deg/s and 360 deg/s^2), while 10 readers receive
   the state pushed at the same rate. ``stream_1000_untimed`` sends the same goals
   at 1 kHz without ``t``: the server then times them by their arrival, and network
   jitter makes some look too fast (they are refused: counted, not an error of the
   benchmark). ``stream_1000_readers_100`` sends the timed goals at 1 kHz again, with
   the 10 readers at 100 Hz (a display's or a logger's rate; reported beside the
   target, which is judged with the readers at 1 kHz). For each target the time from
   its send to its answer (``ack``, ``refused`` or ``error``, matched by ``seq``);
   targets without an answer when the run ends are ``lost``
   (``acks + refused + errors + lost == sent``). For the pushes: how many each
   connection received, the server's ``seq`` (pushes sent) and ``dropped`` (ticks
   the server's pusher skipped because it was late by a period or more: its event
   loop or the send was behind).
3. ``peer``: the same queries through the Python API in this process:
   ``backend.state()``, and ``backend.command(goal, previous=..., before_previous=...,
   period=...)`` (what the server does with a streamed target: the guard's checks,
   no state read back) along the same kind of path (a new backend, so nothing is
   cached from the server's run); ``backend.move(...)``, which also answers the
   state at the goal (its exact distances), beside it.

Targets: at 1 kHz with 10 readers, p99 of the answer latency <= 5 ms,
targets answered at >= 990 per second, and nothing lost silently (every target
answered, every push the server sent received).
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import importlib.util
import json
import math
import multiprocessing
import os
import socket
import sys
import time
from collections.abc import Sequence
from multiprocessing.connection import Connection
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import httpx  # noqa: E402
import numpy as np  # noqa: E402
from websockets.asyncio.client import ClientConnection, connect  # noqa: E402
from websockets.exceptions import ConnectionClosed  # noqa: E402

#: The event loop of every process here, when installed (uvicorn takes it too).
uvloop: Any = importlib.import_module("uvloop") if importlib.util.find_spec("uvloop") else None

import spm_pin as spm  # noqa: E402
from spm_pin.remote import KinematicBackend  # noqa: E402

from ._common import (  # noqa: E402
    Timing,
    format_count,
    format_rate,
    format_seconds,
    format_table,
    machine_info,
    run_main,
    standard_parser,
    target,
    time_each,
    with_all_pass,
)

#: The target: answer latency p99 [s] of targets at TARGET_RATE [Hz].
TARGET_P99_S = 5e-3
TARGET_RATE = 1000.0
#: Answered targets per second at TARGET_RATE that count as sustained [Hz].
TARGET_SUSTAINED = 990.0
#: The readers' rate of the last stream [Hz]: the controlling client at 1 kHz beside
#: readers at a display's or a logger's rate (reported; the target is judged with the
#: readers at 1 kHz).
SLOW_READERS_HZ = 100.0
#: Stream rates of the controlling client and the readers [Hz].
RATES = (100.0, 1000.0)
#: The streamed motion: from rest, this acceleration [deg/s^2] up to this speed [deg/s]
#: (the guard's limits: 360 deg/s^2, 90 deg/s).
ACCEL_DEG_S2 = 300.0
SPEED_DEG_S = 30.0
#: Direction of the streamed path (per input): all three together, a spin about the
#: axis (safe however far it goes).
DIRECTION = (1.0, 1.0, 1.0)
#: Seconds between taking the lease and the first target (from rest, the first step's
#: acceleration is then small).
SETTLE_S = 0.05
#: Seconds to wait for the answers still due after the last target was sent.
DRAIN_S = 5.0
#: Seconds to wait for the server and the readers to start.
START_TIMEOUT_S = 60.0

#: Sizes: GET round trips, seconds of streaming per rate, readers, in-process calls.
SIZES: dict[str, dict[str, float]] = {
    "full": {"gets": 2000, "seconds": 5.0, "readers": 10, "peer": 500},
    "quick": {"gets": 40, "seconds": 0.3, "readers": 2, "peer": 20},
}


# --------------------------------------------------------------------- processes
def _serve(port: int) -> None:
    """The server's process: a kinematic twin served as ``spm serve`` serves it."""
    from spm_pin.remote import serve

    with KinematicBackend(distance_process=True) as twin:
        serve(twin, port=port, log_level="warning")


async def _read(url: str, stop: Any, ready: list[bool]) -> dict[str, Any]:
    """One reader: count (and decode) the states pushed until ``stop`` is set."""
    received, last_seq, dropped = 0, 0, 0
    start = time.perf_counter()
    async with connect(url, max_size=None) as ws:
        json.loads(await ws.recv())  # hello
        ready.append(True)
        start = time.perf_counter()

        async def watch() -> None:  # close when told (no timeout per message)
            while not stop.is_set():
                await asyncio.sleep(0.05)
            await ws.close()

        watcher = asyncio.ensure_future(watch())
        with contextlib.suppress(ConnectionClosed):
            async for text in ws:
                message = json.loads(text)
                if message.get("type") == "state":
                    received += 1
                    last_seq, dropped = int(message["seq"]), int(message["dropped"])
        watcher.cancel()
    return {
        "received": received,
        "pushed": last_seq,
        "dropped": dropped,
        "seconds": time.perf_counter() - start,
    }


def _readers(url: str, count: int, ready: Any, stop: Any, conn: Connection) -> None:
    """The readers' process: ``count`` connections until ``stop``; their counts."""

    async def main() -> list[dict[str, Any]]:
        connected: list[bool] = []
        tasks = [asyncio.ensure_future(_read(url, stop, connected)) for _ in range(count)]
        while len(connected) < count and not all(t.done() for t in tasks):
            await asyncio.sleep(0.01)
        ready.set()
        return list(await asyncio.gather(*tasks))

    cpu = time.process_time()
    counts = _run(main())
    conn.send({"counts": counts, "cpu_s": time.process_time() - cpu})


def _run(main: Any) -> Any:
    """``asyncio.run`` on uvloop's event loop when it is installed (as the server's
    uvicorn does): the readers' and the client's processes then cost less CPU, which
    on a small machine they share with the server."""
    return asyncio.run(main) if uvloop is None else uvloop.run(main)


def _cpu_seconds(pid: int) -> float:
    """User and system CPU seconds of process ``pid`` so far (Linux; NaN elsewhere)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
    except OSError:
        return math.nan
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


# --------------------------------------------------------------------- controller
async def _answer(ws: ClientConnection, seq: int, timeout: float) -> dict[str, Any]:
    """The answer with ``seq`` (state pushes skipped)."""
    end = time.perf_counter() + timeout
    while True:
        text = await asyncio.wait_for(ws.recv(), max(end - time.perf_counter(), 1e-3))
        message: dict[str, Any] = json.loads(text)
        if message.get("seq") == seq and message.get("type") != "state":
            return message


def _path(start_deg: np.ndarray[Any, Any], rate: float, count: int) -> np.ndarray[Any, Any]:
    """Goals 1..count [deg], (count, 3), of the motion from rest at ``start_deg``,
    one every 1/rate s."""
    t = np.arange(1, count + 1) / rate
    ramp = SPEED_DEG_S / ACCEL_DEG_S2
    distance = np.where(
        t <= ramp,
        0.5 * ACCEL_DEG_S2 * t**2,
        0.5 * ACCEL_DEG_S2 * ramp**2 + SPEED_DEG_S * (t - ramp),
    )
    goals: np.ndarray[Any, Any] = start_deg + distance[:, None] * np.asarray(DIRECTION)
    return goals


async def _control(
    url: str, rate: float, count: int, start_deg: np.ndarray[Any, Any], *, timed: bool = True
) -> dict[str, Any]:
    """Take the lease, send ``count`` targets at ``rate`` (timed: with their times on
    the schedule), time every answer."""
    goals = _path(start_deg, rate, count)
    sent_at: dict[int, float] = {}
    answered_at: dict[int, float] = {}
    kinds: dict[str, int] = {"ack": 0, "refused": 0, "error": 0}
    why: dict[str, int] = {}
    pushes = {"received": 0, "pushed": 0, "dropped": 0}
    acked: list[int] = []
    done = asyncio.Event()
    sending = [True]

    async with connect(f"{url}?rate={rate:g}", max_size=None) as ws:
        json.loads(await ws.recv())  # hello
        await ws.send(json.dumps({"type": "lease", "seq": 0}))
        lease = await _answer(ws, 0, START_TIMEOUT_S)
        if not lease.get("held"):
            raise RuntimeError(f"the lease was not granted: {lease}")
        await asyncio.sleep(SETTLE_S)

        async def receive() -> None:
            while True:
                message = json.loads(await ws.recv())
                now = time.perf_counter()
                kind, seq = message.get("type"), message.get("seq")
                if kind == "state":
                    pushes["received"] += 1
                    pushes["pushed"], pushes["dropped"] = message["seq"], message["dropped"]
                    continue
                if kind not in kinds or seq not in sent_at or seq in answered_at:
                    continue
                answered_at[seq] = now
                kinds[kind] += 1
                if kind == "ack":
                    acked.append(seq)
                if kind == "refused":
                    for failed in message.get("failed", []):
                        why[f"refused: {failed['check']}"] = (
                            why.get(f"refused: {failed['check']}", 0) + 1
                        )
                elif kind == "error":
                    name = f"error {message.get('status')}"
                    why[name] = why.get(name, 0) + 1
                if not sending[0] and len(answered_at) == len(sent_at):
                    done.set()

        receiver = asyncio.ensure_future(receive())
        loop = asyncio.get_running_loop()
        first = loop.time()
        send_start = time.perf_counter()
        for k, goal in enumerate(goals, start=1):
            delay = first + (k - 1) / rate - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            message = {"type": "target", "seq": k, "theta_deg": goal.tolist()}
            if timed:
                message["t"] = first + (k - 1) / rate
            text = json.dumps(message)
            sent_at[k] = time.perf_counter()
            await ws.send(text)
        send_end = time.perf_counter()
        sending[0] = False
        if len(answered_at) == len(sent_at):
            done.set()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(done.wait(), DRAIN_S)
        last_answer = max(answered_at.values(), default=send_end)
        receiver.cancel()
        with contextlib.suppress(asyncio.CancelledError, ConnectionClosed):
            await receiver
        await ws.send(json.dumps({"type": "release", "seq": count + 1}))
        with contextlib.suppress(TimeoutError, ConnectionClosed):
            await _answer(ws, count + 1, DRAIN_S)

    latencies = [answered_at[k] - sent_at[k] for k in sorted(answered_at)]
    lost = len(sent_at) - len(answered_at)
    if lost:
        why["lost: no answer"] = lost
    final = goals[max(acked) - 1] if acked else start_deg
    result: dict[str, Any] = {
        "rate_hz": rate,
        "timed": timed,
        "sent": len(sent_at),
        "acks": kinds["ack"],
        "refused": kinds["refused"],
        "errors": kinds["error"],
        "lost": lost,
        "why": why,
        "send_rate_hz": (len(sent_at) - 1) / (send_end - send_start) if count > 1 else 0.0,
        "answer_rate_hz": len(answered_at) / (last_answer - send_start),
        "controller_pushes": pushes,
        "final_deg": final.tolist(),
    }
    if latencies:
        result["latency"] = Timing(tuple(latencies)).summary()
    return result


def bench_stream(
    base: str,
    ws_url: str,
    server: int,
    rate: float,
    seconds: float,
    readers: int,
    start_deg: Any,
    reader_rate: float | None = None,
    *,
    timed: bool = True,
) -> dict[str, Any]:
    """One controlling client at ``rate`` with ``readers`` readers at ``reader_rate``
    (default: the same rate); its targets timed (``t``) or not. ``server``: the
    server's process id (its CPU time is reported)."""
    ctx = multiprocessing.get_context("spawn")
    ready, stop = ctx.Event(), ctx.Event()
    receiver, sender = ctx.Pipe(duplex=False)
    url = f"{ws_url}/stream"
    process = ctx.Process(
        target=_readers,
        args=(f"{url}?rate={reader_rate or rate:g}", readers, ready, stop, sender),
    )
    process.start()
    try:
        if not ready.wait(START_TIMEOUT_S):
            raise RuntimeError("the readers did not connect")
        count = max(round(seconds * rate), 2)
        start = np.asarray(start_deg, dtype=float)
        wall, cpu, served = time.perf_counter(), time.process_time(), _cpu_seconds(server)
        result: dict[str, Any] = _run(_control(url, rate, count, start, timed=timed))
        cpu_s = {
            "wall": time.perf_counter() - wall,
            "server": _cpu_seconds(server) - served,
            "controller": time.process_time() - cpu,
        }
    finally:
        stop.set()
    sent: dict[str, Any] = receiver.recv() if receiver.poll(START_TIMEOUT_S) else {}
    counts: list[dict[str, Any]] = sent.get("counts", [])
    # The readers' process: its whole run (connected before, closing after the stream).
    result["cpu_s"] = {**cpu_s, "readers": sent.get("cpu_s", math.nan)}
    process.join(START_TIMEOUT_S)
    if process.is_alive():
        process.terminate()
    received = sum(c["received"] for c in counts)
    pushed = sum(c["pushed"] for c in counts)
    result["readers"] = {
        "connections": readers,
        "rate_hz": reader_rate or rate,
        "per_connection": counts,
        "received": received,
        "pushed": pushed,
        "dropped": sum(c["dropped"] for c in counts),
        "not_received": pushed - received,
        "received_per_second_each": float(
            np.mean([c["received"] / c["seconds"] for c in counts]) if counts else 0.0
        ),
    }
    with httpx.Client(base_url=base, timeout=30.0) as http:
        result["server_state"] = {"stops": http.get("/state").json().get("stops")}
    return result


# --------------------------------------------------------------------------- peer
def bench_peer(n: int, rates: Sequence[float]) -> dict[str, Any]:
    """backend.state() and backend.move(...) in this process."""
    backend = KinematicBackend()
    state, _ = time_each(lambda _: backend.state(), list(range(n)), warmup=5)
    results: dict[str, Any] = {"state": {**state.summary(), "n": n}}
    for name, calls in (("command", n), ("move", max(n // 10, 5))):
        for rate in rates:
            theta = backend.joints()
            step = np.radians(SPEED_DEG_S / rate * np.asarray(DIRECTION))
            goals = [theta + (k + 1) * step for k in range(calls)]
            history = [theta - step, theta]  # already cruising at the path's speed
            call = getattr(backend, name)

            def one(
                goal: np.ndarray[Any, Any],
                rate: float = rate,
                history: list[Any] = history,
                call: Any = call,
            ) -> None:
                call(goal, previous=history[-1], before_previous=history[-2], period=1 / rate)
                history.append(goal)

            timing, _ = time_each(one, goals, warmup=0)
            results[f"{name}_{rate:g}"] = {**timing.summary(), "n": calls, "period_s": 1 / rate}
    return results


# ------------------------------------------------------------------------------ run
def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _server() -> tuple[Any, int]:
    """The server in a process of its own, on a free loopback port, once it answers."""
    port = _free_port()
    process = multiprocessing.get_context("spawn").Process(target=_serve, args=(port,))
    process.start()
    end = time.monotonic() + START_TIMEOUT_S
    with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=5.0) as http:
        while True:
            try:
                if http.get("/state").status_code == 200:
                    return process, port
            except httpx.TransportError:
                pass
            if not process.is_alive() or time.monotonic() > end:
                process.terminate()
                raise RuntimeError("the server did not start")
            time.sleep(0.1)


def bench_get_state(base: str, n: int) -> dict[str, Any]:
    """GET /state round trips, one at a time on one connection."""
    with httpx.Client(base_url=base, timeout=30.0) as http:

        def get(_: int) -> Any:
            response = http.get("/state")
            response.raise_for_status()
            return response.json()

        timing, answers = time_each(get, list(range(n)), warmup=10)
    return {**timing.summary(), "n": n, "backend": answers[-1]["backend"]}


def run(sizes: dict[str, float], *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    process, port = _server()
    base, ws_url = f"http://127.0.0.1:{port}", f"ws://127.0.0.1:{port}"
    try:
        results: dict[str, Any] = {"get_state": bench_get_state(base, int(sizes["gets"]))}
        # Each stream starts where the one before left the twin.
        streams: list[tuple[str, float, dict[str, Any]]] = [
            *((f"stream_{rate:g}", rate, {}) for rate in RATES),
            (f"stream_{TARGET_RATE:g}_untimed", TARGET_RATE, {"timed": False}),
            (
                f"stream_{TARGET_RATE:g}_readers_{SLOW_READERS_HZ:g}",
                TARGET_RATE,
                {"reader_rate": SLOW_READERS_HZ},
            ),
        ]
        start_deg = np.zeros(3)
        for key, rate, options in streams:
            results[key] = bench_stream(
                base,
                ws_url,
                process.pid,
                rate,
                float(sizes["seconds"]),
                int(sizes["readers"]),
                start_deg,
                **options,
            )
            start_deg = np.asarray(results[key]["final_deg"])
    finally:
        process.terminate()  # SIGTERM: uvicorn shuts down, the twin stops
        process.join(30)
        if process.is_alive():
            process.kill()
    results["peer"] = bench_peer(int(sizes["peer"]), RATES)
    fast = results[f"stream_{TARGET_RATE:g}"]
    p99 = fast["latency"]["p99_s"] if "latency" in fast else float("inf")
    silent = fast["lost"] + fast["readers"]["not_received"]
    silent += results["stream_100"]["lost"] + results["stream_100"]["readers"]["not_received"]
    delivered = 1.0 - silent / max(
        1,
        sum(
            results[f"stream_{r:g}"]["sent"] + results[f"stream_{r:g}"]["readers"]["pushed"]
            for r in RATES
        ),
    )
    return {
        "benchmark": "remote",
        "machine": machine_info(
            ("numpy", "pin", "coal", "fastapi", "uvicorn", "httpx", "websockets", "uvloop"),
            {"spm_pin": spm.__version__},
        ),
        "config": {
            "quick": quick,
            "sizes": sizes,
            "rates_hz": list(RATES),
            "accel_deg_s2": ACCEL_DEG_S2,
            "speed_deg_s": SPEED_DEG_S,
            "direction": list(DIRECTION),
            "drain_s": DRAIN_S,
            "threads_limited_before_numpy": THREADS_LIMITED,
            "processes": "server, readers and the measuring client each in its own process",
            "event_loop": "asyncio" if uvloop is None else "uvloop",
            "timing": "perf_counter from a request's send to its answer in the client; "
            "median/p95/p99",
        },
        "results": results,
        "targets": with_all_pass(
            {
                "stream_1khz_p99": target(p99, TARGET_P99_S, at_least=False, unit="s"),
                "stream_1khz_rate": target(
                    fast["answer_rate_hz"], TARGET_SUSTAINED, at_least=True, unit="Hz"
                ),
                "nothing_lost_silently": target(delivered, 1.0, at_least=True, unit="fraction"),
            }
        ),
    }


def _cpu_line(cpu: dict[str, float] | None) -> str:
    """The processes' CPU seconds over a stream, when measured."""
    if not cpu:
        return ""
    return (
        f"; CPU over {cpu['wall']:.1f} s: server {cpu['server']:.1f} s, readers "
        f"{cpu['readers']:.1f} s, client {cpu['controller']:.1f} s"
    )


def report(payload: dict[str, Any]) -> str:
    """The printed summary."""
    results = payload["results"]
    peer = results["peer"]
    rows = []

    def row(label: str, r: dict[str, Any], n: int) -> list[str]:
        return [
            label,
            format_count(n),
            format_seconds(r["median_s"]),
            format_seconds(r["p95_s"]),
            format_seconds(r["p99_s"]),
        ]

    rows.append(row("GET /state round trip", results["get_state"], results["get_state"]["n"]))
    rows.append(row("in process: backend.state()", peer["state"], peer["state"]["n"]))
    for rate in RATES:
        stream = results[f"stream_{rate:g}"]
        if "latency" in stream:
            rows.append(row(f"WS target at {rate:g} Hz, answer", stream["latency"], stream["sent"]))
        for name in ("command", "move"):
            entry = peer[f"{name}_{rate:g}"]
            rows.append(row(f"in process: backend.{name}(), {rate:g} Hz", entry, entry["n"]))
    slow = results.get(f"stream_{TARGET_RATE:g}_readers_{SLOW_READERS_HZ:g}")
    if slow is not None and "latency" in slow:
        label = f"WS target at {TARGET_RATE:g} Hz, readers at {SLOW_READERS_HZ:g} Hz, answer"
        rows.append(row(label, slow["latency"], slow["sent"]))
    table = format_table(["case", "n", "median", "p95", "p99"], rows)
    lines = []
    for key in [f"stream_{rate:g}" for rate in RATES] + [
        f"stream_{TARGET_RATE:g}_untimed",
        f"stream_{TARGET_RATE:g}_readers_{SLOW_READERS_HZ:g}",
    ]:
        if key not in results:
            continue
        s = results[key]
        r = s["readers"]
        why = ", ".join(f"{k} {v}" for k, v in s["why"].items()) or "none"
        timing = "timed" if s.get("timed", True) else "untimed (arrival times)"
        lines.append(
            f"{s['rate_hz']:g} Hz {timing}: sent {s['sent']} at "
            f"{format_rate(s['send_rate_hz'])}, answered at "
            f"{format_rate(s['answer_rate_hz'])}: {s['acks']} acks, {s['refused']} refused, "
            f"{s['errors']} errors, {s['lost']} lost (why: {why}); {r['connections']} readers "
            f"at {r.get('rate_hz', s['rate_hz']):g} Hz: "
            f"{format_count(r['received'])} states received of {format_count(r['pushed'])} "
            f"pushed ({format_rate(r['received_per_second_each'])} each), "
            f"{format_count(r['dropped'])} ticks dropped by the server" + _cpu_line(s.get("cpu_s"))
        )
    targets = payload["targets"]
    checks = [
        ("stream_1khz_p99", "answer latency p99 at 1 kHz", format_seconds),
        ("stream_1khz_rate", "targets answered per second at 1 kHz", format_rate),
        ("nothing_lost_silently", "targets answered and pushes received", lambda v: f"{v:.1%}"),
    ]
    target_lines = []
    for name, label, fmt in checks:
        t = targets[name]
        status = "PASS" if t["pass"] else "FAIL"
        target_lines.append(
            f"  {status}  {label}: {fmt(t['value'])} ({t['comparison']} {fmt(t['threshold'])})"
        )
    head = "spm-pin remote benchmark: spm serve (kinematic twin) on loopback"
    return "\n\n".join([head, table, "\n".join(lines), "Targets\n" + "\n".join(target_lines)])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "remote",
        "Latency and sustained rate of spm serve over HTTP and WebSocket on loopback.",
    )
    return run_main(
        parser,
        lambda args: run(SIZES["quick" if args.quick else "full"], quick=args.quick),
        report,
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
