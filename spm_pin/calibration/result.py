"""The outcome of a calibration: :class:`CalibrationResult` (estimates, intervals,
identifiability, errors per reading; report, servo configuration, residual plot) and
:class:`ParameterEstimate`."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..design import SPMDesign
from ..errors import InputError
from ..rotations import log_so3
from ._constants import TICKS_PER_TURN, BoolArray, FloatArray, format_float
from .convention import JointConvention, _hardware_config_class
from .identifiability import Identifiability
from .parameters import CalibrationParameters
from .readings import Readings

if TYPE_CHECKING:  # pragma: no cover
    from ..hardware.config import HardwareConfig


@dataclasses.dataclass(frozen=True)
class ParameterEstimate:
    """One identified (or fixed) parameter [rad].

    Attributes:
        name: One of :data:`PARAMETER_NAMES`.
        start: Starting value as given (mount/ref: 0, the correction is estimated).
        value: Estimate (the start when not identified).
        std: Standard deviation (inf when not identified).
        low: Lower end of the confidence interval.
        high: Upper end of the confidence interval.
        identified: Whether the readings determine it.
    """

    name: str
    start: float
    value: float
    std: float
    low: float
    high: float
    identified: bool

    def as_dict(self) -> dict[str, Any]:
        """Degrees, for JSON and reports."""
        return {
            "name": self.name,
            "identified": self.identified,
            "start_deg": math.degrees(self.start),
            "value_deg": math.degrees(self.value),
            "change_deg": math.degrees(self.value - self.start),
            "std_deg": math.degrees(self.std) if math.isfinite(self.std) else None,
            "ci_deg": (
                [math.degrees(self.low), math.degrees(self.high)]
                if math.isfinite(self.std)
                else None
            ),
        }


@dataclasses.dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    Attributes:
        design: The calibrated design (link angles identified; the rest as given).
        parameters: All parameters after calibration.
        start: The starting parameters (before the offsets are guessed from the
            readings, see ``initial_offsets`` of :func:`calibrate`).
        estimates: One entry per requested parameter, in the order of PARAMETER_NAMES.
        covariance: Covariance [rad^2] of the identified parameters, in the order of
            ``identifiability.identified``.
        identifiability: What the readings could tell apart.
        confidence: Level of the intervals (e.g. 0.95).
        readings: The readings given.
        used: (N,) readings used (the start model could assemble them).
        error_start_deg: (N,) orientation error per reading with the starting
            parameters [deg] (for axis readings the largest axis error); NaN where not
            used or not assembled.
        error_deg: (N,) the same after calibration.
        residuals: (N, k) residual components after calibration [rad].
        weights: (N,) mean robust-loss weight per reading (1 = full weight).
        outliers: (N,) readings whose error is improbably large for the noise level.
        sigma_deg: Estimated measurement noise per residual component [deg].
        loss: Robust loss used; ``f_scale`` its scale [rad].
        f_scale: Robust loss scale [rad].
        cost: Final cost 0.5 sum rho(r^2).
        nfev: Residual evaluations.
        njev: Jacobian evaluations.
        method: ``"analytic"`` or the finite-difference scheme used for the Jacobian.
        messages: Warnings (identifiability, excluded readings, outliers).
    """

    design: SPMDesign
    parameters: CalibrationParameters
    start: CalibrationParameters
    estimates: tuple[ParameterEstimate, ...]
    covariance: FloatArray
    identifiability: Identifiability
    confidence: float
    readings: Readings
    used: BoolArray
    error_start_deg: FloatArray
    error_deg: FloatArray
    residuals: FloatArray
    weights: FloatArray
    outliers: BoolArray
    sigma_deg: float
    loss: str
    f_scale: float
    cost: float
    nfev: int
    njev: int
    method: str
    messages: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """Every requested parameter identified and well conditioned."""
        return self.identifiability.ok

    def estimate(self, name: str) -> ParameterEstimate:
        """The estimate of one parameter by name."""
        for entry in self.estimates:
            if entry.name == name:
                return entry
        raise InputError(
            f"{name!r} was not a calibrated parameter; these were: "
            f"{[e.name for e in self.estimates]}",
            argument="name",
            value=name,
        )

    @property
    def offsets_deg(self) -> FloatArray:
        """Identified encoder zero offsets [deg] (3,)."""
        return np.degrees(self.parameters.offsets)

    @property
    def joints(self) -> JointConvention:
        """The readings' encoder convention with the identified zero offsets."""
        return self.readings.joints.with_offsets(self.parameters.offsets)

    @property
    def zero_offsets(self) -> FloatArray:
        """Identified zero offsets [pulses, 4096 per turn] (3,), not rounded.

        The servos' Present Position at which each input is at the model's zero: the
        ``zero_offset`` of a servo configuration (:meth:`servo_config` rounds them). For
        readings of 4096 counts per turn these are ``joints.zero_offset_ticks``.
        """
        joints = self.joints
        result: FloatArray = (
            np.asarray(joints.zero_offset_ticks) * TICKS_PER_TURN / joints.ticks_per_turn
        )
        return result

    def servo_config(self, config: HardwareConfig | str | Path) -> HardwareConfig:
        """A servo configuration with the identified zero offsets (whole pulses).

        Everything else in ``config`` is kept, and the copy is validated like any
        :class:`spm_pin.hardware.HardwareConfig` (write it with ``.save(path)``). The
        readings' directions and gear ratios must be the configuration's: load them
        with ``joints=JointConvention.from_servo_config(config)``, or give the same
        settings in the file. Their zero offsets may be anything (the old
        configuration's, say): the identified ones are absolute. Check :attr:`ok`
        first: offsets the readings cannot identify keep their starting values.

        Needs only the core of :mod:`spm_pin.hardware` (not its SDK).

        Args:
            config: The configuration the readings were taken with, or its file.

        Raises:
            InputError: ``config`` is no configuration, or its directions or gear
                ratios differ from the readings'.
            FileFormatError: the configuration file is malformed.
        """
        hardware_config = _hardware_config_class()
        if isinstance(config, (str, Path)):
            config = hardware_config.load(config)
        if not isinstance(config, hardware_config):
            raise InputError(
                f"config must be a spm_pin.hardware.HardwareConfig or its file, got "
                f"{type(config).__name__}",
                argument="config",
                value=config,
            )
        readings = self.readings.joints
        for i, joint in enumerate(config.joints):
            direction, gear = readings.direction[i], readings.gear_ratio[i]
            if joint.direction != direction or not math.isclose(
                joint.gear_ratio, gear, rel_tol=1e-9
            ):
                raise InputError(
                    f"joint {joint.joint}: the readings were converted with direction "
                    f"{direction:+d} and gear ratio {format_float(gear)}, the servo "
                    f"configuration has direction {joint.direction:+d} and gear ratio "
                    f"{format_float(joint.gear_ratio)}; "
                    "the readings file must give the configuration's direction and "
                    "gear_ratio, or none (then the configuration's apply, by loading it with "
                    "joints=JointConvention.from_servo_config(config), as spm calibrate "
                    "--servo-config does)",
                    argument="config",
                    value=config,
                )
        zero = self.zero_offsets
        u1, u2, u3 = (
            dataclasses.replace(joint, zero_offset=round(float(zero[i])))
            for i, joint in enumerate(config.joints)
        )
        return config.replace(joints=(u1, u2, u3))

    def as_dict(self) -> dict[str, Any]:
        """Plain data (degrees) for JSON."""
        lines = self.readings.lines
        assert lines is not None
        return {
            "ok": self.ok,
            "design": self.design.to_dict(),
            "confidence": self.confidence,
            "readings": len(self.readings),
            "used": int(np.sum(self.used)),
            "excluded_lines": lines[~self.used].tolist(),
            "outlier_lines": lines[self.outliers].tolist(),
            "parameters": [e.as_dict() for e in self.estimates],
            "all_parameters": self.parameters.as_dict(),
            "identifiability": self.identifiability.as_dict(),
            "rms_error_start_deg": _rms(self.error_start_deg[self.used]),
            "rms_error_deg": _rms(self.error_deg[self.used]),
            "sigma_deg": self.sigma_deg,
            "loss": self.loss,
            "f_scale_deg": math.degrees(self.f_scale),
            "nfev": self.nfev,
            "njev": self.njev,
            "jacobian": self.method,
            "encoder": self._encoder_dict(),
            "messages": list(self.messages),
        }

    def _encoder_dict(self) -> dict[str, Any]:
        """The zero offsets in the servo configuration's terms (pulses, 4096 per turn)."""
        joints = self.joints
        zero = self.zero_offsets
        std = [self._offset_std(i) for i in range(3)]
        return {
            "ticks_per_turn": joints.ticks_per_turn,
            "joints": {
                f"u_{i + 1}": {
                    "direction": joints.direction[i],
                    "gear_ratio": joints.gear_ratio[i],
                    "zero_offset": round(float(zero[i])),
                    "zero_offset_exact": float(zero[i]),
                    "offset_deg": float(self.offsets_deg[i]),
                    "offset_std_deg": math.degrees(std[i]) if math.isfinite(std[i]) else None,
                }
                for i in range(3)
            },
        }

    def _offset_std(self, i: int) -> float:
        name = f"offset_{i + 1}"
        return next((e.std for e in self.estimates if e.name == name), math.inf)

    def offsets_toml(self) -> str:
        """The identified zero offsets as the ``[[joints]]`` tables of a servo configuration.

        The keys of :class:`spm_pin.hardware.HardwareConfig`: ``joint``, ``direction``,
        ``gear_ratio`` and ``zero_offset`` (whole pulses, 4096 per turn), for
        ``theta_i = direction * (pulses - zero_offset) * 360 / 4096 / gear_ratio`` [deg];
        only ``servo_id`` is missing. The exact value and the identified offset [deg]
        are comments. :meth:`servo_config` writes a whole configuration instead.
        """
        data = self._encoder_dict()
        source = self.readings.source or "readings"
        lines = [
            f"# Encoder zero offsets identified by spm-pin calibration from {source}:",
            "# [[joints]] tables of a servo configuration (spm_pin.hardware.HardwareConfig).",
            "# Copy each zero_offset into your configuration's table of the same joint, or",
            "# paste the tables and add servo_id; spm calibrate --servo-config CONFIG.toml",
            "# writes the whole configuration instead.",
            "# theta_i [deg] = direction * (pulses - zero_offset) * 360 / 4096 / gear_ratio",
            "# is the model's input angle (0 at home). Each comment gives the exact value",
            "# and the identified offset: the change from the readings' zero.",
        ]
        if data["ticks_per_turn"] != TICKS_PER_TURN:
            lines.append(
                f"# (the readings' {data['ticks_per_turn']} counts per turn are converted to "
                f"{TICKS_PER_TURN} pulses per turn)"
            )
        for name, joint in data["joints"].items():
            std = joint["offset_std_deg"]
            spread = "" if std is None else f" +- {std:.4f}"
            lines += [
                "",
                "[[joints]]",
                f'joint = "{name}"',
                f"direction = {joint['direction']}",
                f"gear_ratio = {float(joint['gear_ratio'])!r}",
                f"zero_offset = {joint['zero_offset']}  # pulses (exact "
                f"{joint['zero_offset_exact']:.2f}); offset {joint['offset_deg']:+.4f}{spread} deg",
            ]
        return "\n".join(lines) + "\n"

    def report(self) -> str:
        """A human-readable report: data, fit, parameters, identifiability, outliers."""
        r = self.readings
        lines_of = r.lines
        assert lines_of is not None
        level = f"{100 * self.confidence:g}%"
        out = [
            f"spm-pin calibration of {self.start_design_name} from "
            f"{r.source or 'readings'}: {len(r)} readings ({r.kind}, servo {r.servo_unit})",
            "",
            f"fit: {self.loss} loss (scale {math.degrees(self.f_scale):.3g} deg), "
            f"{self.nfev} evaluations, Jacobian {self.method}",
            f"rms orientation error: {_rms(self.error_start_deg[self.used]):.4g} deg before, "
            f"{_rms(self.error_deg[self.used]):.4g} deg after; noise estimate "
            f"{self.sigma_deg:.3g} deg per axis",
            "",
            f"{'parameter':<10} {'start':>11} {'estimate':>11} {'std':>9}  {level} interval [deg]",
        ]
        for e in self.estimates:
            d = e.as_dict()
            if d["ci_deg"] is not None:
                ci = f"[{d['ci_deg'][0]:.4f}, {d['ci_deg'][1]:.4f}]"
                std = f"{d['std_deg']:.4f}"
            elif e.identified:
                ci, std = "no interval (no redundancy)", "inf"
            else:
                ci, std = "not identified (kept at start)", "inf"
            out.append(
                f"{e.name:<10} {d['start_deg']:>11.4f} {d['value_deg']:>11.4f} {std:>9}  {ci}"
            )
        ident = self.identifiability
        out += [
            "",
            f"identifiability: condition number {ident.condition_number:.4g}, "
            f"redundancy {ident.redundancy}",
            "  normalised singular values: " + " ".join(f"{s:.3g}" for s in ident.singular_values),
        ]
        out += [f"  WARNING: {w}" for w in ident.warnings]
        if ident.ok:
            out.append("  every parameter is identified")
        enc = self._encoder_dict()
        out += ["", "encoder zero offsets (servo configuration, 4096 pulses per turn):"]
        for name, j in enc["joints"].items():
            std = "" if j["offset_std_deg"] is None else f" +- {j['offset_std_deg']:.4f}"
            out.append(
                f"  {name}: offset {j['offset_deg']:+.4f}{std} deg -> zero_offset "
                f"{j['zero_offset']} ({j['zero_offset_exact']:.2f}), direction "
                f"{j['direction']:+d}, gear ratio {format_float(j['gear_ratio'])}"
            )
        mount = self.parameters.mount
        out += [
            "",
            "sensor mounting (sensor frame in platform frame), rotation vector [deg]: "
            + " ".join(f"{a:+.4f}" for a in np.degrees(log_so3(mount))),
            f"calibrated design: {self.design.summary()}",
        ]
        extra = [m for m in self.messages if m not in ident.warnings]
        if extra:
            out.append("")
            out += [f"note: {m}" for m in extra]
        if np.any(~self.used):
            out.append(f"excluded readings (lines): {lines_of[~self.used].tolist()}")
        if np.any(self.outliers):
            out.append(
                f"outliers (lines, down-weighted by the loss): {lines_of[self.outliers].tolist()}"
            )
        return "\n".join(out) + "\n"

    @property
    def start_design_name(self) -> str:
        """Name of the design calibration started from."""
        name = self.design.name
        return name[: -len("_calibrated")] if name.endswith("_calibrated") else name

    def plot_residuals(self, path: str | Path) -> Path:
        """Write a residual plot (PNG): error per reading before/after, components after.

        Needs matplotlib (``pip install spm-pin[plot]``); imported here only.
        """
        try:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise InputError(
                "the residual plot needs matplotlib: pip install spm-pin[plot]",
                argument="path",
                value=str(path),
            ) from exc
        lines = self.readings.lines
        assert lines is not None
        used = self.used
        fig = Figure(figsize=(9.0, 6.5))
        FigureCanvasAgg(fig)
        top, bottom = fig.subplots(2, 1, sharex=True)
        x = lines[used]
        top.plot(x, self.error_start_deg[used], "o", ms=3, color="0.6", label="before")
        top.plot(x, self.error_deg[used], "o", ms=3, color="C0", label="after")
        if np.any(self.outliers):
            top.plot(
                lines[self.outliers],
                self.error_deg[self.outliers],
                "x",
                ms=8,
                color="C3",
                label="outlier",
            )
        top.set_yscale("log")
        top.set_ylabel("orientation error [deg]")
        top.set_title(
            f"Calibration of {self.start_design_name}: rms "
            f"{_rms(self.error_start_deg[used]):.3g} -> {_rms(self.error_deg[used]):.3g} deg"
        )
        top.legend(loc="upper right", fontsize="small")
        comps = np.degrees(self.residuals[used])
        labels = (
            ["x", "y", "z"]
            if comps.shape[1] == 3
            else [f"v{i}{c}" for i in (1, 2, 3) for c in "xyz"]
        )
        for j in range(comps.shape[1]):
            bottom.plot(x, comps[:, j], ".", ms=3, label=labels[j] if comps.shape[1] == 3 else None)
        band = 2.0 * self.sigma_deg
        bottom.axhline(band, color="0.5", lw=0.8, ls="--")
        bottom.axhline(-band, color="0.5", lw=0.8, ls="--")
        bottom.set_ylabel("residual after [deg]")
        bottom.set_xlabel("line in the readings file")
        if comps.shape[1] == 3:
            bottom.legend(loc="upper right", fontsize="small", ncol=3)
        fig.tight_layout()
        out = Path(path)
        fig.savefig(out, dpi=110)
        return out


def _rms(values: FloatArray) -> float:
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else math.nan
