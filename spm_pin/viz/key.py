"""The colours of the SPM's scene, their three.js materials, and the key that names
them on a saved page.

Each leg has its own hue (the proximal link darker than the distal one), the base and
the platform are neutral, colliding links black; the joint-axis arrows are coloured
by family (u, w, v) and the platform frame x, y, z red, green, blue.

The key (:func:`key_html`) is an HTML overlay at the top left of a saved page,
element ``#spm-key``: one entry per leg (``li.spm-key-leg``, ``data-leg`` 1..3,
with swatches of its proximal and distal colours), one for colliding links
(``li.spm-key-colliding``) and one per kind of arrow drawn (``li.spm-key-axis``,
``data-axis`` ``u``, ``w``, ``v`` or ``frame``).
"""

from __future__ import annotations

import html
from typing import Any

import meshcat.geometry as mg

__all__ = [
    "COLLIDING_COLOR",
    "COLLIDING_SHINE",
    "FRAME_COLORS",
    "JOINT_AXIS_COLORS",
    "LINK_COLORS",
    "Color",
    "css_color",
    "hex_color",
    "key_html",
    "material",
]

Color = tuple[float, float, float, float]

#: Link colours (RGBA, 0..1): each leg its own hue, the proximal link darker than the
#: distal one; the base and the platform neutral.
LINK_COLORS: dict[str, Color] = {
    "base": (0.50, 0.51, 0.54, 1.0),
    "proximal_1": (0.00, 0.40, 0.70, 1.0),
    "distal_1": (0.35, 0.65, 0.90, 1.0),
    "proximal_2": (0.85, 0.40, 0.00, 1.0),
    "distal_2": (0.98, 0.65, 0.25, 1.0),
    "proximal_3": (0.45, 0.20, 0.60, 1.0),
    "distal_3": (0.70, 0.50, 0.82, 1.0),
    "platform": (0.86, 0.86, 0.82, 1.0),
}
#: Colour of a link that collides with another: black, but not quite, so that with
#: :data:`COLLIDING_SHINE` its faces still shade and its shape reads.
COLLIDING_COLOR: Color = (0.12, 0.12, 0.12, 1.0)
#: Material settings (three.js MeshPhongMaterial) of colliding links: highlights.
COLLIDING_SHINE: dict[str, int] = {"specular": 0x666666, "shininess": 40}
#: Colours of the joint-axis arrows, by axis family.
JOINT_AXIS_COLORS: dict[str, Color] = {
    "u": (0.20, 0.20, 0.20, 1.0),
    "w": (0.95, 0.75, 0.05, 1.0),
    "v": (0.00, 0.65, 0.60, 1.0),
}
#: Colours of the platform frame's axes.
FRAME_COLORS: dict[str, Color] = {
    "x": (0.90, 0.10, 0.10, 1.0),
    "y": (0.10, 0.75, 0.10, 1.0),
    "z": (0.10, 0.20, 0.95, 1.0),
}

#: What each family of joint-axis arrows is.
_AXIS_LABELS = {
    "u": "u_i: input axis (base)",
    "w": "w_i: proximal-distal joints",
    "v": "v_i: platform joints",
}


def css_color(color: Color) -> str:
    """``#rrggbb`` of an RGBA colour (0..1)."""
    r, g, b = (round(255 * min(max(c, 0.0), 1.0)) for c in color[:3])
    return f"#{r:02x}{g:02x}{b:02x}"


def hex_color(color: Color) -> int:
    """The colour as the integer three.js takes (0xRRGGBB)."""
    r, g, b = (round(255 * min(max(c, 0.0), 1.0)) for c in color[:3])
    return (r << 16) | (g << 8) | b


def material(color: Color, **extra: Any) -> mg.MeshPhongMaterial:
    """A three.js MeshPhongMaterial of an RGBA colour (0..1), with ``extra`` settings
    (e.g. :data:`COLLIDING_SHINE`)."""
    return mg.MeshPhongMaterial(color=hex_color(color), opacity=float(color[3]), **extra)


def _swatch(color: Color) -> str:
    return f'<span class="spm-swatch" style="background:{css_color(color)}"></span>'


def key_html(*, joint_axes: bool, platform_frame: bool) -> str:
    """The key of a saved page: the legs' colours, colliding links and the arrows drawn.

    Args:
        joint_axes: The joint-axis arrows are drawn (entries u, w, v).
        platform_frame: The platform frame is drawn (entry ``frame``).
    """
    items = []
    for i in (1, 2, 3):
        swatches = _swatch(LINK_COLORS[f"proximal_{i}"]) + _swatch(LINK_COLORS[f"distal_{i}"])
        items.append(
            f'<li class="spm-key-leg" data-leg="{i}">{swatches}leg {i} (proximal, distal)</li>'
        )
    items.append(f'<li class="spm-key-colliding">{_swatch(COLLIDING_COLOR)}colliding link</li>')
    if joint_axes:
        for letter, label in _AXIS_LABELS.items():
            items.append(
                f'<li class="spm-key-axis" data-axis="{letter}">'
                f"{_swatch(JOINT_AXIS_COLORS[letter])}{html.escape(label)}</li>"
            )
    if platform_frame:
        swatches = "".join(_swatch(color) for color in FRAME_COLORS.values())
        items.append(
            f'<li class="spm-key-axis" data-axis="frame">{swatches}platform frame x, y, z</li>'
        )
    return '<ul id="spm-key">' + "".join(items) + "</ul>\n"
