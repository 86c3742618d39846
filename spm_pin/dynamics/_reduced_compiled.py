"""The compiled path of :class:`~spm_pin.dynamics.reduced.ReducedDynamics`: its
kernels (:mod:`spm_pin.dynamics._reduced_kernel`, compiled through
:mod:`spm_pin._jit` on first use) and the constants they take, kept per instance."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from .. import _jit
from ..errors import SingularityError
from ..kinematics.fk import _SIGN_TOL
from . import _reduced_kernel
from ._constants import FloatArray

__all__ = ["CompiledPath", "contiguous", "singular_error"]


def contiguous(array: FloatArray) -> FloatArray:
    """A C-contiguous float array (what the kernels take; no copy when it is one)."""
    result: FloatArray = np.ascontiguousarray(array, dtype=np.float64)
    return result


def singular_error(
    theta: FloatArray, det: FloatArray, singular: npt.NDArray[np.bool_]
) -> SingularityError:
    """The error of rows at a parallel (type II) singularity."""
    rows = np.flatnonzero(singular)
    return SingularityError(
        f"parallel (type II) singularity in rows {rows[:10].tolist()} (det A = "
        f"{float(det[rows[0]]):.3g} at theta = "
        f"{np.degrees(theta[rows[0]]).round(6).tolist()} deg): the input angles "
        "do not determine the motion there",
        kind="type II",
        value=theta[rows],
    )


class CompiledPath:
    """The compiled kernels of one reduced-dynamics object and their constants.

    Args:
        enabled: Use the kernels where numba is installed and not switched off
            (``SPM_PIN_JIT=0``); False: never.
    """

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self._table: dict[str, Any] | None = None
        self._constants: tuple[Any, ...] = ()
        self._key: tuple[Any, ...] = ()

    def kernels(self) -> dict[str, Any] | None:
        """The compiled kernels (compiled on the first call), or None: numpy."""
        table = self._table
        if table is None and self.enabled:
            if _jit.available():
                table = self._table = _jit.kernels(_reduced_kernel.KERNELS)
            else:
                self.enabled = False
        return table

    def constants(
        self, dynamics: Any, singular_det: float, closure_tol: float, iterations: int
    ) -> tuple[Any, ...]:
        """The kernels' constants (:data:`~spm_pin.dynamics._reduced_kernel.Constants`)
        of ``dynamics``, rebuilt when its gravity, friction or armature were replaced
        (and holding those arrays themselves, so that changes made in place count as
        in numpy)."""
        key = (dynamics.gravity, dynamics.friction, dynamics.armature)
        last = self._key
        if last and last[0] is key[0] and last[1] is key[1] and last[2] is key[2]:
            return self._constants
        friction = dynamics.friction

        def array(value: Any) -> FloatArray:
            return np.array(value, dtype=np.float64, order="C")

        def shared(value: FloatArray) -> FloatArray:
            return value if value.dtype == np.float64 and value.flags.c_contiguous else array(value)

        mode = 0.0 if friction is None else 1.0
        constants = (
            array(dynamics._u),
            array(dynamics._w0),
            array(dynamics._v0),
            array(dynamics._frame_inv),
            array(dynamics._dist_inertia),
            array(dynamics._plat_inertia),
            array(dynamics._prox_inertia),
            array(dynamics._prox_moment),
            array(dynamics._dist_moment),
            array(dynamics._plat_moment),
            shared(dynamics.gravity),
            array(np.zeros(9)) if friction is None else shared(friction.viscous),
            array(np.zeros(9)) if friction is None else shared(friction.coulomb),
            float(dynamics._cos_a2),
            1.0 if friction is None else float(friction.smoothing_speed),
            mode,
            float(np.sign(dynamics.design.home_det_a)),
            float(_SIGN_TOL),
            float(singular_det),
            float(closure_tol),
            int(iterations),
            shared(dynamics.armature),
        )
        self._constants, self._key = constants, key
        return constants
