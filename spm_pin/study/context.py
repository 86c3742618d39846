"""What every section of the study works from and what it produces: the study's
settings and tolerances, :class:`DemoContext` (the inputs, with the robot, the
loop-closure solver, the tracked motion and the MuJoCo runs computed once),
:class:`DemoSection`, :class:`ReportItem`, :class:`DemoResult`, the report's file
names and the small text helpers the sections and the report share."""

from __future__ import annotations

import dataclasses
import functools
import math
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._records import FloatArray, Record
from .._records import plain as _plain
from .._records import render as _render
from ..design import SPMDesign
from ..errors import InputError
from ..kinematics import FKResult, TrackResult, forward_kinematics, track
from ._extras import Skipped
from .mujoco import MUJOCO_SETTLE_STEPS, MujocoAxes, mujoco_platform_axes
from .mujoco import export_mjcf as _export_mjcf

if TYPE_CHECKING:  # Pinocchio and meshcat are imported when a section needs them
    from ..closure import ClosedLoop
    from ..model.robot import SPMRobot
    from ..viz import Visualizer

__all__ = [
    "DEMO_COLLIDING_THETA_DEG",
    "DEMO_SAMPLES",
    "DEMO_THETA_DEG",
    "FILES",
    "FK_METHODS",
    "MUJOCO_TOLERANCE",
    "PROJECTION_TOLERANCE",
    "SHOWN_SAMPLES",
    "STUDY_AGREEMENT",
    "DemoContext",
    "DemoResult",
    "DemoSection",
    "ReportItem",
    "degrees_text",
    "methods",
    "sci",
    "verdict",
]

#: The published study's demonstration input [deg].
DEMO_THETA_DEG = (60.0, 90.0, 120.0)
#: The published study's colliding input [deg] (no home-mode assembly exists there).
DEMO_COLLIDING_THETA_DEG = (60.0, 90.0, 220.0)
#: Samples of the motion from home to the demonstration input (as in the study).
DEMO_SAMPLES = 25
#: Agreement of computed and simulated platform axes that the study reported.
STUDY_AGREEMENT = 4e-4
#: Largest |v_projection - v_analytic| the demo accepts (both solve the loops to 1e-12).
PROJECTION_TOLERANCE = 1e-10
#: Largest |v_mujoco - v_analytic| the demo accepts, by run: upright, MuJoCo's soft
#: welds yield under the platform's weight (about 1e-5 at the default settings);
#: without gravity they close to rounding.
MUJOCO_TOLERANCE = {"gravity": 1e-4, "no_gravity": 1e-9}
#: Samples whose platform axes the text output shows.
SHOWN_SAMPLES = (0, 6, 12, 18, 24)

_SCENES = "scenes"
#: The report's files by kind, relative to the output folder.
FILES = {
    "index": "index.html",
    "record": "demo.json",
    "motion_plot": "motion_axes.png",
    "workspace_plot": "safe_workspace.png",
    "workspace_folder": "workspace",
    "torque_plot": "torques.png",
    "demo_scene": f"{_SCENES}/demo_input.html",
    "motion_scene": f"{_SCENES}/motion.html",
    "colliding_scene": f"{_SCENES}/colliding_input.html",
}

#: The forward-kinematics methods, in the order they are shown.
FK_METHODS = {
    "analytic": "analytic (closed form)",
    "projection": "Newton projection",
    "mujoco": "MuJoCo (upright)",
    "mujoco_no_gravity": "MuJoCo (no gravity)",
}


@dataclasses.dataclass(frozen=True)
class ReportItem:
    """A file of the report shown in ``index.html``: a PNG plot or a meshcat scene.

    Attributes:
        path: Path relative to the report folder (``/``-separated).
        caption: What it shows.
        picture_time_s: For an animated scene, the time its picture shows [s]
            (default: the first frame).
        picture_note: What the scene's picture shows, when the caption does not say
            (an animation's frame).
    """

    path: str
    caption: str
    picture_time_s: float | None = None
    picture_note: str = ""


@dataclasses.dataclass(frozen=True)
class DemoSection:
    """One section of the demo.

    Attributes:
        key: Its key in the JSON record.
        title: Its heading.
        data: Its numbers (the JSON record's value).
        text: A shorter view of ``data`` for the text output (default ``data``).
        lines: Text lines that replace the rendered record, when a table reads better.
        figures: PNG plots written for the report.
        scenes: meshcat scenes written for the report.
        skipped: Parts left out for a missing optional dependency.
        files: Other files written to the report folder (relative paths).
    """

    key: str
    title: str
    data: Record
    text: Record | None = None
    lines: list[str] | None = None
    figures: tuple[ReportItem, ...] = ()
    scenes: tuple[ReportItem, ...] = ()
    skipped: tuple[Skipped, ...] = ()
    files: tuple[str, ...] = ()

    def text_lines(self) -> list[str]:
        """The section's text, without its heading."""
        if self.lines is not None:
            return list(self.lines)
        return _render(_plain(self.text if self.text is not None else self.data))


@dataclasses.dataclass(frozen=True)
class DemoContext:
    """What every demo section works from; the defaults are the published study.

    The robot, the loop-closure solver, the tracked motion and the MuJoCo runs are
    computed once, on first use, and shared by the sections.

    Attributes:
        design: The SPM (coaxial; default the prototype).
        theta_deg: The demonstration input [deg].
        colliding_theta_deg: The study's colliding input [deg].
        samples: Samples of the motion from home to the demonstration input (>= 2).
        out: Folder of the report (plots, scenes, ``index.html``, ``demo.json``);
            None writes no file.
        workspace_step_deg: Grid step of the workspace map [deg].
        move_duration_s: Duration of the motion for the torques (minimum jerk) [s].
        torque_rate_hz: Samples per second of the torque computation [Hz].
        mujoco_settle_steps: MuJoCo steps per sample of the cross-check.
        workspace_progress: Show the workspace map's own progress bar (tqdm).
        pictures: Render a PNG picture of each 3-D scene beside it (in a headless
            Chromium, :mod:`spm_pin.viz.browser`), so the report reads without WebGL.
            Without Playwright or a Chromium the report says so and goes on.
        chromium: The Chromium to render them with: a path or a name on the PATH
            (default: the first of :data:`~spm_pin.viz.browser.CHROMIUM_NAMES`).
    """

    design: SPMDesign = dataclasses.field(default_factory=SPMDesign.prototype)
    theta_deg: tuple[float, float, float] = DEMO_THETA_DEG
    colliding_theta_deg: tuple[float, float, float] = DEMO_COLLIDING_THETA_DEG
    samples: int = DEMO_SAMPLES
    out: Path | None = None
    workspace_step_deg: float = 2.0
    move_duration_s: float = 1.0
    torque_rate_hz: float = 500.0
    mujoco_settle_steps: int = MUJOCO_SETTLE_STEPS
    workspace_progress: bool = False
    pictures: bool = True
    chromium: str | Path | None = None

    def __post_init__(self) -> None:
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) or self.samples < 2:
            raise InputError(
                f"samples must be an integer >= 2, got {self.samples!r}",
                argument="samples",
                value=self.samples,
            )
        settle = self.mujoco_settle_steps
        if isinstance(settle, bool) or not isinstance(settle, int) or settle < 2:
            raise InputError(
                f"mujoco_settle_steps must be an integer >= 2, got {settle!r}",
                argument="mujoco_settle_steps",
                value=settle,
            )
        for name in ("workspace_step_deg", "move_duration_s", "torque_rate_hz"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(
                    f"{name} must be a positive number, got {value!r}", argument=name, value=value
                )
        for name in ("theta_deg", "colliding_theta_deg"):
            value = getattr(self, name)
            if len(value) != 3 or not all(math.isfinite(float(x)) for x in value):
                raise InputError(
                    f"{name} must be three finite angles [deg], got {value!r}",
                    argument=name,
                    value=value,
                )
        if not isinstance(self.pictures, bool):
            raise InputError(
                f"pictures must be True or False, got {self.pictures!r}",
                argument="pictures",
                value=self.pictures,
            )
        if self.chromium is not None and (
            not isinstance(self.chromium, (str, Path)) or not str(self.chromium)
        ):
            raise InputError(
                f"chromium must be a path or a program name, got {self.chromium!r}",
                argument="chromium",
                value=self.chromium,
            )
        if self.out is not None:
            object.__setattr__(self, "out", Path(self.out))

    @classmethod
    def quick(cls, **changes: Any) -> DemoContext:
        """A coarser, faster run for smoke tests: a 10-degree workspace grid and 100
        torque samples per second; ``changes`` override fields."""
        settings: dict[str, Any] = {"workspace_step_deg": 10.0, "torque_rate_hz": 100.0}
        settings.update(changes)
        return cls(**settings)

    @property
    def theta(self) -> FloatArray:
        """The demonstration input [rad]."""
        return np.radians(self.theta_deg)

    @property
    def colliding_theta(self) -> FloatArray:
        """The study's colliding input [rad]."""
        return np.radians(self.colliding_theta_deg)

    @property
    def path(self) -> FloatArray:
        """The motion: ``samples`` inputs on the straight line from home to ``theta`` [rad]."""
        result: FloatArray = np.linspace(0.0, 1.0, self.samples)[:, None] * self.theta
        return result

    @functools.cached_property
    def home(self) -> FKResult:
        """The home assembly mode at the demonstration input (solved once)."""
        return forward_kinematics(self.theta, self.design)

    @functools.cached_property
    def robot(self) -> SPMRobot:
        """The :class:`~spm_pin.SPMRobot` of the design (built once)."""
        from ..collision import build_robot

        return build_robot(self.design)

    @functools.cached_property
    def loop(self) -> ClosedLoop:
        """The generic loop-closure solver (:class:`~spm_pin.ClosedLoop`) of the robot."""
        from ..closure import ClosedLoop

        return ClosedLoop.from_robot(self.robot)

    @functools.cached_property
    def motion(self) -> TrackResult:
        """The motion tracked analytically (:class:`~spm_pin.TrackResult`)."""
        return track(self.path, self.design)

    @functools.cached_property
    def mujoco_runs(self) -> dict[str, MujocoAxes]:
        """MuJoCo driven along the motion, upright (``"gravity"``) and without load
        (``"no_gravity"``). Raises ImportError without MuJoCo."""
        from ..dynamics import GRAVITY

        runs = {}
        with tempfile.TemporaryDirectory(prefix="spm-demo-") as folder:
            mjcf = _export_mjcf(self.design, Path(folder))
            for key, gravity in (("gravity", GRAVITY), ("no_gravity", (0.0, 0.0, 0.0))):
                runs[key] = mujoco_platform_axes(
                    self.path,
                    self.robot,
                    gravity=gravity,
                    settle_steps=self.mujoco_settle_steps,
                    mjcf=mjcf,
                )
        return runs

    @functools.cached_property
    def visualizer(self) -> Visualizer:
        """One :class:`~spm_pin.viz.Visualizer` of the robot for every scene (needs meshcat)."""
        from ..viz import Visualizer

        return Visualizer(self.robot)

    def file(self, name: str, skipped: Skipped | None = None) -> Path | None:
        """Where a report file goes (its folder made).

        Args:
            name: The file's kind: ``"index"``, ``"record"``, ``"motion_plot"``,
                ``"workspace_plot"``, ``"workspace_folder"``, ``"torque_plot"``,
                ``"demo_scene"``, ``"motion_scene"`` or ``"colliding_scene"``.
            skipped: What :func:`run_demo` skips for want of the part's dependency.

        Returns:
            The path in ``out``; None without an output folder or when skipped.
        """
        if self.out is None or skipped is not None:
            return None
        path = self.out / FILES[name]
        path.parent.mkdir(parents=True, exist_ok=True)
        return path


@dataclasses.dataclass(frozen=True)
class DemoResult:
    """What :func:`run_demo` produced.

    Attributes:
        record: Every number, as plain data (what ``spm demo --json`` prints).
        lines: The text output.
        sections: The sections, in order.
        skipped: Parts left out for missing optional dependencies.
        failed_checks: Cross-checks outside their tolerance, as ``"section: method"``
            (empty when the three ways of solving the loops agree).
        files: Report files written, by their path relative to the report folder
            (empty without one).
        seconds: Wall time of the run [s].
    """

    record: Record
    lines: list[str]
    sections: list[DemoSection]
    skipped: list[Skipped]
    failed_checks: list[str]
    files: dict[str, Path]
    seconds: float


def degrees_text(values: Sequence[float]) -> str:
    """Angles [deg] as ``[60, 90, 120]``."""
    return "[" + ", ".join(f"{x:g}" for x in values) + "]"


def verdict(within: bool, tolerance: float) -> str:
    """Whether a cross-check is within its tolerance, in words."""
    return f"within {sci(tolerance)}" if within else f"OUTSIDE the tolerance {sci(tolerance)}"


def sci(value: float) -> str:
    """A small number as ``1e-4`` (one significant digit)."""
    return f"{value:.0e}".replace("e-0", "e-").replace("e+00", "")


def methods(data: Record) -> dict[str, Record]:
    """The forward-kinematics methods that ran (MuJoCo's are None without it)."""
    return {key: method for key, method in data["methods"].items() if method is not None}
