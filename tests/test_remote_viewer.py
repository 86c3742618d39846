"""The meshcat scene that follows a twin (spm_pin.remote.TwinViewer, spm serve --viewer).

The viewer draws with its own robot model; what it shows is compared with the closed
configuration that a robot built in this process computes for the twin's angles.
"""

from __future__ import annotations

import re
import subprocess
import sys
import time
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("meshcat")
httpx = pytest.importorskip("httpx")

from _remote_truth import SAFE_DEG  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.errors import InputError  # noqa: E402
from spm_pin.remote import KinematicBackend, TwinViewer  # noqa: E402

TIMEOUT = 60.0
#: The configuration drawn against the one computed here [rad].
Q_TOL = 1e-9


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


def _wait_for(condition: Any, timeout: float = TIMEOUT) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "condition not met in time"
        time.sleep(0.02)


def test_show_draws_each_new_pose_once(robot: spm.SPMRobot) -> None:
    twin = KinematicBackend(robot=robot)
    viewer = TwinViewer(twin)
    assert viewer.visualizer.robot is not robot  # a model of its own
    assert viewer.show() is True
    assert viewer.show() is False  # nothing moved: nothing drawn
    twin.move(np.radians(SAFE_DEG))
    assert viewer.show() is True and viewer.shown == 2
    expected = robot.configuration(np.radians(SAFE_DEG))
    np.testing.assert_allclose(viewer.visualizer.q, expected, atol=Q_TOL)
    assert viewer.visualizer.colliding_links == frozenset()


def test_the_running_viewer_follows_the_twin(robot: spm.SPMRobot) -> None:
    twin = KinematicBackend(robot=robot)
    with TwinViewer(twin, rate=50.0) as viewer:
        assert viewer.visualizer.running
        goal = np.radians([10.0, -5.0, 20.0])
        twin.move(goal)
        expected = robot.configuration(goal)
        _wait_for(lambda: np.allclose(viewer.visualizer.q, expected, atol=Q_TOL))
    assert not viewer.visualizer.running


@pytest.mark.parametrize("rate", [0, -1.0, float("nan"), float("inf"), True, "fast"])
def test_a_bad_rate_is_refused(rate: Any) -> None:
    with pytest.raises(InputError, match="rate"):
        TwinViewer(KinematicBackend(), rate=rate)


def test_spm_serve_viewer_prints_the_page_of_the_live_scene() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "spm_pin", "serve", "--port", "0", "--viewer"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stderr is not None
        process.stderr.readline()  # the twin's line
        line = process.stderr.readline()
        found = re.search(r"the viewer follows the twin at (\S+)", line)
        assert found, line
        page = httpx.get(found.group(1), timeout=TIMEOUT)
        assert page.status_code == 200 and "<html" in page.text.lower()
    finally:
        process.terminate()
        process.wait(timeout=TIMEOUT)
    assert process.returncode == 0
