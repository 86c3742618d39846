"""What readings can tell apart: :class:`Identifiability` (identified and unidentified
parameters, conditioning, correlations) and, before any reading is taken,
:func:`observability` of a set of poses."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError
from ..kinematics._common import check_design
from ._constants import (
    COMPONENTS,
    MAX_CONDITION,
    MAX_CORRELATION,
    NO_EFFECT,
    PARAMETER_NAMES,
    RANK_TOL,
    BoolArray,
    FloatArray,
    check_positive,
)
from ._model import Model
from .parameters import CalibrationParameters, _expand


@dataclasses.dataclass(frozen=True)
class Identifiability:
    """What the readings can and cannot tell apart.

    Attributes:
        parameters: The parameters asked for.
        identified: Those the readings determine (estimated).
        unidentified: Those kept at their starting values.
        combinations: Parameter combinations the readings cannot see, e.g.
            ``"ref_z ~ - offset_1 - offset_2 - offset_3"``: on these readings a change of
            ref_z looks like that change of the identified parameters.
        singular_values: Of the column-normalised Jacobian of ``parameters``, descending.
        condition_number: Of the column-normalised Jacobian of ``identified``.
        correlated: Pairs ``(a, b, r)`` of identified parameters with |r| >= 0.99.
        redundancy: Residual components minus identified parameters (degrees of freedom).
        warnings: Human-readable warnings (empty when all is well).
    """

    parameters: tuple[str, ...]
    identified: tuple[str, ...]
    unidentified: tuple[str, ...]
    combinations: tuple[str, ...]
    singular_values: FloatArray
    condition_number: float
    correlated: tuple[tuple[str, str, float], ...]
    redundancy: int
    warnings: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """Every parameter identified, well conditioned, with redundancy to spare."""
        return not self.warnings

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "ok": self.ok,
            "parameters": list(self.parameters),
            "identified": list(self.identified),
            "unidentified": list(self.unidentified),
            "combinations": list(self.combinations),
            "singular_values": self.singular_values.tolist(),
            "condition_number": self.condition_number,
            "correlated": [list(p) for p in self.correlated],
            "redundancy": self.redundancy,
            "warnings": list(self.warnings),
        }


def _combination(coefficients: FloatArray, names: Sequence[str]) -> str:
    """``"- offset_1 - offset_2 + 0.50 beta"`` from coefficients (small ones left out)."""
    top = float(np.max(np.abs(coefficients))) if coefficients.size else 0.0
    terms = []
    for c, name in zip(coefficients, names, strict=True):
        if abs(c) < 0.05 * top or abs(c) < 5e-3:
            continue
        sign = "-" if c < 0 else "+"
        magnitude = "" if abs(abs(c) - 1.0) < 0.005 else f"{abs(c):.2f} "
        terms.append(f"{sign} {magnitude}{name}")
    text = " ".join(terms) or "0"
    return text[2:] if text.startswith("+ ") else text


def _select(J: FloatArray, names: Sequence[str]) -> tuple[list[int], list[int], list[str]]:
    """Greedy identifiable subset of the columns of J (order = priority).

    A column is kept when the column-normalised Jacobian of the kept columns plus
    this one has relative smallest singular value > RANK_TOL (and there are at least
    as many residuals as kept columns).

    Returns:
        Indices kept, indices dropped, and for each dropped parameter what the
        readings confuse it with: ``"ref_z ~ - offset_1 - offset_2 - offset_3"``
        (a change of ref_z looks like that change of the kept parameters).
    """
    norms = np.linalg.norm(J, axis=0)
    floor = NO_EFFECT * max(float(np.max(norms)) if norms.size else 0.0, 1e-300)
    kept: list[int] = []
    dropped: list[int] = []
    for j in range(J.shape[1]):
        if norms[j] <= floor:
            dropped.append(j)
            continue
        trial = [*kept, j]
        s = np.linalg.svd(J[:, trial] / norms[trial], compute_uv=False)
        if J.shape[0] >= len(trial) and s[-1] > RANK_TOL * s[0]:
            kept.append(j)
        else:
            dropped.append(j)
    combos: list[str] = []
    for j in dropped:
        if norms[j] <= floor:
            combos.append(f"{names[j]} has no effect")
            continue
        if not kept:
            combos.append(f"{names[j]} ~ 0")
            continue
        coefficients = np.asarray(np.linalg.lstsq(J[:, kept], J[:, j], rcond=None)[0], dtype=float)
        combos.append(f"{names[j]} ~ " + _combination(coefficients, [names[k] for k in kept]))
    return kept, dropped, combos


def _identifiability(
    J: FloatArray,
    names: Sequence[str],
    kept: Sequence[int],
    dropped: Sequence[int],
    combos: Sequence[str],
    covariance: FloatArray | None,
) -> Identifiability:
    m = J.shape[0]
    norms = np.linalg.norm(J, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    singular = np.linalg.svd(J / safe, compute_uv=False) if J.size else np.zeros(0)
    if kept:
        s = np.linalg.svd(J[:, list(kept)] / safe[list(kept)], compute_uv=False)
        cond = float(s[0] / s[-1]) if s[-1] > 0 else math.inf
    else:
        cond = math.inf
    redundancy = m - len(kept)
    correlated: list[tuple[str, str, float]] = []
    if covariance is not None and np.all(np.isfinite(covariance)):
        std = np.sqrt(np.diag(covariance))
        corr = covariance / np.outer(std, std)
        for a in range(len(kept)):
            for b in range(a + 1, len(kept)):
                if abs(corr[a, b]) >= MAX_CORRELATION:
                    correlated.append((names[kept[a]], names[kept[b]], float(corr[a, b])))
    messages: list[str] = []
    if dropped:
        messages.append(
            "the readings cannot identify "
            + ", ".join(names[j] for j in dropped)
            + " (kept at the starting values; on these readings "
            + "; ".join(combos)
            + ")"
        )
    if redundancy <= 0:
        messages.append(
            f"{m} residuals for {len(kept)} parameters: no redundancy, so no noise estimate "
            "or confidence interval; add readings"
        )
    if kept and cond > MAX_CONDITION:
        messages.append(
            f"poorly conditioned (condition number {cond:.3g} > {MAX_CONDITION:g}): the "
            "readings barely separate the parameters; use more varied poses (spm plan-poses)"
        )
    if correlated:
        messages.append(
            "estimates nearly inseparable: "
            + ", ".join(f"{a}/{b} (r = {r:+.3f})" for a, b, r in correlated)
        )
    return Identifiability(
        parameters=tuple(names),
        identified=tuple(names[j] for j in kept),
        unidentified=tuple(names[j] for j in dropped),
        combinations=tuple(combos),
        singular_values=np.asarray(singular),
        condition_number=cond,
        correlated=tuple(correlated),
        redundancy=int(redundancy),
        warnings=tuple(messages),
    )


@dataclasses.dataclass(frozen=True)
class Observability:
    """How well a set of poses determines the parameters (before any reading is taken).

    Attributes:
        index: Observability index O1 = (s_1 ... s_n)^(1/n) / sqrt(poses) of the
            identification Jacobian (D-optimality; larger is better) [rad/rad].
        condition_number: Of the column-normalised Jacobian (smaller is better).
        singular_values: Of the (unscaled) Jacobian, descending.
        predicted_std: Expected standard deviation of each parameter [rad] for
            ``noise_deg`` per axis (inf where not identifiable).
        parameters: The parameter names, in order.
        identifiability: Which parameters the poses can separate.
    """

    index: float
    condition_number: float
    singular_values: FloatArray
    predicted_std: FloatArray
    parameters: tuple[str, ...]
    identifiability: Identifiability

    def as_dict(self) -> dict[str, Any]:
        """Plain data (degrees for the predicted deviations)."""
        return {
            "index": self.index,
            "condition_number": self.condition_number,
            "singular_values": self.singular_values.tolist(),
            "predicted_std_deg": {
                n: (math.degrees(s) if math.isfinite(s) else None)
                for n, s in zip(self.parameters, self.predicted_std, strict=True)
            },
            "identifiability": self.identifiability.as_dict(),
        }


def _pose_jacobians(
    theta: FloatArray,
    design: SPMDesign,
    names: Sequence[str],
    kind: str,
    start: CalibrationParameters,
) -> tuple[FloatArray, BoolArray]:
    """Identification Jacobian blocks (N, k, P) at readings ``theta`` = model inputs."""
    model = Model(theta, None, kind, design, start)
    x = start.vector(start)
    evaluation = model.evaluate(x, jac=True)
    assert evaluation.jacobian is not None
    index = [PARAMETER_NAMES.index(n) for n in names]
    return evaluation.jacobian[:, :, index], evaluation.reachable


def _observability_of(
    blocks: FloatArray, names: Sequence[str], noise: float, poses: int
) -> Observability:
    J = blocks.reshape(-1, blocks.shape[-1])
    kept, dropped, combos = _select(J, names)
    singular = np.linalg.svd(J, compute_uv=False)
    P = J.shape[1]
    if singular.size >= P and singular[P - 1] > 0:
        index = float(np.exp(np.mean(np.log(singular[:P])))) / math.sqrt(poses)
    else:
        index = 0.0
    std = np.full(P, np.inf)
    if kept:
        sub = J[:, kept]
        cov = noise**2 * np.linalg.inv(sub.T @ sub)
        std[kept] = np.sqrt(np.diag(cov))
    ident = _identifiability(J, names, kept, dropped, combos, None)
    return Observability(
        index=index,
        condition_number=ident.condition_number,
        singular_values=np.asarray(singular, dtype=float),
        predicted_std=std,
        parameters=tuple(names),
        identifiability=ident,
    )


def observability(
    theta: npt.ArrayLike,
    design: SPMDesign | str | None = None,
    *,
    parameters: Sequence[str] | str | None = None,
    kind: str = "quaternion",
    noise_deg: float = 0.5,
) -> Observability:
    """Observability of the parameters from readings at input angles ``theta``.

    Args:
        theta: Input angles [rad] (N, 3) of the planned poses.
        design: The nominal design (default: the prototype).
        parameters: Names or groups (default as in :func:`calibrate`).
        kind: ``"quaternion"`` or ``"axes"`` readings.
        noise_deg: Measurement noise per axis [deg], for ``predicted_std``.

    Raises:
        InputError: bad arguments, or a pose without a home-mode assembly.
    """
    design = check_design(design)
    if kind not in COMPONENTS:
        raise InputError(f"kind must be one of {sorted(COMPONENTS)}", argument="kind", value=kind)
    names = _expand(parameters, kind)
    angles = _as_poses(theta, "theta")
    noise = math.radians(check_positive(noise_deg, "noise_deg"))
    blocks, ok = _pose_jacobians(angles, design, names, kind, CalibrationParameters.nominal(design))
    if not np.all(ok):
        bad = np.nonzero(~ok)[0]
        raise InputError(
            f"poses {bad.tolist()} have no home-mode assembly", argument="theta", value=angles[bad]
        )
    return _observability_of(blocks, names, noise, angles.shape[0])


def _as_poses(theta: npt.ArrayLike, name: str) -> FloatArray:
    try:
        array = np.asarray(theta, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{name} must be angles [rad] of shape (N, 3)", argument=name) from exc
    if (
        array.ndim != 2
        or array.shape[1] != 3
        or array.shape[0] < 1
        or not np.all(np.isfinite(array))
    ):
        raise InputError(
            f"{name} must be finite angles [rad] of shape (N, 3), got shape {array.shape}",
            argument=name,
            value=theta,
        )
    return array
