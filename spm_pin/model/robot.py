r"""The SPM as a Pinocchio model: a kinematic tree of nine revolute joints plus two welds.

Model conventions (docs/conventions.md):

* Every joint axis passes through the centre O and every joint placement is the
  identity, so q = 0 is home, where every link frame equals the world frame.
* The tree: ``base`` (on the universe joint) -> ``u_i`` (axis u_i, actuated) ->
  ``proximal_i`` -> ``w_i`` (axis w_i0) -> ``distal_i`` -> ``v_i`` (axis v_i0) -> leg
  1 ends in ``platform``; legs 2 and 3 end in ``platform_leg2`` and ``platform_leg3``,
  copies of the same rigid platform that the loop closures weld to ``platform``.
* The platform's mass properties are split in thirds over the three end bodies
  (this keeps the mass matrix well conditioned; the sum is the real platform).
* Joint order in q (and v): u_1, w_1, v_1, u_2, w_2, v_2, u_3, w_3, v_3, the
  depth-first order in which Pinocchio's MJCF parser reads the exported file.

With every axis through O the world placement of a link is a pure rotation:

    proximal_i:  P_i = Rot(u_i, q_ui)
    distal_i:    D_i = P_i Rot(w_i0, q_wi)
    leg end i:   E_i = D_i Rot(v_i0, q_vi)

and the loops close when E_1 = E_2 = E_3 = R, the platform rotation.
:meth:`SPMRobot.configuration` builds q from the analytic forward kinematics: q_ui =
theta_i; q_wi = psi_i with Rot(w_i0, psi_i) v_i0 = P_i^T v_i (so D_i v_i0 = v_i =
R v_i0); q_vi = chi_i with Rot(v_i0, chi_i) = D_i^T R (a rotation about v_i0, since
it keeps v_i0). The result is checked against Pinocchio's own forward kinematics and
constraint residuals.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..design import SPMDesign
from ..errors import ConvergenceError, InputError, UnreachableError
from ..kinematics import forward_kinematics, forward_kinematics_all, select_assembly
from ..kinematics._common import as_rotation, as_theta, check_design, require_angles
from .geometry import LINK_NAMES, LinkInertia, link_inertias, link_meshes

__all__ = [
    "ACTUATED_JOINTS",
    "CLOSURE_TOL",
    "CONSTRAINT_NAMES",
    "END_BODIES",
    "JOINT_NAMES",
    "PASSIVE_JOINTS",
    "CheckerFactory",
    "SPMRobot",
    "SelfCollision",
    "build_robot",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Joint names in q order (depth-first: leg 1, then leg 2, then leg 3).
JOINT_NAMES = ("u_1", "w_1", "v_1", "u_2", "w_2", "v_2", "u_3", "w_3", "v_3")
#: The actuated joints (the input shafts), theta_1..theta_3.
ACTUATED_JOINTS = ("u_1", "u_2", "u_3")
#: The passive joints, in q order.
PASSIVE_JOINTS = ("w_1", "v_1", "w_2", "v_2", "w_3", "v_3")
#: The bodies that end legs 1, 2 and 3 (the last two are welded to the first).
END_BODIES = ("platform", "platform_leg2", "platform_leg3")
#: Names of the two loop closures (as in the exported MJCF's <equality> welds).
CONSTRAINT_NAMES = ("close_leg2", "close_leg3")
#: Largest accepted closure residual of a configuration built by
#: :meth:`SPMRobot.configuration` [rad and m, max-abs of the weld errors].
CLOSURE_TOL = 1e-10

#: Colours (RGBA) of the drawn links, by link family.
_COLORS = {
    "base": (0.35, 0.35, 0.38, 1.0),
    "proximal": (0.20, 0.45, 0.80, 1.0),
    "distal": (0.90, 0.55, 0.15, 1.0),
    "platform": (0.25, 0.65, 0.35, 1.0),
}


def _color(link: str) -> FloatArray:
    return np.array(_COLORS[link.split("_")[0]])


def _rotations(axes: FloatArray, angles: FloatArray) -> FloatArray:
    """Rodrigues with one axis per leg: axes (3, 3) rows, angles (..., 3) -> (..., 3, 3, 3)."""
    c = np.cos(angles)[..., None, None]
    s = np.sin(angles)[..., None, None]
    zero = np.zeros(3)
    K = np.stack(
        [
            np.stack([zero, -axes[:, 2], axes[:, 1]], axis=-1),
            np.stack([axes[:, 2], zero, -axes[:, 0]], axis=-1),
            np.stack([-axes[:, 1], axes[:, 0], zero], axis=-1),
        ],
        axis=-2,
    )
    outer = axes[:, :, None] * axes[:, None, :]
    result: FloatArray = c * np.eye(3) + s * K + (1.0 - c) * outer
    return result


def _bvh(vertices: npt.ArrayLike, faces: npt.ArrayLike) -> coal.BVHModelOBBRSS:
    """A coal BVH triangle mesh from vertices (n, 3) [m] and triangles (m, 3)."""
    points = np.ascontiguousarray(vertices, dtype=np.float64)
    triangles = np.ascontiguousarray(faces, dtype=np.int64)
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(int(triangles.shape[0]), int(points.shape[0]))
    mesh.addVertices(points)
    mesh.addTriangles(triangles)
    mesh.endModel()
    return mesh


def _pin_inertia(inertia: LinkInertia, fraction: float = 1.0) -> pin.Inertia:
    return pin.Inertia(
        fraction * float(inertia.mass),
        np.asarray(inertia.com, dtype=float),
        fraction * np.asarray(inertia.inertia, dtype=float),
    )


class SelfCollision(Protocol):
    """What the robot asks of its self-collision checker (the collision layer's
    :class:`~spm_pin.collision.CollisionChecker` provides it)."""

    @property
    def fixed_clearance(self) -> float: ...

    def collisions(self, x: npt.ArrayLike, *, margin: float = 0.0) -> list[tuple[str, str]]: ...

    def distances(self, x: npt.ArrayLike) -> dict[tuple[str, str], float]: ...

    def min_clearance(self, x: npt.ArrayLike) -> float: ...


#: Makes the self-collision checker of a robot.
CheckerFactory = Callable[["SPMRobot"], SelfCollision]


class SPMRobot:
    """A spherical parallel manipulator as a Pinocchio model with its loop closures.

    Build one with :func:`build_robot`. The attributes are plain Pinocchio objects
    that every Pinocchio algorithm accepts.

    Attributes:
        design: The SPM.
        model: ``pin.Model`` of the open tree (nq = nv = 9, q order :data:`JOINT_NAMES`).
        data: ``pin.Data`` of ``model`` for the caller's use (this class never
            touches it).
        visual_model: ``pin.GeometryModel``, one coal BVH mesh per link, named after
            the link (the platform mesh hangs on the ``platform`` body).
        collision_model: ``pin.GeometryModel`` with the same shapes (the real link
            shapes collide where they are drawn). No collision pairs are registered.
        constraint_models: ``pin.StdVec_ConstraintModel`` with the two loop closures,
            Pinocchio 4 ``FrameAnchorConstraintModel`` welds named
            :data:`CONSTRAINT_NAMES`: ``platform_leg2`` (joint 1, ``v_2``) and
            ``platform_leg3`` (``v_3``) to ``platform`` (joint 2, ``v_1``), both
            anchored at O with identity placements, as in the exported MJCF. Each
            error is log6 of the placement of ``platform`` relative to the leg end,
            6 rows [linear; angular]; the linear rows are identically zero (all axes
            meet at O), so each weld has rank 3.
        constraint_datas: ``pin.StdVec_ConstraintData`` matching ``constraint_models``
            (accepted by ``pin.getConstraintsJacobian``).
        actuated_joints: ``("u_1", "u_2", "u_3")``.
        passive_joints: The other six joint names, in q order.
        actuated_q_idx: Indices of the actuated joints in q (and in v), (3,).
        passive_q_idx: Indices of the passive joints in q (and in v), (6,).
        link_frames: Link name -> Pinocchio frame id of the link body frame, for every
            name of :data:`~spm_pin.model.geometry.LINK_NAMES`. ``"platform"`` is the
            platform frame (origin O, equal to the world frame at home).
        end_frames: Frame ids of :data:`END_BODIES` (the platform as seen by legs 1, 2, 3).
    """

    def __init__(
        self,
        design: SPMDesign | str | None = None,
        *,
        checker_factory: CheckerFactory | None = None,
    ) -> None:
        """Build the model; prefer :func:`spm_pin.build_robot`.

        Args:
            design: The SPM (default: the prototype).
            checker_factory: Makes the robot's self-collision checker on first use
                (:attr:`collision_checker`); :func:`spm_pin.build_robot` passes
                :class:`spm_pin.collision.CollisionChecker`. The model layer does not
                import the collision layer above it: it receives it.
        """
        design = check_design(design)
        if checker_factory is not None and not callable(checker_factory):
            raise InputError(
                f"checker_factory must be callable (e.g. CollisionChecker), got "
                f"{type(checker_factory).__name__}",
                argument="checker_factory",
                value=checker_factory,
            )
        self._checker_factory = checker_factory
        self.design: SPMDesign = design
        inertias = link_inertias(design)
        missing = [name for name in LINK_NAMES if name not in inertias]
        if missing:  # pragma: no cover - a broken geometry module
            raise InputError(f"link inertias are missing for {missing}", argument="design")

        model = pin.Model()
        model.name = "spm"
        model.appendBodyToJoint(0, _pin_inertia(inertias["base"]), pin.SE3.Identity())
        base_frame = model.addBodyFrame("base", 0, pin.SE3.Identity(), 0)
        link_frames: dict[str, int] = {"base": base_frame}
        end_frames: list[int] = []
        end_joints: list[int] = []
        axes = {"u": design.u, "w": design.w0, "v": design.v0}
        for leg in range(3):
            number = leg + 1
            parent_joint, parent_frame = 0, base_frame
            bodies = (f"proximal_{number}", f"distal_{number}", END_BODIES[leg])
            for letter, body in zip("uwv", bodies, strict=True):
                axis = np.array(axes[letter][leg], dtype=float)
                joint = model.addJoint(
                    parent_joint,
                    pin.JointModelRevoluteUnaligned(axis),
                    pin.SE3.Identity(),
                    f"{letter}_{number}",
                )
                joint_frame = model.addJointFrame(joint, parent_frame)
                if letter == "v":
                    inertia = _pin_inertia(inertias["platform"], 1.0 / 3.0)
                else:
                    inertia = _pin_inertia(inertias[body])
                model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
                parent_frame = model.addBodyFrame(body, joint, pin.SE3.Identity(), joint_frame)
                parent_joint = joint
                if letter != "v":
                    link_frames[body] = parent_frame
            end_frames.append(parent_frame)
            end_joints.append(parent_joint)
        link_frames["platform"] = end_frames[0]
        self.model: pin.Model = model
        self.data: pin.Data = model.createData()
        self.link_frames: dict[str, int] = {name: link_frames[name] for name in LINK_NAMES}
        self.end_frames: tuple[int, int, int] = (end_frames[0], end_frames[1], end_frames[2])
        self._end_joints = tuple(end_joints)

        self.visual_model: pin.GeometryModel = pin.GeometryModel()
        self.collision_model: pin.GeometryModel = pin.GeometryModel()
        meshes = link_meshes(design)
        for name in LINK_NAMES:
            frame = model.frames[self.link_frames[name]]
            shape = _bvh(meshes[name].vertices, meshes[name].faces)
            for geometry_model in (self.visual_model, self.collision_model):
                geometry = pin.GeometryObject(
                    name, frame.parentJoint, self.link_frames[name], pin.SE3.Identity(), shape
                )
                geometry.meshColor = _color(name)
                geometry_model.addGeometryObject(geometry)

        self.constraint_models: pin.StdVec_ConstraintModel = pin.StdVec_ConstraintModel()
        self.constraint_datas: pin.StdVec_ConstraintData = pin.StdVec_ConstraintData()
        for name, joint in zip(CONSTRAINT_NAMES, end_joints[1:], strict=True):
            weld = pin.FrameAnchorConstraintModel(
                model, joint, pin.SE3.Identity(), end_joints[0], pin.SE3.Identity()
            )
            weld.name = name
            constraint = pin.ConstraintModel(weld)
            constraint.name = name
            self.constraint_models.append(constraint)
            self.constraint_datas.append(constraint.createData())

        self.actuated_joints: tuple[str, ...] = ACTUATED_JOINTS
        self.passive_joints: tuple[str, ...] = PASSIVE_JOINTS
        self.actuated_q_idx: IntArray = self._q_indices(ACTUATED_JOINTS)
        self.passive_q_idx: IntArray = self._q_indices(PASSIVE_JOINTS)
        # Private workspace for the checks, so that self.data stays the caller's.
        self._data = model.createData()
        self._datas = pin.StdVec_ConstraintData()
        for constraint in self.constraint_models:
            self._datas.append(constraint.createData())

    def __repr__(self) -> str:
        return (
            f"SPMRobot(design={self.design.name!r}, nq={self.model.nq}, "
            f"total_mass={self.total_mass:.4g} kg)"
        )

    # ------------------------------------------------------------------ structure
    def _q_indices(self, names: tuple[str, ...]) -> IntArray:
        model = self.model
        return np.array([model.idx_qs[model.getJointId(name)] for name in names], dtype=np.int64)

    @property
    def total_mass(self) -> float:
        """Mass of the whole robot, base included [kg]."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    @property
    def link_masses(self) -> dict[str, float]:
        """Mass of each link [kg] (the platform's three thirds summed)."""
        inertias = self.model.inertias
        masses = {"base": float(inertias[0].mass)}
        for name in LINK_NAMES[1:]:
            joint = self.model.frames[self.link_frames[name]].parentJoint
            masses[name] = float(inertias[joint].mass)
        masses["platform"] = float(sum(inertias[j].mass for j in self._end_joints))
        return masses

    def rigid_constraint_models(self) -> pin.StdVec_RigidConstraintModel:
        """The loop closures as legacy ``pin.RigidConstraintModel`` (CONTACT_6D, LOCAL).

        These are the only kind ``pin.constraintDynamics``, ``pin.initConstraintDynamics``
        and ``pin.lcaba`` accept. Make their datas with
        ``pin.StdVec_RigidConstraintData([cm.createData() for cm in cms])``.
        """
        models = pin.StdVec_RigidConstraintModel()
        for constraint in self.constraint_models:
            weld = constraint.extract()
            rigid = pin.RigidConstraintModel(
                pin.ContactType.CONTACT_6D,
                self.model,
                weld.joint1_id,
                weld.joint1_placement,
                weld.joint2_id,
                weld.joint2_placement,
                pin.ReferenceFrame.LOCAL,
            )
            rigid.name = constraint.name
            models.append(rigid)
        return models

    # --------------------------------------------------------------- configuration
    def configuration(
        self,
        theta: npt.ArrayLike,
        mode: str = "home",
        *,
        reference: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """The closed joint configuration q at input angles ``theta``.

        q_ui = theta_i (turns kept); the passive angles (in (-pi, pi]) come from the
        platform rotation R of the analytic forward kinematics (see the module
        docstring), and the result is checked: Pinocchio's placements of the three
        leg ends agree to :data:`CLOSURE_TOL`.

        Args:
            theta: Input angles [rad], shape (3,) or (..., 3).
            mode: ``"home"`` for the home assembly mode
                (:func:`~spm_pin.forward_kinematics`); ``"nearest"`` for the rule
                that viewers and collision reports follow
                (:func:`~spm_pin.select_assembly`: the home mode where it exists,
                else the real mode nearest to it); or an assembly-mode label of
                :func:`~spm_pin.forward_kinematics_all` such as ``"+++/-"`` or
                ``"-+-/-#2"``.
            reference: Optional platform rotation(s) (..., 3, 3) near the wanted
                solution; chooses by continuity where several modes qualify.

        Returns:
            q, shape (9,) or (..., 9), joint order :data:`JOINT_NAMES`.

        Raises:
            InputError: bad shape, NaN or inf in ``theta``; unknown ``mode``.
            UnreachableError: no assembly in the requested mode at (some item of)
                ``theta``.
            ConvergenceError: the configuration does not close to :data:`CLOSURE_TOL`
                (a bug or a configuration too close to a singularity).
        """
        theta_in = as_theta(theta)
        R = self._platform_rotation(theta_in, mode, reference)
        return self._closed_configuration(theta_in, R)

    def _closed_configuration(self, theta: FloatArray, R: FloatArray) -> FloatArray:
        """q at checked inputs theta (..., 3) and platform rotations R (..., 3, 3) of a
        solution, its closure checked (ConvergenceError above CLOSURE_TOL)."""
        theta_in = theta
        q = self._configuration_from_rotation(theta_in, R)
        flat = q.reshape(-1, 9)
        residuals = np.array([self._closure_error(item) for item in flat])
        if residuals.size == 0:  # an empty batch: an empty q (0, 9)
            return q
        worst = int(np.argmax(residuals))
        if not residuals[worst] <= CLOSURE_TOL:
            raise ConvergenceError(
                f"the configuration at theta = {np.degrees(flat[worst, self.actuated_q_idx])}"
                f" deg does not close: closure residual {residuals[worst]:.3g} > "
                f"{CLOSURE_TOL:g}",
                data={"theta": theta_in, "q": q, "residual": residuals.reshape(q.shape[:-1])},
            )
        return q

    def _platform_rotation(
        self, theta: FloatArray, mode: str, reference: npt.ArrayLike | None
    ) -> FloatArray:
        shape = theta.shape[:-1]
        if not isinstance(mode, str):
            raise InputError(
                f"mode must be 'home', 'nearest' or an assembly-mode label like '+++/-', "
                f"got {mode!r}",
                argument="mode",
                value=mode,
            )
        if mode == "home":
            fk = forward_kinematics(theta, self.design, reference=reference)
            reachable, R = fk.reachable, fk.R
        elif mode == "nearest":
            if reference is not None:
                raise InputError(
                    "reference applies to mode 'home' or a mode label, not to 'nearest'",
                    argument="reference",
                    value=reference,
                )
            chosen = select_assembly(theta, self.design)
            reachable, R = chosen.exists, chosen.R
        else:
            if not _is_mode_label(mode):
                raise InputError(
                    f"mode must be 'home', 'nearest' or an assembly-mode label of "
                    f"forward_kinematics_all (three signs of b_ii, '/', the sign of det A, "
                    f"then '#k' for the k-th mode with those signs: e.g. '+++/-', "
                    f"'-+-/-#2'), got {mode!r}",
                    argument="mode",
                    value=mode,
                )
            every = forward_kinematics_all(theta, self.design)
            labels = np.array(every.labels, dtype=object).reshape(*shape, 8)
            match = (labels == mode) & every.valid
            if reference is None:
                score = np.where(match, np.arange(8), np.inf)
            else:
                given = as_rotation(reference, "reference")
                try:
                    ref = np.broadcast_to(given, (*shape, 3, 3))
                except ValueError as exc:
                    raise InputError(
                        f"reference must broadcast to shape {(*shape, 3, 3)}, got {given.shape}",
                        argument="reference",
                        value=reference,
                    ) from exc
                distance = np.linalg.norm(every.R - ref[..., None, :, :], axis=(-2, -1))
                score = np.where(match, distance, np.inf)
            pick = np.argmin(score, axis=-1)
            reachable = np.any(match, axis=-1)
            R = np.take_along_axis(every.R, pick[..., None, None, None], axis=-3)[..., 0, :, :]
        if not np.all(reachable):
            bad = np.argwhere(~np.atleast_1d(reachable))
            first = tuple(int(i) for i in bad[0])
            example = theta[first] if shape else theta
            where = f" at index {first} ({bad.shape[0]} of {reachable.size})" if shape else ""
            raise UnreachableError(
                f"theta = {np.degrees(example).round(6).tolist()} deg{where} has no assembly "
                f"in mode {mode!r}; filter inputs with spm.forward_kinematics(theta, "
                "design).reachable",
                value=theta,
            )
        result: FloatArray = np.asarray(R, dtype=float)
        return result

    def _configuration_from_rotation(self, theta: FloatArray, R: FloatArray) -> FloatArray:
        design = self.design
        u, w0, v0 = design.u, design.w0, design.v0
        P = _rotations(u, theta)  # (..., 3 legs, 3, 3)
        v = np.einsum("...jk,ik->...ij", R, v0)  # v_i = R v_i0, rows
        target = np.einsum("...ikj,...ik->...ij", P, v)  # P_i^T v_i
        # psi_i: Rot(w_i0, psi_i) v_i0 = target, from the components normal to w_i0
        a = v0 - np.sum(w0 * v0, axis=-1, keepdims=True) * w0
        b = target - np.sum(w0 * target, axis=-1, keepdims=True) * w0
        psi = np.arctan2(np.sum(w0 * np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))
        D = P @ _rotations(w0, psi)
        # chi_i: Rot(v_i0, chi_i) = D_i^T R
        M = np.swapaxes(D, -1, -2) @ R[..., None, :, :]
        skew = np.stack(
            [M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0], M[..., 1, 0] - M[..., 0, 1]],
            axis=-1,
        )
        sin_chi = 0.5 * np.sum(v0 * skew, axis=-1)
        cos_chi = 0.5 * (np.trace(M, axis1=-2, axis2=-1) - 1.0)
        chi = np.arctan2(sin_chi, cos_chi)
        q = np.stack([theta, psi, chi], axis=-1).reshape(*theta.shape[:-1], 9)
        fit = np.abs(M - _rotations(v0, chi)).max(axis=(-3, -2, -1))
        if fit.size == 0:  # an empty batch: an empty q (0, 9)
            return q
        worst = np.unravel_index(int(np.argmax(fit)), fit.shape) if fit.ndim else ()
        if not fit[worst] <= CLOSURE_TOL:
            raise ConvergenceError(
                f"the platform rotation does not fit leg geometry at theta = "
                f"{np.degrees(theta[worst]).tolist()} deg: residual {float(fit[worst]):.3g}",
                data={"theta": theta, "R": R, "residual": fit},
            )
        result: FloatArray = np.ascontiguousarray(q)
        return result

    # ---------------------------------------------------------------- evaluation
    def _check_q(self, q: npt.ArrayLike, batch: bool = True) -> FloatArray:
        try:
            array = np.asarray(q, dtype=float)
        except (TypeError, ValueError, OverflowError) as exc:
            raise InputError(
                f"q must be numbers of shape (9,) [rad], got {q!r}", argument="q", value=q
            ) from exc
        if array.ndim == 0 or array.shape[-1] != self.model.nq or (not batch and array.ndim != 1):
            allowed = "(9,) or (..., 9)" if batch else "(9,)"
            raise InputError(
                f"q must have shape {allowed} [rad] (joint order {', '.join(JOINT_NAMES)}), "
                f"got shape {array.shape}",
                argument="q",
                value=q,
            )
        require_angles(array, "q", q)
        return array

    def _closure_error(self, q: FloatArray) -> float:
        model, data = self.model, self._data
        pin.forwardKinematics(model, data, q)
        worst = 0.0
        for constraint, constraint_data in zip(self.constraint_models, self._datas, strict=True):
            constraint.calc(model, data, constraint_data)
            error = constraint_data.extract().constraint_position_error
            worst = max(worst, float(np.max(np.abs(error))))
        return worst

    def closure_residual(self, q: npt.ArrayLike) -> FloatArray | float:
        """Loop-closure residual: max-abs of the two welds' errors [rad, m].

        Each weld error is log6 of the placement of ``platform`` relative to
        ``platform_leg2`` (or ``_leg3``), so zero means the three legs hold the same
        platform.

        Args:
            q: Joint configuration(s), shape (9,) or (..., 9).

        Returns:
            A float for one q, an array (...) for a batch.
        """
        array = self._check_q(q)
        flat = array.reshape(-1, self.model.nq)
        residuals = np.array([self._closure_error(item) for item in flat])
        if array.ndim == 1:
            return float(residuals[0])
        result: FloatArray = residuals.reshape(array.shape[:-1])
        return result

    def constraint_jacobian(self, q: npt.ArrayLike) -> FloatArray:
        """Jacobian of the two welds' errors with respect to v, shape (12, 9).

        Rows: weld ``close_leg2`` [linear; angular], then ``close_leg3``. A joint
        velocity v keeps the loops closed (to first order) when J v = 0.

        Args:
            q: One joint configuration, shape (9,).
        """
        array = self._check_q(q, batch=False)
        model, data = self.model, self._data
        pin.computeJointJacobians(model, data, array)
        for constraint, constraint_data in zip(self.constraint_models, self._datas, strict=True):
            constraint.calc(model, data, constraint_data)
        result: FloatArray = np.array(
            pin.getConstraintsJacobian(model, data, self.constraint_models, self._datas)
        )
        return result

    def placement(self, q: npt.ArrayLike, link: str) -> pin.SE3:
        """World placement of a link frame at configuration q.

        Args:
            q: Joint configuration, shape (9,).
            link: A link name (:data:`~spm_pin.model.geometry.LINK_NAMES`) or one of
                :data:`END_BODIES`.

        Returns:
            ``pin.SE3`` (a copy): rotation and translation of the link frame in the world.
        """
        frame = self._frame_id(link)
        array = self._check_q(q, batch=False)
        pin.forwardKinematics(self.model, self._data, array)
        return pin.SE3(pin.updateFramePlacement(self.model, self._data, frame))

    def placements(self, q: npt.ArrayLike) -> dict[str, pin.SE3]:
        """World placements of every link frame (and of the leg ends) at q, by name."""
        array = self._check_q(q, batch=False)
        pin.framesForwardKinematics(self.model, self._data, array)
        names = (*LINK_NAMES, *END_BODIES[1:])
        return {name: pin.SE3(self._data.oMf[self._frame_id(name)]) for name in names}

    # ------------------------------------------------------------------ collision
    @property
    def collision_checker(self) -> SelfCollision:
        """The self-collision checker of this robot, made on first use and kept.

        A :class:`spm_pin.collision.CollisionChecker` for robots from
        :func:`spm_pin.build_robot`; not thread-safe: threads make their own with
        ``CollisionChecker(robot)``.

        Raises:
            InputError: the robot was built without a checker factory (by
                :func:`spm_pin.model.robot.build_robot` or ``SPMRobot(design)``).
        """
        checker: SelfCollision | None = self.__dict__.get("_collision_checker")
        if checker is None:
            if self._checker_factory is None:
                raise InputError(
                    "this robot has no self-collision checker: build it with "
                    "spm.build_robot(design) (or pass checker_factory=CollisionChecker "
                    "from spm_pin.collision)",
                    argument="checker_factory",
                )
            checker = self._checker_factory(self)
            self.__dict__["_collision_checker"] = checker
        return checker

    def collisions(self, x: npt.ArrayLike, *, margin: float = 0.0) -> list[tuple[str, str]]:
        """The link pairs that collide, or come nearer than ``margin``, at x.

        Every link against every other except the pairs that share a joint, on the
        real link shapes (see :mod:`spm_pin.collision`).

        Args:
            x: Input angles theta (3,) [rad] (home assembly mode) or a joint
                configuration q (9,) [rad].
            margin: Safety margin [m], >= 0; keep it below about 1 mm for the
                prototype, whose nested drive tubes are 1 mm apart everywhere.

        Returns:
            Colliding link pairs, e.g. ``[("proximal_2", "proximal_3")]``; empty if
            none.

        Raises:
            InputError: bad ``x`` or ``margin``.
            UnreachableError: theta without a home-mode assembly.
        """
        return self.collision_checker.collisions(x, margin=margin)

    def distances(self, x: npt.ArrayLike) -> dict[tuple[str, str], float]:
        """Distance of every checked link pair at x [m] (negative where they overlap).

        Args:
            x: Input angles theta (3,) [rad] (home mode) or a joint configuration q (9,).
        """
        return self.collision_checker.distances(x)

    def min_clearance(self, x: npt.ArrayLike) -> float:
        """Smallest distance between two checked links at x [m] (negative on overlap).

        Args:
            x: Input angles theta (3,) [rad] (home mode) or a joint configuration q (9,).
        """
        return self.collision_checker.min_clearance(x)

    def _frame_id(self, link: str) -> int:
        if link in self.link_frames:
            return self.link_frames[link]
        if link in END_BODIES:
            return self.end_frames[END_BODIES.index(link)]
        raise InputError(
            f"link must be one of {[*LINK_NAMES, *END_BODIES[1:]]}, got {link!r}",
            argument="link",
            value=link,
        )


def _is_mode_label(mode: str) -> bool:
    signs, _, ordinal = mode.partition("#")
    return (
        len(signs) == 5
        and signs[3] == "/"
        and all(sign in "+-" for sign in signs[:3])
        and signs[4] in "+-"
        and (mode == signs or (ordinal.isdigit() and ordinal.isascii() and int(ordinal) >= 2))
    )


def build_robot(
    design: SPMDesign | str | None = None, *, checker_factory: CheckerFactory | None = None
) -> SPMRobot:
    """The SPM as a Pinocchio model with geometry and loop closures.

    :func:`spm_pin.build_robot` (the one to use) is
    :func:`spm_pin.collision.build_robot`: this one with the self-collision checker.

    Args:
        design: The SPM (default: the prototype).
        checker_factory: See :class:`SPMRobot`.

    Returns:
        :class:`SPMRobot`.

    Example:
        >>> import spm_pin as spm
        >>> robot = spm.build_robot()
        >>> q = robot.configuration([0.3, 0.5, -0.2])
        >>> robot.closure_residual(q) < 1e-12
        True
    """
    return SPMRobot(design, checker_factory=checker_factory)
