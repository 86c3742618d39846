"""Self-collision of the prototype at the study's inputs and its safe workspace map."""

from __future__ import annotations

import tempfile

import numpy as np

import spm_pin as spm
from spm_pin.collision import check_input
from spm_pin.workspace import WorkspaceSettings, workspace_map


def main() -> None:
    robot = spm.build_robot()
    for theta_deg in ([0, 0, 0], [60, 90, 120], [60, 90, 220]):
        report = check_input(np.radians(theta_deg), robot)
        pairs = ", ".join("-".join(pair) for pair in report.pairs) or "none"
        mode = report.mode if report.home else f"{report.mode} (no home-mode assembly)"
        print(
            f"theta = {theta_deg} deg, mode {mode}: colliding pairs {pairs}; "
            f"min distance {report.min_distance * 1e3:.3f} mm"
        )
    settings = WorkspaceSettings(margin=0.0005, min_dexterity=0.2)
    result = workspace_map(step_deg=6.0, settings=settings, progress=False)
    summary = result.summary()
    print(
        f"gap map at 6 deg: {summary['points']} points, "
        f"{summary['reachable_fraction']:.0%} reachable, "
        f"{summary['safe_fraction']:.0%} safe (margin 0.5 mm, dexterity >= 0.2); "
        f"largest safe tilt {summary['max_safe_tilt_deg']:.1f} deg"
    )
    with tempfile.TemporaryDirectory() as folder:  # use a folder of your own to keep them
        written = result.save(folder)
        sizes = ", ".join(f"{path.name} ({path.stat().st_size:,} B)" for path in written.values())
        print(f"written: {sizes}")


if __name__ == "__main__":
    main()
