"""Design studies on a Dask distributed cluster (run_study(scheduler=...), _engines).

One real ``LocalCluster`` of two worker processes for the module (started once: a
worker process costs seconds to start and to import Pinocchio). Its trials are scored
exactly as this process scores the same design values; a study stopped by Ctrl-C in
the driver leaves no trial running in its storage and resumes on the cluster; a
design that does not assemble, an evaluation that raises and a worker that dies are
failed trials with their reason.
"""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

optuna = pytest.importorskip("optuna")
distributed = pytest.importorskip("distributed")

from spm_pin.errors import InputError  # noqa: E402
from spm_pin.optimize import (  # noqa: E402
    DesignSpace,
    Variable,
    _engines,
)
from spm_pin.optimize._engines import local_cluster_options  # noqa: E402
from spm_pin.optimize.study import StudySettings, evaluate, run_study  # noqa: E402

SPACE = DesignSpace((Variable("alpha1_deg", 35.0, 75.0), Variable("alpha2_deg", 60.0, 120.0)))
OBJECTIVES = ["max_tilt", "safe_fraction", "peak_torque"]
FAST = StudySettings(step_deg=8.0, motion_samples=24)
#: alpha1 [deg] of the designs whose evaluation the workers are made to fail.
RAISES_AT, DIES_AT = 36.0, 74.0


@pytest.fixture(scope="module")
def cluster() -> Iterator[Any]:
    with distributed.LocalCluster(**local_cluster_options(2)) as local:
        yield local


def _same_as_in_process(result: Any) -> None:
    """Every completed trial's scores and constraints equal this process's evaluation
    of its design values, to the bit."""
    for trial in result.trials:
        if trial.state != "COMPLETE":
            continue
        truth = evaluate(SPACE.design(trial.values), OBJECTIVES, FAST)
        assert trial.scores == truth.scores, trial.number
        assert trial.constraints == truth.constraints, trial.number


def _interrupt_after_first(record: Any) -> None:
    raise KeyboardInterrupt


def test_a_study_on_the_cluster_scores_as_this_process_and_resumes(
    cluster: Any, tmp_path: Path
) -> None:
    storage = tmp_path / "study.log"
    kwargs: dict[str, Any] = {
        "settings": FAST,
        "population_size": 4,
        "seed": 1,
        "storage": storage,
        "scheduler": cluster.scheduler_address,
    }
    # Ctrl-C in the driver after the first trial: the trials in flight are failed.
    with pytest.raises(KeyboardInterrupt):
        run_study(SPACE, OBJECTIVES, 6, callback=_interrupt_after_first, **kwargs)
    stopped = optuna.load_study(
        study_name="spm-optimize",
        storage=optuna.storages.JournalStorage(
            optuna.storages.journal.JournalFileBackend(str(storage))
        ),
    )
    states = [t.state.name for t in stopped.trials]
    assert states.count("COMPLETE") == 1 and "FAIL" in states, states
    assert set(states) == {"COMPLETE", "FAIL"}  # nothing left running
    assert all(
        t.user_attrs["error"] == "interrupted" for t in stopped.trials if t.state.name == "FAIL"
    )
    # Resumed on the cluster up to 6 trials in all; every one finished and scored as here.
    resumed = run_study(SPACE, OBJECTIVES, 6, **kwargs)
    assert resumed.new_trials == 6 - len(states)
    assert [t.number for t in resumed.trials] == list(range(6))
    fresh = [t for t in resumed.trials if t.number >= len(states)]
    assert fresh and all(t.state == "COMPLETE" for t in fresh)
    _same_as_in_process(resumed)
    # A cluster of its own (workers=2) runs a new study through; all complete.
    local = run_study(SPACE, OBJECTIVES, 3, settings=FAST, population_size=4, seed=1, workers=2)
    assert [t.state for t in local.trials] == ["COMPLETE"] * 3
    _same_as_in_process(local)


def test_designs_that_cannot_be_evaluated_are_failed_trials_on_the_cluster(cluster: Any) -> None:
    # Proximal links as large as the distal ones do not assemble (DesignError).
    space = DesignSpace((Variable("proximal_radius", 0.05, 0.12),))
    result = run_study(
        space, ["tilt"], 6, settings=FAST, seed=0, scheduler=cluster.scheduler_address
    )
    states = [t.state for t in result.trials]
    assert len(states) == 6 and "FAIL" in states and "COMPLETE" in states
    failed = [t for t in result.trials if t.state == "FAIL"]
    assert all(t.error and t.error.startswith("DesignError") for t in failed)
    assert all(t.values["proximal_radius"] > 0.08 for t in failed)


def _failing_evaluate() -> None:
    """On a worker: the evaluation raises at alpha1 = RAISES_AT and the worker process
    dies at alpha1 = DIES_AT (the real evaluation otherwise)."""
    from spm_pin.optimize import study

    original = study.evaluate

    def failing(design: Any, objectives: Any, settings: Any = None) -> Any:
        alpha1 = round(math.degrees(design.alpha1), 9)
        if alpha1 == RAISES_AT:
            raise RuntimeError("evaluation failed on purpose")
        if alpha1 == DIES_AT:
            os._exit(1)
        return original(design, objectives, settings)

    study.evaluate = failing  # type: ignore[assignment]


def test_an_evaluation_that_raises_or_a_worker_that_dies_is_a_failed_trial(cluster: Any) -> None:
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    scheduler = cluster.scheduler
    allowed, scheduler.allowed_failures = scheduler.allowed_failures, 0  # no retry
    try:
        with distributed.Client(cluster.scheduler_address) as client:
            client.run(_failing_evaluate)
        result = run_study(
            SPACE,
            OBJECTIVES,
            5,
            settings=FAST,
            population_size=4,
            seed=2,
            enqueue=[{"alpha1_deg": RAISES_AT, "alpha2_deg": 90.0}],
            scheduler=cluster.scheduler_address,
        )
        # The dead worker's replacement evaluates as usual; the other is still patched.
        dying = run_study(
            SPACE,
            OBJECTIVES,
            3,
            settings=FAST,
            population_size=4,
            seed=2,
            enqueue=[{"alpha1_deg": DIES_AT, "alpha2_deg": 90.0}],
            scheduler=cluster.scheduler_address,
        )
    finally:
        scheduler.allowed_failures = allowed
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
        with distributed.Client(cluster.scheduler_address) as client:
            client.restart()  # workers without the patch for any later test
    first = result.trials[0]
    assert first.state == "FAIL" and first.error == "RuntimeError: evaluation failed on purpose"
    assert len(result.trials) == 5 and [t.state for t in result.trials[1:]] == ["COMPLETE"] * 4
    _same_as_in_process(result)
    killed = dying.trials[0]
    assert killed.state == "FAIL" and killed.error and killed.error.startswith("KilledWorker")
    # A trial queued on the same worker may die with it; none is left running.
    assert len(dying.trials) == 3
    assert all(t.state == "COMPLETE" or "KilledWorker" in (t.error or "") for t in dying.trials)


def test_bad_engine_arguments_are_input_errors(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for kwargs in (
        {"workers": 0},
        {"workers": 1.5},
        {"scheduler": ""},
        {"workers": 2, "scheduler": "tcp://127.0.0.1:1"},
    ):
        with pytest.raises(InputError):
            run_study(SPACE, ["tilt"], 2, **kwargs)  # type: ignore[arg-type]
    # Nothing answers there (port 1): an InputError naming the address.
    monkeypatch.setattr(_engines, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(InputError, match="no Dask scheduler"):
        run_study(SPACE, ["tilt"], 2, storage=tmp_path / "s.log", scheduler="tcp://127.0.0.1:1")


def test_spm_optimize_on_a_scheduler(
    cluster: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from spm_pin.cli import main

    storage = str(tmp_path / "cli.log")
    argv = [
        "optimize", "--vary", "alpha1=35:75", "--trials", "3", "--step", "8", "--storage",
        storage, "--scheduler", cluster.scheduler_address, "--json",
    ]  # fmt: skip
    assert main(argv) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["trials"] == record["new_trials"] == record["complete"] == 3
    assert record["scheduler"] == cluster.scheduler_address and record["workers"] == 1
    for bad in ([*argv[:-1], "--workers", "2"], [*argv[:-3], "--workers", "0"]):
        assert main(bad) == 2
        err = capsys.readouterr().err
        assert err.startswith("spm: error: ") and err.count("\n") == 1
