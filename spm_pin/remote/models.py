"""The JSON bodies of the HTTP API, as pydantic models.

Requests are strict: unknown keys, numbers that are not finite (NaN, Infinity),
strings or booleans in place of numbers and lists of the wrong length are refused
(422, naming the field). Angles are degrees on the wire (the key says the unit);
``null`` stands where a value does not exist (no NaN or infinity is ever sent).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, TypeVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, StrictInt, TypeAdapter, model_validator
from pydantic_core import to_json

from ..kinematics import _scalar
from .backend import CHECK_NAMES, CollisionState, GoalReport, TwinState

__all__ = [
    "CLIENT_MESSAGE",
    "CheckModel",
    "CheckRequest",
    "CheckResponse",
    "CollisionsResponse",
    "ErrorResponse",
    "GoalRefusedResponse",
    "JointsGoal",
    "JointsResponse",
    "OrientationGoal",
    "PairModel",
    "StateResponse",
    "StreamAuth",
    "StreamControl",
    "StreamTarget",
    "check_response",
    "collisions_response",
    "finite_or_none",
    "state_json",
    "state_response",
]

#: A finite JSON number (an integer or a float; not a string, a boolean, NaN or Infinity).
Number = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Vector3 = tuple[Number, Number, Number]
Vector4 = tuple[Number, Number, Number, Number]
LinkPairModel = tuple[str, str]


class _Request(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


#: The forms a goal may take (a body gives exactly one of them).
_GOAL_FORMS = ("theta_deg", "rpy_deg", "quaternion_wxyz")


_Body = TypeVar("_Body", bound=BaseModel)


def _exactly_one(body: _Body, names: tuple[str, ...]) -> _Body:
    """``body`` when exactly one of the fields ``names`` is given, else ValueError."""
    given = [name for name in names if getattr(body, name) is not None]
    if len(given) != 1:
        choices = ", ".join(names[:-1]) + " or " + names[-1]
        none = "neither" if len(names) == 2 else "none"
        raise ValueError(f"give exactly one of {choices}, got {given or none}")
    return body


class JointsGoal(_Request):
    """``PUT /joints``: the goal's input angles."""

    theta_deg: Vector3 = Field(description="Input angles theta_1..3 [deg].")


class OrientationGoal(_Request):
    """``PUT /orientation``: the goal's platform orientation, exactly one of two forms."""

    rpy_deg: Vector3 | None = Field(
        default=None, description="Fixed-axis angles [deg]: R = Rz(yaw) Ry(pitch) Rx(roll)."
    )
    quaternion_wxyz: Vector4 | None = Field(
        default=None, description="Unit quaternion, scalar first (normalised)."
    )

    @model_validator(mode="after")
    def _exactly_one(self) -> OrientationGoal:
        return _exactly_one(self, ("rpy_deg", "quaternion_wxyz"))


class CheckRequest(_Request):
    """``POST /check``: a goal as input angles or as an orientation, exactly one."""

    theta_deg: Vector3 | None = Field(default=None, description="Input angles [deg].")
    rpy_deg: Vector3 | None = Field(default=None, description="Fixed-axis angles [deg].")
    quaternion_wxyz: Vector4 | None = Field(default=None, description="Quaternion (w, x, y, z).")

    @model_validator(mode="after")
    def _exactly_one(self) -> CheckRequest:
        return _exactly_one(self, _GOAL_FORMS)


class StreamTarget(_Request):
    """``WS /stream``: a goal, as input angles or as an orientation (exactly one)."""

    type: Literal["target"]
    seq: StrictInt | None = Field(default=None, description="Echoed in the answer.")
    theta_deg: Vector3 | None = Field(default=None, description="Input angles [deg].")
    rpy_deg: Vector3 | None = Field(default=None, description="Fixed-axis angles [deg].")
    quaternion_wxyz: Vector4 | None = Field(default=None, description="Quaternion (w, x, y, z).")
    t: Number | None = Field(
        default=None,
        description=(
            "The goal's time on the client's clock [s] (any origin, increasing). With "
            "it the guard's speed and acceleration checks use the times between goals "
            "that the client meant, not their arrival times (network jitter)."
        ),
    )

    @model_validator(mode="after")
    def _exactly_one(self) -> StreamTarget:
        return _exactly_one(self, _GOAL_FORMS)


class StreamControl(_Request):
    """``WS /stream``: ask for the lease, give it back, or stop the twin."""

    type: Literal["lease", "release", "stop", "ping"]
    seq: StrictInt | None = Field(default=None, description="Echoed in the answer.")


class StreamAuth(_Request):
    """``WS /stream``: the bearer token, as the first message (for browsers)."""

    type: Literal["auth"]
    token: str


#: Parses one text message of a streaming client (JSON) into its model.
CLIENT_MESSAGE: TypeAdapter[StreamTarget | StreamControl | StreamAuth] = TypeAdapter(
    Annotated[StreamTarget | StreamControl | StreamAuth, Field(discriminator="type")]
)


class _Response(BaseModel):
    model_config = ConfigDict(extra="forbid")


class StateResponse(_Response):
    """The twin's state."""

    theta_deg: list[float] = Field(description="Input angles [deg].")
    R: list[list[float]] | None = Field(description="Platform rotation, row by row.")
    quaternion_wxyz: list[float] | None = Field(description="Platform orientation (w >= 0).")
    rpy_deg: list[float] | None = Field(description="Roll, pitch, yaw [deg].")
    reachable: bool = Field(description="The home assembly mode exists.")
    pairs: list[LinkPairModel] = Field(description="Colliding link pairs.")
    min_distance_m: float | None = Field(description="Smallest distance of two links [m].")
    dexterity: float | None = Field(description="1/kappa(J) in [0, 1].")
    singularity_margin: float | None = Field(description="Distance to singularity in [0, 1].")
    assembly: str | None = Field(description="Assembly-mode label such as +++/-.")
    backend: str = Field(description="The twin: kinematic, dynamic or servos.")
    moving: bool = Field(description="A motion is in progress.")
    stops: int = Field(description="How many times the twin was stopped.")
    theta_dot_deg_s: list[float] | None = Field(
        default=None, description="Input speeds [deg/s] (null for the kinematic twin)."
    )
    goal_deg: list[float] | None = Field(
        default=None, description="The goal being approached [deg] (null: kinematic twin)."
    )
    torque: bool = Field(default=True, description="The actuators hold their goal.")
    fault: str | None = Field(
        default=None, description="Why the twin stopped by itself (simulation or servo fault)."
    )
    time: float = Field(description="Server time [s since the epoch].")


class JointsResponse(_Response):
    """The input angles."""

    theta_deg: list[float] = Field(description="Input angles [deg].")


class PairModel(_Response):
    """One checked link pair."""

    pair: LinkPairModel
    colliding: bool
    distance_m: float | None = Field(description="Distance [m], negative on overlap.")


class CollisionsResponse(_Response):
    """Every checked link pair at the current state."""

    theta_deg: list[float]
    collision: bool = Field(description="Some pair collides.")
    pairs: list[PairModel]


class CheckModel(_Response):
    """One check of a goal."""

    check: str = Field(description=f"One of {', '.join(CHECK_NAMES)}.")
    passed: bool | None = Field(description="null: not evaluated (no home-mode assembly).")
    reason: str | None


class CheckResponse(_Response):
    """The verdict on a goal (``POST /check``)."""

    theta_deg: list[float] = Field(description="The goal's input angles [deg].")
    safe: bool
    checks: list[CheckModel]
    reasons: list[str]
    reachable: bool
    pairs: list[LinkPairModel] = Field(description="Colliding link pairs (with margin).")
    assembly: str | None = Field(description="Assembly mode the collisions were checked in.")
    min_distance_m: float | None
    collision_margin_m: float
    dexterity: float | None
    singularity_margin: float | None


class ErrorResponse(_Response):
    """A refused request: what went wrong."""

    detail: str
    error: str = Field(description="The kind of error, e.g. UnreachableError.")


class GoalRefusedResponse(_Response):
    """A goal the guard refused (409): nothing moved."""

    detail: str
    error: str
    failed: list[CheckModel] = Field(description="The failed checks with their reasons.")
    verdict: CheckResponse


def finite_or_none(value: Any) -> float | None:
    """A float, or None where it is NaN or infinite."""
    number = float(value) + 0.0  # -0.0 -> 0.0
    return number if math.isfinite(number) else None


#: Degrees per radian, as ``np.degrees`` multiplies by it.
_DEGREES = 180.0 / math.pi


def _degrees(theta: Any) -> list[float]:
    """``np.degrees`` of a few angles [rad] (-0.0 written 0.0), in Python floats:
    the same bits, without numpy's per-call cost."""
    return [x * _DEGREES + 0.0 for x in np.asarray(theta, dtype=float).tolist()]


def _state_fields(state: TwinState) -> dict[str, Any]:
    """The fields of :class:`StateResponse` for a state, in its order, as plain
    Python values: the rotation's conversions in Python floats
    (:func:`~spm_pin.kinematics._scalar.quaternion_of`, ``rpy_of``), bit for bit
    those of :func:`~spm_pin.rotations.quaternion_from_matrix` and
    :func:`~spm_pin.rotations.rpy_from_matrix` on one matrix, at a fraction of their
    cost."""
    rows: list[list[float]] | None = None
    quaternion = rpy = None
    if state.R is not None:
        rows = np.asarray(state.R, dtype=float).tolist()
        quaternion = _scalar.quaternion_of(rows)
        rpy = _degrees(_scalar.rpy_of(rows))
    return {
        "theta_deg": _degrees(state.theta),
        "R": rows,
        "quaternion_wxyz": quaternion,
        "rpy_deg": rpy,
        "reachable": bool(state.reachable),
        "pairs": [(a, b) for a, b in state.pairs],
        "min_distance_m": finite_or_none(state.min_distance),
        "dexterity": finite_or_none(state.dexterity),
        "singularity_margin": finite_or_none(state.singularity_margin),
        "assembly": state.assembly,
        "backend": state.backend,
        "moving": bool(state.moving),
        "stops": int(state.stops),
        "theta_dot_deg_s": None if state.theta_dot is None else _degrees(state.theta_dot),
        "goal_deg": None if state.goal is None else _degrees(state.goal),
        "torque": bool(state.torque),
        "fault": state.fault,
        "time": float(state.time),
    }


def state_response(state: TwinState) -> StateResponse:
    """The JSON form of a state."""
    return StateResponse(**_state_fields(state))


def state_json(state: TwinState) -> str:
    """``state_response(state).model_dump_json()``, the same text, without building
    the model: the fields serialised by pydantic's own JSON writer (numbers, the
    escapes of strings; NaN and infinity as ``null``, as the model writes them).
    What a state pushed at up to 1 kHz needs (``tests/test_remote_state_json.py``
    compares the two text for text)."""
    return to_json(_state_fields(state), inf_nan_mode="null").decode()


def check_response(report: GoalReport) -> CheckResponse:
    """The JSON form of a verdict."""
    return CheckResponse(
        theta_deg=_degrees(report.theta),
        safe=report.safe,
        checks=[CheckModel(check=c.name, passed=c.passed, reason=c.reason) for c in report.checks],
        reasons=list(report.reasons),
        reachable=report.reachable,
        pairs=[(a, b) for a, b in report.pairs],
        assembly=report.assembly,
        min_distance_m=finite_or_none(report.min_distance),
        collision_margin_m=report.collision_margin,
        dexterity=finite_or_none(report.dexterity),
        singularity_margin=finite_or_none(report.singularity_margin),
    )


def collisions_response(collisions: CollisionState) -> CollisionsResponse:
    """The JSON form of the link pairs at a state."""
    return CollisionsResponse(
        theta_deg=_degrees(collisions.theta),
        collision=collisions.collision,
        pairs=[
            PairModel(
                pair=pair.pair, colliding=pair.colliding, distance_m=finite_or_none(pair.distance)
            )
            for pair in collisions.pairs
        ],
    )
