"""Design studies on Optuna: search a :class:`~spm_pin.optimize.DesignSpace` for the
designs that are best by one or several objectives, under constraints.

* Objectives are chosen by name from :data:`OBJECTIVES`, each with its direction.
* Constraints (:class:`StudySettings`): no collision at home (home clearance above
  the margin), the peak motor torque within a limit, a required cone of tilts safe in
  every direction. They reach the sampler through Optuna's ``constraints_func``: a
  trial that breaks one is kept but ranks behind every feasible trial.
* The sampler: NSGA-II for several objectives, TPE for one. Each trial is sampled by
  a sampler seeded from (seed, trial number), so a study is a function of its seed
  and of the trials already in its storage: a run stopped after k trials and resumed
  draws the same trials as a run that never stopped.
* The storage: an Optuna JournalStorage file (an append-only log of the study's
  operations; a path), or any Optuna RDB URL (``sqlite:///study.db``). A second run
  on the same file continues the study: it counts the trials already there and runs
  only the remaining ones; it refuses a study of another space, objectives or
  settings (:class:`~spm_pin.errors.InputError`).
* A design that cannot be evaluated (it does not assemble, the required motion leaves
  its workspace: any :class:`~spm_pin.SPMError`) is recorded as a failed trial with
  its reason in the trial's ``error`` attribute; the study goes on.
* The engine: this process, one trial after the other (deterministic for a seed), or
  a Dask distributed cluster (``workers`` local processes, or the cluster of a
  ``scheduler`` address), several trials in flight (see
  :mod:`spm_pin.optimize._engines`). Only this process touches the storage. On a
  cluster the trials are told in the order they complete, so a seed fixes each
  trial's sampler but not which trials it has seen: not the exact trials.

Optuna is an optional dependency (``pip install spm-pin[optimize]``), imported when a
study runs.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..design import SPMDesign
from ..errors import InputError, SPMError
from ._engines import ClusterError
from ._margin_check import margin_check_of
from ._progress import Progress as _Progress
from ._progress import quiet_optuna as _quiet_optuna
from .objectives import DesignSpace, cone_dexterity, envelope, global_conditioning_index
from .scoring import safe_workspace_score
from .torque import Payload, cone_motion, peak_torque

__all__ = [
    "OBJECTIVES",
    "ClusterError",
    "Evaluation",
    "Objective",
    "StudyResult",
    "StudySettings",
    "TrialRecord",
    "evaluate",
    "run_study",
]

#: The name of the study inside a storage.
STUDY_NAME = "spm-optimize"
#: Version of the study description kept in the storage (refused if it differs).
SPEC_VERSION = 1
#: The key of the study description among the study's user attributes.
SPEC_KEY = "spm_pin.spec"


@dataclasses.dataclass(frozen=True)
class Objective:
    """One objective of a study.

    Attributes:
        name: Its name (a key of :data:`OBJECTIVES`).
        direction: ``"maximize"`` or ``"minimize"``.
        unit: Its unit.
        description: What it measures.
    """

    name: str
    direction: str
    unit: str
    description: str


#: The objectives a study may choose, by name.
OBJECTIVES: Mapping[str, Objective] = {
    o.name: o
    for o in (
        Objective("tilt", "maximize", "deg", "largest tilt safe in every direction (0 if none)"),
        Objective("max_tilt", "maximize", "deg", "largest safe tilt in any direction (0 if none)"),
        Objective("safe_fraction", "maximize", "1", "safe share of the gap plane"),
        Objective("gci", "maximize", "1", "mean dexterity over the safe points (0 if none)"),
        Objective(
            "cone_dexterity", "maximize", "1", "worst dexterity over the required cone of tilts"
        ),
        Objective(
            "peak_torque", "minimize", "N m", "largest motor torque along the required motion"
        ),
        Objective("envelope", "minimize", "m", "radius of the ball that holds the moving links"),
    )
}

#: Objectives read from the safe workspace score.
_SCORE_OBJECTIVES = frozenset({"tilt", "max_tilt", "safe_fraction", "gci"})


@dataclasses.dataclass(frozen=True)
class StudySettings:
    """How a study scores a design, and its constraints.

    Attributes:
        step_deg: Grid step of the safe workspace score [deg] (coarser is faster).
        margin: Safety margin of the safe set and of the home clearance [m].
        min_dexterity: Smallest dexterity of a safe point.
        cone_deg: Half-angle of the cone of ``cone_dexterity`` [deg].
        cone_step_deg: Grid step of that cone [deg].
        motion_tilt_deg, motion_period_s, motion_samples: The required motion of
            ``peak_torque``: :func:`~spm_pin.optimize.cone_motion` at that tilt, one
            turn in that time, so many samples.
        payload_kg: Point mass on the platform's axis [kg] ...
        payload_height_m: ... at this height above the centre O [m].
        require_home_clearance: Constraint: the links at home farther apart than
            ``margin``.
        max_torque_nm: Constraint: the peak torque at most this [N m] (None: none;
            the XM540-W150's stall torque is 7.3 N m).
        required_tilt_deg: Constraint: the safe tilt in every direction at least this
            [deg] (None: none), on the score's grid.

    Raises:
        InputError: a value out of its range.
    """

    step_deg: float = 6.0
    margin: float = 0.0
    min_dexterity: float = 0.2
    cone_deg: float = 20.0
    cone_step_deg: float = 5.0
    motion_tilt_deg: float = 20.0
    motion_period_s: float = 2.0
    motion_samples: int = 72
    payload_kg: float = 0.0
    payload_height_m: float = 0.05
    require_home_clearance: bool = True
    max_torque_nm: float | None = None
    required_tilt_deg: float | None = None

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if field.name == "require_home_clearance":
                ok = isinstance(value, bool)
            elif value is None and field.name in ("max_torque_nm", "required_tilt_deg"):
                ok = True
            elif field.name == "motion_samples":
                ok = isinstance(value, int) and not isinstance(value, bool) and value >= 4
            else:
                ok = (
                    isinstance(value, int | float)
                    and not isinstance(value, bool)
                    and math.isfinite(value)
                    and value >= 0.0
                )
            if not ok:
                raise InputError(
                    f"{field.name} must be a finite number >= 0 (or of its type), got {value!r}",
                    argument=field.name,
                    value=value,
                )

    def payload(self) -> Payload:
        """The payload of ``peak_torque``."""
        return Payload(self.payload_kg, (0.0, 0.0, self.payload_height_m))

    def constraint_names(self) -> tuple[str, ...]:
        """The constraints that are on, in order."""
        names = []
        if self.require_home_clearance:
            names.append("home_clearance")
        if self.max_torque_nm is not None:
            names.append("peak_torque")
        if self.required_tilt_deg is not None:
            names.append("required_tilt")
        return tuple(names)


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """The objectives and constraints of one design.

    Attributes:
        scores: Objective values by name (maximized or minimized, see
            :data:`OBJECTIVES`).
        constraints: Constraint values by name: <= 0 where the constraint holds
            (home_clearance: margin - clearance [m]; peak_torque: peak - limit
            [N m]; required_tilt: required - safe tilt in every direction [deg]).
    """

    scores: dict[str, float]
    constraints: dict[str, float]

    @property
    def feasible(self) -> bool:
        """Every constraint holds."""
        return all(value <= 0.0 for value in self.constraints.values())


def _check_objectives(objectives: Sequence[str]) -> tuple[str, ...]:
    if isinstance(objectives, str) or not isinstance(objectives, Sequence):
        raise InputError(
            f"objectives must be a list of names, got {objectives!r}", argument="objectives"
        )
    names = tuple(objectives)
    unknown = [n for n in names if n not in OBJECTIVES]
    if not names or unknown or len(set(names)) != len(names):
        raise InputError(
            f"objectives must be distinct names from {sorted(OBJECTIVES)}, got {list(names)}"
            + (f" (unknown: {unknown})" if unknown else ""),
            argument="objectives",
            value=objectives,
        )
    return names


def _check_coaxial(design: SPMDesign, names: Sequence[str], settings: StudySettings) -> None:
    """The workspace objectives and the required tilt score the gap plane: coaxial
    designs only."""
    needs = [n for n in names if n in _SCORE_OBJECTIVES]
    if settings.required_tilt_deg is not None:
        needs.append("--required-tilt")
    if needs and not design.is_coaxial:
        raise InputError(
            f"{', '.join(needs)} score the safe workspace in the gap plane of a coaxial "
            f"design; {design.name!r} is not coaxial: choose from cone_dexterity, "
            "peak_torque, envelope",
            argument="objectives",
        )


def evaluate(
    design: SPMDesign, objectives: Sequence[str], settings: StudySettings | None = None
) -> Evaluation:
    """The objectives and constraints of one design, as a study computes them.

    Raises:
        InputError: an unknown objective, or a workspace objective (or the required
            tilt) for a design that is not coaxial.
        SPMError: the design cannot be evaluated (it does not assemble, the motion
            leaves its workspace, ...).
    """
    names = _check_objectives(objectives)
    settings = StudySettings() if settings is None else settings
    _check_coaxial(design, names, settings)
    scores: dict[str, float] = {}
    constraints: dict[str, float] = {}
    score = None
    if _SCORE_OBJECTIVES & set(names) or settings.required_tilt_deg is not None:
        score = safe_workspace_score(
            design,
            step_deg=settings.step_deg,
            margin=settings.margin,
            min_dexterity=settings.min_dexterity,
        )
    torque = None
    if "peak_torque" in names or settings.max_torque_nm is not None:
        motion = cone_motion(
            settings.motion_tilt_deg, settings.motion_period_s, settings.motion_samples
        )
        torque = peak_torque(design, motion, settings.payload()).peak_nm
    for name in names:
        if name == "tilt":
            assert score is not None
            scores[name] = score.safe_tilt_every_direction_deg or 0.0
        elif name == "max_tilt":
            assert score is not None
            scores[name] = score.max_safe_tilt_deg or 0.0
        elif name == "safe_fraction":
            assert score is not None
            scores[name] = score.safe_fraction
        elif name == "gci":
            assert score is not None
            scores[name] = global_conditioning_index(score) or 0.0
        elif name == "cone_dexterity":
            scores[name] = cone_dexterity(
                design, settings.cone_deg, step_deg=settings.cone_step_deg
            ).worst_dexterity
        elif name == "peak_torque":
            assert torque is not None
            scores[name] = torque
        elif name == "envelope":
            scores[name] = envelope(robot=margin_check_of(design).robot).radius_m
    if settings.require_home_clearance:
        check = margin_check_of(design)
        distances = check.checker.distances(check.robot.configuration(np.zeros(3)))
        constraints["home_clearance"] = settings.margin - float(min(distances.values()))
    if settings.max_torque_nm is not None:
        assert torque is not None
        constraints["peak_torque"] = torque - settings.max_torque_nm
    if settings.required_tilt_deg is not None:
        assert score is not None
        every = score.safe_tilt_every_direction_deg
        constraints["required_tilt"] = settings.required_tilt_deg - (
            every if every is not None else -90.0
        )
    return Evaluation(scores=scores, constraints=constraints)


@dataclasses.dataclass(frozen=True)
class _Outcome:
    """What the evaluation of one trial sends back to the driver (picklable).

    Attributes:
        scores: The objective values, in the study's order (None if it failed).
        constraints: The constraint values by name ({} if it failed).
        error: Why it failed (None if it did not).
    """

    scores: tuple[float, ...] | None
    constraints: dict[str, float]
    error: str | None


def _evaluate_trial(
    space: DesignSpace,
    values: dict[str, float],
    names: tuple[str, ...],
    settings: StudySettings,
    label: str,
) -> _Outcome:
    """The evaluation of one trial's design values: a pure top-level function, run in
    the driver or on a Dask worker. A design that cannot be evaluated (an
    :class:`~spm_pin.SPMError`) is an outcome with its reason, not an exception."""
    try:
        design = space.design(values, name=label)
        result = evaluate(design, names, settings)
    except SPMError as exc:
        return _Outcome(None, {}, f"{type(exc).__name__}: {exc}")
    return _Outcome(tuple(result.scores[n] for n in names), result.constraints, None)


@dataclasses.dataclass(frozen=True)
class TrialRecord:
    """One trial of a study.

    Attributes:
        number: The trial's number (from 0, in the order of the study).
        state: ``"COMPLETE"`` or ``"FAIL"``.
        values: The design's variables.
        scores: Its objective values ({} if it failed).
        constraints: Its constraint values ({} if it failed).
        feasible: Completed and every constraint holds.
        error: Why it failed (None if it did not).
    """

    number: int
    state: str
    values: dict[str, float]
    scores: dict[str, float]
    constraints: dict[str, float]
    feasible: bool
    error: str | None

    def record(self) -> dict[str, Any]:
        """As plain data (JSON)."""
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class StudyResult:
    """The trials of a study and its Pareto front.

    Attributes:
        study: The Optuna study (its storage holds everything).
        objectives: The objectives, in order.
        trials: Every finished trial, in order.
        pareto: The feasible completed trials that no other feasible one dominates
            (for one objective: the best ones).
        new_trials: Trials run by this call (the others were in the storage).
        seconds: Time this call took [s].
    """

    study: Any
    objectives: tuple[Objective, ...]
    trials: tuple[TrialRecord, ...]
    pareto: tuple[TrialRecord, ...]
    new_trials: int
    seconds: float

    def summary(self) -> dict[str, Any]:
        """The study as plain data (what ``spm optimize --json`` prints)."""
        return {
            "objectives": [
                {"name": o.name, "direction": o.direction, "unit": o.unit} for o in self.objectives
            ],
            "trials": len(self.trials),
            "new_trials": self.new_trials,
            "complete": sum(t.state == "COMPLETE" for t in self.trials),
            "failed": sum(t.state == "FAIL" for t in self.trials),
            "feasible": sum(t.feasible for t in self.trials),
            "pareto": [t.record() for t in self.pareto],
        }


def _spec(
    space: DesignSpace,
    objectives: tuple[str, ...],
    settings: StudySettings,
    seed: int,
    population_size: int,
) -> dict[str, Any]:
    """What a study is: stored with it, compared when it is resumed."""
    return {
        "version": SPEC_VERSION,
        "variables": [[v.name, float(v.low), float(v.high)] for v in space.variables],
        "base": space.base.to_dict(),
        "objectives": list(objectives),
        "settings": dataclasses.asdict(settings),
        "seed": seed,
        "population_size": population_size if len(objectives) > 1 else None,
    }


def _trial_seed(seed: int, number: int) -> int:
    """The seed of trial ``number``'s sampler: a hash of (seed, number)."""
    digest = hashlib.sha256(f"spm-optimize:{seed}:{number}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def _constraints_of(trial: Any) -> Sequence[float]:
    values: Sequence[float] = trial.user_attrs.get("constraints", [])
    return values


def _native_constraints() -> bool:
    """Optuna >= 5 takes constraints per trial (``Trial.set_constraint``); Optuna 4
    through the samplers' ``constraints_func`` (deprecated in 5)."""
    import optuna

    return hasattr(optuna.trial.Trial, "set_constraint")


def _sampler(
    n_objectives: int, seed: int, population_size: int, constrained: bool, *, parallel: bool
) -> Any:
    """The sampler of one trial; ``parallel``: trials are in flight meanwhile (TPE
    then takes them as a constant liar, so it does not propose the same design twice;
    Optuna 5's default, asked for explicitly on Optuna 4)."""
    import optuna

    constraints = _constraints_of if constrained and not _native_constraints() else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        if n_objectives > 1:
            return optuna.samplers.NSGAIISampler(
                population_size=population_size, seed=seed, constraints_func=constraints
            )
        if parallel:
            return optuna.samplers.TPESampler(
                seed=seed, constraints_func=constraints, constant_liar=True
            )
        return optuna.samplers.TPESampler(seed=seed, constraints_func=constraints)


def _fail_running(study: Any, reason: str) -> None:
    """Record the study's RUNNING trials as failed, with ``reason`` as their error."""
    from optuna.trial import TrialState

    for stale in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        study._storage.set_trial_user_attr(stale._trial_id, "error", reason)
        study._storage.set_trial_state_values(stale._trial_id, TrialState.FAIL)


def _storage(storage: str | Path | None) -> Any:
    """An Optuna storage: None (in memory), an RDB URL, or a journal file path."""
    import optuna
    from optuna.storages.journal import JournalFileBackend, JournalStorage

    if storage is None:
        return optuna.storages.InMemoryStorage()
    if isinstance(storage, str) and "://" in storage:
        return storage
    if not isinstance(storage, str | Path) or not str(storage):
        raise InputError(
            f"storage must be a file path or an RDB URL, got {storage!r}", argument="storage"
        )
    path = Path(storage)
    if path.exists() and not path.is_file():
        raise InputError(f"storage {str(path)!r} is not a file", argument="storage")
    return JournalStorage(JournalFileBackend(str(path)))


def _record(trial: Any, names: tuple[str, ...]) -> TrialRecord:
    """The record of a finished (COMPLETE or FAIL) Optuna ``FrozenTrial``."""
    from optuna.trial import TrialState

    complete = trial.state == TrialState.COMPLETE
    constraint_names = trial.user_attrs.get("constraint_names", []) if complete else []
    constraint_values = trial.user_attrs.get("constraints", []) if complete else []
    constraints = dict(zip(constraint_names, constraint_values, strict=True))
    return TrialRecord(
        number=trial.number,
        state=trial.state.name,
        values={k: float(v) for k, v in trial.params.items()},
        scores=dict(zip(names, trial.values, strict=True)) if complete else {},
        constraints=constraints,
        feasible=complete and all(c <= 0.0 for c in constraint_values),
        error=trial.user_attrs.get("error"),
    )


def _records(study: Any, names: tuple[str, ...]) -> tuple[TrialRecord, ...]:
    from optuna.trial import TrialState

    return tuple(
        _record(trial, names)
        for trial in study.get_trials(deepcopy=False)
        if trial.state in (TrialState.COMPLETE, TrialState.FAIL)
    )


def _check_engine(workers: int, scheduler: str | None) -> None:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(
            f"workers must be an integer >= 1, got {workers!r}", argument="workers", value=workers
        )
    if scheduler is None:
        return
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise InputError(
            f"scheduler must be the address of a Dask scheduler (tcp://host:port), "
            f"got {scheduler!r}",
            argument="scheduler",
            value=scheduler,
        )
    if workers != 1:
        raise InputError(
            f"workers={workers} starts a local cluster; with scheduler={scheduler!r} the "
            "cluster's own workers run the trials: give one or the other",
            argument="workers",
            value=workers,
        )


def _pareto(
    records: tuple[TrialRecord, ...], objectives: tuple[Objective, ...]
) -> tuple[TrialRecord, ...]:
    """The feasible trials that no other feasible trial dominates."""
    feasible = [r for r in records if r.feasible]
    if not feasible:
        return ()
    sign = np.array([1.0 if o.direction == "maximize" else -1.0 for o in objectives])
    points = np.array([[r.scores[o.name] for o in objectives] for r in feasible]) * sign
    front = []
    for k, record in enumerate(feasible):
        better_or_equal = np.all(points >= points[k], axis=1)
        strictly = np.any(points > points[k], axis=1)
        if not np.any(better_or_equal & strictly):
            front.append(record)
    return tuple(front)


def run_study(
    space: DesignSpace,
    objectives: Sequence[str],
    n_trials: int,
    *,
    settings: StudySettings | None = None,
    seed: int = 0,
    storage: str | Path | None = None,
    population_size: int = 20,
    enqueue: Sequence[Mapping[str, float]] = (),
    progress: bool = False,
    callback: Callable[[TrialRecord], None] | None = None,
    workers: int = 1,
    scheduler: str | None = None,
) -> StudyResult:
    """Run (or continue) a design study until it holds ``n_trials`` trials.

    Args:
        space: The variables and their bounds.
        objectives: Names from :data:`OBJECTIVES` (one: TPE; several: NSGA-II).
        n_trials: The trials the study should hold in all (failed ones count): a
            study resumed from ``storage`` runs only the missing ones.
        settings: How designs are scored and the constraints (default
            :class:`StudySettings`).
        seed: The seed: one seed, one sequence of trials.
        storage: A journal file path (created if missing, continued if it holds this
            study), an Optuna RDB URL such as ``sqlite:///study.db``, or None (in
            memory).
        population_size: NSGA-II's population (several objectives).
        enqueue: Designs (values of the variables) to evaluate first, when the study
            is new (for example the base design, as a reference).
        progress: A progress bar on stderr.
        callback: Called with each new finished trial (in the order they finish).
        workers: Worker processes: 1 evaluates the trials in this process, one after
            the other (deterministic for a seed); more start a Dask ``LocalCluster``
            of that many processes (one thread each) for this call.
        scheduler: The address of a running Dask scheduler (``tcp://host:8786``):
            its workers evaluate the trials (``workers`` must then be 1). With a
            cluster, up to two trials per worker thread are in flight; they are told
            as they complete, so a seed fixes the sampler but not the exact trials.
            Only this process touches ``storage``. In a script, call ``run_study``
            under ``if __name__ == "__main__":`` (the local workers are spawned).

    Returns:
        :class:`StudyResult`.

    Raises:
        InputError: an unknown or repeated objective, ``n_trials`` not a positive
            integer, a bad seed, population or enqueued design, or a storage that
            holds another study (other space, objectives, settings or seed) or is not
            an Optuna storage; ``workers`` not a positive integer, a bad
            ``scheduler``, or both given; no scheduler answers at ``scheduler``.
        ClusterError: the cluster cancelled the evaluations (its scheduler went
            away); the trials in flight are recorded as failed ("interrupted").
        ImportError: Optuna, or Dask distributed for a cluster, is not installed.

    A trial whose evaluation raised on a worker, or whose worker died, is a failed
    trial with the reason in its ``error``. Whatever stops the call (Ctrl-C
    included), the trials in flight are recorded as failed ("interrupted"): the
    storage stays consistent and a new call continues the study.
    """
    try:
        import optuna
        from optuna.trial import TrialState
    except ImportError as exc:
        raise ImportError(
            f"design studies need Optuna: pip install 'spm-pin[optimize]' ({exc})"
        ) from None

    start = time.perf_counter()
    if not isinstance(space, DesignSpace):
        raise InputError(
            f"space must be a DesignSpace, got {type(space).__name__}", argument="space"
        )
    names = _check_objectives(objectives)
    for name, value, low in (("n_trials", n_trials, 1), ("population_size", population_size, 2)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise InputError(f"{name} must be an integer >= {low}, got {value!r}", argument=name)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        raise InputError(f"seed must be an integer in [0, 2^32), got {seed!r}", argument="seed")
    settings = StudySettings() if settings is None else settings
    if not isinstance(settings, StudySettings):
        raise InputError("settings must be a StudySettings", argument="settings")
    _check_engine(workers, scheduler)
    _check_coaxial(space.base, names, settings)
    for values in enqueue:
        space.design(values)  # checked now: InputError before anything is stored
    spec = _spec(space, names, settings, seed, population_size)
    constraint_names = list(settings.constraint_names())
    directions: Any = [OBJECTIVES[n].direction for n in names]
    store = _storage(storage)
    with _quiet_optuna():
        try:
            study = optuna.create_study(
                storage=store,
                study_name=STUDY_NAME,
                directions=directions,
                load_if_exists=True,
            )
        except (ValueError, KeyError, RuntimeError, OSError, UnicodeDecodeError) as exc:
            raise InputError(
                f"storage {str(storage)!r} is not an Optuna storage of an spm study: {exc}",
                argument="storage",
            ) from exc
        stored = study.user_attrs.get(SPEC_KEY)
        if stored is None:
            if study.get_trials(deepcopy=False):
                raise InputError(
                    f"storage {str(storage)!r} holds a study that spm optimize did not make",
                    argument="storage",
                )
            study.set_user_attr(SPEC_KEY, json.loads(json.dumps(spec)))
            for values in enqueue:
                study.enqueue_trial({k: float(v) for k, v in values.items()})
        elif stored != json.loads(json.dumps(spec)):
            differs = sorted(k for k in set(spec) | set(stored) if stored.get(k) != spec.get(k))
            raise InputError(
                f"storage {str(storage)!r} holds another study (its {', '.join(differs)} "
                "differ): use another file or the same space, objectives, settings and seed",
                argument="storage",
            )
        # A trial left running by a run that was stopped: failed (one driver at a time).
        _fail_running(study, "interrupted")
        finished = (TrialState.COMPLETE, TrialState.FAIL, TrialState.PRUNED)
        done = len(study.get_trials(deepcopy=False, states=finished))
        remaining = max(0, n_trials - done)
        bar = _Progress(remaining, progress)
        distributions: dict[str, Any] = {
            v.name: optuna.distributions.FloatDistribution(float(v.low), float(v.high))
            for v in space.variables
        }
        on_cluster = scheduler is not None or workers > 1
        finished_or_running = (*finished, TrialState.RUNNING)

        def ask() -> tuple[Any, tuple[Any, ...]]:
            # The next trial's number (enqueued trials, waiting, come first).
            number = len(study.get_trials(deepcopy=False, states=finished_or_running))
            study.sampler = _sampler(
                len(names),
                _trial_seed(seed, number),
                population_size,
                bool(constraint_names),
                parallel=on_cluster,
            )
            trial = study.ask(distributions)
            trial.set_user_attr("constraint_names", constraint_names)
            return trial, (space, dict(trial.params), names, settings, f"trial-{trial.number}")

        def tell(trial: Any, outcome: _Outcome | None, reason: str | None) -> None:
            if outcome is None or outcome.scores is None:
                error = reason if outcome is None else outcome.error
                trial.set_user_attr("error", error)
                study.tell(trial, state=TrialState.FAIL)
                bar.update("failed")
            else:
                trial.set_user_attr("constraints", list(outcome.constraints.values()))
                if _native_constraints():
                    for key, limit in outcome.constraints.items():
                        trial.set_constraint(key, limit)
                study.tell(trial, list(outcome.scores))
                feasible = all(value <= 0.0 for value in outcome.constraints.values())
                bar.update(
                    " ".join(f"{n}={v:.3g}" for n, v in zip(names, outcome.scores, strict=True))
                    + ("" if feasible else " (infeasible)")
                )
            if callback is not None:
                callback(_record(study._storage.get_trial(trial._trial_id), names))

        try:
            if not on_cluster:
                for _ in range(remaining):
                    trial, arguments = ask()
                    tell(trial, _evaluate_trial(*arguments), None)
            elif remaining:
                from ._engines import dask_client, evaluate_on_cluster

                local = min(workers, remaining)
                with dask_client(local, scheduler) as client:
                    try:
                        evaluate_on_cluster(client, remaining, ask, _evaluate_trial, tell)
                    except BaseException:
                        _fail_running(study, "interrupted")  # before the cluster closes
                        raise
        except BaseException:
            _fail_running(study, "interrupted")
            raise
        finally:
            bar.close()
    return study_result(study, names, new_trials=remaining, seconds=time.perf_counter() - start)


def study_result(
    study: Any, names: tuple[str, ...], *, new_trials: int, seconds: float
) -> StudyResult:
    """The :class:`StudyResult` of an Optuna study scored by the objectives ``names``:
    its trials read back and their Pareto front."""
    records = _records(study, names)
    chosen = tuple(OBJECTIVES[n] for n in names)
    return StudyResult(
        study=study,
        objectives=chosen,
        trials=records,
        pareto=_pareto(records, chosen),
        new_trials=new_trials,
        seconds=seconds,
    )
