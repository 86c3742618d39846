r"""``spm demo``: the published study of the prototype, reproduced and taken further.

The study ("Modeling and Simulation of Spherical Parallel Manipulators in CoppeliaSim
(V-REP)") modelled a 3D-printed coaxial SPM, compared the platform axes v_i computed
from its kinematic model with those read from the simulation at the input
theta = [60, 90, 120] deg (they agreed to about 4e-4), showed the motion from home to
that input at 25 samples, and found a link collision at theta = [60, 90, 220] deg.
:func:`run_demo` does all of it on the same prototype and adds what the study left as
future work:

1. forward kinematics at the demonstration input three ways, side by side: the
   analytic closed form (:func:`~spm_pin.forward_kinematics`), Newton projection on the
   Pinocchio model (:meth:`~spm_pin.ClosedLoop.project`, from home) and MuJoCo stepping
   the exported MJCF (:func:`mujoco_platform_axes`);
2. every real assembly mode there, the singularity check (the Jacobian) and the
   inverse-kinematics round trip;
3. the motion from home to the input at 25 samples, analytic
   (:func:`~spm_pin.track`) against projection (:meth:`~spm_pin.ClosedLoop.follow`)
   and MuJoCo, with a plot of the x, y, z components of v_1, v_2, v_3;
4. the colliding input: the colliding link pairs (:func:`spm_pin.collision.check_input`,
   which names the assembly mode checked) and a scene with those links in black;
5. the safe workspace over the gaps between the proximal links
   (:func:`spm_pin.workspace.workspace_map`);
6. the actuator torques along the motion (:func:`~spm_pin.inverse_dynamics`) against
   the XM540-W150 servo's torque-speed envelope, with a verdict;
7. an HTML report (``index.html``, PNG plots beside it and meshcat scenes in iframes,
   every file self-contained, so the folder works offline) and ``demo.json``.

MuJoCo, matplotlib and meshcat are optional (the ``demo`` extra): without one of them
the demo runs everything else and lists what it skipped and what to install.

Why MuJoCo differs from the other two: its loop-closing welds are soft constraints
(a spring-damper per weld). With the inputs held and no load the welds close exactly
and MuJoCo agrees with the analytic solution to about 1e-13; standing upright, the
welds carry the platform's weight and yield by about 1e-5 (with the stiff settings of
:func:`~spm_pin.simulate_mujoco`; MuJoCo's stock settings would let them open by a
tenth of a radian). The demo reports both runs.
"""

from __future__ import annotations

import dataclasses
import functools
import html
import importlib
import math
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt

from ._records import FloatArray, Record, fk_all_record
from ._records import assembly_label as _assembly_label
from ._records import checked_links as _checked_links
from ._records import dumps as _dumps
from ._records import orientation as _orientation
from ._records import plain as _plain
from ._records import render as _render
from ._records import worst_sample as _worst_sample
from ._version import __version__
from .design import SPMDesign
from .errors import InputError
from .kinematics import (
    FKResult,
    TrackResult,
    forward_kinematics,
    forward_kinematics_all,
    inverse_kinematics,
    jacobian,
    track,
)

if TYPE_CHECKING:  # Pinocchio and meshcat are imported when a section needs them
    from .closure import ClosedLoop
    from .model.robot import SPMRobot
    from .viz import Visualizer

__all__ = [
    "DEMO_COLLIDING_THETA_DEG",
    "DEMO_SAMPLES",
    "DEMO_SECTIONS",
    "DEMO_THETA_DEG",
    "INSTALL_DEMO",
    "MUJOCO_SETTLE_STEPS",
    "MUJOCO_TIMESTEP",
    "MUJOCO_TOLERANCE",
    "OPTIONAL_DEPENDENCIES",
    "PROJECTION_TOLERANCE",
    "STUDY_AGREEMENT",
    "DemoContext",
    "DemoResult",
    "DemoSection",
    "MujocoAxes",
    "ReportItem",
    "Skipped",
    "demo_record",
    "mujoco_platform_axes",
    "run_demo",
]

# ------------------------------------------------------------------------ settings
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
#: MuJoCo's physics step in the cross-check [s] (the welds' time constant is twice it).
MUJOCO_TIMESTEP = 1e-4
#: MuJoCo steps per sample: the inputs move during the first half and are held while
#: the welds settle during the second.
MUJOCO_SETTLE_STEPS = 500
#: Viscous damping of the passive joints in the cross-check [N m s/rad]: it settles
#: the welds' oscillation and has no effect at rest.
MUJOCO_PASSIVE_DAMPING = 0.05
#: Samples whose platform axes the text output shows.
_SHOWN_SAMPLES = (0, 6, 12, 18, 24)

#: The command that installs every optional dependency of the demo.
INSTALL_DEMO = 'pip install "spm-pin[demo]"'
#: The demo's optional dependencies -> the extra that brings each alone (MuJoCo for
#: the cross-check, matplotlib for the plots, meshcat for the scenes).
OPTIONAL_DEPENDENCIES: dict[str, str] = {"mujoco": "sim", "matplotlib": "plot", "meshcat": "viz"}
#: Modules imported to check that a dependency works (spm_pin.viz needs meshcat).
_PROBES: dict[str, tuple[str, ...]] = {
    "mujoco": ("mujoco",),
    "matplotlib": ("matplotlib", "matplotlib.backends.backend_agg"),
    "meshcat": ("spm_pin.viz", "meshcat"),
}

# Report file names, relative to the output folder.
_SCENES = "scenes"
_FILES = {
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


# --------------------------------------------------------------------- data types
@dataclasses.dataclass(frozen=True)
class Skipped:
    """A part of the demo left out because an optional dependency is missing.

    Attributes:
        part: What was left out, e.g. ``"MuJoCo cross-check"``.
        missing: The missing Python package.
        install: The command that brings it.
    """

    part: str
    missing: str
    install: str

    def as_dict(self) -> Record:
        """Plain data (JSON)."""
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class ReportItem:
    """A file of the report shown in ``index.html``: a PNG plot or a meshcat scene.

    Attributes:
        path: Path relative to the report folder (``/``-separated).
        caption: What it shows.
    """

    path: str
    caption: str


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
class MujocoAxes:
    """Platform axes read from MuJoCo along a path of imposed inputs.

    Attributes:
        theta: The inputs imposed [rad], (N, 3).
        R: Platform rotation at each sample, MuJoCo's body orientation, (N, 3, 3).
        v: Platform joint axes v_i = R v_i0 as rows, (N, 3, 3).
        weld_opening: Largest angle between the platform and the ends of legs 2 and 3,
            the welds' violation [rad], (N,).
        gravity: Gravity of the run [m/s^2], (3,).
        timestep: MuJoCo's physics step [s].
        steps: MuJoCo steps taken.
    """

    theta: FloatArray
    R: FloatArray
    v: FloatArray
    weld_opening: FloatArray
    gravity: FloatArray
    timestep: float
    steps: int


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
        from .collision import build_robot

        return build_robot(self.design)

    @functools.cached_property
    def loop(self) -> ClosedLoop:
        """The generic loop-closure solver (:class:`~spm_pin.ClosedLoop`) of the robot."""
        from .closure import ClosedLoop

        return ClosedLoop.from_robot(self.robot)

    @functools.cached_property
    def motion(self) -> TrackResult:
        """The motion tracked analytically (:class:`~spm_pin.TrackResult`)."""
        return track(self.path, self.design)

    @functools.cached_property
    def mujoco_runs(self) -> dict[str, MujocoAxes]:
        """MuJoCo driven along the motion, upright (``"gravity"``) and without load
        (``"no_gravity"``). Raises ImportError without MuJoCo."""
        from .dynamics import GRAVITY

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
        from .viz import Visualizer

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
        path = self.out / _FILES[name]
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


# --------------------------------------------------------------- optional imports
def _install(module: str) -> str:
    extra = OPTIONAL_DEPENDENCIES[module]
    return f'{INSTALL_DEMO} (or "spm-pin[{extra}]" for {module} alone)'


def _missing(module: str, part: str) -> Skipped | None:
    """None when ``module`` imports; otherwise what is skipped without it."""
    try:
        for name in _PROBES[module]:
            importlib.import_module(name)
    except ImportError:
        return Skipped(part=part, missing=module, install=_install(module))
    return None


# ------------------------------------------------------------------------- MuJoCo
def _export_mjcf(design: SPMDesign, folder: Path) -> Path:
    from .model.export import export

    export(design, folder)
    return folder / "spm.xml"


def _rotation_angle(Ra: FloatArray, Rb: FloatArray) -> float:
    """Angle of the rotation between two orientations [rad] (accurate near zero)."""
    chord = float(np.linalg.norm(Ra - Rb)) / math.sqrt(8.0)
    return 2.0 * math.asin(min(1.0, chord))


def mujoco_platform_axes(
    path: npt.ArrayLike,
    robot: SPMRobot | None = None,
    *,
    gravity: Sequence[float] = (0.0, 0.0, -9.81),
    timestep: float = MUJOCO_TIMESTEP,
    settle_steps: int = MUJOCO_SETTLE_STEPS,
    mjcf: str | Path | None = None,
) -> MujocoAxes:
    """Forward kinematics by MuJoCo: impose the inputs, let the welds close the loops.

    MuJoCo loads the exported MJCF (the open tree plus the two welds that close legs 2
    and 3) and starts at its reference pose, home. The inputs are imposed, as the study
    set joint positions in CoppeliaSim: for each sample they move on a straight line
    from the previous sample during the first half of ``settle_steps`` MuJoCo steps
    and are held during the second half, while the passive joints follow the welds'
    forces (viscous damping :data:`MUJOCO_PASSIVE_DAMPING` settles them). The platform
    orientation is then read from MuJoCo's own body pose. The welds are stiffened as
    in :func:`~spm_pin.simulate_mujoco` (time constant 2 ``timestep``, solimp
    0.999/0.9999); they remain soft, so under gravity they yield by the load they
    carry, and the platform differs from the rigid answer by that much.

    Args:
        path: Inputs [rad], (N, 3) or (3,); start near home, move in small steps.
        robot: The :class:`~spm_pin.SPMRobot` (default: the prototype).
        gravity: Gravity [m/s^2] (default upright; zeros remove the load).
        timestep: MuJoCo's physics step [s].
        settle_steps: MuJoCo steps per sample (>= 2).
        mjcf: The robot's MJCF file (default: exported to a temporary folder).

    Returns:
        :class:`MujocoAxes`.

    Raises:
        ImportError: MuJoCo is not installed (``pip install "spm-pin[sim]"``).
        InputError: bad arguments; an MJCF of another robot.
    """
    try:
        import mujoco
    except ImportError as exc:
        raise ImportError(f"mujoco_platform_axes needs MuJoCo: {_install('mujoco')}") from exc
    from .dynamics import MUJOCO_SOLIMP
    from .model.robot import ACTUATED_JOINTS, END_BODIES, JOINT_NAMES, build_robot

    if robot is None:
        robot = build_robot()
    try:
        inputs = np.atleast_2d(np.asarray(path, dtype=float))
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"path must be input angles of shape (N, 3) [rad], got {path!r}",
            argument="path",
            value=path,
        ) from exc
    if inputs.ndim != 2 or inputs.shape[1] != 3 or not np.all(np.isfinite(inputs)):
        raise InputError(
            f"path must be finite input angles of shape (N, 3) [rad], got shape {inputs.shape}",
            argument="path",
            value=path,
        )
    if isinstance(settle_steps, bool) or not isinstance(settle_steps, int) or settle_steps < 2:
        raise InputError(
            f"settle_steps must be an integer >= 2, got {settle_steps!r}",
            argument="settle_steps",
            value=settle_steps,
        )
    if not (isinstance(timestep, (int, float)) and math.isfinite(timestep) and timestep > 0):
        raise InputError(
            f"timestep must be positive [s], got {timestep!r}", argument="timestep", value=timestep
        )
    g = np.asarray(gravity, dtype=float)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise InputError("gravity must be 3 finite numbers [m/s^2]", argument="gravity")
    if mjcf is not None:
        file = Path(mjcf)
        if not file.is_file():
            raise InputError(f"MJCF file {str(file)!r} does not exist", argument="mjcf", value=mjcf)
        model = mujoco.MjModel.from_xml_path(str(file))
    else:
        with tempfile.TemporaryDirectory(prefix="spm-mjcf-") as folder:
            file = _export_mjcf(robot.design, Path(folder))
            model = mujoco.MjModel.from_xml_path(str(file))
    joints = tuple(
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)
    )
    if joints != JOINT_NAMES or not math.isclose(
        float(np.sum(model.body_mass)), robot.total_mass, rel_tol=1e-9
    ):
        raise InputError(
            f"{file} is not the MJCF of this robot; export it with spm export",
            argument="mjcf",
            value=mjcf,
        )
    model.opt.timestep = timestep
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    model.opt.gravity[:] = g
    model.eq_solref[:] = (2.0 * timestep, 1.0)
    model.eq_solimp[:] = np.asarray(MUJOCO_SOLIMP, dtype=float)
    model.dof_damping[:] = MUJOCO_PASSIVE_DAMPING
    data = mujoco.MjData(model)
    joint_ids = [JOINT_NAMES.index(name) for name in ACTUATED_JOINTS]
    qpos = np.asarray(model.jnt_qposadr[joint_ids], dtype=int)
    dof = np.asarray(model.jnt_dofadr[joint_ids], dtype=int)
    bodies = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in END_BODIES]
    v0 = robot.design.v0
    ramp = settle_steps // 2
    previous = data.qpos[qpos].copy()
    rotations, openings = [], []
    for target in inputs:
        rate = (target - previous) / (ramp * timestep)
        for step in range(settle_steps):
            moving = step < ramp
            data.qpos[qpos] = previous + (target - previous) * (step / ramp if moving else 1.0)
            data.qvel[dof] = rate if moving else 0.0
            mujoco.mj_step(model, data)
        data.qpos[qpos] = target
        data.qvel[dof] = 0.0
        mujoco.mj_forward(model, data)
        ends = [np.array(data.xmat[b]).reshape(3, 3) for b in bodies]
        rotations.append(ends[0])
        openings.append(max(_rotation_angle(ends[0], end) for end in ends[1:]))
        previous = target.copy()
    R = np.array(rotations)
    return MujocoAxes(
        theta=inputs.copy(),
        R=R,
        v=np.einsum("njk,ik->nij", R, v0),
        weld_opening=np.array(openings),
        gravity=g,
        timestep=float(timestep),
        steps=settle_steps * inputs.shape[0],
    )


# ----------------------------------------------------------------------- helpers
def _deviation(a: FloatArray, b: FloatArray) -> FloatArray:
    """Largest |a - b| over the last two axes (components of the three axes v_i)."""
    result: FloatArray = np.abs(np.asarray(a) - np.asarray(b)).max(axis=(-2, -1))
    return result


def _platform_axes(robot: SPMRobot, q: FloatArray) -> FloatArray:
    """v_i = R v_i0 (rows) with R the platform frame's rotation at q (Pinocchio)."""
    R = np.array(robot.placement(q, "platform").rotation)
    result: FloatArray = np.einsum("jk,ik->ij", R, robot.design.v0)
    return result


def _degrees_text(values: Sequence[float]) -> str:
    return "[" + ", ".join(f"{x:g}" for x in values) + "]"


# -------------------------------------------------------------------- sections
def _demo_design(ctx: DemoContext) -> DemoSection:
    d = ctx.design
    data = {
        "name": d.name,
        "summary": d.summary(),
        "alpha1_deg": math.degrees(d.alpha1),
        "alpha2_deg": math.degrees(d.alpha2),
        "beta_deg": math.degrees(d.beta),
        "eta_deg": np.degrees(d.eta),
        "coaxial": d.is_coaxial,
        "total_mass_kg": ctx.robot.total_mass,
    }
    return DemoSection("design", "The prototype", data)


#: The forward-kinematics methods, in the order they are shown.
_FK_METHODS = {
    "analytic": "analytic (closed form)",
    "projection": "Newton projection",
    "mujoco": "MuJoCo (upright)",
    "mujoco_no_gravity": "MuJoCo (no gravity)",
}


def _demo_forward_kinematics(ctx: DemoContext) -> DemoSection:
    theta = ctx.theta
    fk = ctx.home
    if not bool(fk.reachable):
        raise InputError(
            f"the demonstration input {_degrees_text(ctx.theta_deg)} deg has no home-mode assembly",
            argument="theta_deg",
            value=ctx.theta_deg,
        )
    start = time.perf_counter()
    projection = ctx.loop.project(theta)
    projection_s = time.perf_counter() - start
    methods: dict[str, Record | None] = {
        "analytic": {
            "v": fk.v,
            "deviation_from_analytic": 0.0,
            "residual": fk.residual,
            "how": "degree-8 resultant polished by Newton steps, home assembly mode",
        },
        "projection": {
            "v": _platform_axes(ctx.robot, projection.q),
            "deviation_from_analytic": 0.0,
            "residual": projection.residual,
            "iterations": projection.iterations,
            "seconds": projection_s,
            "how": "damped Newton projection of the Pinocchio model's loop closures, from "
            "home (ClosedLoop.project)",
        },
        "mujoco": None,
        "mujoco_no_gravity": None,
    }
    skipped = _missing("mujoco", "MuJoCo cross-check")
    if skipped is None:
        for key, run in ctx.mujoco_runs.items():
            methods["mujoco" if key == "gravity" else "mujoco_no_gravity"] = {
                "v": run.v[-1],
                "deviation_from_analytic": 0.0,
                "weld_opening_rad": run.weld_opening[-1],
                "gravity_m_s2": run.gravity,
                "timestep_s": run.timestep,
                "steps": run.steps,
                "how": f"the exported MJCF stepped with the inputs imposed along the "
                f"{ctx.samples}-sample motion, the welds settled, the platform body read",
            }
    for method in methods.values():
        if method is not None:
            method["deviation_from_analytic"] = float(_deviation(method["v"], fk.v))

    def deviation(key: str) -> float | None:
        method = methods[key]
        return None if method is None else float(method["deviation_from_analytic"])

    checks: Record = {
        "projection": _within(deviation("projection"), PROJECTION_TOLERANCE),
        "mujoco": _within(deviation("mujoco"), MUJOCO_TOLERANCE["gravity"]),
        "mujoco_no_gravity": _within(
            deviation("mujoco_no_gravity"), MUJOCO_TOLERANCE["no_gravity"]
        ),
    }
    jac = jacobian(theta[None], ctx.design, R=fk.R[None])
    data: Record = {
        "theta_deg": ctx.theta_deg,
        "mode": _assembly_label(jac.b[0], float(jac.det_a[0])),
        **_orientation(fk.R),
        "methods": methods,
        "tolerance": {
            "projection": PROJECTION_TOLERANCE,
            "mujoco": MUJOCO_TOLERANCE["gravity"],
            "mujoco_no_gravity": MUJOCO_TOLERANCE["no_gravity"],
        },
        "within_tolerance": checks,
        "study_agreement": STUDY_AGREEMENT,
        "scene": None,
    }
    scenes: list[ReportItem] = []
    skipped_scene = _missing("meshcat", "scene of the demonstration input")
    target = ctx.file("demo_scene", skipped_scene)
    if target is not None:
        viz = ctx.visualizer
        viz.set_overlays(joint_axes=True, platform_frame=True)
        viz.display(theta)
        where = _degrees_text(ctx.theta_deg)
        viz.save_html(target, title=f"spm-pin demo: theta = {where} deg")
        data["scene"] = _FILES["demo_scene"]
        scenes.append(
            ReportItem(
                _FILES["demo_scene"],
                f"The {ctx.design.name} at theta = {where} deg with the joint axes u_i, w_i, "
                "v_i and the platform frame.",
            )
        )
    return DemoSection(
        "forward_kinematics",
        f"Forward kinematics at theta = {_degrees_text(ctx.theta_deg)} deg, three ways",
        data,
        lines=_fk_lines(data),
        scenes=tuple(scenes),
        skipped=tuple(s for s in (skipped, skipped_scene) if s is not None),
    )


def _within(deviation: float | None, tolerance: float) -> bool | None:
    return None if deviation is None else bool(deviation <= tolerance)


def _verdict(within: bool, tolerance: float) -> str:
    return f"within {_sci(tolerance)}" if within else f"OUTSIDE the tolerance {_sci(tolerance)}"


def _sci(value: float) -> str:
    """A small number as ``1e-4`` (one significant digit)."""
    return f"{value:.0e}".replace("e-0", "e-").replace("e+00", "")


def _methods(data: Record) -> dict[str, Record]:
    """The forward-kinematics methods that ran (MuJoCo's are None without it)."""
    return {key: method for key, method in data["methods"].items() if method is not None}


def _fk_lines(data: Record) -> list[str]:
    methods = _methods(data)
    shown = [key for key in ("analytic", "projection", "mujoco") if key in methods]
    width = 30
    lines = [
        (" " * 5 + "  ".join(f"{_FK_METHODS[key]:<{width}}" for key in shown)).rstrip(),
        " " * 5 + "  ".join(f"{'x':>10}{'y':>10}{'z':>10}" for _ in shown),
    ]
    for i in range(3):
        blocks = [np.asarray(methods[key]["v"])[i] for key in shown]
        lines.append(
            f"{'v_' + str(i + 1):<5}"
            + "  ".join("".join(f"{x:10.6f}" for x in block).ljust(width) for block in blocks)
        )
    deviations = ", ".join(
        f"{_FK_METHODS[key]} {method['deviation_from_analytic']:.1e}"
        for key, method in methods.items()
        if key != "analytic"
    )
    lines += [f"max |v - v_analytic|: {deviations}", ""]
    checks, tolerance = data["within_tolerance"], data["tolerance"]
    projection = methods["projection"]
    lines.append(
        f"Newton projection: {projection['iterations']} steps from home, closure residual "
        f"{projection['residual']:.1e}; " + _verdict(checks["projection"], tolerance["projection"])
    )
    gravity, free = methods.get("mujoco"), methods.get("mujoco_no_gravity")
    if gravity is not None and free is not None:
        lines += [
            "MuJoCo (upright): " + _verdict(checks["mujoco"], tolerance["mujoco"]) + "; its "
            "welds are soft (spring-dampers) and carry the platform's weight: they open by "
            f"{gravity['weld_opening_rad']:.1e} rad",
            "MuJoCo (no gravity): "
            + _verdict(checks["mujoco_no_gravity"], tolerance["mujoco_no_gravity"])
            + f"; without load the welds close (open by {free['weld_opening_rad']:.1e} rad)",
        ]
    else:
        lines.append("MuJoCo: skipped (mujoco is not installed)")
    lines += [
        f"the study (its model against CoppeliaSim): about {_sci(STUDY_AGREEMENT)}",
        f"assembly mode {data['mode']} (home); roll, pitch, yaw [deg] {_vector(data['rpy_deg'])}",
    ]
    return lines


def _vector(values: Any) -> str:
    return " ".join(f"{float(x):.6f}" for x in np.asarray(values).ravel())


def _demo_assembly_modes(ctx: DemoContext) -> DemoSection:
    modes = [
        {key: mode[key] for key in ("label", "home", "residual", "v")}
        for mode in fk_all_record(ctx.theta_deg, ctx.design)["modes"]
    ]
    data = {"theta_deg": ctx.theta_deg, "count": len(modes), "modes": modes}
    text = {
        "count": len(modes),
        "labels": [str(m["label"]) + (" (home)" if m["home"] else "") for m in modes],
        "max_residual": max((float(m["residual"]) for m in modes), default=None),
    }
    return DemoSection("assembly_modes", "Every real assembly mode at that input", data, text)


def _demo_velocity(ctx: DemoContext) -> DemoSection:
    jac = jacobian(ctx.theta, ctx.design, R=ctx.home.R)
    data = {
        "J": jac.J,
        "det_a": jac.det_a,
        "b": jac.b,
        "full_rank": not (bool(jac.type_i) or bool(jac.type_ii)),
        "dexterity": jac.dexterity,
        "dexterity_ga": jac.dexterity_ga,
        "singularity_margin": jac.singularity_margin,
        "type_i_singular": jac.type_i,
        "type_ii_singular": jac.type_ii,
    }
    return DemoSection("velocity", "Singularity check: omega = J theta_dot", data)


def _demo_inverse(ctx: DemoContext) -> DemoSection:
    ik = inverse_kinematics(ctx.home.R, ctx.design)
    error = np.degrees(np.max(np.abs(ik.theta - ctx.theta)))
    data = {
        "theta_deg": np.degrees(ik.theta),
        "mode": ik.mode,
        "b": ik.b,
        "round_trip_error_deg": error,
    }
    where = ", ".join(f"{x:g}" for x in np.round(np.degrees(ctx.theta), 6))
    return DemoSection(
        "inverse",
        f"Inverse kinematics of the platform orientation at theta = [{where}] deg "
        "(home working mode, round trip)",
        data,
    )


def _demo_motion(ctx: DemoContext) -> DemoSection:
    path = ctx.path
    path_deg = np.degrees(path)
    motion = ctx.motion
    # Independent checks: the home mode solved at every sample on its own, and the
    # Pinocchio model's loops closed by path following.
    fk_each = forward_kinematics(path, ctx.design)
    followed = ctx.loop.follow(path)
    v_projection = np.array([_platform_axes(ctx.robot, q) for q in followed.q])
    runs: dict[str, MujocoAxes] | None = None
    skipped = [s for s in (_missing("mujoco", "MuJoCo samples of the motion"),) if s]
    if not skipped:
        runs = ctx.mujoco_runs
    v_mujoco = None if runs is None else runs["gravity"].v
    deviation_projection = _deviation(v_projection, motion.v)
    deviation_mujoco = None if v_mujoco is None else _deviation(v_mujoco, motion.v)
    samples = [
        {
            "theta_deg": path_deg[k],
            "label": motion.labels[k],
            "home": motion.home[k],
            "v": motion.v[k],
            "v_projection": v_projection[k],
            "v_mujoco": None if v_mujoco is None else v_mujoco[k],
            "deviation_projection": deviation_projection[k],
            "deviation_mujoco": None if deviation_mujoco is None else deviation_mujoco[k],
        }
        for k in range(ctx.samples)
    ]
    summary: Record = {
        "samples": ctx.samples,
        "all_home": bool(np.all(motion.home)),
        "lost": bool(np.any(motion.lost)),
        "subdivisions": motion.subdivisions,
        "deviation_from_fk": float(np.max(np.abs(motion.R - fk_each.R))),
        "max_deviation_projection": float(deviation_projection.max()),
        "max_deviation_mujoco": None if deviation_mujoco is None else float(deviation_mujoco.max()),
        "projection_newton_steps": followed.total_iterations,
        "max_projection_residual": float(np.max(followed.residual)),
        "within_tolerance": {
            "projection": _within(float(deviation_projection.max()), PROJECTION_TOLERANCE),
            "mujoco": _within(
                None if deviation_mujoco is None else float(deviation_mujoco.max()),
                MUJOCO_TOLERANCE["gravity"],
            ),
        },
        "plot": None,
        "scene": None,
    }
    figures: list[ReportItem] = []
    scenes: list[ReportItem] = []
    skipped_plot = _missing("matplotlib", "plot of the motion")
    target = ctx.file("motion_plot", skipped_plot)
    if target is not None:
        _plot_motion(target, path_deg, motion.v, v_projection, v_mujoco)
        summary["plot"] = _FILES["motion_plot"]
        figures.append(
            ReportItem(
                _FILES["motion_plot"],
                "Top: the x, y, z components of the platform axes v_1, v_2, v_3 along the "
                "motion, analytic (lines) and Newton projection (circles)"
                + (", MuJoCo (crosses)" if v_mujoco is not None else "")
                + ". Bottom: their largest deviation from the analytic axes at each sample, "
                "with the study's agreement (dashed).",
            )
        )
    elif skipped_plot is not None:
        skipped.append(skipped_plot)
    skipped_scene = _missing("meshcat", "animation of the motion")
    target = ctx.file("motion_scene", skipped_scene)
    if target is not None:
        viz = ctx.visualizer
        viz.set_overlays(joint_axes=True, platform_frame=False)
        viz.animate(path, dt=2.0 / (ctx.samples - 1), repetitions=1000)
        viz.save_html(target, title="spm-pin demo: the motion")
        summary["scene"] = _FILES["motion_scene"]
        scenes.append(
            ReportItem(
                _FILES["motion_scene"],
                f"The motion from home to theta = {_degrees_text(ctx.theta_deg)} deg, "
                f"{ctx.samples} samples (the animation repeats; drag to orbit).",
            )
        )
    elif skipped_scene is not None:
        skipped.append(skipped_scene)
    shown = [k for k in _SHOWN_SAMPLES if k < ctx.samples]
    text = {
        **summary,
        "shown": [
            {
                "sample": k,
                "theta_deg": path_deg[k],
                "v": motion.v[k],
                "deviation_projection": deviation_projection[k],
                "deviation_mujoco": None if deviation_mujoco is None else deviation_mujoco[k],
            }
            for k in shown
        ],
    }
    return DemoSection(
        "motion",
        f"The motion from home to that input, {ctx.samples} samples",
        {**summary, "path": samples},
        text,
        figures=tuple(figures),
        scenes=tuple(scenes),
        skipped=tuple(skipped),
    )


def _demo_colliding_input(ctx: DemoContext) -> DemoSection:
    from .collision import check_input
    from .workspace import gaps_from_theta

    theta = ctx.colliding_theta
    report = check_input(theta, ctx.robot)
    modes = forward_kinematics_all(theta, ctx.design)
    count = int(modes.count)
    links = sorted({name for pair in report.pairs for name in pair})
    gaps = gaps_from_theta(theta, ctx.design) if ctx.design.is_coaxial else None
    data: Record = {
        "theta_deg": ctx.colliding_theta_deg,
        "gaps_deg": gaps,
        "home_mode_exists": report.reachable,
        "count": count,
        "labels": modes.labels[:count],
        "mode": report.mode,
        "checked": _checked_links(report),
        "collision": report.collision,
        "pairs": [list(pair) for pair in report.pairs],
        "links": links,
        "min_distance_m": report.min_distance,
        "drawn_black": None,
        "scene": None,
    }
    scenes: list[ReportItem] = []
    skipped = _missing("meshcat", "scene of the colliding input")
    target = ctx.file("colliding_scene", skipped)
    if target is not None and report.mode is not None:
        viz = ctx.visualizer
        viz.set_overlays(joint_axes=False, platform_frame=False)
        viz.display(theta, mode=report.mode)
        data["drawn_black"] = sorted(viz.colliding_links)
        where = _degrees_text(ctx.colliding_theta_deg)
        viz.save_html(target, title=f"spm-pin demo: theta = {where} deg")
        data["scene"] = _FILES["colliding_scene"]
        scenes.append(
            ReportItem(
                _FILES["colliding_scene"],
                f"theta = {where} deg in assembly mode {report.mode}: the colliding links "
                f"({', '.join(links) or 'none'}) in black.",
            )
        )
    text = dict(data)
    text["pairs"] = ["-".join(pair) for pair in report.pairs] or "none"
    text["labels"] = " ".join(str(label) for label in data["labels"])
    return DemoSection(
        "colliding_input",
        f"The colliding input {_degrees_text(ctx.colliding_theta_deg)} deg",
        data,
        text,
        scenes=tuple(scenes),
        skipped=() if skipped is None else (skipped,),
    )


def _demo_workspace(ctx: DemoContext) -> DemoSection:
    from .workspace import WorkspaceSettings, gaps_from_theta, workspace_map

    settings = WorkspaceSettings()
    result = workspace_map(
        ctx.design,
        step_deg=ctx.workspace_step_deg,
        settings=settings,
        progress=ctx.workspace_progress,
    )
    summary = result.summary()
    # The demonstration input and the motion on the map, checked directly.
    motion = ctx.motion
    jac = jacobian(ctx.path, ctx.design, R=motion.R)
    qs = [
        ctx.robot.configuration(theta, motion.labels[k], reference=motion.R[k])
        for k, theta in enumerate(ctx.path)
    ]
    colliding = np.array([bool(ctx.robot.collisions(q, margin=settings.margin)) for q in qs])
    safe = motion.home & (jac.dexterity >= settings.min_dexterity) & ~colliding
    gaps = gaps_from_theta(ctx.path, ctx.design)
    data: Record = {
        "step_deg": ctx.workspace_step_deg,
        **summary,
        "demo_input": {
            "gaps_deg": gaps[-1],
            "safe": bool(safe[-1]),
            "dexterity": jac.dexterity[-1],
            "collision": bool(colliding[-1]),
        },
        "motion_safe_samples": int(np.count_nonzero(safe)),
        "motion_min_dexterity": float(np.min(jac.dexterity)),
        "plots": [],
        "files": [],
    }
    files: tuple[str, ...] = ()
    figures: list[ReportItem] = []
    skipped = _missing("matplotlib", "plots of the workspace")
    folder = ctx.file("workspace_folder")
    if folder is not None:
        written = result.save(folder, plots=skipped is None)
        files = tuple(f"{_FILES['workspace_folder']}/{p.name}" for p in written.values())
        data["files"] = list(files)
    target = ctx.file("workspace_plot", skipped)
    if target is not None:
        colliding_gaps = gaps_from_theta(ctx.colliding_theta, ctx.design)
        _plot_safe_workspace(target, result, gaps, colliding_gaps, ctx)
        data["plots"] = [
            _FILES["workspace_plot"],
            f"{_FILES['workspace_folder']}/gap_map.png",
            f"{_FILES['workspace_folder']}/orientation.png",
        ]
        figures += [
            ReportItem(
                _FILES["workspace_plot"],
                "The safe set over the gaps between neighbouring proximal links (reachable in "
                f"the home mode, dexterity >= {settings.min_dexterity:g}, no self-collision), "
                "the motion (white), the demonstration input (star) and the colliding input "
                "(cross).",
            ),
            ReportItem(
                f"{_FILES['workspace_folder']}/gap_map.png",
                "Reachability, singularity margin, dexterity, self-collision, clearance and "
                "the safe set over the gap plane.",
            ),
            ReportItem(
                f"{_FILES['workspace_folder']}/orientation.png",
                "The orientation workspace: tilt against azimuth - torsion, safe points in blue.",
            ),
        ]
    text = {
        key: value
        for key, value in data.items()
        if key not in ("files", "colliding_points_by_pair", "margin_m")
    }
    return DemoSection(
        "workspace",
        f"The safe workspace ({ctx.workspace_step_deg:g}-degree grid over the gaps)",
        data,
        text,
        figures=tuple(figures),
        skipped=() if skipped is None else (skipped,),
        files=files,
    )


def _demo_torques(ctx: DemoContext) -> DemoSection:
    from .dynamics import (
        XM540_W150,
        ClosedLoopDynamics,
        Trajectory,
        check_servo,
        inverse_dynamics,
        plot_torques,
    )

    motion = Trajectory.minimum_jerk(
        np.zeros(3), ctx.theta, ctx.move_duration_s, ctx.torque_rate_hz
    )
    dynamics = ClosedLoopDynamics(ctx.robot)
    result = inverse_dynamics(dynamics, motion)
    servo = XM540_W150
    check = check_servo(result.torque, result.theta_dot, servo, time=motion.time)
    data: Record = {
        "servo": {
            "name": servo.name,
            "stall_torque_nm": servo.stall_torque,
            "no_load_speed_rpm": servo.no_load_rpm,
        },
        "trajectory": {
            "kind": "minimum jerk, home to the demonstration input",
            "duration_s": motion.duration,
            "samples": int(motion.time.shape[0]),
        },
        "gravity_m_s2": dynamics.gravity,
        "peak_torque_nm": check.peak_torque,
        "rms_torque_nm": check.rms_torque,
        "peak_speed_rpm": check.peak_speed * (60.0 / (2.0 * math.pi)),
        "max_utilisation": check.max_utilisation,
        "within_limits": check.within_limits,
        "worst": _worst_sample(result, motion, check),
        "verdict": check.message,
        "plot": None,
    }
    figures: list[ReportItem] = []
    skipped = _missing("matplotlib", "plot of the torques")
    target = ctx.file("torque_plot", skipped)
    if target is not None:
        plot_torques(result, target, servo)
        data["plot"] = _FILES["torque_plot"]
        figures.append(
            ReportItem(
                _FILES["torque_plot"],
                f"Actuator torques of the motion as a {motion.duration:g} s minimum-jerk move "
                f"(left) and every sample against the {servo.name} torque-speed envelope "
                "(right).",
            )
        )
    return DemoSection(
        "torques",
        "Actuator torques along the motion",
        data,
        figures=tuple(figures),
        skipped=() if skipped is None else (skipped,),
    )


#: The demo's sections, in order. A feature adds its section by appending a function
#: ``DemoContext -> DemoSection`` here.
DEMO_SECTIONS: list[Callable[[DemoContext], DemoSection]] = [
    _demo_design,
    _demo_forward_kinematics,
    _demo_assembly_modes,
    _demo_velocity,
    _demo_inverse,
    _demo_motion,
    _demo_colliding_input,
    _demo_workspace,
    _demo_torques,
]


# ------------------------------------------------------------------------- plots
def _figure(size: tuple[float, float]) -> Any:
    """A matplotlib Figure with an Agg canvas (no global pyplot state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def _plot_motion(
    target: Path,
    path_deg: FloatArray,
    v_analytic: FloatArray,
    v_projection: FloatArray,
    v_mujoco: FloatArray | None,
) -> None:
    figure = _figure((13.0, 7.5))
    axes = figure.subplots(2, 3, sharex=True, height_ratios=(2.0, 1.0))
    samples = np.arange(path_deg.shape[0])
    colors = ("tab:red", "tab:green", "tab:blue")
    floor = 1e-17  # exact agreement drawn at the bottom of the log scale
    for i in range(3):
        top, bottom = axes[0, i], axes[1, i]
        for c, (letter, color) in enumerate(zip("xyz", colors, strict=True)):
            top.plot(samples, v_analytic[:, i, c], "-", color=color, lw=1.2, label=letter)
            top.plot(samples, v_projection[:, i, c], "o", mfc="none", color=color, ms=5)
            if v_mujoco is not None:
                top.plot(samples, v_mujoco[:, i, c], "x", color="k", ms=4)
        top.set_title(f"v_{i + 1}")
        top.set_ylim(-1.08, 1.08)
        top.grid(True, alpha=0.3)
        top.legend(loc="best", fontsize=8, title="analytic", title_fontsize=8)
        deviation = np.abs(v_projection[:, i] - v_analytic[:, i]).max(axis=-1)
        bottom.semilogy(samples, np.maximum(deviation, floor), "o-", ms=3, label="projection")
        if v_mujoco is not None:
            gap = np.abs(v_mujoco[:, i] - v_analytic[:, i]).max(axis=-1)
            bottom.semilogy(samples, np.maximum(gap, floor), "x-", ms=4, color="k", label="MuJoCo")
        bottom.axhline(STUDY_AGREEMENT, color="tab:red", ls="--", lw=0.8, label="the study")
        bottom.set_ylim(floor / 2.0, 1e-2)
        bottom.set_xlabel("sample")
        bottom.grid(True, alpha=0.3)
        bottom.legend(loc="center right", fontsize=7)
    axes[0, 0].set_ylabel("component")
    axes[1, 0].set_ylabel("max |v - v_analytic|")
    end = _degrees_text(np.round(path_deg[-1], 6).tolist())
    figure.suptitle(
        f"Platform axes from home to theta = {end} deg: analytic (lines), Newton projection "
        "(circles)" + (", MuJoCo (crosses)" if v_mujoco is not None else "")
    )
    figure.savefig(target, format="png", dpi=100)


def _plot_safe_workspace(
    target: Path, result: Any, gaps: FloatArray, colliding_gaps: FloatArray, ctx: DemoContext
) -> None:
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    f = result.fields
    category = np.zeros(len(result))
    reachable = f["reachable"]
    category[reachable] = 2.0
    category[reachable & f["collision"]] = 1.0
    category[f["safe"]] = 3.0
    d12, d23, index = result.grid
    image = np.full((d12.size, d23.size), np.nan)
    image[index[:, 0], index[:, 1]] = category
    colors = ("0.93", "tab:red", "orange", "tab:blue")
    figure = _figure((7.5, 6.8))
    axis = figure.subplots()
    axis.imshow(
        image,
        origin="lower",
        extent=(d23[0], d23[-1], d12[0], d12[-1]),
        cmap=ListedColormap(colors),
        vmin=-0.5,
        vmax=3.5,
        interpolation="nearest",
        aspect="equal",
    )
    axis.plot(gaps[:, 1], gaps[:, 0], "-", color="white", lw=2.5)
    axis.plot(gaps[:, 1], gaps[:, 0], ".", color="k", ms=3, label="the motion")
    axis.plot(gaps[-1, 1], gaps[-1, 0], "*", color="gold", mec="k", ms=16, label="demonstration")
    axis.plot(
        colliding_gaps[1],
        colliding_gaps[0],
        "X",
        color="tab:red",
        mec="k",
        ms=11,
        label="colliding",
    )
    low = min(float(d23[0]), float(colliding_gaps[1])) - 10.0
    axis.set_xlim(low, float(d23[-1]) + 5.0)
    axis.set_ylim(min(float(d12[0]), float(colliding_gaps[0])) - 10.0, float(d12[-1]) + 5.0)
    axis.set_xlabel("D23 [deg]")
    axis.set_ylabel("D12 [deg]")
    handles = [
        Patch(color=colors[0], label="no home-mode assembly"),
        Patch(color=colors[1], label="links collide"),
        Patch(color=colors[2], label="dexterity too low"),
        Patch(color=colors[3], label="safe"),
    ]
    markers, _ = axis.get_legend_handles_labels()
    axis.legend(handles=handles + markers, loc="upper right", fontsize=8)
    axis.set_title(
        f"{ctx.design.name}: safe workspace over the proximal-link gaps "
        f"({ctx.workspace_step_deg:g} deg grid)",
        fontsize=10,
    )
    figure.savefig(target, format="png", dpi=100)


# -------------------------------------------------------------------------- report
_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 72rem; margin: 2rem auto;
       padding: 0 1rem; color: #222; line-height: 1.45; }
h1 { font-size: 1.6rem; } h2 { margin-top: 2.5rem; border-bottom: 1px solid #ccc; }
pre { background: #f5f6f8; padding: 0.8rem; overflow-x: auto; font-size: 0.82rem; }
table { border-collapse: collapse; font-variant-numeric: tabular-nums; margin: 1rem 0; }
th, td { border: 1px solid #ccd; padding: 0.2rem 0.5rem; text-align: right; }
th { background: #eef0f4; }
figure { margin: 1.2rem 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
iframe { width: 100%; height: 30rem; border: 1px solid #ccd; }
figcaption { font-size: 0.9rem; color: #555; }
.skipped { background: #fff4e0; border-left: 4px solid #f0a020; padding: 0.5rem 0.8rem; }
"""


def _fk_table(data: Record) -> str:
    """The platform axes by every method side by side: one row per component."""
    methods = _methods(data)
    head = "".join(f"<th>{html.escape(_FK_METHODS[key])}</th>" for key in methods)
    rows = []
    for i in range(3):
        for c, letter in enumerate("xyz"):
            cells = "".join(f"<td>{np.asarray(m['v'])[i, c]:.6f}</td>" for m in methods.values())
            rows.append(f"<tr><th>v<sub>{i + 1}</sub> {letter}</th>{cells}</tr>")
    deviations = "".join(
        f"<td>{method['deviation_from_analytic']:.1e}</td>" for method in methods.values()
    )
    rows.append(f"<tr><th>max |v - v<sub>analytic</sub>|</th>{deviations}</tr>")
    return (
        f"<table><tr><th></th>{head}</tr>"
        + "".join(rows)
        + "</table>"
        + f"<p>The study reported an agreement of about {_sci(STUDY_AGREEMENT)} between its "
        "model and CoppeliaSim.</p>"
    )


def _section_html(section: DemoSection) -> str:
    parts = [f'<section id="{section.key}">', f"<h2>{html.escape(section.title)}</h2>"]
    if section.key == "forward_kinematics":
        parts.append(_fk_table(section.data))
    parts.append("<pre>" + html.escape("\n".join(section.text_lines())) + "</pre>")
    for item in section.figures:
        parts.append(
            f'<figure><img src="{html.escape(item.path)}" alt="{html.escape(item.caption)}">'
            f"<figcaption>{html.escape(item.caption)}</figcaption></figure>"
        )
    for item in section.scenes:
        path = html.escape(item.path)
        parts.append(
            f'<figure><iframe src="{path}" title="{html.escape(item.caption)}" '
            'loading="lazy"></iframe>'
            f"<figcaption>{html.escape(item.caption)} "
            f'<a href="{path}">Open the scene on its own page.</a></figcaption></figure>'
        )
    for skip in section.skipped:
        parts.append(_skipped_html(skip))
    parts.append("</section>")
    return "\n".join(parts)


def _skipped_html(skip: Skipped) -> str:
    return (
        f'<p class="skipped">Skipped: {html.escape(skip.part)} ({html.escape(skip.missing)} '
        f"is not installed; <code>{html.escape(skip.install)}</code>).</p>"
    )


def _report_html(
    ctx: DemoContext, sections: list[DemoSection], skipped: list[Skipped], seconds: float
) -> str:
    where = _degrees_text(ctx.theta_deg)
    contents = "".join(
        f'<li><a href="#{section.key}">{html.escape(section.title)}</a></li>'
        for section in sections
    )
    missing = ""
    if skipped:
        missing = '<p class="skipped">Parts skipped for missing optional dependencies: ' + (
            "; ".join(html.escape(f"{s.part} ({s.missing})") for s in skipped)
            + f". Install them with <code>{html.escape(INSTALL_DEMO)}</code>.</p>"
        )
    body = "\n".join(_section_html(section) for section in sections)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>spm-pin demo: the {html.escape(ctx.design.name)}</title>
<style>{_STYLE}</style>
</head>
<body>
<h1>spm-pin {html.escape(__version__)}: the published study of the {html.escape(ctx.design.name)},
reproduced</h1>
<p>The study "Modeling and Simulation of Spherical Parallel Manipulators in CoppeliaSim
(V-REP)" compared the platform axes of a 3D-printed coaxial SPM computed from its kinematic
model with those of a simulation at theta = {html.escape(where)} deg, showed the motion from
home to that input at {ctx.samples} samples and found a link collision at
theta = {html.escape(_degrees_text(ctx.colliding_theta_deg))} deg. This report does the same
on the same prototype with spm-pin, and maps the safe workspace and the actuator torques
that the study left as future work. The scenes are interactive: drag to orbit, scroll to
zoom. Every number is in <a href="{_FILES["record"]}">{_FILES["record"]}</a>.</p>
{missing}
<nav><ol>{contents}</ol></nav>
{body}
<footer><p>Made by <code>spm demo</code> (spm-pin {html.escape(__version__)}) in
{seconds:.1f} s.</p></footer>
</body>
</html>
"""


# ---------------------------------------------------------------------- running
ProgressMode = Literal["auto", "bar", "lines", "off"]


class _Progress:
    """Progress over the sections on a stream: a tqdm bar, one line per section, or none."""

    def __init__(self, mode: ProgressMode, total: int, stream: IO[str]) -> None:
        if mode == "auto":
            isatty = getattr(stream, "isatty", None)
            mode = "bar" if callable(isatty) and isatty() else "lines"
        self.mode = mode
        self.total = total
        self.stream = stream
        self.count = 0
        self._bar: Any = None
        if mode == "bar":
            from tqdm.auto import tqdm

            self._bar = tqdm(total=total, desc="spm demo", unit="part", file=stream)

    def start(self, title: str) -> None:
        if self._bar is not None:
            self._bar.set_postfix_str(title[:40])

    def done(self, title: str, seconds: float) -> None:
        self.count += 1
        if self._bar is not None:
            self._bar.update(1)
        elif self.mode == "lines":
            print(
                f"spm demo [{self.count}/{self.total}] {title} ({seconds:.1f} s)",
                file=self.stream,
                flush=True,
            )

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def run_demo(
    ctx: DemoContext | None = None,
    *,
    progress: ProgressMode = "auto",
    stream: IO[str] | None = None,
) -> DemoResult:
    """Run the study: every section, then the report in ``ctx.out``.

    Args:
        ctx: What to run (default :class:`DemoContext`, the published study, no files).
        progress: ``"bar"`` (tqdm), ``"lines"`` (one line per finished section),
            ``"off"``, or ``"auto"``: a bar on a terminal, lines otherwise.
        stream: Where progress goes (default ``sys.stderr``).

    Returns:
        :class:`DemoResult`.

    Raises:
        InputError: bad settings in ``ctx``.
        OSError: the report folder cannot be made or written.
    """
    if ctx is None:
        ctx = DemoContext()
    if ctx.out is not None:
        ctx.out.mkdir(parents=True, exist_ok=True)
    begin = time.perf_counter()
    bar = _Progress(progress, len(DEMO_SECTIONS), sys.stderr if stream is None else stream)
    if bar.mode == "bar" and not ctx.workspace_progress:
        ctx = dataclasses.replace(ctx, workspace_progress=True)
    sections: list[DemoSection] = []
    timing: dict[str, float] = {}
    try:
        for make_section in DEMO_SECTIONS:
            bar.start(make_section.__name__.removeprefix("_demo_").replace("_", " "))
            start = time.perf_counter()
            section = make_section(ctx)
            timing[section.key] = time.perf_counter() - start
            sections.append(section)
            bar.done(section.title, timing[section.key])
    finally:
        bar.close()
    skipped = _unique([skip for section in sections for skip in section.skipped])
    failed = [
        f"{section.key}: {method}"
        for section in sections
        for method, within in section.data.get("within_tolerance", {}).items()
        if within is False
    ]
    record: Record = {
        "spm_pin_version": __version__,
        "theta_deg": ctx.theta_deg,
        "colliding_theta_deg": ctx.colliding_theta_deg,
        **{section.key: section.data for section in sections},
        "skipped": [skip.as_dict() for skip in skipped],
        "failed_checks": failed,
        "timing_s": timing,
        "runtime_s": None,
        "report": None,
    }
    files: dict[str, Path] = {}
    if ctx.out is not None:
        files = _report_files(ctx.out, sections)
        record["report"] = {
            "out": str(ctx.out),
            "index_html": str(files[_FILES["index"]]),
            "files": sorted(files),
        }
        seconds = time.perf_counter() - begin
        html_text = _report_html(ctx, sections, skipped, seconds)
        files[_FILES["index"]].write_text(html_text, encoding="utf-8")
    seconds = time.perf_counter() - begin
    record["runtime_s"] = seconds
    if ctx.out is not None:
        files[_FILES["record"]].write_text(_dumps(record) + "\n", encoding="utf-8")
    return DemoResult(
        record=_plain(record),
        lines=_text(ctx, sections, skipped, failed, files, seconds),
        sections=sections,
        skipped=skipped,
        failed_checks=failed,
        files=files,
        seconds=seconds,
    )


def _unique(skipped: list[Skipped]) -> list[Skipped]:
    seen: dict[tuple[str, str], Skipped] = {}
    for skip in skipped:
        seen.setdefault((skip.part, skip.missing), skip)
    return list(seen.values())


def _report_files(out: Path, sections: list[DemoSection]) -> dict[str, Path]:
    """Every file of the report, by its path relative to ``out``."""
    names = [_FILES["index"], _FILES["record"]]
    for section in sections:
        names += [item.path for item in (*section.figures, *section.scenes)]
        names += list(section.files)
    return {name: out / name for name in dict.fromkeys(names)}


def _text(
    ctx: DemoContext,
    sections: list[DemoSection],
    skipped: list[Skipped],
    failed: list[str],
    files: dict[str, Path],
    seconds: float,
) -> list[str]:
    where = _degrees_text(ctx.theta_deg)
    lines = [
        f"spm-pin {__version__}: the published study of the {ctx.design.name}, reproduced "
        f"(theta = {where} deg)"
    ]
    for section in sections:
        lines += ["", f"== {section.title} ==", *section.text_lines()]
    lines.append("")
    if failed:
        lines.append("Cross-checks OUTSIDE their tolerance: " + ", ".join(failed))
    if skipped:
        lines.append("Skipped (optional dependencies missing):")
        lines += [f"  {skip.part}: needs {skip.missing}" for skip in skipped]
        lines.append(f"  install them with: {INSTALL_DEMO}")
    if _FILES["index"] in files:
        index = files[_FILES["index"]]
        lines.append(f"report: {index} (open it in a browser; it works offline)")
    lines.append(f"done in {seconds:.1f} s")
    return lines


def demo_record(ctx: DemoContext | None = None) -> tuple[Record, list[str]]:
    """The study's JSON record and its text lines (:func:`run_demo` without progress)."""
    result = run_demo(ctx, progress="off")
    return result.record, result.lines
