"""The benchmarks run (quick mode), write the JSON they promise, and their checks hold.

No timing is asserted: only the structure of the output and the accuracy figures.
"""

from __future__ import annotations

import json
import math
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
