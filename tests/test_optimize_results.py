"""The results of a design study (spm_pin.optimize.results, spm optimize --out).

The Pareto set written is checked against a brute-force non-domination filter over
the trials read back from the Optuna storage itself; the design files against the
project's loader, the study's own designs and the command line; the prototype's scores
in the report against the objective functions called directly; the plot against the
trials it draws; the page against the designs it shows.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import math
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.errors import InputError, SPMError
from spm_pin.optimize import DesignSpace, Variable, safe_workspace_score
from spm_pin.optimize.torque import cone_motion, peak_torque

optuna = pytest.importorskip("optuna")

from spm_pin.optimize.results import (  # noqa: E402
    best_trials,
    load_study_result,
    pareto_figure,
    write_results,
)
from spm_pin.optimize.study import (  # noqa: E402
    OBJECTIVES,
    STUDY_NAME,
    StudyResult,
    StudySettings,
    TrialRecord,
    run_study,
)

#: Tolerances of this module.
TOL = {
    "angle": 1e-12,  # [rad] a design file's angles (stored in degrees to 12 decimals)
    "clearance": 1e-12,  # [m] the home clearance constraint against the robot's own
    "mesh": 1e-9,  # [m] a scene's vertices against the design's link meshes
}

SPACE = DesignSpace((Variable("alpha1_deg", 35.0, 75.0), Variable("alpha2_deg", 60.0, 120.0)))
PROTOTYPE = {"alpha1_deg": 45.0, "alpha2_deg": 90.0}
OBJECTIVES_2 = ["safe_fraction", "peak_torque"]
FAST = StudySettings(step_deg=8.0, motion_samples=24)
BEST = 3
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def storage(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("study") / "study.log"


@pytest.fixture(scope="module")
def study(storage: Path) -> StudyResult:
    """A tiny two-objective study, the prototype first (about 5 s)."""
    return run_study(
        SPACE,
        OBJECTIVES_2,
        8,
        settings=FAST,
        population_size=4,
        seed=1,
        storage=storage,
        enqueue=[PROTOTYPE],
    )


@pytest.fixture(scope="module")
def written(study: StudyResult, tmp_path_factory: pytest.TempPathFactory) -> Any:
    return write_results(study, tmp_path_factory.mktemp("results") / "out", best=BEST)


def _report(written: Any) -> dict[str, Any]:
    report: dict[str, Any] = json.loads(written.report_json.read_text(encoding="utf-8"))
    return report


def _record(number: int, scores: dict[str, float], feasible: bool = True) -> TrialRecord:
    return TrialRecord(
        number=number,
        state="COMPLETE",
        values={"alpha1_deg": 40.0 + number},
        scores=scores,
        constraints={"home_clearance": -1.0 if feasible else 1.0},
        feasible=feasible,
        error=None,
    )


def _synthetic(
    names: list[str], points: Sequence[Sequence[float]], front: list[int]
) -> StudyResult:
    """A StudyResult without a study (for what does not read the storage)."""
    trials = tuple(
        _record(k, dict(zip(names, p, strict=True)), feasible=k % 5 != 4)
        for k, p in enumerate(points)
    )
    return StudyResult(
        study=None,
        objectives=tuple(OBJECTIVES[n] for n in names),
        trials=trials,
        pareto=tuple(trials[k] for k in front),
        new_trials=0,
        seconds=0.0,
    )


# ------------------------------------------------------------------ the Pareto set
def _brute_force_front(storage: Path) -> set[int]:
    """The feasible completed trials that no other one dominates, read from the storage
    with Optuna alone, compared pair by pair in plain Python."""
    from optuna.storages.journal import JournalFileBackend, JournalStorage
    from optuna.trial import TrialState

    stored = optuna.load_study(
        study_name=STUDY_NAME, storage=JournalStorage(JournalFileBackend(str(storage)))
    )
    signs = [1.0 if OBJECTIVES[n].direction == "maximize" else -1.0 for n in OBJECTIVES_2]
    points = {
        t.number: [s * v for s, v in zip(signs, t.values, strict=True)]
        for t in stored.get_trials(states=(TrialState.COMPLETE,))
        if all(c <= 0.0 for c in t.user_attrs["constraints"])
    }

    def dominates(a: list[float], b: list[float]) -> bool:
        return all(x >= y for x, y in zip(a, b, strict=True)) and any(
            x > y for x, y in zip(a, b, strict=True)
        )

    return {n for n, p in points.items() if not any(dominates(q, p) for q in points.values())}


def test_the_pareto_set_written_is_the_brute_force_front(
    study: StudyResult, written: Any, storage: Path
) -> None:
    report = _report(written)
    truth = _brute_force_front(storage)
    assert truth and {t["number"] for t in report["pareto"]} == truth
    assert {t.number for t in study.pareto} == truth
    # The designs written: at most BEST of the front, best first by the first objective.
    best = report["best"]
    assert 1 <= len(best) == min(BEST, len(truth))
    assert {b["number"] for b in best} <= truth
    first = [b["scores"]["safe_fraction"] for b in best]
    assert first == sorted(first, reverse=True)
    assert [b["file"] for b in best] == [f"best_{k}.toml" for k in range(1, len(best) + 1)]
    # Read back from the storage alone, the study gives the same report.
    again = load_study_result(storage)
    assert again.trials == study.trials and again.pareto == study.pareto


def test_best_trials_spread_along_a_longer_front() -> None:
    # Seven points on a front (safe_fraction up, peak_torque up), two dominated.
    points = [(0.1 * k, 0.01 * k) for k in range(7)] + [(0.05, 0.5), (0.2, 0.9)]
    result = _synthetic(["safe_fraction", "peak_torque"], points, front=list(range(7)))
    assert [t.number for t in best_trials(result, 3)] == [6, 3, 0]
    assert [t.number for t in best_trials(result, 1)] == [6]
    assert [t.number for t in best_trials(result, 10)] == [6, 5, 4, 3, 2, 1, 0]
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="best"):
            best_trials(result, bad)  # type: ignore[arg-type]


# ------------------------------------------------------------------ design files
def test_the_design_files_load_as_the_study_s_designs(written: Any) -> None:
    report = _report(written)
    assert [p.name for p in written.designs] == report["files"]["designs"]
    for entry, path in zip(report["best"], written.designs, strict=True):
        expected = SPACE.design(entry["values"])
        for loaded in (spm.SPMDesign.load(path), spm.SPMDesign.from_spec(str(path))):
            assert loaded.name == f"trial-{entry['number']}" == entry["name"]
            for angle in ("alpha1", "alpha2", "beta"):
                np.testing.assert_allclose(
                    getattr(loaded, angle), getattr(expected, angle), rtol=0, atol=TOL["angle"]
                )
            np.testing.assert_allclose(loaded.eta, expected.eta, rtol=0, atol=TOL["angle"])
            assert loaded.base_axes == expected.base_axes
            assert loaded.dimensions == expected.dimensions
        assert entry["values"]["alpha1_deg"] == pytest.approx(
            math.degrees(spm.SPMDesign.load(path).alpha1), abs=1e-9
        )


def test_the_command_line_takes_a_design_file_written(
    written: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    path = written.designs[0]
    design = spm.SPMDesign.load(path)
    assert main(["fk", "10", "20", "30", "--design", str(path), "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["design"] == design.name
    truth = spm.forward_kinematics(np.radians([10.0, 20.0, 30.0]), design)
    np.testing.assert_allclose(record["R"], truth.R, atol=1e-12)
    # spm ik at the orientation fk found gives the inputs back.
    matrix = [repr(float(x)) for x in np.asarray(truth.R).ravel()]
    assert main(["ik", "--matrix", *matrix, "--design", str(path), "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["design"] == design.name
    np.testing.assert_allclose(record["theta_deg"], [10.0, 20.0, 30.0], atol=1e-9)


# ------------------------------------------------------------------ the report
def test_the_report_scores_the_prototype_as_the_objectives_do(
    study: StudyResult, written: Any
) -> None:
    report = _report(written)
    prototype = report["prototype"]
    assert prototype["name"] == "prototype" and prototype["error"] is None
    assert prototype["values"] == PROTOTYPE
    score = safe_workspace_score("prototype", step_deg=FAST.step_deg)
    assert prototype["scores"]["safe_fraction"] == score.safe_fraction
    motion = cone_motion(FAST.motion_tilt_deg, FAST.motion_period_s, FAST.motion_samples)
    assert prototype["scores"]["peak_torque"] == peak_torque("prototype", motion).peak_nm
    clearance = spm.build_robot().min_clearance(np.zeros(3))
    assert prototype["constraints"]["home_clearance"] == pytest.approx(
        -clearance, abs=TOL["clearance"]
    )
    assert prototype["feasible"] is True
    # The prototype was the study's trial 0: the same scores.
    assert study.trials[0].values == PROTOTYPE
    assert study.trials[0].scores == prototype["scores"]
    # The study's settings.
    assert [o["name"] for o in report["objectives"]] == OBJECTIVES_2
    assert [o["unit"] for o in report["objectives"]] == ["1", "N m"]
    assert report["settings"] == dataclasses.asdict(FAST)
    assert report["seed"] == 1 and report["population_size"] == 4
    assert report["variables"] == [["alpha1_deg", 35.0, 75.0], ["alpha2_deg", 60.0, 120.0]]
    assert report["constraints"] == ["home_clearance"]
    counts = report["trials"]
    assert counts["total"] == len(study.trials) == 8
    assert counts["complete"] + counts["failed"] == 8
    # Every file named is there; nothing was skipped.
    files = report["files"]
    names = [files["pareto_png"], files["designs_html"], files["report_json"], *files["designs"]]
    assert sorted(names) == sorted(p.name for p in written.files)
    assert all((written.directory / n).is_file() for n in names)
    assert report["notes"] == []


# ------------------------------------------------------------------ the plot
def _collections(axis: Any) -> dict[str, np.ndarray]:
    return {c.get_label(): np.asarray(c.get_offsets()) for c in axis.collections}


def test_the_plot_draws_every_completed_trial_and_the_front(
    study: StudyResult, written: Any
) -> None:
    data = written.pareto_png.read_bytes()
    assert data.startswith(PNG_SIGNATURE) and len(data) > 10_000
    import matplotlib.image

    pixels = matplotlib.image.imread(written.pareto_png)
    assert pixels.shape[:2] == (550, 770)  # 7 x 5 in at 110 dpi
    report = _report(written)
    prototype = report["prototype"]["scores"]
    figure = pareto_figure(study, prototype_scores=prototype, marked=best_trials(study, BEST))
    (axis,) = figure.axes
    drawn = _collections(axis)
    complete = [t for t in study.trials if t.state == "COMPLETE"]
    assert len(drawn["Pareto front"]) == len(study.pareto)
    assert sum(len(drawn.get(k, ())) for k in ("Pareto front", "other feasible", "infeasible")) == (
        len(complete)
    )
    front = sorted((t.scores["safe_fraction"], t.scores["peak_torque"]) for t in study.pareto)
    np.testing.assert_array_equal(sorted(map(tuple, drawn["Pareto front"])), front)
    np.testing.assert_array_equal(
        drawn["prototype"], [[prototype["safe_fraction"], prototype["peak_torque"]]]
    )
    assert axis.get_xlabel().startswith("safe_fraction [1]")
    assert axis.get_ylabel().startswith("peak_torque [N m]")
    assert {a.get_text() for a in axis.texts} == {f"#{b['number']}" for b in report["best"]}
    assert len(axis.lines) == (1 if len(study.pareto) > 1 else 0)  # the front, joined


def test_three_objectives_make_a_grid_of_pairs_and_one_a_history() -> None:
    names = ["safe_fraction", "max_tilt", "peak_torque"]
    points = [(0.1 * k, 3.0 * k, 0.01 * k) for k in range(6)]
    result = _synthetic(names, points, front=[0, 1, 2, 3])
    figure = pareto_figure(result, prototype_scores=dict(zip(names, (0.3, 9.0, 0.05), strict=True)))
    shown = [a for a in figure.axes if a.axison]
    assert len(figure.axes) == 4 and len(shown) == 3  # the lower triangle of 2 x 2
    pairs = {(a.get_xlabel().split()[0], a.get_ylabel().split()[0]) for a in shown}
    assert pairs == {
        ("safe_fraction", "max_tilt"),
        ("safe_fraction", "peak_torque"),
        ("max_tilt", "peak_torque"),
    }
    for axis in shown:
        drawn = _collections(axis)
        assert len(drawn["Pareto front"]) == 4 and len(drawn["prototype"]) == 1
        assert len(drawn["other feasible"]) + len(drawn["infeasible"]) == 2
        assert not axis.lines  # a projection of the front is no front: not joined
    single = _synthetic(["max_tilt"], [(float(k),) for k in range(5)], front=[3])
    (axis,) = pareto_figure(single, prototype_scores={"max_tilt": 2.0}).axes
    assert axis.get_xlabel() == "trial number" and axis.get_ylabel().startswith("max_tilt [deg]")
    np.testing.assert_array_equal(_collections(axis)["Pareto front"], [[3.0, 3.0]])


# ------------------------------------------------------------------ the page
def test_the_page_shows_one_scene_per_design(written: Any) -> None:
    import umsgpack

    from spm_pin.model import LINK_NAMES, link_meshes

    page = written.designs_html.read_text(encoding="utf-8")
    report = _report(written)
    assert page.count('class="spm-design"') == len(report["best"]) + 1  # + the prototype
    match = re.search(r'<script type="application/json" id="spm-scenes">(.*?)</script>', page)
    assert match is not None
    scenes = json.loads(match.group(1))
    assert len(scenes) == len(report["best"]) + 1
    assert page.count("new MeshCat.Viewer(") == 1 and "window.spm_scene_ready = true" in page
    designs = [spm.SPMDesign.load(p) for p in written.designs] + [spm.SPMDesign.prototype()]
    for index, (scene, design) in enumerate(zip(scenes, designs, strict=True)):
        assert f'id="spm-pane-{index}"' in page
        commands = [umsgpack.unpackb(base64.b64decode(item)) for item in scene]
        objects = {c["path"]: c["object"] for c in commands if c["type"] == "set_object"}
        meshes = link_meshes(design)
        for link in LINK_NAMES:
            (path,) = [p for p in objects if p.endswith(f"/{link}/free")]
            array = objects[path]["geometries"][0]["data"]["attributes"]["position"]["array"]
            vertices = np.frombuffer(array.data if hasattr(array, "data") else array, "<f4")
            np.testing.assert_allclose(
                np.sort(vertices),
                np.sort(meshes[link].smooth_shaded.vertices.astype("<f4").ravel()),
                atol=TOL["mesh"],
            )
    assert "prototype (reference): alpha1_deg 45, alpha2_deg 90" in page


def test_missing_plot_and_page_libraries_are_notes_not_crashes(
    study: StudyResult, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "spm_pin.viz", None)
    monkeypatch.setitem(sys.modules, "matplotlib.backends.backend_agg", None)
    files = write_results(study, tmp_path / "out", best=1)
    notes = files.report["notes"]
    assert files.pareto_png is None and files.designs_html is None
    assert any(n.startswith("pareto.png skipped") and "matplotlib" in n for n in notes)
    assert any(n.startswith("designs.html skipped") and "meshcat" in n for n in notes)
    assert files.report["files"]["pareto_png"] is None
    assert files.report["files"]["designs_html"] is None
    assert len(files.designs) == 1 and files.designs[0].is_file()


# ------------------------------------------------------------------ bad input
def test_a_study_without_a_completed_trial_is_an_input_error(
    study: StudyResult, tmp_path: Path
) -> None:
    with pytest.raises(InputError, match="no completed trial"):
        write_results(dataclasses.replace(study, trials=(), pareto=()), tmp_path / "a")
    # Proximal links as large as the distal ones do not assemble: every trial fails.
    space = DesignSpace((Variable("proximal_radius", 0.095, 0.12),))
    failed = run_study(space, ["tilt"], 2, settings=FAST)
    assert [t.state for t in failed.trials] == ["FAIL", "FAIL"]
    with pytest.raises(InputError, match=r"no completed trial \(2 failed; the first: Design"):
        write_results(failed, tmp_path / "b")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    with pytest.raises(InputError, match="StudyResult"):
        write_results(42, tmp_path / "c")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="best"):
        write_results(study, tmp_path / "d", best=0)


def test_an_unwritable_folder_or_a_bad_storage_is_an_spm_error(
    study: StudyResult, tmp_path: Path
) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder\n")
    for out in (blocker, blocker / "sub"):
        with pytest.raises(SPMError, match="cannot make the results folder"):
            write_results(study, out)
    with pytest.raises(InputError, match="no such file"):
        load_study_result(tmp_path / "missing.log")
    garbage = tmp_path / "garbage.log"
    garbage.write_text("not a journal\n")
    with pytest.raises(InputError, match="holds no spm study"):
        write_results(garbage, tmp_path / "out")


# ------------------------------------------------------------------ spm optimize --out
def test_spm_optimize_writes_the_results(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    storage = str(tmp_path / "cli.log")
    out = tmp_path / "results"
    argv = [
        "optimize", "--objectives", "max_tilt", "--vary", "alpha1=35:75", "--trials", "3",
        "--step", "8", "--include-base", "--storage", storage, "--out", str(out), "--best",
        "2", "--json",
    ]  # fmt: skip
    assert main(argv) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["out"] == str(out) and record["notes"] == []
    names = sorted(Path(f).name for f in record["files"])
    assert {"pareto.png", "designs.html", "report.json", "best_1.toml"} <= set(names)
    assert all(Path(f).is_file() for f in record["files"])
    report = json.loads((out / "report.json").read_text(encoding="utf-8"))
    assert len(report["best"]) <= 2 and report["seed"] == 0
    # The study is done: run again in text, to another folder; nothing new is run.
    argv[argv.index(str(out))] = str(tmp_path / "again")
    argv.remove("--json")
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert f"files to {tmp_path / 'again'}:" in text and "best_1.toml" in text
    assert spm.SPMDesign.load(tmp_path / "again" / "best_1.toml").name.startswith("trial-")
    blocker = tmp_path / "a_file"
    blocker.write_text("x\n")
    for bad in (
        [*argv[:-4], "--out", str(blocker / "sub")],
        [*argv[:-4], "--out", str(tmp_path / "x"), "--best", "0"],
    ):
        assert main(bad) == 2
        err = capsys.readouterr().err
        assert err.startswith("spm: error: ") and err.count("\n") == 1


def test_spm_optimize_compares_with_its_own_base_design(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """With ``--design FILE`` the report's reference is that design, scored by the
    study's objectives, not the prototype."""
    base = dataclasses.replace(spm.SPMDesign.coaxial(45.0, 80.0, 90.0), name="mine")
    design_file = base.save(tmp_path / "mine.toml")
    out = tmp_path / "results"
    argv = [
        "optimize", "--objectives", "max_tilt", "--vary", "alpha1=35:75", "--trials", "1",
        "--step", "8", "--design", str(design_file), "--allow-home-collision", "--quiet",
        "--out", str(out), "--json",
    ]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    reference = json.loads((out / "report.json").read_text(encoding="utf-8"))["prototype"]
    assert reference["name"] == "mine" and reference["error"] is None
    assert reference["values"] == {"alpha1_deg": pytest.approx(45.0, abs=1e-12)}
    score = safe_workspace_score(base, step_deg=8.0)
    assert reference["scores"]["max_tilt"] == score.max_safe_tilt_deg
    assert (
        score.max_safe_tilt_deg != safe_workspace_score("prototype", step_deg=8.0).max_safe_tilt_deg
    )
