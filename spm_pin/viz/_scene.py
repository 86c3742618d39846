"""A meshcat scene kept in Python: sent on to a live server, replayed into static HTML.

meshcat's server keeps a tree of the commands it received (per node: the object, its
properties, its transform) and replays it to every browser that connects, and into
its static HTML. :class:`Scene` keeps the same tree on this side, so a scene can be
built without any server, handed to a server started later, and written as one
self-contained HTML file that opens offline.

Unlike meshcat's own static HTML (which decodes every command with an asynchronous
``fetch`` of a data URL, so commands may run out of order), the HTML written here
runs the commands synchronously, in order, and then sets ``window.spm_scene_ready``.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import json
import uuid
from functools import cache
from pathlib import Path
from typing import Any

import meshcat
import numpy as np
import numpy.typing as npt
import umsgpack

from .server import MeshcatServer

FloatArray = npt.NDArray[np.float64]


_UUID_NAMESPACE = uuid.UUID("5d3c6a3e-2f0c-4a43-9a3f-7f0e0f9b6c11")


def _rename(value: Any, names: dict[str, str]) -> Any:
    """A copy of a lowered object with every string found in ``names`` replaced."""
    if isinstance(value, str):
        return names.get(value, value)
    if isinstance(value, dict):
        return {key: _rename(item, names) for key, item in value.items()}
    if isinstance(value, list):
        return [_rename(item, names) for item in value]
    return value


@cache
def viewer_script() -> str:
    """meshcat's viewer (three.js included) as shipped inside the meshcat wheel."""
    path = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    return path.read_text(encoding="utf-8")


def split_path(path: str) -> tuple[str, ...]:
    """``"/a/b/"`` -> ``("a", "b")`` (as meshcat splits paths)."""
    return tuple(part for part in path.split("/") if part)


@dataclasses.dataclass
class Node:
    """One node of the scene tree (packed msgpack commands, as the server keeps them)."""

    object: bytes | None = None
    properties: dict[str, bytes] = dataclasses.field(default_factory=dict)
    transform: bytes | None = None
    children: dict[str, Node] = dataclasses.field(default_factory=dict)


class Scene:
    """The commands that make a meshcat scene, kept as a tree and optionally sent on."""

    def __init__(self) -> None:
        self.root = Node()
        self.animation: bytes | None = None
        self.server: MeshcatServer | None = None

    # ---------------------------------------------------------------------- output
    def attach(self, server: MeshcatServer | None) -> None:
        """Send every later command to ``server`` too, after the scene so far."""
        self.server = server
        if server is not None:
            for kind, path, data in self.commands():
                server.send(kind, path, data)

    def _node(self, path: str, create: bool = True) -> Node | None:
        node = self.root
        for name in split_path(path):
            if name not in node.children:
                if not create:
                    return None
                node.children[name] = Node()
            node = node.children[name]
        return node

    def _emit(self, command: dict[str, Any]) -> None:
        data: bytes = umsgpack.packb(command)
        kind, path = command["type"], command["path"]
        if kind == "set_animation":
            self.animation = data if command["animations"] else None
        else:
            node = self._node(path)
            assert node is not None
            if kind == "set_object":
                node.object = data
                node.properties = {}
            elif kind == "set_transform":
                node.transform = data
            elif kind == "set_property":
                node.properties.pop(command["property"], None)  # keep the latest last
                node.properties[command["property"]] = data
        if self.server is not None:
            self.server.send(kind, path, data)

    # -------------------------------------------------------------------- commands
    def set_object(self, path: str, obj: Any) -> None:
        """Put a meshcat object (``meshcat.geometry.Mesh`` and alike) at ``path``.

        meshcat names the parts of an object with time-based UUIDs; they are replaced
        by UUIDs derived from ``path``, so the same scene always gives the same bytes.
        """
        lowered = obj.lower()
        names: dict[str, str] = {}
        for field in ("geometries", "materials", "textures", "images"):
            for k, item in enumerate(lowered.get(field, [])):
                names[item["uuid"]] = str(uuid.uuid5(_UUID_NAMESPACE, f"{path}#{field}{k}"))
        names[lowered["object"]["uuid"]] = str(uuid.uuid5(_UUID_NAMESPACE, path))
        self._emit({"type": "set_object", "object": _rename(lowered, names), "path": path})

    def set_transform(self, path: str, matrix: npt.ArrayLike) -> None:
        """Set the homogeneous transform (4, 4) of ``path`` relative to its parent."""
        array = np.asarray(matrix, dtype=float)
        flat = [float(x) for x in array.T.flatten()]  # column-major, as three.js reads it
        self._emit({"type": "set_transform", "path": path, "matrix": flat})

    def set_property(self, path: str, key: str, value: Any) -> None:
        """Set a property (``visible``, ``position``, ``zoom``, ...) of the node at ``path``."""
        self._emit({"type": "set_property", "path": path, "property": key, "value": value})

    def set_animation(
        self, animations: list[dict[str, Any]], *, play: bool, repetitions: int
    ) -> None:
        """Load an animation: a list of ``{"path": ..., "clip": ...}`` (three.js clips)."""
        self._emit(
            {
                "type": "set_animation",
                "animations": animations,
                "options": {"play": play, "repetitions": repetitions},
                "path": "",
            }
        )

    # -------------------------------------------------------------------- reading
    def commands(self) -> list[tuple[str, str, bytes]]:
        """(type, path, packed command) in replay order: node by node, the animation last."""
        out: list[tuple[str, str, bytes]] = []

        def visit(path: str, node: Node) -> None:
            if node.object is not None:
                out.append(("set_object", path, node.object))
            out.extend(("set_property", path, data) for data in node.properties.values())
            if node.transform is not None:
                out.append(("set_transform", path, node.transform))
            for name, child in node.children.items():
                visit(f"{path}/{name}", child)

        visit("", self.root)
        if self.animation is not None:
            out.append(("set_animation", "", self.animation))
        return out

    def property(self, path: str, key: str) -> Any:
        """The last value set for property ``key`` of ``path`` (None when never set)."""
        node = self._node(path, create=False)
        if node is None or key not in node.properties:
            return None
        return umsgpack.unpackb(node.properties[key])["value"]

    def transform(self, path: str) -> FloatArray | None:
        """The transform (4, 4) last set on ``path`` (None when never set)."""
        node = self._node(path, create=False)
        if node is None or node.transform is None:
            return None
        matrix = umsgpack.unpackb(node.transform)["matrix"]
        result: FloatArray = np.array(matrix, dtype=float).reshape(4, 4).T
        return result

    def children(self, path: str) -> list[str]:
        """Names of the children of ``path``, in the order they were made."""
        node = self._node(path, create=False)
        return [] if node is None else list(node.children)

    def object(self, path: str) -> dict[str, Any] | None:
        """The object put at ``path`` (three.js JSON: geometries, materials, object)."""
        node = self._node(path, create=False)
        if node is None or node.object is None:
            return None
        lowered: dict[str, Any] = umsgpack.unpackb(node.object)["object"]
        return lowered

    def static_html(
        self,
        title: str = "spm-pin",
        caption: str | None = None,
        *,
        key: str | None = None,
        views: dict[str, list[tuple[str, str, Any]]] | None = None,
        view: str | None = None,
    ) -> str:
        """One self-contained HTML page showing the scene (and playing its animation).

        The page needs no server and no network: meshcat's viewer is inlined and the
        scene follows as base64 msgpack commands, decoded in order when the page loads.
        A ``caption``, when given, is a line of text at the bottom left of the page
        (element id ``spm-caption``); a ``key`` is HTML put at the top left.
        ``views`` maps a view name to the ``(path, property, value)`` settings that
        show it: the page gets one button per view (element ``#spm-views``, buttons
        with ``data-view``; the global function ``spm_set_view(name)`` does the same)
        and shows ``view`` (when given) once the scene is built.
        """
        payload = json.dumps(
            [base64.b64encode(data).decode("ascii") for _, _, data in self.commands()]
        )
        caption_html = (
            "" if caption is None else f'<div id="spm-caption">{html.escape(caption)}</div>\n'
        )
        buttons = ""
        settings: dict[str, list[list[Any]]] = {}
        if views:
            settings = {
                name: [[list(split_path(path)), prop, value] for path, prop, value in items]
                for name, items in views.items()
            }
            buttons = (
                '<div id="spm-views">'
                + "".join(
                    f'<button type="button" data-view="{html.escape(name)}" '
                    f'onclick="spm_set_view(this.dataset.view)">{html.escape(name)}</button>'
                    for name in views
                )
                + "</div>\n"
            )
        return _PAGE.format(
            title=html.escape(title),
            caption=caption_html,
            key=key or "",
            buttons=buttons,
            viewer=viewer_script(),
            commands=payload,
            views=json.dumps(settings),
            view=json.dumps(view),
        )


_PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; overflow: hidden; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#spm-caption {{ position: absolute; left: 8px; bottom: 8px; max-width: 70vw;
  padding: 4px 8px; font: 13px/1.4 sans-serif; color: #222;
  background: rgba(255, 255, 255, 0.85); border-radius: 3px; pointer-events: none;
  z-index: 10; }}
#spm-key {{ position: absolute; left: 8px; top: 8px; margin: 0; padding: 4px 8px;
  list-style: none; font: 12px/1.5 sans-serif; color: #222;
  background: rgba(255, 255, 255, 0.85); border-radius: 3px; pointer-events: none;
  z-index: 10; }}
.spm-swatch {{ display: inline-block; width: 10px; height: 10px; margin-right: 3px;
  vertical-align: -1px; border: 1px solid rgba(0, 0, 0, 0.3); }}
#spm-key .spm-swatch:last-of-type {{ margin-right: 6px; }}
#spm-views {{ position: absolute; right: 8px; bottom: 8px; z-index: 10; }}
#spm-views button {{ font: 12px sans-serif; margin-right: 2px; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
{caption}{key}{buttons}<script>
{viewer}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var spm_views = {views};
function spm_set_view(name) {{
  var settings = spm_views[name];
  if (settings === undefined) return false;
  for (var i = 0; i < settings.length; i++) {{
    viewer.set_property(settings[i][0], settings[i][1], settings[i][2]);
  }}
  viewer.set_dirty();
  window.spm_view = name;
  return true;
}}
(function () {{
  var commands = {commands};
  for (var i = 0; i < commands.length; i++) {{
    var text = atob(commands[i]);
    var bytes = new Uint8Array(text.length);
    for (var j = 0; j < text.length; j++) bytes[j] = text.charCodeAt(j);
    viewer.handle_command_bytearray(bytes);
  }}
  var view = {view};
  if (view !== null) spm_set_view(view);
  window.spm_scene_ready = true;
}})();
</script>
</body>
</html>
"""
