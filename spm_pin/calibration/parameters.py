"""The model parameters of a calibration (:class:`CalibrationParameters`: encoder
offsets, link angles, sensor mounting and reference frame) and parameter names."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError
from ..kinematics._common import as_rotation, check_design
from ..rotations import exp_so3, log_so3
from ._constants import DEFAULT_PARAMETERS, PARAMETER_GROUPS, PARAMETER_NAMES, FloatArray, as_triple


@dataclasses.dataclass(frozen=True, eq=False)
class CalibrationParameters:
    """A full set of model parameters (angles in radians).

    Attributes:
        offsets: Encoder zero offsets (3,): model input = reading - offset.
        alpha1: Proximal link angle.
        alpha2: Distal link angle.
        beta: Inclination of the platform joint axes.
        mount: Sensor frame in the platform frame, (3, 3).
        reference: World (base) frame in the sensor's reference frame, (3, 3).
    """

    offsets: FloatArray
    alpha1: float
    alpha2: float
    beta: float
    mount: FloatArray
    reference: FloatArray

    def __post_init__(self) -> None:
        offsets = np.array(as_triple(self.offsets, "offsets"))
        offsets.setflags(write=False)
        object.__setattr__(self, "offsets", offsets)
        for name in ("alpha1", "alpha2", "beta"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                raise InputError(f"{name} must be an angle [rad], got {value!r}", argument=name)
            object.__setattr__(self, name, float(value))
        for name in ("mount", "reference"):
            matrix = np.array(as_rotation(getattr(self, name), name))
            if matrix.shape != (3, 3):
                raise InputError(f"{name} must be one rotation matrix (3, 3)", argument=name)
            matrix.setflags(write=False)
            object.__setattr__(self, name, matrix)

    @classmethod
    def nominal(
        cls,
        design: SPMDesign | str | None = None,
        *,
        mount: npt.ArrayLike | None = None,
        reference: npt.ArrayLike | None = None,
    ) -> CalibrationParameters:
        """Zero offsets, the design's link angles and the given (default identity) rotations."""
        design = check_design(design)
        return cls(
            offsets=np.zeros(3),
            alpha1=design.alpha1,
            alpha2=design.alpha2,
            beta=design.beta,
            mount=np.eye(3) if mount is None else np.asarray(mount, dtype=float),
            reference=np.eye(3) if reference is None else np.asarray(reference, dtype=float),
        )

    def design(self, base: SPMDesign | str | None = None, *, name: str | None = None) -> SPMDesign:
        """``base`` (default: the prototype) with these link angles."""
        base = check_design(base)
        return dataclasses.replace(
            base,
            alpha1=self.alpha1,
            alpha2=self.alpha2,
            beta=self.beta,
            name=base.name if name is None else name,
        )

    def vector(self, start: CalibrationParameters | None = None) -> FloatArray:
        """Values in the order of :data:`PARAMETER_NAMES` [rad]; mount and ref as
        rotation vectors of the corrections relative to ``start`` (default identity)."""
        mount0 = np.eye(3) if start is None else start.mount
        ref0 = np.eye(3) if start is None else start.reference
        return np.concatenate(
            [
                self.offsets,
                [self.alpha1, self.alpha2, self.beta],
                log_so3(mount0.T @ self.mount),
                log_so3(self.reference @ ref0.T),
            ]
        )

    @classmethod
    def from_vector(
        cls, x: npt.ArrayLike, start: CalibrationParameters | None = None
    ) -> CalibrationParameters:
        """Inverse of :meth:`vector`."""
        x = np.asarray(x, dtype=float)
        mount0 = np.eye(3) if start is None else start.mount
        ref0 = np.eye(3) if start is None else start.reference
        return cls(
            offsets=x[0:3],
            alpha1=float(x[3]),
            alpha2=float(x[4]),
            beta=float(x[5]),
            mount=mount0 @ exp_so3(x[6:9]),
            reference=exp_so3(x[9:12]) @ ref0,
        )

    def as_dict(self) -> dict[str, Any]:
        """Degrees for JSON and reports: offsets, link angles, rotations as rotation vectors."""
        return {
            "offsets_deg": np.degrees(self.offsets).tolist(),
            "alpha1_deg": math.degrees(self.alpha1),
            "alpha2_deg": math.degrees(self.alpha2),
            "beta_deg": math.degrees(self.beta),
            "mount_rotvec_deg": np.degrees(log_so3(self.mount)).tolist(),
            "reference_rotvec_deg": np.degrees(log_so3(self.reference)).tolist(),
        }


def _expand(
    names: Sequence[str] | str | None, kind: str, argument: str = "parameters"
) -> list[str]:
    """Parameter names (groups expanded), unique, in the order of PARAMETER_NAMES."""
    if names is None:
        return list(DEFAULT_PARAMETERS[kind])
    if isinstance(names, str):
        names = [n for n in re.split(r"[,\s]+", names) if n]
    chosen: set[str] = set()
    for name in names:
        if name in PARAMETER_GROUPS:
            chosen.update(PARAMETER_GROUPS[name])
        elif name in PARAMETER_NAMES:
            chosen.add(name)
        else:
            raise InputError(
                f"unknown parameter {name!r}; allowed: {list(PARAMETER_NAMES)} or the groups "
                f"{list(PARAMETER_GROUPS)}",
                argument=argument,
                value=name,
            )
    if not chosen:
        raise InputError(f"{argument} must name at least one parameter", argument=argument)
    return [n for n in PARAMETER_NAMES if n in chosen]
