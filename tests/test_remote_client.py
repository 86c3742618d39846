"""The Python client of ``spm serve`` (spm_pin.remote.Client) against a real server.

uvicorn serves the twin in a background thread on a free loopback port
(:class:`~spm_pin.remote.BackgroundServer`); the client's answers are compared with
the server's own HTTP answers (httpx, sent by hand) and with the library run in this
process (forward kinematics, the robot's collision pairs). No mocks.
"""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
httpx = pytest.importorskip("httpx")
pytest.importorskip("websockets")

from _remote_truth import (  # noqa: E402
    SAFE_DEG,
    STUDY_COLLISION_DEG,
    STUDY_COLLISION_PAIRS,
    TOL,
)

import spm_pin as spm  # noqa: E402
from spm_pin.errors import InputError, SPMError, UnreachableError, UnsafeCommandError  # noqa: E402
from spm_pin.remote import (  # noqa: E402
    AsyncClient,
    AuthError,
    BackgroundServer,
    Client,
    KinematicBackend,
    LeaseHeldError,
    RemoteError,
    RemoteRefusedError,
)
from spm_pin.rotations import matrix_from_quaternion, matrix_from_rpy  # noqa: E402

TOKEN = "client-token-0123456789abcdef"
#: The streaming client's deadline in these tests [s].
DEADLINE = 5.0  # long enough for a loaded machine: no test waits for it to pass


# --------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    """The prototype, built in this process: the independent truth."""
    return spm.build_robot()


@pytest.fixture(scope="module")
def server() -> Iterator[BackgroundServer]:
    with BackgroundServer(KinematicBackend(), deadline=DEADLINE) as running:
        yield running


@pytest.fixture()
def client(server: BackgroundServer) -> Iterator[Client]:
    with Client(server.url, timeout=30) as made:
        made.set_joints([0, 0, 0])
        yield made


@pytest.fixture()
def raw(server: BackgroundServer) -> Iterator[Any]:
    """Plain httpx: the server's own answers."""
    with httpx.Client(base_url=server.url, timeout=30) as made:
        yield made


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _same(answer: dict[str, Any], truth: dict[str, Any]) -> None:
    """The same state but for the server's clock."""
    assert {k: v for k, v in answer.items() if k != "time"} == {
        k: v for k, v in truth.items() if k != "time"
    }


# -------------------------------------------------------------------------------- HTTP
def test_reads_match_the_servers_answers(client: Client, raw: Any) -> None:
    client.set_joints(SAFE_DEG)
    _same(client.state(), raw.get("/state").json())
    joints = client.joints()
    assert isinstance(joints, np.ndarray) and joints.shape == (3,)
    np.testing.assert_allclose(joints, raw.get("/joints").json()["theta_deg"], atol=0)
    assert client.collisions() == raw.get("/collisions").json()
    assert (
        client.lease()
        == raw.get("/lease").json()
        == {
            "held": False,
            "deadline_s": DEADLINE,
            "expired": 0,
        }
    )


def test_set_joints_moves_the_twin(client: Client, robot: spm.SPMRobot) -> None:
    state = client.set_joints(np.array(SAFE_DEG))
    np.testing.assert_allclose(client.joints(), SAFE_DEG, atol=TOL["angles_deg"])
    fk = spm.forward_kinematics(np.radians(SAFE_DEG))
    np.testing.assert_allclose(state["R"], fk.R, atol=TOL["same_numbers"])
    assert state["pairs"] == [list(p) for p in robot.collisions(np.radians(SAFE_DEG))] == []


@pytest.mark.parametrize(
    "form",
    [{"rpy_deg": (10.0, -5.0, 30.0)}, {"quaternion_wxyz": np.array([0.98, 0.1, -0.05, 0.15])}],
    ids=["rpy", "quaternion"],
)
def test_set_orientation_reaches_it(client: Client, form: dict[str, Any]) -> None:
    state = client.set_orientation(**form)
    if "rpy_deg" in form:
        asked = matrix_from_rpy(np.radians(form["rpy_deg"]))
    else:
        asked = matrix_from_quaternion(form["quaternion_wxyz"])
    reached = spm.forward_kinematics(np.radians(client.joints())).R
    np.testing.assert_allclose(reached, asked, atol=TOL["orientation"])
    np.testing.assert_allclose(state["R"], asked, atol=TOL["orientation"])


def test_unreachable_orientation(client: Client) -> None:
    with pytest.raises(UnreachableError, match="PUT /orientation"):
        client.set_orientation(rpy_deg=[80, 5, 30])
    np.testing.assert_allclose(client.joints(), [0, 0, 0], atol=TOL["angles_deg"])


def test_check_reports_the_study_collision(client: Client, raw: Any) -> None:
    verdict = client.check(theta_deg=STUDY_COLLISION_DEG)
    assert verdict == raw.post("/check", json={"theta_deg": STUDY_COLLISION_DEG}).json()
    assert verdict["safe"] is False
    assert {tuple(p) for p in verdict["pairs"]} == STUDY_COLLISION_PAIRS
    failed = {c["check"] for c in verdict["checks"] if c["passed"] is False}
    assert "collision" in failed
    assert client.check(theta_deg=SAFE_DEG)["safe"] is True
    assert client.check(rpy_deg=[10, -5, 30])["safe"] is True
    np.testing.assert_allclose(client.joints(), [0, 0, 0], atol=0)  # nothing moved


def test_refused_goal_raises_and_nothing_moves(client: Client) -> None:
    client.set_joints(SAFE_DEG)
    with pytest.raises(RemoteRefusedError) as caught:
        client.set_joints(STUDY_COLLISION_DEG)
    error = caught.value
    assert isinstance(error, UnsafeCommandError)
    assert "collision" in error.checks and "collision" in str(error)
    assert len(error.reasons) == len(error.failed) == len(error.checks)
    assert error.verdict is not None and error.verdict["safe"] is False
    np.testing.assert_allclose(error.goal, np.radians(STUDY_COLLISION_DEG), atol=1e-12)
    np.testing.assert_allclose(client.joints(), SAFE_DEG, atol=TOL["angles_deg"])


def test_stop_counts(client: Client) -> None:
    before = client.state()["stops"]
    assert client.stop()["stops"] == before + 1


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda c: c.set_joints([1.0, float("nan"), 0.0]), "theta_deg"),
        (lambda c: c.set_joints([1.0, 2.0]), "theta_deg"),
        (lambda c: c.set_joints("1 2 3"), "theta_deg"),
        (lambda c: c.set_joints([1e9, 0, 0]), "theta_deg"),
        (lambda c: c.set_orientation(rpy_deg=[0, 0, float("inf")]), "rpy_deg"),
        (lambda c: c.set_orientation(), "goal"),
        (lambda c: c.set_orientation(rpy_deg=[0, 0, 0], quaternion_wxyz=[1, 0, 0, 0]), "goal"),
        (lambda c: c.set_orientation(quaternion_wxyz=[0, 0, 0, 0]), "quaternion_wxyz"),
        (lambda c: c.check(theta_deg=[1, 2, 3, 4]), "theta_deg"),
        (lambda c: c.check(), "goal"),
    ],
)
def test_bad_input_is_refused_before_sending(client: Client, call: Any, argument: str) -> None:
    sent: list[Any] = []
    client.http.event_hooks["request"].append(sent.append)
    with pytest.raises(InputError) as caught:
        call(client)
    assert caught.value.argument == argument
    assert sent == []
    client.joints()
    assert len(sent) == 1  # the hook counts


def test_token() -> None:
    with BackgroundServer(token=TOKEN) as guarded:
        with Client(guarded.url, timeout=30) as anonymous, pytest.raises(AuthError, match="token"):
            anonymous.state()
        with Client(guarded.url, token="wrong-token", timeout=30) as wrong:
            with pytest.raises(AuthError) as caught:
                wrong.joints()
            assert caught.value.status == 401 and isinstance(caught.value, SPMError)
        with Client(guarded.url, token=TOKEN, timeout=30) as good:
            assert good.state()["theta_deg"] == [0.0, 0.0, 0.0]
            with good.stream(rate=20) as stream:
                assert stream.ping()["type"] == "pong"


def test_dead_url_names_it() -> None:
    url = f"http://127.0.0.1:{_free_port()}"
    start = time.monotonic()
    with Client(url, timeout=2) as dead, pytest.raises(RemoteError, match=url) as caught:
        dead.state()
    assert time.monotonic() - start < 5
    assert caught.value.url == url and caught.value.status is None
    with pytest.raises(RemoteError, match=r"127\.0\.0\.1"):
        dead.stream().open()


def test_bad_arguments_of_the_client() -> None:
    with pytest.raises(InputError, match="url"):
        Client("127.0.0.1:8750")
    with pytest.raises(InputError, match="timeout"):
        Client(timeout=0)
    with pytest.raises(InputError, match="token"):
        Client(token="")
    with pytest.raises(InputError, match="rate"):
        Client().stream(rate=5000)


# ------------------------------------------------------------------------------- async
def test_async_client_gives_the_same_answers(client: Client, server: BackgroundServer) -> None:
    async def run() -> dict[str, Any]:
        async with AsyncClient(server.url, timeout=30) as aclient:
            moved = await aclient.set_joints(SAFE_DEG)
            found = {
                "moved": moved,
                "state": await aclient.state(),
                "joints": await aclient.joints(),
                "collisions": await aclient.collisions(),
                "check": await aclient.check(theta_deg=STUDY_COLLISION_DEG),
                "lease": await aclient.lease(),
                "oriented": await aclient.set_orientation(rpy_deg=[10, -5, 30]),
            }
            with pytest.raises(RemoteRefusedError) as caught:
                await aclient.set_joints(STUDY_COLLISION_DEG)
            found["refused"] = caught.value.checks
            with pytest.raises(InputError):
                await aclient.set_joints([1, 2])
            async with aclient.stream(rate=20) as stream:
                found["pong"] = await stream.ping()
                async for state in stream.states():
                    found["pushed"] = state
                    break
            return found

    found = asyncio.run(run())
    _same(found["state"], found["moved"])
    np.testing.assert_allclose(found["joints"], SAFE_DEG, atol=TOL["angles_deg"])
    assert found["check"] == client.check(theta_deg=STUDY_COLLISION_DEG)
    assert found["lease"]["held"] is False
    np.testing.assert_allclose(
        found["oriented"]["R"], matrix_from_rpy(np.radians([10, -5, 30])), atol=TOL["orientation"]
    )
    assert "collision" in found["refused"]
    assert found["pong"]["type"] == "pong"
    assert found["pushed"]["type"] == "state"
    np.testing.assert_allclose(found["pushed"]["R"], client.state()["R"], atol=0)


# --------------------------------------------------------------------------- streaming
def test_stream_states_arrive_in_order(client: Client) -> None:
    with client.stream(rate=50) as stream:
        assert stream.hello["rate_hz"] == 50
        seqs = []
        for state in stream.states():
            seqs.append(state["seq"])
            if len(seqs) == 5:
                break
        assert seqs == sorted(seqs) and len(set(seqs)) == 5
        assert stream.latest is not None and stream.latest["seq"] == seqs[-1]


def test_stream_targets_lease_and_refusal(client: Client) -> None:
    with client.stream(rate=50) as stream:
        assert stream.take_lease()["held"] is True
        assert client.lease()["held"] is True
        with pytest.raises(LeaseHeldError):
            client.set_joints([1, 0, 0])  # HTTP writes wait while the stream controls
        with client.stream(rate=20) as other, pytest.raises(LeaseHeldError):
            other.take_lease()
        theta = 0.0
        for seq in range(8):  # a gentle ramp, well inside the rate limits
            time.sleep(0.05)
            theta += 0.1 * (seq + 1)
            ack = stream.send_target(theta_deg=[theta, 0, 0], seq=100 + seq)
            assert ack["type"] == "ack" and ack["seq"] == 100 + seq
        np.testing.assert_allclose(client.joints(), [theta, 0, 0], atol=TOL["angles_deg"])
        refused = stream.send_target(theta_deg=STUDY_COLLISION_DEG)
        assert refused["type"] == "refused"
        assert "collision" in {check["check"] for check in refused["failed"]}
        np.testing.assert_allclose(client.joints(), [theta, 0, 0], atol=TOL["angles_deg"])
        with pytest.raises(InputError):
            stream.send_target(theta_deg=[1, float("nan"), 0])
        assert stream.stop()["type"] == "stopped"
        released = stream.release()
        assert released["held"] is False and released["released"] is True
        assert client.lease()["held"] is False
    client.set_joints([0, 0, 0])  # HTTP writes work again
