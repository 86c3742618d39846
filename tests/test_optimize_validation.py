"""Design studies against problems with known answers.

The dexterity at home of a coaxial, symmetric design in closed form
(:mod:`spm_pin.optimize.validation`) against the library's Jacobian (its singular
values by LAPACK), and a study of the distal link angle against the closed-form
optimum: the isotropic home pose at alpha2 = 60 deg for alpha1 = 45, beta = 90 deg.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import spm_pin as spm
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
