"""Design problems with known answers, to validate studies against.

The dexterity at home in closed form. For a coaxial design with three-fold symmetry
(the legs 120 degrees apart) the three legs at home are copies of leg 1 turned about
the axis z, so every b_ii = (u_i x w_i0) . v_i0 is the same b and the rows
a_i = w_i0 x v_i0 of A are a_1 turned by 0, 120 and 240 degrees. Then

    A^T A = diag(p, p, q),  p = 3/2 |a_perp|^2,  q = 3 a_par^2,

(a_par the component of a_1 along z, a_perp the rest), J = A^-1 B = b A^-1, and the
dexterity 1/kappa_2(J) is sqrt(min(p, q) / max(p, q)): one leg's geometry fixes it.
It is 1 (isotropic) where tan^2 phi = |a_perp|^2 / a_par^2 = 2, phi the angle of a_1
from the axis (54.74 degrees).

With beta = 90 degrees (each v_i0 square to the platform's axis), write
w_10 = cos(alpha2) v + w_t t - cos(alpha1) z with t = z x v; unit length gives
w_t^2 = sin^2(alpha1) - cos^2(alpha2), and a_1 = w_10 x v = -w_t z - cos(alpha1) t:

    tan^2 phi = cos^2(alpha1) / (sin^2(alpha1) - cos^2(alpha2)),

so the dexterity at home is sqrt(min(r, 1/r)) with r = tan^2 phi / 2, and the
isotropic designs have cos^2(alpha2) = (3 sin^2(alpha1) - 1) / 2 (alpha1 at least
35.26 degrees): for alpha1 = 45 degrees, alpha2 = 60 or 120 degrees.

A published optimum. Gosselin and Angeles (1989, "The optimum kinematic design of a
spherical three-degree-of-freedom parallel manipulator", ASME J. Mech. Trans. Autom.
Des. 111(2):202-207) optimized the conditioning of the spherical 3-RRR; the design
built from it, the Agile Eye (Gosselin and Hamel, ICRA 1994: alpha1 = alpha2 = 90
degrees, mutually orthogonal base axes and platform axes), has a Jacobian of
condition number 1 at its reference configuration. There every platform axis is
opposite a base axis, R v_i0 = -u_(i-1) (indices mod 3). Write w_i = cos(alpha1) u_i +
y u_(i+1) - cos(alpha2) u_(i-1), with y^2 = sin^2(alpha1) - cos^2(alpha2) (y's sign
is the leg's working mode). In the base triad, a_i = w_i x v_i has the components
+-(-y, x, 0) cyclically shifted (x = cos alpha1), and b_ii = -+ y, so A is circulant,
B a multiple of the identity, and the singular values of J are those of A up to a
common factor: |x w^k - y| for the cube roots of unity w^k. Hence

    dexterity = sqrt(min(l0, l1) / max(l0, l1)),  l0 = (x - y)^2,  l1 = x^2 + x y + y^2,

which is 1 exactly where x y = 0: alpha1 = 90 degrees, whatever alpha2 (y = 0 is a
serial singularity). The Agile Eye lies on that line; there J = [u_1 u_2 u_3]: each
input turns the platform about its own axis.
"""

from __future__ import annotations

import math

import numpy as np

from ..design import SPMDesign
from ..errors import InputError, SPMError, UnreachableError
from ..kinematics import inverse_kinematics, jacobian

__all__ = [
    "ISOTROPIC_PHI",
    "find_orthogonal_optimum",
    "home_dexterity",
    "home_dexterity_right_angle",
    "isotropic_alpha2",
    "orthogonal_design",
    "orthogonal_reference_dexterity",
    "reference_dexterity",
    "reference_orientation",
]

#: The angle of a_1 = w_10 x v_10 from the axis at which the home pose is isotropic:
#: arctan(sqrt(2)) [rad].
ISOTROPIC_PHI = math.atan(math.sqrt(2.0))


def _symmetric(design: SPMDesign) -> None:
    eta = np.mod(np.asarray(design.eta, dtype=float) - design.eta[0], 2.0 * math.pi)
    spaced = np.allclose(np.sort(eta), np.radians([0.0, 120.0, 240.0]), atol=1e-12)
    if not design.is_coaxial or not spaced:
        raise InputError(
            "the closed form needs a coaxial design with its legs 120 deg apart "
            f"(got {design.name!r}: coaxial={design.is_coaxial}, "
            f"eta={np.degrees(design.eta).round(3).tolist()} deg)",
            argument="design",
        )


def home_dexterity(design: SPMDesign | str | None = None) -> float:
    """The dexterity 1/kappa_2(J) at home from leg 1's geometry alone (see the
    module): sqrt(min(p, q) / max(p, q)) with p = 3/2 |a_perp|^2, q = 3 a_par^2.

    Raises:
        InputError: a design that is not coaxial with its legs 120 deg apart.
    """
    spm_design = SPMDesign.from_spec(design)
    _symmetric(spm_design)
    axis = spm_design.u[0] / np.linalg.norm(spm_design.u[0])
    a = np.cross(spm_design.w0[0], spm_design.v0[0])
    along = float(a @ axis)
    across = float(a @ a) - along * along
    p, q = 1.5 * across, 3.0 * along * along
    return math.sqrt(min(p, q) / max(p, q))


def home_dexterity_right_angle(alpha1: float, alpha2: float) -> float:
    """The dexterity at home of a coaxial, symmetric design with beta = 90 deg, from
    its link angles [rad] alone (see the module).

    Raises:
        InputError: link angles with which leg 1 cannot be assembled at home.
    """
    rest = math.sin(alpha1) ** 2 - math.cos(alpha2) ** 2
    if not rest > 0.0 or not math.cos(alpha1) != 0.0:
        raise InputError(
            f"alpha1 = {math.degrees(alpha1):.3f} and alpha2 = {math.degrees(alpha2):.3f} deg "
            "cannot be assembled at home with beta = 90 deg (sin^2 alpha1 > cos^2 alpha2 "
            "is needed, and alpha1 != 90 deg)",
            argument="alpha2",
        )
    ratio = math.cos(alpha1) ** 2 / rest / 2.0
    return math.sqrt(min(ratio, 1.0 / ratio))


def isotropic_alpha2(alpha1: float) -> tuple[float, float]:
    """The two distal link angles alpha2 [rad] (below and above 90 deg) that make the
    home pose isotropic (dexterity 1) for a coaxial, symmetric design with beta = 90
    deg and proximal link angle ``alpha1`` [rad]: cos^2(alpha2) = (3 sin^2(alpha1) -
    1) / 2.

    Raises:
        InputError: alpha1 below arctan(1 / sqrt(2)) = 35.26 deg (no isotropic home) or
            not below 90 deg.
    """
    value = (3.0 * math.sin(alpha1) ** 2 - 1.0) / 2.0
    if not 0.0 <= value < 1.0 or not 0.0 < alpha1 < math.pi / 2:
        raise InputError(
            f"no isotropic home pose with alpha1 = {math.degrees(alpha1):.3f} deg: it needs "
            "35.26 <= alpha1 < 90 deg",
            argument="alpha1",
        )
    low = math.acos(math.sqrt(value))
    return low, math.pi - low


def orthogonal_design(alpha1_deg: float, alpha2_deg: float) -> SPMDesign:
    """The Agile Eye's arrangement (mutually orthogonal base axes and platform axes)
    with link angles ``alpha1_deg`` and ``alpha2_deg`` [deg].

    Raises:
        InputError: an angle that is not a finite number in (0, 180) deg.
        DesignError: link angles with which the legs cannot be assembled at home.
    """
    for name, value in (("alpha1_deg", alpha1_deg), ("alpha2_deg", alpha2_deg)):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not 0.0 < value < 180.0
        ):
            raise InputError(
                f"{name} must be an angle in (0, 180) deg, got {value!r}", argument=name
            )
    base = SPMDesign.agile_eye()
    return SPMDesign(
        alpha1=math.radians(alpha1_deg),
        alpha2=math.radians(alpha2_deg),
        beta=base.beta,
        eta=base.eta,
        base_axes=base.base_axes,
        dimensions=base.dimensions,
        name=f"orthogonal_{alpha1_deg:g}_{alpha2_deg:g}",
    )


def reference_orientation(design: SPMDesign | str | None = None) -> np.ndarray:
    """The reference configuration of a design with mutually orthogonal base axes and
    platform axes: the rotation R with R v_i0 = -u_(i-1) (indices mod 3), where every
    platform axis is opposite a base axis (see the module).

    Raises:
        InputError: base or platform axes that are not mutually orthogonal, or triads
            of which no rotation makes every platform axis opposite a base axis.
    """
    spm_design = SPMDesign.from_spec(design)
    u = spm_design.u / np.linalg.norm(spm_design.u, axis=1, keepdims=True)
    v = spm_design.v0 / np.linalg.norm(spm_design.v0, axis=1, keepdims=True)
    for name, triad in (("base", u), ("platform", v)):
        if not np.allclose(triad @ triad.T, np.eye(3), atol=1e-9):
            raise InputError(
                f"design {spm_design.name!r}: its {name} axes are not mutually orthogonal",
                argument="design",
            )
    rotation = -sum(np.outer(u[(i - 1) % 3], v[i]) for i in range(3))
    if np.linalg.det(rotation) < 0.0:
        raise InputError(
            f"design {spm_design.name!r}: its base and platform triads have opposite "
            "handedness, so no rotation makes every platform axis opposite a base axis",
            argument="design",
        )
    return np.asarray(rotation, dtype=float)


def reference_dexterity(design: SPMDesign | str | None = None) -> float:
    """The library's dexterity 1/kappa_2(J) at :func:`reference_orientation`, in the
    home working mode (inverse kinematics, then the Jacobian).

    Raises:
        InputError: see :func:`reference_orientation`.
        UnreachableError: a leg that cannot reach the reference orientation.
    """
    spm_design = SPMDesign.from_spec(design)
    solution = inverse_kinematics(reference_orientation(spm_design), spm_design)
    if not bool(np.all(solution.reachable)):
        raise UnreachableError(f"design {spm_design.name!r} cannot reach its reference orientation")
    return float(jacobian(solution.theta, spm_design).dexterity)


def orthogonal_reference_dexterity(alpha1: float, alpha2: float, y_sign: float = 1.0) -> float:
    """The dexterity at the reference configuration of the orthogonal arrangement in
    closed form (see the module): x = cos(alpha1), y = y_sign sqrt(sin^2(alpha1) -
    cos^2(alpha2)) = w_i . u_(i+1), sqrt(min(l0, l1) / max(l0, l1)) with l0 = (x - y)^2
    and l1 = x^2 + x y + y^2. Angles in radians.

    Raises:
        InputError: link angles with which a leg cannot reach the reference
            configuration (sin^2 alpha1 < cos^2 alpha2), or a ``y_sign`` not +-1.
    """
    rest = math.sin(alpha1) ** 2 - math.cos(alpha2) ** 2
    if y_sign not in (1.0, -1.0) or not rest > 0.0:
        raise InputError(
            f"alpha1 = {math.degrees(alpha1):.3f}, alpha2 = {math.degrees(alpha2):.3f} deg, "
            f"y_sign = {y_sign!r}: the legs reach the reference configuration only with "
            "sin^2 alpha1 > cos^2 alpha2, and y_sign is +1 or -1",
            argument="alpha2",
        )
    x, y = math.cos(alpha1), y_sign * math.sqrt(rest)
    low, high = sorted(((x - y) ** 2, x * x + x * y + y * y))
    return math.sqrt(low / high)


def find_orthogonal_optimum(
    n_trials: int = 80,
    *,
    seed: int = 0,
    bounds_deg: tuple[float, float] = (60.0, 120.0),
) -> tuple[float, float, float]:
    """Search the link angles of the orthogonal arrangement for the largest
    :func:`reference_dexterity` with Optuna's TPE sampler (the single-objective
    sampler of :func:`~spm_pin.optimize.run_study`), both angles within
    ``bounds_deg``. Designs that cannot be built or cannot reach the reference
    orientation score 0.

    Returns:
        ``(alpha1_deg, alpha2_deg, dexterity)`` of the best trial.

    Raises:
        InputError: ``n_trials`` not a positive integer or bounds not within (0, 180).
    """
    from ._progress import quiet_optuna as _quiet_optuna

    try:
        low, high = (float(value) for value in bounds_deg)
    except (TypeError, ValueError):
        low = high = math.nan  # refused below, with the reason
    if (
        isinstance(n_trials, bool)
        or not isinstance(n_trials, int)
        or n_trials < 1
        or not 0.0 < low < high < 180.0
    ):
        raise InputError(
            f"n_trials must be a positive integer and 0 < low < high < 180, got "
            f"{n_trials!r} and {bounds_deg!r}",
            argument="n_trials",
        )
    import optuna

    def objective(trial: optuna.Trial) -> float:
        alpha1 = trial.suggest_float("alpha1_deg", low, high)
        alpha2 = trial.suggest_float("alpha2_deg", low, high)
        try:
            return reference_dexterity(orthogonal_design(alpha1, alpha2))
        except SPMError:
            return 0.0

    with _quiet_optuna():
        study = optuna.create_study(
            direction="maximize", sampler=optuna.samplers.TPESampler(seed=seed)
        )
        study.optimize(objective, n_trials=n_trials)
    best = study.best_trial
    return (
        float(best.params["alpha1_deg"]),
        float(best.params["alpha2_deg"]),
        float(study.best_value),
    )
