"""SPMDesign: presets, the home configuration it derives, TOML save/load."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import DESIGN_NAMES, get_design
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import spm_pin as spm

#: Tolerances of this module.
TOL = {
    # Home geometry recomputed here [unit-vector components, dot products].
    "geometry": 1e-14,
    # Angles after a TOML round trip [rad]: the file holds degrees to 12 decimals.
    "toml_angle": 2e-14,
    # Base axes after a TOML round trip (normalised again on load).
    "toml_axis": 1e-15,
    # Orthogonality of the Agile Eye's axes (its angle is kept to 12 decimals in degrees).
    "agile_eye": 1e-13,
    # Kinematics of a design loaded back vs the original [max |R - R'|].
    "toml_kinematics": 1e-12,
}

PRESETS = ("prototype", "agile_eye")


def _same_design(loaded: spm.SPMDesign, original: spm.SPMDesign) -> None:
    """Equal up to the rounding of the angles (TOML stores degrees, 12 decimals) and the
    last bit of the base axes."""
    for name in ("alpha1", "alpha2", "beta"):
        np.testing.assert_allclose(
            getattr(loaded, name), getattr(original, name), rtol=0, atol=TOL["toml_angle"]
        )
    np.testing.assert_allclose(loaded.eta, original.eta, rtol=0, atol=TOL["toml_angle"])
    np.testing.assert_allclose(loaded.base_axes, original.base_axes, rtol=0, atol=TOL["toml_axis"])
    assert loaded.dimensions == original.dimensions
    assert loaded.name == original.name


# ------------------------------------------------------------------- presets
def test_prototype_parameters() -> None:
    d = spm.SPMDesign.prototype()
    assert d.name == "prototype"
    np.testing.assert_allclose(
        np.degrees([d.alpha1, d.alpha2, d.beta]), [45.0, 90.0, 90.0], atol=1e-12
    )
    np.testing.assert_allclose(np.degrees(d.eta), [0.0, 120.0, 240.0], atol=1e-12)
    np.testing.assert_array_equal(d.u, np.tile([0.0, 0.0, -1.0], (3, 1)))
    assert d.is_coaxial
    assert d == spm.SPMDesign.preset("prototype")
    # docs/conventions.md: w_i0 = [sin a1 cos eta_i, sin a1 sin eta_i, -cos a1],
    # v_i0 = [sin b cos(eta_i - 90), sin b sin(eta_i - 90), cos b].
    eta = np.radians([0.0, 120.0, 240.0])
    a1, b = math.radians(45.0), math.radians(90.0)
    w0 = np.stack([math.sin(a1) * np.cos(eta), math.sin(a1) * np.sin(eta), -np.full(3, 0.5**0.5)])
    v0 = np.stack(
        [
            math.sin(b) * np.cos(eta - np.pi / 2),
            math.sin(b) * np.sin(eta - np.pi / 2),
            np.full(3, math.cos(b)),
        ]
    )
    np.testing.assert_allclose(d.w0, w0.T, atol=TOL["geometry"])
    np.testing.assert_allclose(d.v0, v0.T, atol=TOL["geometry"])
    np.testing.assert_allclose(d.home_det_a, -0.919, atol=5e-4)
    np.testing.assert_allclose(d.platform_combination, (-1.0, -1.0, 0.0), atol=1e-12)


def test_agile_eye_is_orthogonal() -> None:
    d = spm.SPMDesign.agile_eye()
    assert d == spm.SPMDesign.preset("agile_eye")
    assert not d.is_coaxial
    np.testing.assert_allclose(d.u @ d.u.T, np.eye(3), atol=TOL["agile_eye"])
    np.testing.assert_allclose(d.v0 @ d.v0.T, np.eye(3), atol=TOL["agile_eye"])
    np.testing.assert_allclose([d.alpha1, d.alpha2], [math.pi / 2] * 2, atol=1e-15)


def test_coaxial_constructor() -> None:
    d = spm.SPMDesign.coaxial(50.0, 75.0, 100.0)
    np.testing.assert_allclose(
        [d.alpha1, d.alpha2, d.beta], np.radians([50.0, 75.0, 100.0]), atol=1e-15
    )
    assert d.is_coaxial and d.name == "coaxial"
    assert not get_design("general").is_coaxial


@pytest.mark.parametrize("name", DESIGN_NAMES)
def test_home_configuration(name: str) -> None:
    """w_i0 is at alpha1 from u_i and alpha2 from v_i0, on the b_ii > 0 side;
    home_det_a is det of the rows w_i0 x v_i0."""
    d = get_design(name)
    for array in (d.u, d.w0, d.v0):
        np.testing.assert_allclose(np.linalg.norm(array, axis=1), 1.0, atol=TOL["geometry"])
    np.testing.assert_allclose(np.sum(d.u * d.w0, axis=1), math.cos(d.alpha1), atol=1e-14)
    np.testing.assert_allclose(np.sum(d.w0 * d.v0, axis=1), math.cos(d.alpha2), atol=1e-14)
    np.testing.assert_allclose(d.v0[:, 2], math.cos(d.beta), atol=1e-15)
    azimuth = np.arctan2(d.v0[:, 1], d.v0[:, 0])
    np.testing.assert_allclose(
        np.mod(azimuth - (np.asarray(d.eta) - np.pi / 2) + np.pi, 2 * np.pi) - np.pi, 0, atol=1e-12
    )
    assert np.all(np.sum(np.cross(d.u, d.w0) * d.v0, axis=1) > 0)
    np.testing.assert_allclose(d.home_det_a, np.linalg.det(np.cross(d.w0, d.v0)), atol=1e-15)
    a, b, c = d.platform_combination
    v0 = d.v0
    np.testing.assert_allclose(
        a * v0[0] + b * v0[1] + c * np.cross(v0[0], v0[1]), v0[2], atol=1e-14
    )
    # The derived arrays are read-only.
    with pytest.raises(ValueError, match="read-only"):
        d.w0[0, 0] = 1.0
    assert name in d.summary() or d.name in d.summary()


def test_designs_are_frozen_and_hashable() -> None:
    d = spm.SPMDesign.prototype()
    with pytest.raises(dataclasses.FrozenInstanceError, match="cannot assign to field 'alpha1'"):
        d.alpha1 = 1.0  # type: ignore[misc]
    assert hash(d) == hash(spm.SPMDesign.prototype())
    assert d != spm.SPMDesign.coaxial(45.0, 90.0, 91.0)


def test_base_axes_are_normalised() -> None:
    d = spm.SPMDesign(
        alpha1=math.radians(45.0),
        alpha2=math.pi / 2,
        beta=math.pi / 2,
        base_axes=((0.0, 0.0, -2.0),) * 3,
    )
    np.testing.assert_array_equal(d.u, np.tile([0.0, 0.0, -1.0], (3, 1)))
    assert d.is_coaxial


# ----------------------------------------------------------------------- TOML
@pytest.mark.parametrize("name", DESIGN_NAMES)
def test_toml_round_trip(name: str, tmp_path: Path) -> None:
    design = get_design(name)
    path = design.save(tmp_path / f"{name}.toml")
    assert path == tmp_path / f"{name}.toml"
    loaded = spm.SPMDesign.load(path)
    _same_design(loaded, design)
    # Stable from then on, exactly.
    assert spm.SPMDesign.from_toml(loaded.to_toml()) == loaded
    assert spm.SPMDesign.from_toml(design.to_toml()) == loaded
    theta = np.random.default_rng(1).uniform(-np.pi, np.pi, (200, 3))
    ours = spm.forward_kinematics_all(theta, design)
    theirs = spm.forward_kinematics_all(theta, loaded)
    np.testing.assert_array_equal(theirs.count, ours.count)
    np.testing.assert_allclose(theirs.R, ours.R, atol=TOL["toml_kinematics"])


@pytest.mark.parametrize("name", [*PRESETS, "coaxial_50_75_100"])
def test_toml_round_trip_is_exact_for_designs_in_degrees(name: str, tmp_path: Path) -> None:
    design = get_design(name)
    assert spm.SPMDesign.load(design.save(tmp_path / "design.toml")) == design


def test_toml_round_trip_is_exact_for_unnormalised_base_axes() -> None:
    """(1, 0, -1) normalises to 0.7071067811865475...; normalising that again on load
    once gave ...476 (the loaded design was not == the saved one)."""
    design = spm.SPMDesign(
        alpha1=math.radians(60.0),
        alpha2=math.radians(80.0),
        beta=math.radians(70.0),
        base_axes=((1.0, 0.0, -1.0), (0.0, 0.0, -1.0), (0.0, 0.0, -1.0)),
    )
    assert spm.SPMDesign.from_toml(design.to_toml()) == design


def test_toml_text_is_readable() -> None:
    text = spm.SPMDesign.prototype().to_toml()
    assert text.startswith("#")
    assert "[kinematics]" in text and "[dimensions]" in text
    assert "alpha1_deg = 45.0" in text
    minimal = "[kinematics]\nalpha1_deg = 45\nalpha2_deg = 90\nbeta_deg = 90\n"
    loaded = spm.SPMDesign.from_toml(minimal)
    assert dataclasses.replace(loaded, name="prototype") == spm.SPMDesign.prototype()


angles_deg = st.floats(min_value=1.0, max_value=179.0, allow_nan=False)


# Many random parameter sets are not assemblable designs (assume() rejects them).
@settings(max_examples=150, suppress_health_check=[HealthCheck.filter_too_much])
@given(
    alpha1=angles_deg,
    alpha2=angles_deg,
    beta=angles_deg,
    eta2=st.floats(min_value=60.0, max_value=170.0),
    eta3=st.floats(min_value=190.0, max_value=300.0),
    tilt=st.lists(st.floats(min_value=0.0, max_value=60.0), min_size=3, max_size=3),
    name=st.text(max_size=20),
)
def test_toml_round_trip_over_valid_parameters(
    alpha1: float,
    alpha2: float,
    beta: float,
    eta2: float,
    eta3: float,
    tilt: list[float],
    name: str,
) -> None:
    eta = np.radians([0.0, eta2, eta3])
    axes = tuple(
        (
            math.sin(math.radians(g)) * math.cos(e),
            math.sin(math.radians(g)) * math.sin(e),
            -math.cos(math.radians(g)),
        )
        for g, e in zip(tilt, eta, strict=True)
    )
    try:
        design = spm.SPMDesign(
            alpha1=math.radians(alpha1),
            alpha2=math.radians(alpha2),
            beta=math.radians(beta),
            eta=tuple(eta),
            base_axes=axes,
            name=name,
        )
    except spm.DesignError as error:
        assert error.parameter is not None
        assume(False)
    loaded = spm.SPMDesign.from_toml(design.to_toml())
    _same_design(loaded, design)
    assert loaded.base_axes == design.base_axes  # unit vectors are kept bit for bit
    _same_design(spm.SPMDesign.from_toml(loaded.to_toml()), design)
    np.testing.assert_allclose(loaded.w0, design.w0, atol=1e-12)
    np.testing.assert_allclose(loaded.home_det_a, design.home_det_a, atol=1e-12)


# Many random angle triples are not assemblable designs (assume() rejects them).
@settings(max_examples=150, suppress_health_check=[HealthCheck.filter_too_much])
@given(
    alpha1=angles_deg,
    alpha2=angles_deg,
    beta=angles_deg,
    decimals=st.integers(min_value=0, max_value=9),
)
def test_toml_round_trip_is_exact_over_coaxial_designs(
    alpha1: float, alpha2: float, beta: float, decimals: int
) -> None:
    """Coaxial designs given in degrees (up to 9 decimals) come back == the original."""
    parameters = [round(x, decimals) for x in (alpha1, alpha2, beta)]
    try:
        design = spm.SPMDesign.coaxial(*parameters)
    except spm.DesignError as error:
        assert error.parameter is not None
        assume(False)
    assert spm.SPMDesign.from_toml(design.to_toml()) == design


# ------------------------------------------------------------- designs by name
@pytest.mark.parametrize(
    ("spec", "name"),
    [
        ("prototype", "prototype"),
        ("agile_eye", "agile_eye"),
        ("Agile_Eye", "agile_eye"),
        ("AGILE-EYE", "agile_eye"),
        ("agile-eye", "agile_eye"),
        ("PROTOTYPE", "prototype"),
        (None, "prototype"),
    ],
)
def test_from_spec_names_presets(spec: str | None, name: str) -> None:
    """A preset name in any case, with - for _, gives the preset; None the prototype."""
    assert spm.SPMDesign.from_spec(spec) == spm.SPMDesign.preset(name)
    if spec is not None:
        assert spm.SPMDesign.preset(spec) == spm.SPMDesign.preset(name)
    assert spm.SPMDesign.preset_names() == PRESETS


def test_from_spec_passes_a_design_through() -> None:
    design = spm.SPMDesign.coaxial(50.0, 75.0, 100.0)
    assert spm.SPMDesign.from_spec(design) is design


def test_from_spec_loads_files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    design = spm.SPMDesign.coaxial(50.0, 75.0, 100.0, name="mine")
    path = design.save(tmp_path / "mine.toml")
    assert spm.SPMDesign.from_spec(path) == design  # a Path
    assert spm.SPMDesign.from_spec(str(path)) == design  # a str
    # A bare name that is no preset but an existing file is that file.
    design.save(tmp_path / "mine")
    monkeypatch.chdir(tmp_path)
    assert spm.SPMDesign.from_spec("mine") == design
    assert spm.SPMDesign.from_spec("mine.toml") == design


def test_from_spec_a_file_named_like_a_preset(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A bare preset name is the preset even if a file of that name exists; a path with
    a directory part or a suffix is the file."""
    mine = spm.SPMDesign.coaxial(50.0, 75.0, 100.0, name="mine")
    mine.save(tmp_path / "agile_eye")
    mine.save(tmp_path / "prototype.toml")
    monkeypatch.chdir(tmp_path)
    assert spm.SPMDesign.from_spec("agile_eye") == spm.SPMDesign.agile_eye()
    assert spm.SPMDesign.from_spec(Path("agile_eye")) == spm.SPMDesign.agile_eye()
    assert spm.SPMDesign.from_spec("./agile_eye") == mine
    assert spm.SPMDesign.from_spec(str(tmp_path / "agile_eye")) == mine
    assert spm.SPMDesign.from_spec("prototype") == spm.SPMDesign.prototype()
    assert spm.SPMDesign.from_spec("prototype.toml") == mine


def test_from_spec_bad_name_lists_the_presets(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    match = r"unknown design 'agile': not a preset \(prototype, agile_eye\) and not a file"
    with pytest.raises(spm.DesignError, match=match) as info:
        spm.SPMDesign.from_spec("agile")
    message = str(info.value)
    assert "'agile'" in message and "not a file either" in message
    assert all(name in message for name in PRESETS)
    assert info.value.parameter == "design"
    with pytest.raises(spm.FileFormatError, match="cannot read design file"):
        spm.SPMDesign.from_spec("agile.toml")  # a file name: the file is missing
    with pytest.raises(spm.DesignError, match="agile_eye"):
        spm.SPMDesign.preset("agile")
    with pytest.raises(spm.InputError, match="design") as bad:
        spm.SPMDesign.from_spec(42)  # type: ignore[arg-type]
    assert bad.value.argument == "design"


def test_kinematics_take_a_preset_name() -> None:
    """Every function that takes a design takes a preset name as well."""
    theta = np.radians([10.0, -20.0, 30.0])
    by_name = spm.inverse_kinematics(np.eye(3), "agile_eye")
    by_design = spm.inverse_kinematics(np.eye(3), spm.SPMDesign.agile_eye())
    np.testing.assert_array_equal(by_name.theta, by_design.theta)
    np.testing.assert_array_equal(
        spm.jacobian(theta, "Agile-Eye").J, spm.jacobian(theta, spm.SPMDesign.agile_eye()).J
    )
    with pytest.raises(spm.DesignError, match="prototype"):
        spm.jacobian(theta, "no_such_design")
    with pytest.raises(spm.InputError, match="design"):
        spm.jacobian(theta, 3.0)  # type: ignore[arg-type]


def test_agile_eye_home() -> None:
    """The Agile Eye's base triad stands 100 deg clockwise of the platform's at home
    (u_i at azimuth eta_i - 100 deg), with the prototype's link sizes."""
    d = spm.SPMDesign.agile_eye()
    azimuth = np.arctan2(d.u[:, 1], d.u[:, 0])
    expected = np.asarray(d.eta) - np.radians(100.0)
    np.testing.assert_allclose(
        np.mod(azimuth - expected + np.pi, 2 * np.pi) - np.pi, 0.0, atol=1e-14
    )
    assert d.dimensions == spm.LinkDimensions()
    # The study's input is reachable in the home assembly mode.
    assert spm.forward_kinematics(np.radians([60.0, 90.0, 120.0]), d).reachable
