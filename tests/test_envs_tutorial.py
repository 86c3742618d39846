"""The pieces around the learning tutorial: the MuJoCo peer of the environment
benchmark (its task matches ``spm_pin/OrientDynamic-v0``'s), the figures of a quick
benchmark run, and the observation that ``examples/train_ppo.py`` builds from servo
readings (it must equal the environment's)."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from spm_pin.envs import OrientEnv, OrientVectorEnv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

#: Tolerances (absolute, in the unit the name says).
TOL = {
    "observation": 1e-6,  # float32 observations
    "closure_rad": 1e-10,  # loop closure of the reduced dynamics' states
    "home_rad": 1e-2,  # the platform at home, held by the servos (P gain sags under gravity)
}


def _example(name: str):  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_example_observation_is_the_environments() -> None:
    env = OrientEnv(goal="random", start="random")
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    for _ in range(3):
        obs, *_ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
    core = env.core
    rebuilt = _example("train_ppo").observation_of(
        core.R[0], core.goal[0], core.theta[0], core.speed[0], core.limits.max_speed
    )
    np.testing.assert_allclose(rebuilt, obs, atol=TOL["observation"])


def test_mujoco_peer_is_a_gymnasium_env_of_the_same_task() -> None:
    pytest.importorskip("mujoco")
    from gymnasium.utils.env_checker import check_env

    from benchmarks._mujoco_env import MujocoOrientEnv

    vector = OrientVectorEnv(8)
    vector.reset(seed=0)
    env = MujocoOrientEnv(vector.core.goal.copy())
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=1)
    assert obs.shape == OrientEnv().observation_space.shape and obs.dtype == np.float32
    # at home, the servos hold the platform level: its first two columns are e_x, e_y
    for _ in range(5):
        obs, *_ = env.step(np.zeros(3, dtype=np.float32))
    np.testing.assert_allclose(obs[:6], [1, 0, 0, 0, 1, 0], atol=TOL["home_rad"])
    assert env.frame_skip == 20 and math.isclose(env.model.opt.timestep, 1e-3)
    # the goal is one of the bank's rotations, and the error the geodesic angle to it
    goal = obs[6:12]
    assert any(np.allclose(goal, np.concatenate([G[:, 0], G[:, 1]]), atol=1e-6) for G in env.goals)


def test_quick_benchmark_compares_with_mujoco_and_the_simulator(tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    from benchmarks import _figures, bench_envs

    out = tmp_path / "envs.json"
    assert bench_envs.main(["--quick", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    dynamic, mj, physics = data["dynamic"], data["mujoco_peer"], data["physics"]
    assert dynamic["vector"]["n"] == bench_envs.QUICK.dynamic_batch
    assert mj["available"] and mj["vector"]["n"] == dynamic["vector_peer_n"]["n"]
    assert mj["physics_steps_per_env_step"] == dynamic["physics_steps_per_env_step"] == 20
    # the reduced dynamics keep the loops closed; MuJoCo's soft welds do not
    assert dynamic["closure_error"] < TOL["closure_rad"] < mj["closure_error"]
    assert physics["reduced_closure_error"] < TOL["closure_rad"]
    assert physics["constrained_closure_error"] < TOL["closure_rad"]
    # both physics swung the same robot from the same start for the same time
    np.testing.assert_allclose(
        physics["final_theta_rad"]["reduced"], physics["final_theta_rad"]["constrained"], atol=1e-3
    )
    analysis = _figures.analyse(_figures.BENCHMARKS["envs"], data)
    assert analysis.adapter_error is None
    keys = {f.key: f for f in analysis.figures}
    assert {"dynamic_vector_step", "dynamic_single_step", "reduced_closure"} <= set(keys)
    assert keys["dynamic_single_step"].peer_name == "MuJoCo env"
    # the targets' rows: timed in windows side by side with their peers
    quick = bench_envs.QUICK
    for entry, (windows, ours, theirs) in (
        (data["cover"]["cover_only"], quick.side_kinematic),
        (dynamic["vector_cover_only"], quick.side_dynamic),
        (dynamic["single_cover_only"], quick.side_single),
    ):
        assert entry["windows"] == windows
        assert entry["samples"] == windows * ours and entry["peer"]["samples"] == windows * theirs
        assert entry["paired_ratio_ours_vs_peer"] > 0
    assert dynamic["vector_cover_only"]["peer"]["n"] == mj["vector"]["n"]
    assert keys["dynamic_single_step_cover_only"].peer_name == "MuJoCo env, side by side"
    assert keys["reduced_step"].peer_name == "constrained Simulator"
