"""Bad input raises SPMError subclasses that are also the matching builtin exception;
impossible designs and malformed design files are rejected with useful data."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import seeds
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import spm_pin as spm
from spm_pin.rotations import (
    matrix_from_quaternion,
    matrix_from_rpy,
    quaternion_from_matrix,
    rpy_from_matrix,
)

PROTOTYPE = spm.SPMDesign.prototype()
VALID_TOML = "[kinematics]\nalpha1_deg = 45\nalpha2_deg = 90\nbeta_deg = 90\n"


# --------------------------------------------------------------- hierarchy
@pytest.mark.parametrize(
    ("error", "builtin"),
    [
        (spm.InputError, ValueError),
        (spm.DesignError, ValueError),
        (spm.FileFormatError, ValueError),
        (spm.UnreachableError, ValueError),
        (spm.SingularityError, ValueError),
        (spm.ConvergenceError, RuntimeError),
        (spm.HardwareError, RuntimeError),
        (spm.CommunicationError, RuntimeError),
        (spm.ServoError, RuntimeError),
        (spm.ServoAlertError, RuntimeError),
        (spm.UnsafeCommandError, ValueError),
    ],
)
def test_every_error_is_an_spm_error_and_a_builtin(error: type, builtin: type) -> None:
    assert issubclass(error, spm.SPMError)
    assert issubclass(error, builtin)


def test_errors_keep_their_data() -> None:
    assert issubclass(spm.DesignError, spm.InputError)
    error = spm.DesignError("bad", parameter="alpha1", value=0.0)
    assert error.parameter == error.argument == "alpha1" and error.value == 0.0
    error = spm.FileFormatError("broken", path="d.toml", line=3)
    assert str(error) == "d.toml:3: broken" and error.path == "d.toml" and error.line == 3
    assert str(spm.FileFormatError("broken", path="d.toml")) == "d.toml: broken"
    assert spm.UnreachableError("no", leg=2).leg == 2
    assert spm.SingularityError("no", kind="type II").kind == "type II"
    assert spm.ConvergenceError("slow").data == {}


# ------------------------------------------------------------ bad inputs
BAD_THETA: dict[str, Any] = {
    "two entries": [0.0, 0.0],
    "four entries": [0.0, 0.0, 0.0, 0.0],
    "scalar": 0.0,
    "None": None,
    "NaN": [0.0, math.nan, 0.0],
    "inf": [0.0, 0.0, math.inf],
    "-inf in a batch": [[0.0, 0.0, 0.0], [0.0, -math.inf, 0.0]],
    "string": "0 0 0",
    "strings": ["a", "b", "c"],
    "ragged": [[0.0, 0.0, 0.0], [0.0]],
    "complex": [1j, 0.0, 0.0],
    "dict": {"theta": [0, 0, 0]},
    "object": object(),
    "wrong last axis": np.zeros((3, 2)),
}

THETA_FUNCTIONS: dict[str, Callable[[Any], object]] = {
    "forward_kinematics": lambda x: spm.forward_kinematics(x, PROTOTYPE),
    "forward_kinematics_all": lambda x: spm.forward_kinematics_all(x, PROTOTYPE),
    "jacobian": lambda x: spm.jacobian(x, PROTOTYPE),
    "track": lambda x: spm.track(x, PROTOTYPE),
    "ik theta_near": lambda x: spm.inverse_kinematics(np.eye(3), PROTOTYPE, theta_near=x),
}


#: The argument each of THETA_FUNCTIONS names in its messages.
THETA_ARGUMENT = {
    "forward_kinematics": "theta",
    "forward_kinematics_all": "theta",
    "jacobian": "theta",
    "track": "theta_path",
    "ik theta_near": "theta_near",
}


# None is the default of theta_near, so it is not bad input there.
BAD_THETA_CASES = [
    (function, bad)
    for function in THETA_FUNCTIONS
    for bad in BAD_THETA
    if not (function == "ik theta_near" and bad == "None")
]


@pytest.mark.parametrize(("function", "bad"), BAD_THETA_CASES)
def test_bad_theta(function: str, bad: str) -> None:
    name = THETA_ARGUMENT[function]
    # the argument's name, then what is allowed: the finite range or the shape
    allowed = rf"finite with \|{name}\| <= 2048 rad|shape \(3,\) or \(\.\.\., 3\)"
    with pytest.raises(spm.InputError, match=rf"^{name} must .*({allowed})") as info:
        THETA_FUNCTIONS[function](BAD_THETA[bad])
    assert isinstance(info.value, ValueError)
    assert info.value.argument in {"theta", "theta_path", "theta_near"}


@settings(max_examples=100)
@given(
    value=st.sampled_from([math.nan, math.inf, -math.inf]),
    index=st.integers(min_value=0, max_value=11),
)
def test_any_non_finite_entry_is_rejected(value: float, index: int) -> None:
    theta = np.zeros((4, 3))
    theta.flat[index] = value
    for function in ("forward_kinematics", "forward_kinematics_all", "jacobian", "track"):
        with pytest.raises(spm.InputError, match="finite"):
            THETA_FUNCTIONS[function](theta)


def test_track_needs_a_sequence(prototype: spm.SPMDesign) -> None:
    for bad in (np.zeros(3), np.zeros((0, 3)), np.zeros((2, 2, 3))):
        with pytest.raises(
            spm.InputError, match=r"^theta_path must have shape \(N, 3\) with N >= 1"
        ):
            spm.track(bad, prototype)
    with pytest.raises(spm.InputError, match=r"^max_depth must be a non-negative integer, got -1"):
        spm.track(np.zeros((2, 3)), prototype, max_depth=-1)
    with pytest.raises(spm.InputError, match=r"^start must be one rotation \(3, 3\)"):
        spm.track(np.zeros((2, 3)), prototype, start=np.stack([np.eye(3)] * 2))


def _not_rotations() -> dict[str, Any]:
    c, s = math.cos(0.3), math.sin(0.3)
    return {
        "2x2": np.eye(2),
        "vector": np.zeros(3),
        "3x4": np.zeros((3, 4)),
        "scaled": 2 * np.eye(3),
        "mirror": np.diag([1.0, 1.0, -1.0]),
        "sheared": np.array([[1.0, 1e-3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
        "zero": np.zeros((3, 3)),
        "NaN": np.full((3, 3), math.nan),
        "inf": np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, math.inf]]),
        "string": "identity",
        "bad item in a batch": np.stack([np.eye(3), 2 * np.eye(3)]),
    }


_SHAPE = r"must have shape \(3, 3\) or \(\.\.\., 3, 3\), got shape "
_NOT_ROTATION = r"is not a rotation matrix \(.*\); allowed: orthonormal within 1e-06 with det \+1"
#: What the message says of each of _not_rotations(), after the argument's name.
NOT_ROTATION_MATCH = {
    "2x2": _SHAPE + r"\(2, 2\)",
    "vector": _SHAPE + r"\(3,\)",
    "3x4": _SHAPE + r"\(3, 4\)",
    "scaled": _NOT_ROTATION,
    "mirror": _NOT_ROTATION,
    "sheared": _NOT_ROTATION,
    "zero": _NOT_ROTATION,
    "NaN": "must be finite",
    "inf": "must be finite",
    "string": r"must be rotation matrices of shape \(3, 3\) or \(\.\.\., 3, 3\)",
    "bad item in a batch": r"is not a rotation matrix \(.*at batch index \(1,\)\); allowed",
}

ROTATION_FUNCTIONS: dict[str, Callable[[Any], object]] = {
    "inverse_kinematics": lambda R: spm.inverse_kinematics(R, PROTOTYPE),
    "inverse_kinematics_all": lambda R: spm.inverse_kinematics_all(R, PROTOTYPE),
    "jacobian R": lambda R: spm.jacobian(np.zeros(3), PROTOTYPE, R=R),
    "fk reference": lambda R: spm.forward_kinematics(np.zeros(3), PROTOTYPE, reference=R),
    "track start": lambda R: spm.track(np.zeros((2, 3)), PROTOTYPE, start=R),
}
#: The argument each of ROTATION_FUNCTIONS names in its messages.
ROTATION_ARGUMENT = {
    "inverse_kinematics": "R",
    "inverse_kinematics_all": "R",
    "jacobian R": "R",
    "fk reference": "reference",
    "track start": "start",
}


@pytest.mark.parametrize("function", ROTATION_FUNCTIONS)
@pytest.mark.parametrize("bad", _not_rotations())
def test_bad_rotation(function: str, bad: str) -> None:
    match = rf"^{ROTATION_ARGUMENT[function]} {NOT_ROTATION_MATCH[bad]}"
    with pytest.raises(spm.InputError, match=match) as info:
        ROTATION_FUNCTIONS[function](_not_rotations()[bad])
    assert isinstance(info.value, ValueError)


@settings(max_examples=50)
@given(seed=seeds, size=st.floats(1e-5, 1.0))
def test_perturbed_rotations_are_rejected(seed: int, size: float) -> None:
    """A rotation plus a perturbation above the 1e-6 tolerance is not a rotation."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=4)
    R = matrix_from_quaternion(q) + size * rng.normal(size=(3, 3)) / math.sqrt(3)
    error = np.abs(R.T @ R - np.eye(3)).max()
    assume(error >= 1e-5)  # a draw this close to a rotation proves nothing: drawn again
    # The unperturbed rotation passes the check, so the perturbation is what is refused
    # (a batch of one: an unreachable rotation is flagged there, not raised).
    assert spm.inverse_kinematics(matrix_from_quaternion(q)[None], PROTOTYPE).theta.shape == (1, 3)
    with pytest.raises(spm.InputError, match="rotation"):
        spm.inverse_kinematics(R, PROTOTYPE)


@pytest.mark.parametrize("mode", [8, -1, 1.0, True, None, "abc", "++", "+++/-", [0]])
def test_bad_working_mode(mode: Any) -> None:
    with pytest.raises(spm.InputError, match="mode"):
        spm.inverse_kinematics(np.eye(3), PROTOTYPE, mode=mode)


@pytest.mark.parametrize("design", [b"prototype", 3, {"alpha1": 1.0}])
def test_design_argument_must_be_a_design(design: Any) -> None:
    for call in (
        lambda: spm.forward_kinematics(np.zeros(3), design),
        lambda: spm.forward_kinematics_all(np.zeros(3), design),
        lambda: spm.inverse_kinematics(np.eye(3), design),
        lambda: spm.jacobian(np.zeros(3), design),
        lambda: spm.track(np.zeros((2, 3)), design),
    ):
        with pytest.raises(spm.InputError, match="SPMDesign"):
            call()


def test_reference_must_broadcast() -> None:
    with pytest.raises(spm.InputError, match="broadcast"):
        spm.forward_kinematics(np.zeros((4, 3)), PROTOTYPE, reference=np.stack([np.eye(3)] * 3))


def test_jacobian_rotation_must_broadcast() -> None:
    match = r"R of shape \(3, 3, 3\) does not match theta of shape \(4, 3\); R must broadcast"
    with pytest.raises(spm.InputError, match=match):
        spm.jacobian(np.zeros((4, 3)), PROTOTYPE, R=np.stack([np.eye(3)] * 3))


def test_jacobian_tolerance_must_be_a_number() -> None:
    with pytest.raises(spm.InputError, match=r"^tol must be a number in \[0, 1\), got 'tight'"):
        spm.jacobian(np.zeros(3), PROTOTYPE, tol="tight")  # type: ignore[arg-type]


def test_single_unreachable_inputs_raise_with_data() -> None:
    theta = np.radians([0.0, 0.0, 200.0])
    where = r"theta = \[0\.0, 0\.0, 200\.0\] deg"
    with pytest.raises(spm.UnreachableError, match=f"no home-mode assembly at {where}") as info:
        spm.jacobian(theta, PROTOTYPE)
    np.testing.assert_array_equal(info.value.value, theta)
    match = f"no home-mode assembly at the first sample, {where}; pass start="
    with pytest.raises(spm.UnreachableError, match=match):
        spm.track(np.stack([theta, np.zeros(3)]), PROTOTYPE)
    assert not spm.forward_kinematics(theta, PROTOTYPE).reachable  # FK flags, never raises


# -------------------------------------------------------------- rotations
BAD_QUATERNIONS = {
    "zero": [0.0, 0.0, 0.0, 0.0],
    "NaN": [math.nan, 0.0, 0.0, 1.0],
    "inf": [1.0, math.inf, 0.0, 0.0],
    "three entries": [1.0, 0.0, 0.0],
    "string": "q",
}
#: What the message says of each of BAD_QUATERNIONS.
QUATERNION_MATCH = {
    "zero": "must be non-zero",
    "NaN": "must be finite",
    "inf": "must be finite",
    "three entries": r"must have shape \(4,\) or \(\.\.\., 4\), got \(3,\)",
    "string": "must be numbers",
}


@pytest.mark.parametrize("bad", BAD_QUATERNIONS)
def test_bad_quaternion(bad: str) -> None:
    with pytest.raises(spm.InputError, match=f"^quaternion {QUATERNION_MATCH[bad]}"):
        matrix_from_quaternion(BAD_QUATERNIONS[bad])


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ([0.0, 0.0], r"must have shape \(3,\) or \(\.\.\., 3\), got \(2,\)"),
        ([math.nan, 0.0, 0.0], "must be finite"),
        ([0.0, math.inf, 0.0], "must be finite"),
        ("rpy", "must be numbers"),
    ],
)
def test_bad_rpy(bad: Any, message: str) -> None:
    with pytest.raises(spm.InputError, match=f"^rpy {message}"):
        matrix_from_rpy(bad)


@pytest.mark.parametrize("function", [rpy_from_matrix, quaternion_from_matrix])
@pytest.mark.parametrize("bad", ["2x2", "NaN", "string", "scaled", "mirror"])
def test_bad_matrix_for_conversions(function: Callable[[Any], object], bad: str) -> None:
    with pytest.raises(spm.InputError, match=f"^R {NOT_ROTATION_MATCH[bad]}"):
        function(_not_rotations()[bad])


# ---------------------------------------------------------------- designs
def _design(**changes: Any) -> spm.SPMDesign:
    parameters: dict[str, Any] = {
        "alpha1": math.radians(45.0),
        "alpha2": math.radians(90.0),
        "beta": math.radians(90.0),
    }
    parameters.update(changes)
    return spm.SPMDesign(**parameters)


@pytest.mark.parametrize("parameter", ["alpha1", "alpha2", "beta"])
@pytest.mark.parametrize("value", [0.0, math.pi, -0.1, 4.0, math.nan, math.inf, "1", None])
def test_impossible_angles(parameter: str, value: Any) -> None:
    # out of range: the value and the open range (0, 180) deg; not a number: what is wanted
    allowed = r"= -?[\d.]+ deg is impossible: it must lie strictly between 0 and 180 deg"
    match = rf"^{parameter} ({allowed}|must be a finite angle \[rad\])"
    with pytest.raises(spm.DesignError, match=match) as info:
        _design(**{parameter: value})
    assert info.value.parameter == parameter
    assert parameter in str(info.value)
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    ("changes", "parameter"),
    [
        ({"eta": (0.0, 1.0)}, "eta"),
        ({"eta": (0.0, 1.0, 2.0, 3.0)}, "eta"),
        ({"eta": (0.0, 1.0, math.nan)}, "eta"),
        ({"eta": "abc"}, "eta"),
        ({"eta": (0.0, 0.0, 2.0)}, "eta"),  # v_1 and v_2 parallel
        ({"eta": (0.0, math.pi, 2.0)}, "eta"),  # v_1 and v_2 opposite
        ({"base_axes": ((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 0.0, -1.0))}, "base_axes[0]"),
        ({"base_axes": ((0.0, 0.0, -1.0),) * 2}, "base_axes"),
        ({"base_axes": ((0.0, -1.0), (0.0, 0.0, -1.0), (0.0, 0.0, -1.0))}, "base_axes[0]"),
        ({"base_axes": ((0.0, 0.0, -1.0), (0.0, math.nan, -1.0), (0, 0, -1))}, "base_axes[1]"),
        ({"name": 3}, "name"),
        ({"dimensions": "small"}, "dimensions"),
    ],
)
def test_impossible_design_parameters(changes: dict[str, Any], parameter: str) -> None:
    with pytest.raises(spm.DesignError, match=rf"^{re.escape(parameter)}[ :]") as info:
        _design(**changes)
    assert info.value.parameter == parameter


@pytest.mark.parametrize(
    "degrees",
    [
        (10.0, 20.0, 90.0),  # a1 + a2 < 90 deg: v_i0 out of reach of w_i
        (45.0, 30.0, 170.0),  # v_i0 too close to the base axis
        (45.0, 90.0, 45.0),  # v_i0 at 135 deg from u: beyond a1 + a2
    ],
)
def test_home_that_cannot_be_assembled(degrees: tuple[float, float, float]) -> None:
    with pytest.raises(spm.DesignError, match="cannot be assembled"):
        spm.SPMDesign.coaxial(*degrees)


def test_unknown_preset_lists_the_choices() -> None:
    with pytest.raises(spm.DesignError, match="agile_eye") as info:
        spm.SPMDesign.preset("nope")
    assert info.value.parameter == "preset"


def test_bad_link_dimensions() -> None:
    match = r"^dimensions\.proximal_radius must be a finite positive number, got -1\.0"
    with pytest.raises(spm.DesignError, match=match) as info:
        spm.LinkDimensions(proximal_radius=-1.0)
    assert info.value.parameter == "proximal_radius"
    with pytest.raises(spm.DesignError, match=r"^dimensions\.servo_size must be 3 lengths \[m\]"):
        spm.LinkDimensions(servo_size=(0.03, 0.05))
    match = r"the proximal sphere \(.*\) must lie inside the distal sphere \(.*= 0\.066 m\)"
    with pytest.raises(spm.DesignError, match=match):
        spm.LinkDimensions(distal_radius=0.07)  # inside the proximal sphere


@pytest.mark.parametrize("build", ["base_axes None", "coaxial string"])
def test_wrong_types_in_design_constructors(build: str) -> None:
    match = {
        "base_axes None": "^base_axes must hold 3 unit vectors, got None",
        "coaxial string": "^alpha1 must be an angle in degrees, got 'a'",
    }[build]
    with pytest.raises(spm.DesignError, match=match):
        if build == "base_axes None":
            _design(base_axes=None)
        else:
            spm.SPMDesign.coaxial("a", 90.0, 90.0)  # type: ignore[arg-type]


# ------------------------------------------------------------- TOML files
MALFORMED_TOML = {
    "not TOML": "this is [not toml",
    "empty": "",
    "no [kinematics]": 'name = "a"\n',
    "kinematics not a table": "kinematics = 3\n",
    "array of tables": "[[kinematics]]\nalpha1_deg = 45\n",
    "unknown top-level key": VALID_TOML + "[extra]\na = 1\n",
    "unknown kinematics key": VALID_TOML + "gamma_deg = 1\n",
    "missing beta_deg": "[kinematics]\nalpha1_deg = 45\nalpha2_deg = 90\n",
    "string angle": '[kinematics]\nalpha1_deg = "45"\nalpha2_deg = 90\nbeta_deg = 90\n',
    "boolean angle": "[kinematics]\nalpha1_deg = true\nalpha2_deg = 90\nbeta_deg = 90\n",
    "list angle": "[kinematics]\nalpha1_deg = [45]\nalpha2_deg = 90\nbeta_deg = 90\n",
    "date angle": "[kinematics]\nalpha1_deg = 1979-05-27\nalpha2_deg = 90\nbeta_deg = 90\n",
    "eta not a list": VALID_TOML + "eta_deg = 3\n",
    "eta with a string": VALID_TOML + 'eta_deg = [0, 120, "a"]\n',
    "base_axes flat": VALID_TOML + "base_axes = [1, 2, 3]\n",
    "dimensions not a table": "dimensions = 3\n" + VALID_TOML,
    "unknown dimension": VALID_TOML + "[dimensions]\nfoo = 1\n",
    "string dimension": VALID_TOML + '[dimensions]\ndensity = "x"\n',
    "table dimension": VALID_TOML + "[dimensions]\ndensity = {a = 1}\n",
}
#: What the message says of each of MALFORMED_TOML.
MALFORMED_TOML_MATCH = {
    "not TOML": "not valid TOML",
    "empty": r"missing table \[kinematics\]",
    "no [kinematics]": r"missing table \[kinematics\]",
    "kinematics not a table": r"missing table \[kinematics\]",
    "array of tables": r"missing table \[kinematics\]",
    "unknown top-level key": r"unknown key\(s\) \['extra'\]; allowed: \['dimensions', 'kinematics'",
    "unknown kinematics key": r"\[kinematics\] has unknown key\(s\) \['gamma_deg'\]; allowed",
    "missing beta_deg": r"\[kinematics\] lacks \['beta_deg'\]",
    "string angle": "alpha1_deg must be a number",
    "boolean angle": "alpha1_deg must be a number",
    "list angle": "alpha1_deg must be a number",
    "date angle": "alpha1_deg must be a number",
    "eta not a list": "eta_deg must be a list",
    "eta with a string": "eta_deg must be a number",
    "base_axes flat": "base_axes must be a list of 3 vectors",
    "dimensions not a table": r"\[dimensions\] must be a table",
    "unknown dimension": r"\[dimensions\] has unknown key\(s\) \['foo'\]; allowed",
    "string dimension": "density must be a number",
    "table dimension": "density must be a number",
}


@pytest.mark.parametrize("case", MALFORMED_TOML)
def test_malformed_toml(case: str, tmp_path: Path) -> None:
    path = tmp_path / "design.toml"
    path.write_text(MALFORMED_TOML[case], encoding="utf-8")
    message = MALFORMED_TOML_MATCH[case]
    with pytest.raises(spm.FileFormatError, match=f": {message}") as info:
        spm.SPMDesign.load(path)
    assert info.value.path == str(path)
    assert str(path) in str(info.value)
    assert isinstance(info.value, ValueError)
    with pytest.raises(spm.FileFormatError, match=f"^{message}"):
        spm.SPMDesign.from_toml(MALFORMED_TOML[case])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            VALID_TOML + "[dimensions]\ndensity = [1, 2]\n",
            r"^density must be a number, got \[1, 2\]",
        ),
        ("name = 3\n" + VALID_TOML, "^name must be a string, got 3"),
    ],
    ids=["list for a scalar dimension", "number for the name"],
)
def test_wrongly_typed_toml_values(text: str, message: str) -> None:
    with pytest.raises(spm.FileFormatError, match=message):
        spm.SPMDesign.from_toml(text)


_BETWEEN = "it must lie strictly between 0 and 180 deg"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[kinematics]\nalpha1_deg = 0\nalpha2_deg = 90\nbeta_deg = 90\n",
            f"alpha1 = 0 deg is impossible: {_BETWEEN}",
        ),
        (
            "[kinematics]\nalpha1_deg = nan\nalpha2_deg = 90\nbeta_deg = 90\n",
            "alpha1 must be a finite angle",
        ),
        (
            "[kinematics]\nalpha1_deg = 45\nalpha2_deg = 90\nbeta_deg = 180\n",
            f"beta = 180 deg is impossible: {_BETWEEN}",
        ),
        (VALID_TOML + "eta_deg = [0, 120]\n", "eta must be 3 finite leg azimuths"),
        (
            VALID_TOML + "base_axes = [[0, 0, 0], [0, 0, -1], [0, 0, -1]]\n",
            r"base_axes\[0\] must be non-zero",
        ),
        (
            VALID_TOML + "[dimensions]\ndensity = -1\n",
            r"dimensions\.density must be a finite positive number, got -1\.0",
        ),
        (
            "[kinematics]\nalpha1_deg = 10\nalpha2_deg = 20\nbeta_deg = 90\n",
            "leg 1 cannot be assembled at home",
        ),
    ],
)
def test_impossible_values_in_toml(text: str, message: str, tmp_path: Path) -> None:
    path = tmp_path / "design.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(spm.DesignError, match=f"design.toml: {message}") as info:
        spm.SPMDesign.load(path)
    assert str(path) in str(info.value)
    assert info.value.parameter is not None


def test_unreadable_design_files(tmp_path: Path) -> None:
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00 not text")
    for path, message in (
        (tmp_path / "missing.toml", "cannot read design file: No such file or directory"),
        (binary, "design file is not UTF-8 text"),
        (tmp_path, "cannot read design file"),
    ):
        with pytest.raises(spm.FileFormatError, match=f": {message}") as info:
            spm.SPMDesign.load(path)
        assert info.value.path == str(path)


@settings(max_examples=300)
@given(st.text(max_size=200))
def test_arbitrary_text_never_escapes_as_another_error(text: str) -> None:
    try:
        design = spm.SPMDesign.from_toml(text)
    except spm.SPMError as error:
        assert isinstance(error, ValueError)
    else:
        assert isinstance(design, spm.SPMDesign)


_leaf = st.one_of(
    st.integers(-1000, 1000),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
    st.booleans(),
)
_value = st.recursive(
    _leaf,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=5), inner, max_size=3)
    ),
    max_leaves=10,
)


@settings(max_examples=300)
@given(
    st.fixed_dictionaries(
        {
            "kinematics": st.dictionaries(
                st.sampled_from(["alpha1_deg", "alpha2_deg", "beta_deg", "eta_deg", "base_axes"]),
                _value,
            )
        },
        optional={
            "name": st.text(max_size=5),
            "dimensions": st.dictionaries(
                st.sampled_from(["density", "servo_size", "hub_radius", "proximal_radius"]),
                _value,
            ),
        },
    )
)
def test_arbitrary_tables_never_escape_as_another_error(data: dict[str, Any]) -> None:
    try:
        spm.SPMDesign.from_dict(data, source="fuzz.toml")
    except spm.SPMError as error:
        assert isinstance(error, ValueError)
        assert "fuzz.toml" in str(error)
