"""The design of a spherical parallel manipulator: parameters, validation, presets, TOML.

Kinematic parameters (docs/conventions.md):

* ``alpha1`` [rad]: proximal link angle, the angle between u_i and w_i.
* ``alpha2`` [rad]: distal link angle, the angle between w_i and v_i.
* ``beta`` [rad]: inclination of the platform joint axes v_i from the platform
  normal z.
* ``eta`` [rad]: leg azimuths (counterclockwise seen from above).
* ``base_axes``: the base joint axes u_i (unit vectors, world frame). The coaxial
  SPM has u_i = [0, 0, -1] for all legs; any other triad gives a general 3-RRR SPM.

The home configuration (theta = 0, R = identity) is built from these:
v_i0 = [sin b cos(eta_i - 90deg), sin b sin(eta_i - 90deg), cos b], and w_i0 is the
unit vector at angle alpha1 from u_i and alpha2 from v_i0 on the side where
b_ii = (u_i x w_i0) . v_i0 > 0 (the home working mode). For the coaxial prototype
this gives w_i0 = [sin a1 cos eta_i, sin a1 sin eta_i, -cos a1], as in docs/conventions.md.
Input theta_i turns w_i about u_i by theta_i (right-handed about u_i; for
u = [0, 0, -1] that is clockwise seen from above).

Link dimensions (used by the robot model) live in :class:`LinkDimensions`.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import tomli_w

from .errors import DesignError, FileFormatError, InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["LinkDimensions", "SPMDesign"]

FloatArray = npt.NDArray[np.float64]

#: Tolerance for "not degenerate" checks on unit-vector geometry.
_GEOMETRY_TOL = 1e-9


@dataclasses.dataclass(frozen=True)
class LinkDimensions:
    """Physical sizes of the links [m, kg, kg/m^3].

    Defaults fit the prototype's envelope (about 200 x 200 x 290 mm at home): the
    proximal links are curved plates on an inner sphere of radius
    ``proximal_radius`` around O, the distal links curved plates on an outer sphere
    of radius ``distal_radius``; the platform plate sits ``platform_height`` above O
    and brackets reach down to its joints; the base plate lies ``base_depth`` below O
    with the three servos on it.
    """

    proximal_radius: float = 0.075
    proximal_width: float = 0.030
    proximal_thickness: float = 0.008
    distal_radius: float = 0.090
    distal_width: float = 0.025
    distal_thickness: float = 0.008
    platform_radius: float = 0.070
    platform_thickness: float = 0.008
    platform_height: float = 0.045
    base_radius: float = 0.100
    base_thickness: float = 0.010
    base_depth: float = 0.235
    hub_radius: float = 0.018
    joint_radius: float = 0.008
    servo_size: tuple[float, float, float] = (0.0335, 0.0585, 0.044)
    servo_mass: float = 0.165
    density: float = 1240.0

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            values: tuple[Any, ...]
            if field.name == "servo_size":
                if not isinstance(value, tuple) or len(value) != 3:
                    raise DesignError(
                        f"dimensions.servo_size must be 3 lengths [m], got {value!r}",
                        parameter="servo_size",
                        value=value,
                    )
                values = value
            else:
                values = (value,)
            for item in values:
                if not _is_number(item) or not math.isfinite(item) or item <= 0:
                    raise DesignError(
                        f"dimensions.{field.name} must be a finite positive number, got {value!r}",
                        parameter=field.name,
                        value=value,
                    )
        inner = self.proximal_radius + self.proximal_thickness / 2
        outer = self.distal_radius - self.distal_thickness / 2
        if inner >= outer:
            raise DesignError(
                "dimensions: the proximal sphere (proximal_radius + proximal_thickness/2 = "
                f"{inner:.4g} m) must lie inside the distal sphere (distal_radius - "
                f"distal_thickness/2 = {outer:.4g} m)",
                parameter="distal_radius",
                value=self.distal_radius,
            )
        if self.hub_radius >= self.proximal_radius:
            raise DesignError(
                f"dimensions.hub_radius ({self.hub_radius} m) must be smaller than "
                f"proximal_radius ({self.proximal_radius} m)",
                parameter="hub_radius",
                value=self.hub_radius,
            )


def _unit(vector: Sequence[float], name: str) -> tuple[float, float, float]:
    try:
        array = np.asarray(vector, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DesignError(
            f"{name} must be a 3-vector of numbers, got {vector!r}", parameter=name, value=vector
        ) from exc
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise DesignError(
            f"{name} must be a finite 3-vector, got {vector!r}", parameter=name, value=vector
        )
    norm = float(np.linalg.norm(array))
    if norm < _GEOMETRY_TOL:
        raise DesignError(f"{name} must be non-zero, got {vector!r}", parameter=name, value=vector)
    # A vector that is already unit to rounding is kept bit for bit, so that saving
    # and loading a design never moves the last digit.
    unit = array if abs(norm - 1.0) <= 4 * np.finfo(float).eps else array / norm
    return (float(unit[0]), float(unit[1]), float(unit[2]))


def _read_text(path: str | Path, what: str) -> tuple[str, str]:
    """The UTF-8 text of a file and its name; FileFormatError names ``what`` on failure.

    Shared by every loader (designs, servo configurations, calibration files).
    """
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as exc:
        raise FileFormatError(f"cannot read {what}: {exc.strerror}", path=str(file)) from exc
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{what} is not UTF-8 text", path=str(file)) from exc
    return text, str(file)


def _parse_toml(text: str, source: str | None) -> dict[str, Any]:
    """TOML text as a dict, or FileFormatError naming ``source``."""
    try:
        data: dict[str, Any] = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"not valid TOML: {exc}", path=source) from exc
    return data


def _round_deg(angle: float) -> float:
    """An angle [rad] in degrees rounded to 12 decimals: what design files store, so
    that radians(degrees(x)) round-trips exactly for designs given in degrees."""
    return round(math.degrees(angle), 12)


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _check_angle(value: float, name: str, low: float, high: float) -> float:
    if not _is_number(value) or not math.isfinite(value):
        raise DesignError(f"{name} must be a finite angle [rad], got {value!r}", parameter=name)
    if not low < value < high:
        raise DesignError(
            f"{name} = {math.degrees(value):.6g} deg is impossible: it must lie strictly between "
            f"{math.degrees(low):.6g} and {math.degrees(high):.6g} deg",
            parameter=name,
            value=value,
        )
    return float(value)


#: Preset names and the classmethods that make them (see :meth:`SPMDesign.preset`).
_PRESETS: dict[str, str] = {"prototype": "prototype", "agile_eye": "agile_eye"}


def _preset_key(name: object) -> str | None:
    """The preset ``name`` stands for (any case, ``-`` for ``_``), or None."""
    if not isinstance(name, str):
        return None
    key = name.strip().lower().replace("-", "_")
    return key if key in _PRESETS else None


def _is_bare_name(text: str) -> bool:
    """True for a plain name: no directory part and no suffix (``agile_eye``, not
    ``./agile_eye`` or ``agile_eye.toml``)."""
    separators = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    return not any(sep in text for sep in separators) and not Path(text).suffix


@dataclasses.dataclass(frozen=True)
class SPMDesign:
    """Parameters of a 3-RRR spherical parallel manipulator (frozen, validated).

    Angles are in radians. Build one with :meth:`prototype`, :meth:`agile_eye`,
    :meth:`coaxial` or the constructor; save and load with :meth:`save` / :meth:`load`;
    :meth:`from_spec` takes a design, a preset name or a file, as every function and
    command that accepts a design does.

    Raises:
        DesignError: a parameter is impossible (its name is in the message and in
            ``error.parameter``), or the home configuration cannot be assembled.
    """

    alpha1: float
    alpha2: float
    beta: float
    eta: tuple[float, float, float] = (0.0, math.radians(120.0), math.radians(240.0))
    base_axes: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, -1.0),) * 3
    dimensions: LinkDimensions = dataclasses.field(default_factory=LinkDimensions)
    name: str = "custom"

    def __post_init__(self) -> None:
        _check_angle(self.alpha1, "alpha1", 0.0, math.pi)
        _check_angle(self.alpha2, "alpha2", 0.0, math.pi)
        _check_angle(self.beta, "beta", 0.0, math.pi)
        try:
            eta = tuple(float(e) for e in self.eta)
        except (TypeError, ValueError) as exc:
            raise DesignError(
                f"eta must be 3 leg azimuths [rad], got {self.eta!r}",
                parameter="eta",
                value=self.eta,
            ) from exc
        if len(eta) != 3 or not all(math.isfinite(e) for e in eta):
            raise DesignError(
                f"eta must be 3 finite leg azimuths [rad], got {self.eta!r}",
                parameter="eta",
                value=self.eta,
            )
        object.__setattr__(self, "eta", eta)
        if not isinstance(self.base_axes, (tuple, list)) or len(self.base_axes) != 3:
            raise DesignError(
                f"base_axes must hold 3 unit vectors, got {self.base_axes!r}",
                parameter="base_axes",
                value=self.base_axes,
            )
        axes = tuple(_unit(u, f"base_axes[{i}]") for i, u in enumerate(self.base_axes))
        object.__setattr__(self, "base_axes", axes)
        if not isinstance(self.dimensions, LinkDimensions):
            raise DesignError(
                f"dimensions must be a LinkDimensions, got {type(self.dimensions).__name__}",
                parameter="dimensions",
            )
        if not isinstance(self.name, str):
            raise DesignError(f"name must be a string, got {self.name!r}", parameter="name")
        # Platform rigidity: v_10 and v_20 must span a frame.
        v0 = self.v0
        if np.linalg.norm(np.cross(v0[0], v0[1])) < 1e-6:
            raise DesignError(
                "eta: the platform joint axes v_1 and v_2 are parallel, so the platform "
                f"is not determined (eta = {np.degrees(eta)} deg)",
                parameter="eta",
                value=eta,
            )
        self._home_axes()  # raises when the home configuration cannot be assembled
        if abs(self.home_det_a) < 1e-6:
            raise DesignError(
                "the home configuration is a type II singularity (det A = 0); change beta or eta",
                parameter="beta",
                value=self.beta,
            )

    # ------------------------------------------------------------------ presets
    @classmethod
    def prototype(cls) -> SPMDesign:
        """The 3D-printed coaxial prototype: a1 = 45, a2 = 90, b = 90 deg."""
        return cls.coaxial(45.0, 90.0, 90.0, name="prototype")

    @classmethod
    def coaxial(
        cls,
        alpha1_deg: float,
        alpha2_deg: float,
        beta_deg: float,
        *,
        dimensions: LinkDimensions | None = None,
        name: str = "coaxial",
    ) -> SPMDesign:
        """A coaxial SPM (u_i = [0, 0, -1]) with legs at 0, 120, 240 deg; angles in degrees."""
        for parameter, value in (
            ("alpha1", alpha1_deg),
            ("alpha2", alpha2_deg),
            ("beta", beta_deg),
        ):
            if not _is_number(value):
                raise DesignError(
                    f"{parameter} must be an angle in degrees, got {value!r}",
                    parameter=parameter,
                )
        return cls(
            alpha1=math.radians(alpha1_deg),
            alpha2=math.radians(alpha2_deg),
            beta=math.radians(beta_deg),
            dimensions=dimensions if dimensions is not None else LinkDimensions(),
            name=name,
        )

    @classmethod
    def agile_eye(cls) -> SPMDesign:
        """The Agile Eye: a1 = a2 = 90 deg, mutually orthogonal base and platform axes.

        The base axes are u_i = [sin g cos(eta_i + t), sin g sin(eta_i + t), -cos g]
        with g = acos(1/sqrt(3)), so they are mutually orthogonal, and t = -100 deg;
        beta = g makes the platform axes orthogonal too. The twist t (where the base
        triad stands about z relative to the platform's at home) only chooses which
        pose of the mechanism is home (theta = 0, R = identity). It is chosen so that
        the links do not collide at home and the inputs are regular there:

        * Every proximal link is a plate on one inner sphere and every distal link a
          plate on one outer sphere (:mod:`spm_pin.model.geometry`), so two links of a
          kind meet wherever their great-circle arcs cross, whatever their width and
          thickness. With t = 0 (this preset before), the distal arc w_1 -> v_1
          crosses the arc w_2 -> v_2 4 deg from w_1 and the proximal links rise 53 mm
          above O, through the platform plate: no link sizes free that home. With
          t = -100 deg the proximal arcs stay 36 deg apart and the distal arcs 54 deg
          apart at their closest, and the proximal links stay below the platform.
        * With t = 0 or -90 deg, inputs in round degrees (multiples of 15 deg) often
          place a w_i where the forward kinematics degenerates (all its modes singular,
          coinciding roots; theta = [60, 90, 120] deg is one for t = -90). With
          t = -100 deg none on a 5 deg grid does, and the study's input
          [60, 90, 120] deg is reachable in the home assembly mode.

        Link sizes: the prototype's :class:`LinkDimensions` (inner sphere 75 mm,
        outer sphere 90 mm, plates 30 and 25 mm wide and 8 mm thick, platform plate of
        70 mm radius 45 mm above O): a real robot of the prototype's build and
        servos, and sizes the home above clears. The nearest links at home are two
        proximal links, 15.3 mm apart (then a proximal and a distal link, 19.7 mm);
        the prototype's home clearance is 1.0 mm, set by its nested drive tubes,
        which the Agile Eye (one short shaft per leg) has not. The kinematics do not
        depend on these sizes.
        """
        # g = acos(1/sqrt(3)) = 54.7356... deg, kept to the 12 decimals a design file holds
        g = math.radians(_round_deg(math.acos(1.0 / math.sqrt(3.0))))
        eta = (0.0, math.radians(120.0), math.radians(240.0))
        twist = math.radians(-100.0)
        axes = tuple(
            (math.sin(g) * math.cos(e + twist), math.sin(g) * math.sin(e + twist), -math.cos(g))
            for e in eta
        )
        return cls(
            alpha1=math.pi / 2,
            alpha2=math.pi / 2,
            beta=g,
            eta=eta,
            base_axes=axes,
            dimensions=LinkDimensions(),
            name="agile_eye",
        )

    @classmethod
    def preset_names(cls) -> tuple[str, ...]:
        """The names :meth:`preset` and :meth:`from_spec` accept: ``("prototype", "agile_eye")``."""
        return tuple(_PRESETS)

    @classmethod
    def preset(cls, name: str) -> SPMDesign:
        """A preset by name: ``"prototype"`` or ``"agile_eye"``.

        Case does not matter and ``-`` stands for ``_`` (``"Agile-Eye"`` is the Agile Eye).

        Raises:
            DesignError: no preset has that name (the message lists the presets).
        """
        key = _preset_key(name)
        if key is None:
            raise DesignError(
                f"unknown preset {name!r}; choose one of {', '.join(_PRESETS)}",
                parameter="preset",
                value=name,
            )
        factory: Callable[[], SPMDesign] = getattr(cls, _PRESETS[key])
        return factory()

    @classmethod
    def from_spec(cls, spec: SPMDesign | str | os.PathLike[str] | None) -> SPMDesign:
        """A design from what a user gives: a design, a preset name or a TOML file.

        * an :class:`SPMDesign` is returned as it is; ``None`` gives the prototype;
        * a bare preset name (``"prototype"``, ``"agile_eye"``; any case, ``-`` for
          ``_``) gives the preset, even when a file of that name exists in the current
          directory: a bare name is never read as a file (write ``./agile_eye`` for the
          file);
        * anything else is the path of a design TOML file (:meth:`load`).

        Raises:
            DesignError: a bare name that is neither a preset nor an existing file (the
                message lists the presets), or a file whose design is impossible.
            FileFormatError: the file cannot be read or is not a valid design.
            InputError: ``spec`` is of another type.
        """
        if spec is None:
            return cls.prototype()
        if isinstance(spec, SPMDesign):
            return spec
        if not isinstance(spec, (str, os.PathLike)):
            raise InputError(
                "design must be an SPMDesign, a preset name or a design file, got "
                f"{type(spec).__name__}",
                argument="design",
                value=spec,
            )
        text = str(os.fspath(spec))
        bare = _is_bare_name(text)
        key = _preset_key(text) if bare else None
        if key is not None:
            return cls.preset(key)
        if bare and not Path(text).is_file():
            raise DesignError(
                f"unknown design {text!r}: not a preset ({', '.join(_PRESETS)}) and not a "
                "file either",
                parameter="design",
                value=text,
            )
        return cls.load(text)

    # ------------------------------------------------------------ derived data
    @cached_property
    def u(self) -> FloatArray:
        """Base joint axes u_i, rows, shape (3, 3)."""
        array = np.array(self.base_axes, dtype=float)
        array.setflags(write=False)
        return array

    @cached_property
    def v0(self) -> FloatArray:
        """Platform joint axes v_i0 in the platform frame, rows, shape (3, 3)."""
        eta = np.asarray(self.eta) - math.pi / 2
        sb, cb = math.sin(self.beta), math.cos(self.beta)
        array = np.stack([sb * np.cos(eta), sb * np.sin(eta), np.full(3, cb)], axis=1)
        array.setflags(write=False)
        return array

    @cached_property
    def w0(self) -> FloatArray:
        """Proximal-distal joint axes w_i at home (theta = 0), rows, shape (3, 3)."""
        array = self._home_axes()
        array.setflags(write=False)
        return array

    @cached_property
    def is_coaxial(self) -> bool:
        """True when the three base axes coincide (the platform can spin endlessly;
        computed once per design)."""
        return bool(np.allclose(self.u, self.u[0], atol=1e-12))

    @cached_property
    def home_det_a(self) -> float:
        """det A at home, A with rows a_i = w_i x v_i (its sign labels the home mode)."""
        return float(np.linalg.det(np.cross(self.w0, self.v0)))

    @cached_property
    def platform_combination(self) -> tuple[float, float, float]:
        """(a, b, d) with v_30 = a v_10 + b v_20 + d (v_10 x v_20)."""
        v0 = self.v0
        basis = np.stack([v0[0], v0[1], np.cross(v0[0], v0[1])], axis=1)
        a, b, d = np.linalg.solve(basis, v0[2])
        return float(a), float(b), float(d)

    def _home_axes(self) -> FloatArray:
        cos1, cos2 = math.cos(self.alpha1), math.cos(self.alpha2)
        rows = []
        for i in range(3):
            u, v = np.asarray(self.base_axes[i]), self.v0[i]
            c = float(u @ v)
            s2 = 1.0 - c * c
            x = (cos1 - c * cos2) / s2 if s2 > _GEOMETRY_TOL else math.nan
            y = (cos2 - c * cos1) / s2 if s2 > _GEOMETRY_TOL else math.nan
            z2 = (1.0 - x * x - y * y - 2 * x * y * c) / s2 if s2 > _GEOMETRY_TOL else math.nan
            if not z2 > _GEOMETRY_TOL:
                angle = math.degrees(math.acos(max(-1.0, min(1.0, c))))
                raise DesignError(
                    f"leg {i + 1} cannot be assembled at home: the angle between u_{i + 1} and "
                    f"v_{i + 1}0 is {angle:.6g} deg, but with alpha1 = "
                    f"{math.degrees(self.alpha1):.6g} and alpha2 = "
                    f"{math.degrees(self.alpha2):.6g} deg it must lie strictly between "
                    f"|alpha1 - alpha2| and min(alpha1 + alpha2, 360 - alpha1 - alpha2); "
                    "change alpha1, alpha2 or beta",
                    parameter="alpha2",
                    value=self.alpha2,
                )
            z = -math.sqrt(z2)  # b_ii = z (c^2 - 1) > 0: the home working mode
            rows.append(x * u + y * v + z * np.cross(u, v))
        return np.array(rows)

    # -------------------------------------------------------------------- TOML
    def to_dict(self) -> dict[str, Any]:
        """A plain dictionary (degrees for angles, metres for lengths), as in TOML."""
        return {
            "name": self.name,
            "kinematics": {
                "alpha1_deg": _round_deg(self.alpha1),
                "alpha2_deg": _round_deg(self.alpha2),
                "beta_deg": _round_deg(self.beta),
                "eta_deg": [_round_deg(e) for e in self.eta],
                "base_axes": [list(u) for u in self.base_axes],
            },
            "dimensions": {
                f.name: (
                    list(getattr(self.dimensions, f.name))
                    if isinstance(getattr(self.dimensions, f.name), tuple)
                    else getattr(self.dimensions, f.name)
                )
                for f in dataclasses.fields(LinkDimensions)
            },
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, source: str | None = None) -> SPMDesign:
        """Inverse of :meth:`to_dict`; unknown or missing keys raise FileFormatError."""
        known_top = {"name", "kinematics", "dimensions"}
        unknown = set(data) - known_top
        if unknown:
            raise FileFormatError(
                f"unknown key(s) {sorted(unknown)}; allowed: {sorted(known_top)}", path=source
            )
        kin = data.get("kinematics")
        if not isinstance(kin, Mapping):
            raise FileFormatError("missing table [kinematics]", path=source)
        required = {"alpha1_deg", "alpha2_deg", "beta_deg"}
        optional = {"eta_deg", "base_axes"}
        missing = required - set(kin)
        if missing:
            raise FileFormatError(f"[kinematics] lacks {sorted(missing)}", path=source)
        extra = set(kin) - required - optional
        if extra:
            raise FileFormatError(
                f"[kinematics] has unknown key(s) {sorted(extra)}; allowed: "
                f"{sorted(required | optional)}",
                path=source,
            )
        dims = data.get("dimensions", {})
        if not isinstance(dims, Mapping):
            raise FileFormatError("[dimensions] must be a table", path=source)
        dim_fields = {f.name for f in dataclasses.fields(LinkDimensions)}
        extra = set(dims) - dim_fields
        if extra:
            raise FileFormatError(
                f"[dimensions] has unknown key(s) {sorted(extra)}; allowed: {sorted(dim_fields)}",
                path=source,
            )

        def number(value: Any, key: str) -> float:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise FileFormatError(f"{key} must be a number, got {value!r}", path=source)
            return float(value)

        if not isinstance(data.get("name", ""), str):
            raise FileFormatError(f"name must be a string, got {data['name']!r}", path=source)
        try:
            dim_values: dict[str, Any] = {
                k: (
                    tuple(number(x, k) for x in v)
                    if isinstance(v, list) and k == "servo_size"
                    else number(v, k)
                )
                for k, v in dims.items()
            }
            kwargs: dict[str, Any] = {
                "alpha1": math.radians(number(kin["alpha1_deg"], "alpha1_deg")),
                "alpha2": math.radians(number(kin["alpha2_deg"], "alpha2_deg")),
                "beta": math.radians(number(kin["beta_deg"], "beta_deg")),
                "dimensions": LinkDimensions(**dim_values),
                "name": data.get("name", "custom"),
            }
            if "eta_deg" in kin:
                eta = kin["eta_deg"]
                if not isinstance(eta, list):
                    raise FileFormatError(f"eta_deg must be a list, got {eta!r}", path=source)
                kwargs["eta"] = tuple(math.radians(number(e, "eta_deg")) for e in eta)
            if "base_axes" in kin:
                axes = kin["base_axes"]
                if not isinstance(axes, list) or not all(isinstance(a, list) for a in axes):
                    raise FileFormatError(
                        f"base_axes must be a list of 3 vectors, got {axes!r}", path=source
                    )
                kwargs["base_axes"] = tuple(tuple(number(x, "base_axes") for x in a) for a in axes)
            return cls(**kwargs)
        except DesignError as exc:
            where = f"{source}: " if source else ""
            raise DesignError(f"{where}{exc}", parameter=exc.parameter, value=exc.value) from exc

    def to_toml(self) -> str:
        """The design as TOML text."""
        header = "# spm-pin design: angles in degrees, lengths in metres, masses in kg\n"
        return header + tomli_w.dumps(self.to_dict())

    def save(self, path: str | Path) -> Path:
        """Write the design to a TOML file and return its path."""
        path = Path(path)
        path.write_text(self.to_toml(), encoding="utf-8")
        return path

    @classmethod
    def from_toml(cls, text: str, *, source: str | None = None) -> SPMDesign:
        """Parse TOML text (see :meth:`to_toml`)."""
        return cls.from_dict(_parse_toml(text, source), source=source)

    @classmethod
    def load(cls, path: str | Path) -> SPMDesign:
        """Read a design from a TOML file written by :meth:`save` (or by hand)."""
        text, source = _read_text(path, "design file")
        return cls.from_toml(text, source=source)

    def summary(self) -> str:
        """One line describing the kinematic parameters."""
        kind = "coaxial" if self.is_coaxial else "general"
        return (
            f"{self.name} ({kind}): alpha1 = {math.degrees(self.alpha1):.6g} deg, "
            f"alpha2 = {math.degrees(self.alpha2):.6g} deg, "
            f"beta = {math.degrees(self.beta):.6g} deg"
        )
