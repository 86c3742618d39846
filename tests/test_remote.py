"""The HTTP API of the twin (spm_pin.remote) against a real server.

uvicorn serves the application in a background thread on a free loopback port and
httpx sends real HTTP requests (no test client, no mocks). What the server answers is
checked against the library run in this process: forward kinematics, the robot's
collision checks and distances, the safety guard. ``spm serve`` is started as a user
would, in a subprocess.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
httpx = pytest.importorskip("httpx")

import uvicorn  # noqa: E402
from _remote_truth import (  # noqa: E402
    SAFE_DEG,
    STUDY_COLLISION_DEG,
    STUDY_COLLISION_PAIRS,
    TOL,
)

import spm_pin as spm  # noqa: E402
from spm_pin.collision import LINK_PAIRS  # noqa: E402
from spm_pin.errors import InputError  # noqa: E402
from spm_pin.hardware.guard import SafetyGuard  # noqa: E402
from spm_pin.remote import (  # noqa: E402
    BackgroundServer,
    KinematicBackend,
    check_binding,
    create_app,
    is_loopback,
    load_token,
    serve,
)
from spm_pin.rotations import (  # noqa: E402
    matrix_from_quaternion,
    matrix_from_rpy,
    quaternion_from_matrix,
    rpy_from_matrix,
)

TOKEN = "test-token-0123456789abcdef"
STATE_KEYS = {
    "theta_deg",
    "R",
    "quaternion_wxyz",
    "rpy_deg",
    "reachable",
    "pairs",
    "min_distance_m",
    "dexterity",
    "assembly",
    "backend",
    "time",
}
#: Seconds for a subprocess server to answer, and for one request.
STARTUP_TIMEOUT = 90.0
REQUEST_TIMEOUT = 30.0


# --------------------------------------------------------------------------- fixtures
class _Thread:
    """uvicorn serving ``app`` in a thread, on a socket bound here to a free port."""

    def __init__(self, app: Any) -> None:
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.socket.bind(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self.socket.getsockname()[1]}"
        config = uvicorn.Config(app, log_level="warning")
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(
            target=self.server.run, kwargs={"sockets": [self.socket]}, daemon=True
        )

    def __enter__(self) -> _Thread:
        self.thread.start()
        deadline = time.monotonic() + STARTUP_TIMEOUT
        while not self.server.started:
            assert self.thread.is_alive() and time.monotonic() < deadline, "no server"
            time.sleep(0.01)
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(REQUEST_TIMEOUT)
        self.socket.close()


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    """The prototype, built in this process: the independent truth."""
    return spm.build_robot()


@pytest.fixture(scope="module")
def backend() -> KinematicBackend:
    return KinematicBackend()


@pytest.fixture(scope="module")
def url(backend: KinematicBackend) -> Iterator[str]:
    with _Thread(create_app(backend)) as running:
        yield running.url


@pytest.fixture(scope="module")
def token_url(backend: KinematicBackend) -> Iterator[str]:
    with _Thread(create_app(backend, token=TOKEN)) as running:
        yield running.url


@pytest.fixture()
def client(url: str) -> Iterator[httpx.Client]:
    with httpx.Client(base_url=url, timeout=REQUEST_TIMEOUT) as session:
        yield session
        session.put("/joints", json={"theta_deg": [0, 0, 0]})  # back home


def _no_nan(constant: str) -> Any:
    raise AssertionError(f"the server sent {constant}, which is not JSON")


def _json(response: Any) -> Any:
    """The body, refusing NaN and Infinity."""
    return json.loads(response.text, parse_constant=_no_nan)


def _theta_of(state: dict[str, Any]) -> np.ndarray:
    return np.radians(np.asarray(state["theta_deg"], dtype=float))


# ----------------------------------------------------------------------- state, joints
def test_state_at_home(client: httpx.Client) -> None:
    response = client.get("/state")
    assert response.status_code == 200
    state = _json(response)
    assert set(state) >= STATE_KEYS
    np.testing.assert_allclose(state["theta_deg"], [0, 0, 0], atol=TOL["angles_deg"])
    np.testing.assert_allclose(state["R"], np.eye(3), atol=TOL["same_numbers"])
    np.testing.assert_allclose(state["quaternion_wxyz"], [1, 0, 0, 0], atol=TOL["same_numbers"])
    np.testing.assert_allclose(state["rpy_deg"], [0, 0, 0], atol=1e-10)
    assert state["reachable"] is True
    assert state["pairs"] == []
    assert state["assembly"] == "+++/-"
    assert state["backend"] == "kinematic"
    assert 0 < state["min_distance_m"] < 0.002  # the nested drive tubes, 1 mm apart
    assert abs(state["time"] - time.time()) < 60


def test_safe_goal_moves(client: httpx.Client, robot: spm.SPMRobot) -> None:
    response = client.put("/joints", json={"theta_deg": SAFE_DEG})
    assert response.status_code == 200, response.text
    moved = _json(response)
    joints = _json(client.get("/joints"))
    state = _json(client.get("/state"))
    np.testing.assert_allclose(joints["theta_deg"], SAFE_DEG, atol=TOL["angles_deg"])
    np.testing.assert_allclose(state["theta_deg"], SAFE_DEG, atol=TOL["angles_deg"])
    fk = spm.forward_kinematics(np.radians(SAFE_DEG))
    jac = spm.jacobian(np.radians(SAFE_DEG))
    for answer in (moved, state):
        np.testing.assert_allclose(answer["R"], fk.R, atol=TOL["same_numbers"])
        np.testing.assert_allclose(
            answer["quaternion_wxyz"], quaternion_from_matrix(fk.R), atol=TOL["same_numbers"]
        )
        np.testing.assert_allclose(
            answer["rpy_deg"], np.degrees(rpy_from_matrix(fk.R)), atol=TOL["angles_deg"]
        )
        np.testing.assert_allclose(answer["dexterity"], jac.dexterity, atol=TOL["same_numbers"])
        assert answer["pairs"] == [list(p) for p in robot.collisions(np.radians(SAFE_DEG))]


def test_unsafe_goal_is_refused_and_nothing_moves(client: httpx.Client) -> None:
    client.put("/joints", json={"theta_deg": SAFE_DEG})
    before = _json(client.get("/state"))
    response = client.put("/joints", json={"theta_deg": STUDY_COLLISION_DEG})
    assert response.status_code == 409
    body = _json(response)
    failed = {check["check"]: check["reason"] for check in body["failed"]}
    assert "collision" in failed and "reachable" in failed
    for a, b in STUDY_COLLISION_PAIRS:
        assert f"{a}-{b}" in failed["collision"]
    assert body["verdict"]["safe"] is False
    assert "nothing moved" in body["detail"]
    after = _json(client.get("/state"))
    before.pop("time"), after.pop("time")
    assert after == before


def test_check_reports_the_study_collision(client: httpx.Client) -> None:
    before = _json(client.get("/joints"))
    response = client.post("/check", json={"theta_deg": STUDY_COLLISION_DEG})
    assert response.status_code == 200
    verdict = _json(response)
    assert verdict["safe"] is False
    assert {tuple(pair) for pair in verdict["pairs"]} == STUDY_COLLISION_PAIRS
    checks = {check["check"]: check for check in verdict["checks"]}
    assert checks["collision"]["passed"] is False
    assert checks["reachable"]["passed"] is False
    assert checks["joint_limits"]["passed"] is True
    assert verdict["reasons"] and verdict["min_distance_m"] < 0
    assert _json(client.get("/joints")) == before  # checking moves nothing


@pytest.mark.parametrize(
    "theta_deg",
    [SAFE_DEG, STUDY_COLLISION_DEG, [0, 0, 0], [0, 60, 120], [0, 70, 140], [10, 20, 30]],
)
def test_check_agrees_with_the_guard(
    client: httpx.Client, robot: spm.SPMRobot, theta_deg: list[float]
) -> None:
    verdict = _json(client.post("/check", json={"theta_deg": theta_deg}))
    truth = SafetyGuard(robot).check(np.radians(theta_deg))
    assert verdict["safe"] == truth.safe
    assert verdict["reachable"] == truth.reachable
    assert set(truth.reasons) <= set(verdict["reasons"])
    if truth.reachable:
        assert verdict["singularity_margin"] == pytest.approx(truth.singularity_margin, abs=1e-12)
    else:
        assert verdict["singularity_margin"] is None


def test_move_accepts_exactly_the_goals_the_full_check_calls_safe(robot: spm.SPMRobot) -> None:
    """A move decides with the cheap collision test (no distances); it must accept
    exactly the goals that the guard plus the full `spm collide` report call safe."""
    from spm_pin.collision import check_input
    from spm_pin.errors import UnsafeCommandError

    twin = KinematicBackend(robot=robot)
    guard = SafetyGuard(robot)
    margin = guard.limits.collision_margin
    rng = np.random.default_rng(7)
    goals = np.radians(SAFE_DEG) + rng.uniform(-0.6, 0.6, size=(30, 3))
    goals = np.vstack([goals, np.radians([STUDY_COLLISION_DEG, [0.0, 60.0, 120.0]])])
    accepted = []
    for goal in goals:
        truth = guard.check(goal).safe and not check_input(goal, robot, margin=margin).collision
        assert twin.check(goal).safe == truth
        try:
            twin.move(goal)
        except UnsafeCommandError:
            moved = False
        else:
            moved = True
        assert moved == truth, np.degrees(goal)
        accepted.append(moved)
    assert any(accepted) and not all(accepted)  # both kinds of goal were tried


def test_check_an_orientation(client: httpx.Client) -> None:
    for body in ({"rpy_deg": [10, -5, 30]}, {"quaternion_wxyz": [0.99, 0.05, 0.02, 0.1]}):
        verdict = _json(client.post("/check", json=body))
        assert verdict["safe"] is True, verdict
        assert all(check["passed"] for check in verdict["checks"])


# ------------------------------------------------------------------------ orientation
@pytest.mark.parametrize(
    "body",
    [{"rpy_deg": [10.0, -5.0, 30.0]}, {"quaternion_wxyz": [0.95, 0.1, -0.05, 0.28]}],
    ids=["rpy", "quaternion"],
)
def test_orientation_round_trip(client: httpx.Client, body: dict[str, list[float]]) -> None:
    response = client.put("/orientation", json=body)
    assert response.status_code == 200, response.text
    state = _json(response)
    if "rpy_deg" in body:
        asked = matrix_from_rpy(np.radians(body["rpy_deg"]))
    else:
        asked = matrix_from_quaternion(body["quaternion_wxyz"])
    reached = spm.forward_kinematics(_theta_of(state)).R
    np.testing.assert_allclose(reached, asked, atol=TOL["orientation"])
    np.testing.assert_allclose(state["R"], asked, atol=TOL["orientation"])
    ik = spm.inverse_kinematics(asked)
    np.testing.assert_allclose(_theta_of(state), ik.theta, atol=TOL["orientation"])


def test_unreachable_orientation_is_422(client: httpx.Client) -> None:
    before = _json(client.get("/joints"))
    response = client.put("/orientation", json={"rpy_deg": [80, 5, 30]})
    assert response.status_code == 422
    body = _json(response)
    assert body["error"] == "UnreachableError" and "cannot close" in body["detail"]
    assert _json(client.get("/joints")) == before


# ------------------------------------------------------------------------- collisions
def test_collisions_match_the_robot_in_process(client: httpx.Client, robot: spm.SPMRobot) -> None:
    theta_deg = [-30.0, 30.0, 0.0]
    assert client.put("/joints", json={"theta_deg": theta_deg}).status_code == 200
    answer = _json(client.get("/collisions"))
    theta = np.radians(theta_deg)
    colliding = set(robot.collisions(theta))
    distances = robot.distances(theta)
    assert [tuple(entry["pair"]) for entry in answer["pairs"]] == list(LINK_PAIRS)
    for entry in answer["pairs"]:
        pair = tuple(entry["pair"])
        assert entry["colliding"] == (pair in colliding)
        assert entry["distance_m"] == pytest.approx(distances[pair], abs=TOL["same_numbers"])
    assert answer["collision"] == bool(colliding)
    np.testing.assert_allclose(answer["theta_deg"], theta_deg, atol=TOL["angles_deg"])


def test_stop_answers_the_state(client: httpx.Client) -> None:
    client.put("/joints", json={"theta_deg": SAFE_DEG})
    response = client.post("/stop")
    assert response.status_code == 200
    state = _json(response)
    assert state["moving"] is False
    np.testing.assert_allclose(state["theta_deg"], SAFE_DEG, atol=TOL["angles_deg"])


def test_concurrent_requests_stay_consistent(url: str) -> None:
    goals = [[0, 0, 0], SAFE_DEG, [10, 20, 30], [-20, 5, 15]]
    answers: list[dict[str, Any]] = []
    errors: list[BaseException] = []

    def work(goal: list[float]) -> None:
        try:
            with httpx.Client(base_url=url, timeout=REQUEST_TIMEOUT) as session:
                for _ in range(3):
                    answers.append(_json(session.put("/joints", json={"theta_deg": goal})))
                    answers.append(_json(session.get("/state")))
        except BaseException as exc:  # reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(goal,)) for goal in goals]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(STARTUP_TIMEOUT)
    assert not errors
    assert len(answers) == 24
    for state in answers:  # every state is whole: its R belongs to its theta
        fk = spm.forward_kinematics(_theta_of(state))
        np.testing.assert_allclose(state["R"], fk.R, atol=TOL["same_numbers"])
    httpx.put(f"{url}/joints", json={"theta_deg": [0, 0, 0]}, timeout=REQUEST_TIMEOUT)


# --------------------------------------------------------------------- malformed bodies
MALFORMED = {
    "nan": ("/joints", '{"theta_deg": [NaN, 0, 0]}', "theta_deg"),
    "infinity": ("/joints", '{"theta_deg": [0, Infinity, 0]}', "theta_deg"),
    "minus_infinity": ("/check", '{"theta_deg": [0, 0, -Infinity]}', "theta_deg"),
    "huge_number": ("/joints", '{"theta_deg": [1e999, 0, 0]}', "theta_deg"),
    "two_values": ("/joints", '{"theta_deg": [1, 2]}', "theta_deg"),
    "four_values": ("/joints", '{"theta_deg": [1, 2, 3, 4]}', "theta_deg"),
    "string": ("/joints", '{"theta_deg": ["1", 2, 3]}', "theta_deg"),
    "boolean": ("/joints", '{"theta_deg": [true, 2, 3]}', "theta_deg"),
    "not_a_list": ("/joints", '{"theta_deg": 5}', "theta_deg"),
    "unknown_key": ("/joints", '{"theta_deg": [1, 2, 3], "speed": 1}', "speed"),
    "missing_key": ("/joints", "{}", "theta_deg"),
    "both_forms": (
        "/orientation",
        '{"rpy_deg": [1, 2, 3], "quaternion_wxyz": [1, 0, 0, 0]}',
        "body",
    ),
    "neither_form": ("/orientation", "{}", "body"),
    "rpy_too_short": ("/orientation", '{"rpy_deg": [1, 2]}', "rpy_deg"),
    "check_two_forms": ("/check", '{"theta_deg": [1, 2, 3], "rpy_deg": [0, 0, 0]}', "body"),
    "not_json": ("/joints", "theta_deg = 1, 2, 3", "body"),
    "empty": ("/joints", "", "body"),
    "json_list": ("/joints", "[1, 2, 3]", "body"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_bodies_are_422(client: httpx.Client, case: str) -> None:
    path, text, field = MALFORMED[case]
    before = _json(client.get("/joints"))
    method = "POST" if path == "/check" else "PUT"
    response = client.request(
        method, path, content=text.encode(), headers={"content-type": "application/json"}
    )
    assert response.status_code == 422, response.text
    body = _json(response)
    assert any(field in error["loc"] for error in body["detail"]), body
    assert all(error["msg"] for error in body["detail"])
    assert _json(client.get("/joints")) == before


def test_library_errors_are_422(client: httpx.Client) -> None:
    response = client.put("/orientation", json={"quaternion_wxyz": [0, 0, 0, 0]})
    assert response.status_code == 422
    assert _json(response) == {"detail": "quaternion must be non-zero", "error": "InputError"}
    response = client.put("/joints", json={"theta_deg": [1e300, 0, 0]})
    assert response.status_code == 422
    assert _json(response)["error"] == "InputError"


def test_oversized_bodies_are_413(client: httpx.Client) -> None:
    big = b'{"theta_deg": [1, 2, 3]' + b" " * 20_000 + b"}"
    headers = {"content-type": "application/json"}
    response = client.put("/joints", content=big, headers=headers)
    assert response.status_code == 413
    assert "exceeds 16384 bytes" in _json(response)["detail"]

    def chunks() -> Iterator[bytes]:  # no Content-Length: counted as it arrives
        yield b'{"theta_deg": [1, 2, 3]'
        for _ in range(40):
            yield b" " * 1000
        yield b"}"

    with httpx.Client(base_url=str(client.base_url), timeout=REQUEST_TIMEOUT) as session:
        response = session.put("/joints", content=chunks(), headers=headers)
    assert response.status_code == 413
    just_fits = b'{"theta_deg": [1, 2, 3]' + b" " * 16_000 + b"}"
    assert client.put("/joints", content=just_fits, headers=headers).status_code == 200


# ------------------------------------------------------------------------ description
def test_openapi_and_docs(client: httpx.Client) -> None:
    paths = _json(client.get("/openapi.json"))["paths"]
    for path in ("/state", "/joints", "/orientation", "/collisions", "/check", "/stop"):
        assert path in paths
    assert {"get", "put"} <= set(paths["/joints"])
    docs = client.get("/docs")
    assert docs.status_code == 200 and "swagger" in docs.text.lower()
    index = _json(client.get("/"))
    assert index["backend"] == "kinematic" and index["design"] == "prototype"


# ------------------------------------------------------------------------------- auth
RESOURCES = [
    ("GET", "/", None),
    ("GET", "/state", None),
    ("GET", "/joints", None),
    ("PUT", "/joints", {"theta_deg": [0, 0, 0]}),
    ("PUT", "/orientation", {"rpy_deg": [0, 0, 0]}),
    ("GET", "/collisions", None),
    ("POST", "/check", {"theta_deg": [0, 0, 0]}),
    ("POST", "/stop", None),
]


@pytest.mark.parametrize(("method", "path", "body"), RESOURCES)
def test_every_resource_needs_the_token(
    token_url: str, method: str, path: str, body: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    import spm_pin.remote.app as app_module

    compared: list[tuple[bytes, bytes]] = []
    real_compare = app_module.secrets.compare_digest

    def spy(a: bytes, b: bytes) -> bool:
        compared.append((a, b))
        return real_compare(a, b)

    monkeypatch.setattr(app_module.secrets, "compare_digest", spy)
    with httpx.Client(base_url=token_url, timeout=REQUEST_TIMEOUT) as session:
        for headers in ({}, {"Authorization": "Bearer wrong"}, {"Authorization": TOKEN}):
            response = session.request(method, path, json=body, headers=headers)
            assert response.status_code == 401, (headers, response.text)
            assert response.headers["www-authenticate"] == "Bearer"
        good = {"Authorization": f"Bearer {TOKEN}"}
        assert session.request(method, path, json=body, headers=good).status_code == 200
        # A malformed body without the token: 401 before anything reads it.
        if body is not None:
            bad = session.request(method, path, content=b"{", headers={})
            assert bad.status_code == 401
    assert (b"wrong", TOKEN.encode()) in compared  # the constant-time comparison decided
    assert (TOKEN.encode(), TOKEN.encode()) in compared


def test_docs_stay_open_with_a_token(token_url: str) -> None:
    assert httpx.get(f"{token_url}/docs", timeout=REQUEST_TIMEOUT).status_code == 200
    spec = httpx.get(f"{token_url}/openapi.json", timeout=REQUEST_TIMEOUT).json()
    assert "HTTPBearer" in spec["components"]["securitySchemes"]


def test_non_loopback_needs_a_token() -> None:
    for host in ("127.0.0.1", "localhost", "::1", "127.0.0.2"):
        assert is_loopback(host)
        check_binding(host, 8750, None)
    for host in ("0.0.0.0", "::", "192.168.1.20", "example.org"):
        assert not is_loopback(host)
        with pytest.raises(InputError, match="without a token"):
            check_binding(host, 8750, None)
        check_binding(host, 8750, TOKEN)
    # Refused before anything is built or bound.
    with pytest.raises(InputError, match="SPM_TOKEN"):
        serve(host="0.0.0.0", port=8750)
    with pytest.raises(InputError, match="without a token"):
        BackgroundServer(host="0.0.0.0")
    with pytest.raises(InputError, match="port"):
        check_binding("127.0.0.1", 70000, None)


def test_load_token(tmp_path: Path) -> None:
    path = tmp_path / "token"
    path.write_text(TOKEN + "\n")
    assert load_token(path, environ={}) == TOKEN
    assert load_token(None, environ={"SPM_TOKEN": " abc "}) == "abc"
    assert load_token(path, environ={"SPM_TOKEN": "other"}) == TOKEN  # the file first
    assert load_token(None, environ={}) is None
    path.write_text("\n")
    with pytest.raises(InputError, match="empty"):
        load_token(path, environ={})
    with pytest.raises(InputError, match="printable ASCII"):
        load_token(None, environ={"SPM_TOKEN": "two words"})
    with pytest.raises(InputError, match="empty"):
        create_app(KinematicBackend.__new__(KinematicBackend), token="")


# -------------------------------------------------------------------------------- CLI
def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _environment() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("SPM_TOKEN", None)
    return env


@contextlib.contextmanager
def _spm_serve(*args: str) -> Iterator[tuple[str, subprocess.Popen[str]]]:
    port = _free_port()
    process = subprocess.Popen(
        [sys.executable, "-m", "spm_pin", "serve", "--port", str(port), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_environment(),
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + STARTUP_TIMEOUT
        while True:
            assert process.poll() is None, process.communicate(timeout=REQUEST_TIMEOUT)
            assert time.monotonic() < deadline, "spm serve did not answer"
            try:
                httpx.get(f"{url}/state", timeout=1.0)
                break
            except httpx.TransportError:
                time.sleep(0.1)
        yield url, process
    finally:
        process.terminate()
        try:
            process.communicate(timeout=REQUEST_TIMEOUT)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()


def test_spm_serve_as_a_newcomer_starts_it() -> None:
    with _spm_serve() as (url, process):
        with httpx.Client(base_url=url, timeout=REQUEST_TIMEOUT) as session:
            state = _json(session.get("/state"))
            assert state["backend"] == "kinematic"
            moved = session.put("/joints", json={"theta_deg": SAFE_DEG})
            assert moved.status_code == 200
            np.testing.assert_allclose(
                _json(session.get("/joints"))["theta_deg"], SAFE_DEG, atol=TOL["angles_deg"]
            )
            refused = session.put("/joints", json={"theta_deg": STUDY_COLLISION_DEG})
            assert refused.status_code == 409
            assert "links collide" in _json(refused)["detail"]
        process.terminate()
        _, err = process.communicate(timeout=REQUEST_TIMEOUT)
    assert process.returncode == 0, err
    assert "kinematic twin of design 'prototype'" in err


def test_spm_serve_sim_dynamic_moves_in_time() -> None:
    with _spm_serve("--sim", "dynamic") as (url, process):
        with httpx.Client(base_url=url, timeout=REQUEST_TIMEOUT) as session:
            state = _json(session.put("/joints", json={"theta_deg": [10.0, 0.0, 0.0]}))
            assert state["backend"] == "dynamic" and state["moving"] is True
            assert state["goal_deg"] == [10.0, 0.0, 0.0]
            deadline = time.monotonic() + STARTUP_TIMEOUT
            while _json(session.get("/state"))["moving"]:
                assert time.monotonic() < deadline
                time.sleep(0.02)
            np.testing.assert_allclose(
                _json(session.get("/joints"))["theta_deg"], [10, 0, 0], atol=0.5
            )
        process.terminate()
        _, err = process.communicate(timeout=REQUEST_TIMEOUT)
    assert process.returncode == 0, err
    assert "dynamic twin of design 'prototype'" in err


def test_spm_serve_refuses_other_hosts_without_a_token() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "spm_pin", "serve", "--host", "0.0.0.0", "--port", "8750"],
        capture_output=True,
        text=True,
        timeout=STARTUP_TIMEOUT,
        env=_environment(),
        check=False,
    )
    assert result.returncode == 2
    assert result.stderr.startswith("spm: error: refusing to serve on 0.0.0.0")
    assert "--token-file" in result.stderr and "SPM_TOKEN" in result.stderr


def test_spm_serve_without_the_extra_names_it() -> None:
    code = (
        "import sys; sys.modules['fastapi'] = None\n"
        "from spm_pin.cli import main\n"
        "sys.exit(main(['serve']))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=STARTUP_TIMEOUT,
        env=_environment(),
        check=False,
    )
    assert result.returncode == 2
    assert 'pip install "spm-pin[remote]"' in result.stderr


def test_importing_spm_pin_loads_no_web_framework() -> None:
    code = (
        "import sys, spm_pin, spm_pin.cli\n"
        "spm_pin.cli.build_parser()\n"
        "loaded = [m for m in sys.modules if m.split('.')[0] in "
        "('fastapi', 'uvicorn', 'pydantic', 'starlette', 'httpx', 'spm_pin.remote')]\n"
        "assert not loaded and 'spm_pin.remote' not in sys.modules, loaded\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=STARTUP_TIMEOUT
    )
    assert result.returncode == 0, result.stderr


def test_json_has_no_nan(client: httpx.Client) -> None:
    verdict = _json(client.post("/check", json={"theta_deg": STUDY_COLLISION_DEG}))
    assert verdict["dexterity"] is None and verdict["singularity_margin"] is None
    assert not any(
        isinstance(v, float) and not math.isfinite(v) for v in verdict.values() if v is not None
    )


def test_a_child_process_computes_the_distances_of_a_stream(
    robot: spm.SPMRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With distance_process, a stream's exact distances come from a child process
    (equal to check_input at the goal it was asked for); a read never waits for it.
    Closed (or gone), the twin computes them in process again."""
    from spm_pin.collision import check_input
    from spm_pin.remote import kinematic

    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 0.0)  # ask at every read
    # A spin about the axis with a small wobble of the gaps (safe all along).
    path = np.radians([[k, k + 2.0 * math.sin(k / 20), k] for k in range(1, 400)])
    with KinematicBackend(robot=robot, distance_process=True) as twin:
        worker = twin._worker
        assert worker is not None
        home = twin.state().min_distance
        assert home == check_input(np.zeros(3), robot).min_distance
        end = time.monotonic() + 60.0
        k = 0
        while worker.answers < 2:
            assert time.monotonic() < end and worker.alive, "the child did not answer"
            twin.command(path[k % len(path)])
            twin.state()
            k += 1
            time.sleep(0.005)
        answer = worker.last
        assert answer is not None
        _, theta, distance = answer
        assert distance == check_input(theta, robot).min_distance
        assert any(np.array_equal(theta, goal) for goal in path)
        process = worker._process
        if hasattr(os, "getpriority"):  # background work: the lowest priority
            assert os.getpriority(os.PRIO_PROCESS, process.pid) == 19
    assert not process.is_alive() and twin._worker is None
    # In process from now on: exact at the goal.
    twin.command(path[0])
    assert twin.state().min_distance == check_input(path[0], robot).min_distance


def test_a_child_process_that_dies_leaves_the_distances_in_process(
    robot: spm.SPMRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    from spm_pin.collision import check_input
    from spm_pin.remote import kinematic

    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 0.0)
    with KinematicBackend(robot=robot, distance_process=True) as twin:
        worker = twin._worker
        assert worker is not None
        worker._process.kill()
        worker._process.join(10)
        goal = np.radians([3.0, 1.0, -1.0])
        twin.command(goal)
        assert twin.state().min_distance == check_input(goal, robot).min_distance


def test_a_child_process_that_cannot_start_leaves_the_distances_in_process(
    robot: spm.SPMRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    from spm_pin.collision import check_input
    from spm_pin.remote import kinematic

    def refuse(design: object) -> None:
        raise OSError("no processes here")

    monkeypatch.setattr(kinematic, "DistanceWorker", refuse)
    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 0.0)
    with KinematicBackend(robot=robot, distance_process=True) as twin:
        assert twin.distance_process is False and twin._worker is None
        goal = np.radians([3.0, 1.0, -1.0])
        twin.command(goal)
        assert twin.state().min_distance == check_input(goal, robot).min_distance


def test_streamed_goals_recompute_the_distance_at_most_every_interval(
    robot: spm.SPMRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """While goals stream in, the exact distance is reused for DISTANCE_INTERVAL
    seconds (reads stay cheap); after the interval, or after move(), it is exact."""
    from spm_pin.collision import check_input
    from spm_pin.remote import kinematic

    twin = KinematicBackend(robot=robot)
    path = np.radians([[1.0, 0.5, -0.2], [6.0, 3.0, -1.2], [12.0, 6.0, -2.4]])
    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 60.0)  # well within it
    twin.command(path[0])
    first = twin.state().min_distance
    assert first == check_input(path[0], robot).min_distance
    twin.command(path[1])
    assert twin.state().min_distance == first  # within the interval: the last one
    monkeypatch.setattr(kinematic, "DISTANCE_INTERVAL", 0.0)  # past it
    twin.command(path[2])
    assert twin.state().min_distance == check_input(path[2], robot).min_distance
    twin.command(path[1])
    moved = twin.move(path[0])  # an HTTP goal: exact at once
    assert moved.min_distance == check_input(path[0], robot).min_distance


def test_state_after_goals_is_exact(robot: spm.SPMRobot) -> None:
    """The state read after goals (streamed without reading it back, or moved to) has
    the exact smallest distance that the full collision report computes, though the
    twin computes it lazily and with a cap; it is kept until the next goal."""
    from spm_pin.collision import check_input

    twin = KinematicBackend(robot=robot)
    path = np.radians([[1.0, 0.5, -0.2], [2.0, 1.0, -0.4], [10.0, -5.0, 20.0]])
    for goal in path[:2]:
        twin.command(goal)
    first = twin.state()
    assert first.min_distance == check_input(path[1], robot).min_distance
    assert twin.state().min_distance == first.min_distance  # kept, not recomputed
    moved = twin.move(path[2])
    report = check_input(path[2], robot)
    assert moved.min_distance == report.min_distance
    assert moved.pairs == report.pairs
    np.testing.assert_allclose(twin.state().theta, path[2], atol=TOL["same_numbers"])
    assert twin.state().min_distance == report.min_distance


def test_states_at_accepted_goals_equal_the_full_computation(robot: spm.SPMRobot) -> None:
    """Between exact distances a streamed goal's state comes from the guard's safe
    verdict and the single-input kinematics; every value equals, bit for bit, the
    full computation (batch kinematics and Jacobian, the collision report)."""
    from spm_pin.remote import backend

    twin = KinematicBackend(robot=robot)
    rng = np.random.default_rng(7)
    accepted = 0
    for theta in np.radians(rng.uniform(-60.0, 60.0, size=(40, 3))):
        if not twin.guard.check(theta).safe:
            assert twin._accepted_state(theta, 0.01) is None  # refused: the full path
            continue
        accepted += 1
        fast = twin._accepted_state(theta, 0.01)
        assert fast is not None
        full = backend.GuardedTwin._compute_state(twin, theta, None)
        assert fast.R is not None and full.R is not None
        assert np.array_equal(fast.R, full.R)
        assert (fast.reachable, fast.pairs, fast.assembly) == (
            full.reachable,
            full.pairs,
            full.assembly,
        )
        assert fast.dexterity == full.dexterity
        assert fast.singularity_margin == full.singularity_margin
    assert accepted >= 10
    unchecked = np.radians([3.0, 1.0, 2.0])
    assert twin._accepted_state(unchecked, 0.01) is None  # never checked: the full path


def test_command_quick_takes_exactly_the_goals_command_takes(robot: spm.SPMRobot) -> None:
    """``command_quick`` (the event loop's path for streamed goals) accepts what
    ``command`` accepts and, refused by a static check, moves nothing and raises
    nothing (``command`` then gives the refusal's report); refused for its timing
    alone, it raises the same report ``command`` gives, at once."""
    from spm_pin.remote import GoalRefusedError

    quick, full = KinematicBackend(robot=robot), KinematicBackend(robot=robot)
    goals = np.radians([[2.0, 1.0, 0.5], list(STUDY_COLLISION_DEG), [4.0, 2.0, 1.0]])
    for goal in goals:
        before = quick.joints()
        taken = quick.command_quick(goal)
        try:
            full.command(goal)
            accepted = True
        except GoalRefusedError as exc:
            accepted = False
            assert not exc.report.safe and exc.report.reasons
        assert taken == accepted
        assert np.array_equal(quick.joints(), goal if taken else before)
        assert np.array_equal(quick.joints(), full.joints())
    # Rate checks too: a jump far beyond the speed limit within 1 ms.
    jump = {"previous": goals[2], "period": 1e-3}
    with pytest.raises(GoalRefusedError) as refused:
        quick.command_quick(goals[2] + 0.5, **jump)
    assert np.array_equal(quick.joints(), goals[2])
    with pytest.raises(GoalRefusedError) as expected:
        full.command(goals[2] + 0.5, **jump)
    got, want = refused.value.report, expected.value.report
    assert np.array_equal(got.theta, want.theta)
    for field in ("safe", "reasons", "checks", "pairs", "assembly", "min_distance"):
        assert getattr(got, field) == getattr(want, field), field
    assert [check.name for check in refused.value.report.failed] == ["speed"]
    from spm_pin.collision import check_input

    assert got.assembly == check_input(goals[2] + 0.5, robot).mode  # without its distances
