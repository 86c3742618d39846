"""``spm export``: the robot files of a design (URDF, MJCF and link meshes)."""

from __future__ import annotations

import argparse
from typing import Any

from .._records import dumps as _dumps
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import design_of as _design

__all__ = ["add_parser"]


def _run_export(args: argparse.Namespace) -> int:
    design = _design(args)
    # Imported here: the model layer (trimesh) is not needed by the other commands.
    from ..model.export import export

    written = export(design, args.out)
    if args.json:
        print(
            _dumps(
                {
                    "design": design.name,
                    "out": str(args.out),
                    "files": [str(p) for p in written.values()],
                }
            )
        )
    else:
        print(f"wrote the robot files of design {design.name!r} to {args.out}:")
        for path in written.values():
            print(f"  {path}")
    return 0


def add_parser(commands: Any) -> None:
    """``spm export``."""
    export = commands.add_parser(
        "export",
        help="write the URDF, MJCF and link meshes",
        description="Write the robot files of a design: DIR/spm.urdf (open tree), "
        "DIR/spm.xml (MJCF with the loop-closing welds) and DIR/meshes/<link>.stl.",
    )
    export.add_argument(
        "--out", metavar="DIR", default="urdf", help="output directory (default: ./urdf)"
    )
    _add_json_option(export)
    _add_design_option(export)
    export.set_defaults(run=_run_export)
