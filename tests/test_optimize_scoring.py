"""Fast scoring of a design's safe orientation workspace: equal, point by point and in
its figures, to the workspace map that ``spm workspace`` computes with the same
settings (the prototype and two other coaxial designs, with and without a margin);
bad input; the base package does not import the optimization package."""

from __future__ import annotations

import subprocess
import sys
from typing import Any

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.errors import InputError
from spm_pin.optimize import WorkspaceScore, safe_workspace_score
from spm_pin.workspace import WorkspaceMap, WorkspaceSettings, workspace_map

#: Tolerances of this module.
TOL = {
    "figure": 0.0,  # the score's figures against the map's (the same computations)
}

#: Designs and settings compared with a map: name -> (design, step [deg], margin [m],
#: min dexterity).
CASES: dict[str, tuple[spm.SPMDesign, float, float, float]] = {
    "prototype": (spm.SPMDesign.prototype(), 2.0, 0.0, 0.2),
    "prototype-margin": (spm.SPMDesign.prototype(), 4.0, 0.0005, 0.3),
    "a1-55-a2-80": (spm.SPMDesign.coaxial(55.0, 80.0, 90.0, name="a1-55-a2-80"), 3.0, 0.0, 0.2),
    "a1-40-a2-100-b-80": (
        spm.SPMDesign.coaxial(40.0, 100.0, 80.0, name="a1-40-a2-100-b-80"),
        3.0,
        0.0002,
        0.1,
    ),
}

#: The figures a score shares with a map's summary.
FIGURES = (
    "points",
    "reachable_fraction",
    "safe_fraction",
    "max_safe_tilt_deg",
    "safe_tilt_every_direction_deg",
    "margin_m",
    "min_dexterity",
)

_RESULTS: dict[str, tuple[WorkspaceScore, WorkspaceMap]] = {}


def _both(name: str) -> tuple[WorkspaceScore, WorkspaceMap]:
    """The score and the map of a case (computed once)."""
    if name not in _RESULTS:
        design, step, margin, dexterity = CASES[name]
        score = safe_workspace_score(design, step_deg=step, margin=margin, min_dexterity=dexterity)
        settings = WorkspaceSettings(margin=margin, min_dexterity=dexterity, clearance=False)
        full = workspace_map(design, step_deg=step, settings=settings, progress=False)
        _RESULTS[name] = (score, full)
    return _RESULTS[name]


@pytest.mark.parametrize("name", list(CASES))
def test_score_equals_the_map_point_by_point(name: str) -> None:
    score, full = _both(name)
    f = full.fields
    assert score.points == len(full)
    np.testing.assert_array_equal(score.d12_deg, f["d12_deg"])
    np.testing.assert_array_equal(score.d23_deg, f["d23_deg"])
    np.testing.assert_array_equal(score.reachable, f["reachable"])
    np.testing.assert_array_equal(score.safe, f["safe"])
    for field in ("dexterity", "tilt_deg", "azimuth_deg", "torsion_deg"):
        np.testing.assert_allclose(
            getattr(score, field), f[field], rtol=0.0, atol=TOL["figure"], err_msg=field
        )
    # The cases are not trivial: part of the plane is safe, part collides.
    assert 0 < np.count_nonzero(score.safe) < np.count_nonzero(score.reachable)
    assert np.any(f["collision"] & f["reachable"])
    # Only points that pass the kinematic checks were checked for collision.
    checked = score.reachable & (np.nan_to_num(score.dexterity, nan=-1.0) >= score.min_dexterity)
    assert score.collision_checks == np.count_nonzero(checked) < score.points


@pytest.mark.parametrize("name", list(CASES))
def test_score_figures_equal_the_map_summary(name: str) -> None:
    score, full = _both(name)
    expected: dict[str, Any] = full.summary()
    got = score.summary()
    assert list(got) == list(FIGURES)
    for key in FIGURES:
        assert got[key] == expected[key], key
    assert got["max_safe_tilt_deg"] is not None
    assert score.safe_fraction == got["safe_fraction"]
    assert score.seconds > 0.0


def test_prototype_figures() -> None:
    """The prototype's figures (notes of the release: about 24 % safe, 48 and 32 deg)."""
    score, _ = _both("prototype")
    assert score.safe_fraction == pytest.approx(0.24, abs=0.01)
    assert score.max_safe_tilt_deg == pytest.approx(48.0, abs=1.0)
    assert score.safe_tilt_every_direction_deg == pytest.approx(32.0, abs=1.0)


def test_defaults_are_those_of_spm_workspace() -> None:
    score, _ = _both("prototype")
    again = safe_workspace_score()
    assert (again.step_deg, again.margin, again.min_dexterity) == (2.0, 0.0, 0.2)
    np.testing.assert_array_equal(again.safe, score.safe)
    assert again.summary() == score.summary()


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"design": spm.SPMDesign.agile_eye()}, "design"),
        ({"design": "no-such-design"}, "design"),
        ({"step_deg": 0.0}, "step_deg"),
        ({"step_deg": float("nan")}, "step_deg"),
        ({"step_deg": "2"}, "step_deg"),
        ({"margin": -0.001}, "margin"),
        ({"margin": float("inf")}, "margin"),
        ({"margin": True}, "margin"),
        ({"min_dexterity": 1.5}, "min_dexterity"),
        ({"min_dexterity": None}, "min_dexterity"),
    ],
)
def test_bad_input(kwargs: dict[str, Any], argument: str) -> None:
    design = kwargs.pop("design", None)
    with pytest.raises(InputError) as info:
        safe_workspace_score(design, **kwargs)
    if argument != "design" or isinstance(design, spm.SPMDesign):
        assert info.value.argument == argument


def test_spm_pin_does_not_import_optimize() -> None:
    code = "import sys, spm_pin; print('spm_pin.optimize' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.strip() == "False"
