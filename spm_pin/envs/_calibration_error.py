"""Calibration errors drawn at each episode: what a controller with a miscalibrated
model observes (domain randomisation for transfer to the prototype).

The prototype's controller computes the platform orientation from its encoders'
readings with the model its calibration gave (:mod:`spm_pin.calibration`). What is
left of the calibration's error makes that model differ from the robot: its inputs
by the encoder offsets' error, its link angles ``alpha1``, ``alpha2`` and ``beta`` by
theirs. :class:`BelievedModels` draws such errors for each robot at each reset (each
Gaussian, of the standard deviations of
:class:`~spm_pin.envs.settings.CalibrationSpread`, from the robot's own generator)
and gives the state that the robot's controller would believe: the input angles
plus the offsets' error, and the platform rotation of the believed model
(:meth:`CalibrationParameters.design <spm_pin.calibration.CalibrationParameters.design>`)
at those inputs, in the home assembly mode.

The simulated robot itself is the nominal design: its motion, its safety, the
reward and the ends are the truth's. Only the observation sees the believed state,
so a policy learns to reach the goal through a biased estimate, as on the prototype.

The believed rotation is found by Newton's method on the believed model's closure
equations, started from the true rotation (a few hundredths of a radian away), row
by row (:func:`~spm_pin.envs._believed_kernel.believed_rows`, compiled where numba
is installed): a row's numbers do not depend on the rows beside it, so the vector
environment gives the single environment's bits. A row Newton does not settle takes
the believed model's forward kinematics (or, where that model does not assemble
there, the true rotation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .. import _jit
from ..calibration import CalibrationParameters
from ..design import SPMDesign
from ..dynamics.reduced import _NEWTON_ITERATIONS, REDUCED_CLOSURE_TOL
from ..kinematics import forward_kinematics
from ..kinematics.fk import _SIGN_TOL
from . import _believed_kernel
from .settings import CalibrationSpread

__all__ = ["BelievedModels"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]


class BelievedModels:
    """The models that the robots' controllers believe, one per robot, drawn at each
    reset (see the module).

    Args:
        design: The simulated robots' (nominal) design.
        num: How many robots.
        spread: The errors' standard deviations.

    Attributes:
        parameters: Each robot's believed calibration parameters, for its episode.
        offsets: The encoder offsets' errors [rad] (num, 3): believed input = true
            input + offset.
    """

    def __init__(self, design: SPMDesign, num: int, spread: CalibrationSpread) -> None:
        self.design = design
        self.spread = spread
        nominal = CalibrationParameters.nominal(design)
        self.parameters: list[CalibrationParameters] = [nominal] * num
        self._designs: list[SPMDesign] = [design] * num
        self.offsets = np.zeros((num, 3))
        self.u = np.tile(design.u, (num, 1, 1))
        self.w0 = np.tile(design.w0, (num, 1, 1))
        self.v0 = np.tile(design.v0, (num, 1, 1))
        self.cos_a2 = np.full(num, math.cos(design.alpha2))
        self.home_sign = np.full(num, float(np.sign(design.home_det_a)))
        self._kernel: Any = None

    def draw(self, rows: IntArray, rngs: list[np.random.Generator]) -> None:
        """New errors for ``rows``: six standard normal numbers from each row's
        generator (offsets, alpha1, alpha2, beta), times the spread."""
        s, d = self.spread, self.design
        for i in rows:
            k = int(i)
            z = rngs[k].standard_normal(6)
            parameters = CalibrationParameters(
                offsets=z[:3] * s.offsets,
                alpha1=d.alpha1 + z[3] * s.alpha1,
                alpha2=d.alpha2 + z[4] * s.alpha2,
                beta=d.beta + z[5] * s.beta,
                mount=np.eye(3),
                reference=np.eye(3),
            )
            believed = parameters.design(d)
            self.parameters[k] = parameters
            self._designs[k] = believed
            self.offsets[k] = parameters.offsets
            self.u[k], self.w0[k], self.v0[k] = believed.u, believed.w0, believed.v0
            self.cos_a2[k] = math.cos(believed.alpha2)
            self.home_sign[k] = float(np.sign(believed.home_det_a))

    def observed(
        self, rows: IntArray, theta: FloatArray, R: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """(input angles, platform rotations) that the controllers of ``rows`` believe
        at their true inputs ``theta`` (n, 3) and rotations ``R`` (n, 3, 3)."""
        believed_theta = theta + self.offsets[rows]
        n = rows.size
        out = np.empty((n, 3, 3))
        settled = np.zeros(n, dtype=bool)
        args = (
            believed_theta,
            np.ascontiguousarray(R, dtype=float),
            self.u[rows],
            self.w0[rows],
            self.v0[rows],
            self.cos_a2[rows],
            self.home_sign[rows],
            float(_SIGN_TOL),
            float(REDUCED_CLOSURE_TOL),
            int(_NEWTON_ITERATIONS),
            out,
            settled,
        )
        if self._kernel is None:  # the same types every call: no dispatch
            kernel = _jit.kernels(_believed_kernel.KERNELS)["believed_rows"]
            self._kernel = _jit.entry(kernel, args)
        self._kernel(*args)
        for m in np.flatnonzero(~settled):
            fk = forward_kinematics(believed_theta[m], self._designs[int(rows[m])])
            out[m] = fk.R if bool(fk.reachable) else R[m]
        return believed_theta, out
