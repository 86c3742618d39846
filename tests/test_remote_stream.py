"""``WS /stream`` of the twin (spm_pin.remote.stream) against a real server.

uvicorn serves the application in a background thread on a free loopback port; the
``websockets`` package's client opens real WebSocket connections and httpx sends
real HTTP requests (no test client, no mocks). Deadlines are short (0.3 s) so the
file runs in seconds.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
httpx = pytest.importorskip("httpx")
pytest.importorskip("websockets")

from _remote_truth import STUDY_COLLISION_DEG  # noqa: E402
from websockets.exceptions import ConnectionClosed  # noqa: E402
from websockets.sync.client import ClientConnection, connect  # noqa: E402

from spm_pin.remote import BackgroundServer, KinematicBackend  # noqa: E402

#: Tolerances, by what is compared.
TOL = {
    "angles_deg": 1e-9,  # angles sent and read back [deg]
    "rate": 0.25,  # relative error of the count of pushed states
}
#: The streaming client's deadline in these tests [s].
DEADLINE = 0.3
#: Seconds to wait for one answer of the server.
ANSWER_TIMEOUT = 10.0
TOKEN = "stream-token-0123456789abcdef"
STATE_KEYS = {"type", "seq", "dropped", "lease", "theta_deg", "R", "reachable", "pairs", "stops"}


# --------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def backend() -> KinematicBackend:
    return KinematicBackend()


@pytest.fixture(scope="module")
def server(backend: KinematicBackend) -> Iterator[BackgroundServer]:
    with BackgroundServer(backend, deadline=DEADLINE) as running:
        yield running


@pytest.fixture(scope="module")
def token_server(backend: KinematicBackend) -> Iterator[BackgroundServer]:
    with BackgroundServer(backend, token=TOKEN, deadline=DEADLINE) as running:
        yield running


@pytest.fixture()
def http(server: BackgroundServer) -> Iterator[httpx.Client]:
    """An HTTP client; the twin starts at home with no lease held."""
    with httpx.Client(base_url=server.url, timeout=ANSWER_TIMEOUT) as session:
        _wait_for(lambda: not session.get("/lease").json()["held"])
        assert session.put("/joints", json={"theta_deg": [0, 0, 0]}).status_code == 200
        yield session


def _wait_for(condition: Any, timeout: float = ANSWER_TIMEOUT) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "condition not met in time"
        time.sleep(0.01)


@contextlib.contextmanager
def _open(server: BackgroundServer, query: str = "", **kwargs: Any) -> Iterator[ClientConnection]:
    """A connection whose hello message has been read."""
    with connect(f"{server.ws_url}/stream{query}", open_timeout=ANSWER_TIMEOUT, **kwargs) as ws:
        hello = json.loads(ws.recv(timeout=ANSWER_TIMEOUT))
        assert hello["type"] == "hello", hello
        yield ws


def _answer(ws: ClientConnection) -> dict[str, Any]:
    """The next message that is not a state."""
    while True:
        message: dict[str, Any] = json.loads(ws.recv(timeout=ANSWER_TIMEOUT))
        if message["type"] != "state":
            return message


def _send(ws: ClientConnection, message: dict[str, Any]) -> dict[str, Any]:
    ws.send(json.dumps(message))
    return _answer(ws)


def _state(ws: ClientConnection) -> dict[str, Any]:
    while True:
        message: dict[str, Any] = json.loads(ws.recv(timeout=ANSWER_TIMEOUT))
        if message["type"] == "state":
            return message


def _joints(http: httpx.Client) -> list[float]:
    theta: list[float] = http.get("/joints").json()["theta_deg"]
    return theta


def _closed_with(ws_url: str, **kwargs: Any) -> Any:
    """The close frame the server sends to a connection opened with ``kwargs``."""
    with (
        connect(ws_url, open_timeout=ANSWER_TIMEOUT, **kwargs) as ws,
        pytest.raises(ConnectionClosed) as closed,
    ):
        while True:
            ws.recv(timeout=ANSWER_TIMEOUT)
    return closed.value.rcvd


# ----------------------------------------------------------------------- states
def test_states_are_pushed_at_the_requested_rate(server: BackgroundServer) -> None:
    with _open(server, "?rate=50") as ws:
        seqs = []
        start = time.monotonic()
        while time.monotonic() - start < 1.0:
            message = json.loads(ws.recv(timeout=ANSWER_TIMEOUT))
            assert set(message) >= STATE_KEYS, message
            seqs.append(message["seq"])
        assert message["lease"] == {"held": False, "yours": False}
    # Pushes sent plus pushes skipped (none unless this machine is overloaded).
    assert abs(len(seqs) + message["dropped"] - 50) <= 50 * TOL["rate"], len(seqs)
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # increasing by one


def test_a_state_agrees_with_http(server: BackgroundServer, http: httpx.Client) -> None:
    with _open(server) as ws:
        pushed = _state(ws)
    got = http.get("/state").json()
    for key in ("theta_deg", "R", "reachable", "pairs", "assembly", "backend"):
        assert pushed[key] == got[key], key


@pytest.mark.parametrize("rate", ["0", "0.5", "1001", "fast", "nan", "inf"])
def test_a_bad_rate_closes_with_1008(server: BackgroundServer, rate: str) -> None:
    close = _closed_with(f"{server.ws_url}/stream?rate={rate}")
    assert close.code == 1008 and "rate" in close.reason


# ----------------------------------------------------------------------- targets
def test_a_streamed_safe_target_moves_the_twin(
    server: BackgroundServer, http: httpx.Client
) -> None:
    with _open(server) as ws:
        assert _send(ws, {"type": "lease", "seq": 1})["held"] is True
        time.sleep(0.1)  # from rest: 1 deg in 0.1 s is 10 deg/s, 100 deg/s^2
        ack = _send(ws, {"type": "target", "seq": 2, "theta_deg": [1.0, 0.0, 0.0]})
        assert ack == {"type": "ack", "seq": 2, "theta_deg": [1.0, 0.0, 0.0]}
        np.testing.assert_allclose(_joints(http), [1, 0, 0], atol=TOL["angles_deg"])
        time.sleep(0.1)
        ack = _send(ws, {"type": "target", "seq": 3, "rpy_deg": [0.0, 0.0, 0.0]})
        assert ack["type"] == "ack" and ack["seq"] == 3
        np.testing.assert_allclose(_joints(http), ack["theta_deg"], atol=TOL["angles_deg"])
        # The pushed state follows.
        _wait_for(lambda: _state(ws)["theta_deg"] == ack["theta_deg"])


def test_an_unsafe_target_is_refused_and_nothing_moves(
    server: BackgroundServer, http: httpx.Client
) -> None:
    with _open(server) as ws:
        time.sleep(0.05)
        answer = _send(ws, {"type": "target", "seq": 7, "theta_deg": STUDY_COLLISION_DEG})
        assert answer["type"] == "refused" and answer["seq"] == 7
        failed = {check["check"]: check["reason"] for check in answer["failed"]}
        assert "collision" in failed and "reachable" in failed
        assert "proximal_2-proximal_3" in failed["collision"]
        assert answer["verdict"]["safe"] is False
    assert _joints(http) == [0.0, 0.0, 0.0]


def test_a_too_fast_jump_is_refused_by_the_speed_check(
    server: BackgroundServer, http: httpx.Client
) -> None:
    with _open(server) as ws:
        assert _send(ws, {"type": "lease"})["held"] is True
        time.sleep(0.1)  # 30 deg in 0.1 s: 300 deg/s > 90 deg/s; the goal itself is safe
        answer = _send(ws, {"type": "target", "seq": 1, "theta_deg": [30.0, 30.0, 30.0]})
        assert answer["type"] == "refused", answer
        failed = {check["check"] for check in answer["failed"]}
        assert "speed" in failed and failed <= {"speed", "acceleration"}
        reasons = " ".join(check["reason"] for check in answer["failed"])
        assert "deg/s > 90.0 deg/s" in reasons
        # Refused for its speed alone: the exact distances are not computed.
        assert answer["verdict"]["min_distance_m"] is None
        assert answer["verdict"]["pairs"] == [] and answer["verdict"]["reachable"] is True
    assert _joints(http) == [0.0, 0.0, 0.0]
    check = http.post("/check", json={"theta_deg": [30, 30, 30]}).json()
    assert check["safe"] is True and check["min_distance_m"] > 0


MALFORMED = {
    "nan_as_text": '{"type": "target", "seq": 5, "theta_deg": [1, 2, NaN]}',
    "wrong_length": '{"type": "target", "seq": 5, "theta_deg": [1, 2]}',
    "unknown_key": '{"type": "target", "seq": 5, "theta_deg": [1, 2, 3], "speed": 1}',
    "both_forms": '{"type": "target", "seq": 5, "theta_deg": [1, 2, 3], "rpy_deg": [0, 0, 0]}',
    "string_number": '{"type": "target", "seq": 5, "theta_deg": ["1", 2, 3]}',
    "unknown_type": '{"type": "jump", "seq": 5}',
    "not_json": "theta = [1, 2, 3]",
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_messages_are_422_and_the_connection_stays(
    server: BackgroundServer, http: httpx.Client, case: str
) -> None:
    with _open(server) as ws:
        ws.send(MALFORMED[case])
        answer = _answer(ws)
        assert answer["type"] == "error" and answer["status"] == 422, answer
        if case != "not_json":
            assert answer["seq"] == 5
        assert _send(ws, {"type": "ping", "seq": 6}) == {"type": "pong", "seq": 6}
    assert _joints(http) == [0.0, 0.0, 0.0]


def test_binary_and_oversized_messages_are_answered(server: BackgroundServer) -> None:
    with _open(server) as ws:
        ws.send(b'{"type": "ping"}')
        assert _answer(ws)["status"] == 422
        ws.send(json.dumps({"type": "ping", "pad": "x" * 20_000}))
        answer = _answer(ws)
        assert answer["status"] == 413 and "16384 bytes" in answer["detail"]
        assert _send(ws, {"type": "ping", "seq": 1})["type"] == "pong"


def test_every_target_gets_exactly_one_answer(server: BackgroundServer, http: httpx.Client) -> None:
    targets: list[str] = []
    for seq in range(12):
        if seq % 3 == 0:
            body: dict[str, Any] = {"theta_deg": STUDY_COLLISION_DEG}
        elif seq % 3 == 1:
            body = {"theta_deg": [0.0, 0.0, 0.0]}  # where it is: safe, no motion
        else:
            body = {"theta_deg": [1.0, 2.0]}
        targets.append(json.dumps({"type": "target", "seq": seq, **body}))
    with _open(server, "?rate=200") as ws:
        for text in targets:  # a burst: nothing waits for an answer
            ws.send(text)
        answers: dict[int, list[str]] = {}
        while sum(len(kinds) for kinds in answers.values()) < len(targets):
            answer = _answer(ws)
            answers.setdefault(answer["seq"], []).append(answer["type"])
        # A holder busy being answered is not silent: the burst kept the lease.
        assert http.get("/lease").json()["held"] is True
        assert _send(ws, {"type": "ping", "seq": 99}) == {"type": "pong", "seq": 99}
    assert sorted(answers) == list(range(12))
    expected = {0: ["refused"], 1: ["ack"], 2: ["error"]}
    assert all(kinds == expected[seq % 3] for seq, kinds in answers.items()), answers


# ----------------------------------------------------------------------- the lease
def test_one_controlling_client_any_number_of_readers(
    server: BackgroundServer, http: httpx.Client
) -> None:
    with _open(server) as controller, _open(server) as other, _open(server) as reader:
        assert _send(controller, {"type": "lease", "seq": 1})["held"] is True
        assert http.get("/lease").json()["held"] is True
        conflict = _send(other, {"type": "target", "seq": 3, "theta_deg": [1, 0, 0]})
        assert conflict == {
            "type": "error",
            "status": 409,
            "seq": 3,
            "detail": "another client holds the lease",
        }
        assert _send(other, {"type": "lease", "seq": 4})["status"] == 409
        refused = http.put("/joints", json={"theta_deg": [1, 0, 0]})
        assert refused.status_code == 409 and "lease" in refused.json()["detail"]
        assert http.put("/orientation", json={"rpy_deg": [0, 0, 0]}).status_code == 409
        assert http.post("/check", json={"theta_deg": [1, 0, 0]}).status_code == 200
        _wait_for(lambda: _state(reader)["lease"] == {"held": True, "yours": False})
        _wait_for(lambda: _state(controller)["lease"] == {"held": True, "yours": True})
        assert _send(controller, {"type": "release", "seq": 2})["released"] is True
        assert http.get("/lease").json()["held"] is False
        assert _send(other, {"type": "lease", "seq": 5})["held"] is True
    assert _joints(http) == [0.0, 0.0, 0.0]


def test_a_quiet_controller_loses_the_lease_and_the_twin_stops(
    server: BackgroundServer, backend: KinematicBackend, http: httpx.Client
) -> None:
    stops = http.get("/state").json()["stops"]
    expired = http.get("/lease").json()["expired"]
    with _open(server) as ws:
        start = time.monotonic()  # before the server hears the last message
        assert _send(ws, {"type": "lease"})["held"] is True
        ended = _answer(ws)  # the controller stays quiet
        waited = time.monotonic() - start
        assert ended == {
            "type": "lease",
            "held": False,
            "reason": f"deadline: nothing received for {DEADLINE:g} s",
        }
        assert DEADLINE * 0.95 <= waited <= DEADLINE + 1.0, waited
        assert http.get("/state").json()["stops"] == stops + 1
        assert backend.last_stop_reason is not None and "deadline" in backend.last_stop_reason
        assert http.get("/lease").json() == {
            "held": False,
            "deadline_s": DEADLINE,
            "expired": expired + 1,
        }
        assert http.put("/joints", json={"theta_deg": [0, 0, 0]}).status_code == 200
        # The connection stays open, as a reader; it may take the lease again.
        assert _send(ws, {"type": "lease"})["held"] is True
        assert _send(ws, {"type": "release"})["released"] is True


def test_messages_within_the_deadline_keep_the_lease(
    server: BackgroundServer, http: httpx.Client
) -> None:
    with _open(server) as ws:
        assert _send(ws, {"type": "lease"})["held"] is True
        for _ in range(int(3 * DEADLINE / 0.1)):  # three deadlines, a ping every 0.1 s
            time.sleep(0.1)
            assert _send(ws, {"type": "ping"})["type"] == "pong"
        assert http.get("/lease").json()["held"] is True
        assert _send(ws, {"type": "release"})["released"] is True


def test_a_disconnect_frees_the_lease_and_stops_the_twin(
    server: BackgroundServer, backend: KinematicBackend, http: httpx.Client
) -> None:
    stops = backend.stops
    with _open(server) as ws:
        assert _send(ws, {"type": "lease"})["held"] is True
    _wait_for(lambda: not http.get("/lease").json()["held"], timeout=DEADLINE / 2 + 2.0)
    assert backend.stops == stops + 1
    assert backend.last_stop_reason == "the controlling client disconnected"


def test_the_stop_message(server: BackgroundServer, backend: KinematicBackend) -> None:
    stops = backend.stops
    with _open(server) as ws:
        assert _send(ws, {"type": "stop", "seq": 3}) == {"type": "stopped", "seq": 3}
    assert backend.stops == stops + 1


# ----------------------------------------------------------------------- the token
def test_the_stream_needs_the_token(token_server: BackgroundServer) -> None:
    url = f"{token_server.ws_url}/stream"
    close = _closed_with(url, additional_headers={"Authorization": "Bearer wrong"})
    assert close.code == 1008 and "token" in close.reason
    # Without the header, the first message must be the token.
    for first in ({"type": "ping"}, {"type": "auth", "token": "wrong"}, {"type": "auth"}):
        with connect(url, open_timeout=ANSWER_TIMEOUT) as ws:
            ws.send(json.dumps(first))
            with pytest.raises(ConnectionClosed) as closed:
                ws.recv(timeout=ANSWER_TIMEOUT)
            assert closed.value.rcvd is not None, first
            assert closed.value.rcvd.code == 1008 and "token" in closed.value.rcvd.reason
    headers = {"Authorization": f"Bearer {TOKEN}"}
    with _open(token_server, additional_headers=headers) as ws:
        assert _state(ws)["type"] == "state"
    with connect(url, open_timeout=ANSWER_TIMEOUT) as ws:  # as a browser would
        ws.send(json.dumps({"type": "auth", "token": TOKEN}))
        assert json.loads(ws.recv(timeout=ANSWER_TIMEOUT))["type"] == "hello"
        assert _state(ws)["type"] == "state"


def test_the_period_is_measured_between_accepted_targets(
    server: BackgroundServer, http: httpx.Client
) -> None:
    """At 20 Hz, steps of 1 deg (20 deg/s) pass once the stream has ramped up."""
    with _open(server) as ws:
        assert _send(ws, {"type": "lease"})["held"] is True
        answers = []
        theta = 0.0
        for seq in range(4):
            time.sleep(0.05)
            theta += 0.25 * (seq + 1)  # 0.25, 0.75, 1.5, 2.5 deg: a gentle ramp
            answers.append(_send(ws, {"type": "target", "seq": seq, "theta_deg": [theta, 0, 0]}))
        assert [answer["type"] for answer in answers] == ["ack"] * 4, answers
        assert math.isclose(_joints(http)[0], theta, abs_tol=TOL["angles_deg"])
        assert _send(ws, {"type": "release"})["released"] is True


# ----------------------------------------------------------------------- timed targets
#: A timed stream: goals 1 ms apart on the client's clock, ramping at 300 deg/s^2
#: (below the guard's 360) up to 30 deg/s, then cruising.
TIMED = {"period_s": 1e-3, "accel_deg_s2": 300.0, "speed_deg_s": 30.0}


def _timed_path(count: int) -> list[float]:
    """Input 1 [deg] at goals 1..count of the timed stream (from rest at goal 0)."""
    h, a, v = TIMED["period_s"], TIMED["accel_deg_s2"], TIMED["speed_deg_s"]
    ramp = v / a
    out = []
    for k in range(1, count + 1):
        t = k * h
        out.append(0.5 * a * t**2 if t <= ramp else 0.5 * a * ramp**2 + v * (t - ramp))
    return out


def _send_timed(
    ws: ClientConnection, seq: int, theta1: float, t: float, *, ahead: float = 0.005
) -> dict[str, Any]:
    """Send a goal timed ``t`` (client clock: time.monotonic) no more than ``ahead``
    seconds before its time: goals go out in bursts of about five, as through a
    jittery network."""
    delay = t - ahead - time.monotonic()
    if delay > 0:
        time.sleep(delay)
    return _send(ws, {"type": "target", "seq": seq, "theta_deg": [theta1, 0, 0], "t": t})


def test_timed_targets_are_checked_on_their_times_and_a_refusal_does_not_cascade(
    server: BackgroundServer, http: httpx.Client
) -> None:
    """Goals sent in bursts (up to 5 ms early) pass on their own times; one goal
    that jumps is refused, and the stream goes on from the last goal accepted."""
    path = _timed_path(160)
    jump = 120  # this goal jumps 1 deg ahead: 1,000 deg/s
    with _open(server) as ws:
        assert _send(ws, {"type": "lease"})["held"] is True
        t0 = time.monotonic() + 0.05
        kinds = {}
        for k, theta1 in enumerate(path, start=1):
            goal = theta1 + (1.0 if k == jump else 0.0)
            answer = _send_timed(ws, k, goal, t0 + k * TIMED["period_s"])
            kinds[k] = answer["type"]
            if k == jump:
                assert answer["type"] == "refused", answer
                assert {check["check"] for check in answer["failed"]} >= {"speed"}
        assert [k for k, kind in kinds.items() if kind != "ack"] == [jump], kinds
        assert math.isclose(_joints(http)[0], path[-1], abs_tol=TOL["angles_deg"])
        assert _send(ws, {"type": "release"})["released"] is True


def test_untimed_targets_go_on_after_a_refusal(
    server: BackgroundServer, http: httpx.Client
) -> None:
    """Untimed goals about 100 Hz (arrival times), ramping at about 100 deg/s^2 to
    20 deg/s; one jump is refused and the next goal, two intervals after the last
    accepted one, is judged over both (taken as one interval, its acceleration would
    be 0.2 deg / (0.02 s)^2 = 500 deg/s^2 > 360)."""
    steps = [min(0.01 * (k + 1), 0.2) for k in range(40)]  # [deg] per goal
    jump = 30
    with _open(server) as ws:
        assert _send(ws, {"type": "lease"})["held"] is True
        theta, kinds = 0.0, {}
        for k, step in enumerate(steps, start=1):
            time.sleep(0.01)
            theta += step
            goal = theta + (5.0 if k == jump else 0.0)
            kinds[k] = _send(ws, {"type": "target", "seq": k, "theta_deg": [goal, 0, 0]})["type"]
        assert [k for k, kind in kinds.items() if kind != "ack"] == [jump], kinds
        assert math.isclose(_joints(http)[0], theta, abs_tol=TOL["angles_deg"])
        assert _send(ws, {"type": "release"})["released"] is True


def test_goals_timed_ahead_of_the_clock_are_422_and_do_not_move(
    server: BackgroundServer, http: httpx.Client
) -> None:
    """Goals stamped 10 ms apart but sent back to back: once their times run more
    than the slack (50 ms) ahead of the server's clock, they are refused."""
    with _open(server) as ws:
        assert _send(ws, {"type": "lease"})["held"] is True
        time.sleep(0.05)
        t0 = time.monotonic()
        answers = []
        for k in range(1, 21):
            message = {
                "type": "target",
                "seq": k,
                "theta_deg": [1e-4 * k, 0, 0],
                "t": t0 + 0.01 * k,
            }
            answers.append(_send(ws, message))
            if answers[-1]["type"] != "ack":
                break
        last = answers[-1]
        assert last["type"] == "error" and last["status"] == 422, answers
        assert "ahead of the server's clock" in last["detail"]
        assert 5 <= len(answers) < 20
        acked = answers[-2]["theta_deg"][0]
        assert math.isclose(_joints(http)[0], acked, abs_tol=TOL["angles_deg"])
        # Times must increase.
        again = _send(ws, {"type": "target", "seq": 99, "theta_deg": [acked, 0, 0], "t": t0})
        assert again["type"] == "error" and again["status"] == 422
        assert "t must increase" in again["detail"]
        # Not a finite number: 422 from the body's validation.
        text = '{"type": "target", "seq": 100, "theta_deg": [0, 0, 0], "t": NaN}'
        ws.send(text)
        nan = _answer(ws)
        assert nan["status"] == 422 and nan["detail"][0]["loc"][-1] == "t", nan


# ----------------------------------------------------------------------- spm serve
def test_spm_serve_takes_a_deadline() -> None:
    environment = {key: value for key, value in os.environ.items() if key != "SPM_TOKEN"}
    bad = subprocess.run(
        [sys.executable, "-m", "spm_pin", "serve", "--deadline", "0"],
        capture_output=True,
        text=True,
        timeout=120,
        env=environment,
        check=False,
    )
    assert bad.returncode == 2 and "--deadline" in bad.stderr, bad.stderr
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    process = subprocess.Popen(
        [sys.executable, "-m", "spm_pin", "serve", "--port", str(port), "--deadline", "0.2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )
    try:
        end = time.monotonic() + 120
        while True:
            assert process.poll() is None and time.monotonic() < end, "spm serve did not start"
            try:
                ws = connect(f"ws://127.0.0.1:{port}/stream", open_timeout=ANSWER_TIMEOUT)
                break
            except OSError:
                time.sleep(0.1)
        with ws:
            hello = json.loads(ws.recv(timeout=ANSWER_TIMEOUT))
            assert hello["deadline_s"] == 0.2
            assert _send(ws, {"type": "lease"})["held"] is True
            ended = _answer(ws)
            assert ended["held"] is False and "0.2 s" in ended["reason"]
    finally:
        process.terminate()
        process.communicate(timeout=30)
    assert process.returncode == 0


# ----------------------------------------------------------------------- origins
def test_a_browser_page_of_another_site_cannot_open_the_stream(server: BackgroundServer) -> None:
    """Browsers send Origin on every WebSocket and CORS does not apply to them: the
    server refuses other sites itself (its own pages and programs without an Origin
    connect)."""
    from websockets.exceptions import InvalidStatus

    with pytest.raises(InvalidStatus) as refused:
        connect(
            f"{server.ws_url}/stream", origin="http://evil.example", open_timeout=ANSWER_TIMEOUT
        )
    assert refused.value.response.status_code == 403
    host = server.url.removeprefix("http://")
    with _open(server, origin=f"http://{host}") as ws:  # a page the server itself serves
        assert _send(ws, {"type": "ping", "seq": 1})["type"] == "pong"
    with _open(server) as ws:  # a program: no Origin header
        assert _send(ws, {"type": "ping", "seq": 2})["type"] == "pong"


def test_a_change_during_a_state_read_is_read_again() -> None:
    """StateCache: a goal accepted while a state read is under way is not lost (the
    next request reads again), and a fresh read is reused within its age."""
    import asyncio
    import threading

    from spm_pin.remote.stream import StateCache

    class HeldTwin(KinematicBackend):
        """The real kinematic twin whose second state read waits to be let go."""

        def __init__(self) -> None:
            super().__init__()
            self.reads = 0
            self.entered, self.release = threading.Event(), threading.Event()

        def state_quick(self) -> Any:
            return None  # read in a worker thread: the race is that read's

        def state(self) -> Any:
            self.reads += 1
            result = super().state()
            if self.reads == 2:  # read, then held before it is handed back
                self.entered.set()
                assert self.release.wait(10.0)
            return result

    twin = HeldTwin()
    cache = StateCache(twin)
    goal = np.radians([10.0, 5.0, 0.0])

    async def run() -> tuple[str, str, str]:
        first = await cache.latest(10.0)
        assert await cache.latest(10.0) == first and twin.reads == 1  # fresh: reused
        cache.invalidate()
        pending = asyncio.ensure_future(cache.latest(10.0))  # read 2, held
        assert await asyncio.to_thread(twin.entered.wait, 10.0)
        twin.move(goal)  # accepted while read 2 is under way (it saw the old joints)
        cache.invalidate()
        twin.release.set()
        second = await pending
        third = await cache.latest(10.0)  # read 3: the change is read
        return first, second, third

    first, second, third = asyncio.run(run())
    assert twin.reads == 3
    assert json.loads("{" + second)["theta_deg"] == [0.0, 0.0, 0.0]  # read before the move
    theta = json.loads("{" + third)["theta_deg"]
    np.testing.assert_allclose(theta, np.degrees(goal), rtol=0.0, atol=1e-9)
    assert json.loads("{" + first)["theta_deg"] == [0.0, 0.0, 0.0]
    twin.close()


def test_state_quick_is_the_state_or_none_and_never_waits(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``state_quick`` (read on the server's event loop) gives what ``state`` gives,
    field for field, where no exact distance is due; None where one is (the first read
    after an HTTP goal), and None at once while another thread holds the twin's lock
    (a goal's refusal report may hold it for milliseconds)."""
    import dataclasses
    import threading

    from spm_pin.collision import check_input
    from spm_pin.remote import kinematic

    def same(a: Any, b: Any) -> bool:
        return all(
            np.array_equal(getattr(a, f.name), getattr(b, f.name))
            for f in dataclasses.fields(a)
            if f.name != "time"
        )

    twin = KinematicBackend()
    goal = np.radians([4.0, 2.0, 1.0])
    twin.move(goal)  # an HTTP goal: its state is computed and kept
    kept = twin.state_quick()
    assert kept is not None and same(kept, twin.state())
    # Streamed goals within the distance interval: the last distance, no computation.
    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 0.0)
    path = np.radians([[4.5, 2.2, 1.1], [5.0, 2.4, 1.2]])
    twin.command(path[0])
    assert twin.state_quick() is None  # past the interval: the distance is due
    first = twin.state()  # exact
    assert first.min_distance == check_input(path[0], twin.robot).min_distance
    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 60.0)
    twin.command(path[1])
    quick = twin.state_quick()
    assert quick is not None and np.array_equal(quick.theta, path[1])
    assert quick.min_distance == first.min_distance and same(quick, twin.state())
    # Past the interval, without a child process: the distance is due.
    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 0.0)
    twin.command(path[0])
    assert twin.state_quick() is None
    exact = twin.state()
    assert exact.min_distance == check_input(path[0], twin.robot).min_distance
    # Another thread holds the twin's lock: None at once.
    twin._lock.acquire()
    try:
        result: list[Any] = []
        reader = threading.Thread(target=lambda: result.append(twin.state_quick()))
        start = time.monotonic()
        reader.start()
        reader.join(5.0)
        assert not reader.is_alive() and result == [None]
        assert time.monotonic() - start < 1.0
    finally:
        twin._lock.release()
    assert twin.state_quick() is not None  # kept again, lock free


def test_state_cache_reads_a_quick_twin_on_the_event_loop() -> None:
    """StateCache reads ``state_quick`` on the event loop's thread; where it gives
    None, ``state`` in a worker thread; the text is the state's either way."""
    import asyncio
    import threading

    from spm_pin.remote.models import state_json
    from spm_pin.remote.stream import StateCache

    class CountingTwin(KinematicBackend):
        def __init__(self) -> None:
            super().__init__()
            self.quick_ok = True
            self.threads: dict[str, list[str]] = {"quick": [], "state": []}

        def state_quick(self) -> Any:
            self.threads["quick"].append(threading.current_thread().name)
            return super().state_quick() if self.quick_ok else None

        def state(self) -> Any:
            self.threads["state"].append(threading.current_thread().name)
            return super().state()

    twin = CountingTwin()
    cache = StateCache(twin)

    async def run() -> tuple[str, str, str]:
        loop_thread = threading.current_thread().name
        first = await cache.latest(0.0)
        twin.quick_ok = False
        cache.invalidate()
        second = await cache.latest(0.0)
        return loop_thread, first, second

    loop_thread, first, second = asyncio.run(run())
    assert twin.threads["quick"] == [loop_thread, loop_thread]
    assert len(twin.threads["state"]) == 1 and twin.threads["state"][0] != loop_thread
    expected = json.loads(state_json(twin.state()))
    for text in (first, second):
        got = json.loads("{" + text)
        assert {k: v for k, v in got.items() if k != "time"} == {
            k: v for k, v in expected.items() if k != "time"
        }
    twin.close()
