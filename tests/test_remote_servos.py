"""The servo twin (spm_pin.remote.ServoBackend) behind a real server, on the emulated bus.

The emulator runs in its own process on a real pseudo-terminal and the unmodified
dynamixel-sdk talks to it; uvicorn serves the twin on a free loopback port and httpx
and the ``websockets`` client drive it. The truths are independent of the twin: the
emulator's own log of every goal that reached a servo (each one checked again by a
guard on a robot model of its own), its control table (torque enable), and the
joints' pulse conversion.
"""

from __future__ import annotations

import json
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

from _hardware_data import BAUD, IDS, LATENCY_MS, fast_config  # noqa: E402
from _remote_truth import SAFE_DEG, STUDY_COLLISION_DEG  # noqa: E402
from websockets.sync.client import connect  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.hardware import EmulatedBus, ServoBus  # noqa: E402
from spm_pin.hardware.guard import SafetyGuard  # noqa: E402
from spm_pin.hardware.joints import JointMap  # noqa: E402
from spm_pin.remote import BackgroundServer, ServoBackend  # noqa: E402

pytest_plugins = ["_hardware"]

ANSWER_TIMEOUT = 30.0
SETTLE_TIMEOUT = 20.0
#: The streaming client's deadline in these tests [s].
DEADLINE = 0.3
#: One encoder pulse [deg]: where the servos settle against the goal.
PULSE_DEG = 360.0 / 4096.0


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


@pytest.fixture()
def served(bus: EmulatedBus, robot: spm.SPMRobot) -> Iterator[tuple[ServoBackend, str]]:
    """The servo twin on the fresh emulated bus, served on a free loopback port."""
    config = fast_config(bus.port)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS) as servos,
        ServoBackend(servos, config, robot=robot) as twin,
        BackgroundServer(twin, deadline=DEADLINE) as server,
    ):
        yield twin, server.url


def _wait_for(condition: Any, timeout: float = ANSWER_TIMEOUT) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "condition not met in time"
        time.sleep(0.01)


def _settle(http: httpx.Client) -> dict[str, Any]:
    end = time.monotonic() + SETTLE_TIMEOUT
    while True:
        state: dict[str, Any] = http.get("/state").json()
        if not state["moving"]:
            return state
        assert time.monotonic() < end, f"the servos did not settle: {state}"
        time.sleep(0.02)


def _written_goals(bus: EmulatedBus, twin: ServoBackend) -> np.ndarray:
    """Every goal the servos received, as theta [rad], (n, 3)."""
    writes = bus.goal_writes()
    joints = JointMap(twin.config.joints, coaxial=True)
    latest = dict.fromkeys(IDS, 2048)
    rows = []
    for write in writes:  # a sync write reaches the three servos one after the other
        latest[write.servo_id] = write.pulses
        if write.servo_id == IDS[-1]:
            rows.append(joints.to_theta([latest[i] for i in IDS]))
    return np.array(rows).reshape(-1, 3)


def test_a_goal_moves_the_servos_and_every_goal_sent_is_safe(
    served: tuple[ServoBackend, str], bus: EmulatedBus, robot: spm.SPMRobot
) -> None:
    twin, url = served
    with httpx.Client(base_url=url, timeout=ANSWER_TIMEOUT) as http:
        state = http.get("/state").json()
        assert state["backend"] == "servos" and state["torque"] is True
        answer = http.put("/joints", json={"theta_deg": SAFE_DEG})
        assert answer.status_code == 200, answer.text
        assert answer.json()["goal_deg"] == pytest.approx(SAFE_DEG, abs=1e-9)
        state = _settle(http)
    np.testing.assert_allclose(state["theta_deg"], SAFE_DEG, atol=2 * PULSE_DEG)
    # The servos hold the pulses of the goal.
    held = [bus.item(i, "Goal Position") for i in IDS]
    assert held == list(
        JointMap(twin.config.joints, coaxial=True).to_pulses(np.radians(SAFE_DEG)).values()
    )
    # Every goal that reached the servos is safe for a guard of its own.
    goals = _written_goals(bus, twin)
    assert len(goals) > 10  # a path, not a jump
    guard = SafetyGuard(spm.build_robot(), twin.config.safety)
    assert all(guard.check(goal).safe for goal in goals)
    steps = np.abs(np.diff(goals, axis=0)).max(axis=1) / twin.period
    assert steps.max() <= twin.config.safety.max_speed * 1.05


def test_an_unsafe_goal_never_reaches_a_servo(
    served: tuple[ServoBackend, str], bus: EmulatedBus
) -> None:
    _, url = served
    before = len(bus.goal_writes())
    with httpx.Client(base_url=url, timeout=ANSWER_TIMEOUT) as http:
        answer = http.put("/joints", json={"theta_deg": STUDY_COLLISION_DEG})
        assert answer.status_code == 409
        assert {"reachable", "collision"} <= {c["check"] for c in answer.json()["failed"]}
        time.sleep(0.3)
        assert http.get("/state").json()["moving"] is False
    assert len(bus.goal_writes()) == before


def test_a_stop_turns_torque_off_and_the_next_goal_turns_it_on(
    served: tuple[ServoBackend, str], bus: EmulatedBus
) -> None:
    twin, url = served
    with httpx.Client(base_url=url, timeout=ANSWER_TIMEOUT) as http:
        assert http.put("/joints", json={"theta_deg": [30.0, 0.0, 0.0]}).status_code == 200
        time.sleep(0.1)
        assert http.post("/stop").status_code == 200
        _wait_for(lambda: [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0])
        _wait_for(lambda: http.get("/state").json()["torque"] is False)
        stopped = http.get("/state").json()
        assert stopped["theta_deg"][0] < 29.0  # stopped on the way
        assert twin.last_stop_reason == "POST /stop"
        # A new goal: torque comes back (holding where the servos stand), then moves.
        assert http.put("/joints", json={"theta_deg": [5.0, 0.0, 0.0]}).status_code == 200
        state = _settle(http)
    assert [bus.item(i, "Torque Enable") for i in IDS] == [1, 1, 1]
    np.testing.assert_allclose(state["theta_deg"], [5.0, 0.0, 0.0], atol=2 * PULSE_DEG)
    assert any("torque on, holding" in event for event in twin.events)


def test_a_streaming_client_that_goes_quiet_turns_torque_off(
    served: tuple[ServoBackend, str], bus: EmulatedBus
) -> None:
    twin, url = served
    ws_url = "ws" + url[len("http") :] + "/stream"
    with connect(ws_url, open_timeout=ANSWER_TIMEOUT) as ws:
        assert json.loads(ws.recv(timeout=ANSWER_TIMEOUT))["type"] == "hello"
        ws.send(json.dumps({"type": "lease", "seq": 1}))
        time.sleep(0.1)
        ws.send(json.dumps({"type": "target", "seq": 2, "theta_deg": [0.5, 0.0, 0.0]}))
        answers = []
        while len(answers) < 2:
            message = json.loads(ws.recv(timeout=ANSWER_TIMEOUT))
            if message["type"] != "state":
                answers.append(message)
        assert answers[1]["type"] == "ack", answers
        _wait_for(lambda: twin.stops == 1)  # silent past the deadline
        _wait_for(lambda: [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0])
    assert twin.last_stop_reason is not None and "deadline" in twin.last_stop_reason


def test_a_servo_that_stops_answering_ends_in_a_fault_with_torque_off(
    bus: EmulatedBus, robot: spm.SPMRobot
) -> None:
    config = fast_config(bus.port).replace(max_failures=3)
    with (
        ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS, retries=1) as servos,
        ServoBackend(servos, config, robot=robot) as twin,
        BackgroundServer(twin) as server,
        httpx.Client(base_url=server.url, timeout=ANSWER_TIMEOUT) as http,
    ):
        bus.unplug(2)
        # The fault is reported, then torque goes off (the same cycle of the loop).
        _wait_for(lambda: http.get("/state").json()["torque"] is False)
        state = http.get("/state").json()
        assert "HardwareError" in state["fault"] and state["torque"] is False
        assert [bus.item(i, "Torque Enable") for i in (1, 3)] == [0, 0]
        before = len(bus.goal_writes())
        refused = http.put("/joints", json={"theta_deg": [1.0, 0.0, 0.0]})
        assert refused.status_code == 409 and "fault" in refused.json()["detail"]
        assert len(bus.goal_writes()) == before
        bus.plug(2)


def test_spm_serve_device_serves_the_servos(bus: EmulatedBus, tmp_path: Any) -> None:
    config_file = fast_config(bus.port).save(tmp_path / "servos.toml")
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "spm_pin",
            "serve",
            "--port",
            "0",
            "--device",
            bus.port,
            "--config",
            str(config_file),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = process.stderr.readline() if process.stderr else ""
        assert f"the servos twin of design 'prototype' on {bus.port}" in line, line
        _wait_for(lambda: [bus.item(i, "Torque Enable") for i in IDS] == [1, 1, 1])
    finally:
        process.terminate()
        _, err = process.communicate(timeout=ANSWER_TIMEOUT)
    assert process.returncode == 0, err
    assert [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0]  # off on exit
