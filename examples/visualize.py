"""The prototype at home, at the study's input and at its colliding input, as HTML scenes.

Writes home.html, demo.html, safe.html, colliding.html and motion.html (the motion from
home to theta = [60, 90, 120] deg, 25 samples) into --out DIR (without it, into a
temporary directory that is removed at the end) and prints the colliding links. safe.html
and colliding.html show the study's input and its colliding input from one camera that
sees the contact of legs 2 and 3 (COLLISION_VIEW_DEG). With --png DIR it also renders
the pictures of the documentation (needs Playwright and a Chromium):

    python examples/visualize.py --png docs/images
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

import spm_pin as spm
from spm_pin.viz import Visualizer

DEMO_DEG = [60.0, 90.0, 120.0]  # the study's demonstration input
COLLIDING_DEG = [60.0, 90.0, 220.0]  # the study's colliding input
PICTURE_SIZE = (960, 720)  # [px]
# Camera of the collision pictures, azimuth and elevation [deg]: the platform's face, the
# free leg 1 and the contact of legs 2 and 3 at the colliding input all face it.
COLLISION_VIEW_DEG = (-60.0, 35.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="directory for the HTML files")
    parser.add_argument("--png", type=Path, metavar="DIR", help="also write PNG pictures to DIR")
    args = parser.parse_args()
    if args.out is None:
        with tempfile.TemporaryDirectory(prefix="spm-visualize-") as scratch:
            write(Path(scratch), args.png)
    else:
        args.out.mkdir(parents=True, exist_ok=True)
        write(args.out, args.png)


def write(out: Path, png: Path | None) -> None:
    """Write the scenes into ``out`` and, with ``png``, their pictures into ``png``."""
    robot = spm.build_robot()
    scenes: dict[str, Path] = {}

    viz = Visualizer(robot)
    scenes["home"] = viz.save_html(out / "home.html")

    viz = Visualizer(robot, joint_axes=True, platform_frame=True)
    viz.display(np.radians(DEMO_DEG))
    scenes["demo"] = viz.save_html(out / "demo.html")

    azimuth, elevation = np.radians(COLLISION_VIEW_DEG)
    viz = Visualizer(robot)
    viz.display(np.radians(DEMO_DEG))
    viz.set_camera(azimuth, elevation)
    scenes["safe"] = viz.save_html(out / "safe.html")

    # The colliding input has no home-mode assembly: show its first real assembly mode.
    theta = np.radians(COLLIDING_DEG)
    label = spm.forward_kinematics_all(theta).labels[0]
    viz = Visualizer(robot)
    pairs = viz.display(theta, mode=label)
    viz.set_camera(azimuth, elevation)
    scenes["colliding"] = viz.save_html(out / "colliding.html")
    print(f"colliding_theta_deg: {' '.join(f'{x:g}' for x in COLLIDING_DEG)}")
    print(f"colliding_mode: {label}")
    print(f"colliding_links: {' '.join(f'{a}-{b}' for a, b in pairs) or 'none'}")

    viz = Visualizer(robot)
    path = np.linspace(0.0, 1.0, 25)[:, None] * np.radians(DEMO_DEG)
    motion = viz.animate(path, dt=0.08)
    scenes["motion"] = viz.save_html(out / "motion.html")
    print(f"motion_samples: {len(motion.times)}")
    print(f"motion_colliding_samples: {' '.join(map(str, motion.colliding_samples)) or 'none'}")

    for name, path_html in scenes.items():
        print(f"wrote_{name}: {path_html} ({path_html.stat().st_size} B)")

    if png is not None:
        from spm_pin.viz.browser import chromium, screenshot

        png.mkdir(parents=True, exist_ok=True)
        with chromium() as browser:
            for name in ("home", "demo", "safe", "colliding"):
                picture = png / f"spm_{name}.png"
                screenshot(scenes[name], picture, size=PICTURE_SIZE, browser=browser)
                compress(picture)
                print(f"wrote_{name}_png: {picture} ({picture.stat().st_size} B)")


def compress(png: Path) -> None:
    """Store a picture as RGB at PNG's best compression, if Pillow is there (about half)."""
    try:
        from PIL import Image
    except ImportError:
        return
    with Image.open(png) as picture:
        opaque = picture.convert("RGB")
    opaque.save(png, optimize=True)


if __name__ == "__main__":
    main()
