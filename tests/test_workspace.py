"""Workspace maps: gap coordinates, tilt-and-torsion angles, every field against the
library's own single-point answers, torsion symmetry, reproducibility, executors
(process pool, threads, a Dask local cluster), files, the command line, bad input."""

from __future__ import annotations

import concurrent.futures
import csv
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import get_design
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import spm_pin as spm
from spm_pin.cli import main as cli_main
from spm_pin.collision import LINK_PAIRS, check_input
from spm_pin.workspace import (
    MAP_FIELDS,
    WorkspaceMap,
    WorkspaceSettings,
    gap_inputs,
    gaps_from_theta,
    tilt_torsion,
    workspace_map,
)

#: Tolerances of this module.
TOL = {
    "angle": 1e-12,  # gap and tilt-torsion round trips [deg or rad]
    "kinematics": 1e-12,  # map fields against direct calls
    "torsion": 1e-9,  # torsion symmetry of the kinematic fields
}

#: A coarse grid for the tests [deg].
STEP = 20.0
FIELDS_COMPARED = ("reachable", "collision", "pair_mask", "dexterity", "safe", "clearance")


@pytest.fixture(scope="module")
def coarse() -> WorkspaceMap:
    return workspace_map(step_deg=STEP, settings=WorkspaceSettings(margin=0.0003), progress=False)


def _same(first: WorkspaceMap, second: WorkspaceMap) -> None:
    np.testing.assert_array_equal(first.theta, second.theta)
    for name in MAP_FIELDS:
        np.testing.assert_array_equal(first.fields[name], second.fields[name], err_msg=name)


# ---------------------------------------------------------------- coordinates
@settings(max_examples=50)
@given(st.tuples(*(st.floats(-math.pi, math.pi) for _ in range(3))))
def test_gaps_follow_the_design_definition(theta: tuple[float, float, float]) -> None:
    """D12 = 120 + theta_1 - theta_2 (deg, mod 360) etc. for the prototype; the gaps sum
    to 360 and gap_inputs inverts them up to the torsion."""
    angles = np.degrees(theta)
    gaps = gaps_from_theta(np.radians(angles))
    expected = np.array(
        [120 + angles[0] - angles[1], 120 + angles[1] - angles[2], 120 + angles[2] - angles[0]]
    )
    np.testing.assert_allclose(np.mod(gaps - expected + 180, 360) - 180, 0, atol=1e-9)
    assert gaps.sum() == pytest.approx(360.0)
    back = gap_inputs(gaps[0], gaps[1])
    shift = back - np.radians(angles)
    np.testing.assert_allclose(
        np.mod(shift - shift[0] + math.pi, 2 * math.pi) - math.pi, 0, atol=1e-9
    )


@settings(max_examples=50)
@given(
    st.floats(0.0, math.pi),
    st.floats(-math.pi, math.pi),
    st.floats(-math.pi, math.pi),
)
def test_tilt_torsion_round_trip(tilt: float, azimuth: float, torsion: float) -> None:
    """R = Rz(phi) Ry(tilt) Rz(-phi) Rz(sigma), built with scipy, gives back its angles."""

    def build(phi: float, theta: float, sigma: float) -> np.ndarray:
        turn = Rotation.from_euler("ZYZ", [phi, theta, -phi]) * Rotation.from_euler("z", sigma)
        return np.asarray(turn.as_matrix())

    R = build(azimuth, tilt, torsion)
    t, a, s = tilt_torsion(R)
    assert float(t) == pytest.approx(tilt, abs=1e-7)
    np.testing.assert_allclose(build(float(a), float(t), float(s)), R, atol=1e-7)
    n = R[:, 2]  # the platform normal
    if n[0] ** 2 + n[1] ** 2 > 1e-12:
        assert float(a) == pytest.approx(math.atan2(n[1], n[0]), abs=TOL["angle"])


# ------------------------------------------------------------------- fields
def test_fields_match_single_point_calls(coarse: WorkspaceMap) -> None:
    """Every field at every point equals the library's answer for that one input."""
    robot = spm.build_robot()
    f = coarse.fields
    theta = coarse.theta
    fk = spm.forward_kinematics(theta)
    np.testing.assert_array_equal(f["reachable"], fk.reachable)
    jac = spm.jacobian(theta[fk.reachable])
    np.testing.assert_allclose(f["dexterity"][fk.reachable], jac.dexterity, atol=TOL["kinematics"])
    assert np.all(np.isnan(f["dexterity"][~fk.reachable]))
    for k in range(0, len(coarse), 2):  # every other point: check_input also measures
        report = check_input(theta[k], robot)
        # One rule for the assembly mode: the map checks what spm collide checks.
        found = set(report.pairs)
        if f["reachable"][k]:
            margin = robot.collisions(theta[k], margin=coarse.settings.margin)
            safe = f["dexterity"][k] >= coarse.settings.min_dexterity and not margin
            assert f["safe"][k] == safe
        else:
            assert not f["safe"][k]
        mask = sum(1 << LINK_PAIRS.index(p) for p in found)
        assert f["pair_mask"][k] == mask, (k, found)
        assert f["collision"][k] == bool(found)
    free = f["reachable"] & ~f["collision"]
    assert np.all(f["clearance"][f["reachable"] & f["collision"]] == 0.0)
    assert np.all(np.isnan(f["clearance"][~f["reachable"]]))
    # The clearance is the largest ladder level with no collision (fixed parts out).
    checker = robot.collision_checker
    ladder = coarse.settings.ladder
    for k in np.flatnonzero(free)[:6]:
        q = robot.configuration(theta[k])
        level = f["clearance"][k]
        assert checker.collisions(q, margin=level, include_fixed=False) == []
        bigger = [m for m in ladder if m > level]
        if bigger:
            assert checker.collisions(q, margin=bigger[0], include_fixed=False)
        assert min(checker.distances(q, include_fixed=False).values()) >= level


def test_map_is_torsion_free(coarse: WorkspaceMap) -> None:
    """The same gaps at another torsion give the same kinematics, and tilt and azimuth
    minus torsion do not move."""
    turned = coarse.theta + 0.7
    fk = spm.forward_kinematics(turned)
    np.testing.assert_array_equal(fk.reachable, coarse.fields["reachable"])
    ok = fk.reachable
    jac = spm.jacobian(turned[ok])
    np.testing.assert_allclose(jac.dexterity, coarse.fields["dexterity"][ok], atol=TOL["torsion"])
    tilt, azimuth, torsion = tilt_torsion(fk.R[ok])
    np.testing.assert_allclose(np.degrees(tilt), coarse.fields["tilt_deg"][ok], atol=1e-7)
    psi = (
        np.degrees(azimuth - torsion)
        - (coarse.fields["azimuth_deg"] - coarse.fields["torsion_deg"])[ok]
    )
    np.testing.assert_allclose(np.mod(psi[tilt > 1e-6] + 180, 360) - 180, 0, atol=1e-6)


def test_summary_counts(coarse: WorkspaceMap) -> None:
    summary = coarse.summary()
    f = coarse.fields
    assert summary["points"] == len(coarse)
    assert summary["reachable_fraction"] == pytest.approx(np.mean(f["reachable"]))
    assert summary["safe_fraction"] == pytest.approx(np.mean(f["safe"]))
    for key, count in summary["colliding_points_by_pair"].items():
        a, b = key.split("-")
        assert count == int(np.count_nonzero(coarse.pair_collides((a, b))))
    # Proximal links collide wherever a gap is below about 49 deg.
    small = np.min(np.stack([f["d12_deg"], f["d23_deg"], f["d31_deg"]]), axis=0) < 40.0
    assert np.all(f["collision"][small])
    # The map's grid covers the gap triangle.
    assert np.allclose(f["d12_deg"] + f["d23_deg"] + f["d31_deg"], 360.0)
    assert f["d31_deg"].min() >= 0.0


def test_sampled_maps_are_reproducible() -> None:
    first = workspace_map(
        samples=60, seed=3, settings=WorkspaceSettings(clearance=False), progress=False
    )
    second = workspace_map(
        samples=60, seed=3, settings=WorkspaceSettings(clearance=False), progress=False
    )
    other = workspace_map(
        samples=60, seed=4, settings=WorkspaceSettings(clearance=False), progress=False
    )
    _same(first, second)
    assert not np.array_equal(first.theta, other.theta)
    assert first.seed == 3 and first.grid is None
    d = np.stack([first["d12_deg"], first["d23_deg"], first["d31_deg"]])
    assert d.min() >= 0.0 and d.max() <= 360.0


# ---------------------------------------------------------------- executors
def test_executors_give_the_same_map(coarse: WorkspaceMap) -> None:
    """Chunks in a process pool or in threads (each thread its own checker) give the
    serial map exactly, whatever order they finish in."""
    pool = workspace_map(
        step_deg=STEP, settings=coarse.settings, workers=2, chunk_size=97, progress=False
    )
    _same(pool, coarse)
    with concurrent.futures.ThreadPoolExecutor(max_workers=3) as threads:
        threaded = workspace_map(
            step_deg=STEP, settings=coarse.settings, executor=threads, chunk_size=50, progress=False
        )
    _same(threaded, coarse)


def test_dask_local_cluster(coarse: WorkspaceMap) -> None:
    """A Dask executor runs the same code: ``client.get_executor()``. The cluster uses
    threads (processes=False): starting worker processes would cost seconds per test
    while the scheduler, the task graph and the futures are the same; the thread-local
    checkers are what a threaded worker needs."""
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        result = workspace_map(
            step_deg=STEP,
            settings=coarse.settings,
            executor=client.get_executor(),
            chunk_size=60,
            progress=False,
        )
    _same(result, coarse)


# -------------------------------------------------------------------- files
def test_save_load_and_plots(coarse: WorkspaceMap, tmp_path: Path) -> None:
    written = coarse.save(tmp_path / "map")
    assert set(written) == {"npz", "csv", "summary", "gap_map", "orientation"}
    for kind in ("gap_map", "orientation"):
        assert written[kind].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    loaded = WorkspaceMap.load(tmp_path / "map")
    _same(loaded, coarse)
    assert loaded.settings == coarse.settings and loaded.design == coarse.design
    for name in ("reachable", "dexterity"):
        np.testing.assert_array_equal(loaded.image(name), coarse.image(name))
    with written["csv"].open() as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == len(coarse)
    k = int(np.flatnonzero(coarse["reachable"])[0])
    assert float(rows[k]["dexterity"]) == pytest.approx(coarse["dexterity"][k], rel=1e-8)
    assert int(rows[k]["reachable"]) == 1
    summary = json.loads(written["summary"].read_text())
    assert summary["summary"]["points"] == len(coarse)
    with pytest.raises(spm.FileFormatError, match=r"workspace\.csv: not a workspace map"):
        WorkspaceMap.load(written["csv"])


def test_gap_map_legends(coarse: WorkspaceMap) -> None:
    """The yes/no maps carry a legend of exactly their two values (no 0-1 colour bar);
    the continuous maps a colour bar each."""
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    from spm_pin.workspace.result import BINARY_PANELS, GAP_PANELS

    figure = coarse.gap_figure()
    try:
        panels = {axis.get_title(): axis for axis in figure.axes if axis.get_title()}
        assert len(panels) == len(GAP_PANELS)
        for name, title, _ in GAP_PANELS:
            legend = panels[title].get_legend()
            if name in BINARY_PANELS:
                no, yes = BINARY_PANELS[name]
                assert legend is not None, title
                assert [text.get_text() for text in legend.get_texts()] == [yes[0], no[0]]
                # both values occur on this map, so neither entry is empty
                assert np.any(coarse[name]) and not np.all(coarse[name])
            else:
                assert legend is None, title
        colorbars = len(figure.axes) - len(GAP_PANELS)
        assert colorbars == len(GAP_PANELS) - len(BINARY_PANELS)
    finally:
        plt.close(figure)


def test_cli_workspace(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ws"
    argv = ["workspace", "--step", "30", "--no-plots", "--quiet", "--json", "--out", str(out)]
    assert cli_main(argv) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["step_deg"] == 30.0
    assert 0.0 < record["reachable_fraction"] < 1.0
    assert (out / "workspace.npz").is_file() and (out / "workspace.csv").is_file()
    assert not (out / "gap_map.png").exists()
    assert cli_main(["workspace", "--step", "0", "--quiet", "--out", str(out)]) == 2
    assert "step_deg" in capsys.readouterr().err


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"design": get_design("agile_eye")}, "design"),
        ({"step_deg": 0.0}, "step_deg"),
        ({"step_deg": math.nan}, "step_deg"),
        ({"gap_range_deg": (10.0, 5.0)}, "gap_range_deg"),
        ({"gap_range_deg": (130.0, 300.0)}, "gap_range_deg"),
        ({"gap_range_deg": "wide"}, "gap_range_deg"),
        ({"samples": 0}, "samples"),
        ({"samples": 10, "seed": -1}, "seed"),
        ({"settings": {"margin": 0.0}}, "settings"),
        ({"settings": WorkspaceSettings(margin=0.5)}, "settings.margin"),  # > 0.1 m
        ({"settings": WorkspaceSettings(ladder=(0.001,))}, "settings.ladder"),
        ({"executor": object()}, "executor"),
        ({"workers": 0}, "workers"),
        ({"chunk_size": 1.5}, "chunk_size"),
    ],
)
def test_bad_input(kwargs: dict[str, Any], argument: str) -> None:
    with pytest.raises(spm.InputError, match=rf"\b{re.escape(argument)}\b") as info:
        workspace_map(progress=False, **kwargs)
    assert info.value.argument == argument
    assert argument.split(".")[-1] in str(info.value)


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"margin": -1.0}, "margin"),
        ({"margin": math.nan}, "margin"),
        ({"min_dexterity": 2.0}, "min_dexterity"),
        ({"clearance": "yes"}, "clearance"),
    ],
)
def test_bad_settings(kwargs: dict[str, Any], argument: str) -> None:
    with pytest.raises(spm.InputError, match=argument) as info:
        WorkspaceSettings(**kwargs)
    assert info.value.argument == argument


def test_bad_gaps_and_fields(coarse: WorkspaceMap) -> None:
    with pytest.raises(spm.InputError, match="gaps"):
        gap_inputs([1.0, math.nan], 3.0)
    with pytest.raises(spm.InputError, match="name"):
        coarse.image("height")
    with pytest.raises(spm.InputError, match="pair"):
        coarse.pair_collides(("base", "proximal_1"))
    sampled = workspace_map(samples=5, settings=WorkspaceSettings(clearance=False), progress=False)
    with pytest.raises(spm.InputError, match="grid"):
        sampled.image("reachable")
