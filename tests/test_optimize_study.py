"""Design studies (spm_pin.optimize.study, spm optimize) and the peak-torque objective.

The peak torque is checked against Pinocchio's closed-loop inverse dynamics with the
payload added to the model, and its input rates against finite differences of the
inverse kinematics in time; a study's score of the prototype against the direct
computation; a study is deterministic for a seed, resumes where it stopped (exactly
as if it had not), refuses another study's storage, and records designs that cannot
be evaluated as failed trials.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.errors import InputError
from spm_pin.optimize import DesignSpace, Variable, safe_workspace_score
from spm_pin.optimize.objectives import tilt_rotations
from spm_pin.optimize.torque import Payload, cone_motion, motion_inputs, peak_torque

optuna = pytest.importorskip("optuna")

from spm_pin.optimize.study import StudySettings, evaluate, run_study  # noqa: E402

#: Tolerances of this module.
TOL = {
    "torque": 1e-10,  # [N m] reduced + payload against the closed-loop inverse dynamics
    "rate": 1e-7,  # [rad/s] against central differences (h = 1e-5 s)
    "acceleration": 1e-4,  # [rad/s^2] against second differences
}

SPACE = DesignSpace((Variable("alpha1_deg", 35.0, 75.0), Variable("alpha2_deg", 60.0, 120.0)))
PROTOTYPE = {"alpha1_deg": 45.0, "alpha2_deg": 90.0}
OBJECTIVES = ["tilt", "peak_torque"]
FAST = StudySettings(step_deg=8.0, motion_samples=24)


def _study(n: int, **kwargs: object) -> list[tuple[int, str, dict[str, float], dict[str, float]]]:
    result = run_study(SPACE, OBJECTIVES, n, settings=FAST, population_size=4, **kwargs)  # type: ignore[arg-type]
    return [(t.number, t.state, t.values, t.scores) for t in result.trials]


@pytest.mark.parametrize(
    "design", [spm.SPMDesign.prototype(), spm.SPMDesign.coaxial(55.0, 80.0, 90.0, name="o")]
)
def test_peak_torque_equals_the_closed_loop_inverse_dynamics_with_the_payload(
    design: spm.SPMDesign,
) -> None:
    import pinocchio as pin

    from spm_pin.dynamics import ClosedLoopDynamics

    motion = cone_motion(25.0, 1.0, 24)
    inertia = ((2e-4, 1e-5, 0.0), (1e-5, 3e-4, 0.0), (0.0, 0.0, 1e-4))
    payload = Payload(0.3, (0.01, -0.02, 0.05), inertia)
    peak = peak_torque(design, motion, payload)
    # Truth: the payload as a body of the Pinocchio model (on the platform's leg-1
    # end, the platform frame being the world frame at home).
    robot = spm.build_robot(design)
    model = robot.model
    joint = model.frames[robot.end_frames[0]].parentJoint
    data = model.createData()
    pin.forwardKinematics(model, data, robot.configuration(np.zeros(3)))
    body = pin.Inertia(payload.mass, np.array(payload.com), np.array(payload.inertia))
    model.inertias[joint] = model.inertias[joint] + data.oMi[joint].actInv(body)
    truth = ClosedLoopDynamics(robot).inverse(peak.theta, peak.theta_dot, peak.theta_ddot)
    np.testing.assert_allclose(peak.torque, truth.torque, rtol=0.0, atol=TOL["torque"])
    assert peak.peak_nm == pytest.approx(float(np.max(np.abs(truth.torque))), abs=TOL["torque"])
    # A heavier payload needs more torque; none is the robot alone.
    assert peak_torque(design, motion).peak_nm < peak.peak_nm
    # The input rates: finite differences of the inverse kinematics in time.
    _, theta_dot, theta_ddot = motion_inputs(design, motion)
    h = 1e-5
    for k in (3, 10):

        def at(t: float) -> np.ndarray:
            R = tilt_rotations([25.0], [360.0 * t / 1.0])
            return np.asarray(spm.inverse_kinematics(R, design).theta[0])

        t0 = float(motion.time_s[k])
        rate = (at(t0 + h) - at(t0 - h)) / (2 * h)
        acceleration = (at(t0 + h) - 2 * at(t0) + at(t0 - h)) / h**2
        np.testing.assert_allclose(theta_dot[k], rate, atol=TOL["rate"])
        np.testing.assert_allclose(theta_ddot[k], acceleration, atol=TOL["acceleration"])


def test_bad_motion_and_payload_are_input_errors() -> None:
    with pytest.raises(InputError):
        Payload(-1.0)
    with pytest.raises(InputError):
        Payload(1.0, inertia=((1.0, 0, 0), (0, -1.0, 0), (0, 0, 1.0)))
    with pytest.raises(InputError):
        cone_motion(95.0)
    with pytest.raises(InputError):
        cone_motion(20.0, 0.0)


def test_the_study_scores_the_prototype_as_the_direct_computation() -> None:
    settings = StudySettings(step_deg=6.0, motion_samples=24)
    result = run_study(
        SPACE,
        ["tilt", "safe_fraction", "gci", "peak_torque"],
        1,
        settings=settings,
        enqueue=[PROTOTYPE],
    )
    (trial,) = result.trials
    assert trial.values == PROTOTYPE
    score = safe_workspace_score("prototype", step_deg=6.0)
    assert trial.scores["tilt"] == score.safe_tilt_every_direction_deg
    assert trial.scores["safe_fraction"] == score.safe_fraction
    motion = cone_motion(20.0, 2.0, 24)
    assert trial.scores["peak_torque"] == peak_torque("prototype", motion).peak_nm
    assert trial.constraints["home_clearance"] == pytest.approx(
        -spm.build_robot().min_clearance(np.zeros(3)), abs=1e-12
    )
    assert trial.feasible and result.pareto == (trial,)


def test_a_study_is_deterministic_and_resumes_where_it_stopped(tmp_path: Path) -> None:
    first = _study(7, seed=3)
    assert first == _study(7, seed=3)
    assert first != _study(7, seed=4)
    storage = tmp_path / "study.log"
    stopped = run_study(
        SPACE, OBJECTIVES, 3, settings=FAST, population_size=4, seed=3, storage=storage
    )
    assert len(stopped.trials) == 3 and stopped.new_trials == 3
    resumed = run_study(
        SPACE, OBJECTIVES, 7, settings=FAST, population_size=4, seed=3, storage=storage
    )
    assert resumed.new_trials == 4 and resumed.trials[:3] == stopped.trials
    assert [(t.number, t.state, t.values, t.scores) for t in resumed.trials] == first
    # Done: a third run adds nothing.
    again = run_study(
        SPACE, OBJECTIVES, 7, settings=FAST, population_size=4, seed=3, storage=storage
    )
    assert again.new_trials == 0 and again.trials == resumed.trials
    # Another study's file is refused.
    for kwargs in ({"seed": 4}, {"settings": StudySettings(step_deg=4.0)}):
        with pytest.raises(InputError, match="holds another study"):
            run_study(
                SPACE,
                OBJECTIVES,
                8,
                population_size=4,
                storage=storage,
                **{"settings": FAST, "seed": 3, **kwargs},
            )  # type: ignore[arg-type]
    with pytest.raises(InputError, match="objectives"):
        run_study(SPACE, ["tilt"], 8, settings=FAST, seed=3, storage=storage)
    other = DesignSpace((Variable("alpha1_deg", 30.0, 75.0), Variable("alpha2_deg", 60.0, 120.0)))
    with pytest.raises(InputError, match="variables"):
        run_study(other, OBJECTIVES, 8, settings=FAST, population_size=4, seed=3, storage=storage)
    garbage = tmp_path / "garbage.log"
    garbage.write_text("not a journal\n")
    with pytest.raises(InputError):
        run_study(SPACE, OBJECTIVES, 2, settings=FAST, storage=garbage)


def test_designs_that_cannot_be_evaluated_are_failed_trials() -> None:
    # Proximal links as large as the distal ones do not assemble (DesignError).
    space = DesignSpace((Variable("proximal_radius", 0.05, 0.12),))
    result = run_study(space, ["tilt"], 6, settings=FAST, seed=0)
    states = [t.state for t in result.trials]
    assert len(states) == 6 and "FAIL" in states and "COMPLETE" in states
    failed = [t for t in result.trials if t.state == "FAIL"]
    assert all(t.error and t.error.startswith("DesignError") for t in failed)
    assert all(t.values["proximal_radius"] > 0.08 for t in failed)
    assert all(not t.feasible and not t.scores for t in failed)


@pytest.mark.parametrize(
    ("objectives", "n"), [(["nope"], 2), ([], 2), (["tilt", "tilt"], 2), (["tilt"], 0)]
)
def test_bad_study_input_is_an_input_error(objectives: list[str], n: int) -> None:
    with pytest.raises(InputError):
        run_study(SPACE, objectives, n)
    with pytest.raises(InputError):
        DesignSpace(())
    with pytest.raises(InputError):
        evaluate(spm.SPMDesign.prototype(), ["nope"])


def test_spm_optimize_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    storage = str(tmp_path / "cli.log")
    argv = [
        "optimize", "--objectives", "tilt", "peak_torque", "--vary", "alpha1=35:75",
        "alpha2=60:120", "--trials", "4", "--seed", "2", "--step", "8", "--population", "4",
        "--include-base", "--storage", storage, "--json",
    ]  # fmt: skip
    assert main(argv) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["trials"] == 4 and record["new_trials"] == 4
    assert [o["name"] for o in record["objectives"]] == ["tilt", "peak_torque"]
    assert record["pareto"] and all(
        set(t["scores"]) == {"tilt", "peak_torque"} for t in record["pareto"]
    )
    assert any(t["values"] == PROTOTYPE for t in record["pareto"])
    argv[argv.index("4")] = "6"
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["new_trials"] == 2
    space = tmp_path / "space.toml"
    space.write_text("[variables]\nalpha1_deg = [35, 75]\n")
    for bad in (
        ["optimize", "--objectives", "nope", "--vary", "alpha1=35:75"],
        ["optimize", "--vary", "alpha1=35"],
        ["optimize", "--vary", "alpha1=35:75", "--trials", "0"],
        ["optimize"],
        ["optimize", "--space", str(space), "--storage", storage],
    ):
        assert main(bad) == 2
        err = capsys.readouterr().err
        assert err.startswith("spm: error: ") and err.count("\n") == 1


def test_spm_optimize_ctrl_c_keeps_the_study_and_says_so(tmp_path: Path) -> None:
    """Ctrl-C (a real SIGINT to a real ``spm optimize``) ends with one line on stderr,
    no traceback, exit status 130; the finished trials are in the storage, the one
    running is marked failed, and the same command continues the study."""
    import re
    import signal
    import subprocess
    import sys
    import time

    from spm_pin.optimize.results import load_study_result

    storage = tmp_path / "study.log"
    argv = [
        sys.executable, "-m", "spm_pin", "optimize", "--objectives", "tilt",
        "--vary", "alpha1=35:75", "alpha2=60:120", "--step", "8", "--seed", "3",
        "--allow-home-collision", "--quiet", "--storage", str(storage),
    ]  # fmt: skip
    process = subprocess.Popen(
        [*argv, "--trials", "10000"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and process.poll() is None:
            if storage.exists() and len(re.findall(r'"state":\s*1\b', storage.read_text())) >= 2:
                break  # two trials completed (COMPLETE is state 1 in Optuna's journal)
            time.sleep(0.1)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1] == (
        f"spm optimize: interrupted; the finished trials are kept in {storage}: run the "
        "same command again to continue"
    )
    stopped = load_study_result(storage)
    done = len(stopped.trials)
    assert done >= 2
    assert not any(t.state == "RUNNING" for t in stopped.trials)
    resumed = subprocess.run(
        [*argv, "--trials", str(done + 2), "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert resumed.returncode == 0, resumed.stderr
    record = json.loads(resumed.stdout)
    assert record["trials"] == done + 2 and record["new_trials"] == 2


def test_a_general_design_is_optimized_by_the_objectives_that_fit_it(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A base that is not coaxial (the Agile Eye): its base axes and leg azimuths stay,
    its link angles vary; the study scores cone dexterity and the envelope as
    `evaluate` does; the gap-plane objectives are refused with the reason."""
    import dataclasses
    import math

    eye = spm.SPMDesign.agile_eye()
    space = DesignSpace((Variable("alpha2_deg", 80.0, 100.0),), base=eye)
    design = space.design({"alpha2_deg": 85.0}, name="eye-85")
    assert design.base_axes == eye.base_axes and design.eta == eye.eta
    assert design == dataclasses.replace(eye, alpha2=math.radians(85.0), name="eye-85")
    assert space.values_of(design) == pytest.approx({"alpha2_deg": 85.0}, abs=1e-12)
    settings = StudySettings(cone_deg=10.0, require_home_clearance=False)
    result = run_study(space, ["cone_dexterity", "envelope"], 3, settings=settings, seed=1)
    assert len(result.trials) == 3
    for trial in result.trials:
        assert trial.state == "COMPLETE", trial.error
        direct = evaluate(space.design(trial.values), ["cone_dexterity", "envelope"], settings)
        assert trial.scores == direct.scores
    for objectives, extra in ((["tilt"], {}), (["envelope"], {"required_tilt_deg": 20.0})):
        with pytest.raises(InputError, match="not coaxial"):
            run_study(space, objectives, 1, settings=dataclasses.replace(settings, **extra), seed=0)
    argv = [
        "optimize", "--design", "agile_eye", "--vary", "alpha2=80:100", "--objectives",
        "cone_dexterity", "--cone", "10", "--trials", "2", "--allow-home-collision", "--json",
    ]  # fmt: skip
    assert main(argv) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["design"] == "agile_eye" and record["trials"] == 2
    argv[argv.index("cone_dexterity")] = "tilt"
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "not coaxial" in err and err.count("\n") == 1
