"""The sections of the study, in order (:data:`DEMO_SECTIONS`): the design, forward
kinematics three ways, every assembly mode, the singularity check, the inverse
round trip, the motion from home, the colliding input, the safe workspace and the
actuator torques. Each is a function ``DemoContext -> DemoSection``."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from .._records import FloatArray, Record, fk_all_record
from .._records import assembly_label as _assembly_label
from .._records import checked_links as _checked_links
from .._records import orientation as _orientation
from .._records import worst_sample as _worst_sample
from ..errors import InputError
from ..kinematics import forward_kinematics, forward_kinematics_all, inverse_kinematics, jacobian
from ._extras import missing as _missing
from .context import FILES as _FILES
from .context import FK_METHODS as _FK_METHODS
from .context import (
    MUJOCO_TOLERANCE,
    PROJECTION_TOLERANCE,
    STUDY_AGREEMENT,
    DemoContext,
    DemoSection,
    ReportItem,
)
from .context import SHOWN_SAMPLES as _SHOWN_SAMPLES
from .context import degrees_text as _degrees_text
from .context import methods as _methods
from .context import sci as _sci
from .context import verdict as _verdict
from .mujoco import MujocoAxes
from .plots import plot_motion as _plot_motion
from .plots import plot_safe_workspace as _plot_safe_workspace

if TYPE_CHECKING:  # Pinocchio is imported when a section needs it
    from ..model.robot import SPMRobot

__all__ = ["DEMO_SECTIONS"]


def _deviation(a: FloatArray, b: FloatArray) -> FloatArray:
    """Largest |a - b| over the last two axes (components of the three axes v_i)."""
    result: FloatArray = np.abs(np.asarray(a) - np.asarray(b)).max(axis=(-2, -1))
    return result


def _platform_axes(robot: SPMRobot, q: FloatArray) -> FloatArray:
    """v_i = R v_i0 (rows) with R the platform frame's rotation at q (Pinocchio)."""
    R = np.array(robot.placement(q, "platform").rotation)
    result: FloatArray = np.einsum("jk,ik->ij", R, robot.design.v0)
    return result


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
        animation = viz.animate(path, dt=2.0 / (ctx.samples - 1), repetitions=1000)
        viz.save_html(target, title="spm-pin demo: the motion")
        summary["scene"] = _FILES["motion_scene"]
        half = (ctx.samples - 1) // 2  # the picture: half way, unlike the other scenes
        scenes.append(
            ReportItem(
                _FILES["motion_scene"],
                f"The motion from home to theta = {_degrees_text(ctx.theta_deg)} deg, "
                f"{ctx.samples} samples (the animation repeats; drag to orbit).",
                picture_time_s=float(animation.times[half]),
                picture_note=f"The picture shows sample {half}, "
                f"theta = {_degrees_text(path_deg[half].tolist())} deg.",
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
    from ..collision import check_input
    from ..workspace import gaps_from_theta

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
    from ..workspace import WorkspaceSettings, gaps_from_theta, workspace_map

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
                "the motion from home (black dots on a white line), the demonstration input "
                "(gold star) and the colliding input (red cross).",
            ),
            ReportItem(
                f"{_FILES['workspace_folder']}/gap_map.png",
                "Reachability, singularity margin, dexterity, self-collision, clearance and "
                "the safe set over the gap plane (yes/no maps with a legend of their two "
                "values, the others with a colour bar; white: outside the gap plane).",
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
    from ..dynamics import (
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
        "limiting_factor": check.limit,
        "plot": None,
    }
    figures: list[ReportItem] = []
    skipped = _missing("matplotlib", "plot of the torques")
    target = ctx.file("torque_plot", skipped)
    if target is not None:
        where = _degrees_text(ctx.theta_deg)
        plot_torques(
            result,
            target,
            servo,
            title=f"Actuator torques of the {motion.duration:g} s minimum-jerk move from home "
            f"to theta = {where} deg against the {servo.name}",
        )
        data["plot"] = _FILES["torque_plot"]
        figures.append(
            ReportItem(
                _FILES["torque_plot"],
                f"Left: the actuator torques of the motion as a {motion.duration:g} s "
                "minimum-jerk move. Right: every sample (coloured lines) in the torque-speed "
                f"plane, inside the full {servo.name} envelope (grey: the current limit "
                f"+-{servo.stall_torque:g} N m and the voltage lines through the no-load "
                f"speed {servo.no_load_rpm:g} rpm), with contours of the load and the "
                f"sample of the peak load (star), set by {check.limit}.",
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
