"""The simulated twin (spm_pin.remote.DynamicBackend) behind a real server.

uvicorn serves the twin on a free loopback port; httpx and the ``websockets`` client
drive it as any program would. What the twin does is checked against independent
truths: the planned straight line (plan_linear) for the time a move takes, the
closed-loop statics (the servo's PD torque at rest equals the holding torque that
``spm.dynamics.holding_torques`` computes with Pinocchio), the guard's own path check
for a goal whose way is unsafe.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
httpx = pytest.importorskip("httpx")
pytest.importorskip("websockets")

from _remote_truth import SAFE_DEG, STUDY_COLLISION_DEG  # noqa: E402
from websockets.sync.client import connect  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.dynamics import holding_torques  # noqa: E402
from spm_pin.dynamics.servo import XM540_W150  # noqa: E402
from spm_pin.hardware.guard import SafetyGuard  # noqa: E402
from spm_pin.hardware.sync import plan_linear  # noqa: E402
from spm_pin.remote import BackgroundServer, DynamicBackend  # noqa: E402

#: Seconds to wait for an answer, and for the twin to settle after a move.
ANSWER_TIMEOUT = 30.0
SETTLE_TIMEOUT = 20.0
#: The streaming client's deadline in these tests [s]. The twin's simulation shares
#: the process (and the GIL) with the client, so a loaded machine can hold the client
#: back for a few tenths of a second between goals: 1 s keeps such a pause from
#: reading as a quiet client.
DEADLINE = 1.0
#: Two safe inputs whose straight line passes a collision (proximal_1-distal_2) [deg].
WAY_UNSAFE_START_DEG = [71.0, 8.0, 67.0]
WAY_UNSAFE_GOAL_DEG = [33.0, -37.0, 8.0]
#: Tolerances.
TOL = {
    "settled_deg": 0.5,  # the twin at rest is this close to its goal
    "statics_deg": 0.01,  # the PD offset at rest against holding torque / kp
    "timing_s": 0.05,  # a move takes at least the planned time minus this
}


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


@pytest.fixture(scope="module")
def twin(robot: spm.SPMRobot) -> Iterator[DynamicBackend]:
    with DynamicBackend(robot=robot) as running:
        yield running


@pytest.fixture(scope="module")
def server(twin: DynamicBackend) -> Iterator[BackgroundServer]:
    with BackgroundServer(twin, deadline=DEADLINE) as running:
        yield running


@pytest.fixture()
def http(server: BackgroundServer) -> Iterator[httpx.Client]:
    """An HTTP client; the twin starts at rest at home."""
    with httpx.Client(base_url=server.url, timeout=ANSWER_TIMEOUT) as session:
        _wait_for(lambda: not session.get("/lease").json()["held"])
        assert session.put("/joints", json={"theta_deg": [0, 0, 0]}).status_code == 200
        _settle(session)
        yield session


def _wait_for(condition: Any, timeout: float = ANSWER_TIMEOUT) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "condition not met in time"
        time.sleep(0.01)


def _settle(http: httpx.Client) -> dict[str, Any]:
    """Poll until the twin is at rest; its last state."""
    end = time.monotonic() + SETTLE_TIMEOUT
    while True:
        state: dict[str, Any] = http.get("/state").json()
        if not state["moving"]:
            return state
        assert time.monotonic() < end, f"the twin did not settle: {state}"
        time.sleep(0.02)


def _wait_until_still(http: httpx.Client) -> None:
    """Poll until the twin's input speeds are all under 1e-3 deg/s."""
    _wait_for(lambda: max(abs(x) for x in http.get("/state").json()["theta_dot_deg_s"]) < 1e-3)


def test_a_move_takes_the_time_of_the_planned_line_and_settles_on_the_goal(
    http: httpx.Client, twin: DynamicBackend
) -> None:
    limits = twin.guard.limits
    plan = plan_linear(
        np.zeros(3),
        np.radians(SAFE_DEG),
        max_speed=limits.max_speed,
        max_acceleration=limits.max_acceleration,
        period=twin.period,
    )
    planned = len(plan) * twin.period
    start = time.monotonic()
    answer = http.put("/joints", json={"theta_deg": SAFE_DEG})
    assert answer.status_code == 200, answer.text
    state = answer.json()
    assert state["backend"] == "dynamic" and state["moving"] is True
    np.testing.assert_allclose(state["goal_deg"], SAFE_DEG, atol=1e-9)
    speeds = []
    while True:
        state = http.get("/state").json()
        speeds.append(max(abs(x) for x in state["theta_dot_deg_s"]))
        if not state["moving"]:
            break
        assert time.monotonic() - start < SETTLE_TIMEOUT, state
        time.sleep(0.02)
    elapsed = time.monotonic() - start
    assert elapsed >= planned - TOL["timing_s"], (elapsed, planned)
    # It really moved in between, at no more than the guard's speed (plus the
    # servos' overshoot of a few percent).
    assert max(speeds) > 0.5 * math.degrees(limits.max_speed)
    assert max(speeds) < 1.2 * math.degrees(limits.max_speed)
    np.testing.assert_allclose(state["theta_deg"], SAFE_DEG, atol=TOL["settled_deg"])
    assert state["pairs"] == [] and state["reachable"] is True
    assert state["fault"] is None and state["torque"] is True


def test_at_rest_the_servo_torque_holds_the_robot_against_gravity(
    http: httpx.Client, twin: DynamicBackend
) -> None:
    """The PD loop's offset kp (goal - theta) equals Pinocchio's holding torque."""
    assert http.put("/joints", json={"theta_deg": SAFE_DEG}).status_code == 200
    _settle(http)
    _wait_until_still(http)
    state = http.get("/state").json()
    theta = np.radians(state["theta_deg"])
    tau = holding_torques(twin.simulator.dynamics, theta)
    offset = np.degrees(tau / XM540_W150.kp)
    np.testing.assert_allclose(
        np.subtract(state["goal_deg"], state["theta_deg"]), offset, atol=TOL["statics_deg"]
    )


def test_an_unsafe_goal_is_refused_and_nothing_moves(http: httpx.Client) -> None:
    # At rest first: a twin that counts as settled still creeps onto its goal
    # (hundredths of a degree for about a second), which is not a move.
    _wait_until_still(http)
    before = http.get("/state").json()
    answer = http.put("/joints", json={"theta_deg": STUDY_COLLISION_DEG})
    assert answer.status_code == 409
    failed = {check["check"] for check in answer.json()["failed"]}
    assert {"reachable", "collision"} <= failed
    time.sleep(0.2)
    after = http.get("/state").json()
    # The goal is unchanged (the twin only settles further on the one it had).
    assert after["goal_deg"] == before["goal_deg"] and after["moving"] is False
    np.testing.assert_allclose(after["theta_deg"], before["theta_deg"], atol=0.01)


def test_a_goal_whose_straight_way_collides_is_refused_by_the_path_check(
    robot: spm.SPMRobot,
) -> None:
    start, goal = np.radians(WAY_UNSAFE_START_DEG), np.radians(WAY_UNSAFE_GOAL_DEG)
    guard = SafetyGuard(robot)
    # The truth, from the guard alone: both ends are safe, the line between them not.
    assert guard.check(start).safe and guard.check(goal).safe
    assert not guard.check_path(goal[None], start=start).safe
    with (
        DynamicBackend(robot=robot, theta=start) as twin,
        BackgroundServer(twin) as server,
        httpx.Client(base_url=server.url, timeout=ANSWER_TIMEOUT) as http,
    ):
        answer = http.put("/joints", json={"theta_deg": WAY_UNSAFE_GOAL_DEG})
        assert answer.status_code == 409, answer.text
        body = answer.json()
        assert [check["check"] for check in body["failed"]] == ["path"]
        assert "proximal_1-distal_2" in body["failed"][0]["reason"]
        state = http.get("/state").json()
        np.testing.assert_allclose(state["goal_deg"], WAY_UNSAFE_START_DEG, atol=1e-9)
        # POST /check judges the goal alone: it is safe.
        assert http.post("/check", json={"theta_deg": WAY_UNSAFE_GOAL_DEG}).json()["safe"]


def test_a_stop_holds_the_twin_where_it_is(http: httpx.Client, twin: DynamicBackend) -> None:
    stops = twin.stops
    assert http.put("/joints", json={"theta_deg": SAFE_DEG}).status_code == 200
    time.sleep(0.4)  # under way: the move takes about 1.6 s
    stopped = http.post("/stop").json()
    assert twin.stops == stops + 1
    # The goal is where the twin was when stopped, short of the asked goal.
    np.testing.assert_allclose(stopped["goal_deg"], stopped["theta_deg"], atol=1e-9)
    assert abs(stopped["goal_deg"][2] - SAFE_DEG[2]) > 20.0
    state = _settle(http)
    np.testing.assert_allclose(state["theta_deg"], stopped["goal_deg"], atol=TOL["settled_deg"] * 4)


def test_a_streaming_client_that_goes_quiet_stops_the_twin(
    server: BackgroundServer, http: httpx.Client, twin: DynamicBackend
) -> None:
    stops = twin.stops
    with connect(f"{server.ws_url}/stream", open_timeout=ANSWER_TIMEOUT) as ws:
        assert json.loads(ws.recv(timeout=ANSWER_TIMEOUT))["type"] == "hello"
        ws.send(json.dumps({"type": "lease", "seq": 1}))
        # Gently accelerating goals (about 50 deg/s^2 at 20 ms apart): the guard's
        # speed and acceleration checks pass them.
        for k in range(1, 26):
            time.sleep(0.02)
            ws.send(json.dumps({"type": "target", "seq": k + 1, "theta_deg": [0.01 * k * k, 0, 0]}))
        answers: list[dict[str, Any]] = []
        while len(answers) < 26:  # the lease and every target: one answer each
            message = json.loads(ws.recv(timeout=ANSWER_TIMEOUT))
            if message["type"] != "state":
                answers.append(message)
        acked = [m["theta_deg"][0] for m in answers if m["type"] == "ack"]
        # The server times goals by their arrival: on a loaded machine a goal that
        # arrives early reads as a jump in acceleration and is refused (never lost).
        for answer in answers[1:]:
            if answer["type"] == "refused":
                assert {c["check"] for c in answer["failed"]} <= {"speed", "acceleration"}
        assert len(acked) >= 5, answers
        _wait_for(lambda: twin.stops == stops + 1)  # silent past the deadline
    assert twin.last_stop_reason is not None and "deadline" in twin.last_stop_reason
    state = _settle(http)
    # It moved with the goals, then held where it was when stopped.
    assert 0.5 * acked[-1] < state["theta_deg"][0] <= acked[-1] + 0.5, (state, acked)


def test_at_rest_the_exact_distance_is_kept_while_the_angles_only_round(
    robot: spm.SPMRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The exact smallest link distance (the costly part) is computed at most every
    ``distance_interval`` while a twin at rest still creeps onto its goal, and once
    settled (its angles move by rounding alone) kept: exact where it stands; a move to
    a new place computes it again."""
    from spm_pin import collision
    from spm_pin.remote import _motion

    exact: list[np.ndarray] = []
    original = collision.check_input

    def counting(theta: Any, *args: Any, **kwargs: Any) -> Any:
        if kwargs.get("distances", True):
            exact.append(np.array(theta, dtype=float))
        return original(theta, *args, **kwargs)

    monkeypatch.setattr(collision, "check_input", counting)
    with DynamicBackend(robot=robot) as twin:
        for goal_deg in (SAFE_DEG, [10.0, 20.0, -15.0]):
            twin.move(np.radians(goal_deg))
            _wait_for(lambda: not twin.state().moving, SETTLE_TIMEOUT)
            start, before = time.monotonic(), len(exact)
            while time.monotonic() - start < 0.5:  # still creeping onto the goal
                assert not twin.state().moving
                time.sleep(0.005)
            rate_limited = 0.5 / twin.distance_interval + 2
            assert len(exact) - before <= rate_limited
            time.sleep(2.0)  # settled: the angles move by rounding alone
            before = len(exact)
            states = []
            for _ in range(15):
                states.append(twin.state())
                time.sleep(0.02)
            assert len(exact) - before <= 1  # once at most, not at every read
            kept = exact[-1]
            for state in states:
                assert not state.moving
                assert np.max(np.abs(state.theta - kept)) <= _motion.REST_ANGLE
                assert state.min_distance == states[0].min_distance
            truth = original(kept, robot).min_distance
            assert states[-1].min_distance == truth  # the exact distance where it was
        assert not np.allclose(exact[0], exact[-1])  # the move computed it again
