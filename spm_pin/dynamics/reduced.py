r"""Reduced (three-coordinate) dynamics of the SPM, batched over N robots.

Every link of an SPM turns about the centre O (all joint axes pass through it), so
each moving link k has an angular velocity that is linear in the input speeds,

    omega_k = W_k(theta) theta_dot,

and its kinetic energy is 1/2 omega_k^T I_k omega_k with I_k its inertia about O in
the world frame. With the analytic kinematics (rows w_i, v_i, a_i = w_i x v_i,
b_ii = (u_i x w_i) . v_i, A omega_p = B theta_dot):

* proximal link i: W = u_i e_i^T (a constant inertia u_i^T I u_i on the diagonal);
* platform: W = J = A^-1 B;
* distal link i: omega_d = u_i theta_dot_i + w_i psi_dot_i, with the rate of the
  passive joint w_i from v_i_dot = omega_d x v_i = omega_p x v_i,
  psi_dot_i = s_i . (omega_p - u_i theta_dot_i), s_i = (v_i x a_i) / |a_i|^2;
  the rate of the passive joint v_i is chi_dot_i = v_i . (omega_p - omega_d).

Kane's equations (virtual power of the inertia torques about O, link by link) give

    M(theta) theta_ddot + c(theta, theta_dot) + g(theta) = tau + tau_f,
    M = sum_k W_k^T I_k W_k + diag(armature),
    c = sum_k W_k^T (I_k alpha_k + omega_k x I_k omega_k),
    g = -sum_k W_k^T ((m c)_k x gravity),  tau_f = S^T f(S theta_dot),

with alpha_k = W_dot_k theta_dot the angular acceleration of link k at zero input
acceleration, found analytically by differentiating the same relations
(A alpha_p = B_dot theta_dot - A_dot omega_p for the platform, and the w_i-rate
relation once more for the distal links), (m c)_k the link's first moment of mass,
S (9, 3) the joint velocities per unit input speed and f the joint friction.
The state is (theta, theta_dot) alone: no passive joint is integrated, so there is no
loop drift. The platform rotation at each theta is solved by Newton on the three
closures w_i . R v_i0 = cos a2 from a nearby rotation (the previous step), checked
against the home sign rule, and otherwise by :func:`~spm_pin.forward_kinematics`.

With numba installed (extra ``fast``) the same equations run compiled, row by row
(:mod:`spm_pin.dynamics._reduced_kernel`): a time step of one robot costs
microseconds instead of a millisecond of numpy calls. The results agree with the
numpy path to rounding (1e-12); ``compiled=False`` or ``SPM_PIN_JIT=0`` keeps numpy.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .._checks import check_design
from ..design import SPMDesign
from ..errors import InputError, UnreachableError
from ..kinematics import forward_kinematics
from ..kinematics.fk import satisfies_home_rule
from ..model.geometry import link_inertias
from ..model.robot import SPMRobot
from . import _reduced_kernel
from ._checks import LIMITS, array3, nonnegative_vector, positive, vector
from ._constants import DEFAULT_DT, GRAVITY, INTEGRATORS, FloatArray
from ._reduced_compiled import CompiledPath
from ._reduced_compiled import contiguous as _contiguous
from ._reduced_compiled import singular_error as _singular_error
from .servo import JointFriction

__all__ = ["REDUCED_CLOSURE_TOL", "ReducedDynamics", "ReducedStep", "ReducedTerms"]

#: Largest closure residual |w_i . v_i - cos a2| accepted from the warm-started
#: Newton solve of the platform rotation; rows above it are solved again by
#: :func:`~spm_pin.forward_kinematics`.
REDUCED_CLOSURE_TOL = 1e-13
#: Newton iterations of the warm-started platform rotation.
_NEWTON_ITERATIONS = 8
#: |det A| / (|a_1| |a_2| |a_3|) at or below which a state is a parallel singularity.
_SINGULAR_DET = 1e-8


@dataclasses.dataclass(frozen=True)
class ReducedTerms:
    """The terms of M theta_ddot + c + g = tau + tau_f at N states (leading axis N).

    Attributes:
        M: Reduced mass matrix [kg m^2], (N, 3, 3), armature included.
        c: Coriolis and centrifugal torques [N m], (N, 3).
        g: Gravity torques [N m], (N, 3) (the torques that hold the robot at rest).
        friction: Joint friction mapped to the inputs, S^T f [N m], (N, 3).
        R: Platform rotations, (N, 3, 3).
        J: Platform Jacobian omega_p = J theta_dot, (N, 3, 3).
        S: Joint velocities per unit input speed, (N, 9, 3), q order.
    """

    M: FloatArray
    c: FloatArray
    g: FloatArray
    friction: FloatArray
    R: FloatArray
    J: FloatArray
    S: FloatArray


@dataclasses.dataclass(frozen=True)
class ReducedStep:
    """One time step of N robots.

    Attributes:
        theta: Input angles after the step [rad], (N, 3) (or (3,)).
        theta_dot: Input speeds after the step [rad/s], same shape.
        theta_ddot: Input accelerations at the state the step started from
            [rad/s^2], same shape.
        R: Platform rotations at the state the step started from, (N, 3, 3) (or
            (3, 3)): pass them as ``reference`` to the next step (a warm start).
    """

    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray
    R: FloatArray


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product over the last axis, with broadcasting (faster than np.cross)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def _array3(value: Any, name: str, unit: str) -> FloatArray:
    """:func:`~spm_pin.dynamics._checks.array3` with a fast path for arrays that pass
    (a batched step checks its inputs every call; the message is built only on error)."""
    if (
        type(value) is np.ndarray
        and value.dtype == np.float64
        and value.ndim in (1, 2)
        and value.shape[-1] == 3
        and value.size
    ):
        size = float(np.abs(value).max())  # NaN propagates
        if size <= LIMITS[unit]:
            return value
    return array3(value, name, unit)


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    result: FloatArray = np.einsum("...k,...k->...", a, b)
    return result


def _rotate(axes: FloatArray, angles: FloatArray, vectors: FloatArray) -> FloatArray:
    """Rodrigues: turn ``vectors`` (..., 3) about unit ``axes`` by ``angles`` (...)."""
    c = np.cos(angles)[..., None]
    s = np.sin(angles)[..., None]
    along = _dot(axes, vectors)[..., None] * axes
    result: FloatArray = along + c * (vectors - along) + s * _cross(axes, vectors)
    return result


def _inertia_about_o(mass: float, com: FloatArray, inertia: FloatArray) -> FloatArray:
    """Inertia about the frame origin O from the one about the centre of mass."""
    shift = mass * (float(com @ com) * np.eye(3) - np.outer(com, com))
    result: FloatArray = np.asarray(inertia, dtype=float) + shift
    return result


class ReducedDynamics:
    """Closed-loop dynamics on the three input angles, for N robots at once.

    See :mod:`spm_pin.dynamics.reduced` for the equations. The same physics as
    :class:`~spm_pin.dynamics.ClosedLoopDynamics` (the accelerations agree to about
    1e-12), evaluated in numpy over a leading batch axis, without Pinocchio.

    Args:
        robot: An :class:`~spm_pin.SPMRobot` (its model's link inertias), or a design
            (an :class:`~spm_pin.SPMDesign`, a preset name or None for the prototype:
            the inertias of :func:`~spm_pin.model.link_inertias`).
        gravity: Gravity in the world frame [m/s^2] (default upright).
        friction: Joint friction (default none).
        armature: Reflected rotor inertia of each actuator [kg m^2], scalar or (3,).
        compiled: Run the numba kernels of :mod:`spm_pin.dynamics._reduced_kernel`
            where numba is installed (extra ``fast``) and not switched off
            (``SPM_PIN_JIT=0``); compiled on first use (cached on disk). False: the
            numpy code only. Both agree to rounding.

    Raises:
        InputError: bad arguments.

    Example:
        >>> import numpy as np
        >>> from spm_pin.dynamics import ReducedDynamics
        >>> reduced = ReducedDynamics()
        >>> reduced.forward(np.zeros((64, 3)), np.zeros((64, 3))).shape
        (64, 3)
    """

    def __init__(
        self,
        robot: SPMRobot | SPMDesign | str | None = None,
        *,
        gravity: npt.ArrayLike = GRAVITY,
        friction: JointFriction | None = None,
        armature: npt.ArrayLike = 0.0,
        compiled: bool = True,
    ) -> None:
        if friction is not None and not isinstance(friction, JointFriction):
            raise InputError(
                f"friction must be a JointFriction or None, got {type(friction).__name__}",
                argument="friction",
                value=friction,
            )
        if isinstance(robot, SPMRobot):
            design = robot.design
            bodies = self._robot_bodies(robot)
        elif robot is None or isinstance(robot, (SPMDesign, str)):
            design = check_design(robot)
            table = link_inertias(design)
            bodies = {
                name: (float(item.mass), np.asarray(item.com, float), np.asarray(item.inertia))
                for name, item in table.items()
            }
        else:
            raise InputError(
                f"robot must be an SPMRobot, an SPMDesign, a preset name or None, got "
                f"{type(robot).__name__}",
                argument="robot",
                value=robot,
            )
        self.design: SPMDesign = design
        self.gravity: FloatArray = vector(gravity, 3, "gravity", "[m/s^2]")
        self.friction: JointFriction | None = friction
        self.armature: FloatArray = nonnegative_vector(armature, 3, "armature", "[kg m^2]")
        u, w0, v0 = design.u, design.w0, design.v0
        self._u, self._w0, self._v0 = u, w0, v0
        self._cos_a2 = math.cos(design.alpha2)

        def about_o(name: str) -> FloatArray:
            mass, com, inertia = bodies[name]
            return _inertia_about_o(mass, com, inertia)

        def moment(name: str) -> FloatArray:
            mass, com, _ = bodies[name]
            result: FloatArray = mass * com
            return result

        legs = range(1, 4)
        prox = [about_o(f"proximal_{i}") for i in legs]
        #: u_i^T I_O u_i of each proximal link (its angular velocity is u_i theta_dot_i).
        self._prox_inertia: FloatArray = np.array([u[i] @ prox[i] @ u[i] for i in range(3)])
        self._prox_moment: FloatArray = np.array([moment(f"proximal_{i}") for i in legs])
        self._dist_inertia: FloatArray = np.array([about_o(f"distal_{i}") for i in legs])
        self._dist_moment: FloatArray = np.array([moment(f"distal_{i}") for i in legs])
        self._plat_inertia: FloatArray = about_o("platform")
        self._plat_moment: FloatArray = moment("platform")
        # Distal link i at home: columns (w_i0, v_i0, w_i0 x v_i0); its rotation is
        # D_i = [w_i v_i a_i] F_i^-1.
        frames = np.stack([w0, v0, np.cross(w0, v0)], axis=-1)
        self._frame_inv: FloatArray = np.linalg.inv(frames)
        self._eye: FloatArray = np.eye(3)
        self._compiled = CompiledPath(bool(compiled))

    @staticmethod
    def _robot_bodies(robot: SPMRobot) -> dict[str, tuple[float, FloatArray, FloatArray]]:
        """(mass, com, inertia about the com) of each moving link of the robot's model."""
        model = robot.model
        bodies: dict[str, tuple[float, FloatArray, FloatArray]] = {}
        for name, frame in robot.link_frames.items():
            if name in ("base", "platform"):
                continue
            inertia = model.inertias[model.frames[frame].parentJoint]
            bodies[name] = (float(inertia.mass), np.array(inertia.lever), np.array(inertia.inertia))
        total = None
        for frame in robot.end_frames:  # the platform: three thirds on the leg ends
            part = model.inertias[model.frames[frame].parentJoint]
            total = part if total is None else total + part
        assert total is not None
        bodies["platform"] = (float(total.mass), np.array(total.lever), np.array(total.inertia))
        return bodies

    @classmethod
    def from_dynamics(cls, dynamics: Any) -> ReducedDynamics:
        """The reduced dynamics of a :class:`~spm_pin.dynamics.ClosedLoopDynamics`:
        its robot, gravity, friction and armature."""
        from .closed_loop import ClosedLoopDynamics

        if not isinstance(dynamics, ClosedLoopDynamics):
            raise InputError(
                f"dynamics must be a ClosedLoopDynamics, got {type(dynamics).__name__}",
                argument="dynamics",
                value=dynamics,
            )
        return cls(
            dynamics.robot,
            gravity=dynamics.gravity,
            friction=dynamics.friction,
            armature=dynamics.armature,
        )

    def __repr__(self) -> str:
        return (
            f"ReducedDynamics(design={self.design.name!r}, gravity={self.gravity.tolist()}, "
            f"armature={self.armature.tolist()}, friction="
            f"{'yes' if self.friction is not None else 'none'})"
        )

    # ------------------------------------------------------------ kernels
    def _kernels(self) -> dict[str, Any] | None:
        """The compiled kernels (compiled on the first call), or None: numpy."""
        return self._compiled.kernels()

    def _constants(self) -> tuple[Any, ...]:
        """The kernels' constants (rebuilt when gravity, friction or armature change)."""
        return self._compiled.constants(
            self, _SINGULAR_DET, REDUCED_CLOSURE_TOL, _NEWTON_ITERATIONS
        )

    # ------------------------------------------------------------ kinematics
    def _proximal_axes(self, theta: FloatArray) -> FloatArray:
        """w_i(theta_i) as rows, (N, 3, 3)."""
        return _rotate(self._u, theta, self._w0)

    def rotation(self, theta: npt.ArrayLike, reference: npt.ArrayLike | None = None) -> FloatArray:
        """Platform rotations (N, 3, 3) of the home assembly mode at theta (N, 3) [rad].

        Args:
            theta: Input angles [rad], (3,) or (N, 3).
            reference: Rotations (N, 3, 3) at nearby inputs (e.g. the previous time
                step): Newton starts there; rows that do not converge or leave the
                home mode are solved by :func:`~spm_pin.forward_kinematics`.

        Raises:
            InputError: bad shapes, NaN or inf.
            UnreachableError: rows without a home-mode assembly (named).
        """
        angles = _array3(theta, "theta", "[rad]")
        flat = angles.reshape(-1, 3)
        ref = None if reference is None else self._reference(reference, flat.shape[0])
        R = self._rotation(flat, ref)
        result: FloatArray = R.reshape(*angles.shape[:-1], 3, 3)
        return result

    def _reference(self, reference: npt.ArrayLike, n: int) -> FloatArray:
        if (
            type(reference) is np.ndarray
            and reference.dtype == np.float64
            and reference.shape == (n, 3, 3)
            and float(np.abs(reference).max()) < math.inf  # NaN compares False
        ):
            return reference  # the usual warm start: last step's R
        try:
            ref = np.asarray(reference, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(
                "reference must be rotation matrices (N, 3, 3)", argument="reference"
            ) from exc
        if ref.shape not in ((n, 3, 3), (3, 3)) or not np.all(np.isfinite(ref)):
            raise InputError(
                f"reference must be finite rotations of shape ({n}, 3, 3), got shape {ref.shape}",
                argument="reference",
                value=reference,
            )
        return np.broadcast_to(ref, (n, 3, 3))

    def _rotation(self, theta: FloatArray, reference: FloatArray | None) -> FloatArray:
        """R (N, 3, 3) at checked theta (N, 3): warm Newton, else forward kinematics."""
        n = theta.shape[0]
        todo = np.ones(n, dtype=bool)
        R = np.empty((n, 3, 3))
        kernels = None if reference is None else self._kernels()
        if reference is not None and kernels is not None:
            settled = kernels["rotations"](
                _contiguous(theta), _contiguous(reference), self._constants(), R
            )
            todo = ~settled
        elif reference is not None:
            w = self._proximal_axes(theta)
            R = np.array(reference, dtype=float)
            residual = np.full(n, np.inf)
            for _ in range(_NEWTON_ITERATIONS):
                v = np.matmul(R, self._v0.T).swapaxes(-1, -2)
                r = _dot(w, v) - self._cos_a2
                residual = np.abs(r).max(axis=-1)
                active = ~(residual <= 0.1 * REDUCED_CLOSURE_TOL)  # rows converge alone
                if not np.any(active):
                    break
                a = _cross(w, v)
                cof = np.stack(
                    (_cross(a[:, 1], a[:, 2]), _cross(a[:, 2], a[:, 0]), _cross(a[:, 0], a[:, 1])),
                    axis=1,
                )
                det = _dot(a[:, 0], cof[:, 0])
                det = np.where(np.abs(det) > 1e-300, det, 1e-300)
                delta = np.einsum("ni,nij->nj", r, cof) / det[:, None]
                angle = np.sqrt(_dot(delta, delta))
                safe = np.where(angle > 0.0, angle, 1.0)
                axis = delta / safe[:, None]
                turned = _rotate(axis[:, None, :], angle[:, None], R.swapaxes(-1, -2))
                R = np.where(active[:, None, None], turned.swapaxes(-1, -2), R)
            v = np.matmul(R, self._v0.T).swapaxes(-1, -2)
            b = _dot(_cross(self._u, w), v)
            det_a = np.linalg.det(_cross(w, v))
            home = satisfies_home_rule(b, det_a, self.design)
            todo = ~(np.isfinite(residual) & (residual <= REDUCED_CLOSURE_TOL) & home)
        if np.any(todo):
            fk = forward_kinematics(theta[todo], self.design)
            if not np.all(fk.reachable):
                rows = np.flatnonzero(todo)[~fk.reachable]
                shown = ", ".join(str(int(i)) for i in rows[:10])
                more = f" and {rows.size - 10} more" if rows.size > 10 else ""
                first = np.degrees(theta[rows[0]]).round(6).tolist()
                raise UnreachableError(
                    f"theta has no home-mode assembly in rows [{shown}]{more} ({rows.size} of "
                    f"{n}; row {int(rows[0])}: {first} deg); filter inputs with "
                    "spm.forward_kinematics(theta, design).reachable",
                    value=theta[rows],
                )
            R[todo] = fk.R
        return R

    # --------------------------------------------------------------- terms
    def _terms(
        self, theta: FloatArray, theta_dot: FloatArray, R: FloatArray, *, bias: bool = True
    ) -> ReducedTerms:
        """Every term at checked states (N, 3) and closed rotations R (N, 3, 3)."""
        n = theta.shape[0]
        kernels = self._kernels()
        if kernels is not None:
            M, c, g, friction = (
                np.empty((n, 3, 3)),
                np.empty((n, 3)),
                np.empty((n, 3)),
                np.empty((n, 3)),
            )
            J, S, det = np.empty((n, 3, 3)), np.empty((n, 9, 3)), np.empty(n)
            singular = kernels["terms"](
                _contiguous(theta),
                _contiguous(theta_dot),
                _contiguous(R),
                self._constants(),
                bias,
                M,
                c,
                g,
                friction,
                J,
                S,
                det,
            )
            if singular.any():
                raise _singular_error(theta, det, singular)
            return ReducedTerms(M=M, c=c, g=g, friction=friction, R=R, J=J, S=S)
        u, eye = self._u, self._eye
        w = self._proximal_axes(theta)  # rows w_i, (N, 3, 3)
        v = np.matmul(R, self._v0.T).swapaxes(-1, -2)  # rows v_i = R v_i0
        a = _cross(w, v)
        uxw = _cross(u, w)
        b = _dot(uxw, v)
        cof = np.stack(
            (_cross(a[:, 1], a[:, 2]), _cross(a[:, 2], a[:, 0]), _cross(a[:, 0], a[:, 1])), axis=1
        )
        det = _dot(a[:, 0], cof[:, 0])
        scale = np.prod(np.sqrt(_dot(a, a)), axis=-1)
        singular = ~(np.abs(det) > _SINGULAR_DET * scale)
        if np.any(singular):
            raise _singular_error(theta, det, singular)
        # J = A^-1 B: the columns of A^-1 are the cofactor rows over det A.
        J = cof.swapaxes(-1, -2) * (b / det[:, None])[:, None, :]
        s = _cross(v, a) / _dot(a, a)[..., None]  # psi_dot_i = s_i . (omega_p - u_i theta_i')
        Psi = np.matmul(s, J) - _dot(s, u)[..., None] * eye  # (N, legs, 3)
        # omega_d,i = W_d,i theta_dot, W_d,i = u_i e_i^T + w_i Psi_i  (N, legs, 3, 3)
        W_d = u[None, :, :, None] * eye[None, :, None, :] + w[..., None] * Psi[..., None, :]
        Chi = np.matmul(v, J) - _dot(v, u)[..., None] * eye - _dot(v, w)[..., None] * Psi
        legs = np.empty((n, 3, 3, 3))  # (N, leg, joint u/w/v, input)
        legs[:, :, 0] = eye
        legs[:, :, 1] = Psi
        legs[:, :, 2] = Chi
        S = legs.reshape(n, 9, 3)
        # Distal rotations D_i = [w_i v_i a_i] F_i^-1 and the platform's R: work in
        # body frames, where the inertias about O are constant.
        D = np.matmul(np.stack((w, v, a), axis=-1), self._frame_inv)  # (N, legs, 3, 3)
        Dt = D.swapaxes(-1, -2)
        Rt = R.swapaxes(-1, -2)
        Wd_body = np.matmul(Dt, W_d)
        Jp_body = np.matmul(Rt, J)
        I_d, I_p = self._dist_inertia, self._plat_inertia
        M = np.matmul(Wd_body.swapaxes(-1, -2), np.matmul(I_d, Wd_body)).sum(axis=1)
        M += np.matmul(Jp_body.swapaxes(-1, -2), np.matmul(I_p, Jp_body))
        M[:, [0, 1, 2], [0, 1, 2]] += self._prox_inertia + self.armature
        # Gravity: the torque about O of each link's weight, mapped to the inputs.
        grav = self.gravity
        prox_h = _rotate(u, theta, self._prox_moment)  # world first moments, (N, legs, 3)
        dist_h = np.matmul(D, self._dist_moment[..., None])[..., 0]
        plat_h = np.matmul(R, self._plat_moment)
        g = -_dot(u, _cross(prox_h, grav))
        g -= np.matmul(W_d.swapaxes(-1, -2), _cross(dist_h, grav)[..., None])[..., 0].sum(axis=1)
        g -= np.matmul(J.swapaxes(-1, -2), _cross(plat_h, grav)[..., None])[..., 0]
        c = np.zeros((n, 3))
        if bias:
            c = self._bias(theta_dot, u, w, v, a, uxw, cof, det, J, s, Psi, Chi, Dt, Rt)
        friction = np.zeros((n, 3))
        if self.friction is not None:
            joint_rates = np.matmul(S, theta_dot[..., None])[..., 0]
            f = self.friction.torque(joint_rates)
            friction = np.matmul(S.swapaxes(-1, -2), f[..., None])[..., 0]
        return ReducedTerms(M=M, c=c, g=g, friction=friction, R=R, J=J, S=S)

    def _bias(
        self,
        theta_dot: FloatArray,
        u: FloatArray,
        w: FloatArray,
        v: FloatArray,
        a: FloatArray,
        uxw: FloatArray,
        cof: FloatArray,
        det: FloatArray,
        J: FloatArray,
        s: FloatArray,
        Psi: FloatArray,
        Chi: FloatArray,
        Dt: FloatArray,
        Rt: FloatArray,
    ) -> FloatArray:
        """c = sum_k W_k^T (I_k alpha_k + omega_k x I_k omega_k) (Kane), (N, 3)."""
        rate = theta_dot
        omega_p = np.matmul(J, rate[..., None])[..., 0]  # (N, 3)
        psi_dot = np.matmul(Psi, rate[..., None])[..., 0]  # (N, legs)
        chi_dot = np.matmul(Chi, rate[..., None])[..., 0]
        w_dot = rate[..., None] * uxw  # proximal links turn w_i about u_i
        v_dot = _cross(omega_p[:, None, :], v)
        a_dot = _cross(w_dot, v) + _cross(w, v_dot)
        b_dot = _dot(_cross(u, w_dot), v) + _dot(uxw, v_dot)
        # A alpha_p = B_dot theta_dot - A_dot omega_p  (theta_ddot = 0)
        rhs = b_dot * rate - _dot(a_dot, omega_p[:, None, :])
        alpha_p = np.einsum("ni,nij->nj", rhs, cof) / det[:, None]
        # distal: alpha_d = psi_ddot w + psi_dot w_dot, with psi_ddot from the v_i rate
        psi_ddot = _dot(
            alpha_p[:, None, :] - psi_dot[..., None] * w_dot - chi_dot[..., None] * v_dot, s
        )
        alpha_d = psi_ddot[..., None] * w + psi_dot[..., None] * w_dot
        omega_d = u * rate[..., None] + w * psi_dot[..., None]
        W_d = u[None, :, :, None] * self._eye[None, :, None, :] + w[..., None] * Psi[..., None, :]
        # body frames
        I_d, I_p = self._dist_inertia, self._plat_inertia
        od = np.matmul(Dt, omega_d[..., None])[..., 0]
        ad = np.matmul(Dt, alpha_d[..., None])[..., 0]
        torque_d = np.matmul(I_d, ad[..., None])[..., 0]
        torque_d += _cross(od, np.matmul(I_d, od[..., None])[..., 0])
        world_d = np.matmul(Dt.swapaxes(-1, -2), torque_d[..., None])  # back to world
        c: FloatArray = np.matmul(W_d.swapaxes(-1, -2), world_d)[..., 0].sum(axis=1)
        op = np.matmul(Rt, omega_p[..., None])[..., 0]
        ap = np.matmul(Rt, alpha_p[..., None])[..., 0]
        torque_p = np.matmul(I_p, ap[..., None])[..., 0]
        torque_p += _cross(op, np.matmul(I_p, op[..., None])[..., 0])
        world_p = np.matmul(Rt.swapaxes(-1, -2), torque_p[..., None])
        c += np.matmul(J.swapaxes(-1, -2), world_p)[..., 0]
        return c

    # -------------------------------------------------------------- checks
    def _states(
        self, theta: npt.ArrayLike, theta_dot: npt.ArrayLike | None
    ) -> tuple[FloatArray, FloatArray, bool]:
        angles = _array3(theta, "theta", "[rad]")
        single = angles.ndim == 1
        if theta_dot is None:
            rate = np.zeros_like(angles)
        else:
            rate = _array3(theta_dot, "theta_dot", "[rad/s]")
            if rate.shape != angles.shape:
                raise InputError(
                    f"theta_dot must have the shape of theta {angles.shape}, got {rate.shape}",
                    argument="theta_dot",
                    value=theta_dot,
                )
        return angles.reshape(-1, 3), rate.reshape(-1, 3), single

    def _torque(self, torque: npt.ArrayLike | None, n: int) -> FloatArray:
        if torque is None:
            return np.zeros((n, 3))
        tau = _array3(torque, "torque", "[N m]")
        if tau.ndim == 2 and tau.shape[0] != n:
            raise InputError(
                f"torque must have shape (3,) or ({n}, 3) [N m], got {tau.shape}",
                argument="torque",
                value=torque,
            )
        if tau.shape == (n, 3):
            return tau
        result: FloatArray = np.broadcast_to(tau, (n, 3))
        return result

    def _shape(self, array: FloatArray, single: bool) -> FloatArray:
        result: FloatArray = array[0] if single else array
        return result

    # -------------------------------------------------------------- public
    def terms(
        self,
        theta: npt.ArrayLike,
        theta_dot: npt.ArrayLike | None = None,
        *,
        reference: npt.ArrayLike | None = None,
    ) -> ReducedTerms:
        """M, c, g, the friction torques, R, J and S at N states (always a batch axis).

        Args:
            theta: Input angles [rad], (3,) or (N, 3), home assembly mode.
            theta_dot: Input speeds [rad/s], the same shape (default 0).
            reference: Platform rotations near the solution (see :meth:`rotation`).

        Raises:
            InputError: bad shapes, NaN or inf.
            UnreachableError: rows without a home-mode assembly (named).
            SingularityError: rows at a parallel (type II) singularity.
        """
        angles, rate, _ = self._states(theta, theta_dot)
        ref = None if reference is None else self._reference(reference, angles.shape[0])
        return self._terms(angles, rate, self._rotation(angles, ref))

    def mass_matrix(self, theta: npt.ArrayLike) -> FloatArray:
        """Reduced mass matrix M(theta) [kg m^2], (3, 3) or (N, 3, 3)."""
        angles, rate, single = self._states(theta, None)
        terms = self._terms(angles, rate, self._rotation(angles, None), bias=False)
        return self._shape(terms.M, single)

    def holding_torques(self, theta: npt.ArrayLike) -> FloatArray:
        """Gravity torques g(theta) [N m], (3,) or (N, 3): what holds the robot at rest."""
        angles, rate, single = self._states(theta, None)
        terms = self._terms(angles, rate, self._rotation(angles, None), bias=False)
        return self._shape(terms.g, single)

    def energy(
        self, theta: npt.ArrayLike, theta_dot: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """(kinetic 1/2 theta_dot^T M theta_dot, potential -sum m g . c) [J] of the moving
        links (the base's constant potential left out), (N,) each or scalars."""
        angles, rate, single = self._states(theta, theta_dot)
        R = self._rotation(angles, None)
        terms = self._terms(angles, rate, R, bias=False)
        kinetic = 0.5 * np.einsum("ni,nij,nj->n", rate, terms.M, rate)
        u = self._u
        w = self._proximal_axes(angles)
        v = np.matmul(R, self._v0.T).swapaxes(-1, -2)
        D = np.matmul(np.stack((w, v, _cross(w, v)), axis=-1), self._frame_inv)
        first = _rotate(u, angles, self._prox_moment).sum(axis=1)
        first += np.matmul(D, self._dist_moment[..., None])[..., 0].sum(axis=1)
        first += np.matmul(R, self._plat_moment)
        potential = -first @ self.gravity
        return self._shape(kinetic, single), self._shape(potential, single)

    def forward(
        self,
        theta: npt.ArrayLike,
        theta_dot: npt.ArrayLike,
        torque: npt.ArrayLike | None = None,
        *,
        reference: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Input accelerations theta_ddot = M^-1 (tau + tau_f - c - g) [rad/s^2].

        Args:
            theta: Input angles [rad], (3,) or (N, 3), home assembly mode.
            theta_dot: Input speeds [rad/s], the same shape.
            torque: Actuator torques [N m], (3,) (every robot) or (N, 3) (default 0).
            reference: Platform rotations near the solution (see :meth:`rotation`).

        Returns:
            (3,) or (N, 3), like theta.

        Raises:
            InputError: bad shapes, NaN or inf.
            UnreachableError: rows without a home-mode assembly (named).
            SingularityError: rows at a parallel (type II) singularity.
        """
        angles, rate, single = self._states(theta, theta_dot)
        tau = self._torque(torque, angles.shape[0])
        ref = None if reference is None else self._reference(reference, angles.shape[0])
        R = self._rotation(angles, ref)
        return self._shape(self._accelerate(angles, rate, tau, R), single)

    def _accelerate(
        self, theta: FloatArray, theta_dot: FloatArray, tau: FloatArray, R: FloatArray
    ) -> FloatArray:
        kernels = self._kernels()
        if kernels is not None:
            n = theta.shape[0]
            out, det = np.empty((n, 3)), np.empty(n)
            singular = kernels["accelerations"](
                _contiguous(theta),
                _contiguous(theta_dot),
                _contiguous(tau),
                _contiguous(R),
                self._constants(),
                out,
                det,
            )
            if singular.any():
                raise _singular_error(theta, det, singular)
            return out
        t = self._terms(theta, theta_dot, R)
        rhs: FloatArray = tau + t.friction - t.c - t.g
        result: FloatArray = np.asarray(
            np.linalg.solve(t.M, rhs[..., None])[..., 0], dtype=np.float64
        )
        return result

    def step(
        self,
        theta: npt.ArrayLike,
        theta_dot: npt.ArrayLike,
        torque: npt.ArrayLike | None = None,
        dt: float = DEFAULT_DT,
        *,
        integrator: str = "euler",
        reference: npt.ArrayLike | None = None,
    ) -> ReducedStep:
        """One time step of N robots with torques held over it.

        ``"euler"`` (semi-implicit, as :class:`~spm_pin.dynamics.Simulator`):
        theta_dot' = theta_dot + dt theta_ddot, theta' = theta + dt theta_dot'.
        ``"rk4"``: classic fourth order on (theta, theta_dot).

        Args:
            theta: Input angles [rad], (3,) or (N, 3).
            theta_dot: Input speeds [rad/s], the same shape.
            torque: Actuator torques [N m], (3,) or (N, 3) (default 0).
            dt: Time step [s].
            integrator: ``"euler"`` or ``"rk4"``.
            reference: Platform rotations at (or near) theta: the ``R`` of the
                previous step's result (a warm start; default: solved afresh).

        Returns:
            :class:`ReducedStep`.

        Raises:
            InputError: bad arguments.
            UnreachableError: a robot without a home-mode assembly (rows named).
            SingularityError: a robot at a parallel (type II) singularity.
        """
        angles, rate, single = self._states(theta, theta_dot)
        n = angles.shape[0]
        tau = self._torque(torque, n)
        h = positive(dt, "dt", "[s]")
        if integrator not in INTEGRATORS:
            raise InputError(
                f"integrator must be one of {list(INTEGRATORS)}, got {integrator!r}",
                argument="integrator",
                value=integrator,
            )
        ref = None if reference is None else self._reference(reference, n)
        kernels = None if ref is None else self._kernels()
        if ref is not None and kernels is not None:
            # The whole step in one compiled call; a batch with a row it does not
            # settle (forward kinematics, an error to raise) takes the path below.
            out = (np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, 3)))
            status = kernels["step"](
                _contiguous(angles),
                _contiguous(rate),
                _contiguous(tau),
                _contiguous(ref),
                h,
                integrator == "rk4",
                self._constants(),
                *out,
            )
            if status == _reduced_kernel.STATUS_OK:
                return ReducedStep(
                    theta=self._shape(out[0], single),
                    theta_dot=self._shape(out[1], single),
                    theta_ddot=self._shape(out[2], single),
                    R=self._shape(out[3], single),
                )
        R = self._rotation(angles, ref)
        a1 = self._accelerate(angles, rate, tau, R)
        if integrator == "euler":
            rate_next = rate + h * a1
            angles_next = angles + h * rate_next
        else:
            half = 0.5 * h
            t2, r2 = angles + half * rate, rate + half * a1
            a2 = self._accelerate(t2, r2, tau, self._rotation(t2, R))
            t3, r3 = angles + half * r2, rate + half * a2
            a3 = self._accelerate(t3, r3, tau, self._rotation(t3, R))
            t4, r4 = angles + h * r3, rate + h * a3
            a4 = self._accelerate(t4, r4, tau, self._rotation(t4, R))
            angles_next = angles + h / 6.0 * (rate + 2.0 * (r2 + r3) + r4)
            rate_next = rate + h / 6.0 * (a1 + 2.0 * (a2 + a3) + a4)
        return ReducedStep(
            theta=self._shape(angles_next, single),
            theta_dot=self._shape(rate_next, single),
            theta_ddot=self._shape(a1, single),
            R=self._shape(R, single),
        )
