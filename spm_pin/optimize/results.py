"""The results of a design study, as files: :func:`write_results` takes a finished
study (what :func:`~spm_pin.optimize.run_study` returns, or its storage) and writes
into one folder:

* ``pareto.png``: the trials in objective space, the Pareto front highlighted, the
  designs written marked by trial number and the prototype's scores (a star) for
  comparison: one objective against the trial number, two objectives as a scatter,
  three or more as a grid of every pair (:func:`pareto_figure`; matplotlib, the
  ``plot`` extra);
* ``best_1.toml``, ``best_2.toml``, ...: the best designs, at most ``best`` of the
  Pareto front (:func:`best_trials`), as design files that every command takes with
  ``--design FILE`` and :meth:`~spm_pin.SPMDesign.load` reads;
* ``designs.html``: one self-contained page with those designs side by side at home,
  each in its own meshcat scene, the prototype's last (meshcat, the ``viz`` extra);
* ``report.json``: what the study was and what it found (below).

A file whose library is not installed (matplotlib, meshcat) is skipped, with a note in
the report saying why; nothing else is skipped silently.

Keys of ``report.json`` (version 1; scores and constraints keyed by name, in the units
of :data:`~spm_pin.optimize.OBJECTIVES`; constraint values are <= 0 where they hold):

* ``format``: ``"spm-pin optimize results"``; ``version``: 1;
* ``objectives``: list of ``{name, direction, unit, description}``, in the study's
  order;
* ``variables``: list of ``[name, low, high]`` (degrees for angles, metres for sizes);
* ``base``: the base design of the space (the design file's table, as
  :meth:`~spm_pin.SPMDesign.to_dict`);
* ``settings``: the study's :class:`~spm_pin.optimize.StudySettings`, field by field;
* ``constraints``: the names of the constraints that were on;
* ``seed``, ``population_size``: as the study was run (population None for one
  objective);
* ``trials``: ``{total, complete, failed, feasible}``, counts of the finished trials;
* ``pareto``: every trial of the Pareto front (feasible, not dominated), each
  ``{number, values, scores, constraints}``;
* ``best``: the designs written, best first by the first objective, each ``{rank,
  number, name, file, values, scores, constraints}`` (``file``: the TOML file's name
  in the folder);
* ``prototype``: the reference design scored by the same objectives, settings and
  constraints: ``{name, values, scores, constraints, feasible, error}`` (``error``:
  why it could not be scored, else None; then ``scores`` is empty);
* ``files``: what was written, names relative to the folder: ``{pareto_png,
  designs_html, report_json, designs}`` (``pareto_png`` or ``designs_html`` None when
  skipped; ``designs`` a list);
* ``notes``: sentences on what was skipped and why (empty when nothing was).
"""

from __future__ import annotations

import base64
import dataclasses
import html
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..design import SPMDesign
from ..errors import InputError, SPMError
from ._progress import quiet_optuna as _quiet_optuna
from .objectives import DesignSpace, Variable
from .study import (
    OBJECTIVES,
    SPEC_KEY,
    STUDY_NAME,
    Objective,
    StudyResult,
    StudySettings,
    TrialRecord,
    _storage,
    evaluate,
    study_result,
)

__all__ = [
    "DEFAULT_BEST",
    "REPORT_VERSION",
    "ResultFiles",
    "best_trials",
    "designs_page",
    "load_study_result",
    "pareto_figure",
    "write_results",
]

#: How many designs :func:`write_results` writes at most, by default.
DEFAULT_BEST = 5
#: Version of the layout of ``report.json``.
REPORT_VERSION = 1
#: File names in the results folder.
PARETO_PNG = "pareto.png"
REPORT_JSON = "report.json"
DESIGNS_HTML = "designs.html"


@dataclasses.dataclass(frozen=True)
class ResultFiles:
    """What :func:`write_results` wrote.

    Attributes:
        directory: The results folder.
        report: The content of ``report.json`` (plain data).
        report_json: The path of ``report.json``.
        designs: The design TOML files, best first.
        pareto_png: The path of ``pareto.png`` (None when matplotlib is missing).
        designs_html: The path of ``designs.html`` (None when meshcat is missing, or
            when it was not asked for).
    """

    directory: Path
    report: dict[str, Any]
    report_json: Path
    designs: tuple[Path, ...]
    pareto_png: Path | None
    designs_html: Path | None

    @property
    def files(self) -> tuple[Path, ...]:
        """Every file written, the report last."""
        extra = [p for p in (self.pareto_png, self.designs_html) if p is not None]
        return (*self.designs, *extra, self.report_json)


# ------------------------------------------------------------------ the study
@dataclasses.dataclass(frozen=True)
class _Study:
    """What a study was (from the description stored with it)."""

    space: DesignSpace
    settings: StudySettings
    seed: int
    population_size: int | None


def _study_of(result: StudyResult) -> _Study:
    """The space, settings and seed stored with the study of ``result``."""
    spec = getattr(result.study, "user_attrs", {}).get(SPEC_KEY)
    if not isinstance(spec, dict):
        raise InputError(
            "the study holds no description of an spm study (it was not made by run_study)",
            argument="result",
        )
    try:
        variables = tuple(Variable(str(n), float(lo), float(hi)) for n, lo, hi in spec["variables"])
        space = DesignSpace(variables, base=SPMDesign.from_dict(spec["base"]))
        settings = StudySettings(**spec["settings"])
        return _Study(space, settings, int(spec["seed"]), spec.get("population_size"))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(
            f"the study's stored description is not readable ({exc!r}): a study of another "
            "spm-pin version?",
            argument="result",
        ) from exc


def load_study_result(storage: str | os.PathLike[str]) -> StudyResult:
    """The trials and Pareto front of a study kept in a storage, without running it.

    Args:
        storage: The journal file or the Optuna RDB URL that ``run_study`` (or ``spm
            optimize --storage``) wrote.

    Returns:
        The :class:`~spm_pin.optimize.StudyResult` (``new_trials`` 0).

    Raises:
        InputError: no such file, or a storage that holds no spm study.
        ImportError: Optuna is not installed.
    """
    try:
        import optuna
    except ImportError as exc:
        raise ImportError(
            f"reading a study needs Optuna: pip install 'spm-pin[optimize]' ({exc})"
        ) from None
    text = os.fspath(storage) if isinstance(storage, str | os.PathLike) else None
    if not text:
        raise InputError(
            f"storage must be a file path or an RDB URL, got {storage!r}", argument="storage"
        )
    if "://" not in text and not Path(text).is_file():
        raise InputError(f"no study storage {text!r}: no such file", argument="storage")
    with _quiet_optuna():
        try:
            study = optuna.load_study(study_name=STUDY_NAME, storage=_storage(text))
        except (ValueError, KeyError, RuntimeError, OSError, UnicodeDecodeError) as exc:
            raise InputError(
                f"storage {text!r} holds no spm study: {exc}", argument="storage"
            ) from exc
    spec = study.user_attrs.get(SPEC_KEY)
    if not isinstance(spec, dict) or "objectives" not in spec:
        raise InputError(
            f"storage {text!r} holds a study that spm optimize did not make", argument="storage"
        )
    names = tuple(str(n) for n in spec["objectives"])
    if any(n not in OBJECTIVES for n in names):
        raise InputError(f"storage {text!r}: unknown objectives {list(names)}", argument="storage")
    return study_result(study, names, new_trials=0, seconds=0.0)


def _signs(objectives: Sequence[Objective]) -> np.ndarray:
    """+1 for an objective to maximize, -1 to minimize (larger signed is better)."""
    return np.array([1.0 if o.direction == "maximize" else -1.0 for o in objectives])


def best_trials(result: StudyResult, best: int = DEFAULT_BEST) -> tuple[TrialRecord, ...]:
    """At most ``best`` trials of the Pareto front, best first by the first objective.

    When the front holds more, they are spread along it: the front sorted by the first
    objective (best first, then by trial number), and ``best`` of them evenly spaced,
    both ends included.

    Args:
        result: A finished study.
        best: How many at most (>= 1).

    Returns:
        The trials, best first by the first objective (empty when no trial is
        feasible).

    Raises:
        InputError: ``best`` not an integer >= 1.
    """
    if isinstance(best, bool) or not isinstance(best, int) or best < 1:
        raise InputError(f"best must be an integer >= 1, got {best!r}", argument="best", value=best)
    first = result.objectives[0]
    sign = 1.0 if first.direction == "maximize" else -1.0
    front = sorted(result.pareto, key=lambda t: (-sign * t.scores[first.name], t.number))
    if len(front) <= best:
        return tuple(front)
    picks = np.round(np.linspace(0, len(front) - 1, best)).astype(int) if best > 1 else [0]
    return tuple(front[int(k)] for k in picks)


def _check_result(result: StudyResult | str | os.PathLike[str]) -> StudyResult:
    if isinstance(result, str | os.PathLike):
        result = load_study_result(result)
    if not isinstance(result, StudyResult):
        raise InputError(
            "result must be a StudyResult (what run_study returns) or a study's storage, "
            f"got {type(result).__name__}",
            argument="result",
        )
    complete = [t for t in result.trials if t.state == "COMPLETE"]
    if not complete:
        failed = [t for t in result.trials if t.state == "FAIL"]
        why = f" ({len(failed)} failed; the first: {failed[0].error})" if failed else ""
        raise InputError(
            f"the study has no completed trial{why}: there are no results to write",
            argument="result",
        )
    return result


# --------------------------------------------------------------------- the plot
def _label(objective: Objective) -> str:
    better = "higher" if objective.direction == "maximize" else "lower"
    return f"{objective.name} [{objective.unit}] ({better} is better)"


def pareto_figure(
    result: StudyResult,
    *,
    prototype_scores: dict[str, float] | None = None,
    marked: Sequence[TrialRecord] = (),
) -> Any:
    """The matplotlib ``Figure`` of a study's trials in objective space (what
    ``pareto.png`` shows).

    Every completed trial is a point: the Pareto front in colour (collection label
    ``"Pareto front"``), the other feasible trials in grey (``"other feasible"``),
    the infeasible ones as crosses (``"infeasible"``); the ``marked`` trials are
    annotated with their numbers, and the prototype's scores are a star
    (``"prototype"``). One objective: the score against the trial number (the
    prototype a dashed line); two: one scatter, the front joined by a line; three or
    more: the lower triangle of a grid, one panel per pair of objectives (the
    front's points highlighted, not joined). Axes carry the objectives' names and
    units. No global pyplot state is used.

    Args:
        result: A finished study.
        prototype_scores: Scores by objective name to mark (None: no mark).
        marked: Trials to annotate with their numbers (the designs written).

    Returns:
        The figure (Agg canvas).

    Raises:
        ImportError: matplotlib is missing.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise ImportError(
            f"pareto.png needs matplotlib: pip install 'spm-pin[plot]' ({exc})"
        ) from None
    objectives = result.objectives
    names = [o.name for o in objectives]
    front_numbers = {t.number for t in result.pareto}
    groups = {
        "Pareto front": [t for t in result.trials if t.number in front_numbers],
        "other feasible": [
            t for t in result.trials if t.feasible and t.number not in front_numbers
        ],
        "infeasible": [t for t in result.trials if t.state == "COMPLETE" and not t.feasible],
    }
    styles: dict[str, dict[str, Any]] = {
        "Pareto front": {"color": "tab:blue", "s": 36, "zorder": 3, "edgecolors": "k"},
        "other feasible": {"color": "0.6", "s": 16, "zorder": 2},
        "infeasible": {"color": "tab:orange", "s": 20, "marker": "x", "zorder": 1},
    }
    complete = sum(t.state == "COMPLETE" for t in result.trials)
    title = (
        f"{len(result.trials)} trials, {complete} completed, "
        f"{complete - len(groups['infeasible'])} feasible; Pareto front of {len(result.pareto)}"
    )
    k = len(objectives)
    size = (7.0, 5.0) if k <= 2 else (3.2 * (k - 1) + 1.0, 3.0 * (k - 1) + 0.6)
    figure = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(figure)
    if k == 1:
        axis = figure.subplots()
        for label, trials in groups.items():
            if trials:
                x = [t.number for t in trials]
                y = [t.scores[names[0]] for t in trials]
                axis.scatter(x, y, label=label, **styles[label])
        for trial in marked:
            axis.annotate(f"#{trial.number}", (trial.number, trial.scores[names[0]]), fontsize=8)
        if prototype_scores is not None:
            axis.axhline(prototype_scores[names[0]], color="tab:red", ls="--", label="prototype")
        axis.set_xlabel("trial number")
        axis.set_ylabel(_label(objectives[0]))
        axis.grid(True, alpha=0.3)
        axis.legend(loc="best", fontsize=8)
    else:
        grid = figure.subplots(k - 1, k - 1, squeeze=False)
        for row in range(k - 1):
            for col in range(k - 1):
                axis = grid[row][col]
                if col > row:
                    axis.set_axis_off()
                    continue
                across, up = objectives[col], objectives[row + 1]
                _pair(axis, groups, styles, across, up, marked, join=k == 2)
                if prototype_scores is not None:
                    axis.scatter(
                        [prototype_scores[across.name]],
                        [prototype_scores[up.name]],
                        marker="*",
                        s=160,
                        color="tab:red",
                        edgecolors="k",
                        zorder=4,
                        label="prototype",
                    )
        handles, labels = grid[0][0].get_legend_handles_labels()
        where = grid[0][0] if k == 2 else grid[0][k - 2]
        where.legend(handles, labels, loc="best" if k == 2 else "center", fontsize=8)
    figure.suptitle(title, fontsize=9)
    return figure


def _pair(
    axis: Any,
    groups: dict[str, list[TrialRecord]],
    styles: dict[str, dict[str, Any]],
    x: Objective,
    y: Objective,
    marked: Sequence[TrialRecord],
    *,
    join: bool,
) -> None:
    """One panel: objective ``y`` against objective ``x``; ``join``: the front joined
    by a line (for two objectives only: a projection of a longer front is no front)."""
    for label, trials in groups.items():
        if trials:
            axis.scatter(
                [t.scores[x.name] for t in trials],
                [t.scores[y.name] for t in trials],
                label=label,
                **styles[label],
            )
    front = sorted(groups["Pareto front"], key=lambda t: (t.scores[x.name], t.scores[y.name]))
    if join and len(front) > 1:
        axis.plot(
            [t.scores[x.name] for t in front],
            [t.scores[y.name] for t in front],
            color="tab:blue",
            lw=0.8,
            alpha=0.6,
            zorder=2,
        )
    for trial in marked:
        axis.annotate(
            f"#{trial.number}",
            (trial.scores[x.name], trial.scores[y.name]),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=8,
        )
    axis.set_xlabel(_label(x), fontsize=8)
    axis.set_ylabel(_label(y), fontsize=8)
    axis.grid(True, alpha=0.3)


# ------------------------------------------------------------------- the page
def _scores_text(scores: dict[str, float], objectives: Sequence[Objective]) -> str:
    return ", ".join(
        f"{o.name} {scores[o.name]:.4g}" + ("" if o.unit == "1" else f" {o.unit}")
        for o in objectives
        if o.name in scores
    )


def _values_text(values: dict[str, float]) -> str:
    return ", ".join(f"{name} {value:.4g}" for name, value in values.items())


def designs_page(
    designs: Sequence[tuple[str, SPMDesign]], *, title: str = "spm-pin: designs"
) -> str:
    """One self-contained HTML page with designs side by side at home, each in its
    own meshcat scene (needs meshcat, the ``viz`` extra; no network when opened).

    Each design is a ``div.spm-design`` (``data-index``: its place) with a heading
    and its scene; the scenes are the :class:`~spm_pin.viz.Visualizer` scenes of the
    designs (collision colouring off), kept as base64 msgpack commands in the JSON
    script ``#spm-scenes`` (one list per design) and replayed in order when the page
    loads, after which ``window.spm_scene_ready`` is true.

    Args:
        designs: (caption, design) pairs, in the order shown.
        title: The page's title.

    Returns:
        The page's text.

    Raises:
        ImportError: meshcat is missing.
    """
    from ..model import build_robot
    from ..viz import Visualizer
    from ..viz._scene import viewer_script

    scenes = []
    cells = []
    for index, (caption, design) in enumerate(designs):
        scene = Visualizer(build_robot(design), check_collisions=False).scene
        scenes.append([base64.b64encode(data).decode("ascii") for _, _, data in scene.commands()])
        heading, _, detail = caption.partition("\n")
        cells.append(
            f'<div class="spm-design" data-index="{index}">'
            f"<h2>{html.escape(heading)}</h2><p>{html.escape(detail)}</p>"
            f'<div class="spm-view"><div class="spm-pane" id="spm-pane-{index}"></div></div>'
            "</div>"
        )
    return _PAGE.format(
        title=html.escape(title),
        cells="\n".join(cells),
        scenes=json.dumps(scenes),
        viewer=viewer_script(),
    )


_PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; font: 13px/1.4 sans-serif; color: #222; background: #eef0f3; }}
h1 {{ font-size: 16px; margin: 10px 12px 6px; }}
#spm-designs {{ display: grid; gap: 8px; padding: 0 8px 8px;
  grid-template-columns: repeat(auto-fill, minmax(420px, 1fr)); }}
.spm-design {{ background: #fff; border-radius: 3px; overflow: hidden; }}
.spm-design h2 {{ font-size: 14px; margin: 6px 8px 0; }}
.spm-design p {{ margin: 0 8px 4px; min-height: 1.4em; }}
.spm-view {{ position: relative; height: 360px; }}
.spm-pane {{ width: 100%; height: 100%; }}
</style>
</head>
<body>
<h1>{title}</h1>
<div id="spm-designs">
{cells}
</div>
<script type="application/json" id="spm-scenes">{scenes}</script>
<script>
{viewer}
</script>
<script>
var spm_viewers = [];
// meshcat sizes its canvas to the window's height: size each to its own pane.
function spm_fit_pane(viewer, pane) {{
  var size = viewer.set_3d_pane_size;
  viewer.set_3d_pane_size = function (width, height) {{
    size.call(viewer, width === undefined ? pane.offsetWidth : width,
              height === undefined ? pane.offsetHeight : height);
  }};
  viewer.set_3d_pane_size();
}}
(function () {{
  var scenes = JSON.parse(document.getElementById("spm-scenes").textContent);
  for (var k = 0; k < scenes.length; k++) {{
    var pane = document.getElementById("spm-pane-" + k);
    var viewer = new MeshCat.Viewer(pane);
    spm_fit_pane(viewer, pane);
    for (var i = 0; i < scenes[k].length; i++) {{
      var text = atob(scenes[k][i]);
      var bytes = new Uint8Array(text.length);
      for (var j = 0; j < text.length; j++) bytes[j] = text.charCodeAt(j);
      viewer.handle_command_bytearray(bytes);
    }}
    if (viewer.gui) viewer.gui.close();
    spm_viewers.push(viewer);
  }}
  window.spm_scene_ready = true;
}})();
</script>
</body>
</html>
"""


# ------------------------------------------------------------------- writing
def _write(path: Path, text: str) -> None:
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise InputError(
            f"cannot write {str(path)!r}: {exc.strerror or exc}", argument="out_dir"
        ) from exc


def _prepare(out_dir: str | os.PathLike[str]) -> Path:
    if not isinstance(out_dir, str | os.PathLike) or not os.fspath(out_dir):
        raise InputError(
            f"out_dir must be a folder path, got {out_dir!r}", argument="out_dir", value=out_dir
        )
    directory = Path(out_dir)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"cannot make the results folder {str(directory)!r}: {exc.strerror or exc}",
            argument="out_dir",
            value=str(directory),
        ) from exc
    if not os.access(directory, os.W_OK):
        raise InputError(
            f"the results folder {str(directory)!r} is not writable",
            argument="out_dir",
            value=str(directory),
        )
    return directory


def _prototype_entry(prototype: SPMDesign, result: StudyResult, study: _Study) -> dict[str, Any]:
    names = [o.name for o in result.objectives]
    values = study.space.values_of(prototype)
    entry: dict[str, Any] = {"name": prototype.name, "values": values}
    try:
        evaluation = evaluate(prototype, names, study.settings)
    except SPMError as exc:
        return entry | {
            "scores": {},
            "constraints": {},
            "feasible": False,
            "error": f"{type(exc).__name__}: {exc}",
        }
    return entry | {
        "scores": evaluation.scores,
        "constraints": evaluation.constraints,
        "feasible": evaluation.feasible,
        "error": None,
    }


def _finite(value: Any) -> Any:
    """JSON-safe data: non-finite floats become None (JSON has no NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def write_results(
    result: StudyResult | str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    best: int = DEFAULT_BEST,
    prototype: SPMDesign | str | os.PathLike[str] | None = None,
    html_page: bool = True,
) -> ResultFiles:
    """Write the results of a finished study into a folder: ``pareto.png``, the best
    designs as ``best_1.toml`` ... (design files for ``--design FILE``),
    ``designs.html`` and ``report.json`` (see :mod:`spm_pin.optimize.results` for the
    report's keys).

    The best designs are at most ``best`` trials of the Pareto front
    (:func:`best_trials`), named ``trial-N`` after their trial. The prototype is
    scored with the study's own objectives, settings and constraints
    (:func:`~spm_pin.optimize.evaluate`), for comparison. The folder is made if
    missing; files of the same names in it are replaced. Without matplotlib the plot
    is skipped, without meshcat the page: the report's ``notes`` say so.

    Args:
        result: What :func:`~spm_pin.optimize.run_study` returned, or the study's
            storage (a journal file or an RDB URL, read by :func:`load_study_result`).
        out_dir: The results folder.
        best: How many designs to write at most (>= 1).
        prototype: The reference design (a design, a preset name or a design file;
            default: the prototype).
        html_page: Write ``designs.html``.

    Returns:
        :class:`ResultFiles`: the paths written and the report.

    Raises:
        InputError: a study without any completed trial, a bad ``best``, or a folder
            that cannot be made or written to; a storage without an spm study.
        DesignError: ``prototype`` names no design.
        ImportError: Optuna is missing (to read a storage).

    Example:
        After ``result = run_study(...)``::

            files = write_results(result, "results")
            design = spm.SPMDesign.load(files.designs[0])

        and from the shell: ``spm fk 0 0 0 --design results/best_1.toml``.
    """
    result = _check_result(result)
    if isinstance(best, bool) or not isinstance(best, int) or best < 1:
        raise InputError(f"best must be an integer >= 1, got {best!r}", argument="best", value=best)
    reference = SPMDesign.from_spec(prototype)
    study = _study_of(result)
    chosen = best_trials(result, best)
    directory = _prepare(out_dir)
    notes: list[str] = []
    objectives = result.objectives

    designs: list[tuple[TrialRecord, SPMDesign, Path]] = []
    for rank, trial in enumerate(chosen, start=1):
        design = study.space.design(trial.values, name=f"trial-{trial.number}")
        path = directory / f"best_{rank}.toml"
        _write(path, design.to_toml())
        designs.append((trial, design, path))
    if not chosen:
        notes.append("no feasible trial: no design file written")

    reference_entry = _prototype_entry(reference, result, study)
    reference_scores = reference_entry["scores"] or None

    pareto_png: Path | None = directory / PARETO_PNG
    try:
        figure = pareto_figure(result, prototype_scores=reference_scores, marked=chosen)
    except ImportError as exc:
        notes.append(f"{PARETO_PNG} skipped: {exc}")
        pareto_png = None
    else:
        assert pareto_png is not None
        try:
            figure.savefig(pareto_png, format="png", dpi=110)
        except OSError as exc:
            raise InputError(
                f"cannot write {str(pareto_png)!r}: {exc.strerror or exc}", argument="out_dir"
            ) from exc

    designs_html: Path | None = None
    if html_page and designs:
        shown = [
            (
                f"#{rank} trial {trial.number}: {_values_text(trial.values)}\n"
                + _scores_text(trial.scores, objectives),
                design,
            )
            for rank, (trial, design, _) in enumerate(designs, start=1)
        ]
        caption = _scores_text(reference_entry["scores"], objectives) or "not scored"
        values = _values_text(reference_entry["values"])
        shown.append((f"{reference.name} (reference): {values}\n{caption}", reference))
        try:
            page = designs_page(shown, title="spm-pin: the best designs of a study")
        except ImportError as exc:
            notes.append(f"{DESIGNS_HTML} skipped: meshcat is missing ({exc})")
        else:
            designs_html = directory / DESIGNS_HTML
            _write(designs_html, page)
    elif html_page:
        notes.append(f"{DESIGNS_HTML} skipped: no design to show")

    report: dict[str, Any] = {
        "format": "spm-pin optimize results",
        "version": REPORT_VERSION,
        "objectives": [dataclasses.asdict(o) for o in objectives],
        "variables": [[v.name, v.low, v.high] for v in study.space.variables],
        "base": study.space.base.to_dict(),
        "settings": dataclasses.asdict(study.settings),
        "constraints": list(study.settings.constraint_names()),
        "seed": study.seed,
        "population_size": study.population_size,
        "trials": {
            "total": len(result.trials),
            "complete": sum(t.state == "COMPLETE" for t in result.trials),
            "failed": sum(t.state == "FAIL" for t in result.trials),
            "feasible": sum(t.feasible for t in result.trials),
        },
        "pareto": [
            {
                "number": t.number,
                "values": t.values,
                "scores": t.scores,
                "constraints": t.constraints,
            }
            for t in result.pareto
        ],
        "best": [
            {
                "rank": rank,
                "number": trial.number,
                "name": design.name,
                "file": path.name,
                "values": trial.values,
                "scores": trial.scores,
                "constraints": trial.constraints,
            }
            for rank, (trial, design, path) in enumerate(designs, start=1)
        ],
        "prototype": reference_entry,
        "files": {
            "pareto_png": None if pareto_png is None else pareto_png.name,
            "designs_html": None if designs_html is None else designs_html.name,
            "report_json": REPORT_JSON,
            "designs": [path.name for _, _, path in designs],
        },
        "notes": notes,
    }
    report = _finite(report)
    report_json = directory / REPORT_JSON
    _write(report_json, json.dumps(report, indent=2) + "\n")
    return ResultFiles(
        directory=directory,
        report=report,
        report_json=report_json,
        designs=tuple(path for _, _, path in designs),
        pareto_png=pareto_png,
        designs_html=designs_html,
    )
