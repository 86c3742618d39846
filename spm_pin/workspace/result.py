"""A computed workspace map (:class:`WorkspaceMap`): its fields, images, summary,
files (npz, csv, json) and plots."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .._checks import BoolArray, FloatArray
from ..design import SPMDesign
from ..errors import FileFormatError, InputError
from .settings import WorkspaceSettings

__all__ = ["BINARY_PANELS", "GAP_PANELS", "MAP_FIELDS", "WorkspaceMap", "safe_tilt_figures"]

IntArray = npt.NDArray[np.int64]

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


#: The panels of the gap map: field, title, colour map (continuous fields).
GAP_PANELS: tuple[tuple[str, str, str], ...] = (
    ("reachable", "home-mode assembly", "Greens"),
    ("singularity_margin", "singularity margin", "viridis"),
    ("dexterity", "dexterity 1/kappa(J)", "viridis"),
    ("collision", "self-collision", "Reds"),
    ("clearance", "clearance [mm]", "magma"),
    ("safe", "safe set", "Blues"),
)
#: The yes/no fields of the gap map: (label, colour) of false, then of true.
BINARY_PANELS: dict[str, tuple[tuple[str, str], tuple[str, str]]] = {
    "reachable": (("no home-mode assembly", "0.88"), ("home-mode assembly", "tab:green")),
    "collision": (("no collision", "0.88"), ("links collide", "tab:red")),
    "safe": (("not safe", "0.88"), ("safe", "tab:blue")),
}


#: Sectors of azimuth - torsion [deg] over which the safe tilt in every direction is
#: taken (the smallest of the sectors' largest safe tilts).
TILT_SECTOR_DEG = 5.0


def safe_tilt_figures(
    safe: BoolArray, tilt_deg: FloatArray, psi_deg: FloatArray
) -> tuple[float | None, float | None]:
    """The largest safe tilt and the safe tilt in every direction [deg] of a map.

    Args:
        safe: Per point, whether it is safe.
        tilt_deg: Tilt of the platform per point [deg].
        psi_deg: Azimuth minus torsion per point [deg]: the direction of the tilt in
            the platform frame, free of the common yaw of the inputs.

    Returns:
        The largest tilt over the safe points (None if none is safe), and the
        smallest over the 5-degree sectors of psi of the largest safe tilt in the
        sector (None if a sector holds no safe point).
    """
    count = round(360.0 / TILT_SECTOR_DEG)
    sectors = np.full(count, np.nan)
    if np.any(safe):
        bins = np.floor(np.mod(psi_deg[safe], 360.0) / TILT_SECTOR_DEG).astype(int) % count
        for k in range(count):
            inside = tilt_deg[safe][bins == k]
            if inside.size:
                sectors[k] = float(inside.max())
    largest = float(np.max(tilt_deg[safe])) if np.any(safe) else None
    every = float(np.min(sectors)) if np.all(np.isfinite(sectors)) else None
    return largest, every


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
        from ..collision import LINK_PAIRS

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
        largest_tilt, every_direction = safe_tilt_figures(
            safe, f["tilt_deg"], f["azimuth_deg"] - f["torsion_deg"]
        )
        counts = {}
        from ..collision import LINK_PAIRS

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
            "max_safe_tilt_deg": largest_tilt,
            "safe_tilt_every_direction_deg": every_direction,
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
        figure = self.gap_figure()
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

    def gap_figure(self) -> Any:
        """The figure of ``gap_map.png`` (a pyplot ``Figure``; close it when done): six
        panels over the gap plane. Continuous fields carry a colour bar; the yes/no
        fields (home-mode assembly, self-collision, safe) carry a legend of their two
        values instead.

        Raises:
            InputError: matplotlib is missing (``pip install spm-pin[plot]``).
        """
        plt = _pyplot()
        from matplotlib.colors import ListedColormap
        from matplotlib.patches import Patch

        f = self.fields
        figure, axes = plt.subplots(2, 3, figsize=(15, 9.5), constrained_layout=True)
        for axis, (name, title, look) in zip(axes.flat, GAP_PANELS, strict=True):
            scale = 1e3 if name == "clearance" else 1.0
            binary = name in BINARY_PANELS
            cmap: Any = look
            if binary:
                no, yes = BINARY_PANELS[name]
                cmap = ListedColormap([no[1], yes[1]])
            limits = {"vmin": 0.0, "vmax": 1.0} if binary else {}
            if self.grid is not None:
                d12, d23, _ = self.grid
                shown = axis.imshow(
                    self.image(name) * scale,
                    origin="lower",
                    extent=(d23[0], d23[-1], d12[0], d12[-1]),
                    cmap=cmap,
                    aspect="equal",
                    interpolation="nearest",
                    **limits,
                )
            else:
                values = f[name].astype(float) * scale
                shown = axis.scatter(f["d23_deg"], f["d12_deg"], c=values, s=4, cmap=cmap, **limits)
            if binary:
                axis.legend(
                    handles=[Patch(color=color, label=label) for label, color in (yes, no)],
                    loc="upper right",
                    fontsize=8,
                )
            else:
                figure.colorbar(shown, ax=axis, shrink=0.8)
            axis.set_title(title)
            axis.set_xlabel("D23 [deg]")
            axis.set_ylabel("D12 [deg]")
        figure.suptitle(
            f"{self.design.name}: maps over the proximal-link gaps (theta_1 = 0; "
            f"margin {self.settings.margin * 1e3:g} mm, dexterity >= "
            f"{self.settings.min_dexterity:g}); white: no such gaps"
        )
        return figure

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
