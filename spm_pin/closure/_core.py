"""The state of a closed loop: its facts and the preallocated workspace of the Newton steps.

A :class:`LoopCore` holds the model, its ``pin.Data``, the loop closures and their
datas, the index arrays of the actuated and passive joints, the generic ranks, and the
buffers the solver writes into (the damped Newton system, its factorisations, the
residual). The solver's functions (``_solve``, ``_frames``) take it as their first
argument; :class:`~spm_pin.closure.ClosedLoop` is the public face over it.
"""

from __future__ import annotations

from typing import Any

import eigenpy
import numpy as np
import pinocchio as pin

from ..errors import InputError
from ..kinematics._common import float_array, require_angles
from ._constants import FLOAT64, LIMIT_SQUARED, RANK_SEED, RANK_TOL, FloatArray, IntArray, rank
from ._constraints import EUCLIDEAN_JOINTS, indices


class LoopCore:
    """A Pinocchio tree with checked loop closures and actuated joints, ready to solve.

    Args:
        model: The open kinematic tree.
        constraint_models: The closures, checked (``loop_constraints``).
        joint_ids: Ids of the actuated joints, checked (``actuated_ids``).

    Raises:
        InputError: the actuated joints are not independent.
    """

    def __init__(
        self,
        model: pin.Model,
        constraint_models: pin.StdVec_ConstraintModel,
        joint_ids: list[int],
    ) -> None:
        self.model: pin.Model = model
        self.data: pin.Data = model.createData()
        self.constraint_models: pin.StdVec_ConstraintModel = constraint_models
        self.constraint_datas = pin.StdVec_ConstraintData()
        for constraint in constraint_models:
            self.constraint_datas.append(constraint.createData())
        bare = [
            (constraint.extract(), data.extract())
            for constraint, data in zip(constraint_models, self.constraint_datas, strict=True)
        ]
        self.calcs = [(constraint.calc, data) for constraint, data in bare]
        self.errors = [data.constraint_position_error for _, data in bare]
        self.n_constraints: int = int(sum(error.shape[0] for error in self.errors))

        self.actuated_joints: tuple[str, ...] = tuple(model.names[j] for j in joint_ids)
        passive_ids = [j for j in range(1, model.njoints) if j not in joint_ids]
        self.passive_joints: tuple[str, ...] = tuple(model.names[j] for j in passive_ids)
        self.actuated_q_idx: IntArray = indices(model.idx_qs, model.nqs, joint_ids)
        self.actuated_v_idx: IntArray = indices(model.idx_vs, model.nvs, joint_ids)
        self.passive_q_idx: IntArray = indices(model.idx_qs, model.nqs, passive_ids)
        self.passive_v_idx: IntArray = indices(model.idx_vs, model.nvs, passive_ids)
        self.n_actuated = int(self.actuated_q_idx.shape[0])
        self.euclidean = all(
            model.joints[j].shortname() in EUCLIDEAN_JOINTS for j in range(1, model.njoints)
        )
        self._setup_workspace()
        self.nominal_rank: int
        self.mobility: int
        self.idle_dof: int
        self._nominal_ranks()

    def _setup_workspace(self) -> None:
        m, nv = self.n_constraints, self.model.nv
        n_p = self.passive_v_idx.shape[0]
        n_a = self.actuated_v_idx.shape[0]
        # [J_p; sqrt(lambda) I] and [e; 0]: the damped Newton system, preallocated.
        self.aug = np.zeros((m + n_p, n_p))
        self.aug_top = self.aug[:m]
        self.rhs = np.zeros(m + n_p)
        self.ebuf = self.rhs[:m]
        # the diagonal of the damping block, a writable strided view
        self.aug_diag = self.aug[m:].reshape(-1)[:: n_p + 1]
        self.select_p = np.zeros((nv, n_p))
        self.select_p[self.passive_v_idx, np.arange(n_p)] = 1.0
        self.select_a = np.zeros((nv, n_a))
        self.select_a[self.actuated_v_idx, np.arange(n_a)] = 1.0
        self.cod = eigenpy.CompleteOrthogonalDecomposition(np.eye(max(m + n_p, 1), max(n_p, 1)))
        self.cod_p = eigenpy.CompleteOrthogonalDecomposition(np.eye(max(m, 1), max(n_p, 1)))
        self.cod_p.setThreshold(RANK_TOL)
        self.neg_select_a = -self.select_a
        # [-J_a; 0] for the predictor map, solved with the last step's factorisation
        self.rhs_a = np.zeros((m + n_p, n_a))
        self.rhs_a_top = self.rhs_a[:m]
        self.jp = np.zeros((m, n_p))
        self.ja = np.zeros((m, n_a))
        self.e_old = np.zeros(m)
        self.v = np.zeros(nv)
        self.q_shape = (int(self.model.nq),)
        self.a_shape = (n_a,)
        self.g_shape = (n_p, n_a)
        # (rows of e, error view) of every closure, to gather e without a temporary
        self.copies = []
        row = 0
        for error in self.errors:
            size = int(error.shape[0])
            self.copies.append((slice(row, row + size), error))
            row += size

    def _nominal_ranks(self) -> None:
        """Generic ranks of J and J_p from random configurations; independence check."""
        rng = np.random.default_rng(RANK_SEED)
        rank_j = rank_p = 0
        neutral = pin.neutral(self.model)
        for _ in range(3):
            q = pin.integrate(self.model, neutral, rng.normal(size=self.model.nv))
            J = self.jacobian_at(q)
            rank_j = max(rank_j, rank(J))
            rank_p = max(rank_p, rank(J[:, self.passive_v_idx]))
        if rank_p < rank_j:
            raise InputError(
                f"the actuated joints {list(self.actuated_joints)} are not independent: "
                f"the loop closures have rank {rank_j}, but with the actuated joints fixed "
                f"the passive joints {list(self.passive_joints)} can satisfy only "
                f"{rank_p} of those directions; actuate fewer joints (the mechanism has "
                f"{self.model.nv - rank_j} degrees of freedom)",
                argument="actuated",
                value=list(self.actuated_joints),
            )
        self.nominal_rank = rank_j
        self.mobility = self.model.nv - rank_j
        self.idle_dof = int(self.passive_v_idx.shape[0]) - rank_p

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, q: FloatArray) -> float:
        """Kinematics and constraint residual at q into the workspace; returns ||e||^2."""
        model, data, ebuf = self.model, self.data, self.ebuf
        pin.computeJointJacobians(model, data, q)
        for calc, constraint_data in self.calcs:
            calc(model, data, constraint_data)
        for rows, error in self.copies:
            ebuf[rows] = error
        r2: float = ebuf.dot(ebuf)
        return r2

    def jacobian_at(self, q: FloatArray) -> FloatArray:
        """Constraint Jacobian (m, nv) at q (leaves e(q) in ``ebuf``)."""
        self.evaluate(q)
        return self.jacobian()

    def jacobian(self) -> FloatArray:
        """Constraint Jacobian (m, nv) at the configuration last evaluated."""
        if not self.errors:
            return np.zeros((0, self.model.nv))
        J: FloatArray = pin.getConstraintsJacobian(
            self.model, self.data, self.constraint_models, self.constraint_datas
        )
        return J

    def step(self, q: FloatArray, dx: FloatArray) -> FloatArray:
        """q moved by -dx on the passive joints (in place when q is Euclidean)."""
        if self.euclidean:
            q[self.passive_q_idx] -= dx
            return q
        v = self.v
        v[:] = 0.0
        v[self.passive_v_idx] = -dx
        result: FloatArray = pin.integrate(self.model, q, v)
        return result

    def passive_map(self, J: FloatArray) -> tuple[int, FloatArray]:
        """Rank of J_p and G = -J_p^+ J_a (minimum norm, rank-revealing) from J (m, nv).

        Leaves J_p in ``self.jp``.
        """
        n_p, n_a = self.g_shape
        if n_p == 0:
            return 0, np.zeros((0, n_a))
        cod = self.cod_p
        cod.compute(np.dot(J, self.select_p, out=self.jp))
        rank_p = int(cod.rank())
        if n_a == 0:
            return rank_p, np.zeros((n_p, 0))
        G: FloatArray = cod.solve(np.dot(J, self.neg_select_a, out=self.ja))
        if G.ndim != 2:  # a single column comes back as a vector
            G = G.reshape(n_p, n_a)
        return rank_p, G

    def analysis(self, q: FloatArray) -> tuple[int, FloatArray]:
        """Exact rank of J_p and velocity map G at q (leaves J_p in ``self.jp``)."""
        self.evaluate(q)
        return self.passive_map(self.jacobian())

    # ---------------------------------------------------------------------- input
    def neutral(self) -> FloatArray:
        """``pin.neutral(model)``, shape (nq,)."""
        result: FloatArray = np.array(pin.neutral(self.model), dtype=float)
        return result

    def check_actuated(self, actuated: Any, name: str = "actuated") -> FloatArray:
        """Actuated values (or velocities) as a float array (n_actuated,), checked."""
        if (
            type(actuated) is np.ndarray
            and actuated.dtype is FLOAT64
            and actuated.shape == self.a_shape
        ):
            array: FloatArray = actuated
        else:
            n = self.n_actuated
            array = float_array(
                actuated,
                name,
                f"{name} must be {n} numbers (values of {list(self.actuated_joints)}) "
                f"[rad or m], got {actuated!r}",
            )
            if array.shape != (n,):
                raise InputError(
                    f"{name} must have shape ({n},) (values of {list(self.actuated_joints)}) "
                    f"[rad or m], got shape {array.shape}",
                    argument=name,
                    value=actuated,
                )
        # Cheap test first (a NaN spreads; a sum of squares <= limit**2 bounds every
        # entry; Python floats overflow to inf without numpy's warning machinery, which
        # costs more than the test), then the one rule for joint values: finite,
        # |value| <= ANGLE_LIMIT.
        if not sum(v * v for v in array.tolist()) <= LIMIT_SQUARED:
            require_angles(array, name, actuated)
        return array

    def check_q(self, q: Any, name: str = "q") -> FloatArray:
        """A configuration as a float array (nq,), checked."""
        nq = self.model.nq
        array = float_array(q, name, f"{name} must be a configuration of {nq} numbers, got {q!r}")
        if array.shape != (nq,):
            raise InputError(
                f"{name} must have shape ({nq},) (model {self.model.name!r}), "
                f"got shape {array.shape}",
                argument=name,
                value=q,
            )
        require_angles(array, name, q)
        return array
