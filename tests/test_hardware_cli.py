"""``spm servo``: the emulator in the foreground, status, move and follow against it,
and bad input as one-line errors."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("dynamixel_sdk")

import dynamixel_sdk as sdk
from _hardware_data import IDS, fast_config

from spm_pin.cli import main
from spm_pin.hardware import EmulatedBus

pytestmark = pytest.mark.hardware
pytest_plugins = ["_hardware"]

#: Bounded waits of this file [s].
START_TIMEOUT = 30.0
STOP_TIMEOUT = 10.0


def test_emulate_prints_the_device_and_stops_on_ctrl_c() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "spm_pin", "servo", "emulate", "--ids", "4", "5"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
    )
    try:
        assert process.stdout is not None
        ready, _, _ = select.select([process.stdout], [], [], START_TIMEOUT)
        assert ready, "the emulator printed nothing"
        first = process.stdout.readline()
        device = first.split()[-1]
        # The factory default rate unless --baud asks otherwise.
        assert first.startswith("emulating XM540-W150 servos 4 5 at 57600 bit/s")
        assert device.startswith("/dev/") and Path(device).exists()
        port = sdk.PortHandler(device)
        assert port.openPort()  # at the SDK's default, 1 Mbit/s: the servos hear noise
        try:
            handler = sdk.PacketHandler(2.0)
            assert handler.ping(port, 5)[1] == sdk.COMM_RX_TIMEOUT
            assert port.setBaudRate(57_600)
            assert handler.ping(port, 5)[:2] == (1130, sdk.COMM_SUCCESS)
            assert handler.ping(port, 1)[1] == sdk.COMM_RX_TIMEOUT
        finally:
            port.closePort()
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=STOP_TIMEOUT)
        assert process.returncode == 0, err
        assert "stopped after" in out and "Traceback" not in err
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate(timeout=STOP_TIMEOUT)


def test_emulate_stops_on_sigterm() -> None:
    bus = EmulatedBus((1,)).start()
    process = bus._process
    assert process is not None
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=STOP_TIMEOUT) == 0
    bus.stop()
    assert not bus.running


def test_status_move_follow(
    bus: EmulatedBus, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = fast_config(bus.port).save(tmp_path / "servos.toml")
    assert main(["servo", "status", "--port", bus.port, "--json"]) == 0
    status = json.loads(capsys.readouterr().out)
    assert [s["id"] for s in status["servos"]] == list(IDS)
    assert status["servos"][0]["model"] == 1130 and status["servos"][0]["torque"] is False
    assert status["theta_deg"] == [0.0, 0.0, 0.0] and status["safe"] is True
    assert status["servos"][1]["operating_mode"] == "position"  # status changes nothing

    code = main(["servo", "move", "20", "-10", "5", "--config", str(config), "--json"])
    moved = json.loads(capsys.readouterr().out)
    assert code == 0 and moved["reached"] is True
    assert moved["final"]["theta_deg"] == pytest.approx([20, -10, 5], abs=0.5)
    assert [bus.item(i, "Torque Enable") for i in IDS] == [0, 0, 0]  # off at the end

    writes = len(bus.goal_writes())
    argv = ["servo", "move", "0", "80", "0", "--config", str(config)]
    assert main([*argv, "--straight"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("spm: error: path refused at sample") and "links collide" in err
    assert err.count("\n") == 1
    assert len(bus.goal_writes()) == writes + 3  # only start()'s hold of the present
    assert main(argv) == 2  # planned: the goal itself is unsafe
    err = capsys.readouterr().err
    assert "is unsafe" in err and "nearest safe input" in err and err.count("\n") == 1
    assert len(bus.goal_writes()) == writes + 6  # again only start()'s hold

    assert main(["servo", "follow", "--config", str(config), "--duration", "0.2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("theta_deg") and "rpy_deg" in lines[0]
    assert lines[-1].startswith("followed ")
    assert main(["servo", "follow", "--config", str(config), "--duration", "0.1", "--json"]) == 0
    followed = json.loads(capsys.readouterr().out)
    assert followed["samples"] >= 3
    assert followed["last"]["theta_deg"] == pytest.approx([20, -10, 5], abs=0.5)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["servo"], "spm servo needs a subcommand"),
        (["servo", "status", "--port", "/dev/no-such-port"], "cannot open servo port"),
        (["servo", "emulate", "--ids", "1", "1"], "--ids must be distinct"),
        (["servo", "emulate", "--ids", "300"], "servo ids lie in 0..252"),
        (["servo", "move", "1", "2"], "give three input angles T1 T2 T3 [deg], got 2"),
        (["servo", "move"], "give the goal once"),
        (["servo", "move", "1", "2", "3", "--rpy", "0", "0", "0"], "give the goal once"),
        (["servo", "move", "1", "2", "3", "--turns", "1"], "--turns applies"),
        (["servo", "follow", "--duration", "-1"], "must be a positive number"),
        (["servo", "status", "--config", "/no/such.toml"], "cannot read servo configuration"),
    ],
)
def test_bad_input_is_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("spm: error: ") and message in err and err.count("\n") == 1
