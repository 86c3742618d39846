r"""Workspace maps of a coaxial SPM: reachability, singularities, dexterity, collisions.

Adding one angle c to all three inputs of a coaxial SPM only turns the platform
about the common axis (by -c), so every quantity mapped here depends on the gaps
between neighbouring proximal links alone (docs/conventions.md). With w_i at azimuth
eta_i - theta_i, the gap from link i to the next one counterclockwise is

    D12 = (eta_2 - theta_2) - (eta_1 - theta_1),  D23 = (eta_3 - theta_3) - (eta_2 - theta_2),
    D31 = 360 deg - D12 - D23

(for the prototype D12 = 120 + theta_1 - theta_2, ...). A map samples the plane
(D12, D23) and evaluates the input theta = (0, eta_2 - eta_1 - D12,
eta_3 - eta_1 - D12 - D23) at each point. Every kinematic quantity is the same at
any other torsion; so are the collisions of every link pair except those with the
base, whose hub (the only base part within reach of the moving links) is a faceted
cylinder, so they change by at most its facet depth (0.04 mm for the prototype).

At each point (home assembly mode):

* ``reachable``: a home-mode assembly exists;
* ``type_i`` / ``type_ii``, ``singularity_margin``, ``det_a``: singularity data of
  :func:`spm_pin.jacobian` (type I bounds the home-mode region; type II does not
  occur inside it for the prototype);
* ``dexterity``: 1/kappa_2(J);
* ``collision``, ``pair_mask``: self-collision (:mod:`spm_pin.collision`) in the
  assembly mode of the library's rule (:func:`spm_pin.select_assembly`): where no
  home-mode assembly exists, in the real mode nearest to it, as ``spm collide``
  reports; with no real assembly, only the proximal links, placed by theta alone;
* ``clearance``: a lower bound of the distance between the links at the point, from
  collision checks at a ladder of margins (the largest level at which nothing
  collides), leaving out the parts whose distance does not depend on the
  configuration (the nested drive tubes);
* ``safe``: reachable, dexterity >= ``min_dexterity`` and no collision at ``margin``;
* ``tilt``, ``azimuth``, ``torsion``: tilt-and-torsion angles of the platform, R =
  Rz(azimuth) Ry(tilt) Rz(-azimuth) Rz(torsion). Tilt and azimuth - torsion do not
  depend on the torsion of the inputs: they describe the orientation workspace.

The points are evaluated in chunks through a ``concurrent.futures``-style executor
(anything with ``submit(fn, *args)`` returning futures), so a process pool, a Dask
``client.get_executor()`` or a Ray executor run the same code; results are put back
in point order, so a map does not depend on the executor.
"""

from __future__ import annotations

import concurrent.futures
import csv
import dataclasses
import itertools
import json
import math
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .design import SPMDesign
from .errors import FileFormatError, InputError
from .kinematics import forward_kinematics, jacobian, select_assembly
from .kinematics._common import check_design

__all__ = [
    "CLEARANCE_LADDER",
    "MAP_FIELDS",
    "WorkspaceMap",
    "WorkspaceSettings",
    "gap_inputs",
    "gaps_from_theta",
    "tilt_torsion",
    "workspace_map",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

#: Margins at which the clearance is bracketed [m]: the clearance field reads the
#: largest level at which no link pair collides (a lower bound of the distance).
#: (Larger margins make each check slower: the BVHs then have more to look at.)
CLEARANCE_LADDER: tuple[float, ...] = (
    0.0,
    0.00025,
    0.0005,
    0.00075,
    0.001,
    0.0015,
    0.002,
    0.003,
    0.004,
    0.005,
)

#: Per-point fields of a :class:`WorkspaceMap` (all of shape (N,) unless noted).
MAP_FIELDS: tuple[str, ...] = (
    "d12_deg",
    "d23_deg",
    "d31_deg",
    "reachable",
    "type_i",
    "type_ii",
    "singularity_margin",
    "det_a",
    "dexterity",
    "dexterity_ga",
    "collision",
    "pair_mask",
    "clearance",
    "safe",
    "tilt_deg",
    "azimuth_deg",
    "torsion_deg",
)

#: Points per chunk sent to the executor by default.
DEFAULT_CHUNK = 2048


@dataclasses.dataclass(frozen=True)
class WorkspaceSettings:
    """What a map computes (picklable: it travels to the workers).

    Attributes:
        margin: Safety margin of the safe set [m].
        min_dexterity: Smallest dexterity (1/kappa_2(J)) of the safe set.
        clearance: Compute the clearance field (several collision checks per point).
        ladder: Margins of the clearance field [m], increasing from 0.
    """

    margin: float = 0.0
    min_dexterity: float = 0.2
    clearance: bool = True
    ladder: tuple[float, ...] = CLEARANCE_LADDER

    def __post_init__(self) -> None:
        _check_number("margin", self.margin, 0.0, 1.0)
        _check_number("min_dexterity", self.min_dexterity, 0.0, 1.0)
        if not isinstance(self.clearance, (bool, np.bool_)):
            raise InputError(
                f"clearance must be True or False, got {self.clearance!r}",
                argument="clearance",
                value=self.clearance,
            )


# ---------------------------------------------------------------------- gaps
def _coaxial(design: SPMDesign | str | None) -> SPMDesign:
    design = check_design(design)
    if not design.is_coaxial:
        raise InputError(
            f"workspace maps over the proximal-link gaps need a coaxial design (all u_i "
            f"equal); design {design.name!r} is not coaxial",
            argument="design",
            value=design.name,
        )
    return design


def gap_inputs(
    d12_deg: npt.ArrayLike, d23_deg: npt.ArrayLike, design: SPMDesign | str | None = None
) -> FloatArray:
    """Input angles [rad] with theta_1 = 0 and the given gaps [deg] (broadcast).

    theta_2 = eta_2 - eta_1 - D12, theta_3 = eta_3 - eta_1 - D12 - D23.

    Raises:
        InputError: a non-coaxial design; gaps that are not finite numbers.
    """
    design = _coaxial(design)
    try:
        d12 = np.asarray(d12_deg, dtype=float)
        d23 = np.asarray(d23_deg, dtype=float)
        d12, d23 = np.broadcast_arrays(d12, d23)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"gaps must be numbers [deg] of broadcastable shapes, got {d12_deg!r}, {d23_deg!r}",
            argument="gaps",
            value=(d12_deg, d23_deg),
        ) from exc
    if not (np.all(np.isfinite(d12)) and np.all(np.isfinite(d23))):
        raise InputError("gaps must be finite [deg]", argument="gaps", value=(d12_deg, d23_deg))
    eta = np.degrees(np.asarray(design.eta, dtype=float))
    theta2 = eta[1] - eta[0] - d12
    theta3 = eta[2] - eta[0] - d12 - d23
    result: FloatArray = np.radians(np.stack([np.zeros_like(d12), theta2, theta3], axis=-1))
    return result


def gaps_from_theta(theta: npt.ArrayLike, design: SPMDesign | str | None = None) -> FloatArray:
    """Gaps (D12, D23, D31) [deg] of input angles theta [rad], (..., 3); they sum to 360.

    D12 and D23 are wrapped into (-180, 540] around the home gaps so that small
    motions never jump; D31 = 360 - D12 - D23.
    """
    design = _coaxial(design)
    from .kinematics._common import as_theta

    angles = np.degrees(as_theta(theta))
    eta = np.degrees(np.asarray(design.eta, dtype=float))
    azimuth = eta - angles  # of w_i [deg]
    home = np.array([eta[1] - eta[0], eta[2] - eta[1]])
    raw = np.stack([azimuth[..., 1] - azimuth[..., 0], azimuth[..., 2] - azimuth[..., 1]], -1)
    wrapped = home + np.mod(raw - home + 180.0, 360.0) - 180.0
    return np.concatenate([wrapped, 360.0 - wrapped.sum(axis=-1, keepdims=True)], axis=-1)


def tilt_torsion(R: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    r"""Tilt-and-torsion angles of platform rotations [rad].

    R = Rz(phi) Ry(tilt) Rz(-phi) Rz(torsion): the platform normal n = R e_z has
    tilt = arccos(n_z) (computed as atan2(|n_xy|, n_z)) and azimuth
    phi = atan2(n_y, n_x) (0 where tilt = 0), and
    Rz(torsion) = (Rz(phi) Ry(tilt) Rz(-phi))^T R.

    Args:
        R: Rotations (..., 3, 3).

    Returns:
        (tilt in [0, pi], azimuth in (-pi, pi], torsion in (-pi, pi]), each (...).
    """
    M = np.asarray(R, dtype=float)
    n = M[..., :, 2]
    horizontal = np.hypot(n[..., 0], n[..., 1])
    tilt = np.arctan2(horizontal, n[..., 2])  # arccos(n_z), accurate near 0 and pi
    azimuth = np.where(horizontal > 1e-12, np.arctan2(n[..., 1], n[..., 0]), 0.0)
    c, s = np.cos(azimuth), np.sin(azimuth)
    ct, st = np.cos(tilt), np.sin(tilt)
    # T = Rz(phi) Ry(tilt) Rz(-phi); torsion from the first column of T^T R.
    T = np.empty(M.shape)
    T[..., 0, 0] = c * c * ct + s * s
    T[..., 0, 1] = c * s * (ct - 1.0)
    T[..., 0, 2] = c * st
    T[..., 1, 0] = c * s * (ct - 1.0)
    T[..., 1, 1] = s * s * ct + c * c
    T[..., 1, 2] = s * st
    T[..., 2, 0] = -c * st
    T[..., 2, 1] = -s * st
    T[..., 2, 2] = ct
    Z = np.swapaxes(T, -1, -2) @ M
    torsion = np.arctan2(Z[..., 1, 0], Z[..., 0, 0])
    return tilt, azimuth, torsion


# ------------------------------------------------------------------- workers
_LOCAL = threading.local()
#: Links placed by theta alone (no loop closure needed).
_THETA_LINKS = frozenset({"base", "proximal_1", "proximal_2", "proximal_3"})


def _checker(design: SPMDesign) -> Any:
    """This thread's robot checker for ``design`` (built once per thread and design)."""
    cache: dict[SPMDesign, Any] | None = getattr(_LOCAL, "checkers", None)
    if cache is None:
        cache = {}
        _LOCAL.checkers = cache
    if design not in cache:
        from .collision import CollisionChecker
        from .model.robot import build_robot

        cache[design] = CollisionChecker(build_robot(design))
    return cache[design]


def _evaluate(
    design: SPMDesign, theta: FloatArray, settings: WorkspaceSettings
) -> dict[str, npt.NDArray[Any]]:
    """Every field but the gaps at inputs theta (n, 3): the work of one chunk."""
    from .collision import LINK_PAIRS

    checker = _checker(design)
    robot = checker.robot
    n = theta.shape[0]
    fk = forward_kinematics(theta, design)
    reachable = np.asarray(fk.reachable, dtype=bool)
    jac = jacobian(theta, design, R=np.where(reachable[:, None, None], fk.R, np.eye(3)))
    out: dict[str, npt.NDArray[Any]] = {
        "reachable": reachable,
        "type_i": jac.type_i & reachable,
        "type_ii": jac.type_ii & reachable,
        "singularity_margin": np.where(reachable, jac.singularity_margin, np.nan),
        "det_a": np.where(reachable, jac.det_a, np.nan),
        "dexterity": np.where(reachable, jac.dexterity, np.nan),
        "dexterity_ga": np.where(reachable, jac.dexterity_ga, np.nan),
    }
    tilt, azimuth, torsion = tilt_torsion(np.where(reachable[:, None, None], fk.R, np.nan))
    out["tilt_deg"] = np.degrees(tilt)
    out["azimuth_deg"] = np.degrees(azimuth)
    out["torsion_deg"] = np.degrees(torsion)

    pair_mask = np.zeros(n, dtype=np.int64)
    collision = np.zeros(n, dtype=bool)
    unsafe_margin = np.zeros(n, dtype=bool)
    clearance = np.full(n, np.nan)
    bit = {pair: 1 << k for k, pair in enumerate(LINK_PAIRS)}
    plan0 = checker._plan(0.0)
    plan_m = checker._plan(settings.margin)
    # The library's rule (spm.select_assembly): without a home-mode assembly the real
    # mode nearest to it is checked; with no real assembly, only the links theta places.
    placed = [p for p in LINK_PAIRS if p[0] in _THETA_LINKS and p[1] in _THETA_LINKS]
    plan_placed = checker._plan(0.0, pairs=placed)
    ladder = settings.ladder
    q = np.zeros((n, robot.model.nq))
    q[:, robot.actuated_q_idx] = theta
    R = fk.R.copy()
    assembled = reachable.copy()
    if not np.all(reachable):
        rest = np.nonzero(~reachable)[0]
        other = select_assembly(theta[rest], design)
        R[rest] = other.R
        assembled[rest] = other.exists
    if np.any(assembled):
        # q from the platform rotations just solved (checked against each leg).
        q[assembled] = robot._configuration_from_rotation(theta[assembled], R[assembled])
    for k in range(n):
        pairs = checker._check(q[k], plan0 if assembled[k] else plan_placed, False)
        mask = 0
        for pair in pairs:
            mask |= bit[pair]
        pair_mask[k] = mask
        collision[k] = bool(pairs)
        if not reachable[k]:
            continue
        if collision[k]:
            unsafe_margin[k] = True
            clearance[k] = 0.0
            continue
        if settings.margin > 0.0:
            unsafe_margin[k] = bool(checker._check(q[k], plan_m, True))
        if settings.clearance:
            clearance[k] = _ladder_level(checker, q[k], ladder)
    out["collision"] = collision
    out["pair_mask"] = pair_mask
    out["clearance"] = clearance
    dexterity_ok = np.where(reachable, out["dexterity"], -1.0) >= settings.min_dexterity
    out["safe"] = reachable & dexterity_ok & ~unsafe_margin
    return out


def _ladder_level(checker: Any, q: FloatArray, ladder: Sequence[float]) -> float:
    """Largest ladder margin at which nothing collides (configuration-dependent parts
    only); free at ladder[0] is known. Bisection over the levels."""
    low, high = 0, len(ladder)  # free at ladder[low]; collides at ladder[high] (or beyond)
    while high - low > 1:
        middle = (low + high) // 2
        if checker._check(q, checker._plan(ladder[middle], False), True):
            high = middle
        else:
            low = middle
    return float(ladder[low])


def _chunk_task(
    design: SPMDesign, theta: FloatArray, settings: WorkspaceSettings
) -> dict[str, npt.NDArray[Any]]:
    """Module-level (picklable) entry point of one chunk."""
    return _evaluate(design, theta, settings)


# ------------------------------------------------------------------------ map
@dataclasses.dataclass(frozen=True)
class WorkspaceMap:
    """A workspace map: per-point fields over the gap plane.

    Attributes:
        design: The SPM.
        settings: What was computed.
        theta: Input angles of the points [rad], (N, 3) (theta_1 = 0).
        fields: Per-point arrays, keys :data:`MAP_FIELDS` (``pair_mask``: bit k set
            when ``LINK_PAIRS[k]`` collides; ``clearance`` NaN where unreachable and
            0 where links collide; angles in degrees, NaN where unreachable).
        grid: For a grid map, (d12 axis, d23 axis) [deg] and the (row, column) of each
            point in the (len(d12), len(d23)) grid; None for sampled points.
        step_deg: Grid step [deg] (None for sampled points).
        seed: Seed of sampled points (None for a grid).
    """

    design: SPMDesign
    settings: WorkspaceSettings
    theta: FloatArray
    fields: dict[str, npt.NDArray[Any]]
    grid: tuple[FloatArray, FloatArray, IntArray] | None
    step_deg: float | None
    seed: int | None

    def __len__(self) -> int:
        return int(self.theta.shape[0])

    def __getitem__(self, name: str) -> npt.NDArray[Any]:
        return self.fields[name]

    def image(self, name: str) -> FloatArray:
        """A field as a 2D grid (rows d12, columns d23; NaN outside the domain).

        Raises:
            InputError: a sampled (not gridded) map, or an unknown field.
        """
        if self.grid is None:
            raise InputError("image needs a grid map, this one has sampled points", argument="name")
        if name not in self.fields:
            raise InputError(
                f"name must be one of {list(self.fields)}, got {name!r}",
                argument="name",
                value=name,
            )
        d12, d23, index = self.grid
        image = np.full((d12.size, d23.size), np.nan)
        image[index[:, 0], index[:, 1]] = self.fields[name].astype(float)
        return image

    def pair_collides(self, pair: tuple[str, str]) -> BoolArray:
        """Per point: whether link ``pair`` collides."""
        from .collision import LINK_PAIRS

        key = tuple(pair)
        if key not in LINK_PAIRS:
            key = key[::-1]
        if key not in LINK_PAIRS:
            raise InputError(
                f"pair must be one of {list(LINK_PAIRS)}, got {pair!r}", argument="pair", value=pair
            )
        result: BoolArray = (self.fields["pair_mask"] >> LINK_PAIRS.index(key)) & 1 == 1
        return result

    def summary(self) -> dict[str, Any]:
        """Fractions of the map and orientation-workspace figures (plain data)."""
        f = self.fields
        n = max(len(self), 1)
        reachable = f["reachable"]
        safe = f["safe"]
        tilt = f["tilt_deg"]
        psi = f["azimuth_deg"] - f["torsion_deg"]
        sectors = np.full(72, np.nan)
        if np.any(safe):
            bins = np.floor(np.mod(psi[safe], 360.0) / 5.0).astype(int) % 72
            for k in range(72):
                inside = tilt[safe][bins == k]
                if inside.size:
                    sectors[k] = float(inside.max())
        counts = {}
        from .collision import LINK_PAIRS

        for k, pair in enumerate(LINK_PAIRS):
            hits = int(np.count_nonzero((f["pair_mask"] >> k) & 1))
            if hits:
                counts["-".join(pair)] = hits
        n_reachable = int(np.count_nonzero(reachable))
        n_colliding = int(np.count_nonzero(f["collision"] & reachable))
        return {
            "points": len(self),
            "reachable_fraction": n_reachable / n,
            "collision_fraction_of_reachable": n_colliding / max(n_reachable, 1),
            "safe_fraction": int(np.count_nonzero(safe)) / n,
            "type_i_points": int(np.count_nonzero(f["type_i"])),
            "type_ii_points": int(np.count_nonzero(f["type_ii"])),
            "max_dexterity": float(np.nanmax(f["dexterity"])) if np.any(reachable) else None,
            "max_safe_tilt_deg": float(np.max(tilt[safe])) if np.any(safe) else None,
            "safe_tilt_every_direction_deg": (
                float(np.min(sectors)) if np.all(np.isfinite(sectors)) else None
            ),
            "colliding_points_by_pair": counts,
            "margin_m": self.settings.margin,
            "min_dexterity": self.settings.min_dexterity,
        }

    # ------------------------------------------------------------- output
    def save(self, folder: str | Path, *, plots: bool = True) -> dict[str, Path]:
        """Write the map to a folder: ``workspace.npz`` (every field, the inputs, the
        grid and the settings), ``workspace.csv`` (one row per point),
        ``summary.json`` and, with ``plots``, PNG figures (:meth:`plot`).

        Returns:
            File kind -> path.

        Raises:
            InputError: plots requested without matplotlib.
        """
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        written: dict[str, Path] = {}
        arrays: dict[str, Any] = dict(self.fields)
        arrays["theta"] = self.theta
        if self.grid is not None:
            arrays["grid_d12_deg"], arrays["grid_d23_deg"], arrays["grid_index"] = self.grid
        arrays["meta"] = np.array(json.dumps(self._meta()))
        written["npz"] = out / "workspace.npz"
        np.savez_compressed(written["npz"], **arrays)
        written["csv"] = out / "workspace.csv"
        with written["csv"].open("w", newline="", encoding="utf-8") as stream:
            writer = csv.writer(stream)
            writer.writerow(["theta1_rad", "theta2_rad", "theta3_rad", *MAP_FIELDS])
            columns = [self.fields[name] for name in MAP_FIELDS]
            for k in range(len(self)):
                row: list[Any] = [f"{v:.12g}" for v in self.theta[k]]
                for value in (column[k] for column in columns):
                    if isinstance(value, (bool, np.bool_, int, np.integer)):
                        row.append(int(value))
                    else:
                        row.append("" if not np.isfinite(value) else f"{float(value):.9g}")
                writer.writerow(row)
        written["summary"] = out / "summary.json"
        written["summary"].write_text(
            json.dumps({**self._meta(), "summary": self.summary()}, indent=2) + "\n",
            encoding="utf-8",
        )
        if plots:
            written.update(self.plot(out))
        return written

    def _meta(self) -> dict[str, Any]:
        return {
            "design": self.design.name,
            "design_toml": self.design.to_toml(),
            "step_deg": self.step_deg,
            "seed": self.seed,
            "settings": dataclasses.asdict(self.settings),
        }

    def plot(self, folder: str | Path) -> dict[str, Path]:
        """PNG figures: ``gap_map.png`` (six panels over the gap plane) and
        ``orientation.png`` (tilt against azimuth - torsion).

        Raises:
            InputError: matplotlib is missing (``pip install spm-pin[plot]``).
        """
        plt = _pyplot()
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        written = {"gap_map": out / "gap_map.png", "orientation": out / "orientation.png"}
        f = self.fields
        panels = (
            ("reachable", "home-mode assembly", "Greens"),
            ("singularity_margin", "singularity margin", "viridis"),
            ("dexterity", "dexterity 1/kappa(J)", "viridis"),
            ("collision", "self-collision", "Reds"),
            ("clearance", "clearance [mm]", "magma"),
            ("safe", "safe set", "Blues"),
        )
        figure, axes = plt.subplots(2, 3, figsize=(15, 9.5), constrained_layout=True)
        for axis, (name, title, cmap) in zip(axes.flat, panels, strict=True):
            values = f[name].astype(float) * (1e3 if name == "clearance" else 1.0)
            if self.grid is not None:
                d12, d23, _ = self.grid
                image = self.image(name) * (1e3 if name == "clearance" else 1.0)
                extent = (d23[0], d23[-1], d12[0], d12[-1])
                shown = axis.imshow(
                    image,
                    origin="lower",
                    extent=extent,
                    cmap=cmap,
                    aspect="equal",
                    interpolation="nearest",
                )
            else:
                shown = axis.scatter(f["d23_deg"], f["d12_deg"], c=values, s=4, cmap=cmap)
            figure.colorbar(shown, ax=axis, shrink=0.8)
            axis.set_title(title)
            axis.set_xlabel("D23 [deg]")
            axis.set_ylabel("D12 [deg]")
        figure.suptitle(
            f"{self.design.name}: maps over the proximal-link gaps (theta_1 = 0; "
            f"margin {self.settings.margin * 1e3:g} mm, dexterity >= "
            f"{self.settings.min_dexterity:g})"
        )
        figure.savefig(written["gap_map"], dpi=110)
        plt.close(figure)

        figure = plt.figure(figsize=(7.5, 7), constrained_layout=True)
        axis = figure.add_subplot(projection="polar")
        psi = np.radians(f["azimuth_deg"] - f["torsion_deg"])
        reachable, safe = f["reachable"], f["safe"]
        axis.scatter(
            psi[reachable & ~safe],
            f["tilt_deg"][reachable & ~safe],
            s=1,
            c="0.75",
            label="reachable, not safe",
        )
        axis.scatter(psi[safe], f["tilt_deg"][safe], s=1, c="tab:blue", label="safe")
        axis.set_title("orientation workspace: tilt [deg] against azimuth - torsion")
        axis.legend(loc="lower left", markerscale=8)
        figure.savefig(written["orientation"], dpi=110)
        plt.close(figure)
        return written

    @classmethod
    def load(cls, path: str | Path) -> WorkspaceMap:
        """Read a map written by :meth:`save` (its ``workspace.npz``, or the folder).

        Raises:
            FileFormatError: not a workspace file.
        """
        file = Path(path)
        if file.is_dir():
            file = file / "workspace.npz"
        try:
            with np.load(file, allow_pickle=False) as data:
                meta = json.loads(str(data["meta"]))
                fields = {name: np.array(data[name]) for name in MAP_FIELDS}
                theta = np.array(data["theta"])
                grid = None
                if "grid_index" in data:
                    grid = (
                        np.array(data["grid_d12_deg"]),
                        np.array(data["grid_d23_deg"]),
                        np.array(data["grid_index"]),
                    )
            design = SPMDesign.from_toml(meta["design_toml"], source=str(file))
            settings = dict(meta["settings"])
            settings["ladder"] = tuple(settings["ladder"])
            loaded = WorkspaceSettings(**settings)
        except (OSError, KeyError, ValueError, TypeError) as exc:
            raise FileFormatError(f"not a workspace map: {exc}", path=str(file)) from exc
        return cls(
            design=design,
            settings=loaded,
            theta=theta,
            fields=fields,
            grid=grid,
            step_deg=meta["step_deg"],
            seed=meta["seed"],
        )


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise InputError(
            "plots need matplotlib: pip install spm-pin[plot]", argument="plots"
        ) from exc
    return plt


# ---------------------------------------------------------------- the driver
def _check_number(name: str, value: object, low: float, high: float = math.inf) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not -1e308 <= value <= 1e308  # NaN, inf and ints too large for a float
        or not math.isfinite(float(value))
        or not low <= float(value) <= high
    ):
        raise InputError(
            f"{name} must be a finite number in [{low:g}, {high:g}], got {value!r}",
            argument=name,
            value=value,
        )
    return float(value)


#: Largest count accepted (samples, seed, workers, chunk size).
_MAX_COUNT = 2**32


def _check_count(name: str, value: object, low: int = 1) -> int:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or not low <= value <= _MAX_COUNT
    ):
        raise InputError(
            f"{name} must be an integer in [{low}, {_MAX_COUNT}], got {value!r}",
            argument=name,
            value=value,
        )
    return int(value)


def _grid_points(
    step: float, low: float, high: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, IntArray]:
    axis = np.arange(low, high + 0.5 * step, step)
    axis = axis[axis <= high + 1e-9]
    d12, d23 = np.meshgrid(axis, axis, indexing="ij")
    d31 = 360.0 - d12 - d23
    inside = (d31 >= low - 1e-9) & (d31 <= high + 1e-9)
    rows, columns = np.nonzero(inside)
    index = np.stack([rows, columns], axis=1).astype(np.int64)
    return axis, axis.copy(), d12[inside], d23[inside], index


def _sampled_points(
    count: int, seed: int, low: float, high: float
) -> tuple[FloatArray, FloatArray]:
    """Uniform points of the gap triangle (all three gaps in [low, high]), by rejection."""
    rng = np.random.default_rng(seed)
    found: list[FloatArray] = []
    total = 0
    while total < count:
        d = rng.uniform(low, high, size=(4 * count + 16, 2))
        d31 = 360.0 - d.sum(axis=1)
        d = d[(d31 >= low) & (d31 <= high)]
        found.append(d)
        total += d.shape[0]
    points = np.concatenate(found)[:count]
    return points[:, 0], points[:, 1]


def workspace_map(
    design: SPMDesign | str | None = None,
    *,
    step_deg: float = 2.0,
    gap_range_deg: tuple[float, float] = (0.0, 360.0),
    samples: int | None = None,
    seed: int = 0,
    settings: WorkspaceSettings | None = None,
    executor: concurrent.futures.Executor | Any | None = None,
    workers: int = 1,
    chunk_size: int = DEFAULT_CHUNK,
    progress: bool = True,
) -> WorkspaceMap:
    """Map the workspace over the gap plane (see the module docstring).

    Args:
        design: A coaxial SPM (default: the prototype).
        step_deg: Grid step [deg] (grid maps).
        gap_range_deg: Range of every gap [deg]; points outside are left out. The
            default keeps the proximal links in their order; a lower bound below 0
            also maps links that have passed each other.
        samples: If given, that many random points uniform over the gap domain instead
            of a grid (reproducible for a given ``seed``).
        seed: Seed of the random points.
        settings: What to compute (margin, dexterity threshold, clearance).
        executor: A ``concurrent.futures``-style executor (``submit(fn, *args)``);
            it is used as is and not shut down. Default: a process pool of
            ``workers`` processes, or this process when ``workers`` is 1.
        workers: Processes of the default pool.
        chunk_size: Points per task.
        progress: Show a progress bar (tqdm) on stderr.

    Returns:
        The map.

    Raises:
        InputError: bad arguments or a non-coaxial design.
    """
    design = _coaxial(design)
    settings = WorkspaceSettings() if settings is None else settings
    if not isinstance(settings, WorkspaceSettings):
        raise InputError(
            f"settings must be a WorkspaceSettings, got {type(settings).__name__}",
            argument="settings",
            value=settings,
        )
    _check_number("settings.margin", settings.margin, 0.0, 0.1)
    _check_number("settings.min_dexterity", settings.min_dexterity, 0.0, 1.0)
    try:
        ladder = tuple(float(v) for v in settings.ladder)
    except (TypeError, ValueError, OverflowError):
        ladder = ()
    if (
        not ladder
        or ladder[0] != 0.0
        or not all(math.isfinite(v) for v in ladder)
        or any(b <= a for a, b in itertools.pairwise(ladder))
    ):
        raise InputError(
            "settings.ladder must be increasing margins [m] starting at 0, got "
            f"{settings.ladder!r}",
            argument="settings.ladder",
            value=settings.ladder,
        )
    # The workers and the map get the ladder as floats (cached plans key on floats).
    settings = dataclasses.replace(settings, ladder=ladder)
    try:
        low, high = (float(v) for v in gap_range_deg)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"gap_range_deg must be (low, high) [deg], got {gap_range_deg!r}",
            argument="gap_range_deg",
            value=gap_range_deg,
        ) from exc
    if not (math.isfinite(low) and math.isfinite(high) and -180.0 <= low < high <= 540.0):
        raise InputError(
            f"gap_range_deg must satisfy -180 <= low < high <= 540 [deg], got {gap_range_deg!r}",
            argument="gap_range_deg",
            value=gap_range_deg,
        )
    if 3.0 * low > 360.0 or 3.0 * high < 360.0:
        raise InputError(
            f"gap_range_deg {gap_range_deg!r} holds no point: the three gaps sum to 360 deg",
            argument="gap_range_deg",
            value=gap_range_deg,
        )
    chunk = _check_count("chunk_size", chunk_size)
    count_workers = _check_count("workers", workers)
    grid: tuple[FloatArray, FloatArray, IntArray] | None
    step: float | None
    if samples is None:
        step = _check_number("step_deg", step_deg, 0.05, 60.0)
        axis12, axis23, d12, d23, index = _grid_points(step, low, high)
        grid = (axis12, axis23, index)
        used_seed: int | None = None
    else:
        count = _check_count("samples", samples)
        used_seed = _check_count("seed", seed, 0)
        d12, d23 = _sampled_points(count, used_seed, low, high)
        grid, step = None, None
    theta = gap_inputs(d12, d23, design)
    n = theta.shape[0]
    starts = list(range(0, n, chunk))

    def run(pool: Any) -> list[dict[str, npt.NDArray[Any]]]:
        futures = {
            pool.submit(_chunk_task, design, theta[s : s + chunk], settings): number
            for number, s in enumerate(starts)
        }
        parts: list[dict[str, npt.NDArray[Any]] | None] = [None] * len(starts)
        bar = _progress(n, progress)
        try:
            for future in concurrent.futures.as_completed(futures):
                number = futures[future]
                parts[number] = future.result()
                bar(min(chunk, n - starts[number]))
        finally:
            bar(None)
        return [p for p in parts if p is not None]

    if executor is not None:
        if not callable(getattr(executor, "submit", None)):
            raise InputError(
                "executor must have a concurrent.futures-style submit(fn, *args) method, "
                f"got {type(executor).__name__}",
                argument="executor",
                value=executor,
            )
        chunks = run(executor)
    elif count_workers > 1:
        with concurrent.futures.ProcessPoolExecutor(max_workers=count_workers) as pool:
            chunks = run(pool)
    else:
        chunks = run(_InlineExecutor())
    fields = {name: np.concatenate([c[name] for c in chunks]) for name in chunks[0]}
    fields["d12_deg"] = np.asarray(d12, dtype=float)
    fields["d23_deg"] = np.asarray(d23, dtype=float)
    fields["d31_deg"] = 360.0 - fields["d12_deg"] - fields["d23_deg"]
    ordered = {name: fields[name] for name in MAP_FIELDS}
    return WorkspaceMap(
        design=design,
        settings=settings,
        theta=theta,
        fields=ordered,
        grid=grid,
        step_deg=step,
        seed=used_seed,
    )


class _InlineExecutor:
    """Runs each task at once in this process (the default with one worker)."""

    def submit(self, fn: Callable[..., Any], *args: Any) -> concurrent.futures.Future[Any]:
        future: concurrent.futures.Future[Any] = concurrent.futures.Future()
        try:
            future.set_result(fn(*args))
        except BaseException as exc:  # handed to the caller through the future
            future.set_exception(exc)
        return future


def _progress(total: int, enabled: bool) -> Callable[[int | None], None]:
    """A tqdm progress bar as a function: bar(k) advances by k points, bar(None) closes."""
    if not enabled:
        return lambda _step: None
    from tqdm.auto import tqdm

    bar = tqdm(total=total, unit="pt", desc="workspace", leave=False)

    def update(step: int | None) -> None:
        if step is None:
            bar.close()
        else:
            bar.update(step)

    return update
