"""Design studies against problems with known answers.

The dexterity at home of a coaxial, symmetric design in closed form
(:mod:`spm_pin.optimize.validation`) against the library's Jacobian (its singular
values by LAPACK), and a study of the distal link angle against the closed-form
optimum: the isotropic home pose at alpha2 = 60 deg for alpha1 = 45, beta = 90 deg.
A published optimum: the Agile Eye's isotropic reference configuration (Gosselin and
Angeles 1989), its closed form and a search that finds it; and the prototype's scores
of ``spm optimize`` against ``spm workspace``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.errors import InputError
from spm_pin.optimize import (
    DesignSpace,
    StudySettings,
    Variable,
    cone_dexterity,
    home_dexterity,
    home_dexterity_right_angle,
    isotropic_alpha2,
    run_study,
)
from spm_pin.optimize.validation import (
    find_orthogonal_optimum,
    orthogonal_design,
    orthogonal_reference_dexterity,
    reference_dexterity,
    reference_orientation,
)

pytest.importorskip("optuna")

SEED = 20290


def _design(alpha1_deg: float, alpha2_deg: float, beta_deg: float) -> spm.SPMDesign:
    return dataclasses.replace(
        spm.SPMDesign.prototype(),
        alpha1=math.radians(alpha1_deg),
        alpha2=math.radians(alpha2_deg),
        beta=math.radians(beta_deg),
    )


def _library_dexterity(design: spm.SPMDesign) -> float:
    return float(spm.jacobian(np.zeros(3), design).dexterity)


def test_home_dexterity_in_closed_form_equals_the_jacobian() -> None:
    rng = np.random.default_rng(SEED)
    checked = right = 0
    while checked < 60:
        a1, a2 = rng.uniform(20.0, 85.0), rng.uniform(20.0, 160.0)
        beta = 90.0 if checked % 2 else rng.uniform(50.0, 130.0)
        try:
            design = _design(a1, a2, beta)
            truth = _library_dexterity(design)
        except spm.SPMError:  # not assembled at home
            continue
        checked += 1
        assert home_dexterity(design) == pytest.approx(truth, abs=1e-12), (a1, a2, beta)
        if beta == 90.0:
            right += 1
            formula = home_dexterity_right_angle(math.radians(a1), math.radians(a2))
            assert formula == pytest.approx(truth, abs=1e-12), (a1, a2)
    assert right >= 20


def test_the_isotropic_designs_are_isotropic() -> None:
    low, high = isotropic_alpha2(math.radians(45.0))
    assert math.degrees(low) == pytest.approx(60.0, abs=1e-12)
    assert math.degrees(high) == pytest.approx(120.0, abs=1e-12)
    for alpha1 in (40.0, 45.0, 55.0, 70.0):
        for alpha2 in isotropic_alpha2(math.radians(alpha1)):
            design = _design(alpha1, math.degrees(alpha2), 90.0)
            assert _library_dexterity(design) == pytest.approx(1.0, abs=1e-9)
            # A degree either way is worse: it is the maximum.
            for step in (-1.0, 1.0):
                near = _design(alpha1, math.degrees(alpha2) + step, 90.0)
                assert _library_dexterity(near) < 1.0 - 1e-3


def test_bad_input_is_refused() -> None:
    with pytest.raises(InputError, match="isotropic"):
        isotropic_alpha2(math.radians(30.0))
    with pytest.raises(InputError, match="cannot be assembled"):
        home_dexterity_right_angle(math.radians(45.0), math.radians(30.0))
    with pytest.raises(InputError, match="coaxial"):
        home_dexterity("agile_eye")


@pytest.mark.parametrize("seed", [0, 1])
def test_a_study_finds_the_closed_form_optimum(seed: int) -> None:
    """A study of alpha2 in [50, 85] deg (alpha1 = 45, beta = 90) maximising the
    dexterity at home (``cone_dexterity`` with a cone of 0 deg) lands within 0.5 deg
    of the closed-form optimum, 60 deg."""
    space = DesignSpace((Variable("alpha2_deg", 50.0, 85.0),))
    settings = StudySettings(cone_deg=0.0, require_home_clearance=False)
    result = run_study(space, ["cone_dexterity"], 60, settings=settings, seed=seed)
    best = max(result.pareto, key=lambda trial: trial.scores["cone_dexterity"])
    optimum = math.degrees(isotropic_alpha2(math.radians(45.0))[0])
    assert abs(best.values["alpha2_deg"] - optimum) < 0.5, best
    design = space.design(best.values)
    assert cone_dexterity(design, 0.0).worst_dexterity == pytest.approx(
        best.scores["cone_dexterity"], abs=1e-12
    )
    assert best.scores["cone_dexterity"] == pytest.approx(home_dexterity(design), abs=1e-12)


def _reference_jacobian(design: spm.SPMDesign) -> spm.JacobianResult:
    solution = spm.inverse_kinematics(reference_orientation(design), design)
    assert bool(np.all(solution.reachable)) and solution.mode == "+++"
    return spm.jacobian(solution.theta, design)


def test_the_agile_eye_is_isotropic_at_its_reference_configuration() -> None:
    """The published number (Gosselin and Angeles 1989; the Agile Eye): condition
    number 1 at the reference configuration, where R v_i0 = -u_(i-1). There each input
    turns the platform about its own axis (J = [u_1 u_2 u_3], orthonormal), and the
    forward kinematics of those inputs returns the same rotation."""
    design = spm.SPMDesign.agile_eye()
    rotation = reference_orientation(design)
    assert rotation @ rotation.T == pytest.approx(np.eye(3), abs=1e-12)
    assert np.linalg.det(rotation) == pytest.approx(1.0, abs=1e-12)
    for i in range(3):
        assert rotation @ design.v0[i] == pytest.approx(-design.u[(i - 1) % 3], abs=1e-12)
    result = _reference_jacobian(design)
    np.testing.assert_allclose(result.J, design.u.T, rtol=0.0, atol=1e-12)
    assert float(result.dexterity) == pytest.approx(1.0, abs=1e-12)
    assert reference_dexterity("agile_eye") == pytest.approx(1.0, abs=1e-12)
    back = spm.forward_kinematics(spm.inverse_kinematics(rotation, design).theta, design)
    np.testing.assert_allclose(back.R, rotation, rtol=0.0, atol=1e-10)
    # orthogonal_design(90, 90) is the preset's kinematics
    built = orthogonal_design(90.0, 90.0)
    assert built.u == pytest.approx(design.u, abs=1e-15)
    assert built.w0 == pytest.approx(design.w0, abs=1e-12)
    assert built.v0 == pytest.approx(design.v0, abs=1e-15)


def test_the_reference_dexterity_in_closed_form_equals_the_jacobian() -> None:
    """The circulant closed form against the library's Jacobian (LAPACK singular
    values) on random link angles; y's sign is the leg's working mode:
    y = w_i . u_(i+1) = -h b_ii with h the handedness of the base triad."""
    rng = np.random.default_rng(SEED)
    handedness = np.sign(np.linalg.det(spm.SPMDesign.agile_eye().u))
    checked = 0
    while checked < 40:
        a1, a2 = rng.uniform(50.0, 130.0, size=2)
        if math.sin(math.radians(a1)) ** 2 - math.cos(math.radians(a2)) ** 2 < 0.05:
            continue
        result = _reference_jacobian(orthogonal_design(float(a1), float(a2)))
        y_sign = -handedness * np.sign(result.b[0])
        formula = orthogonal_reference_dexterity(math.radians(a1), math.radians(a2), y_sign)
        assert formula == pytest.approx(float(result.dexterity), abs=1e-9), (a1, a2)
        other = orthogonal_reference_dexterity(math.radians(a1), math.radians(a2), -y_sign)
        assert abs(other - formula) > 1e-3 or abs(a1 - 90.0) < 1.0, (a1, a2)
        checked += 1


def test_the_whole_line_alpha1_90_is_isotropic_and_nothing_else() -> None:
    for alpha2 in (50.0, 65.0, 80.0, 90.0, 105.0, 130.0):
        assert reference_dexterity(orthogonal_design(90.0, alpha2)) == pytest.approx(1.0, abs=1e-9)
        for alpha1 in (88.0, 92.0):
            assert reference_dexterity(orthogonal_design(alpha1, alpha2)) < 0.97


@pytest.mark.parametrize("seed", [0, 1])
def test_a_search_finds_the_published_optimum(seed: int) -> None:
    """Optuna's TPE over both link angles in [60, 120] deg finds alpha1 = 90 deg (the
    Agile Eye's) within half a degree, with a dexterity above 0.99."""
    alpha1, alpha2, dexterity = find_orthogonal_optimum(80, seed=seed)
    assert abs(alpha1 - 90.0) < 0.5, (alpha1, alpha2, dexterity)
    assert dexterity > 0.99
    assert dexterity == pytest.approx(
        reference_dexterity(orthogonal_design(alpha1, alpha2)), abs=1e-15
    )


def test_the_reference_configuration_refuses_other_arrangements() -> None:
    with pytest.raises(InputError, match="not mutually orthogonal"):
        reference_orientation("prototype")
    with pytest.raises(InputError, match="y_sign"):
        orthogonal_reference_dexterity(math.pi / 2, math.pi / 2, 0.5)
    with pytest.raises(InputError, match="reach the reference"):
        orthogonal_reference_dexterity(math.radians(30.0), math.radians(30.0))
    for bad in (float("nan"), True, 180.0, "90"):
        with pytest.raises(InputError, match="alpha1_deg"):
            orthogonal_design(bad, 90.0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="n_trials"):
        find_orthogonal_optimum(0)
    for bounds in ((90.0,), (120.0, 60.0), ("a", "b"), (math.nan, 90.0)):
        with pytest.raises(InputError, match="n_trials"):
            find_orthogonal_optimum(5, bounds_deg=bounds)  # type: ignore[arg-type]


def test_the_prototype_scores_of_spm_optimize_equal_spm_workspace(
    tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    """The two commands a user runs: the prototype's workspace scores in the report of
    ``spm optimize --out`` equal the summary of ``spm workspace`` on the same grid."""
    out = tmp_path / "study"
    study = [
        "optimize",
        "--objectives", "tilt", "max_tilt", "safe_fraction",
        "--vary", "alpha2=85:95",
        "--trials", "1",
        "--step", "2",
        "--allow-home-collision",
        "--quiet",
        "--out", str(out),
    ]  # fmt: skip
    assert main(study) == 0
    capsys.readouterr()
    workspace = ["workspace", "--no-clearance", "--no-plots", "--quiet", "--json"]
    assert main([*workspace, "--out", str(tmp_path / "map")]) == 0
    summary = json.loads(capsys.readouterr().out)
    scores = json.loads((out / "report.json").read_text())["prototype"]["scores"]
    assert summary["step_deg"] == 2.0 and summary["design"] == "prototype"
    assert scores["safe_fraction"] == summary["safe_fraction"]
    assert scores["max_tilt"] == summary["max_safe_tilt_deg"]
    assert scores["tilt"] == summary["safe_tilt_every_direction_deg"]
    assert 0.2 < scores["safe_fraction"] < 0.3 and 40.0 < scores["max_tilt"] < 55.0


def test_spm_optimize_lands_on_the_closed_form_optimum(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The command line, as a user runs it, on the closed-form problem: the best
    alpha2 within 0.5 deg of 60 (alpha1 = 45, beta = 90: the prototype's)."""
    argv = [
        "optimize", "--objectives", "cone_dexterity", "--cone", "0", "--vary",
        "alpha2=50:85", "--trials", "60", "--seed", "0", "--allow-home-collision",
        "--quiet", "--json",
    ]  # fmt: skip
    assert main(argv) == 0
    record = json.loads(capsys.readouterr().out)
    (best,) = record["pareto"]
    optimum = math.degrees(isotropic_alpha2(math.radians(45.0))[0])
    assert abs(best["values"]["alpha2_deg"] - optimum) < 0.5, best
    assert best["scores"]["cone_dexterity"] > 0.99
