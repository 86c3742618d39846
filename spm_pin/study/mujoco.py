"""Forward kinematics by MuJoCo for the study's cross-check: the exported MJCF
stepped with the inputs imposed, its welds left to close the loops
(:func:`mujoco_platform_axes`), and the platform axes read from MuJoCo's body pose."""

from __future__ import annotations

import dataclasses
import math
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .._records import FloatArray
from ..design import SPMDesign
from ..errors import InputError
from ._extras import install as _install

if TYPE_CHECKING:  # Pinocchio is imported when the cross-check runs
    from ..model.robot import SPMRobot

__all__ = [
    "MUJOCO_PASSIVE_DAMPING",
    "MUJOCO_SETTLE_STEPS",
    "MUJOCO_TIMESTEP",
    "MujocoAxes",
    "export_mjcf",
    "mujoco_platform_axes",
]

#: MuJoCo's physics step in the cross-check [s] (the welds' time constant is twice it).
MUJOCO_TIMESTEP = 1e-4
#: MuJoCo steps per sample: the inputs move during the first half and are held while
#: the welds settle during the second.
MUJOCO_SETTLE_STEPS = 500
#: Viscous damping of the passive joints in the cross-check [N m s/rad]: it settles
#: the welds' oscillation and has no effect at rest.
MUJOCO_PASSIVE_DAMPING = 0.05


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


def export_mjcf(design: SPMDesign, folder: Path) -> Path:
    from ..model.export import export

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
    from ..dynamics import MUJOCO_SOLIMP
    from ..model.robot import ACTUATED_JOINTS, END_BODIES, JOINT_NAMES, build_robot

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
            file = export_mjcf(robot.design, Path(folder))
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
