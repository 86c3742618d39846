"""Self-collision of the prototype at the study's inputs and its safe workspace map.

Writes workspace.npz, workspace.csv, summary.json, gap_map.png and orientation.png into
--out DIR (without it, into a temporary directory that is removed at the end).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

import spm_pin as spm
from spm_pin.collision import check_input
from spm_pin.workspace import WorkspaceSettings, workspace_map


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="directory for the files")
    args = parser.parse_args()
    if args.out is None:
        with tempfile.TemporaryDirectory(prefix="spm-workspace-") as scratch:
            run(Path(scratch))
    else:
        args.out.mkdir(parents=True, exist_ok=True)
        run(args.out)


def run(out: Path) -> None:
    """Print the collision checks and the map's summary; write the map into ``out``."""
    robot = spm.build_robot()
    for k, theta_deg in enumerate(([0, 0, 0], [60, 90, 120], [60, 90, 220]), start=1):
        report = check_input(np.radians(theta_deg), robot)
        pairs = " ".join("-".join(pair) for pair in report.pairs) or "none"
        print(
            f"check_{k}: theta_deg {' '.join(map(str, theta_deg))}; mode {report.mode}; "
            f"home {report.home}; colliding {pairs}; "
            f"min_distance_mm {report.min_distance * 1e3:.4f}"
        )
    settings = WorkspaceSettings(margin=0.0005, min_dexterity=0.2)
    result = workspace_map(step_deg=6.0, settings=settings, progress=False)
    summary = result.summary()
    print("map: step 6 deg, safe = clearance >= 0.5 mm and dexterity >= 0.2")
    for name in ("points", "reachable_fraction", "safe_fraction", "max_safe_tilt_deg"):
        print(f"{name}: {summary[name]:.6g}")
    for name, path in result.save(out).items():
        print(f"wrote_{name}: {path} ({path.stat().st_size} B)")


if __name__ == "__main__":
    main()
