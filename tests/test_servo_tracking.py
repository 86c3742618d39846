"""How the servos follow streamed goals (spm_pin.dynamics.track_goals).

Checked against independent truths: the statics (at rest the servo's PD offset
balances the holding torque Pinocchio computes), MuJoCo on the exported MJCF fed the
same zero-order-hold goals, and the servos' guard on every simulated state of a
planned motion.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.dynamics import ServoController, holding_torques, track_goals
from spm_pin.dynamics.servo import XM540_W150
from spm_pin.errors import InputError
from spm_pin.hardware.guard import SafetyGuard
from spm_pin.hardware.orientation import planned_goals
from spm_pin.planning import plan

MJCF = Path(__file__).resolve().parent.parent / "urdf" / "spm.xml"
PERIOD = 0.01
TOL = {
    "statics_deg": 0.01,  # the settled offset against holding torque / kp
    "mujoco_rad": 1e-4,  # our simulator against MuJoCo, same goals
}


def _goals() -> np.ndarray:
    path = plan(np.radians([71.0, 8.0, 67.0]), np.radians([33.0, -37.0, 8.0]))
    return planned_goals(
        path.theta, max_speed=math.radians(90.0), max_acceleration=math.radians(360.0),
        period=PERIOD,
    )  # fmt: skip


def test_a_planned_motion_is_tracked_and_stays_safe() -> None:
    goals = _goals()
    result = track_goals(goals, PERIOD, start=goals[0], settle=1.0)
    assert result.theta.shape == result.goal.shape == (len(result.time), 3)
    assert math.degrees(result.max_error) < 3.0  # the servos lag by a few degrees
    # Settled: the PD offset balances gravity (Pinocchio's holding torque).
    tau = holding_torques(None, result.theta[-1])
    np.testing.assert_allclose(
        np.degrees(result.goal[-1] - result.theta[-1]),
        np.degrees(tau / XM540_W150.kp),
        atol=TOL["statics_deg"],
    )
    guard = SafetyGuard(spm.build_robot())
    assert guard.check_path(result.theta).safe  # the real motion is safe too


def test_the_same_goals_in_mujoco() -> None:
    pytest.importorskip("mujoco")
    from spm_pin.dynamics import simulate_mujoco

    goals = _goals()[:40]
    ours = track_goals(goals, PERIOD, start=goals[0], settle=0.0)

    def controller(t: float, theta: np.ndarray, theta_dot: np.ndarray) -> np.ndarray:
        k = min(math.floor(t / PERIOD + 1e-9), len(goals) - 1)
        result: np.ndarray = ServoController(XM540_W150, goals[k])(t, theta, theta_dot)
        return result

    theirs = simulate_mujoco(
        MJCF, None, len(goals) * PERIOD, controller, state=goals[0], record_every=10
    )
    np.testing.assert_allclose(theirs.theta[1:], ours.theta, atol=TOL["mujoco_rad"])


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"goals": [[0.0, 0.0]]}, "goals"),
        ({"goals": [[0.0, np.nan, 0.0]]}, "goals"),
        ({"period": 0.0105}, "period"),
        ({"period": -1.0}, "period"),
        ({"settle": -1.0}, "settle"),
    ],
)
def test_bad_input(kwargs: dict[str, object], argument: str) -> None:
    arguments: dict[str, object] = {"goals": np.zeros((2, 3)), "period": PERIOD, **kwargs}
    with pytest.raises(InputError, match=argument):
        track_goals(**arguments)  # type: ignore[arg-type]
