"""Robot files of an SPM: URDF (open tree), MJCF (tree plus loop-closing welds), STL meshes.

:func:`export` writes into one directory::

    spm.urdf            the open kinematic tree (URDF has no closed loops)
    spm.xml             MJCF: the same tree under one root body, and <equality> welds
                        that close legs 2 and 3 on the platform (Pinocchio's
                        buildModelAndConstraintsFromMJCF and MuJoCo both load it)
    meshes/<link>.stl   binary STL of every link (the names of docs/conventions.md)

The tree (docs/conventions.md): ``base`` -> ``u_i`` -> ``proximal_i`` -> ``w_i`` ->
``distal_i`` -> ``v_i`` -> ``platform`` for leg 1, ``platform_leg2`` / ``platform_leg3``
for legs 2 and 3: end bodies that are the same rigid platform, welded to ``platform``
by the closures. Every joint axis passes through O and every joint placement is the
identity, so at home (q = 0) every link frame, the platform frame included, is the
world frame; each joint's axis is its world axis at home (u_i, w_i0, v_i0).

The output is deterministic: the same design gives the same bytes (numbers in the
XML files are rounded to 12 significant digits; STL headers
carry no date or version), so the committed prototype files can be compared with a
fresh export byte for byte.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh

from ..design import SPMDesign
from .geometry import LINK_NAMES, LinkInertia, link_inertias, link_meshes
from .robot import END_BODIES, JOINT_NAMES  # re-exported: the robot's names and q order

__all__ = [
    "END_BODIES",
    "JOINT_NAMES",
    "MESH_DIR",
    "MJCF_NAME",
    "URDF_NAME",
    "export",
    "mjcf_text",
    "stl_bytes",
    "urdf_text",
]

FloatArray = npt.NDArray[np.float64]

URDF_NAME = "spm.urdf"
MJCF_NAME = "spm.xml"
MESH_DIR = "meshes"

#: Position limits written to the URDF [rad] (URDF revolute joints need limits; a
#: "continuous" joint would become a two-coordinate joint in Pinocchio). The coaxial
#: inputs turn endlessly (the XM540 has a multi-turn mode), so their limits only bound
#: the model's range; the passive joints are stopped by the links, not by the joints.
_INPUT_LIMIT = 2 * math.pi
_PASSIVE_LIMIT = math.pi
#: Dynamixel XM540-W150 at 12 V: stall torque [N m] and no-load speed [rad/s].
_SERVO_EFFORT = 7.3
_SERVO_SPEED = 53.0 * 2 * math.pi / 60
_PASSIVE_SPEED = 10.0

_COLORS = {
    "base": (0.35, 0.35, 0.38, 1.0),
    "proximal": (0.20, 0.45, 0.80, 1.0),
    "distal": (0.90, 0.55, 0.15, 1.0),
    "platform": (0.25, 0.65, 0.35, 1.0),
}

#: Significant digits written for lengths and inertias: 1e-12 relative is far below any
#: physical precision, and unlike full `repr` precision it keeps the committed files
#: byte-identical across platforms whose libm differs in the last bit.
_GEOMETRY_DIGITS = 12
_INERTIA_DIGITS = 12
#: Lengths [m] below this are written as 0 (rounding noise of zero coordinates).
_ZERO_LENGTH = 1e-12


# --------------------------------------------------------------------- formatting
def _number(value: float, digits: int = _GEOMETRY_DIGITS) -> str:
    text = f"{float(value):.{digits}g}"
    return "0" if float(text) == 0.0 else text  # no "-0"


def _vector(values: Iterable[float], digits: int = _GEOMETRY_DIGITS) -> str:
    return " ".join(
        _number(0.0 if abs(v) < _ZERO_LENGTH else v, digits) for v in np.asarray(values).ravel()
    )


def _clean_inertia(inertia: FloatArray) -> FloatArray:
    """The tensor with entries below 1e-10 of its largest set to 0 (rounding noise)."""
    scale = float(np.max(np.abs(inertia)))
    return np.where(np.abs(inertia) < 1e-10 * scale, 0.0, inertia)


def _inertial_parts(inertia: LinkInertia, fraction: float) -> tuple[str, str, FloatArray]:
    mass = _number(fraction * inertia.mass, _INERTIA_DIGITS)
    com = _vector(inertia.com, _INERTIA_DIGITS)
    return mass, com, _clean_inertia(fraction * inertia.inertia)


def _color(link: str) -> tuple[float, float, float, float]:
    return _COLORS[link.split("_")[0]]


def _end_inertias(design: SPMDesign) -> dict[str, tuple[LinkInertia, float]]:
    """Body name -> (mass properties, fraction) for every body of the tree."""
    inertias = link_inertias(design)
    bodies: dict[str, tuple[LinkInertia, float]] = {
        name: (inertias[name], 1.0) for name in LINK_NAMES if name != "platform"
    }
    for body in END_BODIES:
        bodies[body] = (inertias["platform"], 1.0 / 3.0)
    return bodies


def _joint_axes(design: SPMDesign) -> dict[str, FloatArray]:
    axes = {"u": design.u, "w": design.w0, "v": design.v0}
    return {f"{letter}_{leg + 1}": axes[letter][leg] for leg in range(3) for letter in "uwv"}


def _leg_bodies(leg: int) -> tuple[str, str, str]:
    return (f"proximal_{leg + 1}", f"distal_{leg + 1}", END_BODIES[leg])


def _header(design: SPMDesign) -> str:
    return (
        f"Generated by spm_pin.model.export from the design {design.name!r} "
        f"({design.summary().split(': ', 1)[-1]}). Do not edit: run `spm export`."
    )


# --------------------------------------------------------------------------- STL
def stl_bytes(mesh: trimesh.Trimesh, name: str) -> bytes:
    """A binary STL of ``mesh`` with a fixed header (deterministic bytes).

    Args:
        mesh: The triangle mesh [m].
        name: Written into the 80-byte header.
    """
    triangles = np.asarray(mesh.vertices, dtype=float)[np.asarray(mesh.faces)]
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)
    record = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])
    data = np.zeros(len(triangles), dtype=record)
    data["normal"] = normals
    data["vertices"] = triangles
    header = f"spm-pin link {name} [m]".encode("ascii")[:80].ljust(80, b" ")
    return header + struct.pack("<I", len(triangles)) + bytes(data.tobytes())


# -------------------------------------------------------------------------- URDF
def _urdf_inertial(inertia: LinkInertia, fraction: float, indent: str) -> list[str]:
    mass, com, tensor = _inertial_parts(inertia, fraction)
    i = [_number(x, _INERTIA_DIGITS) for x in tensor.ravel()]
    return [
        f"{indent}<inertial>",
        f'{indent}  <origin xyz="{com}" rpy="0 0 0"/>',
        f'{indent}  <mass value="{mass}"/>',
        f'{indent}  <inertia ixx="{i[0]}" ixy="{i[1]}" ixz="{i[2]}" '
        f'iyy="{i[4]}" iyz="{i[5]}" izz="{i[8]}"/>',
        f"{indent}</inertial>",
    ]


def _urdf_link(name: str, inertia: LinkInertia, fraction: float, mesh: str | None) -> list[str]:
    lines = [f'  <link name="{name}">', *_urdf_inertial(inertia, fraction, "    ")]
    if mesh is not None:
        rgba = _vector(_color(name), 4)
        geometry = [
            '      <origin xyz="0 0 0" rpy="0 0 0"/>',
            f'      <geometry><mesh filename="{MESH_DIR}/{mesh}.stl"/></geometry>',
        ]
        lines += [
            '    <visual name="' + name + '">',
            *geometry,
            f'      <material name="{name.split("_")[0]}"><color rgba="{rgba}"/></material>',
            "    </visual>",
            '    <collision name="' + name + '">',
            *geometry,
            "    </collision>",
        ]
    lines.append("  </link>")
    return lines


def urdf_text(design: SPMDesign | None = None) -> str:
    """The URDF of the open tree (links, joints, inertias, mesh references).

    Args:
        design: The SPM (default: the prototype).
    """
    design = SPMDesign.prototype() if design is None else design
    bodies = _end_inertias(design)
    axes = _joint_axes(design)
    lines = [
        '<?xml version="1.0"?>',
        f"<!-- {_header(design)} -->",
        "<!-- The open tree of the SPM: every joint axis passes through O and every joint",
        "     origin is the identity, so at home (q = 0) every link frame is the world frame",
        "     and each axis is the joint's world axis at home. Legs 2 and 3 end in",
        "     platform_leg2 and platform_leg3: the same rigid platform as platform, to be",
        "     welded to it by the loop closures (see spm.xml). The platform's mass",
        "     properties are split in thirds over platform, platform_leg2 and",
        "     platform_leg3: the sum is the real platform, and no end body is massless,",
        "     which keeps the closed-loop mass matrix well conditioned. -->",
        '<robot name="spm">',
    ]
    base_inertia, _ = bodies["base"]
    lines += _urdf_link("base", base_inertia, 1.0, "base")
    for leg in range(3):
        parent = "base"
        for letter, body in zip("uwv", _leg_bodies(leg), strict=True):
            joint = f"{letter}_{leg + 1}"
            actuated = letter == "u"
            limit = _INPUT_LIMIT if actuated else _PASSIVE_LIMIT
            effort = _SERVO_EFFORT if actuated else 0.0
            speed = _SERVO_SPEED if actuated else _PASSIVE_SPEED
            role = "actuated" if actuated else "passive"
            lines += [
                f'  <joint name="{joint}" type="revolute">  <!-- {role} -->',
                f'    <parent link="{parent}"/>',
                f'    <child link="{body}"/>',
                '    <origin xyz="0 0 0" rpy="0 0 0"/>',
                f'    <axis xyz="{_vector(axes[joint])}"/>',
                f'    <limit lower="{_number(-limit)}" upper="{_number(limit)}" '
                f'effort="{_number(effort)}" velocity="{_number(speed)}"/>',
                "  </joint>",
            ]
            inertia, fraction = bodies[body]
            mesh = body if body in LINK_NAMES else None
            lines += _urdf_link(body, inertia, fraction, mesh)
            parent = body
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


# -------------------------------------------------------------------------- MJCF
def _mjcf_inertial(inertia: LinkInertia, fraction: float) -> str:
    mass, com, tensor = _inertial_parts(inertia, fraction)
    full = [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]
    values = " ".join(_number(x, _INERTIA_DIGITS) for x in full)
    return f'<inertial pos="{com}" mass="{mass}" fullinertia="{values}"/>'


def _mjcf_geom(name: str) -> str:
    return (
        f'<geom name="{name}" type="mesh" mesh="{name}" contype="2" conaffinity="1" '
        f'rgba="{_vector(_color(name), 4)}"/>'
    )


def mjcf_text(design: SPMDesign | None = None) -> str:
    """The MJCF: the tree under one root body ``base`` plus two loop-closing welds.

    Args:
        design: The SPM (default: the prototype).
    """
    design = SPMDesign.prototype() if design is None else design
    bodies = _end_inertias(design)
    axes = _joint_axes(design)
    lines = [
        f"<!-- {_header(design)} -->",
        '<mujoco model="spm">',
        '  <compiler angle="radian" meshdir="meshes" inertiafromgeom="false"/>',
        "  <asset>",
        *(f'    <mesh name="{name}" file="{name}.stl"/>' for name in LINK_NAMES),
        "  </asset>",
        "  <worldbody>",
        "    <!-- One root body: Pinocchio's MJCF parser reads only the first body under",
        "         worldbody. base has no joint, so it is fixed to the world. -->",
        '    <body name="base">',
        f"      {_mjcf_inertial(*bodies['base'])}",
        "      <!-- One mesh geom per link: the real link shape, drawn and used for",
        "           collision. Links that share a joint touch at their pins and bosses, and",
        "           MuJoCo would collide the convex hulls of these concave meshes, so no",
        "           two of them may make a MuJoCo contact: contype=2 and conaffinity=1",
        "           never match each other (self-collision is checked with coal on the",
        "           meshes instead). contype=conaffinity=0 would do the same in MuJoCo, but",
        "           Pinocchio's MJCF parser then reads the geoms as visual only. -->",
        f"      {_mjcf_geom('base')}",
    ]
    closing: list[str] = []
    for leg in range(3):
        indent = "      "
        for letter, body in zip("uwv", _leg_bodies(leg), strict=True):
            joint = f"{letter}_{leg + 1}"
            lines += [
                f'{indent}<body name="{body}">',
                f'{indent}  <joint name="{joint}" type="hinge" pos="0 0 0" '
                f'axis="{_vector(axes[joint])}"/>',
                f"{indent}  {_mjcf_inertial(*bodies[body])}",
            ]
            if body in LINK_NAMES:
                lines.append(f"{indent}  {_mjcf_geom(body)}")
            closing.insert(0, f"{indent}</body>")
            indent += "  "
        lines += closing
        closing = []
    lines += [
        "    </body>",
        "  </worldbody>",
        "  <!-- Loop closures: the end bodies of legs 2 and 3 are the platform itself; all",
        "       axes meet at O, so each weld has rank 3 (its linear part is always zero).",
        "       The platform's mass properties are split in thirds over the three end",
        "       bodies (this conditions the closed-loop dynamics). -->",
        "  <equality>",
        '    <weld name="close_leg2" body1="platform_leg2" body2="platform" '
        'relpose="0 0 0 1 0 0 0"/>',
        '    <weld name="close_leg3" body1="platform_leg3" body2="platform" '
        'relpose="0 0 0 1 0 0 0"/>',
        "  </equality>",
        "</mujoco>",
    ]
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------ export
def _write_if_changed(path: Path, data: bytes) -> None:
    if not path.exists() or path.read_bytes() != data:
        path.write_bytes(data)


def export(design: SPMDesign | None = None, out_dir: str | Path = "urdf") -> dict[str, Path]:
    """Write the URDF, the MJCF and the link meshes of ``design`` into ``out_dir``.

    Args:
        design: The SPM (default: the prototype).
        out_dir: Output directory (created if needed); meshes go to ``out_dir/meshes``.

    Returns:
        Relative file name (``"spm.urdf"``, ``"spm.xml"``, ``"meshes/base.stl"``, ...)
        -> the path written.

    Raises:
        OSError: A file cannot be written.
    """
    design = SPMDesign.prototype() if design is None else design
    out = Path(out_dir)
    (out / MESH_DIR).mkdir(parents=True, exist_ok=True)
    files: dict[str, bytes] = {
        URDF_NAME: urdf_text(design).encode("utf-8"),
        MJCF_NAME: mjcf_text(design).encode("utf-8"),
    }
    for name, mesh in link_meshes(design).items():
        files[f"{MESH_DIR}/{name}.stl"] = stl_bytes(mesh, name)
    written: dict[str, Path] = {}
    for relative, data in files.items():
        path = out / relative
        _write_if_changed(path, data)
        written[relative] = path
    return written
