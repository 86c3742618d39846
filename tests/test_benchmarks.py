"""The benchmarks run (quick mode), write the JSON they promise, and their checks hold.

No timing is asserted: only the structure of the output and the accuracy figures.
"""

from __future__ import annotations

import importlib.util
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("scipy")

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # `benchmarks` is a top-level folder, not installed
    sys.path.insert(0, str(ROOT))

import spm_pin as spm  # noqa: E402
from benchmarks import _common  # noqa: E402
from benchmarks.bench_kinematics import (  # noqa: E402
    OUTCOMES,
    PeerAnswer,
    classify,
    fsolve_fk,
    main,
    proximal_axes,
)

#: Tolerances of this file.
TOL = {
    "residual": 1e-12,  # the closure target
    "axes": 1e-12,  # independent w_i against the library's
    "percentile": 1e-12,
}

RESULT_KEYS = {
    "fk_home_reachable",
    "fk_home_uniform",
    "fk_all_modes",
    "ik_reachable",
    "ik_uniform",
    "fk_home_single_call",
}
TIMING_KEYS = {"median_s", "p95_s", "p99_s", "per_second", "per_item_s", "n"}
TARGET_KEYS = {
    "fk_home_per_second",
    "fk_home_uniform_per_second",
    "fk_home_max_residual",
    "fk_home_speedup_vs_fsolve",
    "ik_per_second",
    "all_pass",
}


def test_quick_kinematics_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "k.json"
    assert main(["--quick", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Targets" in printed
    assert "PASS" in printed or "FAIL" in printed

    data = json.loads(out.read_text())
    assert data["benchmark"] == "kinematics"
    assert {"python", "packages", "cpu"} <= set(data["machine"])
    assert {"numpy", "scipy"} <= set(data["machine"]["packages"])
    assert data["config"]["quick"] is True
    assert set(data["results"]) == RESULT_KEYS
    for name, entry in data["results"].items():
        assert set(entry) >= TIMING_KEYS, name
        assert entry["per_second"] > 0, name
        assert entry["p95_s"] >= entry["median_s"], name
    assert set(data["targets"]) == TARGET_KEYS

    fk = data["results"]["fk_home_reachable"]
    assert fk["reachable_fraction"] == 1.0
    assert fk["home_rate"] == 1.0
    assert fk["max_residual"] <= TOL["residual"]
    assert fk["max_reported_residual"] <= TOL["residual"]
    assert data["results"]["ik_reachable"]["reachable_fraction"] == 1.0
    assert data["results"]["fk_all_modes"]["home_mode_agrees_with_fk"] == 1.0

    peer = data["peer"]
    assert peer["ours_home_rate"] == 1.0
    assert peer["ours_max_residual"] <= TOL["residual"]
    assert set(peer["outcomes"]) == set(OUTCOMES)
    assert sum(peer["outcomes"].values()) == peer["n"]
    assert peer["speed_ratio_ours_vs_peer"] > 0


def test_peer_axes_match_library() -> None:
    """The peer's w_i (Rodrigues from w_i0) are the library's, for both presets."""
    theta = np.random.default_rng(3).uniform(-np.pi, np.pi, size=(50, 3))
    for design in (spm.SPMDesign.prototype(), spm.SPMDesign.agile_eye()):
        fk = spm.forward_kinematics(theta, design)
        np.testing.assert_allclose(proximal_axes(theta, design), fk.w, atol=TOL["axes"])


def test_classify_outcomes() -> None:
    design = spm.SPMDesign.agile_eye()  # beta != 90 deg: a mirror platform exists
    v_home = np.asarray(design.v0)
    w = np.asarray(design.w0)
    # At home fsolve starts on the solution.
    assert classify(fsolve_fk(w, design), v_home, design) == "home"
    # a2 = 90 deg: -v_i0 closes every loop with the same dot products, left-handed.
    assert classify(PeerAnswer(v=-v_home, ier=1), v_home, design) == "mirror"
    assert classify(PeerAnswer(v=v_home, ier=5), v_home, design) == "failed"
    turned = v_home @ np.diag([-1.0, -1.0, 1.0])  # a proper rotation of the platform
    assert classify(PeerAnswer(v=turned, ier=1), v_home, design) == "other_mode"
    # Coplanar home axes (prototype): a mirror is itself a rotation, never "mirror".
    proto = spm.SPMDesign.prototype()
    v_proto = np.asarray(proto.v0)
    flipped = PeerAnswer(v=v_proto @ np.diag([1.0, -1.0, 1.0]), ier=1)
    assert classify(flipped, v_proto, proto) == "other_mode"


def test_common_statistics_and_json(tmp_path: Path) -> None:
    values = [5.0, 1.0, 4.0, 2.0, 3.0]
    for q in (0.0, 37.0, 50.0, 95.0, 99.0, 100.0):
        assert math.isclose(
            _common.percentile(values, q),
            float(np.percentile(values, q)),
            abs_tol=TOL["percentile"],
        )
    timing = _common.Timing(tuple(values))
    summary = timing.summary(items=10)
    assert summary["median_s"] == 3.0
    assert math.isclose(summary["per_second"], 10 / 3.0)
    timed = _common.time_call(lambda: 7, repeats=3)
    assert timed.value == 7
    assert len(timed.timing.samples) == 3
    out = _common.write_json(tmp_path / "sub" / "x.json", {"a": np.float64(np.nan), "b": (1, 2)})
    assert json.loads(out.read_text()) == {"a": None, "b": [1, 2]}


def test_quick_calibration_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from benchmarks import bench_calibration

    out = tmp_path / "c.json"
    assert bench_calibration.main(["--quick", "--out", str(out)]) == 0
    assert "Targets" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["benchmark"] == "calibration"
    assert data["config"]["quick"] is True
    assert set(data["results"]) == {"analytic", "analytic_12", "parse"}
    for name in ("analytic", "analytic_12"):
        entry = data["results"][name]
        assert set(entry) >= TIMING_KEYS - {"n"}, name
        assert entry["p95_s"] >= entry["median_s"] > 0, name
    analytic = data["results"]["analytic"]
    assert analytic["readings"] == 100
    assert analytic["identified"] == analytic["parameters"] >= 7
    assert analytic["ok"] is True
    assert data["results"]["analytic_12"]["unidentified"] == ["ref_z"]
    peer = data["peer"]
    assert peer["identified"] == analytic["identified"]
    assert peer["max_estimate_difference_deg"] < 1e-4  # same answer, other Jacobian
    assert peer["speed_ratio_ours_vs_peer"] > 0
    assert data["accuracy"]["max_abs_z"] < 5.0
    assert set(data["targets"]) == {"identification_seconds", "parameters_identified", "all_pass"}


def test_quick_closure_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from benchmarks import bench_closure

    out = tmp_path / "closure.json"
    assert bench_closure.main(["--quick", "--out", str(out)]) == 0
    assert "Targets" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["benchmark"] == "closure"
    assert data["config"]["quick"] is True
    assert {"pin", "numpy", "scipy"} <= set(data["machine"]["packages"])
    cases = {"warm_1deg", "warm_servo", "warm_1deg_array", "cold", "follow_study"}
    assert set(data["results"]) == cases
    for name, entry in data["results"].items():
        assert set(entry) >= TIMING_KEYS, name
        assert entry["p95_s"] >= entry["median_s"] > 0, name
        assert entry["max_residual"] <= TOL["residual"], name
        assert entry["max_error_rad"] <= 1e-10, name  # against the analytic FK
    warm = data["results"]["warm_1deg"]
    assert warm["max_step_deg"] <= 1.0 + 1e-9
    assert set(warm["iterations_histogram"]) <= {"1", "2"}  # the predictor's work
    assert data["results"]["warm_servo"]["max_step_deg"] <= 0.33
    cold = data["results"]["cold"]
    assert cold["agree_fraction"] == cold["solved_fraction"] >= 0.9
    peer = data["peer"]
    for name in ("default", "default_tight", "lm_exact_jacobian_tight"):
        assert peer[name]["n"] == data["config"]["sizes"]["peer"], name
        assert peer[name]["speed_ratio_peer_over_ours"] > 0, name
    assert peer["default_tight"]["max_residual"] <= TOL["residual"]  # the same job as ours
    assert peer["lm_exact_jacobian_tight"]["max_error_rad"] <= 1e-10
    assert set(data["targets"]) == {
        "warm_median",
        "speedup_vs_least_squares",
        "max_residual",
        "all_pass",
    }
    assert data["targets"]["max_residual"]["pass"] is True


@pytest.mark.hardware
def test_quick_hardware_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("dynamixel_sdk")
    from benchmarks import bench_hardware

    out = tmp_path / "hardware.json"
    assert bench_hardware.main(["--quick", "--out", str(out)]) == 0
    assert "Targets" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["benchmark"] == "hardware" and data["config"]["quick"] is True
    assert {"dynamixel-sdk", "pin"} <= set(data["machine"]["packages"])
    results = data["results"]
    assert set(results) == {"bus", "loop", "loop_with_model", "guard_cold", "wire"}
    for name in ("sync_read_fast", "sync_read_plain", "sync_write"):
        assert results["bus"][name]["p95_s"] >= results["bus"][name]["median_s"] > 0, name
    for name in ("loop", "loop_with_model"):
        loop = results[name]
        assert set(loop["stages"]) == {"read", "kinematics", "view", "guard", "write"}
        assert loop["sent"] == loop["cycles"] + 20 and loop["refused_or_failed"] == 0, name
        assert loop["cycle"]["median_s"] >= loop["software"]["median_s"] > 0, name
    assert results["guard_cold"]["safe_fraction"] == 1.0
    assert results["wire"]["bytes_fast"] < results["wire"]["bytes_plain"]
    assert set(data["targets"]) == {"software_per_second", "all_pass"}


def test_quick_dynamics_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("mujoco")
    from benchmarks import bench_dynamics

    out = tmp_path / "dynamics.json"
    assert bench_dynamics.main(["--quick", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Targets" in printed and ("PASS" in printed or "FAIL" in printed)
    data = json.loads(out.read_text())
    assert data["benchmark"] == "dynamics" and data["config"]["quick"] is True
    assert {"numpy", "pin", "mujoco"} <= set(data["machine"]["packages"])
    results = data["results"]
    for name in ("euler", "rk4"):
        for case in ("passive", "servo"):
            assert f"ours_{name}_{case}" in results
            assert results[f"ours_{name}_{case}"]["max_closure_residual"] <= 1e-10
            assert f"mujoco_{name}_{case}" in results
    assert {"inverse_trajectory", "forward_pinocchio", "forward_nullspace"} <= set(results)
    for name, entry in results.items():
        assert entry["per_second"] > 0 and entry["p95_s"] >= entry["median_s"], name
    accuracy = data["accuracy"]
    assert accuracy["energy"]["relative_drift"] <= 1e-6
    stiff = accuracy["mujoco_stiff"]
    assert stiff["passive_hanging"]["max_theta_error_rad"] <= 1e-6
    assert stiff["driven"]["max_theta_error_rad"] <= 1e-6
    assert set(data["targets"]) == {
        "steps_per_second",
        "closure_drift",
        "energy_drift",
        "mujoco_theta_agreement",
        "all_pass",
    }
    for name in ("closure_drift", "energy_drift", "mujoco_theta_agreement"):
        assert data["targets"][name]["pass"] is True, name


def test_quick_collision_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from benchmarks import bench_collision

    out = tmp_path / "collision.json"
    assert bench_collision.main(["--quick", "--workers", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Targets" in printed and ("PASS" in printed or "FAIL" in printed)
    data = json.loads(out.read_text())
    assert data["benchmark"] == "collision" and data["config"]["quick"] is True
    assert {"numpy", "pin", "coal"} <= set(data["machine"]["packages"])
    results = data["results"]
    for name in ("check_random", "check_path", "check_theta", "peer_bvh", "distances"):
        entry = results[name]
        assert entry["p95_s"] >= entry["median_s"] > 0, name
    # Every method names the same colliding pairs, up to contacts at zero distance.
    for agreement in (
        results["peer_bvh"]["agreement_with_library"],
        results["fidelity"]["convex"]["agreement_with_library"],
        results["fidelity"]["hybrid_no_probes"]["agreement_with_library"],
    ):
        assert agreement["different"] == 0, agreement
        assert agreement["same"] > 0
    assert results["fidelity"]["pieces"] > 100
    assert results["map"]["same_result_parallel_and_single"] is True
    assert 0.0 < results["map"]["reachable_fraction"] < 1.0
    assert data["peer"]["speed_ratio_ours_vs_peer"] > 0
    assert set(data["targets"]) == {"check_median", "all_pass"}  # no map target at 15 deg


@pytest.mark.hardware  # the suite includes bench_hardware (emulated bus on a pty)
def test_gathered_suite_quick(tmp_path: Path) -> None:
    """`python -m benchmarks --quick` runs every benchmark into one JSON file and one
    table whose rows are the JSON's figures; docs/benchmarks.md is left alone."""
    from benchmarks import _gather

    page = ROOT / "docs" / "benchmarks.md"
    page_before = page.read_bytes()
    command = ["-m", "benchmarks", "--quick", "--jobs", "2", "--out", str(tmp_path)]
    done = subprocess.run(
        [sys.executable, *command], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert page.read_bytes() == page_before

    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["config"]["quick"] is True and summary["config"]["complete"] is True
    assert {"cpu", "logical_cpus", "packages", "load_average_end"} <= set(summary["machine"])
    assert list(summary["benchmarks"]) == list(_gather.BENCHMARKS)
    optional = {"dynamics": "mujoco", "hardware": "dynamixel_sdk"}
    expected_rows = []
    for name, entry in summary["benchmarks"].items():
        if importlib.util.find_spec(optional.get(name, "numpy")) is None:
            assert entry["status"] == "skipped", (name, entry["reason"])
        else:
            assert entry["status"] == "ok", (name, entry["reason"])
            own = {k for k, v in entry["result"]["targets"].items() if isinstance(v, dict)}
            assert own and set(entry["targets"]) == own, name
            for target_name, t in entry["targets"].items():
                assert t["verdict"] == ("PASS" if t["pass"] else "FAIL"), target_name
                assert math.isfinite(t["value"]) and math.isfinite(t["threshold"]), target_name
                assert {"peer_value", "ratio", "comparison", "unit"} <= set(t), target_name
            shown = sorted(n for f in entry["figures"] for n in f["targets"])
            assert shown == sorted(own), name  # every target in exactly one row
            assert any(f["peer"] is not None for f in entry["figures"]), name
        for f in entry["figures"]:
            verdicts = "; ".join(entry["targets"][n]["verdict"] for n in f["targets"])
            status = entry["status"].upper() if f["kind"] == "status" else verdicts or "—"
            expected_rows.append((f["label"], status))

    def table(text: str) -> list[list[str]]:
        lines = [line for line in text.splitlines() if line.startswith("| ")]
        return [[c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]] for line in lines]

    header = list(_gather.TABLE_HEADER)
    rows = table((tmp_path / "summary.md").read_text())
    assert rows[0] == header
    assert [(row[0], row[-1]) for row in rows[2:]] == expected_rows

    # The page shows a full table between its markers, and only there is it replaced.
    block = page.read_text().split(_gather.START_MARKER)[1].split(_gather.END_MARKER)[0]
    page_rows = table(block)
    assert page_rows and page_rows[0] == header, "run `python -m benchmarks --update-docs`"
    for name in _gather.BENCHMARKS:
        assert any(row[0].startswith(f"{name}: ") for row in page_rows[2:]), name
    text = f"a\n{_gather.START_MARKER}\nold\n{_gather.END_MARKER}\nb\n"
    new = _gather.replace_between_markers(text, "new")
    assert new == f"a\n{_gather.START_MARKER}\nnew\n{_gather.END_MARKER}\nb\n"
