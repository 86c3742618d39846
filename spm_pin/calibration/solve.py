"""Identification of the parameters from readings (:func:`calibrate`): robust
least squares, covariances and intervals, outliers."""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import ConvergenceError, InputError
from ..kinematics import inverse_kinematics
from ..kinematics._common import check_design, cross
from ._constants import (
    LOSS_SCALE,
    LOSS_SLOPES,
    LOSS_WEIGHTS,
    OUTLIER_P,
    PARAMETER_NAMES,
    BoolArray,
    FloatArray,
    IdentifiabilityWarning,
    check_positive,
)
from ._model import Model
from .identifiability import _identifiability, _select
from .parameters import CalibrationParameters, _expand
from .readings import Readings
from .result import CalibrationResult, ParameterEstimate

if TYPE_CHECKING:  # pragma: no cover
    from scipy.optimize import OptimizeResult


def _error_angle(R_a: FloatArray, R_b: FloatArray) -> FloatArray:
    """Angle [rad] of E = R_a^T R_b, batched (...): atan2(sin, cos), precise near 0."""
    E = np.swapaxes(R_a, -1, -2) @ R_b
    sine = 0.5 * np.linalg.norm(
        np.stack(
            [E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0], E[..., 1, 0] - E[..., 0, 1]],
            -1,
        ),
        axis=-1,
    )
    cosine = 0.5 * (np.trace(E, axis1=-2, axis2=-1) - 1.0)
    result: FloatArray = np.arctan2(sine, cosine)
    return result


def _errors_deg(kind: str, predicted: FloatArray, measured: FloatArray) -> FloatArray:
    if kind == "quaternion":
        return np.degrees(_error_angle(predicted, measured))
    sine = np.linalg.norm(cross(predicted, measured), axis=-1)
    cosine = np.sum(predicted * measured, axis=-1)
    result: FloatArray = np.degrees(np.max(np.arctan2(sine, cosine), axis=-1))
    return result


def _initial_offsets(
    readings: Readings, design: SPMDesign, start: CalibrationParameters
) -> FloatArray | None:
    """Offsets from inverse kinematics of the measured orientations (circular mean)."""
    if readings.kind == "quaternion":
        R = start.reference.T @ readings.orientation @ start.mount.T
    else:
        v = np.einsum("kj,nik->nij", start.reference, readings.orientation)  # R_ref^T v
        H = np.einsum("nij,ik->njk", v, design.v0)  # sum_i v_i v_i0^T
        U, _, Vt = np.linalg.svd(H)
        S = np.ones((len(readings), 3))
        S[:, 2] = np.sign(np.linalg.det(U @ Vt))
        R = (U * S[:, None, :]) @ Vt
    ik = inverse_kinematics(R, design)
    ok = np.asarray(ik.reachable)
    if not np.any(ok):
        return None
    diff = readings.theta[ok] - ik.theta[ok]
    mean = np.angle(np.mean(np.exp(1j * diff), axis=0))
    spread = np.angle(np.exp(1j * (diff - mean)))
    result: FloatArray = mean + np.median(spread, axis=0)
    return result


def calibrate(
    readings: Readings,
    design: SPMDesign | str | None = None,
    *,
    parameters: Sequence[str] | str | None = None,
    start: CalibrationParameters | None = None,
    mount: npt.ArrayLike | None = None,
    reference: npt.ArrayLike | None = None,
    loss: str = "soft_l1",
    noise_deg: float = 0.5,
    confidence: float = 0.95,
    jacobian: str = "analytic",
    initial_offsets: bool = True,
    max_nfev: int = 200,
) -> CalibrationResult:
    """Identify the model's parameters from readings of the prototype.

    Args:
        readings: The readings (:func:`load_readings`, :func:`synthetic_readings`).
        design: The nominal design to start from (default: the prototype).
        parameters: Names (or groups) to identify; default ``offsets, links, mount``
            for quaternion readings and ``offsets, links`` for axis readings.
        start: Starting values of all parameters (default: zero offsets, the design's
            link angles, ``mount`` and ``reference``).
        mount: Nominal sensor frame in the platform frame (3, 3) (default identity).
        reference: Nominal world frame in the sensor's reference frame (default identity).
        loss: Robust loss of :func:`scipy.optimize.least_squares`: ``"soft_l1"``
            (default), ``"huber"``, ``"cauchy"``, ``"arctan"`` or ``"linear"``.
        noise_deg: Expected measurement noise per axis [deg] (0.5 for a typical IMU);
            sets the first loss scale, then the scale follows the residuals.
        confidence: Level of the confidence intervals, in (0, 1).
        jacobian: ``"analytic"`` (default) or ``"2-point"`` / ``"3-point"`` finite
            differences (slower; for checking).
        initial_offsets: Start the offsets from inverse kinematics of the measured
            orientations (robust to offsets of any size).
        max_nfev: Limit on residual evaluations per solve.

    Returns:
        CalibrationResult. When the readings cannot separate some parameters, an
        :class:`IdentifiabilityWarning` is issued, those parameters keep their starting
        values with infinite intervals, and ``result.ok`` is False.

    Raises:
        InputError: a bad argument, or no reading can be assembled by the start model.
        ConvergenceError: the solver stopped without converging.
    """
    from scipy.optimize import least_squares
    from scipy.special import chdtri, stdtrit

    if not isinstance(readings, Readings):
        raise InputError(
            f"readings must be Readings (see load_readings), got {type(readings).__name__}",
            argument="readings",
            value=readings,
        )
    design = check_design(design)
    names = _expand(parameters, readings.kind)
    if loss not in LOSS_WEIGHTS:
        raise InputError(
            f"loss must be one of {list(LOSS_WEIGHTS)}, got {loss!r}", argument="loss", value=loss
        )
    if jacobian not in ("analytic", "2-point", "3-point"):
        raise InputError(
            f"jacobian must be 'analytic', '2-point' or '3-point', got {jacobian!r}",
            argument="jacobian",
            value=jacobian,
        )
    check_positive(noise_deg, "noise_deg")
    if (
        isinstance(confidence, bool)
        or not isinstance(confidence, (int, float))
        or not (0.0 < confidence < 1.0)
    ):
        raise InputError(
            f"confidence must lie strictly between 0 and 1, got {confidence!r}",
            argument="confidence",
            value=confidence,
        )
    if isinstance(max_nfev, bool) or not isinstance(max_nfev, int) or max_nfev < 1:
        raise InputError(
            f"max_nfev must be a positive integer, got {max_nfev!r}", argument="max_nfev"
        )
    if start is None:
        start = CalibrationParameters.nominal(design, mount=mount, reference=reference)
    elif not isinstance(start, CalibrationParameters):
        raise InputError("start must be CalibrationParameters", argument="start", value=start)
    messages: list[str] = []
    nominal = start
    x_nominal = nominal.vector(nominal)
    if initial_offsets and any(n.startswith("offset") for n in names):
        guess = _initial_offsets(readings, start.design(design), start)
        if guess is not None:
            offsets = np.array(start.offsets)
            for i in range(3):
                if f"offset_{i + 1}" in names:
                    offsets[i] = guess[i]
            start = dataclasses.replace(start, offsets=offsets)
    x_start = start.vector(start)
    index = [PARAMETER_NAMES.index(n) for n in names]

    model_all = Model(readings.theta, readings.orientation, readings.kind, design, start)
    first = model_all.evaluate(x_start, jac=True)
    used = first.reachable
    lines = readings.lines
    assert lines is not None
    if not np.any(used):
        raise InputError(
            "the start model cannot assemble any reading (no home-mode assembly at the "
            "readings' input angles); check the servo units, directions and zero offsets",
            argument="readings",
        )
    J0 = first.jacobian
    assert J0 is not None
    J0 = J0[used].reshape(-1, len(PARAMETER_NAMES))[:, index]
    kept, dropped, combos = _select(J0, names)
    free = [index[j] for j in kept]
    x_final = x_start.copy()
    f_scale = LOSS_SCALE * math.radians(noise_deg)
    nfev = njev = 0

    def solve(used: BoolArray, z: FloatArray, f_scale: float) -> tuple[FloatArray, float]:
        """Identify the free parameters from the readings ``used``, starting at z."""
        nonlocal nfev, njev
        model = Model(
            readings.theta[used], readings.orientation[used], readings.kind, design, start
        )

        def fun(z: FloatArray) -> FloatArray:
            x = x_start.copy()
            x[free] = z
            return model.evaluate(x, jac=False).residual.reshape(-1)

        def jac(z: FloatArray) -> FloatArray:
            x = x_start.copy()
            x[free] = z
            J = model.evaluate(x, jac=True).jacobian
            assert J is not None
            return J.reshape(-1, len(PARAMETER_NAMES))[:, free]

        rounds = 1 if loss == "linear" else 2
        for round_ in range(rounds):
            solution: OptimizeResult = least_squares(
                fun,
                z,
                jac=jac if jacobian == "analytic" else jacobian,  # type: ignore[arg-type]
                method="trf",
                loss=loss,  # type: ignore[arg-type]
                f_scale=f_scale,
                max_nfev=max_nfev,
                x_scale=1.0,
            )
            nfev += int(solution.nfev)
            njev += int(solution.njev or 0)
            if solution.status <= 0:
                raise ConvergenceError(
                    f"calibration did not converge: {solution.message}",
                    data={"result": solution, "parameters": [PARAMETER_NAMES[i] for i in free]},
                )
            z = np.asarray(solution.x, dtype=float)
            if round_ + 1 < rounds:
                sigma = 1.4826 * float(np.median(np.abs(fun(z))))
                f_scale = max(LOSS_SCALE * sigma, 1e-9)
        return z, f_scale

    if free:
        z = x_start[free]
        # Readings the start model cannot assemble join once the fitted model can.
        for _ in range(3):
            z, f_scale = solve(used, z, LOSS_SCALE * math.radians(noise_deg))
            x_final[free] = z
            now = model_all.evaluate(x_final, jac=False).reachable
            if np.array_equal(now, used) or np.sum(now) < np.sum(used):
                break
            used = now
    if not np.all(used):
        messages.append(
            f"{int(np.sum(~used))} reading(s) left out: the model cannot assemble them "
            f"(lines {lines[~used].tolist()})"
        )
    model = Model(readings.theta[used], readings.orientation[used], readings.kind, design, start)
    k = model.k
    final = model.evaluate(x_final, jac=True)
    assert final.jacobian is not None
    J_all = final.jacobian.reshape(-1, len(PARAMETER_NAMES))
    r = final.residual.reshape(-1)
    m = r.size
    J_free = J_all[:, free]
    z2 = (r / f_scale) ** 2
    weights = LOSS_WEIGHTS[loss](z2)
    dof = m - len(free)
    covariance = np.full((len(free), len(free)), np.inf)
    if free and dof > 0:
        # Huber's covariance of an M-estimate: [sum psi^2 / dof] / mean(psi')^2 (J^T J)^-1
        # with psi(r) = r rho'(r^2); for the linear loss this is s^2 (J^T J)^-1.
        slope = float(np.mean(LOSS_SLOPES[loss](z2)))
        psi2 = float(np.sum((weights * r) ** 2) / dof)
        if slope > 0.1:
            s2 = psi2 / slope**2
            H = J_free.T @ J_free
        else:  # most residuals beyond the loss scale: fall back to weighted least squares
            s2 = float(np.sum(weights * r * r) / dof)
            H = J_free.T @ (weights[:, None] * J_free)
        try:
            covariance = s2 * np.linalg.inv(H)
        except np.linalg.LinAlgError:
            covariance = np.full((len(free), len(free)), np.inf)
    if not np.all(np.isfinite(covariance)):
        covariance = np.full((len(free), len(free)), np.inf)
    ident = _identifiability(
        J_all[:, index], names, kept, dropped, combos, covariance if dof > 0 else None
    )
    t = float(stdtrit(dof, 0.5 + confidence / 2.0)) if dof > 0 else math.inf
    estimates = []
    for j, name in enumerate(names):
        p = index[j]
        value, origin = float(x_final[p]), float(x_nominal[p])
        if j in kept and dof > 0:
            std = float(math.sqrt(max(covariance[kept.index(j), kept.index(j)], 0.0)))
            if not math.isfinite(std):
                std = math.inf
        else:
            std = math.inf
        half = t * std if math.isfinite(std) else math.inf
        estimates.append(
            ParameterEstimate(
                name=name,
                start=origin,
                value=value,
                std=std,
                low=value - half,
                high=value + half,
                identified=j in kept,
            )
        )
    parameters_final = CalibrationParameters.from_vector(x_final, start)
    calibrated = parameters_final.design(design, name=f"{design.name}_calibrated")

    # Per-reading errors before and after, over all readings.
    n = len(readings)
    at_nominal = model_all.evaluate(x_nominal, jac=False)
    before = _errors_deg(readings.kind, at_nominal.predicted, readings.orientation)
    after_eval = model_all.evaluate(x_final, jac=False)
    after = _errors_deg(readings.kind, after_eval.predicted, readings.orientation)
    residuals = np.full((n, k), np.nan)
    residuals[used] = final.residual
    pose_weights = np.full(n, np.nan)
    pose_weights[used] = weights.reshape(-1, k).mean(axis=1)
    sigma = 1.4826 * float(np.median(np.abs(r))) if r.size else math.nan
    outliers = np.zeros(n, dtype=bool)
    if sigma > 0:
        dof_pose = 3 if readings.kind == "quaternion" else 6
        limit = math.sqrt(float(chdtri(dof_pose, OUTLIER_P))) * sigma
        norms = np.linalg.norm(final.residual, axis=1)
        outliers[np.nonzero(used)[0][norms > limit]] = True
    if np.any(outliers):
        messages.append(
            f"{int(np.sum(outliers))} reading(s) fit far worse than the noise level "
            f"(lines {lines[outliers].tolist()}); the robust loss down-weights them"
        )
    all_messages = [*ident.warnings, *messages]
    if not ident.ok:
        warnings.warn(
            "calibration: " + "; ".join(ident.warnings), IdentifiabilityWarning, stacklevel=2
        )
    return CalibrationResult(
        design=calibrated,
        parameters=parameters_final,
        start=nominal,
        estimates=tuple(estimates),
        covariance=covariance,
        identifiability=ident,
        confidence=float(confidence),
        readings=readings,
        used=used,
        error_start_deg=np.where(used, before, np.nan),
        error_deg=np.where(used, after, np.nan),
        residuals=residuals,
        weights=pose_weights,
        outliers=outliers,
        sigma_deg=math.degrees(sigma),
        loss=loss,
        f_scale=f_scale,
        cost=float(0.5 * np.sum(f_scale**2 * _rho(loss, (r / f_scale) ** 2))),
        nfev=nfev,
        njev=njev,
        method=jacobian,
        messages=tuple(all_messages),
    )


def _rho(loss: str, z: FloatArray) -> FloatArray:
    result: FloatArray
    if loss == "linear":
        result = z
    elif loss == "soft_l1":
        result = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == "huber":
        result = np.where(z <= 1.0, z, 2.0 * np.sqrt(np.maximum(z, 1.0)) - 1.0)
    elif loss == "cauchy":
        result = np.log1p(z)
    else:
        result = np.arctan(z)
    return result
