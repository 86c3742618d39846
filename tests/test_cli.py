"""The ``spm`` command: values against the library, round trips, and one-line errors."""

from __future__ import annotations

import contextlib
import html
import io
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import spm_pin as spm
from spm_pin import demo
from spm_pin.cli import FK_SOLVERS, FKSolution, main
from spm_pin.demo import DEMO_SECTIONS
from spm_pin.rotations import (
    matrix_from_quaternion,
    matrix_from_rpy,
    quaternion_from_matrix,
    rpy_from_matrix,
)
from spm_pin.study.pictures import INSTALL_PICTURES

#: Tolerances, by what they compare.
TOL = {
    "json": 1e-12,  # a value printed as JSON against the library's own value
    "round_trip_deg": 1e-9,  # fk then ik gives back the input [deg]
    "text": 1e-6,  # a value printed as text (6 decimals)
    "residual": 1e-12,  # closure residual of a solution
    # spm demo: MuJoCo's platform axes against the analytic ones, upright (its welds
    # yield under gravity): the demo's acceptance bound MUJOCO_TOLERANCE["gravity"] of
    # docs/demo.md's snippet, 1e-4, over ten times the 8e-6 docs/demo.md measures and
    # below the study's 4e-4.
    "mujoco": 1e-4,
}

THETA_DEG = [60.0, 90.0, 120.0]  # the published study's demonstration input
COLLIDING_DEG = [60.0, 90.0, 220.0]  # the study's colliding input: no home assembly


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def run_json(capsys: pytest.CaptureFixture[str], *argv: str) -> Any:
    status, out, err = run(capsys, *argv, "--json")
    assert status == 0, err
    assert err == ""

    def no_constants(name: str) -> None:
        raise AssertionError(f"JSON output contains {name}")

    return json.loads(out, parse_constant=no_constants)


def matrix_args(R: np.ndarray) -> list[str]:
    return ["--matrix", *(repr(float(x)) for x in np.asarray(R).ravel())]


# ------------------------------------------------------------------------------- fk
def test_fk_json_matches_library(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(capsys, "fk", *map(str, THETA_DEG))
    theta = np.radians(THETA_DEG)
    fk = spm.forward_kinematics(theta)
    jac = spm.jacobian(theta)
    atol = TOL["json"]
    assert out["reachable"] is True
    assert out["theta_deg"] == THETA_DEG
    assert out["mode"] == "+++/-"
    assert out["home"] is True
    np.testing.assert_allclose(out["R"], fk.R, atol=atol)
    np.testing.assert_allclose(out["v"], fk.v, atol=atol)
    np.testing.assert_allclose(out["J"], jac.J, atol=atol)
    np.testing.assert_allclose(out["b"], jac.b, atol=atol)
    np.testing.assert_allclose(out["det_a"], jac.det_a, atol=atol)
    np.testing.assert_allclose(out["dexterity"], jac.dexterity, atol=atol)
    np.testing.assert_allclose(out["dexterity_ga"], jac.dexterity_ga, atol=atol)
    np.testing.assert_allclose(out["singularity_margin"], jac.singularity_margin, atol=atol)
    assert out["type_i_singular"] is False
    assert out["type_ii_singular"] is False
    assert out["residual"] < TOL["residual"]
    # rpy and quaternion describe the same R.
    rpy = np.radians(out["rpy_deg"])
    np.testing.assert_allclose(matrix_from_rpy(rpy), fk.R, atol=atol)
    quaternion = out["quaternion_wxyz"]
    np.testing.assert_allclose(matrix_from_quaternion(quaternion), fk.R, atol=atol)


def test_fk_text_is_aligned(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, err = run(capsys, "fk", "60", "90", "120")
    assert status == 0
    assert err == ""
    lines = {line.split()[0]: line for line in out.splitlines() if line and line[0] != " "}
    assert lines["reachable"].split()[1] == "true"
    assert lines["mode"].split()[1] == "+++/-"
    # Numbers have 6 decimals and are right-aligned in the same columns.
    assert lines["theta_deg"].split()[1:] == ["60.000000", "90.000000", "120.000000"]
    columns = {key: [m.end() for m in re.finditer(r"\d\.\d{6}", lines[key])] for key in lines}
    assert columns["theta_deg"] == columns["R"] == columns["b"] == columns["J"]
    rows = out.splitlines()
    first = next(i for i, line in enumerate(rows) if line.startswith("R "))
    printed = [line.split()[-3:] for line in rows[first : first + 3]]
    fk = spm.forward_kinematics(np.radians(THETA_DEG))
    np.testing.assert_allclose(np.array(printed, dtype=float), fk.R, atol=TOL["text"])


@pytest.mark.parametrize("theta", [["-30", "20", "10"], ["-1e-3", "-.5", "-7"], ["720", "0", "-0"]])
def test_fk_negative_and_odd_numbers(capsys: pytest.CaptureFixture[str], theta: list[str]) -> None:
    out = run_json(capsys, "fk", *theta)
    expected = [float(t) for t in theta]
    assert out["theta_deg"] == expected
    fk = spm.forward_kinematics(np.radians(expected))
    np.testing.assert_allclose(out["R"], fk.R, atol=TOL["json"])


def test_fk_unreachable_is_an_answer(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(capsys, "fk", *map(str, COLLIDING_DEG))
    assert out["reachable"] is False
    assert out["R"] is None
    assert out["J"] is None
    status, text, err = run(capsys, "fk", *map(str, COLLIDING_DEG))
    assert status == 0
    assert err == ""
    assert any(line.split() == ["reachable", "false"] for line in text.splitlines())
    assert not any(line.startswith("R ") for line in text.splitlines())


def test_fk_all_matches_library(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(capsys, "fk", *map(str, THETA_DEG), "--all")
    every = spm.forward_kinematics_all(np.radians(THETA_DEG))
    assert out["count"] == int(every.count) == len(out["modes"])
    assert [m["label"] for m in out["modes"]] == every.labels[: out["count"]]
    assert out["count"] == 8  # the study's input: eight modes, eight distinct labels
    assert len({m["label"] for m in out["modes"]}) == 8
    assert [m["home"] for m in out["modes"]].count(True) == 1
    for k, mode in enumerate(out["modes"]):
        assert set(mode) == {"index", "label", "home", "R", "v", "b", "det_a", "residual"}
        assert mode["index"] == k
        np.testing.assert_allclose(mode["R"], every.R[k], atol=TOL["json"])
        np.testing.assert_allclose(mode["v"], every.v[k], atol=TOL["json"])
        np.testing.assert_allclose(mode["b"], every.b[k], atol=TOL["json"])
        assert mode["home"] == bool(every.home[k])
    # Without a home mode, the other modes are still listed.
    out = run_json(capsys, "fk", *map(str, COLLIDING_DEG), "--all")
    assert out["reachable"] is False
    assert out["count"] > 0
    assert not any(m["home"] for m in out["modes"])


def test_fk_keys_do_not_depend_on_reachability(capsys: pytest.CaptureFixture[str]) -> None:
    reachable = run_json(capsys, "fk", "0", "0", "0")
    unreachable = run_json(capsys, "fk", *map(str, COLLIDING_DEG))
    assert list(reachable) == list(unreachable)
    assert reachable["solver"] == "analytic"


def test_fk_solver_table_is_the_extension_point(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A solver added to FK_SOLVERS is selectable and yields the same keys; mode and
    home are derived from its R (here: a non-home assembly mode)."""
    every = spm.forward_kinematics_all(np.radians(THETA_DEG))
    other = int(np.argmin(every.home))  # a valid slot that is not the home mode

    def second_mode(theta: np.ndarray, design: spm.SPMDesign) -> FKSolution:
        modes = spm.forward_kinematics_all(theta, design)
        return FKSolution(R=modes.R[other], residual=float(modes.residual[other]))

    monkeypatch.setitem(FK_SOLVERS, "second", second_mode)
    analytic = run_json(capsys, "fk", *map(str, THETA_DEG))
    second = run_json(capsys, "fk", *map(str, THETA_DEG), "--solver", "second")
    assert list(second) == list(analytic)
    assert second["solver"] == "second"
    assert second["mode"] == every.labels[other]
    assert second["home"] is False
    np.testing.assert_allclose(second["R"], every.R[other], atol=TOL["json"])
    np.testing.assert_allclose(second["b"], every.b[other], atol=TOL["json"])
    np.testing.assert_allclose(second["det_a"], every.det_a[other], atol=TOL["json"])


# ------------------------------------------------------------------------------- ik
def test_ik_of_fk_gives_back_theta(capsys: pytest.CaptureFixture[str]) -> None:
    R = spm.forward_kinematics(np.radians(THETA_DEG)).R
    out = run_json(capsys, "ik", *matrix_args(R))
    assert out["reachable"] is True
    assert out["mode"] == "+++"
    assert out["home"] is True
    np.testing.assert_allclose(out["theta_deg"], THETA_DEG, atol=TOL["round_trip_deg"])
    assert all(b > 0 for b in out["b"])
    # The same orientation as a quaternion and as roll/pitch/yaw [deg].
    quaternion = [repr(float(x)) for x in quaternion_from_matrix(R)]
    rpy = [repr(float(x)) for x in np.degrees(rpy_from_matrix(R))]
    for given_as in (["--quaternion", *quaternion], ["--rpy", *rpy]):
        other = run_json(capsys, "ik", *given_as)
        np.testing.assert_allclose(other["theta_deg"], THETA_DEG, atol=TOL["round_trip_deg"])


def test_ik_modes_match_library(capsys: pytest.CaptureFixture[str]) -> None:
    R = matrix_from_rpy(np.radians([10.0, -20.0, 30.0]))
    every = spm.inverse_kinematics_all(R)
    out = run_json(capsys, "ik", "--rpy", "10", "-20", "30", "--all")
    assert out["reachable"] is True
    assert [m["label"] for m in out["modes"]] == list(every.labels)
    np.testing.assert_allclose(
        [m["theta_deg"] for m in out["modes"]], np.degrees(every.theta), atol=TOL["json"]
    )
    # A mode by label (even one starting with '-') and by index.
    for label in ("-+-", "--+"):
        index = every.labels.index(label)
        by_label = run_json(capsys, "ik", "--rpy", "10", "-20", "30", "--mode", label)
        by_index = run_json(capsys, "ik", "--rpy", "10", "-20", "30", "--mode", str(index))
        assert by_label == by_index
        assert by_label["mode"] == label
        np.testing.assert_allclose(
            by_label["theta_deg"], np.degrees(every.theta[index]), atol=TOL["json"]
        )


def test_ik_unreachable_exits_2_naming_every_failing_leg(
    capsys: pytest.CaptureFixture[str],
) -> None:
    for rpy in (["0", "100", "0"], ["0", "80", "0"]):
        R = matrix_from_rpy(np.radians([float(x) for x in rpy]))
        reach = spm.inverse_kinematics(R[None]).leg_reachable[0]
        failing = [i + 1 for i in range(3) if not reach[i]]
        assert failing, rpy
        for extra in ([], ["--json"], ["--all"]):
            status, text, err = run(capsys, "ik", "--rpy", *rpy, *extra)
            assert status == 2 and text == ""
            assert err.startswith("spm: error: ") and err.count("\n") == 1
            named = "leg " + str(failing[0]) if len(failing) == 1 else "legs "
            assert named in err
            for leg in failing:
                assert str(leg) in err.split("cannot close")[0].split("of design")[1]
    # 80 deg pitch: legs 2 and 3 both fail, and both are named
    status, _, err = run(capsys, "ik", "--rpy", "0", "80", "0")
    assert "legs 2 and 3 cannot close" in err


def test_mode_numbers_agree_between_all_and_mode(capsys: pytest.CaptureFixture[str]) -> None:
    """Text and JSON number the modes as --mode INDEX does (from 0)."""
    out = run_json(capsys, "ik", "--rpy", "10", "-20", "30", "--all")
    assert [m["index"] for m in out["modes"]] == list(range(8))
    status, text, _ = run(capsys, "ik", "--rpy", "10", "-20", "30", "--all")
    assert status == 0 and "modes[0]:" in text and "modes[7]:" in text
    assert "modes[8]:" not in text
    for m in out["modes"]:
        single = run_json(capsys, "ik", "--rpy", "10", "-20", "30", "--mode", str(m["index"]))
        assert single["mode"] == m["label"] and single["index"] == m["index"]
    every = run_json(capsys, "fk", *map(str, COLLIDING_DEG), "--all")
    assert [m["index"] for m in every["modes"]] == list(range(every["count"]))


# --------------------------------------------------------------------------- design
def same_design(a: spm.SPMDesign, b: spm.SPMDesign) -> None:
    """Equal up to the rounding of radians -> degrees -> radians in the TOML file."""
    assert a.name == b.name
    assert a.dimensions == b.dimensions
    for field in ("alpha1", "alpha2", "beta", "eta", "base_axes"):
        np.testing.assert_allclose(getattr(a, field), getattr(b, field), atol=TOL["json"])


def test_design_round_trip(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    status, out, _ = run(capsys, "design")
    assert status == 0
    same_design(spm.SPMDesign.from_toml(out), spm.SPMDesign.prototype())
    path = tmp_path / "f.toml"
    status, _, err = run(capsys, "design", "--preset", "agile_eye", "--out", str(path))
    assert status == 0, err
    same_design(spm.SPMDesign.load(path), spm.SPMDesign.agile_eye())
    out_json = run_json(capsys, "fk", "0", "0", "0", "--design", str(path))
    assert out_json["design"] == "agile_eye"
    assert out_json["reachable"] is True
    np.testing.assert_allclose(out_json["R"], np.eye(3), atol=TOL["json"])
    status, out, _ = run(capsys, "design", "--design", str(path))
    assert status == 0
    same_design(spm.SPMDesign.from_toml(out), spm.SPMDesign.agile_eye())


# ----------------------------------------------------------------------------- demo
def test_demo_mujoco_bound_is_no_looser_than_documented() -> None:
    """The demo's own acceptance bound on MuJoCo's axes keeps the documented figure."""
    assert TOL["mujoco"] >= demo.MUJOCO_TOLERANCE["gravity"]


def test_demo_text(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """``spm demo --quick``: the study in text, progress on stderr, the report written.
    (tests/test_demo.py checks the default run's numbers and files in depth.)"""
    directory = tmp_path / "new" / "dir"
    # no browser for the scenes' pictures (a Chromium that is not there): the demo
    # goes on and says so in one line (tests/test_demo.py checks the pictures)
    missing = tmp_path / "no-chromium"
    status, out, err = run(
        capsys, "demo", "--quick", "--out", str(directory), "--chromium", str(missing)
    )
    assert status == 0, err
    notes = [line for line in out.splitlines() if line.startswith("No pictures")]
    reason = f"(no Chromium at {re.escape(repr(str(missing)))}|Playwright is not installed)"
    assert len(notes) == 1
    assert re.fullmatch(
        f"No pictures of the 3-D scenes: {reason}. They need Playwright and a Chromium: "
        f"{re.escape(INSTALL_PICTURES)}.",
        notes[0],
    )
    report = (directory / "index.html").read_text(encoding="utf-8")
    assert report.count(html.escape(notes[0])) == 1
    assert report.count("<iframe") == 3 and not list(directory.glob("scenes/*.png"))
    for section in (
        "Forward kinematics at theta = [60, 90, 120] deg, three ways",
        "Every real assembly mode",
        "The motion from home to that input, 25 samples",
        "The colliding input [60, 90, 220] deg",
        "The safe workspace (10-degree grid",
        "Actuator torques along the motion",
    ):
        assert f"== {section}" in out
    assert re.search(r"^all_home\s+true$", out, re.MULTILINE)
    assert re.search(r"^pairs\s+proximal_2-proximal_3", out, re.MULTILINE)
    assert f"report: {directory / 'index.html'}" in out
    assert "Skipped" not in out
    # one progress line per section on stderr, none on stdout
    assert err.count("spm demo [") == len(DEMO_SECTIONS)
    assert "spm demo [" not in out
    # the platform axes printed side by side are the library's
    fk = spm.forward_kinematics(np.radians(THETA_DEG))
    for i in range(3):
        row = re.search(rf"^v_{i + 1}\s+(.*)$", out, re.MULTILINE)
        assert row is not None
        numbers = np.array(row.group(1).split(), dtype=float).reshape(-1, 3)
        assert numbers.shape == (3, 3)  # analytic, projection, MuJoCo
        np.testing.assert_allclose(numbers, np.broadcast_to(fk.v[i], (3, 3)), atol=TOL["mujoco"])
        np.testing.assert_allclose(numbers[:2], np.broadcast_to(fk.v[i], (2, 3)), atol=TOL["text"])
    data = json.loads((directory / "demo.json").read_text())
    assert data["theta_deg"] == THETA_DEG
    assert data["colliding_input"]["theta_deg"] == COLLIDING_DEG
    assert data["colliding_input"]["home_mode_exists"] is False
    assert data["workspace"]["step_deg"] == 10.0
    assert data["report"]["pictures"] == {} and data["report"]["pictures_note"] in out
    assert data["skipped"] == []


# --------------------------------------------------------------------------- errors
def _bad_files(tmp_path: Path) -> dict[str, Path]:
    files = {
        "malformed": "[kinematics\nalpha1_deg = 45\n",
        "incomplete": "[kinematics]\nalpha1_deg = 45\n",
        "impossible": "[kinematics]\nalpha1_deg = 45\nalpha2_deg = 190\nbeta_deg = 90\n",
    }
    paths = {}
    for name, text in files.items():
        paths[name] = tmp_path / f"{name}.toml"
        paths[name].write_text(text)
    return paths


BAD_ARGUMENTS = [
    [],
    ["bogus"],
    ["fk", "1", "2"],
    ["fk", "1", "2", "3", "4"],
    ["fk", "nan", "0", "0"],
    ["fk", "-inf", "0", "0"],
    ["fk", "a", "b", "c"],
    ["fk", "0", "0", "0", "--bogus"],
    ["fk", "0", "0", "0", "--solver", "nope"],
    ["fk", "0", "0", "0", "--design", "missing.toml"],
    ["fk", "0", "0", "0", "--design", "{malformed}"],
    ["fk", "0", "0", "0", "--design", "{incomplete}"],
    ["fk", "0", "0", "0", "--design", "{impossible}"],
    ["fk", "0", "0", "0", "--design", "{tmp}"],
    ["ik"],
    ["ik", "--matrix", "1", "0", "0", "0", "1", "0", "0", "0", "2"],
    ["ik", "--matrix", "1", "0", "0", "0", "1", "0", "0", "0", "-1"],
    ["ik", "--matrix", "1", "0", "0"],
    ["ik", "--quaternion", "0", "0", "0", "0"],
    ["ik", "--rpy", "0", "0", "0", "--quaternion", "1", "0", "0", "0"],
    ["ik", "--rpy", "0", "0", "0", "--mode", "9"],
    ["ik", "--rpy", "0", "0", "0", "--mode", "+*+"],
    ["ik", "--rpy", "0", "0", "0", "--mode", "1", "--all"],
    ["design", "--preset", "nope"],
    ["design", "--preset", "prototype", "--design", "x.toml"],
    ["design", "--out", "{tmp}/no/such/dir/f.toml"],
    ["demo", "--out", "{malformed}"],
    ["demo", "--workspace-step", "0"],
    ["demo", "--workspace-step", "nan"],
    ["demo", "--bogus"],
]


@pytest.mark.parametrize("argv", BAD_ARGUMENTS, ids=" ".join)
def test_bad_arguments_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, argv: list[str]
) -> None:
    names = {name: str(path) for name, path in _bad_files(tmp_path).items()}
    argv = [arg.format(tmp=tmp_path, **names) for arg in argv]
    status, out, err = run(capsys, *argv)
    assert status == 2
    assert out == ""
    assert err.startswith("spm: error: ")
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    assert "usage:" not in err


def test_help_and_version(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = run(capsys, "--help")
    assert status == 0
    assert "fk" in out and "demo" in out
    status, out, _ = run(capsys, "--version")
    assert status == 0
    assert spm.__version__ in out


@settings(max_examples=60, deadline=None)
@given(st.lists(st.text(min_size=1, max_size=8), min_size=3, max_size=3))
def test_any_words_as_angles(words: list[str]) -> None:
    """Whatever the user types, fk answers (status 0) or says why not (status 2)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["fk", *words, "--json"])

    def finite(word: str) -> bool:
        try:
            return math.isfinite(float(word))
        except ValueError:
            return False

    if status == 0 and not out.getvalue().startswith("{"):
        assert "usage:" in out.getvalue()  # a word that abbreviates --help
    elif status == 0:
        assert all(finite(w) for w in words)
        assert json.loads(out.getvalue())["theta_deg"] == [float(w) for w in words]
    else:
        assert status == 2
        assert err.getvalue().startswith("spm: error: ")
        assert err.getvalue().count("\n") == 1


# ----------------------------------------------------------------------- subprocess
def run_module(*argv: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``python -m spm_pin ...`` in a fresh interpreter that imports this checkout."""
    root = str(Path(spm.__file__).resolve().parent.parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    return subprocess.run(
        [sys.executable, "-m", "spm_pin", *argv],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=cwd,
        env=env,
    )


def test_python_m_spm_pin(tmp_path: Path) -> None:
    result = run_module("fk", "60", "90", "120", "--json", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    fk = spm.forward_kinematics(np.radians(THETA_DEG))
    np.testing.assert_allclose(out["R"], fk.R, atol=TOL["json"])
    bad = run_module("fk", "1", "2", cwd=tmp_path)
    assert bad.returncode == 2
    assert bad.stderr.startswith("spm: error: ")
    assert bad.stderr.count("\n") == 1
    assert "Traceback" not in bad.stderr


# ------------------------------------------------------------------- designs by name
def test_fk_with_a_preset_name(capsys: pytest.CaptureFixture[str]) -> None:
    design = spm.SPMDesign.agile_eye()
    for theta_deg in (THETA_DEG, [10.0, -20.0, 30.0]):
        out = run_json(capsys, "fk", *map(str, theta_deg), "--design", "agile_eye")
        assert out["design"] == "agile_eye"
        fk = spm.forward_kinematics(np.radians(theta_deg), design)
        assert out["reachable"] is True
        np.testing.assert_allclose(out["R"], fk.R, atol=TOL["json"])
    assert run_json(capsys, "fk", "0", "0", "0", "--design", "Agile-Eye")["design"] == "agile_eye"
    assert run_json(capsys, "fk", "0", "0", "0", "--design", "prototype")["design"] == "prototype"


def test_collide_agile_eye_at_home(capsys: pytest.CaptureFixture[str]) -> None:
    out = run_json(capsys, "collide", "0", "0", "0", "--design", "agile_eye")
    assert out["design"] == "agile_eye"
    assert out["collision"] is False
    assert out["pairs"] == []
    assert out["min_distance_m"] > 0.01


def test_design_name_against_a_file_named_like_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A bare preset name is the preset; ./NAME or NAME.toml is the file."""
    spm.SPMDesign.coaxial(50.0, 75.0, 100.0, name="mine").save(tmp_path / "agile_eye")
    monkeypatch.chdir(tmp_path)
    assert run_json(capsys, "fk", "0", "0", "0", "--design", "agile_eye")["design"] == "agile_eye"
    assert run_json(capsys, "fk", "0", "0", "0", "--design", "./agile_eye")["design"] == "mine"


def test_bad_design_name_lists_the_presets(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    status, out, err = run(capsys, "fk", "0", "0", "0", "--design", "agile")
    assert status == 2
    assert out == ""
    assert err.startswith("spm: error: ") and err.count("\n") == 1
    assert "'agile'" in err and "not a file" in err
    assert all(name in err for name in spm.SPMDesign.preset_names())
    status, out, _ = run(capsys, "fk", "-h")
    assert status == 0
    assert "NAME|FILE" in out and "agile_eye" in out


@pytest.mark.parametrize("command", ["show", "animate"])
def test_view_option_reaches_the_page(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, command: str
) -> None:
    pytest.importorskip("meshcat")
    target = tmp_path / f"{command}.html"
    where = ["60", "90", "120"] if command == "show" else ["--to", "60", "90", "120"]
    for view in ("iso", "top"):
        extra = [] if view == "iso" else ["--view", view]  # iso is the default
        status, _, err = run(capsys, command, *where, "--html", str(target), *extra)
        assert status == 0, err
        text = target.read_text(encoding="utf-8")
        opened = re.search(r"var view = (.*?);\n", text)
        assert opened is not None and json.loads(opened.group(1)) == view
        assert '<ul id="spm-key">' in text
    status, _, err = run(capsys, command, *where, "--html", str(target), "--view", "diagonal")
    assert status == 2
    assert "--view: invalid choice: 'diagonal' (choose from 'iso', 'top', 'front', 'side')" in err


def test_ctrl_c_is_one_line_and_status_130(tmp_path: Path) -> None:
    """A real SIGINT to a long ``spm workspace``: one line on stderr, no traceback."""
    import signal
    import subprocess
    import time

    process = subprocess.Popen(
        [sys.executable, "-m", "spm_pin", "workspace", "--step", "0.25", "--no-plots",
         "--out", str(tmp_path / "map")],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        time.sleep(4.0)  # past the imports, into the map
        assert process.poll() is None
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert "Traceback" not in err
    assert err.rstrip().splitlines()[-1].endswith("spm: interrupted")
