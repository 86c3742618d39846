"""The state's JSON text (spm_pin.remote.models.state_json) is the model's, byte for byte.

``WS /stream`` pushes ``state_json(state)`` at up to 1 kHz; ``GET /state`` answers the
model :class:`~spm_pin.remote.models.StateResponse`. Both must say the same, and the
same as before the fast path: each is compared, text for text, with the numpy
conversions of the rotation (``quaternion_from_matrix``, ``rpy_from_matrix``,
``np.degrees``) written into the model and dumped by pydantic, on seeded random
states (random rotations hitting every branch of the quaternion, unreachable
inputs, NaN and infinite distances, colliding pairs, the dynamic twin's speeds and
goal, faults with quotes, escapes and non-ASCII text) and on real states of the
kinematic and dynamic twins.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")  # spm_pin.remote.stream needs starlette

import spm_pin as spm
from spm_pin.kinematics import _scalar
from spm_pin.remote import DynamicBackend, KinematicBackend, create_app
from spm_pin.remote.backend import TwinState
from spm_pin.remote.models import (
    StateResponse,
    _state_fields,
    finite_or_none,
    state_json,
    state_response,
)
from spm_pin.remote.stream import StateCache
from spm_pin.rotations import (
    matrix_from_quaternion,
    quaternion_from_matrix,
    rpy_from_matrix,
)

#: Sizes of the random samples.
N = {"rotations": 20000, "states": 3000}
#: Seeds.
SEED = {"rotations": 31410, "states": 31411}
#: Numbers whose JSON text takes every form: exponents both ways, -0.0, subnormals,
#: integers, the bounds of the plain notation, NaN and the infinities.
ODD_NUMBERS = (
    0.0,
    -0.0,
    1.0,
    -2.0,
    0.1,
    1e-4,
    1e-5,
    1e-7,
    -3.8e-17,
    5e-324,
    2.2250738585072014e-308,
    123456.789,
    1e15,
    1e16,
    1.2345678901234567e20,
    1e21,
    1.7976931348623157e308,
    math.nan,
    math.inf,
    -math.inf,
)
#: Fault texts: quotes, backslashes, control characters, non-ASCII text.
FAULTS = (
    None,
    "",
    'SimulationError: the loop "leg 2" cannot close',
    "back\\slash and /slash",
    "tab\tnewline\nreturn\rformfeed\fbackspace\b bell\x07 nul\x00 unit\x1f del\x7f",
    "unicode: θ = 60°, Ω ≥ 1 µm, 中文, emoji 🤖, separators \u2028\u2029, bom \ufeff",
)
PAIRS = (
    (),
    (("proximal_1", "distal_2"),),
    (("proximal_1", "proximal_2"), ("distal_3", "platform"), ("base", "distal_1")),
)


def _reference_json(state: TwinState) -> str:
    """The state's JSON as the model wrote it before the fast path: the numpy
    conversions (one matrix at a time), validated by the model, dumped by pydantic."""

    def degrees(theta: Any) -> list[float]:
        with np.errstate(over="ignore"):  # the largest floats: infinite degrees
            return [float(x) + 0.0 for x in np.degrees(np.asarray(theta, dtype=float))]

    R = state.R
    return StateResponse(
        theta_deg=degrees(state.theta),
        R=None if R is None else [[float(x) for x in row] for row in R],
        quaternion_wxyz=None if R is None else [float(x) for x in quaternion_from_matrix(R)],
        rpy_deg=None if R is None else degrees(rpy_from_matrix(R)),
        reachable=state.reachable,
        pairs=[(a, b) for a, b in state.pairs],
        min_distance_m=finite_or_none(state.min_distance),
        dexterity=finite_or_none(state.dexterity),
        singularity_margin=finite_or_none(state.singularity_margin),
        assembly=state.assembly,
        backend=state.backend,
        moving=state.moving,
        stops=state.stops,
        theta_dot_deg_s=None if state.theta_dot is None else degrees(state.theta_dot),
        goal_deg=None if state.goal is None else degrees(state.goal),
        torque=state.torque,
        fault=state.fault,
        time=state.time,
    ).model_dump_json()


def _assert_same_text(state: TwinState) -> None:
    expected = _reference_json(state)
    assert state_json(state) == expected
    assert state_response(state).model_dump_json() == expected


def _random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """Uniform random rotations, and rotations by pi about random axes and about the
    coordinate axes (w = 0: every row of the quaternion's choice is taken)."""
    q = rng.standard_normal((n, 4))
    half = rng.standard_normal((n // 10, 4))
    half[:, 0] = 0.0
    axes = np.array([[0.0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [1, 0, 0, 0], [-1, 0, 0, 0]])
    q = np.vstack([q, half, axes])
    return matrix_from_quaternion(q / np.linalg.norm(q, axis=1, keepdims=True))


# --------------------------------------------------------------------------- rotations
def test_rotation_conversions_of_one_matrix_bit_for_bit() -> None:
    """``_scalar.quaternion_of`` and ``rpy_of`` equal the numpy functions on one
    matrix, bit for bit; every branch of the quaternion (the largest diagonal
    entry) is taken."""
    rotations = _random_rotations(np.random.default_rng(SEED["rotations"]), N["rotations"])
    branches = set()
    for R in rotations:
        rows = R.tolist()
        quaternion = _scalar.quaternion_of(rows)
        assert quaternion == quaternion_from_matrix(R).tolist(), rows
        assert _scalar.rpy_of(rows) == rpy_from_matrix(R).tolist(), rows
        m = R
        diagonal = [1 + m[0, 0] + m[1, 1] + m[2, 2], 1 + m[0, 0] - m[1, 1] - m[2, 2]]
        diagonal += [1 - m[0, 0] + m[1, 1] - m[2, 2], 1 - m[0, 0] - m[1, 1] + m[2, 2]]
        branches.add(int(np.argmax(diagonal)))
    assert branches == {0, 1, 2, 3}


# --------------------------------------------------------------------------- states
def test_fields_follow_the_model() -> None:
    """The fast path writes the model's fields, in the model's order."""
    state = TwinState(
        theta=np.zeros(3),
        R=np.eye(3),
        reachable=True,
        pairs=(),
        min_distance=0.01,
        dexterity=0.5,
        singularity_margin=0.5,
        assembly="+++/-",
        backend="kinematic",
        time=1.0,
    )
    assert list(_state_fields(state)) == list(StateResponse.model_fields)


def test_random_states_same_text() -> None:
    """Seeded random states, reachable (forward kinematics) and not, with every kind
    of number, pair list, fault and optional field."""
    rng = np.random.default_rng(SEED["states"])
    design = spm.SPMDesign.prototype()
    thetas = rng.uniform(-2.0, 2.0, (N["states"], 3))
    fk = spm.forward_kinematics(thetas, design)
    rotations = _random_rotations(rng, N["states"])
    seen = {"reachable": 0, "unreachable": 0}
    for i, theta in enumerate(thetas):
        reachable = bool(fk.reachable[i])
        seen["reachable" if reachable else "unreachable"] += 1
        R = np.asarray(fk.R[i]) if reachable else None
        if reachable and i % 3 == 0:
            R = rotations[i]  # any rotation, not only the prototype's
        numbers = rng.choice(len(ODD_NUMBERS), 3)
        odd = [ODD_NUMBERS[k] for k in numbers]
        dynamic = i % 2 == 1
        speeds = rng.standard_normal(3) * 10.0 ** rng.integers(-20, 3)
        if i % 7 == 0:
            speeds[rng.integers(3)] = odd[0]
        state = TwinState(
            theta=theta if i % 5 else theta * 1e-18,
            R=R,
            reachable=reachable,
            pairs=PAIRS[i % len(PAIRS)],
            min_distance=odd[0] if i % 4 == 0 else float(rng.uniform(-0.01, 0.05)),
            dexterity=odd[1] if reachable else math.nan,
            singularity_margin=odd[2] if reachable else math.nan,
            assembly=("+++/-" if i % 2 else "+-+/+") if reachable else None,
            backend="dynamic" if dynamic else "kinematic",
            time=time.time() + float(rng.uniform(-1e6, 1e6)) if i % 11 else odd[1],
            moving=bool(i % 3 == 1),
            stops=int(rng.integers(0, 10**6)),
            theta_dot=speeds if dynamic else None,
            goal=theta + rng.uniform(-0.1, 0.1, 3) if dynamic else None,
            fault=FAULTS[i % len(FAULTS)],
            torque=bool(i % 4 != 3),
        )
        _assert_same_text(state)
    assert min(seen.values()) > 0, seen


@pytest.mark.parametrize("fault", FAULTS)
def test_faults_same_text(fault: str | None) -> None:
    state = TwinState(
        theta=np.radians([60.0, 90.0, 220.0]),
        R=None,
        reachable=False,
        pairs=PAIRS[2],
        min_distance=math.inf,
        dexterity=math.nan,
        singularity_margin=math.nan,
        assembly=None,
        backend="servos",
        time=1.5e9,
        theta_dot=np.array([math.nan, -math.inf, 0.0]),
        goal=np.array([-0.0, 1e-300, 2.0]),
        fault=fault,
        torque=False,
    )
    _assert_same_text(state)


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


def test_kinematic_twin_states_same_text(robot: spm.SPMRobot) -> None:
    """Real states of the kinematic twin: after moves, during a stream of goals, at
    an input whose links collide, and the pushed text of the state cache."""
    twin = KinematicBackend(robot=robot)
    _assert_same_text(twin.state())
    twin.move(np.radians([20.0, -10.0, 35.0]))
    _assert_same_text(twin.state())
    previous = twin.joints()
    for _ in range(19):
        goal = previous + np.radians(0.01)
        twin.command(goal, previous=previous, period=1e-3)
        previous = goal
        _assert_same_text(twin.state())
    colliding = twin._compute_state(np.radians([60.0, 90.0, 220.0]))
    assert colliding.pairs
    _assert_same_text(colliding)


class _FixedTwin:
    """A twin whose state never changes (what :class:`StateCache` reads)."""

    def __init__(self, state: TwinState) -> None:
        self._state = state

    def state(self) -> TwinState:
        return self._state


@pytest.mark.parametrize("fault", [None, FAULTS[-1]])
def test_state_cache_pushes_the_model_text(fault: str | None) -> None:
    """The members the pushers send: the model's JSON without its opening brace."""
    quaternion = np.array([0.9, 0.1, -0.2, 0.3])
    state = TwinState(
        theta=np.radians([20.0, -10.0, 35.0]),
        R=matrix_from_quaternion(quaternion / np.linalg.norm(quaternion)),
        reachable=True,
        pairs=PAIRS[1],
        min_distance=-0.002,
        dexterity=0.3,
        singularity_margin=0.2,
        assembly="+++/-",
        backend="kinematic",
        time=time.time(),
        fault=fault,
    )
    cache = StateCache(_FixedTwin(state))  # type: ignore[arg-type]
    assert cache._read() == _reference_json(state)[1:]


def test_dynamic_twin_states_same_text(robot: spm.SPMRobot) -> None:
    """Real states of the dynamic twin, at rest (speeds of 1e-18 deg/s and less) and
    moving (speeds and a goal)."""
    with DynamicBackend(robot=robot) as twin:
        for _ in range(3):
            _assert_same_text(twin.state())
            time.sleep(0.02)
        twin.move(np.radians([10.0, 5.0, -5.0]))
        for _ in range(5):
            state = twin.state()
            _assert_same_text(state)
            time.sleep(0.02)
        assert state.theta_dot is not None and state.goal is not None


def test_openapi_still_documents_the_state_model(robot: spm.SPMRobot) -> None:
    """``GET /state`` is still described by :class:`StateResponse`."""
    spec = create_app(KinematicBackend(robot=robot)).openapi()
    answer = spec["paths"]["/state"]["get"]["responses"]["200"]["content"]["application/json"]
    assert answer["schema"] == {"$ref": "#/components/schemas/StateResponse"}
    schema = spec["components"]["schemas"]["StateResponse"]
    assert list(schema["properties"]) == list(StateResponse.model_fields)
