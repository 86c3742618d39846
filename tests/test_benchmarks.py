"""The benchmarks run (quick mode), write the JSON they promise, and their checks hold.

No timing is asserted: only the structure of the output and the accuracy figures.
"""

from __future__ import annotations

import gc
import importlib.util
import io
import json
import math
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pyperf = pytest.importorskip("pyperf")

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
    # A full collection before each sample, or once before all (the collector stays on).
    full: list[int] = []

    def count(phase: str, info: dict[str, int]) -> None:
        if phase == "start" and info["generation"] == 2:
            full.append(1)

    gc.callbacks.append(count)
    try:
        for collect_each, collections in ((True, 4), (False, 1)):
            full.clear()
            timed = _common.time_call(lambda: 7, repeats=4, collect_each=collect_each)
            assert len(timed.timing.samples) == 4 and len(full) == collections
    finally:
        gc.callbacks.remove(count)
    assert gc.isenabled()
    out = _common.write_json(tmp_path / "sub" / "x.json", {"a": np.float64(np.nan), "b": (1, 2)})
    assert json.loads(out.read_text()) == {"a": None, "b": [1, 2]}


def test_time_alternating_turns_the_order_and_pairs_the_windows(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    log: list[str] = []

    def fake(fn: Any) -> tuple[float, Any]:
        name = fn()
        log.append(name)
        window = (len(log) - 1) // 5  # 3 calls of a and 2 of b per window
        # b takes 2 us; a takes 6 us in even windows, 10 us in odd ones
        return ({"a": 10e-6 if window % 2 else 6e-6, "b": 2e-6}[name], name)

    def call(name: str) -> Any:
        return lambda: name

    monkeypatch.setattr(_common, "_timed_once", fake)
    calls = {"a": (call("a"), 3), "b": (call("b"), 2)}
    timings, ratio = _common.time_alternating(calls, windows=4, warmup=0)
    assert [len(timings[k].samples) for k in "ab"] == [12, 8]
    # window 0: a then b; window 1: b then a; the order turns each window
    assert log[:5] == ["a"] * 3 + ["b"] * 2 and log[5:10] == ["b"] * 2 + ["a"] * 3
    assert sorted(set(timings["a"].samples)) == [6e-6, 10e-6]
    assert ratio == pytest.approx(4.0)  # the median of the windows' 3, 5, 3 and 5
    with pytest.raises(ValueError, match="windows"):
        _common.time_alternating(calls, windows=0)
    with pytest.raises(ValueError, match="at least once"):
        _common.time_alternating({"a": (call("a"), 0)}, windows=1)


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


def test_quick_envs_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("gymnasium")
    from benchmarks import bench_envs

    out = tmp_path / "envs.json"
    assert bench_envs.main(["--quick", "--out", str(out)]) == 0
    assert "Targets" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["benchmark"] == "envs" and data["config"]["quick"] is True
    assert set(data["results"]) == {"vector", "single"}
    for entry in (data["results"]["vector"], data["results"]["single"], data["peer"]):
        assert set(entry) >= TIMING_KEYS - {"n"}
        assert entry["p95_s"] >= entry["median_s"] > 0
    assert data["results"]["vector"]["items"] == data["results"]["vector"]["n"] == 256
    assert data["peer"]["speed_ratio_ours_vs_peer"] > 0
    cover = data["cover"]  # the batched step with a saved cover: the same states
    assert cover["same_states_as_without"] is True and cover["n"] == 256
    assert 0.0 < cover["settled_fraction"] <= 1.0 and cover["file_bytes"] > 0
    only = cover["cover_only"]  # the certified cells as the safe set: part of it
    assert only["n"] == 256 and only["per_second"] > 0
    assert 0.0 < only["safe_inputs_certified"] < 1.0 and 0.0 < only["safe_vertices_kept"] < 1.0
    assert set(data["targets"]) == {"all_pass"}  # the 4096 target: full runs only
    # a row without its side-by-side peer (MuJoCo missing): no ratio line, no NaN
    side = data["dynamic"]["single_cover_only"]
    side.pop("peer", None), side.pop("paired_ratio_ours_vs_peer", None)
    text = bench_envs.report(data)
    assert "nanx" not in text and "dynamic cover_only step side by side" not in text
    assert "cover_only batch side by side with its peer" in text


def test_quick_optimize_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from benchmarks import bench_optimize

    out = tmp_path / "optimize.json"
    assert bench_optimize.main(["--quick", "--out", str(out)]) == 0
    assert "Targets" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["benchmark"] == "optimize" and data["config"]["quick"] is True
    assert set(data["results"]) == {"score", "score_new_design", "engines", "pareto"}
    engines = data["results"]["engines"]
    assert engines["designs"] == bench_optimize.QUICK.engine_designs and engines["equal_scores"]
    for key in ("in_process", "process_pool", "dask_local_cluster"):
        if "skipped" not in engines[key]:  # Dask distributed is optional
            assert engines[key]["per_second"] > 0 and engines[key]["seconds"] > 0
    assert engines["process_pool"]["efficiency"] > 0
    entries = (data["results"]["score"], data["results"]["score_new_design"], data["peer"])
    for entry in (*entries, data["peer_clearance"]):
        assert set(entry) >= TIMING_KEYS - {"n"}
        assert entry["p95_s"] >= entry["median_s"] > 0
    score = data["results"]["score"]
    assert score["points"] == 16471 and 0 < score["collision_checks"] < score["points"]
    for peer in (data["peer"], data["peer_clearance"]):
        assert peer["safe_equal"] is True and peer["figures"] == score["figures"]
    assert data["peer"]["speed_ratio_ours_vs_peer"] > 0
    assert set(data["targets"]) == {"equal_to_map", "all_pass"}  # time: full runs only
    assert data["targets"]["equal_to_map"]["pass"] is True
    pareto = data["results"]["pareto"]
    assert pareto["designs"] == bench_optimize.QUICK.pareto_designs
    for key in ("ours", "process_pool"):  # Optuna and Dask distributed are optional
        entry = pareto[key]
        if "skipped" in entry:
            continue
        assert entry["designs"] == entry["items"] == pareto["designs"]
        assert entry["seconds"] > 0 and entry["values_s"] == [entry["seconds"]]
        assert entry["startup_s"] > 0
        assert 0 <= entry["pareto"] <= entry["designs"] - entry["failed"] - entry["infeasible"]
    if "skipped" not in pareto["ours"]:
        assert pareto["ours"]["pareto"] == pareto["ours"]["pareto_of_study"]
        assert pareto["speed_ratio_ours_vs_peer"] > 0
    _check_optimize_figures(data)


def _check_optimize_figures(data: dict[str, Any]) -> None:
    """The optimize adapter's rows, from a run and from the same run without Dask."""
    from benchmarks import _figures

    benchmark = _figures.BENCHMARKS["optimize"]
    analysis = _figures.analyse(benchmark, data)
    assert analysis.adapter_error is None
    keys = {f.key: f for f in analysis.figures}
    engines, pareto = data["results"]["engines"], data["results"]["pareto"]
    assert keys["engines_in_process"].ours == (engines["in_process"]["per_second"],)
    assert keys["engines_equal_scores"].ours == (1.0,)
    if "skipped" not in engines["dask_local_cluster"]:
        dask = keys["engines_dask"]
        assert dask.ours == (engines["dask_local_cluster"]["per_second"],)
        assert dask.peer == (engines["process_pool"]["per_second"],)
        assert keys["engines_dask_efficiency"].peer == (engines["process_pool"]["efficiency"],)
    if "skipped" not in pareto["ours"]:
        row = keys["pareto"]
        assert row.ours == (pareto["ours"]["seconds"],)
        assert row.peer == (pareto["process_pool"]["seconds"],)
        assert row.ratio == pareto["speed_ratio_ours_vs_peer"]
        assert keys["pareto_front"].ours == (float(pareto["ours"]["pareto"]),)
    # Without Dask: the peer's rate stands alone, and no Pareto rows.
    skipped = json.loads(json.dumps(data))
    skipped["results"]["engines"]["dask_local_cluster"] = {"skipped": "no dask"}
    skipped["results"]["pareto"]["ours"] = {"skipped": "no dask"}
    skipped["results"]["pareto"].pop("speed_ratio_ours_vs_peer", None)
    analysis = _figures.analyse(benchmark, skipped)
    assert analysis.adapter_error is None
    keys = {f.key: f for f in analysis.figures}
    assert {"engines_process_pool", "engines_process_pool_efficiency"} <= set(keys)
    assert not {"engines_dask", "pareto", "pareto_front"} & set(keys)


def test_quick_planning_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Runs with or without OMPL (an optional peer) and toppra (the duration section)."""
    from benchmarks import bench_planning
    from spm_pin.planning import plan, safe_set_of

    out = tmp_path / "planning.json"
    assert bench_planning.main(["--quick", "--out", str(out)]) == 0
    assert "Targets" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["benchmark"] == "planning" and data["config"]["quick"] is True
    assert {"numpy", "ompl", "toppra"} <= set(data["machine"]["packages"])
    assert set(data["results"]) == {
        "safe_set", "cover", "plan", "plan_cached", "duration", "eye"
    }  # fmt: skip
    eye = data["results"]["eye"]
    assert eye["n"] == eye["samples"] == bench_planning.QUICK.eye_pairs
    assert eye["planned"] + eye["failures"] == eye["n"]
    assert eye["certified"] == eye["planned"] and eye["boxes"] >= 1
    cover = data["results"]["cover"]
    assert cover["fill_level"] == 0 and cover["file_bytes"] > 0 and cover["load_s"] > 0
    assert data["results"]["plan_cached"]["n"] == data["results"]["plan"]["n"]
    assert set(data["peer"]) == {"straight", "ompl"}
    sizes = bench_planning.QUICK
    safe_set, planned = data["results"]["safe_set"], data["results"]["plan"]
    straight = data["peer"]["straight"]
    for entry in (safe_set, planned, straight):
        assert set(entry) >= TIMING_KEYS - {"n"}
        assert entry["p99_s"] >= entry["p95_s"] >= entry["median_s"] > 0
    assert safe_set["samples"] == sizes.builds and safe_set["safe_vertices"] > 0
    assert planned["n"] == straight["n"] == planned["samples"] == sizes.pairs
    assert planned["planned"] + planned["failures"] == sizes.pairs
    assert sum(planned["failure_reasons"].values()) == planned["failures"]
    assert planned["certified"] == planned["planned"] == sizes.pairs
    assert planned["max_endpoint_error_rad"] <= bench_planning.ENDPOINT_TOL
    assert 0 <= planned["detours"] <= planned["planned"]
    assert planned["length_vs_straight"]["min"] >= 1.0 - 1e-9
    assert 0.0 <= straight["unsafe_fraction"] <= 1.0
    assert straight["unsafe"] == round(straight["unsafe_fraction"] * straight["n"])

    # The same pairs, planned here: the ends are the pair's, each path certified.
    safe = safe_set_of()
    pairs, _ = bench_planning.sample_pairs(safe, sizes.pairs)
    assert len(pairs) == sizes.pairs
    for start, goal in pairs:
        path = plan(start, goal, safe=safe)
        np.testing.assert_array_equal(path.theta[0], start)
        np.testing.assert_array_equal(path.theta[-1], goal)
        assert safe.certify(path.theta)[0]

    ompl = data["peer"]["ompl"]
    if importlib.util.find_spec("ompl") is None:
        assert ompl["available"] is False and ompl["reason"]
    else:
        assert ompl["available"] is True, ompl.get("reason")
        assert set(ompl) >= TIMING_KEYS - {"n"}
        assert ompl["n"] == ompl["samples"] == sizes.ompl_pairs
        assert 0 <= ompl["certified"] <= ompl["solved"] <= ompl["n"]
        assert 0.0 <= ompl["success_fraction"] <= 1.0
        assert ompl["speed_ratio_ours_vs_peer"] > 0
        if ompl["solved"]:
            assert ompl["max_endpoint_error_rad"] <= 1e-9
    duration = data["results"]["duration"]
    if importlib.util.find_spec("toppra") is None:
        assert duration["available"] is False
    else:
        assert duration["available"] is True, duration.get("reason")
        assert duration["n"] == min(sizes.duration_pairs, sizes.pairs - straight["unsafe"])
        assert duration["max_trapezoid_disagreement_s"] < 1e-6  # plan_linear: same trapezoid
        assert duration["ratio_vs_trapezoid"]["min"] > 0.99  # time-optimal along a line
    assert set(data["targets"]) == {"plan_success", "all_pass"}  # times: full runs only
    assert data["targets"]["plan_success"]["pass"] is True


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
    assert set(results) == {
        "bus",
        "loop",
        "loop_with_model",
        "guard_cold",
        "control_cycle",
        "control_cycle_python",
        "stream",
        "wire",
    }
    for name in ("sync_read_fast", "sync_read_plain", "sync_write"):
        assert results["bus"][name]["p95_s"] >= results["bus"][name]["median_s"] > 0, name
    for name in ("loop", "loop_with_model"):
        loop = results[name]
        assert set(loop["stages"]) == {"read", "kinematics", "view", "guard", "write"}
        assert loop["sent"] == loop["cycles"] + 20 and loop["refused_or_failed"] == 0, name
        assert loop["cycle"]["median_s"] >= loop["software"]["median_s"] > 0, name
    assert results["guard_cold"]["safe_fraction"] == 1.0
    assert results["wire"]["bytes_fast"] < results["wire"]["bytes_plain"]
    cycle = results["control_cycle"]
    assert cycle["same_goals"] is True
    assert cycle["fast"]["median_s"] < cycle["batch"]["median_s"]
    assert set(cycle["stages_median_s"]) == {"ik", "guard", "pulses"}
    stream = results["stream"]
    assert stream["cycles"] > 0 and stream["actions"].get("hold", 0) == 0
    assert stream["software"]["median_s"] > stream["stream_own"]["median_s"] > 0
    # The same cycle with the Python kernels, in a child process without numba.
    python = results["control_cycle_python"]
    assert python["compiled"] is False and python["same_goals"] is True
    assert cycle["compiled"] is (importlib.util.find_spec("numba") is not None)
    assert set(data["targets"]) == {"software_per_second", "control_cycle_median", "all_pass"}


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
    for n in (1, 64, 4096):
        assert results[f"reduced_euler_n{n}"]["n"] % n == 0
    assert data["accuracy"]["reduced"]["closure_drift_rad"] == 0.0
    assert 0.0 <= data["accuracy"]["reduced"]["constrained_closure_drift_rad"] <= 1e-10
    assert data["comparison"]["reduced_batched_vs_ours_euler"] > 0
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


def test_quick_remote_benchmark(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A real server, a streaming client and readers: the JSON's shape, and every
    target and push accounted for (counts, not timings)."""
    for module in ("fastapi", "uvicorn", "httpx", "websockets"):
        pytest.importorskip(module)
    from benchmarks import bench_remote

    out = tmp_path / "remote.json"
    assert bench_remote.main(["--quick", "--out", str(out)]) == 0
    assert "Targets" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["benchmark"] == "remote" and data["config"]["quick"] is True
    assert data["config"]["event_loop"] in {"asyncio", "uvloop"}
    assert {"fastapi", "uvicorn", "httpx", "websockets"} <= set(data["machine"]["packages"])
    results = data["results"]
    streams = ("stream_100", "stream_1000", "stream_1000_untimed", "stream_1000_readers_100")
    assert set(results) == {"get_state", "peer", *streams}
    assert results["get_state"]["backend"] == "kinematic"
    assert results["get_state"]["p95_s"] >= results["get_state"]["median_s"] > 0
    readers = data["config"]["sizes"]["readers"]
    for name in streams:
        stream = results[name]
        assert stream["timed"] is (name != "stream_1000_untimed")
        if stream["timed"]:  # a motion within the limits, timed by its own clock
            assert stream["refused"] == 0, stream["why"]
        sent = stream["sent"]
        assert sent == round(data["config"]["sizes"]["seconds"] * stream["rate_hz"]), name
        assert stream["acks"] + stream["refused"] + stream["errors"] + stream["lost"] == sent
        assert sum(stream["why"].values()) >= stream["refused"] + stream["errors"] + stream["lost"]
        if stream["acks"] + stream["refused"] + stream["errors"]:
            assert stream["latency"]["samples"] == sent - stream["lost"], name
            assert stream["latency"]["p99_s"] >= stream["latency"]["median_s"] > 0, name
        pushes = stream["readers"]
        assert pushes["connections"] == len(pushes["per_connection"]) == readers, name
        assert pushes["rate_hz"] == (100 if name.endswith("readers_100") else stream["rate_hz"])
        assert pushes["received"] == sum(c["received"] for c in pushes["per_connection"])
        assert pushes["pushed"] - pushes["received"] == pushes["not_received"] >= 0, name
        for connection in pushes["per_connection"]:
            assert 0 <= connection["received"] <= connection["pushed"], name
            assert connection["dropped"] >= 0, name
        cpu = stream["cpu_s"]  # each process's CPU seconds over the stream (Linux)
        assert cpu["wall"] >= sent / stream["rate_hz"] * 0.5 and cpu["controller"] > 0, name
        assert cpu["server"] >= 0 and cpu["readers"] > 0, name
    for name in ("state", "command_100", "command_1000", "move_100", "move_1000"):
        assert results["peer"][name]["p95_s"] >= results["peer"][name]["median_s"] > 0, name
    assert set(data["targets"]) == {
        "stream_1khz_p99",
        "stream_1khz_rate",
        "nothing_lost_silently",
        "all_pass",
    }
    assert 0.0 <= data["targets"]["nothing_lost_silently"]["value"] <= 1.0


@pytest.mark.hardware  # the suite includes bench_hardware (emulated bus on a pty)
def test_gathered_suite_quick(tmp_path: Path) -> None:
    """`python -m benchmarks --quick` runs every benchmark into one pyperf suite and one
    table whose rows are the suite's figures; docs/benchmarks.md is left alone."""
    from benchmarks import _figures, _report, _suite

    page = ROOT / "docs" / "benchmarks.md"
    page_before = page.read_bytes()
    command = ["-m", "benchmarks", "--quick", "--jobs", "2", "--out", str(tmp_path)]
    done = subprocess.run(
        [sys.executable, *command], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert page.read_bytes() == page_before

    suite = pyperf.BenchmarkSuite.load(str(tmp_path / "suite.json"))
    info = suite.get_metadata()
    assert info["suite"] == "spm-pin benchmarks" and info["quick"] == 1 and info["complete"] == 1
    assert {"cpu_count", "python", "version.numpy", "load_avg_end"} <= set(info)
    assert info["benchmarks"].split() == list(_figures.BENCHMARKS)
    optional = {
        "dynamics": "mujoco",
        "hardware": "dynamixel_sdk",
        "remote": "fastapi",
        "envs": "gymnasium",
    }
    expected_rows = []
    for name in _figures.BENCHMARKS:
        status = info[f"status.{name}"]
        if importlib.util.find_spec(optional.get(name, "numpy")) is None:
            assert status == "skipped", (name, info.get(f"reason.{name}"))
            expected_rows.append((f"{name}: not run", "SKIPPED"))
            continue
        assert status == "ok", (name, info.get(f"reason.{name}"))
        own = json.loads((tmp_path / f"{name}.json").read_text())["targets"]
        own = {k: v for k, v in own.items() if isinstance(v, dict)}
        ours = [b for b in suite if b.get_metadata()["benchmark"] == name]
        shown = []
        for bench in ours:
            metadata = bench.get_metadata()
            assert bench.get_name().startswith(f"{name}/"), bench.get_name()
            assert metadata["unit"] in {"second", "integer"}
            assert metadata["direction"] in {"lower", "higher"}
            if metadata["role"] == "peer":
                assert suite.get_benchmark(metadata["figure"]), bench.get_name()
                continue
            targets = metadata.get("targets", "").split()
            for target in targets:
                verdict = metadata[f"target.{target}.verdict"]
                assert verdict == ("PASS" if own[target]["pass"] else "FAIL"), target
            shown += targets
            expected_rows.append(
                (
                    metadata["description"],
                    "; ".join(metadata[f"target.{t}.verdict"] for t in targets) or "—",
                )
            )
        assert sorted(shown) == sorted(own), name  # every target in exactly one row
        assert any(b.get_metadata()["role"] == "peer" for b in ours), name
    # The figures keep every raw sample: pyperf's median is the benchmark's own.
    kinematics = json.loads((tmp_path / "kinematics.json").read_text())
    fk = suite.get_benchmark("kinematics/fk-home")
    entry = kinematics["results"]["fk_home_reachable"]
    assert fk.get_nvalue() == len(entry["values_s"])
    assert math.isclose(fk.median(), entry["median_s"] / entry["items"], rel_tol=1e-12)
    assert fk.get_metadata()["inner_loops"] == entry["items"]
    assert len(_suite.rows(suite)) == len(expected_rows)

    def table(text: str) -> list[list[str]]:
        lines = [line for line in text.splitlines() if line.startswith("| ")]
        return [[c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]] for line in lines]

    header = list(_report.TABLE_HEADER)
    rows = table((tmp_path / "summary.md").read_text())
    assert rows[0] == header
    assert len(rows[2:]) == len(expected_rows)
    for row, (label, verdict) in zip(rows[2:], expected_rows, strict=True):
        assert row[0].startswith(label) and row[-1] == verdict, (row, label, verdict)

    # The page shows a full table between its markers, and only there is it replaced.
    block = page.read_text().split(_report.START_MARKER)[1].split(_report.END_MARKER)[0]
    page_rows = table(block)
    assert page_rows and page_rows[0] == header, "run `python -m benchmarks --update-docs`"
    for name in _figures.BENCHMARKS:
        assert any(row[0].startswith(f"{name}: ") for row in page_rows[2:]), name
    text = f"a\n{_report.START_MARKER}\nold\n{_report.END_MARKER}\nb\n"
    new = _report.replace_between_markers(text, "new")
    assert new == f"a\n{_report.START_MARKER}\nnew\n{_report.END_MARKER}\nb\n"


def _made_suite(path: Path, ours_us: tuple[float, ...], rate: float) -> Path:
    """A suite like `python -m benchmarks` writes, from known values: one timing with a
    peer and a target, one fraction (higher is better), and a skipped benchmark."""
    from benchmarks import _figures, _suite

    fk = _figures.Figure(
        "fk_home",
        "kinematics: FK home mode",
        "time",
        tuple(v * 1e-6 for v in ours_us),
        items=10,
        peer_name="fsolve",
        peer=(3e-4, 4e-4, 5e-4),
        ratio=4e-4 / (ours_us[1] * 1e-6),
        targets=("fk_median",),
    )
    home = _figures.valued(
        "home_rate",
        "kinematics: answers in the home mode",
        rate,
        unit="fraction",
        peer_name="fsolve",
        peer=0.25,
        higher_is_better=True,
    )
    targets = {
        "fk_median": {
            "figure": "fk_home",
            "value": ours_us[1] * 1e-6,
            "threshold": 3e-6,
            "comparison": "<=",
            "unit": "s",
            "pass": ours_us[1] <= 3.0,
            "verdict": "PASS" if ours_us[1] <= 3.0 else "FAIL",
        }
    }
    outcomes = [
        _suite.Outcome("kinematics", "ok", 1.0, None, _figures.Analysis([fk, home], targets)),
        _suite.Outcome("dynamics", "skipped", 0.5, "optional module 'mujoco' is not installed"),
    ]
    common = _suite.run_info(outcomes, quick=True, jobs=1, complete=False, load_start=0.5)
    suite = _suite.build_suite(outcomes, common)
    out = path / "suite.json"
    path.mkdir(parents=True, exist_ok=True)
    suite.dump(str(out))
    return out


def test_table_from_suite(tmp_path: Path) -> None:
    """`--from SUITE` renders the table from the pyperf suite alone."""
    from benchmarks import _gather, _report

    path = _made_suite(tmp_path / "run", (1.0, 2.0, 3.0, 4.0, 5.0), 0.75)
    printed = io.StringIO()
    assert _gather.main(["--from", str(path)], stream=printed) == 0
    text = (path.parent / "summary.md").read_text()
    assert text.strip() in printed.getvalue()
    assert "Quick run" in text and "Only kinematics, dynamics ran." in text
    assert "1 of 1 targets passed; 1 benchmark skipped." in text
    rows = [line for line in text.splitlines() if line.startswith("| ")]
    assert rows[0] == "| " + " | ".join(_report.TABLE_HEADER) + " |"
    cells = [[c.strip() for c in line.split("|")[1:-1]] for line in rows[2:]]
    assert cells == [
        # pyperf's median and p95 (linear interpolation) of the samples, per item.
        [
            "kinematics: FK home mode",
            "3 us",
            "4.8 us",
            "400 us (fsolve)",
            "200x",
            "≤ 3 us (2 us)",
            "PASS",
        ],
        ["kinematics: answers in the home mode", "75.0%", "—", "25.0% (fsolve)", "3.00x", "—", "—"],
        [
            "dynamics: not run (skipped: optional module 'mujoco' is not installed)",
            "—",
            "—",
            "—",
            "—",
            "—",
            "SKIPPED",
        ],
    ]
    # --check: a failing target fails the run.
    failing = _made_suite(tmp_path / "bad", (3.0, 4.0, 5.0), 0.75)
    assert _gather.main(["--from", str(failing), "--check"], stream=io.StringIO()) == 1
    assert _gather.main(["--from", str(failing)], stream=io.StringIO()) == 0


def test_compare_two_suites(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`--compare OLD NEW`: one line per figure, exact ratios, the figure's direction,
    pyperf's t-test; `python -m pyperf compare_to` reads the same files."""
    from benchmarks import _gather

    old = _made_suite(tmp_path / "old", (1.0, 2.0, 3.0), 0.5)
    new = _made_suite(tmp_path / "new", (2.0, 4.0, 6.0), 0.75)
    printed = io.StringIO()
    assert _gather.main(["--compare", str(old), str(new)], stream=printed) == 0
    # Columns are separated by two spaces or more.
    cells = [re.split(r"\s{2,}", line.strip()) for line in printed.getvalue().splitlines()]
    lines = {row[0]: row[1:] for row in cells if row and row[0].startswith("kinematics/")}
    # Medians 2 us -> 4 us; Student's t of [1, 2, 3] against [2, 4, 6]: -2 / sqrt(5 / 3).
    assert lines["kinematics/fk-home"] == [
        "2 us",
        "4 us",
        "2",
        "2.00x slower",
        "not significant (t=-1.55)",
    ]
    assert lines["kinematics/fk-home [peer: fsolve]"][:4] == ["400 us", "400 us", "1", "same"]
    # A fraction: higher is better, one value each (no test).
    assert lines["kinematics/home-rate"] == [
        "50.0%",
        "75.0%",
        "1.5",
        "1.50x better",
        "— (one value)",
    ]
    # One file: compared with the latest results, in the default output folder.
    monkeypatch.setattr(_gather, "RESULTS_DIR", new.parent)
    latest = io.StringIO()
    assert _gather.main(["--compare", str(old)], stream=latest) == 0
    assert latest.getvalue() == printed.getvalue()
    missing = io.StringIO()
    status = _gather.main(["--compare", str(old), str(tmp_path / "none.json")], stream=missing)
    assert status == 2 and "error" in missing.getvalue()

    done = subprocess.run(
        [sys.executable, "-m", "pyperf", "compare_to", str(old), str(new), "--table"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "kinematics/home-rate" in done.stdout
