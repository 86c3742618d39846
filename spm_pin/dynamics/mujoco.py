"""The same motion in MuJoCo, for cross-checking the simulator (the ``sim`` extra).

:func:`simulate_mujoco` loads the exported MJCF of the robot, copies the physics of a
:class:`~spm_pin.dynamics.ClosedLoopDynamics` (gravity, armature, viscous friction)
and runs a controller as :class:`~spm_pin.dynamics.Simulator` does; MuJoCo is
imported when it is called.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .._checks import check_count
from ..errors import InputError
from ..model.robot import JOINT_NAMES, SPMRobot
from ._checks import positive, vector
from ._constants import DEFAULT_DT, MUJOCO_INTEGRATORS, MUJOCO_SOLIMP, FloatArray
from .closed_loop import ClosedLoopDynamics, _dynamics
from .simulator import Controller, SimulationResult

__all__ = ["simulate_mujoco"]


def simulate_mujoco(
    mjcf: str | Path,
    dynamics: ClosedLoopDynamics | SPMRobot | None,
    duration: float,
    controller: Controller | npt.ArrayLike | None = None,
    *,
    state: npt.ArrayLike | None = None,
    theta_dot: npt.ArrayLike | None = None,
    dt: float = DEFAULT_DT,
    substeps: int = 10,
    integrator: str = "rk4",
    solref: tuple[float, float] | None = None,
    solimp: Sequence[float] = MUJOCO_SOLIMP,
    record_every: int = 1,
) -> SimulationResult:
    """The same motion in MuJoCo, for cross-checking (needs the ``mujoco`` package).

    MuJoCo loads the exported MJCF (``spm export``: the same tree and welds), with the
    gravity, armature and viscous friction of ``dynamics``. The controller runs every
    ``dt`` (as in :class:`Simulator`) and its torque is held over ``substeps`` MuJoCo
    steps of ``dt / substeps``. MuJoCo's constraints are soft (a spring-damper with
    time constant solref[0]): the defaults stiffen them to twice the physics step
    with solimp close to 1, which brings MuJoCo within about 1e-7 rad of the rigid
    answer; MuJoCo's stock values (solref 0.02 s, solimp 0.9/0.95) and a 1 ms step
    leave errors near 1e-2 rad.

    Args:
        mjcf: Path of the MJCF file of ``dynamics.robot``'s design.
        dynamics: The physics to copy (gravity, armature, viscous friction; Coulomb
            friction is not supported).
        duration: Simulated time [s].
        controller: As in :meth:`Simulator.run`.
        state: Initial theta (3,) [rad] or closed q (9,) (default home).
        theta_dot: Initial input speeds [rad/s] (default 0).
        dt: Control period [s].
        substeps: MuJoCo steps per control period (>= 1).
        integrator: MuJoCo integrator: ``"rk4"``, ``"euler"``, ``"implicit"`` or
            ``"implicitfast"``.
        solref: (time constant [s], damping ratio) of the welds (default
            (2 dt / substeps, 1)).
        solimp: The welds' impedance (5 numbers).
        record_every: Record every k-th control period.

    Returns:
        :class:`SimulationResult` (``max_closure_residual``: the largest Pinocchio weld
        residual at the recorded samples; ``theta_ddot``: MuJoCo's accelerations).

    Raises:
        InputError: bad arguments, Coulomb friction, an MJCF of another robot.
        ImportError: MuJoCo is not installed (``pip install spm-pin[sim]``).
    """
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - mujoco is in the test extra
        raise ImportError("simulate_mujoco needs MuJoCo: pip install 'spm-pin[sim]'") from exc
    dyn = _dynamics(dynamics)
    length = positive(duration, "duration", "[s]")
    period = positive(dt, "dt", "[s]")
    check_count(substeps, "substeps", 1)
    check_count(record_every, "record_every", 1)
    if integrator not in MUJOCO_INTEGRATORS:
        raise InputError(
            f"integrator must be one of {list(MUJOCO_INTEGRATORS)}, got {integrator!r}",
            argument="integrator",
            value=integrator,
        )
    if dyn.friction is not None and dyn.friction.has_coulomb:
        raise InputError(
            "simulate_mujoco supports viscous friction only (MuJoCo's frictionloss is "
            "not a smoothed Coulomb law)",
            argument="dynamics",
        )
    if not isinstance(mjcf, (str, Path)):
        raise InputError(
            f"mjcf must be the path of an MJCF file (str or Path), got {type(mjcf).__name__}",
            argument="mjcf",
            value=mjcf,
        )
    file = Path(mjcf)
    if not file.is_file():
        raise InputError(f"MJCF file {str(file)!r} does not exist", argument="mjcf", value=mjcf)
    model = mujoco.MjModel.from_xml_path(str(file))
    names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt))
    mass = float(np.sum(model.body_mass))
    if names != JOINT_NAMES or not math.isclose(mass, dyn.robot.total_mass, rel_tol=1e-9):
        raise InputError(
            f"{file} is not the MJCF of this robot (joints {names}, total mass {mass:.6g} kg "
            f"vs {dyn.robot.total_mass:.6g} kg); export it with spm export",
            argument="mjcf",
            value=mjcf,
        )
    step = period / substeps
    model.opt.timestep = step
    model.opt.gravity[:] = dyn.gravity
    model.opt.integrator = {
        "euler": mujoco.mjtIntegrator.mjINT_EULER,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
        "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    }[integrator]
    reference = (2.0 * step, 1.0) if solref is None else tuple(float(x) for x in solref)
    impedance = np.array(solimp, dtype=float)
    if len(reference) != 2 or impedance.shape != (5,):
        raise InputError("solref needs 2 numbers and solimp 5", argument="solref")
    model.eq_solref[:] = reference
    model.eq_solimp[:] = impedance
    model.dof_armature[:] = 0.0
    model.dof_armature[dyn.actuated_idx] = dyn.armature
    model.dof_damping[:] = 0.0 if dyn.friction is None else dyn.friction.viscous
    data = mujoco.MjData(model)
    q0 = dyn.configuration(np.zeros(3) if state is None else state)
    rate = np.zeros(3) if theta_dot is None else vector(theta_dot, 3, "theta_dot", "[rad/s]")
    data.qpos[:] = q0
    data.qvel[:] = dyn.velocity(q0, rate)
    mujoco.mj_forward(model, data)

    steps = max(1, round(length / period))
    call: Controller | None = controller if callable(controller) else None
    constant = np.zeros(3)
    if controller is not None and call is None:
        constant = vector(controller, 3, "controller", "[N m] (a constant torque)")
    idx = dyn.actuated_idx
    records: dict[str, list[Any]] = {
        key: []
        for key in ("time", "q", "v", "ddq", "torque", "work", "kinetic", "potential", "loss")
    }
    work = loss = 0.0
    damping = model.dof_damping.copy()

    def torque_now(t: float) -> FloatArray:
        if call is None:
            return constant
        return vector(
            call(t, data.qpos[idx].copy(), data.qvel[idx].copy()), 3, "controller output", "[N m]"
        )

    def record(t: float, tau: FloatArray) -> None:
        q = data.qpos.copy()
        v = data.qvel.copy()
        records["time"].append(t)
        records["q"].append(q)
        records["v"].append(v)
        records["ddq"].append(data.qacc.copy())
        records["torque"].append(tau.copy())
        records["work"].append(work)
        records["loss"].append(loss)
        kinetic, potential = dyn._energy(q, v)
        records["kinetic"].append(kinetic)
        records["potential"].append(potential)

    tau = torque_now(0.0)
    data.qfrc_applied[:] = 0.0
    data.qfrc_applied[idx] = tau
    mujoco.mj_forward(model, data)
    record(0.0, tau)
    for k in range(1, steps + 1):
        theta_before = data.qpos[idx].copy()
        power_before = float(np.dot(damping * data.qvel, data.qvel))
        mujoco.mj_step(model, data, nstep=substeps)
        work += float(tau.dot(data.qpos[idx] - theta_before))
        power_after = float(np.dot(damping * data.qvel, data.qvel))
        loss += 0.5 * period * (power_before + power_after)
        t = k * period
        tau = torque_now(t)
        data.qfrc_applied[idx] = tau
        mujoco.mj_forward(model, data)
        if k % record_every == 0 or k == steps:
            record(t, tau)
    q_all = np.array(records["q"])
    residuals = np.array([float(dyn.robot.closure_residual(q)) for q in q_all])
    return SimulationResult(
        time=np.array(records["time"]),
        theta=q_all[:, idx],
        theta_dot=np.array(records["v"])[:, idx],
        theta_ddot=np.array(records["ddq"])[:, idx],
        torque=np.array(records["torque"]),
        q=q_all,
        kinetic=np.array(records["kinetic"]),
        potential=np.array(records["potential"]),
        actuator_work=np.array(records["work"]),
        friction_loss=np.array(records["loss"]),
        closure_residual=residuals,
        max_closure_residual=float(residuals.max()),
        steps=steps * substeps,
        dt=step,
        integrator=f"mujoco-{integrator}",
    )
